"""Slab tensile fracture with a physical length scale: defaults, strength field, diagnostics.

A perfectly plastic or softening slab without a length scale localises a fracture in one
cell: the energy a fracture dissipates goes to zero with dx (Bazant and Oh 1983), and in a
homogeneous slab under a plateau of tension the place where the next fracture forms is
decided by round-off. The ``"crack_band"`` slab (`SLAB_FRACTURE_MODELS`;
``PSTSetup.slab_fracture = "crack_band"``) has two ingredients that make fractures well
posed:

- a fracture energy G_f per unit crack area (`PSTParams.slab_fracture_energy`): p0, hence
  the tensile strength, decays as exp(-w / w_c) with the opening w [m] of the band
  (`damjax.core.step.band_opening`: the plastic opening strain summed across the band) and
  w_c = G_f / sigma_y, so that a fracture dissipates G_f per unit area on any grid;
- heterogeneity: the tensile strength sigma_t is a seeded log-normal random field
  (`strength_field`) with a coefficient of variation (`slab_strength_cov`) and a
  correlation length (`slab_strength_length`), drawn with `damjax.fields.grf` on a grid fixed
  in metres (`FIELD_SPACING`), so that a seed is the same field on every dx: where a
  fracture forms is decided by the snow.

``"crack_band"`` is the default of PSTs (`damjax.PSTSetup`); slopes (`damjax.SlopeSetup`)
keep ``"paper"`` by default. ``"paper"`` is the paper's perfectly plastic, homogeneous slab
(the strength field ignored; a G_f given explicitly softens over one cell, as in earlier
versions), kept so that its figures stay reproducible. Both models count fractures the same way
(`fractures`): a band whose opening reached `damjax.core.step.fracture_opening`.

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
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax import fields
from damjax.constants import SLAB_FRACTURE_MODELS  # noqa: F401  (the choices, public here)

DEFAULT_FRACTURE_ENERGY = 0.12  # G_f [J/m^2]
DEFAULT_STRENGTH_COV = 0.2  # coefficient of variation of sigma_t [-]
DEFAULT_STRENGTH_LENGTH = 1.0  # correlation length of sigma_t [m]
MAX_STRENGTH_LENGTH = 10.0  # largest correlation length (sets the field's embedding) [m]
FIELD_SPACING = (0.05, 0.1)  # node spacing of the strength field, 1D and 2D [m]
OPENING_HALF_WIDTH = 0.15  # half-width of the window of the band opening [m]
FRACTURE_GAP = 1.0  # fractures closer than this are one [m]
SPEED_WINDOW = 0.05  # crack speed before / after a fracture: mean over this time [s]
_SALT = 0x5AB  # folded into the seed: the slab field is independent of other draws


def opening_window(spacing: float) -> int:
    """Half-width in particles of the band-opening window (`OPENING_HALF_WIDTH`)."""
    return max(1, int(round(OPENING_HALF_WIDTH / spacing)))


def _key(seed: int) -> Any:
    return jax.random.fold_in(jax.random.key(int(seed)), _SALT)


def _lognormal(z: Any, mean: Any, cov: Any) -> Any:
    """mean x exp(s z - s^2 / 2), s^2 = ln(1 + cov^2): mean and CoV exact for z ~ N(0, 1)."""
    s = jnp.sqrt(jnp.log1p(cov * cov))
    return mean * jnp.exp(s * z - 0.5 * s * s)


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
    embed = fields.embedding_shape(shape, h, MAX_STRENGTH_LENGTH)
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


def fractures(
    x: np.ndarray,
    opening: np.ndarray,
    t_fracture: np.ndarray,
    gap: float = FRACTURE_GAP,
) -> list[dict[str, float]]:
    """Slab fractures from the band openings at the end of a run.

    ``opening``: band opening per particle [m] (`damjax.core.step.band_opening`);
    ``t_fracture``: the time each particle's band opening reached the fracture opening
    (inf: never). Particles that fractured, closer than ``gap`` [m] along x, are one
    fracture, reported at the particle of its largest opening: ``{x_m, t_s, opening_m}``
    (position [m], first time [s], opening [m]), sorted by time. The same count for every
    slab model and grid spacing.
    """
    x, opening, t_fracture = (np.asarray(a, dtype=float) for a in (x, opening, t_fracture))
    order = np.argsort(x, kind="stable")
    x, opening, t_fracture = x[order], opening[order], t_fracture[order]
    idx = np.nonzero(np.isfinite(t_fracture))[0]
    if idx.size == 0:
        return []
    splits = np.nonzero(np.diff(x[idx]) > gap)[0] + 1
    out = []
    for band in np.split(idx, splits):
        k = band[np.argmax(opening[band])]
        out.append(
            {
                "x_m": float(x[k]),
                "t_s": float(np.min(t_fracture[band])),
                "opening_m": float(opening[k]),
            }
        )
    return sorted(out, key=lambda f: f["t_s"])


def speed_changes(
    time: np.ndarray, tip: np.ndarray, fracture_list: list[dict[str, float]]
) -> list[dict[str, float]]:
    """Crack speed before and after each fracture [m/s] (the paper's Fig. 8d).

    The mean speed of the crack tip over `SPEED_WINDOW` seconds before the fracture time
    and over the same time after it: ``{x_m, t_s, speed_before_m_per_s,
    speed_after_m_per_s, speed_drop_m_per_s}``.
    """
    time, tip = np.asarray(time, dtype=float), np.asarray(tip, dtype=float)
    out = []
    for f in fracture_list:
        t = f["t_s"]
        if time.size < 2 or not math.isfinite(t):
            continue
        tip_at = lambda s: float(np.interp(s, time, tip))  # noqa: E731
        t0, t1 = max(float(time[0]), t - SPEED_WINDOW), min(float(time[-1]), t + SPEED_WINDOW)
        before = (tip_at(t) - tip_at(t0)) / (t - t0) if t > t0 else math.nan
        after = (tip_at(t1) - tip_at(t)) / (t1 - t) if t1 > t else math.nan
        out.append(
            {
                "x_m": f["x_m"],
                "t_s": t,
                "speed_before_m_per_s": before,
                "speed_after_m_per_s": after,
                "speed_drop_m_per_s": before - after,
            }
        )
    return out
