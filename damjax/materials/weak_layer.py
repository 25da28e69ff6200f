"""Quasi-brittle weak-layer interface law (paper Fig. 1b).

The weak layer is not discretised: it is a traction law between the slab column and
the ground, acting on the slab's slope-parallel displacement u relative to the ground.

- intact (u_max < u_c): tau = K u, K = G_wl / D_wl;
- softening (u_c <= u_max < u_r): the envelope falls linearly from tau_p at u_c to tau_r
  at u_r = u_c (1 + delta); unloading follows the secant to the origin, so damage (the
  history u_max) is irreversible;
- broken (u_max >= u_r, or sawn): no cohesion, Coulomb friction with the cap
  tau_r = rho g h cos(psi) tan(phi) opposing sliding. Friction is applied on the grid as
  an impulse cap (a slab at rest stays at rest), see `damjax.core.step`.

Functions here are per-particle, elementwise, and safe for infinite tau_p (controlled
runs, unbreakable layers) and delta = 0: no NaN in values or gradients.
"""

from __future__ import annotations

from typing import Any

import jax.numpy as jnp


def critical_displacements(tau_peak: Any, stiffness: Any, softening: Any) -> tuple[Any, Any]:
    """(u_c, u_r) [m]: u_c = tau_p / K, u_r = u_c (1 + delta); inf for tau_p = inf."""
    u_c = tau_peak / stiffness
    return u_c, u_c * (1.0 + softening)


def is_broken(u_max: Any, u_r: Any, cut: Any) -> Any:
    """True where the layer has lost all cohesion (sawn, or u_max >= u_r)."""
    return cut | (u_max >= u_r)


def cohesive_factor(
    u_max: Any, tau_peak: Any, tau_res: Any, stiffness: Any, softening: Any, broken: Any
) -> Any:
    """Secant stiffness k_sec [Pa/m] of the cohesive traction tau = k_sec u.

    k_sec = K while intact, envelope(u_max) / u_max while softening, 0 when broken.
    """
    finite = jnp.isfinite(tau_peak)
    # Safe stand-ins keep the unused branch finite (NaN-free values and gradients:
    # an inf anywhere in a discarded branch still poisons the gradient as 0 * inf).
    tau_p_s = jnp.where(finite, tau_peak, 1.0)
    u_c_s, u_r_s = critical_displacements(tau_p_s, stiffness, softening)
    span = jnp.where(softening > 0, u_r_s - u_c_s, 1.0)
    softening_zone = finite & (u_max >= u_c_s)
    u_max_s = jnp.where(softening_zone, u_max, u_c_s)
    frac = jnp.clip((u_max_s - u_c_s) / span, 0.0, 1.0)
    envelope = tau_p_s - (tau_p_s - tau_res) * frac
    k_soft = envelope / u_max_s
    k = jnp.where(softening_zone, k_soft, stiffness)
    return jnp.where(broken, 0.0, k)


def strength_profile(x: Any, tau_peak: Any, steady_length: Any, gradient: Any) -> Any:
    """tau_p(x) [Pa]: tau_peak for x < L_ss, then tau_peak + theta (x - L_ss)."""
    return tau_peak + gradient * jnp.maximum(x - steady_length, 0.0)
