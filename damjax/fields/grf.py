"""Weak-layer strength fields: random fields for slopes and strength profiles for PSTs.

Three tools, all in SI units (metres, pascals):

- `grf`: a seeded, jittable Gaussian random field of the weak-layer peak shear strength
  tau_p on a regular 1D or 2D grid (circulant embedding, i.e. exact FFT spectral synthesis
  of a stationary covariance), with a mean and a linear trend. It is differentiable with
  respect to the mean, the trend, the standard deviation and the correlation lengths.
  `fit_grf` fits those parameters to a measured map by maximum likelihood.
- `linear_profile`, `power_law_profile`: the PST strength profiles of the paper
  (tau_p = tau_peak on [0, L_ss], rising beyond).
- `load_strength_profile`, `fit_linear_profile`, `fit_power_law_profile`, `pst_profile`:
  from a measured transect (CSV) to a fitted gradient, shifted to tau_p = 1 kPa at L_ss and
  extrapolated over a PST, as the paper does for its in-situ cases (Figs. 10-11).

Array layout: a 2D field is indexed ``[ix, iy]`` (axis 0 is x, the up-slope coordinate,
axis 1 is y, cross-slope), node ``(i, j)`` sits at ``(x_0 + i dx, y_0 + j dy)``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Sequence
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax import Array
from jax.typing import ArrayLike

CovarianceModel = Literal["gaussian", "exponential"]
_MODELS = ("gaussian", "exponential")

TAU_FLOOR = 1.0  # default floor of a sampled tau_p [Pa]: a strength must stay positive

# Correlation lengths of padding added to twice the domain in the circulant embedding. At
# 5 l the Gaussian correlation is 3e-9 and the exponential one 7e-3 (and the wrapped
# distance is at least the domain size on top of that).
_EMBED_PAD_LENGTHS = 5.0

# Smallest fitted nugget (noise-to-field variance ratio) of `fit_grf`: a noise std of 1e-4
# of the field's, which keeps the correlation matrix of a smooth field well conditioned.
_NUGGET_FLOOR = 1e-8


# --------------------------------------------------------------------------------------
# covariance models (gstools' length-scale convention)
# --------------------------------------------------------------------------------------


def correlation(
    lag: Sequence[ArrayLike] | ArrayLike,
    length_scale: ArrayLike,
    *,
    angle_deg: ArrayLike = 0.0,
    model: CovarianceModel = "gaussian",
) -> Array:
    """Correlation rho(h) of the field between two points a lag h apart [-].

    The conventions are gstools' (so that parameters carry over): with the lag rotated into
    the principal axes and scaled, r = |R(-angle) h / l|,

    - ``"gaussian"``: rho = exp(-pi/4 r^2) (the integral scale equals l);
    - ``"exponential"``: rho = exp(-r).

    Args:
        lag: lag components ``(hx,)`` or ``(hx, hy)`` [m] (arrays broadcast together), or a
            single array for 1D.
        length_scale: correlation length l [m], a scalar (isotropic) or ``(l1, l2)`` along
            the principal axes.
        angle_deg: rotation of the first principal axis, counter-clockwise from x [deg].
        model: ``"gaussian"`` or ``"exponential"``.
    """
    if model not in _MODELS:
        raise ValueError(f"model={model!r}: expected one of {_MODELS}")
    if isinstance(lag, (list, tuple)):
        comps = [jnp.asarray(h) for h in lag]
    else:
        comps = [jnp.asarray(lag)]
    ndim = len(comps)
    if ndim == 1:
        r2 = (comps[0] / jnp.ravel(jnp.asarray(length_scale))[0]) ** 2
    elif ndim == 2:
        ls = jnp.broadcast_to(jnp.asarray(length_scale), (2,))
        a = jnp.deg2rad(angle_deg)
        u = jnp.cos(a) * comps[0] + jnp.sin(a) * comps[1]
        v = -jnp.sin(a) * comps[0] + jnp.cos(a) * comps[1]
        r2 = (u / ls[0]) ** 2 + (v / ls[1]) ** 2
    else:
        raise ValueError(f"lag has {ndim} components; 1D and 2D fields only")
    if model == "gaussian":
        return jnp.exp(-0.25 * jnp.pi * r2)
    # sqrt is not differentiable at 0: guard it (double-where) so gradients stay finite
    pos = r2 > 0
    r = jnp.where(pos, jnp.sqrt(jnp.where(pos, r2, 1.0)), 0.0)
    return jnp.exp(-r)


_MAX_EMBED_NODES = 2**27  # 1 GiB of complex64 per FFT buffer


def _next_fast_size(n: int) -> int:
    """Smallest m >= n of the form 2^a 3^b 5^c (fast FFT sizes)."""
    m = n
    while True:
        k = m
        for p in (2, 3, 5):
            while k % p == 0:
                k //= p
        if k == 1:
            return m
        m += 1


def embedding_shape(
    shape: Sequence[int], dx: float | Sequence[float], length_scale: float | Sequence[float]
) -> tuple[int, ...]:
    """Shape of the periodic domain the field is synthesised on (circulant embedding).

    Each axis of n nodes is embedded in m >= 2 n + 5 l_max / dx nodes (rounded up to a fast
    FFT size), so that the periodic wrap-around does not correlate opposite edges of the
    domain. Pass the result as ``embed_shape`` to `grf` when the correlation lengths are
    traced (inside `jax.jit`), using the largest length you will use.

    Args:
        shape: grid shape ``(nx,)`` or ``(nx, ny)``.
        dx: node spacing [m], a scalar or one per axis.
        length_scale: correlation length(s) [m]; the largest one sets the padding.
    """
    spacing = np.broadcast_to(np.asarray(dx, dtype=float), (len(shape),))
    ls = np.asarray(length_scale, dtype=float)
    if ls.size == 0 or not np.all(np.isfinite(ls) & (ls > 0)):
        raise ValueError(f"length_scale = {length_scale!r}: must be in (0, inf) m")
    if not np.all(np.isfinite(spacing) & (spacing > 0)):
        raise ValueError(f"dx = {dx!r}: must be in (0, inf) m")
    lmax = float(np.max(ls))
    pads = [math.ceil(_EMBED_PAD_LENGTHS * lmax / float(h)) for h in spacing]
    if math.prod(2 * int(n) + p for n, p in zip(shape, pads, strict=True)) > _MAX_EMBED_NODES:
        raise ValueError(
            f"length_scale = {length_scale!r}: {lmax / float(np.min(spacing)):.3g} grid "
            f"spacings (dx = {dx!r}); the periodic embedding would exceed "
            f"{_MAX_EMBED_NODES:.3g} nodes (a field this smooth over the grid is a trend)"
        )
    return tuple(_next_fast_size(2 * int(n) + p) for n, p in zip(shape, pads, strict=True))


def _traced(value: object) -> bool:
    """Whether any leaf of a value (a number, an array or a tuple of them) is traced."""
    return any(isinstance(v, jax.core.Tracer) for v in jax.tree.leaves(value))


def _concrete(value: ArrayLike, name: str) -> np.ndarray:
    """The value of a possibly differentiated argument, or a clear error inside jit."""
    if not _traced(value):
        return np.asarray(value, dtype=float)  # a constant, also inside jit
    try:
        return np.asarray(jax.lax.stop_gradient(value), dtype=float)
    except (jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError) as e:
        raise ValueError(
            f"grf: {name} is traced (inside jax.jit or vmap over it), so the embedding size "
            "cannot be derived from it; pass embed_shape=embedding_shape(shape, dx, l_max)"
        ) from e


# --------------------------------------------------------------------------------------
# Gaussian random field
# --------------------------------------------------------------------------------------


def grf(
    key: Array,
    shape: Sequence[int],
    dx: float | Sequence[float],
    *,
    mean: ArrayLike,
    std: ArrayLike,
    length_scale: ArrayLike,
    angle_deg: ArrayLike = 0.0,
    model: CovarianceModel = "gaussian",
    trend: ArrayLike = 0.0,
    floor: float | None = TAU_FLOOR,
    embed_shape: Sequence[int] | None = None,
) -> Array:
    """One sample of a Gaussian random field of weak-layer strength tau_p [Pa].

    tau_p(x) = mean + trend . (x - x_0) + std * Z(x), with x_0 the first node and Z a
    zero-mean, unit-variance stationary Gaussian field of correlation
    `correlation(h, length_scale, angle_deg, model)` (gstools' conventions). Z is
    synthesised exactly by circulant embedding: the covariance on a periodic domain of
    `embedding_shape` is diagonalised by the FFT, complex white noise is coloured by the
    square root of its eigenvalues, and the real part of the transform, cut to `shape`, is
    one sample (eigenvalues below 16 eps times the largest, i.e. rounding noise, and the
    negative ones, which the padding keeps at rounding level, are set to zero).

    The sample is a deterministic, differentiable function of (mean, trend, std,
    length_scale, angle_deg) for a fixed key: the same key always gives the same field (in
    float32 and float64 alike, to rounding: the white noise is drawn in float32), and
    `jax.grad` of a statistic of the field with respect to these parameters is finite. It is
    jittable with `shape`, `dx`, `model`, `floor` and `embed_shape` static; when
    `length_scale` is traced, pass `embed_shape`. Draw many samples with
    ``jax.vmap(lambda k: grf(k, ...))(jax.random.split(key, n))``.

    Args:
        key: JAX PRNG key (the seed).
        shape: grid shape ``(nx,)`` (1D) or ``(nx, ny)`` (2D), axis 0 along x.
        dx: node spacing [m], a scalar or ``(dx, dy)``.
        mean: expected tau_p at the first node (index 0) [Pa].
        std: standard deviation of the fluctuation [Pa].
        length_scale: correlation length(s) [m]: a scalar, or ``(l1, l2)`` along the
            principal axes (l1 along the direction `angle_deg`).
        angle_deg: rotation of the first principal axis, counter-clockwise from x [deg].
        model: covariance model, ``"gaussian"`` or ``"exponential"``.
        trend: mean strength gradient [Pa/m], a scalar (along x) or ``(gx, gy)``; e.g. 20
            for tau_p rising 20 Pa/m up-slope (paper Fig. 12).
        floor: samples are clipped from below at this value [Pa] (default 1 Pa: a strength
            must stay positive; the gradient is zero where clipped); None: no clipping, for
            a general-purpose field.
        embed_shape: shape of the periodic embedding (default `embedding_shape`).

    Returns:
        tau_p at the nodes [Pa], an array of `shape`.
    """
    shape = tuple(int(n) for n in shape)
    ndim = len(shape)
    if ndim not in (1, 2):
        raise ValueError(f"grf: shape {shape} is neither 1D nor 2D")
    if min(shape) < 1:
        raise ValueError(f"grf: shape {shape}: every axis must have >= 1 node")
    if model not in _MODELS:
        raise ValueError(f"grf: model={model!r}, expected one of {_MODELS}")
    if np.ndim(dx) > 1 or np.size(dx) not in (1, ndim):
        raise ValueError(f"grf: dx = {dx!r}: a scalar or one spacing per axis ({ndim})")
    spacing = tuple(float(h) for h in np.broadcast_to(np.asarray(dx, dtype=float), (ndim,)))
    if not all(math.isfinite(h) and h > 0 for h in spacing):
        raise ValueError(f"grf: dx = {dx!r}: must be in (0, inf) m")
    for name, value, sizes in (
        ("length_scale", length_scale, (1, 2) if ndim == 2 else (1,)),
        ("trend", trend, (1, ndim)),
        ("std", std, (1,)),
    ):
        if not _traced(value) and np.size(value) not in sizes:
            raise ValueError(
                f"grf: {name} = {value!r}: must have "
                + " or ".join(str(k) for k in sizes)
                + f" value(s) on a {ndim}D grid"
            )
    if not _traced(std) and not float(np.asarray(std)) >= 0:
        raise ValueError(f"grf: std = {std!r}: must be in [0, inf) Pa")
    if not _traced(length_scale):
        ls = np.asarray(length_scale, dtype=float)
        if not np.all(np.isfinite(ls) & (ls > 0)):
            raise ValueError(f"grf: length_scale = {length_scale!r}: must be in (0, inf) m")
    floor = None if floor is None else float(floor)
    if embed_shape is None:
        embed_shape = embedding_shape(shape, spacing, _concrete(length_scale, "length_scale"))
    embed_shape = tuple(int(m) for m in embed_shape)
    if len(embed_shape) != ndim or any(m < n for m, n in zip(embed_shape, shape, strict=True)):
        raise ValueError(f"grf: embed_shape {embed_shape} must cover shape {shape}")
    return _grf(
        key,
        mean,
        std,
        length_scale,
        angle_deg,
        trend,
        shape=shape,
        spacing=spacing,
        model=model,
        floor=floor,
        embed_shape=embed_shape,
    )


def trend_direction(trend_deg: float) -> tuple[float, float]:
    """Unit vector (ux, uy) of a trend direction [deg, counter-clockwise from +x], with
    components below 1e-12 set to exactly 0 (so 0 and +-90 deg depend on one axis only)."""
    ok = isinstance(trend_deg, (int, float, np.integer, np.floating)) and not isinstance(
        trend_deg, bool
    )
    if not ok or not math.isfinite(float(trend_deg)):
        raise ValueError(f"trend_deg = {trend_deg!r}: must be a finite number [deg]")
    a = math.radians(math.fmod(float(trend_deg), 360.0))  # fmod first: exact for big angles
    ux, uy = math.cos(a), math.sin(a)
    return (0.0 if abs(ux) < 1e-12 else ux), (0.0 if abs(uy) < 1e-12 else uy)


def trend_distance(
    x: ArrayLike, y: ArrayLike, length: float, width: float, trend_deg: float
) -> np.ndarray:
    """Distance [m] of points (x, y) of a length x width area from the area's edge (or
    corner) a trend in direction `trend_deg` starts at: (x, y) . u minus its minimum over
    the area, u the unit vector of `trend_direction`. x and y broadcast."""
    ux, uy = trend_direction(trend_deg)
    return (
        ux * np.asarray(x, dtype=float)
        + uy * np.asarray(y, dtype=float)
        - min(0.0, ux * length)
        - min(0.0, uy * width)
    )


def box_sum(a: np.ndarray, k: int, mode: str = "constant") -> np.ndarray:
    """Sums of a 2D array over (2k + 1) x (2k + 1) windows centred on each cell, the array
    padded by ``np.pad`` `mode` ("constant": zeros outside; "edge": the edge repeated)."""
    c = np.pad(np.cumsum(np.cumsum(np.pad(a, k, mode=mode), 0), 1), ((1, 0), (1, 0)))
    n = 2 * k + 1
    return c[n:, n:] - c[:-n, n:] - c[n:, :-n] + c[:-n, :-n]


def plateau_trend_field(
    key: Array,
    x: np.ndarray,
    ny: int,
    dx: float,
    *,
    mean: float,
    mean_at: float,
    trend: float,
    std: float,
    length_scale: ArrayLike,
    angle_deg: float = 0.0,
    model: CovarianceModel = "gaussian",
    field_dx: float | None = None,
    trend_deg: float = 0.0,
) -> np.ndarray:
    """A slope's weak-layer strength on cell centres x (nx,) by ny columns [Pa] (numpy).

    Expected strength `mean` up to a distance `mean_at` [m], rising `trend` [Pa/m] beyond it
    (a PST's L_ss and gradient), plus `std` times a stationary `grf` sample (no trend),
    clipped from below at `TAU_FLOOR`. ``std = 0``: the expected strength alone. The cells
    are (i + 1/2) dx apart from 0 in both directions.

    The distance is measured along the direction `trend_deg` [deg, counter-clockwise from
    +x, up-slope] from the edge of the area it starts at: 0 (default) is x, up-slope from
    the lower edge; 90 is y, across from the y = 0 edge; -90 across from the other edge
    (y = ny dx) towards y = 0 (paper Fig. 12b: strength rising across the slope).

    ``field_dx`` [m]: draw the random part on cells of this size over the same extent and
    interpolate it bilinearly to the cells (None: on the cells themselves). A sample
    depends on the grid it is drawn on, so a grid-convergence study fixes ``field_dx``:
    the same key then gives the same field on every grid. At most half the shortest
    correlation length.
    """
    y = (np.arange(ny) + 0.5) * dx
    d = trend_distance(
        np.asarray(x, dtype=float)[:, None], y[None, :], len(x) * dx, ny * dx, trend_deg
    )
    expected = mean + trend * np.maximum(d - mean_at, 0.0)
    if std == 0.0:
        return np.broadcast_to(expected, (len(x), ny)).copy()
    ls = np.asarray(length_scale, dtype=float)
    fdx = dx if field_dx is None else float(field_dx)
    if field_dx is not None and not (math.isfinite(fdx) and 0.0 < fdx <= 0.5 * float(np.min(ls))):
        raise ValueError(
            f"field_dx = {field_dx!r}: must be at most half the shortest length_scale "
            f"({0.5 * float(np.min(ls))} m) and > 0"
        )
    if field_dx is None:
        shape = (len(x), ny)
    else:
        shape = (max(2, round(len(x) * dx / fdx)), max(2, round(ny * dx / fdx)))
    noise = grf(
        key,
        shape,
        fdx,
        mean=0.0,
        std=std,
        length_scale=ls,
        angle_deg=angle_deg,
        model=model,
        floor=None,
    )
    noise = np.asarray(noise, dtype=float)
    if field_dx is not None:
        xf, yf = ((np.arange(n) + 0.5) * fdx for n in shape)
        noise = map_on_grid(xf, yf, noise, x, (np.arange(ny) + 0.5) * dx)
    return np.maximum(expected + noise, TAU_FLOOR)


@functools.partial(jax.jit, static_argnames=("shape", "spacing", "model", "floor", "embed_shape"))
def _grf(
    key: Array,
    mean: ArrayLike,
    std: ArrayLike,
    length_scale: ArrayLike,
    angle_deg: ArrayLike,
    trend: ArrayLike,
    *,
    shape: tuple[int, ...],
    spacing: tuple[float, ...],
    model: str,
    floor: float | None,
    embed_shape: tuple[int, ...],
) -> Array:
    ndim = len(shape)
    dtype = jnp.result_type(float)
    # signed minimum-image lags of the periodic embedding [m]
    lags = []
    for axis, (m, h) in enumerate(zip(embed_shape, spacing, strict=True)):
        k = jnp.arange(m)
        lag = jnp.where(k <= m // 2, k, k - m).astype(dtype) * h
        lags.append(jnp.reshape(lag, [-1 if a == axis else 1 for a in range(ndim)]))
    rho = correlation(tuple(lags), length_scale, angle_deg=angle_deg, model=model)
    eig = jnp.real(jnp.fft.fftn(rho))  # real: the embedded covariance is symmetric
    n_embed = math.prod(embed_shape)
    # eigenvalues below the rounding level of the largest are noise (the sqrt would amplify
    # it to ~sqrt(eps) of the field in float32): drop them, with the negative ones
    cut = 16.0 * jnp.finfo(eig.dtype).eps * jax.lax.stop_gradient(jnp.max(eig))
    pos = eig > cut
    amplitude = jnp.where(pos, jnp.sqrt(jnp.where(pos, eig, 1.0) / n_embed), 0.0)
    # white noise drawn in float32 whatever the precision: a float64 draw is a different
    # sample, so the same seed would give another field once jax_enable_x64 is on (a
    # float64 run, or any earlier call in the session that enabled it)
    noise = jax.random.normal(key, (2, *embed_shape), jnp.float32).astype(dtype)
    z = jnp.real(jnp.fft.fftn(amplitude * (noise[0] + 1j * noise[1])))
    z = z[tuple(slice(0, n) for n in shape)]

    grad = jnp.ravel(jnp.asarray(trend, dtype))
    if grad.size == 1 and ndim == 2:  # a scalar trend is along x (up-slope)
        grad = jnp.concatenate([grad, jnp.zeros(1, dtype)])
    field = jnp.asarray(mean, dtype) + jnp.asarray(std, dtype) * z
    for axis, (n, h) in enumerate(zip(shape, spacing, strict=True)):
        coord = jnp.arange(n, dtype=dtype) * h  # measured from the first node
        field = field + grad[axis] * jnp.reshape(
            coord, [-1 if a == axis else 1 for a in range(ndim)]
        )
    if floor is not None:
        field = jnp.maximum(field, floor)
    return field


def grid_coordinates(
    shape: Sequence[int], dx: float | Sequence[float], origin: Sequence[float] | float = 0.0
) -> tuple[np.ndarray, ...]:
    """Node coordinates [m] of a grid, as 1D arrays, one per axis (``x`` then ``y``)."""
    ndim = len(shape)
    spacing = np.broadcast_to(np.asarray(dx, dtype=float), (ndim,))
    org = np.broadcast_to(np.asarray(origin, dtype=float), (ndim,))
    return tuple(o + h * np.arange(n) for n, h, o in zip(shape, spacing, org, strict=True))


# --------------------------------------------------------------------------------------
# maximum-likelihood fit of a GRF to a map
# --------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class GRFFit:
    """Maximum-likelihood GRF parameters of a strength map (the arguments of `grf`).

    Attributes:
        mean: expected tau_p at `origin` [Pa].
        origin: ``(min x, min y)`` of the map [m]: node 0 of a `grf` grid laid on the map.
        trend: mean gradient ``(gx, gy)`` [Pa/m].
        std: standard deviation of the correlated fluctuation [Pa].
        length_scale: correlation lengths ``(l1, l2)`` [m].
        angle_deg: rotation of the principal axes (held fixed in the fit) [deg].
        model: covariance model.
        nugget_std: standard deviation of the uncorrelated (measurement) noise [Pa].
        neg_log_likelihood: the minimised Gaussian negative log-likelihood of the map
            values (constants included, for comparing models) [-].
        n_points: number of map values used (NaNs dropped).
        n_iterations: L-BFGS iterations taken, summed over the starts.
        converged: whether the gradient norm fell below `tol` (False: the iteration cap
            was reached or the line search failed; check the parameters).
    """

    mean: float
    origin: tuple[float, float]
    trend: tuple[float, float]
    std: float
    length_scale: tuple[float, float]
    angle_deg: float
    model: str
    nugget_std: float
    neg_log_likelihood: float
    n_points: int
    n_iterations: int
    converged: bool

    def grf_kwargs(self) -> dict:
        """Keyword arguments of `grf` that reproduce the fitted field (without the nugget)."""
        return dict(
            mean=self.mean,
            std=self.std,
            length_scale=self.length_scale,
            angle_deg=self.angle_deg,
            model=self.model,
            trend=self.trend,
        )


def fit_grf(
    x: ArrayLike,
    y: ArrayLike,
    tau: ArrayLike,
    *,
    model: CovarianceModel = "gaussian",
    angle_deg: float = 0.0,
    isotropic: bool = False,
    length_scale0: float | Sequence[float] | None = None,
    nugget: float | None = None,
    max_iterations: int = 200,
    tol: float = 1e-6,
) -> GRFFit:
    """Fit mean, trend, variance and correlation lengths of a GRF to a map, by maximum likelihood.

    The model is tau = mean + gx x + gy y + std Z + noise, Z the unit field of `grf` and
    the noise white with variance nugget * std^2. For given correlation lengths (and nugget
    ratio) the likelihood is maximised in closed form over the mean and trend (generalised
    least squares) and over the variance (profile likelihood), so L-BFGS (optax) only
    searches the log correlation lengths and the log nugget ratio: the same maximum as a
    search over all parameters, reached in a few tens of iterations. The covariance is
    dense (a Cholesky factorisation and an inverse per evaluation, O(n^3) in the number n
    of map values): measured on 2 quiet CPU cores (Intel Xeon) with the default four
    starts, a 16 x 16 map takes 2.6 s, 32 x 32 14 s, 48 x 48 58 s, and 64 x 64 some
    minutes; one start (`length_scale0` a single value) about a quarter. The fit runs in
    float64 whatever jax's default, because the Gaussian covariance of a fine grid is
    ill-conditioned. A noise-free map of a Gaussian-covariance field is a degenerate case
    (the likelihood is then very sharp and the variance poorly determined); measured maps
    carry noise, which the fitted nugget absorbs.

    The likelihood can have more than one local maximum in the correlation length (the
    shipped synthetic map, 25 x 30 nodes, has one at l = 8.7 m, std 254 Pa, besides the
    global one at l = 7.9 m, std 86 Pa). So the search starts from several lengths and
    keeps the best: by default 4, at 1/16, 1/8, 1/4 and 1/2 of the map size (the same
    compiled search runs once per start).

    Args:
        x, y: coordinates of the map values [m], arrays of the shape of `tau` (e.g. a
            meshgrid with ``indexing="ij"``, or scattered points).
        tau: measured strength [Pa]; NaNs (missing values) are ignored.
        model: covariance model, ``"gaussian"`` or ``"exponential"``.
        angle_deg: orientation of the principal axes [deg], held fixed.
        isotropic: fit one correlation length for both axes.
        length_scale0: initial correlation length(s) [m]: one start or a sequence of
            starts (default: 1/16, 1/8, 1/4 and 1/2 of the map size).
        nugget: fixed noise-to-field variance ratio [-]; None (default) fits it (from
            1e-8 up: a floor that keeps the covariance of a smooth field invertible).
        max_iterations: L-BFGS iteration cap.
        tol: stop when the gradient norm (per point) falls below this.
    """
    if model not in _MODELS:
        raise ValueError(f"fit_grf: model={model!r}, expected one of {_MODELS}")
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    t = np.asarray(tau, dtype=float).ravel()
    if not x.size == y.size == t.size:
        raise ValueError(f"fit_grf: x, y and tau sizes differ ({x.size}, {y.size}, {t.size})")
    ok = np.isfinite(t) & np.isfinite(x) & np.isfinite(y)
    x, y, t = x[ok], y[ok], t[ok]
    n = t.size
    if n < 10:
        raise ValueError(f"fit_grf: {n} finite map values; need at least 10")
    if np.ptp(x) == 0 or np.ptp(y) == 0:
        raise ValueError(
            "fit_grf: x and y must both vary (a 2D map); fit a transect with "
            "fit_linear_profile or fit_power_law_profile"
        )
    # centre and scale for conditioning; undone at the end
    xm, ym, tm, ts = x.mean(), y.mean(), t.mean(), t.std()
    ts = ts if ts > 0 else 1.0
    extent = max(np.ptp(x), np.ptp(y), 1e-12)
    if length_scale0 is None:
        starts = extent * np.array([1 / 16, 1 / 8, 1 / 4, 1 / 2])
    else:
        starts = np.atleast_1d(np.asarray(length_scale0, dtype=float)).ravel()
        if starts.size == 0 or not np.all(np.isfinite(starts) & (starts > 0)):
            raise ValueError(
                f"fit_grf: length_scale0={length_scale0!r} must be > 0 [m] (one value or a "
                "sequence of starting lengths)"
            )
    n_len = 1 if isotropic else 2

    # lengths stay within [1e-3, 10] x map size (beyond it they are not identifiable)
    bounds = (float(np.log(1e-3 * extent)), float(np.log(10.0 * extent)))
    with jax.enable_x64(True):
        xc, yc = jnp.asarray(x - xm), jnp.asarray(y - ym)
        data = (
            xc[:, None] - xc[None, :],
            yc[:, None] - yc[None, :],
            jnp.asarray((t - tm) / ts),
            jnp.stack([jnp.ones_like(xc), xc, yc], axis=1),
            jnp.asarray(float(angle_deg)),
            jnp.asarray(np.nan if nugget is None else float(nugget)),
            jnp.asarray(bounds),
        )
        best = None
        count = 0
        for l0 in starts:
            theta0 = np.concatenate([np.full(n_len, np.log(l0)), [np.log(1e-2)]])
            found = _ml_search(
                jnp.asarray(theta0),
                data,
                jnp.asarray(float(tol)),
                model=model,
                n_len=n_len,
                max_iterations=max_iterations,
            )
            count += int(found[5])
            # a start whose value is not finite (failed factorisations) never wins
            if np.isfinite(float(found[1])) and (best is None or float(found[1]) < float(best[1])):
                best = found
        if best is None:
            raise RuntimeError(
                "fit_grf: the likelihood could not be evaluated from any starting length "
                f"({', '.join(f'{v:.3g}' for v in starts)} m); try other length_scale0"
            )
        theta, value, beta, var, ratio, _, converged = best
        ls = np.broadcast_to(np.exp(np.clip(np.asarray(theta[:n_len]), *bounds)), (2,))
        beta = np.asarray(beta, dtype=float)
        var, ratio, value = float(var), float(ratio), float(value)
    gx, gy = beta[1] * ts, beta[2] * ts
    x0, y0 = float(x.min()), float(y.min())
    return GRFFit(
        mean=float(tm + ts * beta[0] + gx * (x0 - xm) + gy * (y0 - ym)),
        origin=(x0, y0),
        trend=(float(gx), float(gy)),
        std=float(ts * np.sqrt(var)),
        length_scale=(float(ls[0]), float(ls[1])),
        angle_deg=float(angle_deg),
        model=model,
        nugget_std=float(ts * np.sqrt(var * ratio)),
        # back to the likelihood of tau in Pa (the scaling adds n log ts)
        neg_log_likelihood=float(
            n * value + n * np.log(ts) + 0.5 * n * np.log(2 * np.pi) + 0.5 * n
        ),
        n_points=int(n),
        n_iterations=int(count),
        converged=bool(converged),
    )


def _correlation_matrix(theta: Array, data: tuple, model: str, n_len: int) -> Array:
    """Correlation matrix of the map values plus the nugget, for theta = (log l, log ratio)."""
    hx, hy, _, _, angle_deg, nugget, bounds = data
    ls = jnp.broadcast_to(jnp.exp(jnp.clip(theta[:n_len], bounds[0], bounds[1])), (2,))
    # nugget is NaN when fitted: the ratio is then _NUGGET_FLOOR + exp(theta[-1])
    ratio = jnp.where(jnp.isnan(nugget), _NUGGET_FLOOR + jnp.exp(theta[-1]), nugget)
    corr = correlation((hx, hy), ls, angle_deg=angle_deg, model=model)
    return corr + ratio * jnp.eye(hx.shape[0], dtype=hx.dtype)


def _profile_terms(theta: Array, data: tuple, model: str, n_len: int) -> tuple[Array, ...]:
    """Profile negative log-likelihood per point, its Cholesky factor, K^-1 r, beta, var."""
    _, _, z, design, *_ = data
    n = z.size
    chol = jnp.linalg.cholesky(_correlation_matrix(theta, data, model, n_len))

    def solve(b):
        return jax.scipy.linalg.cho_solve((chol, True), b)

    ki_x = solve(design)
    beta = jnp.linalg.solve(design.T @ ki_x, ki_x.T @ z)  # generalised least squares
    alpha = solve(z - design @ beta)
    var = (z - design @ beta) @ alpha / n  # profile variance
    nll = 0.5 * n * jnp.log(var) + jnp.sum(jnp.log(jnp.diag(chol)))
    return nll / n, chol, alpha, beta, var


@functools.partial(jax.custom_vjp, nondiff_argnums=(2, 3))
def _profile_nll(theta: Array, data: tuple, model: str, n_len: int) -> Array:
    """Profile negative log-likelihood per point, with a hand-written gradient.

    Mean, trend (GLS beta) and variance are at their optimum for every theta, so by the
    envelope theorem d nll / d theta_k = 1/2 tr((K^-1 - alpha alpha^T / var) dK/dtheta_k)
    (alpha = K^-1 r): one Cholesky factorisation and one inverse, several times cheaper
    than differentiating through the factorisation.
    """
    value = _profile_terms(theta, data, model, n_len)[0]
    return jnp.where(jnp.isfinite(value), value, jnp.inf)


def _profile_nll_fwd(theta, data, model, n_len):
    value, chol, alpha, _, var = _profile_terms(theta, data, model, n_len)
    n = alpha.size
    eye = jnp.eye(n, dtype=alpha.dtype)
    k_inv = jax.scipy.linalg.cho_solve((chol, True), eye)
    weight = 0.5 * (k_inv - jnp.outer(alpha, alpha) / var) / n
    grads = []
    for k in range(theta.size):  # dK/dtheta_k elementwise, by forward mode (n^2 each)
        tangent = jnp.zeros_like(theta).at[k].set(1.0)
        _, dk = jax.jvp(
            lambda th: _correlation_matrix(th, data, model, n_len), (theta,), (tangent,)
        )
        grads.append(jnp.sum(weight * dk))
    # a failed factorisation (not positive definite) is an infinitely bad point, so that
    # the line search steps back instead of carrying NaNs
    ok = jnp.isfinite(value)
    grad = jnp.where(ok, jnp.stack(grads), 0.0)
    return jnp.where(ok, value, jnp.inf), (grad, data)


def _profile_nll_bwd(model, n_len, residuals, g):
    grad, data = residuals
    return g * grad, jax.tree.map(jnp.zeros_like, data)


_profile_nll.defvjp(_profile_nll_fwd, _profile_nll_bwd)


@functools.partial(jax.jit, static_argnames=("model", "n_len", "max_iterations"))
def _ml_search(
    theta0: Array,
    data: tuple,
    tol: Array,
    *,
    model: str,
    n_len: int,
    max_iterations: int,
) -> tuple[Array, ...]:
    """L-BFGS over theta = (log lengths, log nugget ratio) of the profile likelihood.

    Compiled once per (map size, model, n_len): the data are arguments, not constants.
    """

    def objective(theta):
        return _profile_nll(theta, data, model, n_len)

    opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(objective)

    def step(carry):
        theta, state = carry
        value, grad = value_and_grad(theta, state=state)
        updates, state = opt.update(grad, state, theta, value=value, grad=grad, value_fn=objective)
        return optax.apply_updates(theta, updates), state

    def keep_going(carry):
        _, state = carry
        count = optax.tree.get(state, "count")
        gnorm = optax.tree.norm(optax.tree.get(state, "grad"))
        return (count == 0) | ((count < max_iterations) & (gnorm >= tol))

    theta, state = jax.lax.while_loop(keep_going, step, (theta0, opt.init(theta0)))
    value, _, _, beta, var = _profile_terms(theta, data, model, n_len)
    ratio = jnp.diagonal(_correlation_matrix(theta, data, model, n_len))[0] - 1.0
    converged = optax.tree.norm(optax.tree.get(state, "grad")) < tol
    return theta, value, beta, var, ratio, optax.tree.get(state, "count"), converged


# --------------------------------------------------------------------------------------
# PST strength profiles
# --------------------------------------------------------------------------------------


def _safe_power(s: Array, b: ArrayLike) -> Array:
    """s^b for s >= 0, zero at s = 0, with finite gradients in b and s there."""
    pos = s > 0
    return jnp.where(pos, jnp.where(pos, s, 1.0) ** b, 0.0)


def linear_profile(
    x: ArrayLike,
    tau_peak: ArrayLike = 1000.0,
    steady_length: ArrayLike = 20.0,
    theta: ArrayLike = 500.0,
) -> Array:
    """The paper's PST strength: tau_p = tau_peak for x <= L_ss, + theta (x - L_ss) beyond.

    Args:
        x: position along the PST from its bottom end [m].
        tau_peak: weak-layer peak shear strength on [0, L_ss] [Pa].
        steady_length: steady-state length L_ss [m].
        theta: strength gradient beyond L_ss [Pa/m].

    Returns:
        tau_p(x) [Pa] (differentiable in every argument).
    """
    x = jnp.asarray(x)
    return tau_peak + theta * jnp.maximum(x - steady_length, 0.0)


def power_law_profile(
    x: ArrayLike,
    a: ArrayLike,
    b: ArrayLike,
    *,
    tau_peak: ArrayLike = 1000.0,
    steady_length: ArrayLike = 20.0,
) -> Array:
    """Power-law PST strength: tau_p = tau_peak + a (x - L_ss)^b beyond L_ss (paper Fig. 11).

    b = 1 is `linear_profile` with theta = a.

    Args:
        x: position along the PST [m].
        a: prefactor [Pa / m^b].
        b: exponent [-] (> 0).
        tau_peak: tau_p on [0, L_ss] [Pa].
        steady_length: L_ss [m].

    Returns:
        tau_p(x) [Pa] (differentiable in every argument).
    """
    x = jnp.asarray(x)
    return tau_peak + a * _safe_power(jnp.maximum(x - steady_length, 0.0), b)


@dataclasses.dataclass(frozen=True)
class LinearProfileFit:
    """Least-squares fit tau = tau0 + theta (x - x0) to a transect (x0: its first point).

    Attributes:
        theta: strength gradient [Pa/m]; theta_se its standard error.
        tau0: fitted strength at x0 [Pa]; tau0_se its standard error.
        x0: first position of the transect [m].
        residual_std: standard deviation of the residuals [Pa].
        n: number of points.
    """

    theta: float
    tau0: float
    theta_se: float
    tau0_se: float
    x0: float
    residual_std: float
    n: int

    def __call__(self, x: ArrayLike) -> np.ndarray:
        """The fitted strength at x [Pa]."""
        return self.tau0 + self.increment(np.asarray(x, dtype=float) - self.x0)

    def increment(self, s: ArrayLike) -> np.ndarray:
        """Strength gained a distance s >= 0 up the transect [Pa]."""
        return self.theta * np.asarray(s, dtype=float)


@dataclasses.dataclass(frozen=True)
class PowerLawProfileFit:
    """Least-squares fit of a power law to a transect.

    With ``offset=True`` (default) tau = tau0 + a (x - x0)^b, x0 the first point: the
    measured strength is offset by the weak spot where the transect starts, and the
    increment a s^b is what `pst_profile` transfers to a PST. With ``offset=False``,
    tau = a x^b (tau0 = 0, x0 = 0).

    Attributes:
        a: prefactor [Pa / m^b]; b: exponent [-]; tau0: strength at x0 [Pa]; each with its
            standard error (``*_se``, tau0_se = 0 when not fitted).
        x0: origin of the power law [m].
        residual_std: standard deviation of the residuals [Pa].
        n: number of points.
        covariance: covariance of (a, b[, tau0]).
    """

    a: float
    b: float
    tau0: float
    a_se: float
    b_se: float
    tau0_se: float
    x0: float
    residual_std: float
    n: int
    covariance: np.ndarray = dataclasses.field(repr=False, compare=False)

    def __call__(self, x: ArrayLike) -> np.ndarray:
        """The fitted strength at x [Pa]."""
        return self.tau0 + self.increment(np.asarray(x, dtype=float) - self.x0)

    def increment(self, s: ArrayLike) -> np.ndarray:
        """Strength gained a distance s >= 0 from x0 [Pa]."""
        s = np.maximum(np.asarray(s, dtype=float), 0.0)
        return self.a * np.where(s > 0, np.where(s > 0, s, 1.0) ** self.b, 0.0)


def _transect(x: ArrayLike, tau: ArrayLike, min_points: int, name: str):
    x = np.asarray(x, dtype=float).ravel()
    t = np.asarray(tau, dtype=float).ravel()
    if x.size != t.size:
        raise ValueError(f"{name}: x and tau have {x.size} and {t.size} values")
    if x.size < min_points:
        raise ValueError(f"{name}: {x.size} points; need at least {min_points}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(t))):
        raise ValueError(f"{name}: x and tau must be finite")
    if np.unique(x).size < 2:
        raise ValueError(f"{name}: x must take at least 2 different values (all {x[0]:g} m)")
    order = np.argsort(x, kind="stable")
    return x[order], t[order]


def fit_linear_profile(x: ArrayLike, tau: ArrayLike) -> LinearProfileFit:
    """Fit a linear strength gradient to a measured transect (ordinary least squares).

    Standard errors are the square roots of the diagonal of s^2 (J^T J)^-1, s^2 the residual
    variance with n - 2 degrees of freedom.

    Args:
        x: positions along the transect [m].
        tau: measured peak shear strength [Pa].
    """
    x, t = _transect(x, tau, 3, "fit_linear_profile")
    x0 = float(x[0])
    jac = np.stack([np.ones_like(x), x - x0], axis=1)
    coef, cov, s2 = _linear_lsq(jac, t)
    se = np.sqrt(np.diag(cov))
    return LinearProfileFit(
        theta=float(coef[1]),
        tau0=float(coef[0]),
        theta_se=float(se[1]),
        tau0_se=float(se[0]),
        x0=x0,
        residual_std=float(np.sqrt(s2)),
        n=int(x.size),
    )


def _linear_lsq(jac: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares coefficients, their covariance and the residual variance."""
    coef, *_ = np.linalg.lstsq(jac, t, rcond=None)
    resid = t - jac @ coef
    dof = max(t.size - jac.shape[1], 1)
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    return coef, cov, s2


def fit_power_law_profile(
    x: ArrayLike,
    tau: ArrayLike,
    *,
    offset: bool = True,
    b_bounds: tuple[float, float] = (0.05, 20.0),
) -> PowerLawProfileFit:
    """Fit a power law to a measured transect (nonlinear least squares, numpy only).

    The model is linear in (tau0, a) for a fixed exponent b, so the fit is separable: a
    bracketing search over log b of the residual sum of squares, with (tau0, a) from linear
    least squares at each b, then a golden-section refinement. Standard errors come from
    the full Jacobian at the optimum, cov = s^2 (J^T J)^-1 with n - p degrees of freedom.

    Args:
        x: positions along the transect [m] (> 0 when ``offset=False``).
        tau: measured peak shear strength [Pa].
        offset: fit tau = tau0 + a (x - x0)^b, x0 = min(x) (default); False: tau = a x^b.
        b_bounds: search interval of the exponent b [-].
    """
    name = "fit_power_law_profile"
    x, t = _transect(x, tau, 4 if offset else 3, name)
    if not 0 < b_bounds[0] < b_bounds[1] < math.inf:
        raise ValueError(
            f"{name}: b_bounds = {b_bounds!r}: must be (b_min, b_max), 0 < b_min < b_max"
        )
    x0 = float(x[0]) if offset else 0.0
    s = x - x0
    if not offset and np.any(s <= 0):
        raise ValueError(f"{name}: offset=False needs x > 0 (min x = {x[0]:g} m)")
    logs = np.log(np.where(s > 0, s, 1.0))

    def basis(b: float) -> np.ndarray:
        sb = np.where(s > 0, np.exp(b * logs), 0.0)
        return np.stack([sb, np.ones_like(s)], axis=1) if offset else sb[:, None]

    def sse(log_b: float) -> float:
        jac = basis(math.exp(log_b))
        coef, *_ = np.linalg.lstsq(jac, t, rcond=None)
        r = t - jac @ coef
        return float(r @ r)

    lo, hi = math.log(b_bounds[0]), math.log(b_bounds[1])
    grid = np.linspace(lo, hi, 81)
    values = [sse(g) for g in grid]
    k = int(np.argmin(values))
    a_, c_ = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    for _ in range(60):  # golden section on the bracket around the best grid point
        p = c_ - golden * (c_ - a_)
        q = a_ + golden * (c_ - a_)
        if sse(p) < sse(q):
            c_ = q
        else:
            a_ = p
    b = math.exp(0.5 * (a_ + c_))
    coef, *_ = np.linalg.lstsq(basis(b), t, rcond=None)
    a = float(coef[0])
    tau0 = float(coef[1]) if offset else 0.0
    sb = basis(b)[:, 0]
    # Jacobian of the model in (a, b[, tau0])
    cols = [sb, a * sb * logs] + ([np.ones_like(s)] if offset else [])
    jac = np.stack(cols, axis=1)
    resid = t - (tau0 + a * sb)
    dof = max(t.size - jac.shape[1], 1)
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    se = np.sqrt(np.diag(cov))
    return PowerLawProfileFit(
        a=a,
        b=b,
        tau0=tau0,
        a_se=float(se[0]),
        b_se=float(se[1]),
        tau0_se=float(se[2]) if offset else 0.0,
        x0=x0,
        residual_std=math.sqrt(s2),
        n=int(x.size),
        covariance=cov,
    )


def pst_profile(
    fit: LinearProfileFit | PowerLawProfileFit,
    x: ArrayLike,
    *,
    steady_length: float = 20.0,
    tau_peak: float = 1000.0,
) -> np.ndarray:
    """A fitted transect shifted to tau_p = tau_peak at L_ss and extrapolated over a PST.

    As in the paper's in-situ cases (Figs. 10b, 11b): tau_p = tau_peak on [0, L_ss] and
    tau_p = tau_peak + increment(x - L_ss) beyond, the increment being the fitted strength
    gain from the start of the transect (theta s, or a s^b), extended past the measured
    range. For a PST of length L on m equally spaced points, ``x = np.linspace(0, L, m)``
    gives the array `damjax.PSTParams(strength_profile=...)` expects.

    Args:
        fit: a `LinearProfileFit` or `PowerLawProfileFit`.
        x: positions along the PST [m].
        steady_length: L_ss [m].
        tau_peak: tau_p on [0, L_ss] [Pa] (1 kPa in the paper).

    Returns:
        tau_p(x) [Pa], a float64 numpy array.
    """
    x = np.asarray(x, dtype=float)
    return tau_peak + fit.increment(np.maximum(x - steady_length, 0.0))


# --------------------------------------------------------------------------------------
# CSV loaders
# --------------------------------------------------------------------------------------

_MISSING = {"", "nan", "na", "n/a", "null", "none"}


def _read_csv(
    path: str | os.PathLike, columns: Sequence[str]
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, int]]:
    """Read the named numeric columns of a CSV with '#' comments.

    Returns the arrays by name, the (1-based) file line of every row and the (1-based) file
    column of every name. Every problem is a one-line ValueError
    ``"<file>:<line>: column '<name>' (<k>): <problem>"``.
    """
    path = os.fspath(path)
    with open(path, encoding="utf-8-sig") as f:
        lines = f.read().splitlines()
    header, index, rows, linenos = None, {}, [], []
    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        cells = [c.strip() for c in line.split(",")]
        if header is None:
            header = cells
            for name in columns:
                if name not in header:
                    raise ValueError(
                        f"{path}:{lineno}: header has no column {name!r} "
                        f"(found {', '.join(header)}; expected {', '.join(columns)})"
                    )
                index[name] = header.index(name)
            continue
        if len(cells) != len(header):
            raise ValueError(f"{path}:{lineno}: {len(cells)} fields, the header has {len(header)}")
        values = []
        for name in columns:
            k = index[name]
            cell = cells[k]
            where = f"{path}:{lineno}: column {name!r} ({k + 1})"
            if cell.lower() in _MISSING:
                raise ValueError(f"{where}: missing value")
            try:
                v = float(cell)
            except ValueError:
                raise ValueError(f"{where}: {cell!r} is not a number") from None
            if not math.isfinite(v):
                raise ValueError(f"{where}: missing or infinite value {cell!r}")
            values.append(v)
        rows.append(values)
        linenos.append(lineno)
    if header is None:
        raise ValueError(f"{path}: no header line (expected {', '.join(columns)})")
    data = np.asarray(rows, dtype=float).reshape(-1, len(columns))
    cols = {name: data[:, i] for i, name in enumerate(columns)}
    return cols, np.asarray(linenos), {name: k + 1 for name, k in index.items()}


def _check_nonnegative(path, cols: dict, names: Sequence[str], linenos, index: dict) -> None:
    for name in names:
        bad = np.flatnonzero(cols[name] < 0)
        if bad.size:
            i = bad[0]
            raise ValueError(
                f"{os.fspath(path)}:{linenos[i]}: column {name!r} ({index[name]}): "
                f"negative value {cols[name][i]:g}"
            )


def load_strength_profile(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a measured strength transect from a CSV file.

    The file has a header line with the columns ``x_m`` (position along the transect [m],
    >= 0, strictly increasing) and ``tau_peak_pa`` (peak shear strength [Pa], >= 0); other
    columns are ignored; lines starting with ``#`` and blank lines are skipped. Problems
    raise a one-line ValueError naming the file, the line and the column.

    Returns:
        ``(x_m, tau_peak_pa)``, float64 arrays.
    """
    names = ("x_m", "tau_peak_pa")
    cols, linenos, index = _read_csv(path, names)
    if cols["x_m"].size < 2:
        raise ValueError(f"{os.fspath(path)}: {cols['x_m'].size} data rows; need at least 2")
    _check_nonnegative(path, cols, names, linenos, index)
    x = cols["x_m"]
    for i in range(1, x.size):
        if x[i] == x[i - 1]:
            raise ValueError(
                f"{os.fspath(path)}:{linenos[i]}: column 'x_m' ({index['x_m']}): duplicate "
                f"x_m {x[i]:g} (also on line {linenos[i - 1]})"
            )
        if x[i] < x[i - 1]:
            raise ValueError(
                f"{os.fspath(path)}:{linenos[i]}: column 'x_m' ({index['x_m']}): unsorted, "
                f"x_m {x[i]:g} < {x[i - 1]:g} on line {linenos[i - 1]}; sort the rows by x_m"
            )
    return x, cols["tau_peak_pa"]


PROFILE_FITS = ("none", "linear", "power_law")


def pst_strength_profile(
    path: str | os.PathLike,
    length: float,
    num: int,
    *,
    fit: str = "none",
    steady_length: float = 20.0,
    tau_peak: float = 1000.0,
) -> np.ndarray:
    """A CSV strength transect as the ``strength_profile`` array of `damjax.PSTParams`.

    The CSV is read with `load_strength_profile` (columns x_m, tau_peak_pa; one-line
    errors). With ``fit="none"`` the values are tau_p along the PST itself: x_m is the
    PST coordinate [m], tau_p is linearly interpolated between the rows and held at the
    first/last value beyond them. With ``fit="linear"`` or ``"power_law"`` the file is a
    measured transect: the fit (`fit_linear_profile`, `fit_power_law_profile`) is shifted
    to tau_p = ``tau_peak`` at L_ss and extrapolated over the PST (`pst_profile`, the
    paper's in-situ workflow, Figs. 10-11).

    Args:
        path: CSV file.
        length: PST length L [m].
        num: number of equally spaced points spanning [0, L] (>= 2).
        fit: "none", "linear" or "power_law".
        steady_length: L_ss [m] (fits only).
        tau_peak: tau_p on [0, L_ss] [Pa] (fits only).

    Returns:
        tau_p at ``np.linspace(0, length, num)`` [Pa], float64.
    """
    if fit not in PROFILE_FITS:
        raise ValueError(
            f"strength profile fit {fit!r}: must be one of {{{', '.join(PROFILE_FITS)}}}"
        )
    x, tau = load_strength_profile(path)
    xs = np.linspace(0.0, float(length), int(num))
    if fit == "none":
        if x[0] > 0.0 or x[-1] < float(length):
            import warnings

            warnings.warn(
                f"{os.fspath(path)}: x_m covers [{x[0]:g}, {x[-1]:g}] m of the "
                f"[0, {float(length):g}] m PST; tau_p is held constant beyond",
                stacklevel=2,
            )
        return np.interp(xs, x, tau)
    try:
        fitted = fit_linear_profile(x, tau) if fit == "linear" else fit_power_law_profile(x, tau)
    except ValueError as exc:  # name the file and the fit, not the function
        msg = str(exc).split(": ", 1)[-1]
        raise ValueError(f"{os.fspath(path)}: {fit.replace('_', '-')} fit: {msg}") from None
    return pst_profile(fitted, xs, steady_length=steady_length, tau_peak=tau_peak)


def load_strength_map(
    path: str | os.PathLike, **kwargs
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a strength map on a regular grid: CSV (columns x_m, y_m, tau_peak_pa), NetCDF
    (.nc) or GeoTIFF (.tif, needs rasterio), chosen by the suffix.

    NetCDF and GeoTIFF go through the DEM readers (`damjax.terrain.load_netcdf`,
    `damjax.terrain.load_geotiff`, same conventions: metric coordinates, north-up rasters,
    nodata as NaN); keyword arguments go to them (``variable=``, ``band=``). The values
    are tau_p [Pa].

    Rows may come in any order but must fill a complete grid, each node once; tau_peak_pa
    must be >= 0. Errors are one-line ValueErrors naming the file and line.

    Returns:
        ``(x, y, tau)``: node coordinates x (nx,) and y (ny,) [m], ascending, and tau_p
        (nx, ny) [Pa], indexed ``[ix, iy]``.
    """
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    if suffix in (".nc", ".nc4", ".cdf", ".netcdf", ".tif", ".tiff", ".gtiff"):
        from damjax import terrain

        ter = terrain.load_dem(path, **kwargs)
        if np.any(ter.z[np.isfinite(ter.z)] < 0):
            raise ValueError(f"{os.fspath(path)}: negative strength values")
        return ter.x, ter.y, ter.z
    names = ("x_m", "y_m", "tau_peak_pa")
    cols, linenos, index = _read_csv(path, names)
    if cols["x_m"].size == 0:
        raise ValueError(f"{os.fspath(path)}: no data rows (a header alone)")
    _check_nonnegative(path, cols, ("tau_peak_pa",), linenos, index)
    xs, ix = np.unique(cols["x_m"], return_inverse=True)
    ys, iy = np.unique(cols["y_m"], return_inverse=True)
    tau = np.full((xs.size, ys.size), np.nan)
    seen = np.full((xs.size, ys.size), -1)
    for r, (i, j) in enumerate(zip(ix, iy, strict=True)):
        if seen[i, j] >= 0:
            raise ValueError(
                f"{os.fspath(path)}:{linenos[r]}: duplicate node ({xs[i]:g}, {ys[j]:g}) "
                f"(also on line {linenos[seen[i, j]]})"
            )
        seen[i, j] = r
        tau[i, j] = cols["tau_peak_pa"][r]
    if np.any(seen < 0):
        i, j = np.argwhere(seen < 0)[0]
        raise ValueError(
            f"{os.fspath(path)}: node ({xs[i]:g}, {ys[j]:g}) is missing; the map must fill a "
            f"{xs.size} x {ys.size} grid"
        )
    for name, v in (("x_m", xs), ("y_m", ys)):
        d = np.diff(v)
        if d.size and np.ptp(d) > 1e-6 * max(float(np.max(np.abs(v))), 1.0):
            raise ValueError(
                f"{os.fspath(path)}: column '{name}' is not evenly spaced (steps "
                f"{float(d.min()):g} to {float(d.max()):g} m); the map must be a regular grid"
            )
    return xs, ys, tau


def map_on_grid(
    x: ArrayLike, y: ArrayLike, tau: ArrayLike, xq: ArrayLike, yq: ArrayLike
) -> np.ndarray:
    """A strength map (nodes x (nx,), y (ny,) [m], tau (nx, ny) [Pa]) on another grid.

    Bilinear interpolation at the nodes ``xq`` (mx,), ``yq`` (my,) [m] (e.g. the cell
    centres of a slope run, `damjax.scenarios.slope.simulate_slope`'s ``tau_peak``);
    points beyond the map take the value of its nearest edge (constant extrapolation).

    Returns:
        tau_p (mx, my) [Pa].
    """
    from damjax.terrain import Terrain

    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    xq = np.clip(np.asarray(xq, dtype=float), x[0], x[-1])
    yq = np.clip(np.asarray(yq, dtype=float), y[0], y[-1])
    # sample, not resample: clipped query nodes repeat, so they are no regular grid
    xx, yy = np.meshgrid(xq, yq, indexing="ij")
    return Terrain(x, y, np.asarray(tau, dtype=float)).sample(xx, yy)


def transect(
    x: ArrayLike,
    y: ArrayLike,
    tau: ArrayLike,
    start: Sequence[float],
    end: Sequence[float],
    num: int = 101,
) -> tuple[np.ndarray, np.ndarray]:
    """Sample a strength map along the straight line from ``start`` to ``end`` (x, y) [m].

    For a slope-parallel transect pass points of equal y. The result feeds
    `fit_linear_profile` / `fit_power_law_profile` (the paper's in-situ gradients).

    Returns:
        ``(s, tau)``: distance from ``start`` (num,) [m] and bilinear tau_p (num,) [Pa].
    """
    from damjax.terrain import Terrain

    t = np.linspace(0.0, 1.0, int(num))
    px = start[0] + t * (end[0] - start[0])
    py = start[1] + t * (end[1] - start[1])
    ter = Terrain(np.asarray(x, float), np.asarray(y, float), np.asarray(tau, float))
    return t * float(np.hypot(end[0] - start[0], end[1] - start[1])), ter.sample(px, py)
