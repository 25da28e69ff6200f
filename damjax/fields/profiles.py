"""PST strength profiles tau_p(x) [Pa] along the PST [m] (paper Figs. 11-12).

- `linear_profile`, `power_law_profile`: tau_p = tau_peak on [0, L_ss], rising beyond;
- `fit_linear_profile`, `fit_power_law_profile`: least-squares fits to a measured transect;
- `load_strength_profile`, `pst_profile`, `pst_strength_profile`: from a measured transect
  (CSV) to a fitted gradient, shifted to tau_p = tau_peak at L_ss and extrapolated over a
  PST, as the paper does for its in-situ cases.
"""

from __future__ import annotations

import dataclasses
import math
import os

import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

from damjax.fields.tables import _check_nonnegative, _read_csv

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
    """Power-law PST strength: tau_p = tau_peak + a (x - L_ss)^b beyond L_ss (paper Fig. 12).

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

    As in the paper's in-situ cases (Figs. 11b, 12b): tau_p = tau_peak on [0, L_ss] and
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
# measured transects (CSV) to a PST profile
# --------------------------------------------------------------------------------------


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
    paper's in-situ workflow, Figs. 11-12).

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
