"""Maximum-likelihood fit of the `damjax.fields.grf` parameters (mean, trend, standard
deviation, correlation lengths, nugget) to a measured strength map [Pa, m]."""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import jax.scipy.linalg  # cho_solve (no longer imported on the way by optax)
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from damjax.fields.grf import _MODELS, CovarianceModel, correlation

# Smallest fitted nugget (noise-to-field variance ratio) of `fit_grf`: a noise std of 1e-4
# of the field's, which keeps the correlation matrix of a smooth field well conditioned.
_NUGGET_FLOOR = 1e-8
# the fitted fields that are `grf`'s keyword arguments (`GRFFit.grf_kwargs`)
_GRF_KEYS = ("mean", "std", "length_scale", "angle_deg", "model", "trend")


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
        return {k: getattr(self, k) for k in _GRF_KEYS}


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

    import optax  # deferred: importing damjax stays light

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
