"""Scaling laws fitted to sweeps (paper Eqs. 9-10):

- elastic:        A_ca / L_ss = a * Pi_e^b,  Pi_e = tau_g / (theta Lambda sqrt(1 + delta))
  (the paper's exponent b = 3/2);
- elasto-plastic: A_ca / L_t = a * Pi_p^b,  Pi_p = Pi_e sqrt(sigma_t / tau_g)  (b = 1).

`fit_power_law` minimises the squared error in log space with optax (Adam, then the
exact Gauss-Newton step of the linear problem as a check), and reports standard errors
from the Hessian of the loss scaled by the residual variance, 95 % intervals and the
collapse quality R^2 in log space.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax import theory


@dataclasses.dataclass
class PowerLawFit:
    """y = prefactor * x**exponent, fitted in log space."""

    prefactor: float
    exponent: float
    prefactor_se: float  # standard error of the prefactor (delta method)
    exponent_se: float
    exponent_ci95: tuple[float, float]
    r2_log: float  # coefficient of determination of log y
    n: int
    iterations: int

    def __call__(self, x: Any) -> Any:
        return self.prefactor * np.asarray(x) ** self.exponent


def _t95(dof: int) -> float:
    """Two-sided 95 % Student-t quantile (normal beyond 30 dof)."""
    table = {
        1: 12.71,
        2: 4.30,
        3: 3.18,
        4: 2.78,
        5: 2.57,
        6: 2.45,
        7: 2.36,
        8: 2.31,
        9: 2.26,
        10: 2.23,
        12: 2.18,
        15: 2.13,
        20: 2.09,
        25: 2.06,
        30: 2.04,
    }
    if dof <= 0:
        return math.inf
    keys = [k for k in table if k <= dof]
    return table[max(keys)] if dof <= 30 else 1.96


def fit_power_law(
    x: Sequence[float], y: Sequence[float], *, steps: int = 3000, learning_rate: float = 0.05
) -> PowerLawFit:
    """Fit y = a x^b by gradient descent (optax Adam) on the log-space squared error."""
    from damjax.calibrate.inversion import optimizer_problems  # (it imports this module)

    problems = optimizer_problems(steps, learning_rate)
    if problems:
        raise ValueError("\n".join(f"fit_power_law: {p}" for p in problems))
    if np.ndim(x) != 1 or np.ndim(y) != 1 or np.size(x) != np.size(y):
        raise ValueError(
            f"fit_power_law: x and y must be 1-D of the same length (shapes {np.shape(x)}, "
            f"{np.shape(y)})"
        )
    lx = jnp.log(jnp.asarray(x, jnp.float64 if jax.config.x64_enabled else jnp.float32))
    ly = jnp.log(jnp.asarray(y, lx.dtype))
    if np.unique(np.asarray(x)).size < 2 and np.size(x) >= 3:
        raise ValueError("fit_power_law: x must take at least 2 different values")
    if lx.size < 3:
        raise ValueError(f"fit_power_law: need at least 3 points, got {int(lx.size)}")
    if not (np.all(np.isfinite(np.asarray(lx))) and np.all(np.isfinite(np.asarray(ly)))):
        raise ValueError("fit_power_law: x and y must be positive and finite")
    mx = jnp.mean(lx)  # centre for conditioning

    def loss(theta: Any) -> Any:
        return jnp.mean((theta[0] + theta[1] * (lx - mx) - ly) ** 2)

    import optax  # deferred: importing damjax stays light

    opt = optax.adam(learning_rate)
    theta = jnp.asarray([jnp.mean(ly), 1.0], lx.dtype)
    state = opt.init(theta)

    @jax.jit
    def update(theta: Any, state: Any) -> tuple[Any, Any, Any]:
        val, g = jax.value_and_grad(loss)(theta)
        upd, state = opt.update(g, state)
        return optax.apply_updates(theta, upd), state, val

    prev = math.inf
    it = 0
    for it in range(1, steps + 1):
        theta, state, val = update(theta, state)
        if it % 100 == 0:
            if abs(prev - float(val)) < 1e-12 * max(1.0, float(val)):
                break
            prev = float(val)
    n = int(lx.size)
    resid = theta[0] + theta[1] * (lx - mx) - ly
    sigma2 = float(jnp.sum(resid**2)) / max(n - 2, 1)
    H = jax.hessian(lambda t: 0.5 * jnp.sum((t[0] + t[1] * (lx - mx) - ly) ** 2))(theta)
    cov = np.linalg.inv(np.asarray(H, float)) * sigma2
    c0, b = float(theta[0]), float(theta[1])
    log_a = c0 - b * float(mx)
    var_log_a = cov[0, 0] + float(mx) ** 2 * cov[1, 1] - 2 * float(mx) * cov[0, 1]
    a = math.exp(log_a)
    ss_tot = float(jnp.sum((ly - jnp.mean(ly)) ** 2))
    r2 = 1.0 - float(jnp.sum(resid**2)) / ss_tot if ss_tot > 0 else math.nan
    se_b = math.sqrt(max(cov[1, 1], 0.0))
    t = _t95(n - 2)
    return PowerLawFit(
        a, b, a * math.sqrt(max(var_log_a, 0.0)), se_b, (b - t * se_b, b + t * se_b), r2, n, it
    )


def _arrested(results: Sequence[Any]) -> list[Any]:
    return [r for r in results if r.arrested]


def _no_profiles(name: str, results: Sequence[Any]) -> None:
    """A clear error for runs with a strength_profile: the scalings are laws of the
    steady-state length L_ss and the strength gradient theta, which a profile replaces
    (the fit would use their unused defaults)."""
    index = [
        i
        for i, r in enumerate(results)
        if getattr(getattr(r, "params", None), "strength_profile", None) is not None
    ]
    if index:
        shown = ", ".join(str(i) for i in index[:5])
        shown += f" and {len(index) - 5} more" if len(index) > 5 else ""
        raise ValueError(
            f"{name}: result{'s' if len(index) > 1 else ''} {shown} of {len(results)} ran "
            "with a strength_profile, which has no steady-state length L_ss or strength "
            "gradient theta to fit against; fit runs of steady_length and strength_gradient "
            "(strength_profile = None)"
        )


def fit_elastic_scaling(results: Sequence[Any]) -> PowerLawFit:
    """Fit A_ca / L_ss against tau_g / (theta Lambda sqrt(1 + delta)) over arrested runs
    (of steady_length and strength_gradient, not of a strength_profile)."""
    _no_profiles("fit_elastic_scaling", results)
    rs = _arrested(results)
    x = [float(theory.elastic_number(r.params)) for r in rs]
    y = [
        (r.arrest_position - float(r.params.steady_length)) / float(r.params.steady_length)
        for r in rs
    ]
    keep = [i for i, v in enumerate(y) if v > 0]
    dropped = [f"{len(results) - len(rs)} not arrested", _at_or_below(len(rs) - len(keep))]
    _enough("fit_elastic_scaling", len(results), len(keep), dropped)
    return fit_power_law([x[i] for i in keep], [y[i] for i in keep])


def _enough(name: str, given: int, kept: int, dropped: list[str]) -> None:
    """A clear error when fewer than 3 runs are left to fit, saying which were dropped."""
    if kept < 3:
        raise ValueError(
            f"{name}: need at least 3 runs to fit, got {kept} of {given}: {', '.join(dropped)}"
        )


def _at_or_below(n: int) -> str:
    return f"{n} arrested at or below the steady-state length"


def _elastic(r: Any) -> bool:
    params = getattr(r, "params", None)
    return params is not None and not math.isfinite(float(params.tensile_strength))


def fit_plastic_scaling(results: Sequence[Any]) -> PowerLawFit:
    """Fit A_ca / L_t against Pi_e sqrt(sigma_t / tau_g) over arrested runs with a finite
    tensile strength (of steady_length and strength_gradient, not of a strength_profile)."""
    _no_profiles("fit_plastic_scaling", results)
    plastic = [r for r in results if not _elastic(r)]
    rs = _arrested(plastic)
    x = [float(theory.plastic_number(r.params)) for r in rs]
    y = [
        (r.arrest_position - float(r.params.steady_length)) / float(theory.tensile_length(r.params))
        for r in rs
    ]
    keep = [i for i, v in enumerate(y) if v > 0]
    n_elastic = len(results) - len(plastic)
    dropped = [
        f"{len(plastic) - len(rs)} not arrested with a finite tensile strength",
        _at_or_below(len(rs) - len(keep)),
    ]
    if n_elastic:  # an elastic run has no tensile length L_t to scale by, arrested or not
        dropped.insert(0, f"{n_elastic} elastic (tensile_strength = inf: no tensile length L_t)")
    _enough("fit_plastic_scaling", len(results), len(keep), dropped)
    return fit_power_law([x[i] for i in keep], [y[i] for i in keep])
