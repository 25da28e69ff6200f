"""The physical parameters and the static setups of the simulations, declared as one table.

`PSTParams` holds every physical quantity of the slab and the weak layer as a pytree leaf,
so `jax.grad` and `jax.vmap` act on it directly and a new parameter value never triggers
recompilation; one class serves the PST (`damjax.pst`) and the slope (`damjax.slope`).
`PSTSetup` and `SlopeSetup` hold the numerics that fix array shapes and the program
(length, dx, particles per cell, ...): they are hashable and static.

Every field is declared once, beside its default (`param`, `setting`): its unit, its valid
range, its kind (what a scenario file and the command line accept), its meaning, whether
``damjax pst`` has a flag for it, and for some a plausible range (a valid value outside it
is warned before the run, with a hint where a unit mix-up brings it inside: ``4 Pa: did
you mean 4 MPa = 4e6 Pa?``). `specs` reads the declarations back as `Spec` objects; the
checks (`damjax.validation`), the scenario files (`damjax.scenario`), the command line
(`damjax.cli`), the reference pages (docs/hooks.py), the run-time guards of traced values
(`damjax.core.model`) and the ensemble's CF units all read them. Adding a parameter is one
declaration here plus its physics.

The checks themselves (one structured problem per invalid value, naming the field, the
value and the valid range) are `damjax.validation`, run once at the edge by
`damjax.pst.prepare` / `damjax.slope.simulation.prepare`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import equinox as eqx
import jax
import numpy as np

from damjax._tracing import dtype_name
from damjax.constants import (
    ACCUMULATIONS,
    DTYPES,
    LATERAL_CONDITIONS,
    MCC_INVARIANTS,
    P0_RULES,
    SLAB_FRACTURE_MODELS,
)

# --------------------------------------------------------------------------- the table


def _bound(x: float) -> str:
    """A range bound as the messages write it: inf, 10^7, 2^31 - 1, 0.5."""
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 2**31 - 1:
        return "2^31 - 1"
    if x >= 1e5 and math.log10(x).is_integer():
        return f"10^{int(math.log10(x))}"
    return f"{x:g}"


def number_text(x: float) -> str:
    """A number as a hint writes it: 4e6, 250, 34.4."""
    text = f"{x:.3g}"
    if "e" in text and 1e-3 <= abs(x) < 1e5:  # 4000, not 4e3
        text = f"{x:.0f}"
    elif "e" in text:
        mantissa, exp = text.split("e")
        text = f"{mantissa}e{int(exp)}"
    return text


@dataclasses.dataclass(frozen=True)
class Range:
    """An interval of real numbers; ``lo_in`` / ``hi_in``: whether its ends belong to it.

    `holds` takes floats and JAX arrays alike (comparisons and ``&`` only), and NaN is
    never inside."""

    lo: float
    hi: float
    lo_in: bool = False
    hi_in: bool = False

    def holds(self, v: Any) -> Any:
        """Whether ``v`` (a float or an array, elementwise) lies in the interval."""
        above = (v >= self.lo) if self.lo_in else (v > self.lo)
        below = (v <= self.hi) if self.hi_in else (v < self.hi)
        return above & below

    def __str__(self) -> str:
        left, right = "[" if self.lo_in else "(", "]" if self.hi_in else ")"
        return f"{left}{_bound(self.lo)}, {_bound(self.hi)}{right}"


INF = math.inf
POSITIVE = Range(0.0, INF)  # (0, inf)
POSITIVE_OR_INF = Range(0.0, INF, hi_in=True)  # (0, inf]: an infinite strength is valid
NONNEGATIVE = Range(0.0, INF, lo_in=True)  # [0, inf)
ANGLE = Range(0.0, 90.0)  # (0, 90) deg

# units a value may have been given in by mistake, and their factor to the field's unit
_UNIT_MIXUPS: dict[str, tuple[tuple[str, float], ...]] = {
    "Pa": (("kPa", 1e3), ("MPa", 1e6), ("GPa", 1e9)),
    "m": (("cm", 1e-2), ("mm", 1e-3)),
    "kg/m^3": (("g/cm^3", 1e3),),
    "deg": (("rad", 180.0 / math.pi),),
}
# CF (udunits) spelling of the units, for NetCDF attributes
_CF_UNITS = {"": "1", "deg": "degree", "Pa/m": "Pa m-1", "kg/m^3": "kg m-3", "J/m^2": "J m-2"}
_KEY = "damjax"  # the field-metadata key of a declaration


@dataclasses.dataclass(frozen=True)
class Spec:
    """What is declared about one field of `PSTParams`, `PSTSetup` or `SlopeSetup`.

    Attributes:
        unit: SI unit ("" for a dimensionless number).
        doc: meaning, one line (the symbol of the papers included).
        kind: "float", "int", "bool", "choice" (one of ``valid``), "profile" (an array of
            >= 2 values along the PST, each in ``valid``), "point" (two numbers) or "mask"
            (a slope run's (nx, ny) bool map of cells).
        valid: the valid range (a `Range`) or the allowed values (a tuple).
        plausible: values a snow slab has (a `Range`); a valid value outside it is
            warned, naming ``plausible_why``.
        plausible_why: what the plausible range is, with its source.
        cli: whether ``damjax pst`` has the flag ``--NAME`` (dashes for underscores).
        optional: None is allowed and means this (the model's default), else "".
        notes: more on the field (reference pages and ``help()``).
        pst_only: meaningless on a slope (a PST's strength or slope profile).
        name: the field's name (set by `specs`).
    """

    unit: str
    doc: str
    kind: str = "float"
    valid: Range | tuple[Any, ...] | None = None
    plausible: Range | None = None
    plausible_why: str = ""
    cli: bool = True
    optional: str = ""
    notes: str = ""
    pst_only: bool = False
    name: str = ""

    @property
    def flag(self) -> str:
        """The command-line flag (``--slope-deg``), whether ``damjax pst`` has it or not."""
        return "--" + self.name.replace("_", "-")

    @property
    def label(self) -> str:
        """The field as the API and the command line name it: ``slope_deg (--slope-deg)``,
        or the bare name where ``damjax pst`` has no flag for it."""
        return f"{self.name} ({self.flag})" if self.cli else self.name

    @property
    def valid_text(self) -> str:
        """The valid range with the unit, ``(0, inf) Pa``, or the values, ``{free,
        constrained}``."""
        if isinstance(self.valid, Range):
            return f"{self.valid} {self.unit}".rstrip()
        if self.valid is None:
            return ""
        return "{" + ", ".join(str(v) for v in self.valid) + "}"

    @property
    def cf_unit(self) -> str:
        """The unit as CF conventions (udunits) write it: ``kg m-3``, ``degree``, ``1``."""
        return _CF_UNITS.get(self.unit, self.unit)

    def unit_hint(self, value: float) -> str:
        """``did you mean 4 MPa = 4e6 Pa?`` where the value, read in a related unit, is
        plausible; "" where none makes it so."""
        if self.plausible is None or not math.isfinite(value):
            return ""
        for unit, factor in _UNIT_MIXUPS.get(self.unit, ()):
            if self.plausible.holds(value * factor):
                return (
                    f"did you mean {number_text(value)} {unit} = "
                    f"{number_text(value * factor)} {self.unit}?"
                )
        return ""


def param(default: Any, unit: str, doc: str, valid: Any, **more: Any) -> Any:
    """A field of `PSTParams`: its default and its declaration (`Spec`)."""
    return dataclasses.field(default=default, metadata={_KEY: Spec(unit, doc, valid=valid, **more)})


def setting(spec: Spec, default: Any, **changes: Any) -> Any:
    """A field of a setup: its default and its declaration (a shared `Spec`, with
    ``changes``)."""
    return dataclasses.field(default=default, metadata={_KEY: dataclasses.replace(spec, **changes)})


@functools.cache
def specs(cls: type) -> dict[str, Spec]:
    """The declarations of the fields of `PSTParams`, `PSTSetup` or `SlopeSetup` (or of a
    subclass: a field it declares again without one keeps its base's), by name."""
    out = {}
    for f in dataclasses.fields(cls):
        declared = [
            vars(base)["__dataclass_fields__"][f.name].metadata.get(_KEY)
            for base in cls.__mro__
            if f.name in vars(base).get("__dataclass_fields__", {})
        ]
        spec = next(s for s in [f.metadata.get(_KEY), *declared] if s is not None)
        out[f.name] = dataclasses.replace(spec, name=f.name)
    return out


def spec_of(name: str, setup_cls: type | None = None) -> Spec:
    """The declaration of a field of `PSTParams` or of ``setup_cls`` (default `PSTSetup`):
    no name is in both."""
    table = specs(PSTParams)
    if name in table:
        return table[name]
    return specs(setup_cls or PSTSetup)[name]


def _document(cls: type) -> None:
    """Append the declarations to the class docstring (``help()``, ``inspect.getdoc``)."""
    lines = ["", "    Attributes:"]
    for name, s in specs(cls).items():
        unit = f" [{s.unit}]" if s.unit else ""
        valid = f", in {s.valid_text}" if s.valid is not None and s.kind != "bool" else ""
        none = f" None: {s.optional}." if s.optional else ""
        notes = f" {s.notes}" if s.notes else ""
        lines.append(f"        {name}: {s.doc}{unit}{valid}.{none}{notes}")
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n" + "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- physics


class PSTParams(eqx.Module):
    """Slab and weak-layer parameters of a PST or a slope (paper baseline by default).

    Every field is a differentiable leaf (a float or a JAX scalar; batched leaves are
    what `damjax.sweep` vmaps over). Units, valid ranges and meanings: below, and the
    reference page of the parameters (both generated from the declarations).
    """

    # plausible ranges: slab avalanches release on 30-50 deg slopes, from slabs of ~0.1
    # to ~2 m (Schweizer, Jamieson and Schneebeli 2003, Rev. Geophys. 41, 1016); seasonal
    # snow is 50-550 kg/m^3 (Fierz et al. 2009, The International Classification for
    # Seasonal Snow on the Ground, UNESCO-IHP); E(rho) of dry snow runs from ~0.1 MPa to
    # ~1 GPa over 100-450 kg/m^3 (Scapozza 2004; Gerling et al. 2017, GRL 44; Bergfeld et
    # al. 2023, NHESS: `damjax.snow_profiles.youngs_modulus`)
    slope_deg: Any = param(
        35.0,
        "deg",
        "slope angle psi",
        ANGLE,
        plausible=Range(20.0, 60.0, True, True),
        plausible_why="slab avalanches release on 30-50 deg slopes",
    )
    thickness: Any = param(
        0.5,
        "m",
        "slab thickness h0",
        POSITIVE,
        plausible=Range(0.05, 5.0, True, True),
        plausible_why="slab thicknesses of dry-snow slab avalanches",
    )
    density: Any = param(
        250.0,
        "kg/m^3",
        "slab density rho",
        POSITIVE,
        plausible=Range(50.0, 550.0, True, True),
        plausible_why="the density of seasonal snow",
    )
    youngs_modulus: Any = param(
        4.0e6,
        "Pa",
        "slab Young's modulus E",
        POSITIVE,
        plausible=Range(1e5, 1e9, True, True),
        plausible_why="Young's moduli of snow",
    )
    poisson: Any = param(0.3, "", "slab Poisson ratio nu", Range(0.0, 0.5))
    friction_deg: Any = param(
        27.0, "deg", "residual friction angle phi of the broken weak layer", ANGLE
    )
    wl_shear_modulus: Any = param(2.0e5, "Pa", "weak-layer shear modulus G_wl", POSITIVE)
    wl_thickness: Any = param(
        0.04,
        "m",
        "weak-layer thickness D_wl",
        POSITIVE,
        notes="K_wl = G_wl / D_wl [Pa/m].",
        plausible=Range(1e-3, 0.5, True, True),
        plausible_why="weak layers are mm (surface hoar) to decimetres (depth hoar) thick",
    )
    tau_peak: Any = param(
        1000.0,
        "Pa",
        "weak-layer peak shear strength tau_p on [0, L_ss] (inf: unbreakable)",
        POSITIVE_OR_INF,
        plausible=Range(20.0, 2e4, True, True),
        plausible_why="weak-layer shear strengths (shear-frame tests: a few hundred Pa to a "
        "few kPa)",
    )
    steady_length: Any = param(
        20.0,
        "m",
        "steady-state length L_ss over which tau_p is constant",
        NONNEGATIVE,
        pst_only=True,
    )
    strength_gradient: Any = param(
        500.0, "Pa/m", "shear strength gradient theta beyond L_ss", NONNEGATIVE, pst_only=True
    )
    softening: Any = param(
        0.0,
        "",
        "softening coefficient delta (u_r = u_c (1 + delta); 0 is brittle)",
        NONNEGATIVE,
        plausible=Range(0.0, 10.0, True, True),
        plausible_why="weak-layer softening coefficients",
    )
    tensile_strength: Any = param(
        math.inf,
        "Pa",
        "slab tensile strength sigma_t of the MCC surface (inf: elastic slab); the default "
        "slab yields in uniaxial tension at 0.53 sigma_t (docs/model/slab.md)",
        POSITIVE_OR_INF,
        # no upper bound: a very large sigma_t is how a slab is kept elastic on purpose
        plausible=Range(50.0, math.inf, True, True),
        plausible_why="tensile strengths of snow slab layers (in-situ tests: hundreds of Pa "
        "to tens of kPa)",
    )
    saw_speed: Any = param(
        6.0,
        "m/s",
        "speed of the saw (self-propagating PST) or of the imposed cut (controlled run)",
        POSITIVE,
    )
    mcc_m: Any = param(0.3, "", "slope M of the critical state line of the MCC slab", POSITIVE)
    mcc_beta: Any = param(
        1.2, "", "cohesion ratio beta of the MCC surface (tension/compression)", POSITIVE
    )
    mcc_xi: Any = param(
        0.0,
        "",
        "softening coefficient xi of p0 with volumetric plastic strain (SinhExpl law, "
        "`damjax.materials.mcc`; 0 is perfect plasticity)",
        NONNEGATIVE,
    )
    slab_fracture_energy: Any = param(
        None,
        "J/m^2",
        "fracture energy G_f of the slab's tensile fracture",
        POSITIVE_OR_INF,
        optional="the slab model's own (`PSTSetup.slab_fracture`): 0.12 J/m^2 for "
        '"crack_band", none (perfectly plastic) for "paper"',
        notes='With "crack_band", p0 decays as exp(-w / w_c) with the opening w [m] of '
        "the band (summed across it over a window fixed in metres) and w_c = G_f / "
        "sigma_y, so that a fracture dissipates G_f per unit crack area on any grid "
        '(`damjax.materials.slab_fracture`). With "paper", a given G_f softens over one '
        "cell (w = opening strain x dx), as in earlier versions: its fractures stay "
        "grid-dependent.",
    )
    slab_strength_cov: Any = param(
        0.2,
        "",
        "coefficient of variation of the slab's tensile strength (0: homogeneous)",
        Range(0.0, 1.0, True, True),
        notes="sigma_t is a seeded log-normal random field with mean tensile_strength "
        '("crack_band" only; `PSTSetup.seed`); the default 0.2 is from Kronholm and '
        "Schweizer 2003 (`damjax.materials.slab_fracture`).",
    )
    slab_strength_length: Any = param(
        1.0,
        "m",
        "correlation length of the slab's tensile-strength field",
        Range(0.2, 10.0, True, True),
        notes="The default 1 m is from Kronholm, Schneebeli and Schweizer 2004.",
    )
    strength_profile: Any = param(
        None,
        "Pa",
        "weak-layer strength tau_p at m >= 2 equally spaced points spanning [0, length] "
        "of the PST, linearly interpolated at the particles",
        POSITIVE_OR_INF,
        kind="profile",
        optional="tau_peak, steady_length and strength_gradient",
        notes="A differentiable array field (see `damjax.fields`); on the command line "
        "`--strength-profile FILE.csv` reads it from a CSV.",
        pst_only=True,
    )
    slope_profile: Any = param(
        None,
        "deg",
        "slope angle psi at m >= 2 equally spaced points spanning [0, length] of the "
        "PST (e.g. a convex roll, `damjax.terrain.pst_slope_angle`), linearly "
        "interpolated at the particles",
        ANGLE,
        kind="profile",
        cli=False,
        optional="slope_deg",
        notes="Gravity's slope-parallel and normal parts (hence the friction cap) follow "
        "the local angle. A differentiable array field.",
        pst_only=True,
    )


# the fall-line direction of a slope run (`damjax.simulate_slope`'s ``fall_deg``): its
# maps of slope_deg and tau_peak are checked against the declarations of those parameters
FALL_DEG_SPEC = Spec(
    "deg", "fall-line direction relative to -x", valid=Range(-INF, INF), name="fall_deg"
)
# a slope run's map of slope angles: flat cells (0 deg) are terrain too (a valley floor, a
# bench, a lake), where the slab lies but cannot slide; the parameter slope_deg stays (0, 90)
SLOPE_MAP_SPEC = Spec(
    "deg",
    "local slope angle psi of a cell (0: flat ground, where the slab cannot slide)",
    valid=Range(0.0, 90.0, lo_in=True),
    name="slope_deg",
)
# the snow cover and the weak layer's own load on a slope (`damjax.simulate_slope`'s
# thickness, stability, wl_friction, cover and domain; 2026-11-27): a thickness map is
# checked against the parameter thickness, the others against these
STABILITY_SPEC = Spec(
    "",
    "stability ratio S = tau_p / tau_g of the weak layer under its own slab, tau_g = rho g "
    "h0 sin(psi) at each particle (tau_p follows the particle's own load)",
    valid=POSITIVE,
    name="stability",
)
WL_FRICTION_SPEC = Spec(
    "",
    "friction coefficient mu of the weak layer's strength, tau_p = tau_peak + mu rho g h0 "
    "cos(psi) (tau_peak the cohesion)",
    valid=NONNEGATIVE,
    name="wl_friction",
)
COVER_SPEC = Spec(
    "",
    "the snow-covered cells: only they hold particles (a cell without snow costs no "
    "particle work and is a free edge)",
    kind="mask",
    name="cover",
)
DOMAIN_SPEC = Spec(
    "",
    "the cells the run may release (a release polygon's buffer within the DEM's data): "
    "its edge, with the rectangle's, is where a release counts as bounded by the domain",
    kind="mask",
    name="domain",
)


def map_specs() -> dict[str, Spec]:
    """The declarations the maps of a slope run are checked against: those of the
    parameters tau_peak and thickness, the slope map's (flat cells too), the fall-line
    direction's, the stability ratio's and the weak layer's friction coefficient's."""
    table = specs(PSTParams)
    return {
        "slope_deg": SLOPE_MAP_SPEC,
        "tau_peak": table["tau_peak"],
        "fall_deg": FALL_DEG_SPEC,
        "thickness": table["thickness"],
        "stability": STABILITY_SPEC,
        "wl_friction": WL_FRICTION_SPEC,
    }


# PSTParams fields that are arrays over x (a batch of them has shape (B, m))
PROFILE_FIELDS = tuple(n for n, s in specs(PSTParams).items() if s.kind == "profile")


def is_plastic(params: PSTParams) -> bool | None:
    """Whether some tensile strength is finite (an MCC slab); None for traced values."""
    try:
        return bool(np.any(np.isfinite(np.asarray(params.tensile_strength, dtype=float))))
    except (TypeError, jax.errors.TracerArrayConversionError):
        return None


# --------------------------------------------------------------------------- numerics

# the settings of both setups, declared once (each setup adds its default and wording)
_LENGTH = Spec("m", "extent", valid=POSITIVE)
_WIDTH = Spec("m", "width", valid=POSITIVE)
_DX = Spec("m", "grid spacing", valid=POSITIVE)
_DURATION = Spec("s", "simulated time", valid=POSITIVE)
_CFL = Spec("", "Courant number C in dt = C dx / c_p", valid=Range(0.0, 1.0))
_PPC = Spec("", "particles per cell and per dimension", kind="int", valid=Range(1, 64, True, True))
_DTYPE = Spec(
    "",
    "floating-point type of the run",
    kind="choice",
    valid=DTYPES,
    notes="A string or a numpy / JAX dtype (``jnp.float64``; stored as its name). "
    "float64 switches JAX's 64-bit mode on for the whole process, with a warning; "
    "traced runs need it switched on beforehand.",
)
# a chunk is one compiled scan: 10^7 steps is hours of run between snapshots
_CHUNK = Spec(
    "",
    "time steps per jitted chunk (progress, snapshots, checkpoints); the run's step count "
    "is rounded up to whole chunks, so it also sets dt",
    kind="int",
    valid=Range(1, 1e7, True, True),
    notes="At most the run's step count; the step count is rounded up to a multiple of "
    "it, dt shrinks accordingly: up to chunk_steps - 1 more steps than the stable dt "
    "needs (1050 needed, chunks of 1000: 2000 steps), and results that differ slightly "
    "with it. Keep it when comparing runs.",
)
_P0_RULE = Spec(
    "",
    'how p0 follows from the tensile strength: "paper" (Eq. 6 as printed; uniaxial '
    'tension yields at 0.534 sigma_t with the "3d" invariants) or "uniaxial" (yields at '
    "sigma_t)",
    kind="choice",
    valid=P0_RULES,
    cli=False,
)
_INVARIANTS = Spec(
    "",
    'stress invariants of the MCC yield function: "3d" (p = -tr/3 and the 3D von Mises q '
    'of the plane-stress tensor, sigma_zz = 0) or "plane" (invariants of the 2D in-plane '
    "tensor; `damjax.materials.mcc`)",
    kind="choice",
    valid=MCC_INVARIANTS,
    cli=False,
)
_SLAB_FRACTURE = Spec(
    "",
    'slab tensile fracture model (`damjax.materials.slab_fracture`): "paper" (the '
    "paper's homogeneous, perfectly plastic slab, whose arrests reproduce the paper's "
    'and converge with dx) or "crack_band" (a fracture energy G_f and a seeded random '
    "tensile-strength field; its measured status is in docs/model/slab.md)",
    kind="choice",
    valid=SLAB_FRACTURE_MODELS,
)
_SEED = Spec(
    "",
    'picks the tensile-strength field ("crack_band"; the same field on every dx)',
    kind="int",
    valid=Range(0, 2**31 - 1, True, True),
)
_ACCUMULATION = Spec(
    "",
    'how the particle-to-grid sums are added: "auto" ("float" on a CPU, "fixed" on a GPU '
    'or any other backend; deterministic on each), "fixed" (fixed-point integers: '
    "deterministic on every backend and independent of the particles' order) or "
    '"float" (plain float scatter-adds: on a GPU their order, hence the last bits, '
    "varies between identical runs)",
    kind="choice",
    valid=ACCUMULATIONS,
    cli=False,
    notes="`damjax.core.transfer.p2g_channels`, `damjax.core.transfer."
    "resolve_accumulation`; a fixed-point contribution is rounded to 4.4e-16 N of the "
    "largest, N = 3^dim contributions per particle x particles, far below float32's "
    "6e-8.",
)


@dataclasses.dataclass(frozen=True)
class PSTSetup:
    """Static numerics of a PST run (they fix shapes and the compiled program).

    Units, valid ranges and meanings: below, and the reference page of the setups (both
    generated from the declarations).
    """

    length: float = setting(_LENGTH, 100.0, doc="PST length L")
    dx: float = setting(_DX, 0.02, notes="At most Lambda/2 (a warning above Lambda/5).")
    duration: float = setting(_DURATION, 3.0)
    controlled: bool = setting(
        Spec(
            "",
            "if true, the weak layer is unbreakable (tau_p = inf, the strength fields of "
            "`PSTParams` are ignored) and the cut advances at saw_speed for the whole run "
            "(paper Sect. 3.1)",
            kind="bool",
            valid=(True, False),
        ),
        False,
    )
    lateral: str = setting(
        Spec(
            "",
            'lateral condition of the width-uniform strip: "free" (sigma_yy = 0, bar '
            'modulus E, free edges of the paper\'s 30 cm wide PST) or "constrained" '
            "(eps_yy = 0, modulus E' = E / (1 - nu^2), periodic in y)",
            kind="choice",
            valid=LATERAL_CONDITIONS,
        ),
        "free",
    )
    cfl: float = setting(_CFL, 0.5)
    particles_per_cell: int = setting(_PPC, 2)
    dtype: str = setting(_DTYPE, "float32")
    chunk_steps: int = setting(_CHUNK, 1000)
    dim: int = setting(
        Spec(
            "",
            "1 for the width-uniform strip, 2 to run the 2D step on a strip",
            kind="int",
            valid=(1, 2),
        ),
        1,
    )
    width: float = setting(_WIDTH, 0.3, doc="strip width for dim = 2 with free edges")
    p0_rule: str = setting(_P0_RULE, "paper")
    mcc_invariants: str = setting(_INVARIANTS, "3d")
    slab_fracture: str = setting(_SLAB_FRACTURE, "paper")
    seed: int = setting(_SEED, 0)
    accumulation: str = setting(_ACCUMULATION, "auto")

    def __post_init__(self) -> None:
        _normalise_dtype(self)


def _normalise_dtype(setup: Any) -> None:
    """A setup's dtype as its canonical name: "float64", jnp.float64, np.float64 and
    np.dtype("float64") are one setting (and one compiled program). Anything else is
    kept as given, for validation to name."""
    name = dtype_name(setup.dtype) if not isinstance(setup.dtype, bool) else None
    if name is not None:
        object.__setattr__(setup, "dtype", name)


@dataclasses.dataclass(frozen=True)
class SlopeSetup:
    """Numerics and geometry of a slope-scale run.

    Units, valid ranges and meanings: below, and the reference page of the setups (both
    generated from the declarations).
    """

    length: float = setting(
        _LENGTH, 50.0, doc="down-slope extent of the release area along the surface", cli=False
    )
    width: float = setting(_WIDTH, 60.0, doc="cross-slope extent", cli=False)
    dx: float = setting(_DX, 0.2, cli=False)
    duration: float = setting(_DURATION, 2.0, cli=False)
    start: tuple[float, float] = setting(
        Spec(
            "m",
            "crack initiation point (x, y), x up-slope from the lower edge; inside the "
            "release area",
            kind="point",
            cli=False,
        ),
        (5.0, 30.0),
    )
    cfl: float = setting(_CFL, 0.5, cli=False)
    particles_per_cell: int = setting(_PPC, 2, cli=False)
    dtype: str = setting(_DTYPE, "float32", cli=False)
    chunk_steps: int = setting(
        _CHUNK, 100, doc="steps per jitted chunk (one snapshot per chunk)", cli=False
    )
    p0_rule: str = setting(_P0_RULE, "paper")
    mcc_invariants: str = setting(_INVARIANTS, "3d")
    slab_fracture: str = setting(
        _SLAB_FRACTURE,
        "paper",
        cli=False,
        notes='With "crack_band" the strength field is drawn over length x width; a '
        "30 m x 8 m slope on dx 0.125 m runs 1.4-1.7 x longer with it.",
    )
    seed: int = setting(_SEED, 0, cli=False)
    accumulation: str = setting(_ACCUMULATION, "auto")

    def __post_init__(self) -> None:
        _normalise_dtype(self)


def _unknown_keywords_named(cls: Any, shown: str) -> None:
    """Make ``cls(misspelt=...)`` a TypeError that names the field it probably meant
    (``PSTParams(poison=0.3)``: did you mean 'poisson'?) instead of the generated
    ``__init__``'s bare "unexpected keyword argument"."""
    import difflib

    init = cls.__init__
    names = [f.name for f in dataclasses.fields(cls)]

    @functools.wraps(init)
    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        for key in kwargs:
            if key not in names:
                close = difflib.get_close_matches(key, names, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else f" (fields: {names})"
                raise TypeError(f"{shown}: unknown field {key!r}{hint}")
        init(self, *args, **kwargs)

    cls.__init__ = __init__


for _cls in (PSTParams, PSTSetup, SlopeSetup):
    _unknown_keywords_named(_cls, _cls.__name__)
    _document(_cls)
