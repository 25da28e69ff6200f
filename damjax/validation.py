"""Checks at the edge: every problem of the input is a structured `Problem` (the field,
the value, the valid range and the reason), found before anything is traced.

The values are checked against the declarations of `damjax.params` (`check_value`, the
one check of a value against its field); the checks across fields (the weak layer must
carry the slab, dx must resolve Lambda, ...) are here too. Each consumer words the
problems itself: the API and the command line name ``poisson (--poisson)``
(`Problem.text`, `InputError`), a scenario file ``params.poisson``
(`damjax.scenario.schema`). Valid but dubious or implausible values are `Problem` notes
too (``category``), warned before the run.

`damjax.pst.prepare` and `damjax.slope.simulation.prepare` run these checks once per run;
`size_problem` finds runs too large for this machine; `ensure_x64` / `require_x64`
handle float64 runs.
"""

from __future__ import annotations

import dataclasses
import math
import os
import string
import warnings
from collections.abc import Callable, Iterable
from typing import Any

import jax
import numpy as np

from damjax import theory
from damjax._tracing import is_traced
from damjax.constants import G_ACC
from damjax.params import (
    COVER_SPEC,
    DOMAIN_SPEC,
    PROFILE_FIELDS,
    PSTParams,
    PSTSetup,
    SlopeSetup,
    Spec,
    is_plastic,
    map_specs,
    spec_of,
    specs,
)

MAX_ELASTIC_SLIP = 0.1  # [m]
MAX_CELLS = 1e15  # [-] cells along an extent: far beyond any memory (the sizes overflow)
MIN_CELLS = 4  # a strip shorter than this has no interior (quadratic B-spline stencil)


# --------------------------------------------------------------------------- problems


def shown(value: Any) -> str:
    """A value as the API's messages show it (``repr``; huge integers as floats)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**15:
        return f"{float(value):.3g}"  # 1e30 typed for an integer field
    return repr(value)


class _Names:
    """``${field}`` in a reason, named by a function of the field's name."""

    def __init__(self, name: Callable[[str], str]) -> None:
        self.name = name

    def __getitem__(self, key: str) -> str:
        return self.name(key)


@dataclasses.dataclass(frozen=True)
class Problem:
    """One problem (or one warning) of the input, for each consumer to word.

    Attributes:
        field: the field the line is about (None: ``reason`` is the whole line).
        value: its value (the offending one of a batch or profile; a shape for
            ``form = "shape"``; the (min, max) of a map for ``form = "map"``).
        reason: why, e.g. ``must be in (0, 0.5)``; other fields are written ``${name}``
            and named by the consumer.
        valid: the valid range alone, e.g. ``(0, 0.5)`` ("" where none applies).
        form: "value" (``NAME = VALUE: REASON``), "shape" (``NAME has shape S:
            REASON``), "map" (``NAME field: REASON``) or "line" (``REASON``).
        what: words after the name (``minimum``: ``strength_profile minimum = ...``).
        setup: the setup class whose fields are meant (`PSTSetup` or `SlopeSetup`).
        category: "error", or the warning it is: "dubious" (valid but physically
            dubious), "implausible" (outside a field's plausible range), "resolution"
            (dx and Lambda), "slope" / "overloaded" (slope runs).
    """

    field: str | None
    value: Any = None
    reason: str = ""
    valid: str = ""
    form: str = "value"
    what: str = ""
    setup: type = PSTSetup
    category: str = "error"

    def api_name(self, field: str) -> str:
        """A field as the API and the command line name it: ``poisson (--poisson)``."""
        try:
            return spec_of(field, self.setup).label
        except KeyError:
            return field

    def text(
        self,
        name: Callable[[str], str] | None = None,
        show: Callable[[str, Any], str] | None = None,
    ) -> str:
        """The problem as one line: fields named by ``name`` (default `api_name`),
        values written by ``show(field, value)`` (default: as the API shows them)."""
        name = name or self.api_name
        reason = string.Template(self.reason).safe_substitute(_Names(name))
        if self.form == "line" or self.field is None:
            return reason
        if self.form == "map":  # a map of a slope run, an argument: its bare name
            return f"{self.field} field: {reason}"
        head = name(self.field) + (f" {self.what}" if self.what else "")
        if self.form == "shape":
            return f"{head} has shape {self.value}: {reason}"
        value = show(self.field, self.value) if show else shown(self.value)
        return f"{head} = {value}: {reason}"

    def __str__(self) -> str:
        return self.text()


class InputError(ValueError):
    """Invalid input: a ValueError whose message is one line per `Problem` (in the API's
    words), with the problems themselves in ``problems`` for callers that word them
    otherwise (a scenario file's keys), and ``notes`` on implausible values (a unit
    mix-up is the likely cause of some problems: ``youngs_modulus = 4``, meant in MPa,
    fails on dx against Lambda)."""

    def __init__(self, problems: Iterable[Problem], notes: Iterable[Problem] = ()) -> None:
        self.problems = list(problems)
        self.notes = list(notes)
        super().__init__("\n".join(p.text() for p in self.problems))


def raise_if(problems: list[Problem]) -> None:
    """`InputError` if there are problems."""
    if problems:
        raise InputError(problems)


def must_text(valid: str, integer: bool = False) -> str:
    """'must be in (0, inf) m', or 'must be an integer in [1, 64]'."""
    return f"must be an integer in {valid}" if integer else f"must be in {valid}"


# --------------------------------------------------------------------------- one field


def as_number(v: Any) -> float | None:
    """``v`` as a float where it is one number (not a bool, a string or an array), else
    None: for the options of a function (a window, a tolerance), checked before use."""
    if isinstance(v, (bool, str, bytes)) or np.ndim(v) != 0:
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def same_value(a: Any, b: Any) -> bool:
    """Whether two parameter values are equal (numbers, profiles or None)."""
    if a is None or b is None:
        return a is b
    return bool(np.array_equal(np.asarray(a), np.asarray(b)))


def _leaf_values(value: Any) -> list[float] | None:
    """All scalar values of a (possibly batched) leaf, or None if not numeric (a string
    or a bool is not a number here, though numpy would convert it)."""
    if isinstance(value, (str, bytes, bool, np.bool_)):
        return None
    try:
        given = np.asarray(value)
        if given.dtype.kind not in "iuf":
            return None
        arr = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        return None
    if given.dtype.kind == "f" and given.dtype.itemsize < 8:
        # the shortest decimal of the float32 value (0.7, not its float64 0.699999988...)
        return [float(str(x)) for x in given.ravel()]
    return [float(x) for x in arr]


def _members(index: list[int]) -> str:
    shown_ = ", ".join(str(i) for i in index[:5])
    return shown_ + (f" and {len(index) - 5} more" if len(index) > 5 else "")


def check_value(spec: Spec, value: Any, setup: type = PSTSetup) -> Problem | None:
    """The one check of a value against its field's declaration (`damjax.params`): its
    kind and its valid range. A parameter may be batched (every member is checked, the
    first bad one named with the members), a profile is an array of >= 2 values each in
    range; a setting is one number, integer or choice. None where it is valid."""
    name, valid = spec.name, spec.valid_text
    if value is None and spec.optional:
        return None
    if spec.kind == "point":
        return None  # a slope's start: checked against the release area
    if spec.kind == "profile":
        values = _leaf_values(value)
        shape = np.shape(value)
        if values is None or len(shape) < 1 or shape[-1] < 2:
            return Problem(
                name, shape, f"must be an array of >= 2 values [{spec.unit}]", form="shape"
            )
        bad = [v for v in values if not spec.valid.holds(v)]
        if bad:
            return Problem(name, bad[0], must_text(f"{valid} (every value)"), valid)
        return None
    if isinstance(spec.valid, tuple):  # a choice, a flag, dim
        if spec.kind == "bool":
            ok = isinstance(value, bool)
        else:
            ok = not isinstance(value, bool) and value in spec.valid
        if not ok:
            return Problem(name, value, must_text(valid), valid, setup=setup)
        return None
    if name in specs(PSTParams):  # a leaf: a number or a batch of them
        values = _leaf_values(value)
        if values == []:  # numbers, but none: an empty batch
            return Problem(name, np.shape(value), "a batch needs >= 1 member", form="shape")
        if not values:
            return Problem(name, value, must_text(f"{valid} (a number)"), valid)
        bad = [i for i, v in enumerate(values) if not spec.valid.holds(v)]
        if not bad:
            return None
        reason = must_text(valid)
        if len(values) > 1:  # a batch: which members
            reason += f" (batch member{'s' if len(bad) > 1 else ''} {_members(bad)})"
        return Problem(name, values[bad[0]], reason, valid)
    integer = spec.kind == "int"
    try:
        if isinstance(value, (str, bytes)):
            raise TypeError(name)
        v = float(value)
    except (TypeError, ValueError):
        text = must_text(valid, integer) if integer else must_text(f"{valid} (a number)")
        return Problem(name, value, text, valid, setup=setup)
    if (
        isinstance(value, bool)
        or not spec.valid.holds(v)
        or (integer and not float(v).is_integer())
    ):
        return Problem(name, value, must_text(valid, integer), valid, setup=setup)
    return None


def _fields(obj: Any, setup: type = PSTSetup, skip: Iterable[str] = ()) -> list[Problem]:
    """`check_value` of every declared field of a parameter or setup object."""
    out = []
    for name, spec in specs(type(obj)).items():
        if name not in skip:
            problem = check_value(spec, getattr(obj, name), setup)
            if problem is not None:
                out.append(problem)
    return out


# --------------------------------------------------------------------------- parameters


def _as_min(x: Any) -> float:
    return float(np.min(np.asarray(x, dtype=float)))


def lambda_problem(dx: float, lam: float, setup: type = PSTSetup) -> Problem | None:
    """dx must resolve the weak-layer elastic length Lambda [m]: at most Lambda/2."""
    if dx > lam / 2:
        return Problem(
            "dx",
            dx,
            f"must be at most Lambda/2 = {lam / 2:.4g} m (Lambda = {lam:.4g} m, the "
            "weak-layer elastic length, must be resolved)",
            setup=setup,
        )
    return None


def uniform_failure_stress_of(
    params: PSTParams, spacing: float, tau_p: Any, thickness: Any = None
) -> np.ndarray:
    """`damjax.materials.weak_layer.uniform_failure_stress` on the host [Pa]: of strength
    tau_p [Pa] under slabs of ``thickness`` h0 [m] (default ``params.thickness``) on
    particles ``spacing`` [m] apart, with the front width of
    `damjax.core.state.Model.with_constants`."""
    from damjax.materials.weak_layer import uniform_failure_stress

    def a(v: Any) -> np.ndarray:
        return np.asarray(v, dtype=float)

    h = a(params.thickness if thickness is None else thickness)
    k = a(params.wl_shear_modulus) / a(params.wl_thickness)
    lam = np.sqrt(a(params.youngs_modulus) * h / ((1.0 - a(params.poisson) ** 2) * k))
    u_r = a(tau_p) / k * (1.0 + a(params.softening))
    with np.errstate(invalid="ignore"):  # tau_p = inf: an unbreakable layer
        width = np.where(np.isfinite(u_r), u_r, 1.0) * (spacing / lam)
    return uniform_failure_stress(a(tau_p), k, u_r, width, xp=np)


def param_problems(
    params: PSTParams, setup: PSTSetup | None = None, skip: Iterable[str] = ()
) -> list[Problem]:
    """The problems of the parameter values (empty when all are valid): every field
    (`check_value`), then how they fit together and, given a ``setup``, how they fit it.
    ``skip``: fields given otherwise (a slope's slope_deg map)."""
    problems = _fields(params, skip=skip)
    if problems:
        return problems
    lam = _as_min(theory.elastic_length(params))
    tau_g = theory.gravity_shear(params)
    if params.slope_profile is not None:  # the steepest point loads the layer most
        psi_max = np.max(np.asarray(params.slope_profile, dtype=float), axis=-1)
        tau_g = (
            np.asarray(params.density, dtype=float)
            * G_ACC
            * np.asarray(params.thickness, dtype=float)
            * np.sin(np.radians(psi_max))
        )
    if setup is not None and not setup.controlled:
        profiled = params.strength_profile is not None
        tau_min = (
            np.min(np.asarray(params.strength_profile, dtype=float))
            if profiled
            else np.asarray(params.tau_peak, dtype=float)
        )
        spacing = setup.dx / int(setup.particles_per_cell)
        fails_at = uniform_failure_stress_of(params, spacing, tau_min)
        reason = None
        if np.any(tau_min <= np.asarray(tau_g)):
            reason = (
                f"must exceed the gravitational shear stress tau_g = "
                f"{float(np.max(tau_g)):.1f} Pa, otherwise the weak layer has already "
                "failed under the slab's weight"
            )
        elif setup.dx <= lam / 2 and np.any(fails_at <= np.asarray(tau_g)):
            # a brittle layer on coarse particles fails below tau_p under a uniform load
            need = float(np.max(np.asarray(tau_g) * tau_min / fails_at))
            reason = (
                f"must exceed {need:.1f} Pa at a particle spacing of {spacing:.3g} m "
                f"(tau_g = {float(np.max(tau_g)):.1f} Pa): a weak layer that softens so "
                "little starts failing under the slab's uniform weight at tau_p (1 + "
                "delta) (1 - spacing / (2 Lambda)), so it would fail everywhere at "
                "once (damjax.materials.weak_layer.uniform_failure_stress); a finer "
                "${dx}, more ${particles_per_cell} or some ${softening} hold it"
            )
        if reason is not None:
            problems.append(
                Problem(
                    "strength_profile" if profiled else "tau_peak",
                    float(np.min(tau_min)),
                    reason,
                    what="minimum" if profiled else "",
                )
            )
    # the slab's elastic slip on the intact layer, tau_g / K (baseline 0.14 mm): metres of
    # it mean a layer with no stiffness, and a slab that leaves the grid before failing
    slip = np.max(
        np.asarray(tau_g, dtype=float)
        * np.asarray(params.wl_thickness, dtype=float)
        / np.asarray(params.wl_shear_modulus, dtype=float)
    )
    if slip > MAX_ELASTIC_SLIP:
        g_wl = _as_min(params.wl_shear_modulus)
        d_wl = float(np.max(np.asarray(params.wl_thickness, dtype=float)))
        problems.append(
            Problem(
                None,
                reason=f"${{wl_shear_modulus}} = {g_wl!r} with ${{wl_thickness}} = {d_wl!r}: "
                f"the weak layer's elastic slip under the slab, tau_g D_wl / G_wl = "
                f"{slip:.3g} m, must be at most {MAX_ELASTIC_SLIP} m (a stiffer or thinner "
                "layer; the baseline's is 0.14 mm)",
                form="line",
            )
        )
    if setup is not None and math.isfinite(setup.dx) and setup.dx > 0:
        problem = lambda_problem(setup.dx, lam)
        if problem is not None:
            problems.append(problem)
    if setup is not None:
        lss = _leaf_values(params.steady_length) or [0.0]
        if not setup.controlled and params.strength_profile is None and max(lss) >= setup.length:
            problems.append(
                Problem(
                    "steady_length",
                    max(lss),
                    f"must be in [0, length = {setup.length!r}) m",
                )
            )
    return problems


def single_run_problems(params: PSTParams) -> list[Problem]:
    """One problem per batched field (a run of one PST takes scalars, and 1-D profiles)."""
    problems = []
    for f in dataclasses.fields(params):
        v = getattr(params, f.name)
        if v is None:
            continue
        want = 1 if f.name in PROFILE_FIELDS else 0
        if np.ndim(v) != want:
            kind = "a 1-D array of values along the strip" if want else "a number"
            problems.append(
                Problem(
                    f.name,
                    np.shape(v),
                    f"must be {kind} for one run (a batch of runs is damjax.sweep)",
                    form="shape",
                )
            )
    return problems


def shape_problems(params: PSTParams, batch: bool = False) -> list[Problem]:
    """The problems of the parameters' shapes, all that `jax.jit` knows of traced values:
    scalars and 1-D profiles of >= 2 values (with ``batch``, one more leading axis)."""
    problems = [] if batch else single_run_problems(params)
    named = {p.field for p in problems}
    for name in PROFILE_FIELDS:
        v = getattr(params, name)
        shape = np.shape(v)
        if v is not None and name not in named and (len(shape) < 1 or shape[-1] < 2):
            unit = specs(PSTParams)[name].unit
            problems.append(
                Problem(name, shape, f"must be an array of >= 2 values [{unit}]", form="shape")
            )
    return problems


def setup_problems(setup: PSTSetup) -> list[Problem]:
    """The problems of a PST's numerical settings (empty when all are valid)."""
    problems = _fields(setup)
    if not problems and setup.length / setup.dx < MIN_CELLS:
        problems.append(_cells_problem("length", setup))
    if not problems and not setup.length / setup.dx <= MAX_CELLS:
        problems.append(_too_many_cells("length", setup))
    return problems


def _too_many_cells(name: str, setup: Any) -> Problem:
    """dx so small that the extent ``name`` holds more than `MAX_CELLS` cells: no machine
    holds the run, and the sizes that follow overflow."""
    return Problem(
        "dx",
        setup.dx,
        f"must be at least ${{{name}}} / {MAX_CELLS:.0e} = "
        f"{getattr(setup, name) / MAX_CELLS:.3g} m (more cells than any run can hold)",
        setup=type(setup),
    )


def _cells_problem(name: str, setup: Any) -> Problem:
    return Problem(
        name,
        getattr(setup, name),
        f"must be at least {MIN_CELLS} cells of ${{dx}} = {setup.dx!r}, i.e. >= "
        f"{MIN_CELLS * setup.dx:.4g} m",
        setup=type(setup),
    )


# --------------------------------------------------------------------------- slopes


# the snow cover's inputs of a slope run (`damjax.simulate_slope`; 2026-11-27)
SNOW_MAPS = ("thickness", "stability", "wl_friction")
SNOW_MASKS = ("cover", "domain")


def mask_specs() -> dict[str, Spec]:
    """The declarations of a slope run's bool maps (`damjax.params`): the snow cover and
    the domain."""
    return {"cover": COVER_SPEC, "domain": DOMAIN_SPEC}


def slope_setup_problems(setup: SlopeSetup) -> list[Problem]:
    """The problems of a slope run's numerical settings: each field, then the grid
    (at least `MIN_CELLS` cells along and across)."""
    out = _fields(setup, SlopeSetup)
    if out:
        return out
    return [
        _cells_problem(name, setup)
        for name in ("length", "width")
        if getattr(setup, name) / setup.dx < MIN_CELLS
    ] + [
        _too_many_cells(name, setup)
        for name in ("length", "width")
        if not getattr(setup, name) / setup.dx <= MAX_CELLS
    ][:1]


def slope_problems(
    params: PSTParams,
    setup: SlopeSetup,
    slope: Any = None,
    tau: Any = None,
    fall: Any = 0.0,
    *,
    defer_lambda: bool = False,
    **snow: Any,
) -> list[Problem]:
    """The problems of a slope run's input (`damjax.simulate_slope`): the values, the
    grid, dx against Lambda (of params.thickness; with a thickness map, at its thinnest
    slab; ``defer_lambda``: not yet, the maps are read later) and, where the maps are
    given (``slope`` [deg], ``tau`` [Pa], ``fall`` [deg]: scalars or (nx, ny) arrays at
    the cell centres; ``snow``: the snow cover's ``thickness`` [m], ``stability`` [-],
    ``wl_friction`` [-], ``cover`` and ``domain``), the start and the maps
    (`slope_field_problems`). A given slope map replaces params.slope_deg."""
    out = param_problems(params, skip=["slope_deg"] if slope is not None else [])
    setup_out = slope_setup_problems(setup)
    if out or setup_out:  # the checks below need a valid grid
        return out + setup_out
    if not defer_lambda and snow.get("thickness") is None:
        problem = lambda_problem(setup.dx, float(theory.elastic_length(params)), SlopeSetup)
        if problem is not None:
            return [problem]
    if slope is None and tau is None and all(v is None for v in snow.values()):
        return []
    return slope_field_problems(setup, slope, tau, fall, params=params, **snow)


def _map_shape_reason(shape: tuple[int, ...], setup: SlopeSetup) -> str | None:
    """Why a slope map of ``shape`` does not fit the release area's cells (None: it
    does): a scalar or (nx, ny)."""
    cells = (int(round(setup.length / setup.dx)), int(round(setup.width / setup.dx)))
    if len(shape) == 2 and tuple(shape) != cells:
        return (
            f"shape {tuple(shape)} must be (nx, ny) = {cells}, the cells of length "
            f"{setup.length} m x width {setup.width} m at dx {setup.dx} m"
        )
    if len(shape) not in (0, 2):
        return "must be a scalar or a 2D array (nx, ny)"
    return None


def map_shape_problems(setup: SlopeSetup, **maps: Any) -> list[Problem]:
    """The problems of the slope maps' shapes (``slope_deg``, ``tau_peak``, ``fall_deg``,
    ``thickness``, ``stability``, ``wl_friction``), all that `jax.jit` knows of traced
    maps: each a scalar or (nx, ny). The setup must be valid."""
    out = []
    for name, arr in maps.items():
        reason = None if arr is None else _map_shape_reason(np.shape(arr), setup)
        if reason is not None:
            out.append(Problem(name, None, reason, form="map", setup=SlopeSetup))
    return out


def slope_field_problems(
    setup: SlopeSetup,
    slope: Any,
    tau: Any,
    fall: Any,
    *,
    params: PSTParams | None = None,
    thickness: Any = None,
    cover: Any = None,
    stability: Any = None,
    wl_friction: Any = None,
    domain: Any = None,
) -> list[Problem]:
    """The problems of a slope run's start and fields: the start inside the release area,
    the slope angle [deg], strength [Pa] and fall-line direction [deg], and the snow
    cover's slab thickness h0 [m], stability ratio [-] and friction coefficient [-]:
    scalars or (nx, ny) arrays at the cell centres, each value in its range (a snow map
    on every cell, those without snow too: the particles beside them interpolate); the
    bool maps ``cover`` and ``domain`` (nx, ny), the cover not empty. Given the
    ``params``, also what the snow cover asks of them: dx resolves Lambda at the thinnest
    slab, and a "crack_band" slab has a particle in every cell."""
    try:
        x0, y0 = (float(c) for c in setup.start)
    except (TypeError, ValueError):
        return [Problem("start", setup.start, "must be a point (x, y) [m]", setup=SlopeSetup)]
    out = []
    if not (0 <= x0 <= setup.length and 0 <= y0 <= setup.width):
        out.append(
            Problem(
                "start",
                setup.start,
                f"must lie in [0, {setup.length:g}] x [0, {setup.width:g}] m (the release area)",
                setup=SlopeSetup,
            )
        )
    cells = (int(round(setup.length / setup.dx)), int(round(setup.width / setup.dx)))
    given = dict(slope_deg=slope, tau_peak=tau, fall_deg=fall, thickness=thickness)
    given.update(stability=stability, wl_friction=wl_friction)
    for name, arr in given.items():
        if arr is None:
            continue
        spec = map_specs()[name]
        snow_map = name in SNOW_MAPS
        kind = getattr(np.asarray(arr) if not is_traced(arr) else arr, "dtype", None)
        try:
            if kind is None or kind.kind not in "iuf":  # no bools, strings or objects
                raise TypeError(name)
            a = np.asarray(arr, dtype=float)
        except (TypeError, ValueError):
            reason = "must be a number or a 2D array (nx, ny) of numbers"
            out.append(Problem(name, None, reason, form="map", setup=SlopeSetup))
            continue
        shape_reason = _map_shape_reason(a.shape, setup)
        if shape_reason is not None:
            reason = shape_reason
        elif not snow_map and not np.all(np.isfinite(a) | (np.isinf(a) & (name == "tau_peak"))):
            reason = "must be a finite scalar or a 2D array (nx, ny)"
            bad = ~(np.isfinite(a) | (np.isinf(a) & (name == "tau_peak")))
            if a.ndim == 0:
                reason = f"is {a.item()}: must be a finite number in {spec.valid_text}"
            if a.ndim == 2:  # where: a map from a file or a computation
                i, j = (int(k[0]) for k in np.nonzero(bad))
                reason += (
                    f" of finite numbers ({int(bad.sum())} not, the first {a[i, j]} at cell "
                    f"({i}, {j}))"
                )
        elif not np.all(spec.valid.holds(a)):
            where = (
                "every cell, those without snow too: the particles beside them interpolate; "
                "fill them, e.g. from a neighbour"
                if snow_map and a.ndim == 2
                else "every cell"
            )
            reason = must_text(f"{spec.valid_text} ({where})")
            if a.ndim == 2:  # where: the first cell out of range
                i, j = (int(k[0]) for k in np.nonzero(~spec.valid.holds(a)))
                reason += f"; the first out of range, {a[i, j]:g}, at cell ({i}, {j})"
        else:
            continue
        finite = np.isfinite(a) | np.isinf(a)  # (no all-NaN warning from nanmin)
        found = (float(np.nanmin(a)), float(np.nanmax(a))) if finite.any() else (math.nan,) * 2
        out.append(Problem(name, found, reason, spec.valid_text, form="map", setup=SlopeSetup))
    for name, arr in (("cover", cover), ("domain", domain)):
        if arr is None:
            continue
        a = np.asarray(arr)
        if a.shape != cells or a.dtype != bool:
            reason = (
                f"must be a bool map (nx, ny) = {cells}, the cells of length {setup.length} m "
                f"x width {setup.width} m at dx {setup.dx} m (got {a.dtype} {a.shape})"
            )
        elif name == "cover" and not a.any():
            reason = "no snow-covered cell (every cell is False): the slope has no slab to run"
        else:
            continue
        out.append(Problem(name, a.shape, reason, form="map", setup=SlopeSetup))
    if not out and cover is not None and np.ndim(cover) == 2:
        # the crack starts in the slab: a start on a cell without snow saws nothing
        i = min(max(int(x0 / setup.dx), 0), cells[0] - 1)
        j = min(max(int(y0 / setup.dx), 0), cells[1] - 1)
        if not bool(np.asarray(cover)[i, j]):
            out.append(
                Problem(
                    "start",
                    setup.start,
                    f"lies on a cell without snow (cell ({i}, {j}) of the cover): the crack "
                    "must start in the slab; move it onto snow-covered ground",
                    setup=SlopeSetup,
                )
            )
    if out or params is None:
        return out
    return out + _snow_cover_problems(params, setup, thickness, cover)


def _snow_cover_problems(
    params: PSTParams, setup: SlopeSetup, thickness: Any, cover: Any
) -> list[Problem]:
    """What a (valid) snow cover asks of the parameters and the setup: dx at most Lambda/2
    at the thinnest slab of the snow-covered cells; a "crack_band" slab (its band openings
    sum over the particles' lattice) with a particle in every cell."""
    out = []
    if thickness is not None:
        h = np.asarray(thickness, dtype=float)
        if cover is not None and h.ndim == 2:
            h = h[np.asarray(cover, bool)]
        thin = float(np.min(h))
        lam = float(theory.elastic_length(dataclasses.replace(params, thickness=thin)))
        if setup.dx > lam / 2:
            out.append(
                Problem(
                    "dx",
                    setup.dx,
                    f"must be at most Lambda/2 = {lam / 2:.4g} m at the thinnest slab, "
                    f"{thin:.3g} m (Lambda = {lam:.4g} m, the weak-layer elastic length, must "
                    "be resolved)",
                    setup=SlopeSetup,
                )
            )
    return out


# --------------------------------------------------------------------------- warnings


class DubiousInputWarning(UserWarning):
    """Valid but physically dubious input (`dubious`): the run goes ahead."""


def implausible(params: PSTParams, given: Iterable[str] | None = None) -> list[Problem]:
    """Notes on the parameters outside their plausible range (`damjax.params`), each with
    a unit hint where one makes it plausible (``4 Pa: did you mean 4 MPa = 4e6 Pa?``).
    ``given``: only these fields (None: all)."""
    notes = []
    for name, spec in specs(PSTParams).items():
        if spec.plausible is None or (given is not None and name not in given):
            continue
        v = _scalar(params, name)
        if v is None or not spec.valid.holds(v) or spec.plausible.holds(v) or np.isinf(v):
            continue  # inf: the documented "unbreakable" / "elastic" setting
        hint = spec.unit_hint(v)
        reason = f"outside {spec.plausible} {spec.unit}".rstrip() + f", {spec.plausible_why}"
        notes.append(
            Problem(name, v, reason + (f": {hint}" if hint else ""), category="implausible")
        )
    return notes


def _scalar(params: PSTParams, name: str) -> float | None:
    """A parameter's value when it is one number (not a batch, a string or a bool)."""
    value = getattr(params, name)
    values = _leaf_values(value)
    return values[0] if values is not None and np.ndim(value) == 0 else None


def dubious(
    params: PSTParams, setup: PSTSetup, given: Iterable[str] | None = None
) -> list[Problem]:
    """Notes on valid values that are physically dubious for a slab avalanche release
    (`implausible` values first), the warnings of a PST run.

    ``given``: parameter names set explicitly (None: all); only those are reported as
    ignored by a controlled run."""
    given = None if given is None else set(given)
    notes = implausible(params)

    def note(field: str | None, value: Any, reason: str, form: str = "value") -> None:
        notes.append(Problem(field, value, reason, form=form, category="dubious"))

    psi, phi = _scalar(params, "slope_deg"), _scalar(params, "friction_deg")
    if params.slope_profile is not None:
        try:
            psi = float(np.max(np.asarray(params.slope_profile, dtype=float)))
        except (TypeError, ValueError):
            psi = None
    if psi is not None and phi is not None and psi <= phi:
        note(
            "slope_deg",
            psi,
            f"at or below ${{friction_deg}} = {phi!r}, friction holds a released slab, so "
            "a crack does not run away as a shear crack (the paper's mechanism needs "
            "slope_deg > friction_deg); the theory values that assume it are reported as "
            "null",
        )
    if setup.controlled:
        default = PSTParams()
        # every member of a batch (`damjax.sweep` broadcasts the fields it was not given)
        ignored = [
            k
            for k in ("tau_peak", "steady_length", "strength_gradient", "softening")
            if (given is None or k in given)
            and any(v != getattr(default, k) for v in _leaf_values(getattr(params, k)) or [])
        ]
        if params.strength_profile is not None:
            ignored.append("strength_profile")
        if ignored:
            note(
                None,
                None,
                "${controlled} = true: the weak layer is unbreakable, so "
                + _listed(ignored)
                + (" is" if len(ignored) == 1 else " are")
                + " ignored",
                "line",
            )
        v = _scalar(params, "saw_speed")
        if v is not None and v * setup.duration > setup.length:
            note(
                "duration",
                float(setup.duration),
                f"the controlled cut (${{saw_speed}} = {v!r} m/s) leaves the "
                f"{setup.length:g} m domain at t = {setup.length / v:.3g} s; the tension "
                "gradient is then reported as null",
            )
    else:
        v = _scalar(params, "saw_speed")
        c = float(np.min(np.asarray(theory.shear_wave_speed(params), dtype=float)))
        if v is not None and v > 0.5 * c:
            note(
                "saw_speed",
                v,
                f"a saw at {v / c:.2g} c_s in a self-propagating PST (the paper saws at 6 m/s)",
            )
    sides = ("length", "width") if setup.dim == 2 and setup.lateral == "free" else ("length",)
    for name, v, grid in partial_cells(setup, sides):
        note(
            name,
            v,
            f"not a whole number of cells of ${{dx}} = {float(setup.dx)!r}; the strip is "
            f"{grid:.6g} m" + (" long" if name == "length" else " wide"),
        )
    if setup.cfl > 0.9:
        note("cfl", float(setup.cfl), "close to the stability limit 1")
    notes += _unused_slab_settings(params, setup, given)
    return notes


def _listed(names: list[str]) -> str:
    return ", ".join(f"${{{n}}}" for n in names)


def resolution_note(dx: float, lam: float) -> Problem | None:
    """A note where dx > Lambda/5: the crack tip is under-resolved."""
    if dx <= lam / 5:
        return None
    return Problem(
        None,
        reason=f"dx = {dx} m is larger than Lambda/5 = {lam / 5:.3g} m: the crack-tip stress "
        "concentration is under-resolved; results may depend on dx",
        form="line",
        category="resolution",
    )


def warn_notes(notes: Iterable[Problem], stacklevel: int = 2) -> None:
    """Warn each note in the API's words: `DubiousInputWarning` for dubious and
    implausible values, a plain UserWarning for the resolution."""
    for note in notes:
        dubious_ = note.category in ("dubious", "implausible")
        category = DubiousInputWarning if dubious_ else UserWarning
        warnings.warn(note.text(), category, stacklevel=stacklevel + 1)


def partial_cells(setup: Any, names: Iterable[str]) -> list[tuple[str, float, float]]:
    """(name, value, the grid's extent) of the setup's extents [m] that are not a whole
    number of cells of dx (the grid rounds them to the nearest)."""
    out = []
    for name in names:
        v = float(getattr(setup, name))
        n = max(1, round(v / setup.dx))
        if abs(n * setup.dx - v) > 1e-6 * v:
            out.append((name, v, n * setup.dx))
    return out


def _unused_slab_settings(
    params: PSTParams, setup: PSTSetup, given: set[str] | None
) -> list[Problem]:
    """Settings of a slab law the run does not use, set away from their defaults: the
    plastic law's with an elastic slab (every tensile_strength infinite), the seeded
    strength field's with the "paper" slab (only "crack_band" seeds one)."""
    default, default_setup = PSTParams(), PSTSetup()

    def changed(name: str) -> bool:
        if given is not None and name not in given:
            return False
        v, d = getattr(params, name), getattr(default, name)
        if v is None or d is None:
            return v is not d
        try:
            return bool(np.any(np.asarray(v, dtype=float) != float(d)))
        except (TypeError, ValueError):
            return False

    field_keys = ("slab_strength_cov", "slab_strength_length")
    if is_plastic(params) is False:
        unused = [
            k
            for k in ("mcc_m", "mcc_beta", "mcc_xi", "slab_fracture_energy", *field_keys)
            if changed(k)
        ]
        if setup.seed != default_setup.seed:  # the crack band's strength field's
            unused.append("seed")
        if not unused:
            return []
        return [
            Problem(
                None,
                reason="${tensile_strength} = inf (an elastic slab): "
                + _listed(unused)
                + (" is" if len(unused) == 1 else " are")
                + " ignored (they set the plastic slab's law and fractures)",
                form="line",
                category="dubious",
            )
        ]
    if setup.slab_fracture == "crack_band":
        return []
    unused = [k for k in field_keys if changed(k)]
    if setup.seed != default_setup.seed:
        unused.append("seed")
    if not unused:
        return []
    return [
        Problem(
            "slab_fracture",
            setup.slab_fracture,
            _listed(unused)
            + (" is" if len(unused) == 1 else " are")
            + ' ignored (they set the seeded strength field of slab_fracture = "crack_band")',
            category="dubious",
        )
    ]


# --------------------------------------------------------------------------- other checks


def concrete_only(caller: str, traced: bool, progress: bool, resume: dict[str, Any]) -> None:
    """TypeError where a progress bar, a resumed run (``state``, ``start_chunk``,
    ``history``) or a ``callback`` come with traced inputs: they need a concrete run."""
    given = [resume[k] is not None for k in ("state", "history", "callback")]
    if traced and (progress or resume["start_chunk"] or any(given)):
        raise TypeError(
            f"{caller}: progress, resume (state, start_chunk, history) and callback need "
            "concrete inputs; inside jax.grad/jit/vmap call it without them"
        )


def check_width(width: Any) -> None:
    """ValueError unless the smooth arrest position's damage-ramp ``width`` is None or a
    number in (0, 1] (the ramp spans u_max / u_r in [1 - width, 1])."""
    if width is None or is_traced(width):
        return
    try:
        w = float(width)
    except (TypeError, ValueError):
        w = math.nan
    if isinstance(width, bool) or not 0 < w <= 1:
        raise ValueError(f"width = {width!r}: must be None or a number in (0, 1] [-]")


def expect_types(where: str, **values: tuple[Any, Any]) -> None:
    """TypeError unless each ``name=(value, cls)`` holds a ``cls`` (a class or a tuple;
    None passes where ``cls`` includes ``type(None)``): swapped or foreign arguments get
    one line naming the argument, not an AttributeError from deep inside."""
    for name, (value, cls) in values.items():
        if not isinstance(value, cls):
            classes = cls if isinstance(cls, tuple) else (cls,)
            names_ = {
                type(None): "None",
                PSTParams: "damjax.PSTParams",
                "Layout": "a Layout (damjax.make_layout)",
                "SlopeLayout": "a SlopeLayout (damjax.core.model.make_slope_layout)",
                "SlopeProblem": "a SlopeProblem (damjax.calibrate.slope.slope_problem)",
                "ObservationGrid": "an ObservationGrid (damjax.calibrate.slope.observation_grid)",
            }
            names = " or ".join(
                names_.get(c, names_.get(c.__name__, f"damjax.{c.__name__}")) for c in classes
            )
            raise TypeError(f"{where}: {name} must be {names}, got {type(value).__name__}")


def ensure_x64(dtype: str) -> None:
    """Switch JAX's 64-bit mode on for a float64 run (``jax_enable_x64``, process-wide: it
    also changes the default dtype of your own JAX code), with a warning the first time."""
    if dtype != "float64" or jax.config.jax_enable_x64:
        return
    jax.config.update("jax_enable_x64", True)
    warnings.warn(
        "dtype = 'float64': damjax switched jax_enable_x64 on for this process (JAX's "
        "default float is now float64 in your code too); set it yourself at start-up, "
        "jax.config.update('jax_enable_x64', True), or in the environment, "
        "JAX_ENABLE_X64=1 (the command line), to silence this",
        stacklevel=4,
    )


def require_x64(dtype: str) -> None:
    """ValueError for a float64 run in a traced function while 64-bit mode is off (it
    cannot be switched on inside a trace; the run would silently be float32)."""
    if dtype == "float64" and not jax.config.jax_enable_x64:
        raise ValueError(
            "dtype (--dtype) = 'float64': needs JAX's 64-bit mode, which cannot be switched "
            "on inside jax.grad/jit/vmap: call jax.config.update('jax_enable_x64', True) "
            "at start-up"
        )


# bytes per particle and float of a run: ~60 particle rows live in a step (state, model,
# the step's temporaries, the donated copy), plus the per-chunk snapshots kept on the host
_ROWS_PER_PARTICLE = 64
_SNAPSHOT_ROWS = 8


def _physical_memory() -> int | None:
    """Total physical memory [bytes], None where the OS does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def size_problem(
    n_particles: int,
    n_nodes: int,
    n_chunks: int,
    itemsize: int,
    fields: tuple[str, ...],
    what: str = "",
    setup: type = PSTSetup,
) -> Problem | None:
    """A problem where a run cannot fit in this machine's memory, else None.

    A generous estimate (~64 particle-sized rows in a step plus 8 per stored snapshot) is
    compared with the total physical memory, so that an absurd size (a 1e9 m PST) fails at
    once with a message naming the fields that set the size (``fields``; ``what``: words
    after them), not with an allocation traceback from numpy or XLA.
    """
    total = _physical_memory()
    if total is None:
        return None
    need = itemsize * (
        n_particles * (_ROWS_PER_PARTICLE + _SNAPSHOT_ROWS * max(1, n_chunks)) + 8 * n_nodes
    )
    if need <= total:
        return None
    names = [f"${{{f}}}" for f in fields]
    listed = ", ".join(names[:-1]) + " and " + names[-1] if len(names) > 1 else names[0]
    return Problem(
        None,
        reason=f"{listed}{what} give {n_particles:.3g} particles on {n_nodes:.3g} grid nodes "
        f"over {n_chunks} chunks: ~{need / 2**30:.3g} GiB, more than this machine's "
        f"{total / 2**30:.3g} GiB of memory; use a coarser dx, a smaller domain, a "
        "shorter duration or larger chunk_steps",
        form="line",
        setup=setup,
    )
