"""Validation at the edge: every problem of the input is one line that names the API field,
the CLI flag, the value and the valid range, raised before anything is traced.

`validate` (PST) and `slope_problems` (slope) are called once by `damjax.simulate_pst` and
`damjax.simulate_slope`; `dubious` lists valid but physically dubious values (warnings);
`check_problem_size` stops runs too large for this machine; `ensure_x64` / `require_x64`
handle float64 runs. The rules themselves (`PARAM_RULES`, `SETUP_RULES`, `SETUP_CHOICES`)
are shared with the scenario files (`damjax.scenario`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Iterable
from typing import Any

import jax
import numpy as np

from damjax import theory
from damjax._tracing import concrete_tree, is_traced
from damjax.constants import (
    DTYPES,
    G_ACC,
    LATERAL_CONDITIONS,
    MCC_INVARIANTS,
    P0_RULES,
    SLAB_FRACTURE_MODELS,
)
from damjax.core.transfer import ACCUMULATIONS
from damjax.params import PROFILE_FIELDS, PSTParams, PSTSetup, SlopeSetup


# field name -> (check, description of the valid range); the checks are written with `&`
# and comparisons only, so they take floats (here) and JAX arrays (`traced_param_checks`)
def _pos(v: Any) -> Any:
    return (v > 0) & (v < math.inf)


def _nonneg(v: Any) -> Any:
    return (v >= 0) & (v < math.inf)


PARAM_RULES: dict[str, tuple[Any, str]] = {
    "slope_deg": (lambda v: (v > 0) & (v < 90), "(0, 90) deg"),
    "thickness": (_pos, "(0, inf) m"),
    "density": (_pos, "(0, inf) kg/m^3"),
    "youngs_modulus": (_pos, "(0, inf) Pa"),
    "poisson": (lambda v: (v > 0) & (v < 0.5), "(0, 0.5)"),
    "friction_deg": (lambda v: (v > 0) & (v < 90), "(0, 90) deg"),
    "wl_shear_modulus": (_pos, "(0, inf) Pa"),
    "wl_thickness": (_pos, "(0, inf) m"),
    "tau_peak": (lambda v: v > 0, "(0, inf] Pa"),
    "steady_length": (_nonneg, "[0, inf) m"),
    "strength_gradient": (_nonneg, "[0, inf) Pa/m"),
    "softening": (_nonneg, "[0, inf)"),
    "tensile_strength": (lambda v: v > 0, "(0, inf] Pa"),
    "saw_speed": (_pos, "(0, inf) m/s"),
    "mcc_m": (_pos, "(0, inf)"),
    "mcc_beta": (_pos, "(0, inf)"),
    "mcc_xi": (_nonneg, "[0, inf)"),
    "slab_fracture_energy": (lambda v: v > 0, "(0, inf] J/m^2"),
    "slab_strength_cov": (lambda v: (v >= 0) & (v <= 1), "[0, 1]"),
    "slab_strength_length": (lambda v: (v >= 0.2) & (v <= 10.0), "[0.2, 10] m"),
}
# every value of a profile (a measured field along the PST)
PROFILE_RULES: dict[str, tuple[Any, str]] = {
    "strength_profile": (lambda v: v > 0, "(0, inf] Pa (every value)"),
    "slope_profile": (lambda v: (v > 0) & (v < 90), "(0, 90) deg (every value)"),
}
# parameters whose None means "the model's default" (see `PSTParams`)
OPTIONAL_PARAMS = ("slab_fracture_energy",)

SETUP_RULES: dict[str, tuple[Any, str]] = {
    "length": (_pos, "(0, inf) m"),
    "dx": (_pos, "(0, inf) m"),
    "duration": (_pos, "(0, inf) s"),
    "cfl": (lambda v: 0 < v < 1, "(0, 1)"),
    "particles_per_cell": (lambda v: 1 <= v <= 64 and float(v).is_integer(), "[1, 64], integers"),
    # a chunk is one compiled scan: 10^7 steps is hours of run between snapshots
    "chunk_steps": (lambda v: 1 <= v <= 1e7 and float(v).is_integer(), "[1, 10^7], integers"),
    "dim": (lambda v: v in (1, 2), "{1, 2}"),
    "width": (_pos, "(0, inf) m"),
    "seed": (lambda v: 0 <= v <= 2**31 - 1 and float(v).is_integer(), "[0, 2^31 - 1], integers"),
}


# API fields that `damjax pst` has no flag for (scenario files and the API only)
NO_CLI_FLAG = ("slope_profile", "p0_rule", "mcc_invariants", "accumulation")


def flag(name: str) -> str:
    """CLI flag of an API field name (``slope_deg`` -> ``--slope-deg``)."""
    return "--" + name.replace("_", "-")


def label(name: str) -> str:
    """A field as errors name it: ``slope_deg (--slope-deg)``, or the bare name where the
    command line has no flag for it."""
    return name if name in NO_CLI_FLAG else f"{name} ({flag(name)})"


def _problem(name: str, value: Any, valid: str, with_flag: bool = True) -> str:
    label_ = label(name) if with_flag else name
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**15:
        shown = f"{float(value):.3g}"  # 1e30 typed for an integer field
    else:
        shown = repr(value)
    return f"{label_} = {shown}: {must_text(valid)}"


def must_text(valid: str) -> str:
    """'must be in (0, inf) m', or 'must be an integer in [1, 64]' for integer rules."""
    if valid.endswith(", integers"):
        return f"must be an integer in {valid[: -len(', integers')]}"
    return f"must be in {valid}"


def _as_float(value: Any) -> float | None:
    try:
        import numpy as np

        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return None
    return float(arr.max()) if arr.size else None


def _leaf_values(value: Any) -> list[float] | None:
    """All scalar values of a (possibly batched) leaf, or None if not numeric (a string
    or a bool is not a number here, though numpy would convert it)."""
    if isinstance(value, (str, bytes, bool, np.bool_)):
        return None
    try:
        if np.asarray(value).dtype.kind not in "iuf":
            return None
        arr = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        return None
    return [float(x) for x in arr]


def _members(index: list[int]) -> str:
    shown = ", ".join(str(i) for i in index[:5])
    return shown + (f" and {len(index) - 5} more" if len(index) > 5 else "")


def param_problems(params: PSTParams, setup: PSTSetup | None = None) -> list[str]:
    """One line per invalid parameter value (empty when all are valid)."""
    import numpy as np

    problems: list[str] = []
    if params.strength_profile is not None:
        prof = _leaf_values(params.strength_profile)
        shape = np.shape(params.strength_profile)
        if prof is None or len(shape) < 1 or shape[-1] < 2:
            problems.append(
                f"{label('strength_profile')} has shape {shape}: "
                "must be an array of >= 2 values [Pa]"
            )
        elif any(math.isnan(v) or not PROFILE_RULES["strength_profile"][0](v) for v in prof):
            ok, valid = PROFILE_RULES["strength_profile"]
            bad = next(v for v in prof if math.isnan(v) or not ok(v))
            problems.append(_problem("strength_profile", bad, valid))
    if params.slope_profile is not None:
        prof = _leaf_values(params.slope_profile)
        shape = np.shape(params.slope_profile)
        if prof is None or len(shape) < 1 or shape[-1] < 2:
            problems.append(
                f"{label('slope_profile')} has shape {shape}: must be an array of >= 2 values [deg]"
            )
        elif any(math.isnan(v) or not PROFILE_RULES["slope_profile"][0](v) for v in prof):
            ok, valid = PROFILE_RULES["slope_profile"]
            bad = next(v for v in prof if math.isnan(v) or not ok(v))
            problems.append(_problem("slope_profile", bad, valid))
    for name, (ok, valid) in PARAM_RULES.items():
        if name in OPTIONAL_PARAMS and getattr(params, name) is None:
            continue
        values = _leaf_values(getattr(params, name))
        if values is None or not values:
            problems.append(_problem(name, getattr(params, name), valid + " (a number)"))
            continue
        bad = [i for i, v in enumerate(values) if math.isnan(v) or not ok(v)]
        if bad:
            line = _problem(name, values[bad[0]], valid)
            if len(values) > 1:  # a batch: which members
                line += f" (batch member{'s' if len(bad) > 1 else ''} {_members(bad)})"
            problems.append(line)
    if problems:
        return problems
    # consistency checks between fields (elementwise over a batch)
    try:
        lam = _as_min(theory.elastic_length(params))
        tau_g = theory.gravity_shear(params)
    except Exception:  # pragma: no cover - defensive: numbers already validated
        return problems
    import numpy as np

    if params.slope_profile is not None:  # the steepest point loads the layer most
        psi_max = np.max(np.asarray(params.slope_profile, dtype=float), axis=-1)
        tau_g = (
            np.asarray(params.density, dtype=float)
            * G_ACC
            * np.asarray(params.thickness, dtype=float)
            * np.sin(np.radians(psi_max))
        )

    if setup is not None and not setup.controlled:
        tau_min = (
            np.min(np.asarray(params.strength_profile, dtype=float))
            if params.strength_profile is not None
            else np.asarray(params.tau_peak, dtype=float)
        )
        weak = tau_min <= np.asarray(tau_g)
        if np.any(weak):
            what = (
                "strength_profile (--strength-profile) minimum"
                if params.strength_profile is not None
                else "tau_peak (--tau-peak)"
            )
            problems.append(
                f"{what} = {float(np.min(tau_min))!r}: must exceed the "
                f"gravitational shear stress tau_g = {float(np.max(tau_g)):.1f} Pa, otherwise "
                "the weak layer has already failed under the slab's weight"
            )
    # the slab's elastic slip on the intact layer, tau_g / K (baseline 0.14 mm): metres of
    # it mean a layer with no stiffness, and a slab that leaves the grid before failing
    slip = np.max(
        np.asarray(tau_g, dtype=float)
        * np.asarray(params.wl_thickness, dtype=float)
        / np.asarray(params.wl_shear_modulus, dtype=float)
    )
    if slip > MAX_ELASTIC_SLIP:
        problems.append(
            f"wl_shear_modulus (--wl-shear-modulus) = {_as_min(params.wl_shear_modulus)!r} with "
            f"wl_thickness (--wl-thickness) = {_as_float(params.wl_thickness)!r}: the weak layer's "
            f"elastic slip under the slab, tau_g D_wl / G_wl = {slip:.3g} m, must be at most "
            f"{MAX_ELASTIC_SLIP} m (a stiffer or thinner layer; the baseline's is 0.14 mm)"
        )
    if setup is not None and math.isfinite(setup.dx) and setup.dx > 0:
        if setup.dx > lam / 2:
            problems.append(
                f"dx (--dx) = {setup.dx!r}: must be at most Lambda/2 = {lam / 2:.4g} m "
                f"(Lambda = {lam:.4g} m, the weak-layer elastic length, must be resolved)"
            )
    if setup is not None:
        lss = _leaf_values(params.steady_length) or [0.0]
        if not setup.controlled and params.strength_profile is None and max(lss) >= setup.length:
            problems.append(
                f"steady_length (--steady-length) = {max(lss)!r}: must be in "
                f"[0, length = {setup.length!r}) m"
            )
    return problems


def traced_param_checks(params: PSTParams) -> list[tuple[Any, str]]:
    """(bad, message) per parameter that holds a JAX tracer: ``bad`` a JAX bool, true
    when any of its values is outside `PARAM_RULES` / `PROFILE_RULES` (NaN included).
    Inside `jax.jit` no value is known when the run is traced, so these become runtime
    errors (`equinox.error_if`, `damjax.core.model`) instead of a silent NaN or a
    plausible number; concrete values are checked before tracing (`param_problems`)."""
    rules = {**PARAM_RULES, **PROFILE_RULES}
    return _traced_range_checks({k: getattr(params, k) for k in rules}, rules, label)


# the maps of a slope run (`damjax.simulate_slope`'s ``tau_peak``, ``slope_deg``,
# ``fall_deg``): every cell
MAP_RULES: dict[str, tuple[Any, str]] = {
    "tau_peak": (lambda v: v > 0, "(0, inf] Pa (every cell)"),
    "slope_deg": (lambda v: (v > 0) & (v < 90), "(0, 90) deg (every cell)"),
    "fall_deg": (lambda v: (v > -math.inf) & (v < math.inf), "finite deg (every cell)"),
}


def traced_map_checks(**maps: Any) -> list[tuple[Any, str]]:
    """`traced_param_checks` for the maps of a slope run given by name (`MAP_RULES`)."""
    return _traced_range_checks(maps, MAP_RULES, str)


def _traced_range_checks(
    values: dict[str, Any], rules: dict[str, tuple[Any, str]], name_of: Any
) -> list[tuple[Any, str]]:
    import jax.numpy as jnp

    out = []
    for name, value in values.items():
        if value is None or not is_traced(value):
            continue
        ok, valid = rules[name]
        bad = ~jnp.all(ok(jnp.asarray(value)))
        message = (
            f"{name_of(name)}: a value outside {valid}, found at run time (under jax.jit "
            "the values are not known when the run is traced)"
        )
        out.append((bad, message))
    return out


MAX_ELASTIC_SLIP = 0.1  # [m]
MIN_CELLS = 4  # a strip shorter than this has no interior (quadratic B-spline stencil)


def single_run_problems(params: PSTParams) -> list[str]:
    """One line per batched field (a run of one PST takes scalars, and 1-D profiles)."""
    problems = []
    for f in dataclasses.fields(params):
        v = getattr(params, f.name)
        if v is None:
            continue
        want = 1 if f.name in PROFILE_FIELDS else 0
        if np.ndim(v) != want:
            shape = np.shape(v)
            kind = "a 1-D array of values along the strip" if want else "a number"
            problems.append(
                f"{label(f.name)} has shape {shape}: must be {kind} for one run "
                "(a batch of runs is damjax.sweep)"
            )
    return problems


def _as_min(x: Any) -> float:
    import numpy as np

    return float(np.min(np.asarray(x, dtype=float)))


SETUP_CHOICES: dict[str, tuple[str, ...]] = {
    "lateral": LATERAL_CONDITIONS,
    "p0_rule": P0_RULES,
    "mcc_invariants": MCC_INVARIANTS,
    "dtype": DTYPES,
    "slab_fracture": SLAB_FRACTURE_MODELS,
    "accumulation": ACCUMULATIONS,  # P2G sums (damjax.core.transfer.p2g_channels)
}


def field_problems(
    setup: Any, rules: Iterable[str], choices: Iterable[str], with_flags: bool = True
) -> list[str]:
    """One line per invalid numerical setting among `rules` (keys of `SETUP_RULES`) and
    `choices` (keys of `SETUP_CHOICES`) of any setup object (PST or slope); `with_flags`
    names the CLI flag next to the field."""
    problems: list[str] = []
    for name in rules:
        ok, valid = SETUP_RULES[name]
        value = getattr(setup, name)
        try:
            if isinstance(value, (str, bytes)):
                raise TypeError(name)
            v = float(value)
        except (TypeError, ValueError):
            problems.append(_problem(name, value, valid + " (a number)", with_flags))
            continue
        if isinstance(value, bool) or math.isnan(v) or not ok(v):
            problems.append(_problem(name, value, valid, with_flags))
    for name in choices:
        allowed = SETUP_CHOICES[name]
        if getattr(setup, name) not in allowed:
            valid = "{" + ", ".join(allowed) + "}"
            problems.append(_problem(name, getattr(setup, name), valid, with_flags))
    return problems


def setup_problems(setup: PSTSetup) -> list[str]:
    """One line per invalid numerical setting (empty when all are valid)."""
    problems = field_problems(setup, SETUP_RULES, SETUP_CHOICES)
    if not problems and setup.length / setup.dx < MIN_CELLS:
        problems.append(
            f"length (--length) = {setup.length!r}: must be at least {MIN_CELLS} cells of "
            f"dx (--dx) = {setup.dx!r}, i.e. >= {MIN_CELLS * setup.dx:.4g} m"
        )
    if not isinstance(setup.controlled, bool):
        problems.append(_problem("controlled", setup.controlled, "{True, False}"))
    return problems


def ensure_x64(dtype: str) -> None:
    """Switch JAX's 64-bit mode on for a float64 run (``jax_enable_x64``, process-wide: it
    also changes the default dtype of your own JAX code), with a warning the first time."""
    if dtype != "float64" or jax.config.jax_enable_x64:
        return
    jax.config.update("jax_enable_x64", True)
    warnings.warn(
        "dtype = 'float64': damjax switched jax_enable_x64 on for this process (JAX's "
        "default float is now float64 in your code too); set it yourself at start-up, "
        "jax.config.update('jax_enable_x64', True), to silence this",
        stacklevel=3,
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


class DubiousInputWarning(UserWarning):
    """Valid but physically dubious input (`dubious`): the run goes ahead."""


def dubious(
    params: PSTParams,
    setup: PSTSetup,
    given: Iterable[str] | None = None,
    style: str = "api",
) -> list[str]:
    """One line per valid value that is physically dubious for a slab avalanche release
    (the warnings of `validate` and of scenario files).

    ``given``: parameter names set explicitly (None: all); only those are reported as
    ignored by a controlled run. ``style``: "api" names fields as ``slope_deg
    (--slope-deg)``, "toml" as ``params.slope_deg`` / ``setup.duration``.
    """
    given = None if given is None else set(given)

    def name_of(name: str, section: str = "params") -> str:
        return f"{section}.{name}" if style == "toml" else label(name)

    def fmt(v: Any) -> str:
        return repr(float(v))

    notes: list[str] = []

    def scalar(name: str) -> float | None:
        try:
            v = np.asarray(getattr(params, name), dtype=float)
        except (TypeError, ValueError):
            return None
        return float(v) if v.ndim == 0 else None

    ranges = {
        "slope_deg": (20.0, 60.0, "deg", "slab avalanches release on 30-50 deg slopes"),
        "density": (50.0, 550.0, "kg/m^3", "the density of seasonal snow"),
        "thickness": (0.05, 5.0, "m", "slab thicknesses of dry-snow slab avalanches"),
        "youngs_modulus": (1e5, 1e9, "Pa", "Young's moduli of snow"),
        "softening": (0.0, 10.0, "", "weak-layer softening coefficients"),
    }
    for name, (lo, hi, unit, what) in ranges.items():
        v = scalar(name)
        if v is not None and not lo <= v <= hi:
            text = f"{name_of(name)} = {fmt(v)}: outside [{lo:g}, {hi:g}] {unit}, {what}"
            notes.append(text.rstrip())
    psi, phi = scalar("slope_deg"), scalar("friction_deg")
    if params.slope_profile is not None:
        try:
            psi = float(np.max(np.asarray(params.slope_profile, dtype=float)))
        except (TypeError, ValueError):
            psi = None
    if psi is not None and phi is not None and psi <= phi:
        notes.append(
            f"{name_of('slope_deg')} = {fmt(psi)}: at or below {name_of('friction_deg')} = "
            f"{fmt(phi)}, friction holds a released slab, so a crack does not run away as a "
            "shear crack (the paper's mechanism needs slope_deg > friction_deg); the "
            "theory values that assume it are reported as null"
        )
    if setup.controlled:
        default = PSTParams()
        ignored = [
            k
            for k in ("tau_peak", "steady_length", "strength_gradient", "softening")
            if (given is None or k in given) and scalar(k) != getattr(default, k)
        ]
        if params.strength_profile is not None:
            ignored.append("strength_profile")
        if ignored:
            notes.append(
                f"{name_of('controlled', 'setup')} = true: the weak layer is unbreakable, so "
                + ", ".join(name_of(k) for k in ignored)
                + (" is" if len(ignored) == 1 else " are")
                + " ignored"
            )
        v = scalar("saw_speed")
        if v is not None and v * setup.duration > setup.length:
            notes.append(
                f"{name_of('duration', 'setup')} = {fmt(setup.duration)}: the controlled cut "
                f"({name_of('saw_speed')} = {fmt(v)} m/s) leaves the {setup.length:g} m domain at "
                f"t = {setup.length / v:.3g} s; the tension gradient is then reported as null"
            )
    else:
        v = scalar("saw_speed")
        c = float(np.min(np.asarray(theory.shear_wave_speed(params), dtype=float)))
        if v is not None and v > 0.5 * c:
            notes.append(
                f"{name_of('saw_speed')} = {fmt(v)}: a saw at {v / c:.2g} c_s in a "
                "self-propagating PST (the paper saws at 6 m/s)"
            )
    sides = ("length", "width") if setup.dim == 2 and setup.lateral == "free" else ("length",)
    for name, v, grid in partial_cells(setup, sides):
        notes.append(
            f"{name_of(name, 'setup')} = {fmt(v)}: not a whole number of cells of "
            f"dx = {fmt(setup.dx)}; the strip is {grid:.6g} m"
            + (" long" if name == "length" else " wide")
        )
    if setup.cfl > 0.9:
        notes.append(
            f"{name_of('cfl', 'setup')} = {fmt(setup.cfl)}: close to the stability limit 1"
        )
    notes += _unused_slab_settings(params, setup, given, name_of)
    return notes


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
    params: PSTParams, setup: PSTSetup, given: set[str] | None, name_of: Any
) -> list[str]:
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
            name_of(k)
            for k in ("mcc_m", "mcc_beta", "mcc_xi", "slab_fracture_energy", *field_keys)
            if changed(k)
        ]
        if unused:
            return [
                f"{name_of('tensile_strength')} = inf (an elastic slab): "
                + ", ".join(unused)
                + (" is" if len(unused) == 1 else " are")
                + " ignored (they set the plastic slab's law)"
            ]
        return []
    if setup.slab_fracture == "crack_band":
        return []
    unused = [name_of(k) for k in field_keys if changed(k)]
    if setup.seed != default_setup.seed:
        unused.append(name_of("seed", "setup"))
    if not unused:
        return []
    return [
        f"{name_of('slab_fracture', 'setup')} = {setup.slab_fracture!r}: "
        + ", ".join(unused)
        + (" is" if len(unused) == 1 else " are")
        + ' ignored (they set the seeded strength field of slab_fracture = "crack_band")'
    ]


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
            shown = {
                type(None): "None",
                PSTParams: "damjax.PSTParams",
                "Layout": "a Layout (damjax.make_layout)",
                "SlopeLayout": "a SlopeLayout (damjax.core.model.make_slope_layout)",
            }
            names = " or ".join(
                shown.get(c, shown.get(c.__name__, f"damjax.{c.__name__}")) for c in classes
            )
            raise TypeError(f"{where}: {name} must be {names}, got {type(value).__name__}")


def validate(
    params: PSTParams, setup: PSTSetup, *, warn_dubious: bool = True, batch: bool = False
) -> None:
    """Raise ValueError (one line per problem) for invalid input; warn on dubious input
    (`dubious`, as `DubiousInputWarning`; ``warn_dubious=False``: only the resolution
    warning). ``batch``: batched fields allowed (`damjax.sweep`).

    Traced parameters (inside `jax.grad` / `jax.vmap`) are checked through the concrete
    values JAX holds behind them (a batch under `jax.vmap`); inside `jax.jit` there are
    none, so only the setup is checked here and the runtime guards of the run remain.
    """
    if is_traced(params):
        concrete = concrete_tree(params)
        if concrete is None:
            problems = setup_problems(setup)
            if problems:
                raise ValueError("\n".join(problems))
            return
        params, batch = concrete, True
    if not batch:
        problems = single_run_problems(params)
        if problems:
            raise ValueError("\n".join(problems))
    problems = setup_problems(setup)
    if not problems:
        problems = param_problems(params, setup)
    else:
        problems += param_problems(params, None)
    if problems:
        raise ValueError("\n".join(problems))
    lam = _as_min(theory.elastic_length(params))
    if setup.dx > lam / 5:
        warnings.warn(
            f"dx = {setup.dx} m is larger than Lambda/5 = {lam / 5:.3g} m: the crack-tip stress "
            "concentration is under-resolved; results may depend on dx",
            stacklevel=3,
        )
    if warn_dubious:
        for note in dubious(params, setup):
            warnings.warn(note, DubiousInputWarning, stacklevel=3)


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


def check_problem_size(
    n_particles: int, n_nodes: int, n_chunks: int, itemsize: int, fields: str
) -> None:
    """Raise ValueError when a run cannot fit in this machine's memory.

    A generous estimate (~64 particle-sized rows in a step plus 8 per stored snapshot) is
    compared with the total physical memory, so that an absurd size (a 1e9 m PST) fails at
    once with a message naming the fields, not with an allocation traceback from numpy or
    XLA. `fields`: the inputs that set the size, e.g. "length (--length) and dx (--dx)".
    """
    total = _physical_memory()
    if total is None:
        return
    need = itemsize * (
        n_particles * (_ROWS_PER_PARTICLE + _SNAPSHOT_ROWS * max(1, n_chunks)) + 8 * n_nodes
    )
    if need > total:
        raise ValueError(
            f"{fields} give {n_particles:.3g} particles on {n_nodes:.3g} grid nodes over "
            f"{n_chunks} chunks: ~{need / 2**30:.3g} GiB, more than this machine's "
            f"{total / 2**30:.3g} GiB of memory; use a coarser dx, a smaller domain, a "
            "shorter duration or larger chunk_steps"
        )


def is_plastic(params: PSTParams) -> bool | None:
    """Whether some tensile strength is finite (an MCC slab); None for traced values."""
    try:
        return bool(np.any(np.isfinite(np.asarray(params.tensile_strength, dtype=float))))
    except (TypeError, jax.errors.TracerArrayConversionError):
        return None


def slope_problems(
    params: PSTParams, setup: SlopeSetup, slope: Any, tau: Any, fall: Any = 0.0
) -> list[str]:
    """One line per invalid input of a slope run (`damjax.simulate_slope`): the parameters,
    the setup, and the slope angle [deg], strength [Pa] and fall-line direction [deg]
    fields (scalars or (nx, ny) arrays at the cell centres)."""
    out = [p for p in param_problems(params) if "slope_deg" not in p or slope is None]
    setup_out = field_problems(
        setup,
        ("length", "width", "dx", "duration", "cfl", "particles_per_cell", "chunk_steps", "seed"),
        ("dtype", "p0_rule", "mcc_invariants", "slab_fracture", "accumulation"),
        with_flags=False,
    )
    if setup_out:  # the checks below need a valid grid
        return out + setup_out
    for name in ("length", "width"):
        if getattr(setup, name) / setup.dx < MIN_CELLS:
            out.append(
                f"{name} = {getattr(setup, name)!r}: must be at least {MIN_CELLS} cells of "
                f"dx = {setup.dx!r}, i.e. >= {MIN_CELLS * setup.dx:.4g} m"
            )
    if out:
        return out
    try:
        x0, y0 = (float(c) for c in setup.start)
    except (TypeError, ValueError):
        return [f"start = {setup.start!r}: must be a point (x, y) [m]"]
    x0, y0 = setup.start
    if not (0 <= x0 <= setup.length and 0 <= y0 <= setup.width):
        out.append(
            f"start = {setup.start!r}: must lie in [0, {setup.length}] x [0, {setup.width}] m"
        )
    lam = float(theory.elastic_length(params)) if not out else 1.0
    if not out and setup.dx > lam / 2:
        out.append(f"dx = {setup.dx!r}: must be at most Lambda/2 = {lam / 2:.4g} m")
    cells = (int(round(setup.length / setup.dx)), int(round(setup.width / setup.dx)))
    for name, arr, lo, hi in (
        ("slope_deg", slope, 0.0, 90.0),
        ("tau_peak", tau, 0.0, math.inf),
        ("fall_deg", fall, -math.inf, math.inf),
    ):
        if arr is None:
            continue
        a = np.asarray(arr, dtype=float)
        if a.ndim == 2 and a.shape != cells:
            out.append(
                f"{name} field: shape {a.shape} must be (nx, ny) = {cells}, the cells of "
                f"length {setup.length} m x width {setup.width} m at dx {setup.dx} m"
            )
        elif a.ndim not in (0, 2) or not np.all(
            np.isfinite(a) | (np.isinf(a) & (name == "tau_peak"))
        ):
            out.append(f"{name} field: must be a finite scalar or a 2D array (nx, ny)")
        elif np.any(a <= lo) or np.any(a >= hi):
            out.append(f"{name} field: values must be in ({lo}, {hi})")
    return out


# --------------------------------------------------------------------------- snow cover
# The snow-cover and weak-layer-load inputs of a slope run (`damjax.simulate_slope`'s
# thickness, cover, stability, wl_friction and domain maps; 2026-11-27), kept together so
# that they can join the parameter table: name, valid range, unit.
SNOW_MAP_RULES: dict[str, tuple[Any, str]] = {
    "thickness": (lambda a: np.isfinite(a) & (a > 0), "(0, inf) m"),
    "stability": (lambda a: np.isfinite(a) & (a > 0), "(0, inf)"),
    "wl_friction": (lambda a: np.isfinite(a) & (a >= 0), "[0, inf)"),
}


def snow_problems(
    setup: SlopeSetup,
    thickness: Any = None,
    cover: Any = None,
    stability: Any = None,
    wl_friction: Any = None,
    domain: Any = None,
) -> list[str]:
    """One line per invalid snow-cover input of a slope run: ``thickness`` [m] and
    ``stability`` [-] (maps (nx, ny) at the cell centres, or scalars), ``wl_friction``
    [-], and the bool maps ``cover`` and ``domain``."""
    cells = (int(round(setup.length / setup.dx)), int(round(setup.width / setup.dx)))
    out = []
    for name, m in (("cover", cover), ("domain", domain)):
        if m is None:
            continue
        a = np.asarray(m)
        if a.shape != cells or a.dtype != bool:
            out.append(
                f"{name}: must be a bool map (nx, ny) = {cells}, the cells of length "
                f"{setup.length} m x width {setup.width} m at dx {setup.dx} m (got "
                f"{a.dtype} {a.shape})"
            )
        elif name == "cover" and not a.any():
            out.append("cover: no snow-covered cell (every cell is False)")
    for name, m in (
        ("thickness", thickness),
        ("stability", stability),
        ("wl_friction", wl_friction),
    ):
        if m is None:
            continue
        ok, valid = SNOW_MAP_RULES[name]
        try:
            a = np.asarray(m, dtype=float)
        except (TypeError, ValueError):
            out.append(f"{name}: must be a number or a map (nx, ny) of numbers")
            continue
        if a.ndim == 2 and a.shape != cells:
            out.append(f"{name} field: shape {a.shape} must be (nx, ny) = {cells}")
            continue
        if a.ndim not in (0, 2):
            out.append(f"{name}: must be a scalar or a 2D array (nx, ny)")
            continue
        bad = ~np.asarray(ok(a))
        if np.any(bad):
            first = float(a[bad].ravel()[0])
            out.append(
                f"{name} field: {first!r}: must be in {valid} on every cell (cells without "
                "snow too: particles near them interpolate; fill them, e.g. from a neighbour)"
            )
    return out
