"""The differentiable physical parameters and the static setups of the simulations.

`SnowParams` (alias `PSTParams`, the name of the PST papers and of earlier versions) holds
every physical quantity of the slab and the weak layer as a pytree leaf, so `jax.grad`
and `jax.vmap` act on it directly and a new parameter value never triggers recompilation;
one class serves the PST (`damjax.pst`) and the slope (`damjax.slope`). `PSTSetup` and
`SlopeSetup` hold the numerics that fix array shapes and the program (length, dx,
particles per cell, ...): they are hashable and static.

Their validation (one line per problem, naming the field, the value and the valid range)
is `damjax.validation`, run once at the edge by `simulate_pst` / `simulate_slope`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import equinox as eqx

from damjax._tracing import dtype_name


class SnowParams(eqx.Module):
    """Slab and weak-layer parameters of a PST or a slope (paper baseline by default).

    Every field is a differentiable leaf (a float or a JAX scalar; batched leaves are
    what `damjax.sweep` vmaps over).

    Attributes:
        slope_deg: slope angle psi [deg], in (0, 90).
        thickness: slab thickness h0 [m].
        density: slab density rho [kg/m^3].
        youngs_modulus: slab Young's modulus E [Pa].
        poisson: slab Poisson ratio nu [-], in (0, 0.5).
        friction_deg: residual friction angle phi of the broken weak layer [deg].
        wl_shear_modulus: weak-layer shear modulus G_wl [Pa].
        wl_thickness: weak-layer thickness D_wl [m]; K_wl = G_wl / D_wl [Pa/m].
        tau_peak: weak-layer peak shear strength tau_p [Pa] on [0, L_ss] (inf: unbreakable).
        steady_length: steady-state length L_ss over which tau_p is constant [m].
        strength_gradient: shear strength gradient theta beyond L_ss [Pa/m].
        softening: softening coefficient delta [-]; u_r = u_c (1 + delta); 0 is brittle.
        tensile_strength: slab uniaxial tensile strength sigma_t [Pa]; inf: elastic slab.
        saw_speed: speed of the saw (self-propagating PST) or of the imposed cut
            (controlled run) [m/s].
        mcc_m: slope M of the critical state line of the Modified Cam Clay slab [-].
        mcc_beta: cohesion ratio beta of the MCC surface (tension/compression) [-].
        mcc_xi: softening coefficient xi of p0 with volumetric plastic strain [-]
            (SinhExpl law, `damjax.materials.mcc`); 0 is perfect plasticity.
        slab_fracture_energy: fracture energy G_f of the slab's tensile fracture [J/m^2],
            in (0, inf]. None (default): the slab model's own (`PSTSetup.slab_fracture`):
            0.12 J/m^2 for "crack_band" (`damjax.materials.slab_fracture`, from the
            fracture toughness of snow), none (perfectly plastic) for "paper". With
            "crack_band", p0 decays as exp(-w / w_c) with the opening w [m] of the band
            (summed across it over a window fixed in metres) and w_c = G_f / sigma_y, so
            that a fracture dissipates G_f per unit crack area on any grid. With "paper", a
            given G_f softens over one cell (w = opening strain x dx), as in earlier
            versions: its fractures stay grid-dependent.
        slab_strength_cov: coefficient of variation of the slab's tensile strength [-], in
            [0, 1] (0: homogeneous; default 0.2, Kronholm and Schweizer 2003; see
            `damjax.materials.slab_fracture`): sigma_t is a seeded log-normal random field
            with mean ``tensile_strength`` ("crack_band" only; `PSTSetup.seed`).
        slab_strength_length: correlation length of that field [m], in [0.2, 10]
            (default 1 m, Kronholm, Schneebeli and Schweizer 2004).
        strength_profile: optional weak-layer strength tau_p [Pa] at m >= 2 equally
            spaced points spanning [0, length] of the PST, linearly interpolated at the
            particles (a differentiable array field; see `damjax.fields`). None (default)
            uses tau_peak, steady_length and strength_gradient.
        slope_profile: optional slope angle psi [deg] at m >= 2 equally spaced points
            spanning [0, length] of the PST (e.g. a convex roll,
            `damjax.terrain.pst_slope_angle`), linearly interpolated at the particles:
            gravity's slope-parallel and normal parts (hence the friction cap) follow the
            local angle. A differentiable array field; None (default) uses slope_deg.
    """

    slope_deg: Any = 35.0
    thickness: Any = 0.5
    density: Any = 250.0
    youngs_modulus: Any = 4.0e6
    poisson: Any = 0.3
    friction_deg: Any = 27.0
    wl_shear_modulus: Any = 2.0e5
    wl_thickness: Any = 0.04
    tau_peak: Any = 1000.0
    steady_length: Any = 20.0
    strength_gradient: Any = 500.0
    softening: Any = 0.0
    tensile_strength: Any = math.inf
    saw_speed: Any = 6.0
    mcc_m: Any = 0.3
    mcc_beta: Any = 1.2
    mcc_xi: Any = 0.0
    slab_fracture_energy: Any = None
    slab_strength_cov: Any = 0.2
    slab_strength_length: Any = 1.0
    strength_profile: Any = None
    slope_profile: Any = None


# SnowParams fields that are arrays over x (a batch of them has shape (B, m))
PROFILE_FIELDS = ("strength_profile", "slope_profile")


@dataclasses.dataclass(frozen=True)
class PSTSetup:
    """Static numerics of a PST run (they fix shapes and the compiled program).

    Attributes:
        length: PST length L [m].
        dx: grid spacing [m]; must be below Lambda/2 (warns above Lambda/5).
        duration: simulated time [s].
        controlled: if True, the weak layer is unbreakable (tau_p = inf, the strength
            fields of `PSTParams` are ignored) and the cut advances at `saw_speed`
            for the whole run (paper Sect. 3.1).
        lateral: lateral condition of the width-uniform strip: "free" (sigma_yy = 0,
            bar modulus E, free edges of the paper's 30 cm wide PST; the default) or
            "constrained" (eps_yy = 0, modulus E' = E / (1 - nu^2), periodic in y).
        cfl: Courant number C in dt = C dx / c_p, in (0, 1).
        particles_per_cell: particles per cell and per dimension, in [1, 64].
        dtype: "float32" or "float64", as a string or a numpy / JAX dtype
            (``jnp.float64``; stored as its name). float64 switches JAX's 64-bit mode on
            for the whole process, with a warning; traced runs need it switched on
            beforehand.
        chunk_steps: time steps per jitted chunk, in [1, 10^7] (progress and snapshot
            granularity; at most the run's step count; the step count is rounded up to a
            multiple of it, dt shrinks accordingly).
        dim: 1 for the width-uniform strip (default), 2 to run the 2D step on a strip.
        width: strip width for ``dim=2`` with free edges [m] (the paper's 0.3 m).
        p0_rule: how p0 follows from the tensile strength: "paper" (Eq. 6 as printed;
            uniaxial tension yields at 0.534 sigma_t with the "3d" invariants) or
            "uniaxial" (yields at sigma_t).
        mcc_invariants: stress invariants of the MCC yield function: "3d" (p = -tr/3 and
            the 3D von Mises q of the plane-stress tensor, sigma_zz = 0; the default) or
            "plane" (invariants of the 2D in-plane tensor). See `damjax.materials.mcc`.
        slab_fracture: slab tensile fracture model (`damjax.materials.slab_fracture`), for
            a finite tensile strength: "paper" (the default: the paper's homogeneous,
            perfectly plastic slab, whose arrests reproduce the paper's and converge with
            dx) or "crack_band" (an alternative with a fracture energy G_f and a seeded
            random tensile-strength field; its measured status is in docs/model/slab.md).
        seed: integer in [0, 2^31 - 1], picks the tensile-strength field ("crack_band";
            the same field on every dx).
        accumulation: how the particle-to-grid sums are added
            (`damjax.core.transfer.p2g_channels`): "auto" (the default: "float" on a
            CPU, "fixed" on a GPU or any other backend; deterministic on each,
            `damjax.core.transfer.resolve_accumulation`), "fixed" (fixed-point
            integers, so a run is deterministic on every backend and does not depend
            on the particles' order; each contribution is rounded to 4.4e-16 N of the
            largest, N = 3^dim contributions per particle x particles, far below
            float32's 6e-8) or "float" (plain float scatter-adds: deterministic on a
            CPU, which adds them in the particles' order; on a GPU their order, hence
            the last bits, varies between identical runs).
    """

    length: float = 100.0
    dx: float = 0.02
    duration: float = 3.0
    controlled: bool = False
    lateral: str = "free"
    cfl: float = 0.5
    particles_per_cell: int = 2
    dtype: str = "float32"
    chunk_steps: int = 1000
    dim: int = 1
    width: float = 0.3
    p0_rule: str = "paper"
    mcc_invariants: str = "3d"
    slab_fracture: str = "paper"
    seed: int = 0
    accumulation: str = "auto"

    def __post_init__(self) -> None:
        _normalise_dtype(self)


def _normalise_dtype(setup: Any) -> None:
    """A setup's dtype as its canonical name: "float64", jnp.float64, np.float64 and
    np.dtype("float64") are one setting (and one compiled program). Anything else is
    kept as given, for validation to name."""
    name = dtype_name(setup.dtype) if not isinstance(setup.dtype, bool) else None
    if name is not None:
        object.__setattr__(setup, "dtype", name)


PSTParams = SnowParams  # the name users know (PST papers, earlier versions)


@dataclasses.dataclass(frozen=True)
class SlopeSetup:
    """Numerics and geometry of a slope-scale run.

    Attributes:
        length: down-slope extent of the release area along the surface [m].
        width: cross-slope extent [m].
        dx: grid spacing [m].
        duration: simulated time [s].
        start: crack initiation point (x, y) [m] (x up-slope from the lower edge).
        cfl: Courant number.
        particles_per_cell: particles per cell and dimension.
        dtype: "float32" or "float64", as a string or a numpy / JAX dtype (stored as its
            name).
        chunk_steps: steps per jitted chunk (one snapshot per chunk).
        p0_rule: MCC p0 rule (see `PSTSetup`).
        mcc_invariants: MCC stress invariants, "3d" or "plane" (see `PSTSetup`).
        slab_fracture: slab fracture model, "paper" (the default, as for `PSTSetup`) or
            "crack_band" (see `PSTSetup`; the strength field is drawn over length x width;
            a 30 m x 8 m slope on dx 0.125 m runs 1.4-1.7 x longer with it).
        seed: integer in [0, 2^31 - 1], picks the tensile-strength field ("crack_band").
        accumulation: particle-to-grid sums, "auto" (the default: "float" on a CPU,
            "fixed" elsewhere), "fixed" or "float" (see `PSTSetup`).
    """

    length: float = 50.0
    width: float = 60.0
    dx: float = 0.2
    duration: float = 2.0
    start: tuple[float, float] = (5.0, 30.0)
    cfl: float = 0.5
    particles_per_cell: int = 2
    dtype: str = "float32"
    chunk_steps: int = 100
    p0_rule: str = "paper"
    mcc_invariants: str = "3d"
    slab_fracture: str = "paper"
    seed: int = 0
    accumulation: str = "auto"

    def __post_init__(self) -> None:
        _normalise_dtype(self)


def _unknown_keywords_named(cls: Any, shown: str) -> None:
    """Make ``cls(misspelt=...)`` a TypeError that names the field it probably meant
    (``PSTParams(poison=0.3)``: did you mean 'poisson'?) instead of the generated
    ``__init__``'s bare "unexpected keyword argument"."""
    import difflib
    import functools

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


_unknown_keywords_named(SnowParams, "PSTParams")
_unknown_keywords_named(PSTSetup, "PSTSetup")
_unknown_keywords_named(SlopeSetup, "SlopeSetup")
