"""Slab tensile fracture: the fracture law of the time step, defaults, strength field.

A perfectly plastic or softening slab without a length scale localises a fracture in one
cell: the energy a fracture dissipates goes to zero with dx (Bazant and Oh 1983), and in a
homogeneous slab under a plateau of tension the place where the next fracture forms is
decided by round-off. The ``"crack_band"`` slab (`SLAB_FRACTURE_MODELS`;
``PSTSetup.slab_fracture = "crack_band"``) has two ingredients that make fractures well
posed:

- a fracture energy G_f per unit crack area (`PSTParams.slab_fracture_energy`): p0, hence
  the tensile strength, decays as exp(-w / w_c) with the opening w [m] of the band
  (`band_opening`: the plastic opening strain summed across the band) and
  w_c = G_f / sigma_y, so that a fracture dissipates G_f per unit area on any grid;
- heterogeneity: the tensile strength sigma_t is a seeded log-normal random field
  (`strength_field`) with a coefficient of variation (`slab_strength_cov`) and a
  correlation length (`slab_strength_length`), drawn with `damjax.fields.grf` on a grid fixed
  in metres (`FIELD_SPACING`), so that a seed is the same field on every dx: where a
  fracture forms is decided by the snow.

``"paper"``, the default of PSTs and slopes (`damjax.PSTSetup`, `damjax.SlopeSetup`), is the
paper's perfectly plastic, homogeneous slab (the strength field ignored; a G_f given
explicitly softens over one cell, as in earlier versions): its arrests reproduce the paper's
and converge with dx. ``"crack_band"`` is an explicit alternative; with literature G_f and
strength variability its arrests differ from the paper's and its fracture count does not yet
converge with dx (docs/model/slab.md has the measurements).

The law (`step_start`, `return_map_uniaxial`, `return_map_plane`; band openings over windows
fixed in metres, `band_opening`; the strength a band keeps, `p0_and_band`) is what
`damjax.core.step` calls, with the model's parts it reads: the slab's elastic constants
(`damjax.materials.slab.Slab`) and `Fracture`, this law's constants and lattice. The
counts of a run's fractures are diagnostics (`damjax.diagnostics`): the "crack_band"
slab's fractures are bands whose opening reached `fracture_opening`
(`damjax.diagnostics.band_fractures`); the "paper" slab's are those the crack feels
(`damjax.diagnostics.crack_fractures`: speed drops with a separation behind the tip, and
the crown).

Default values (chosen from the literature, not fitted to any result):

- G_f = 0.12 J/m^2 (`DEFAULT_FRACTURE_ENERGY`): G_f = K_Ic^2 / E with the tensile fracture
  toughness K_Ic = 0.7 kPa m^(1/2), the middle of the 0.5-1 kPa m^(1/2) that Schweizer,
  Michot and Kirchner (2004, Ann. Glaciol. 38, "On the fracture toughness of snow"; the
  cantilever-beam tests of Sigrist 2006) measured for snow of 100-300 kg/m^3, and E = 4 MPa.
  Snow is very brittle: the characteristic length E G_f / sigma_t^2 is 1.3 cm at
  sigma_t = 6 kPa, so the strength, not G_f, decides whether a slab breaks.
- coefficient of variation 0.2 (`DEFAULT_STRENGTH_COV`): slab-layer penetration resistance
  varied by about 25 % across a small slope (Kronholm, Schneebeli and Schweizer 2004, Ann.
  Glaciol. 38), and point stability by a quartile coefficient of variation of 20 % once the
  slope-scale trend is removed (Kronholm and Schweizer 2003, Cold Reg. Sci. Technol. 37);
  physics notes: 10-30 % in penetrometer-derived maps.
- correlation length 1 m (`DEFAULT_STRENGTH_LENGTH`): Kronholm et al. (2004) found slab
  layers autocorrelated on metre scales, with layer-specific ranges (Kronholm and Schweizer
  2003 could not resolve a range below their array spacing of a few metres); 1 m is at the
  short end, which keeps several independent strengths along a 20 m tension zone.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from damjax import fields
from damjax.constants import SLAB_FRACTURE_MODELS  # noqa: F401  (the choices, public here)
from damjax.materials import mcc
from damjax.materials.slab import Slab

DEFAULT_FRACTURE_ENERGY = 0.12  # G_f [J/m^2]
DEFAULT_STRENGTH_COV = 0.2  # coefficient of variation of sigma_t [-]
DEFAULT_STRENGTH_LENGTH = 1.0  # correlation length of sigma_t [m]
MAX_STRENGTH_LENGTH = 10.0  # largest correlation length (sets the field's embedding) [m]
FIELD_SPACING = (0.05, 0.1)  # node spacing of the strength field, 1D and 2D [m]
OPENING_HALF_WIDTH = 0.15  # half-width of the window of the band opening [m]
_SALT = 0x5AB  # folded into the seed: the slab field is independent of other draws


def opening_window(spacing: float) -> int:
    """Half-width in particles of the band-opening window (`OPENING_HALF_WIDTH`)."""
    return max(1, int(round(OPENING_HALF_WIDTH / spacing)))


def _key(seed: int) -> Any:
    return jax.random.fold_in(jax.random.key(int(seed)), _SALT)


def _lognormal(z: Any, mean: Any, cov: Any) -> Any:
    """mean x exp(s z - s^2 / 2), s^2 = ln(1 + cov^2): mean and CoV exact for z ~ N(0, 1)."""
    # s ~ |cov| near 0: sqrt(log1p(cov^2)) has a 0 * inf = NaN derivative at cov = 0
    x = cov * cov
    pos = x > 0.0
    s = jnp.where(pos, jnp.sqrt(jnp.where(pos, jnp.log1p(x), 1.0)), jnp.abs(cov))
    return mean * jnp.exp(s * z - 0.5 * s * s)


# --------------------------------------------------------------------------------------
# The slab's tensile fracture law, one place for the time step (`damjax.core.step` calls
# `step_start` once per step and `return_map_uniaxial` or `return_map_plane` from its
# constitutive update): band openings over windows fixed in metres, the strength a band
# keeps (crack-band softening with G_f), and the MCC return maps that soften with it.
# They take the model's parts they read (`Slab`, `Fracture`: ``model.slab``,
# ``model.fracture`` of `damjax.core.state.Model`); ``state`` is the core's `State`, read
# by attribute (this module imports nothing from the core).
# --------------------------------------------------------------------------------------

# A particle counts as opened (its strength follows its band's opening) once its own
# opening exceeds this fraction of w_c: elastic steps leave round-off openings (1e-29 m
# per step measured in float32 under jit), which must not soften an intact particle.
OPENED = 1e-3
FRACTURE_STRAIN = 0.01  # tensile plastic strain that marks a slab fracture (no lattice) [-]
FRACTURE_OPENING = 1e-3  # smallest band opening counted as a slab fracture [m]


class Fracture(eqx.Module):
    """The slab's plasticity and tensile fracture, its part of a run's model
    (`damjax.core.state.Model.fracture`): the Modified Cam Clay constants
    (`damjax.materials.mcc`; p0_init = inf: an elastic slab), the crack band's fracture
    energy and the particles' lattice that band openings are summed over (SI units;
    arrays traced, the rest static)."""

    plastic: bool = eqx.field(static=True)  # False: skip the return mapping entirely
    p0_init: Any  # initial consolidation pressure [Pa] (from the tensile strength)
    mcc_m: Any  # critical-state slope M [-]
    mcc_beta: Any  # tension parameter beta [-]
    mcc_xi: Any  # volumetric softening xi [-]
    fracture_energy: Any  # slab G_f [J/m^2] of the crack-band softening (inf: none)
    # width of a band without a lattice [m]: one grid cell, dx (the opening strain x dx)
    cell_width: float = eqx.field(static=True)
    # stress invariants of the MCC yield function ("3d" or "plane", see materials.mcc)
    mcc_invariants: str = eqx.field(static=True, default="3d")
    # slab fracture model: True for "crack_band" (p0 softens with the band opening, needs
    # the lattice), False for "paper" (with a finite G_f it softens with the opening
    # strain x dx, one cell)
    crack_band: bool = eqx.field(static=True, default=False)
    # the particles as a regular lattice in their reference positions, x-major (particles
    # per axis), its spacing [m], and the half-width in particles of the window over which
    # the plastic opening strain is summed into a band opening [m] (`band_opening`);
    # () : no lattice, opening = strain x dx
    lattice: tuple[int, ...] = eqx.field(static=True, default=())
    lattice_spacing: float = eqx.field(static=True, default=0.0)
    opening_window: int = eqx.field(static=True, default=0)
    # derived (`damjax.core.state.Model.with_constants`): the crack band's w_c [m]
    # (`crack_band_opening`; None: derived where it is used, in every step)
    band_w_c: Any = None
    # (n,) each particle's flat index in the lattice where some lattice sites hold no
    # particle (a snow cover with gaps: no slab there, an opening of 0); None: the
    # particles are the whole lattice, in its order
    lattice_index: Any = None


class StepStart(NamedTuple):
    """What the fracture law needs of the state at the start of a step (`step_start`)."""

    plain: Any  # window sums of the openings [m] (`band_openings`; None without a lattice)
    band: Any  # the same, spread over each band (None without a lattice)
    p0: Any  # consolidation pressure of each particle [Pa] (`p0_and_band`)
    p0_band: Any  # the strength each particle takes on once it yields with its band [Pa]
    t_fracture: Any  # time each particle's band reached `fracture_opening` [s] (inf: not)


def step_start(slab: Slab, fracture: Fracture, state: Any) -> StepStart:
    """Band openings, strengths and fracture times at the start of a step (plastic slabs).

    A band reaches the fracture opening when the largest window sum in it does: the window
    sum alone (`band_opening` without its max) marks the band's first time. Tested on the
    openings at the start of the step, the time they were reached (the end of the previous
    step): the sums are the crack-band slab's own (`p0_and_band`), and a window of the new
    openings cost 0.05 of a 0.25 ms step.
    """
    opening_y = state.opening_y if len(fracture.lattice) > 1 else None
    if fracture.lattice:
        plain, band = band_openings(fracture, state.opening, opening_y)
    else:
        plain, band = band_opening(fracture, state.opening), None
    t_fracture = jnp.where(
        jnp.isinf(state.t_fracture) & (plain >= fracture_opening(fracture)),
        state.time,
        state.t_fracture,
    )
    p0, p0_band = p0_and_band(slab, fracture, state, band)
    return StepStart(plain if fracture.lattice else None, band, p0, p0_band, t_fracture)


def return_map_uniaxial(slab: Slab, fracture: Fracture, sig_tr: Any, start: StepStart) -> Any:
    """(sigma_xx [Pa], d eps_p_xx, d eps_p_yy) of a 1D free strip (uniaxial stress) from the
    trial stress ``sig_tr`` [Pa]: `damjax.materials.mcc.return_map_uniaxial`, or for the
    "crack_band" slab its energy-consistent softening map."""
    if not (fracture.crack_band and fracture.lattice):
        return mcc.return_map_uniaxial(
            sig_tr,
            start.p0,
            fracture.mcc_m,
            fracture.mcc_beta,
            slab.youngs_modulus,
            fracture.mcc_invariants,
        )
    # the band's other particles open in the step too: each Newton step takes their
    # openings (the window sum, `band_opening`) at the current iterate, so the particles
    # of a band soften together and the band dissipates G_f h (20 m PST: 0.99-1.00 on dx
    # 0.08-0.02; with the other openings of the step's start, 1.10-1.28)
    w_c = crack_band_opening(fracture)
    rate = fracture.lattice_spacing / w_c

    def others(d: Any) -> Any:
        d = jnp.maximum(d, 0.0)
        band = band_opening(fracture, d, spread=False)
        return jnp.maximum(band / w_c - rate * d, 0.0)

    return mcc.return_map_uniaxial_softening(
        sig_tr,
        start.p0,
        start.p0_band,
        rate,
        others,
        fracture.mcc_m,
        fracture.mcc_beta,
        slab.youngs_modulus,
        fracture.mcc_invariants,
        settled=mcc.SETTLED * fracture.p0_init,
    )


def return_map_plane(
    slab: Slab, fracture: Fracture, state: Any, eps_e: Any, start: StepStart
) -> tuple[Any, Any, Any, Any]:
    """(sigma, d eps_p, d_opening, d_opening_y) of the plane-stress update from the trial
    elastic strain ``eps_e`` (xx, yy, xy rows): `damjax.materials.mcc.return_map_plane`, or
    for the "crack_band" slab its energy-consistent softening map; the opening increments
    from `principal_opening`."""
    args = (fracture.mcc_m, fracture.mcc_beta, slab.youngs_modulus, slab.poisson)
    args = (*args, fracture.mcc_invariants)
    if fracture.crack_band and fracture.lattice:
        # energy-consistent, as the 1D map: the band's strength averaged over the step's
        # opening (a fracture across a 0.3 m strip: 1.06-1.09 G_f h W on dx 0.08-0.02;
        # with the strength of the step's start, 1.83 / 1.53 on dx 0.08 / 0.04)
        w_c = crack_band_opening(fracture)
        o, oy = state.opening, state.opening_y
        w0 = _jump(fracture, o, oy) if start.plain is None else start.plain

        def increase(d: Any) -> Any:
            d_open, d_open_y = principal_opening(d)
            return jnp.maximum(_jump(fracture, o + d_open, oy + d_open_y) - w0, 0.0) / w_c

        sigma, d_eps_p = mcc.return_map_plane_softening(
            eps_e,
            start.p0,
            start.p0_band,
            increase,
            *args,
            settled=mcc.SETTLED * fracture.p0_init,
        )
    else:
        sigma, d_eps_p = mcc.return_map_plane(eps_e, start.p0, *args)
    d_open, d_open_y = principal_opening(d_eps_p)
    return sigma, d_eps_p, d_open, d_open_y


def principal_opening(d_eps_p: Any) -> tuple[Any, Any]:
    """(d_opening, d_opening_y) of a plastic strain increment (xx, yy, xy): its largest
    principal value, floored at 0, and that times n_y^2 for its direction n, the part a
    band normal to y takes up (`band_opening`)."""
    half = 0.5 * (d_eps_p[0] - d_eps_p[1])
    r = jnp.sqrt(half * half + d_eps_p[2] ** 2 + 1e-30)
    d_open = jnp.maximum(0.5 * (d_eps_p[0] + d_eps_p[1]) + r, 0.0)
    return d_open, d_open * jnp.clip(0.5 - 0.5 * half / r, 0.0, 1.0)


def _jump(fracture: Fracture, opening: Any, opening_y: Any) -> Any:
    """`band_opening` without spread: the window sums only."""
    return band_openings(fracture, opening, opening_y)[0]


def crack_band_opening(fracture: Fracture) -> Any:
    """w_c = G_f / sigma_y [m] of the slab's crack-band softening (inf: none); derived once
    when the model is built (`Fracture.band_w_c`)."""
    if fracture.band_w_c is not None:
        return fracture.band_w_c
    return mcc.crack_band_opening(
        fracture.p0_init,
        fracture.fracture_energy,
        fracture.mcc_m,
        fracture.mcc_beta,
        fracture.mcc_invariants,
    )


def band_opening(
    fracture: Fracture, opening: Any, spread: bool = True, opening_y: Any = None
) -> Any:
    """Opening w [m] of the tensile band through each particle, rows (n,).

    With a particle lattice (`Fracture.lattice`), the plastic opening strain times the
    particle spacing, summed over the particles within `Fracture.opening_window` of it along
    x. A localised band, one cell or a few wide, then has the same opening, its
    displacement jump, on any grid, and a diffuse plastic zone counts as a band of the
    window's width (2 window + 1 particles), fixed in metres. Without a lattice: the
    strain times dx (one cell).

    In 2D, ``opening_y`` (`State.opening_y`) is the part of ``opening`` along y: the x
    part summed along x and the y part summed along y are the two components of the
    band's jump, w n_x and w n_y for a band of any orientation n (a line along x crosses
    a band of width b over b / n_x, where the band's strain is n_x^2 w / b), and w is
    their length. Without it (a strain with no direction, such as a compaction): the
    smaller of the x and y sums of ``opening``, the sum across a band, not along it.
    """
    if not fracture.lattice:
        return opening * fracture.cell_width
    return band_openings(fracture, opening, opening_y)[1 if spread else 0]


def band_openings(fracture: Fracture, opening: Any, opening_y: Any = None) -> tuple[Any, Any]:
    """`band_opening` without and with ``spread``, from one set of window sums (with a
    lattice)."""
    k = fracture.opening_window
    s = fracture.lattice_spacing
    # the sum over the window centred on each particle, then its largest value over the
    # window: every particle of a band sees the band's whole opening, also near its edges
    # (without spread: the window sum only, the opening of the band centred there)
    if len(fracture.lattice) == 1:
        w = _window(opening * s, k, jnp.add, 0.0, 0)
        return w, _window(w, k, jnp.maximum, -jnp.inf, 0)
    if opening_y is None:
        grid = _to_lattice(fracture, opening * s)
        w = [_window(grid, k, jnp.add, 0.0, axis) for axis in (0, 1)]
        spread = [_window(a, k, jnp.maximum, -jnp.inf, axis) for axis, a in enumerate(w)]
        return tuple(_from_lattice(fracture, jnp.minimum(*a), opening.shape) for a in (w, spread))
    parts = (jnp.maximum(opening - opening_y, 0.0) * s, opening_y * s)
    w = [_window(_to_lattice(fracture, o), k, jnp.add, 0.0, axis) for axis, o in enumerate(parts)]
    spread = [_window(a, k, jnp.maximum, -jnp.inf, axis) for axis, a in enumerate(w)]
    return tuple(
        _from_lattice(fracture, mcc._sqrt(a[0] * a[0] + a[1] * a[1]), opening.shape)
        for a in (w, spread)
    )


def _to_lattice(fracture: Fracture, values: Any) -> Any:
    """Per-particle values (n,) on the 2D lattice: in place, or scattered to the sites
    of `Fracture.lattice_index` with 0 on the sites without a particle (no slab: no
    opening)."""
    sites = getattr(fracture, "lattice_index", None)  # (a lattice-like object has none)
    if sites is None:
        return jnp.reshape(values, fracture.lattice)
    size = math.prod(fracture.lattice)
    flat = jnp.zeros((size,), values.dtype).at[sites].set(values)
    return jnp.reshape(flat, fracture.lattice)


def _from_lattice(fracture: Fracture, grid: Any, shape: tuple[int, ...]) -> Any:
    """The lattice's values back at the particles (`_to_lattice` undone)."""
    sites = getattr(fracture, "lattice_index", None)
    if sites is None:
        return jnp.reshape(grid, shape)
    return jnp.reshape(jnp.reshape(grid, (-1,))[sites], shape)


def _window(a: Any, k: int, op: Any, pad_value: float, axis: int) -> Any:
    """op (add or maximum) of ``a`` over [i - k, i + k] along ``axis``, padded with
    ``pad_value``: blocks of 1, 2, 4, ... elements made by doubling and combined along the
    binary digits of 2 k + 1 (2 log2(2 k + 1) elementwise ops; XLA:CPU's reduce_window
    takes 2 k + 1 per element: with it a 100 m PST step at dx 0.02 took 1.19 / 1.72 x the
    step without a lattice for the paper / crack_band slab, with this 1.01 / 1.16 x)."""
    n = a.shape[axis]
    pad = [(0, 0)] * a.ndim
    pad[axis] = (k, k)
    m = jnp.pad(a, pad, constant_values=pad_value)
    out, offset, span, rest = None, 0, 1, 2 * k + 1
    while True:
        if rest & 1:  # the block of `span` elements at `offset`
            block = jax.lax.slice_in_dim(m, offset, offset + n, axis=axis)
            out = block if out is None else op(out, block)
            offset += span
        rest >>= 1
        if not rest:
            return out
        size = m.shape[axis]
        m = op(
            jax.lax.slice_in_dim(m, 0, size - span, axis=axis),
            jax.lax.slice_in_dim(m, span, size, axis=axis),
        )
        span *= 2


def fracture_opening(fracture: Fracture) -> Any:
    """Band opening [m] that marks a slab fracture, per particle.

    With a particle lattice: FRACTURE_OPENING (1 mm), or, with crack-band softening
    where it is larger, the opening at which the band keeps 1 % of its strength
    (ln(100) w_c), the same on every grid and for every slab model. Without a lattice
    (older layouts): FRACTURE_STRAIN x dx for a perfectly plastic slab, 3 w_c with
    softening.
    """
    w_c = crack_band_opening(fracture)
    finite = jnp.isfinite(w_c)
    if not fracture.lattice:
        return jnp.where(finite, 3.0 * w_c, FRACTURE_STRAIN * fracture.cell_width)
    return jnp.where(
        finite,
        jnp.maximum(FRACTURE_OPENING, float(np.log(100.0)) * jnp.where(finite, w_c, 0.0)),
        FRACTURE_OPENING,
    )


def fracture_strain(fracture: Fracture) -> Any:
    """Opening strain that marks a slab fracture without a lattice (`fracture_opening` / dx)."""
    return fracture_opening(fracture) / fracture.cell_width


def p0_and_band(slab: Slab, fracture: Fracture, state: Any, band: Any = None) -> tuple[Any, Any]:
    """(p0, the band's p0) [Pa]: the current consolidation pressure, explicit in the
    previous step's plastic strains (SinhExpl softening with volumetric plastic strain, xi,
    and crack-band softening with the band's opening, G_f: `band_opening` for the
    "crack_band" slab, the opening strain x dx, one cell, for the "paper" slab with a
    finite G_f), and for the "crack_band" slab every particle's strength as if it had
    opened, the strength a particle of a band takes on once it yields
    (`damjax.core.step.constitutive`); both from one band opening. Otherwise the same p0
    twice."""
    bulk = slab.youngs_modulus / (2.0 * (1.0 - slab.poisson))
    w_c = crack_band_opening(fracture)
    eps_pv = state.eps_p[0] + state.eps_p[1]
    if not (fracture.crack_band and fracture.lattice):
        p0 = fracture.p0_init * mcc.crack_band_factor(state.opening, fracture.cell_width, w_c)
        p0 = mcc.softened_p0(p0, eps_pv, fracture.mcc_xi, bulk)
        return p0, p0
    # only particles that opened themselves soften (by more than round-off, OPENED): the
    # window's sum must not weaken an intact neighbour, which would then yield too and
    # spread the band over a plateau
    if band is None:
        w = band_opening(fracture, state.opening, opening_y=state.opening_y)
    else:
        w = band
    opened = state.opening * fracture.lattice_spacing > OPENED * w_c
    p0_band = mcc.softened_p0(fracture.p0_init * jnp.exp(-w / w_c), eps_pv, fracture.mcc_xi, bulk)
    p0_intact = mcc.softened_p0(fracture.p0_init, eps_pv, fracture.mcc_xi, bulk)
    return jnp.where(opened, p0_band, p0_intact), p0_band


def _strength_embedding(
    shape: tuple[int, ...], h: float, extent: float | tuple[float, float]
) -> tuple[int, ...]:
    """The periodic embedding of the strength field: `damjax.fields.embedding_shape`'s
    (each axis doubled, plus 5 `MAX_STRENGTH_LENGTH`), or, where that exceeds the GRF's
    node limit (a slab hundreds of metres wide on the 0.1 m grid), each axis plus the pad
    only: points of the slab then lie at least 5 MAX_STRENGTH_LENGTH apart across the
    wrap-around, where the field's correlation (metres) has vanished, and smaller slabs
    keep the field they had."""
    import importlib

    g = importlib.import_module("damjax.fields.grf")  # the module (`fields.grf` is its function)

    try:
        return fields.embedding_shape(shape, h, MAX_STRENGTH_LENGTH)
    except ValueError:
        pad = math.ceil(g._EMBED_PAD_LENGTHS * MAX_STRENGTH_LENGTH / h)
        embed = tuple(g._next_fast_size(int(n) + pad) for n in shape)
        if math.prod(embed) > g._MAX_EMBED_NODES:
            raise ValueError(
                f'setup.slab_fracture = "crack_band": the slab\'s tensile-strength field over '
                f"{extent} m needs {math.prod(embed):.3g} nodes on its {h} m grid, above "
                f"{g._MAX_EMBED_NODES:.3g}; a smaller domain"
            ) from None
        return embed


def strength_field(
    seed: int,
    mean: Any,
    cov: Any,
    length_scale: Any,
    x: Any,
    extent: float | tuple[float, float],
    y: Any = None,
) -> Any:
    """Tensile strength sigma_t [Pa] at the points (x[, y]) [m] of a slab of ``extent``.

    A log-normal field with mean ``mean`` [Pa], coefficient of variation ``cov`` [-] and
    Gaussian correlation of length ``length_scale`` [m] (`damjax.fields.grf`), drawn on a
    grid with node spacing `FIELD_SPACING` over [0, extent] (1D) or [0, Lx] x [0, Ly] (2D)
    and interpolated linearly: the same seed and extent give the same field on every
    particle grid. ``cov`` = 0 (concrete) returns ``mean`` everywhere. Differentiable in
    ``mean`` and ``cov``; ``length_scale`` may be traced (the embedding is sized for
    `MAX_STRENGTH_LENGTH`).
    """
    if not isinstance(cov, jax.core.Tracer) and np.all(np.asarray(cov) == 0.0):
        return jnp.broadcast_to(jnp.asarray(mean, x.dtype), x.shape)
    dtype = x.dtype
    if y is None:
        h = FIELD_SPACING[0]
        n = int(math.ceil(float(extent) / h)) + 2
        shape: tuple[int, ...] = (n,)
    else:
        h = FIELD_SPACING[1]
        shape = tuple(int(math.ceil(float(e) / h)) + 2 for e in extent)
    embed = _strength_embedding(shape, h, extent)
    z = fields.grf(
        _key(seed),
        shape,
        h,
        mean=0.0,
        std=1.0,
        length_scale=length_scale,
        floor=None,
        embed_shape=embed,
    ).astype(dtype)
    if y is None:
        zp = jnp.interp(x, jnp.arange(shape[0], dtype=dtype) * h, z)
    else:
        gx, gy = x / h, y / h
        i0 = jnp.clip(jnp.floor(gx).astype(jnp.int32), 0, shape[0] - 2)
        j0 = jnp.clip(jnp.floor(gy).astype(jnp.int32), 0, shape[1] - 2)
        tx, ty = gx - i0, gy - j0
        zp = (
            (1 - tx) * (1 - ty) * z[i0, j0]
            + tx * (1 - ty) * z[i0 + 1, j0]
            + (1 - tx) * ty * z[i0, j0 + 1]
            + tx * ty * z[i0 + 1, j0 + 1]
        )
    return _lognormal(zp, jnp.asarray(mean, dtype), jnp.asarray(cov, dtype))
