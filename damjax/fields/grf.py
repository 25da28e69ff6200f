"""Gaussian random fields of the weak-layer peak shear strength tau_p (SI units).

`grf`: a seeded, jittable Gaussian random field on a regular 1D or 2D grid (circulant
embedding, i.e. exact FFT spectral synthesis of a stationary covariance), with a mean and
a linear trend; differentiable with respect to the mean, the trend, the standard deviation
and the correlation lengths. `plateau_trend_field`: the paper's arrangement (constant
strength where the crack starts, then a gradient) plus such a field. `correlation`: the
covariance models (gstools' length-scale convention).

Array layout: a 2D field is indexed ``[ix, iy]`` (axis 0 is x, the up-slope coordinate,
axis 1 is y, cross-slope), node ``(i, j)`` sits at ``(x_0 + i dx, y_0 + j dy)``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any, Literal

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from damjax._tracing import is_traced
from damjax.fields.maps import map_on_grid

CovarianceModel = Literal["gaussian", "exponential"]
_MODELS = ("gaussian", "exponential")

TAU_FLOOR = 1.0  # default floor of a sampled tau_p [Pa]: a strength must stay positive

# Correlation lengths of padding added to twice the domain in the circulant embedding. At
# 5 l the Gaussian correlation is 3e-9 and the exponential one 7e-3 (and the wrapped
# distance is at least the domain size on top of that).
_EMBED_PAD_LENGTHS = 5.0


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
    comps = [jnp.asarray(h) for h in lag] if isinstance(lag, (list, tuple)) else [jnp.asarray(lag)]
    if len(comps) not in (1, 2):
        raise ValueError(f"lag has {len(comps)} components; 1D and 2D fields only")
    return _correlation(jnp, comps, length_scale, angle_deg, model)


def _correlation(xp: Any, comps: list[Any], length_scale: Any, angle_deg: Any, model: str) -> Any:
    """`correlation` of 1 or 2 lag components in the array module ``xp`` (numpy on the
    host, jax.numpy when traced)."""
    if len(comps) == 1:
        r2 = (comps[0] / xp.ravel(xp.asarray(length_scale))[0]) ** 2
    else:
        ls = xp.broadcast_to(xp.asarray(length_scale), (2,))
        a = xp.deg2rad(angle_deg)
        u = xp.cos(a) * comps[0] + xp.sin(a) * comps[1]
        v = -xp.sin(a) * comps[0] + xp.cos(a) * comps[1]
        r2 = (u / ls[0]) ** 2 + (v / ls[1]) ** 2
    if model == "gaussian":
        return xp.exp(-0.25 * np.pi * r2)
    # sqrt is not differentiable at 0: guard it (double-where) so gradients stay finite
    pos = r2 > 0
    r = xp.where(pos, xp.sqrt(xp.where(pos, r2, 1.0)), 0.0)
    return xp.exp(-r)


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


def _concrete(value: ArrayLike, name: str) -> np.ndarray:
    """The value of a possibly differentiated argument, or a clear error inside jit."""
    if not is_traced(value):
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
    `length_scale` is traced, pass `embed_shape`. With concrete arguments the transforms
    run on the host in numpy (the same bits on every call, whatever else runs: XLA:CPU's
    FFT is not, see `_grf_host`); traced ones run in XLA and agree to rounding. Draw many
    samples with ``jax.vmap(lambda k: grf(k, ...))(jax.random.split(key, n))``.

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
            for tau_p rising 20 Pa/m up-slope (paper Fig. 13).
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
        if not is_traced(value) and np.size(value) not in sizes:
            raise ValueError(
                f"grf: {name} = {value!r}: must have "
                + " or ".join(str(k) for k in sizes)
                + f" value(s) on a {ndim}D grid"
            )
    if not is_traced(std) and not float(np.asarray(std)) >= 0:
        raise ValueError(f"grf: std = {std!r}: must be in [0, inf) Pa")
    if not is_traced(length_scale):
        ls = np.asarray(length_scale, dtype=float)
        if not np.all(np.isfinite(ls) & (ls > 0)):
            raise ValueError(f"grf: length_scale = {length_scale!r}: must be in (0, inf) m")
    floor = None if floor is None else float(floor)
    if embed_shape is None:
        embed_shape = embedding_shape(shape, spacing, _concrete(length_scale, "length_scale"))
    embed_shape = tuple(int(m) for m in embed_shape)
    if len(embed_shape) != ndim or any(m < n for m, n in zip(embed_shape, shape, strict=True)):
        raise ValueError(f"grf: embed_shape {embed_shape} must cover shape {shape}")
    args = (key, mean, std, length_scale, angle_deg, trend)
    kw = dict(shape=shape, spacing=spacing, model=model, floor=floor, embed_shape=embed_shape)
    if not is_traced(args):
        return jnp.asarray(_grf_host(*args, **kw))
    return _grf(*args, **kw)


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
    (y = ny dx) towards y = 0 (paper Fig. 13b: strength rising across the slope).

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
    noise = _cell_noise(key, x, ny, dx, std, length_scale, angle_deg, model, field_dx)
    return np.maximum(expected + noise, TAU_FLOOR)


def _cell_noise(
    key: Array,
    x: np.ndarray,
    ny: int,
    dx: float,
    std: float,
    length_scale: ArrayLike,
    angle_deg: float,
    model: CovarianceModel,
    field_dx: float | None,
) -> np.ndarray:
    """A zero-mean stationary `grf` sample of standard deviation ``std`` on the cells x
    (nx,) by ny, drawn on cells of ``field_dx`` and interpolated when given
    (`plateau_trend_field`)."""
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
    return noise


def stability_field(
    key: Array,
    x: np.ndarray,
    ny: int,
    dx: float,
    *,
    mean: float,
    cov: float,
    length_scale: ArrayLike,
    angle_deg: float = 0.0,
    model: CovarianceModel = "gaussian",
    field_dx: float | None = None,
) -> np.ndarray:
    """A random field of the weak layer's stability ratio S = tau_p / tau_g on cell
    centres x (nx,) by ny [-] (numpy), above 1 everywhere: a weak layer that held its slab
    until the trigger.

    S - 1 is log-normal, S = 1 + m exp(s Z - s^2 / 2), Z a zero-mean, unit-variance
    stationary `grf` sample (correlation ``length_scale``, ``angle_deg``, ``model``, drawn
    on ``field_dx`` cells as in `plateau_trend_field`), m = mean - 1 and s^2 = ln(1 +
    (cov mean / m)^2): S has the expected value ``mean`` (> 1) and the standard deviation
    ``cov`` x ``mean`` (the coefficient of variation ``cov`` >= 0). ``cov = 0``: S =
    ``mean`` everywhere.
    """
    m = float(mean) - 1.0
    if not (math.isfinite(m) and m > 0):
        raise ValueError(f"mean = {mean!r}: must be in (1, inf)")
    if not (math.isfinite(float(cov)) and cov >= 0):
        raise ValueError(f"cov = {cov!r}: must be in [0, inf)")
    if cov == 0.0:
        return np.full((len(x), ny), float(mean))
    s2 = math.log1p((float(cov) * float(mean) / m) ** 2)
    z = _cell_noise(key, x, ny, dx, 1.0, length_scale, angle_deg, model, field_dx)
    return 1.0 + m * np.exp(math.sqrt(s2) * z - 0.5 * s2)


def _grf_host(
    key: Array,
    mean: ArrayLike,
    std: ArrayLike,
    length_scale: ArrayLike,
    angle_deg: ArrayLike,
    trend: ArrayLike,
    **kw: Any,
) -> np.ndarray:
    """`_grf` for concrete arguments, with numpy's FFT on the host (float64, returned in
    JAX's default float dtype, as `_grf`'s).

    XLA:CPU's FFT splits its lines over the threads that are free at the time, and the
    result changes in the last bits with that split: with a matrix product running on a
    second thread, 3 of 40 draws of the same seed (360 x 225 embedding) differed by a
    float32 rounding step (2026-11-27), enough for two runs of one ensemble to differ.
    numpy's FFT runs on one thread and gives the same bits every time; the white noise is
    JAX's (threefry, the same on every device and thread). The traced path (`_grf`: under
    `jax.grad`, `jax.vmap`, `jax.jit`) keeps XLA's FFT and agrees to rounding.
    """
    f64 = functools.partial(np.asarray, dtype=float)
    args = (f64(mean), f64(std), f64(length_scale), f64(angle_deg), f64(trend))
    field = _circulant_draw(np, float, lambda v: v, key, *args, **kw)
    return field.astype(jnp.result_type(float))


@functools.partial(jax.jit, static_argnames=("shape", "spacing", "model", "floor", "embed_shape"))
def _grf(
    key: Array,
    mean: ArrayLike,
    std: ArrayLike,
    length_scale: ArrayLike,
    angle_deg: ArrayLike,
    trend: ArrayLike,
    **kw: Any,
) -> Array:
    dtype = jnp.result_type(float)
    return _circulant_draw(
        jnp, dtype, jax.lax.stop_gradient, key, mean, std, length_scale, angle_deg, trend, **kw
    )


def _circulant_draw(
    xp: Any,
    dtype: Any,
    stop_gradient: Any,
    key: Array,
    mean: Any,
    std: Any,
    length_scale: Any,
    angle_deg: Any,
    trend: Any,
    *,
    shape: tuple[int, ...],
    spacing: tuple[float, ...],
    model: str,
    floor: float | None,
    embed_shape: tuple[int, ...],
) -> Any:
    """The body of `grf` in the array module ``xp`` (numpy on the host in float64,
    jax.numpy when traced), computing in ``dtype``."""
    ndim = len(shape)
    # signed minimum-image lags of the periodic embedding [m]
    lags = []
    for axis, (m, h) in enumerate(zip(embed_shape, spacing, strict=True)):
        k = xp.arange(m)
        lag = xp.where(k <= m // 2, k, k - m).astype(dtype) * h
        lags.append(xp.reshape(lag, [-1 if a == axis else 1 for a in range(ndim)]))
    rho = _correlation(xp, lags, length_scale, angle_deg, model)
    eig = xp.real(xp.fft.fftn(rho))  # real: the embedded covariance is symmetric
    n_embed = math.prod(embed_shape)
    # eigenvalues below the rounding level of the largest are noise (the sqrt would amplify
    # it to ~sqrt(eps) of the field in float32): drop them, with the negative ones; the
    # rounding level is that of JAX's default float on the host too
    eps = np.finfo(jnp.result_type(float)).eps
    cut = 16.0 * eps * stop_gradient(xp.max(eig))
    pos = eig > cut
    amplitude = xp.where(pos, xp.sqrt(xp.where(pos, eig, 1.0) / n_embed), 0.0)
    # white noise drawn in float32 whatever the precision: a float64 draw is a different
    # sample, so the same seed would give another field once jax_enable_x64 is on (a
    # float64 run, or any earlier call in the session that enabled it)
    noise = xp.asarray(jax.random.normal(key, (2, *embed_shape), jnp.float32), dtype)
    z = xp.real(xp.fft.fftn(amplitude * (noise[0] + 1j * noise[1])))
    z = z[tuple(slice(0, n) for n in shape)]

    grad = xp.ravel(xp.asarray(trend, dtype))
    if grad.size == 1 and ndim == 2:  # a scalar trend is along x (up-slope)
        grad = xp.concatenate([grad, xp.zeros(1, dtype)])
    field = xp.asarray(mean, dtype) + xp.asarray(std, dtype) * z
    for axis, (n, h) in enumerate(zip(shape, spacing, strict=True)):
        coord = xp.arange(n, dtype=dtype) * h  # measured from the first node
        field = field + grad[axis] * xp.reshape(
            coord, [-1 if a == axis else 1 for a in range(ndim)]
        )
    if floor is not None:
        field = xp.maximum(field, floor)
    return field


def grid_coordinates(
    shape: Sequence[int], dx: float | Sequence[float], origin: Sequence[float] | float = 0.0
) -> tuple[np.ndarray, ...]:
    """Node coordinates [m] of a grid, as 1D arrays, one per axis (``x`` then ``y``)."""
    ndim = len(shape)
    spacing = np.broadcast_to(np.asarray(dx, dtype=float), (ndim,))
    org = np.broadcast_to(np.asarray(origin, dtype=float), (ndim,))
    return tuple(o + h * np.arange(n) for n, h, o in zip(shape, spacing, org, strict=True))
