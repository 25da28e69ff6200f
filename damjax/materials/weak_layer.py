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

Failure without events. Losing cohesion at u_r is a jump of the traction (at delta = 0
the whole drop from tau_p to friction). Applied to a whole particle from the step after
its slip crossed u_r, the state after the event would be a step function of the
parameters: move theta a little and the layer fails at the same step with the same
impulse, until it suddenly fails one step earlier, so reverse mode would miss the shift
of every event and with it almost all of the crack's sensitivity at delta = 0. Instead
each particle stands for a segment of weak layer one particle spacing long, across which
the slip near a crack front varies by `front_width` (u_r x spacing / Lambda); the segment
fails progressively (`failed_fraction`) as its centre slip passes u_r, and
`failed_fraction_in_step` averages that fraction exactly over each step for a linear slip
path (the time-of-impact treatment of differentiable contact, as in DiffTaichi, applied
to the part of the step after the crossing). Cohesion acts on the intact part, friction
on the failed part, so the impulse and the state after each failure move continuously
with the parameters. The crack length that results (`damjax.diagnostics`) is continuous
and piecewise smooth in every parameter, with kinks where a segment enters or leaves its
partly failed range.

Functions here are per-particle, elementwise, and safe for infinite tau_p (controlled
runs, unbreakable layers) and delta = 0: no NaN in values or gradients.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax.numpy as jnp


class WeakLayer(eqx.Module):
    """The weak layer's part of a run's model (`damjax.core.state.Model.weak_layer`):
    the interface law's constants (SI units, traced)."""

    stiffness: Any  # K_wl [Pa/m]
    tau_peak: Any  # (n,) peak shear strength tau_p [Pa]
    softening: Any  # delta [-]
    u_res: Any  # (n,) residual displacement u_r [m] (inf where unbreakable)
    friction: Any  # tan(phi) [-]
    # derived (`damjax.core.state.Model.with_constants`): the slip range [m] (n,) across a
    # particle's segment near a crack front (`front_width`; None: derived in every step,
    # `damjax.core.step.front_width`)
    front_width: Any = None


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
    # the span itself, not softening > 0: a softening below float resolution (1 + delta
    # rounds to 1) gives u_r = u_c and a zero span, whose 0 / 0 poisoned the gradient
    # through the discarded branch of a broken particle
    span = u_r_s - u_c_s
    span = jnp.where(span > 0, span, 1.0)
    softening_zone = finite & (u_max >= u_c_s)
    u_max_s = jnp.where(softening_zone, u_max, u_c_s)
    frac = jnp.clip((u_max_s - u_c_s) / span, 0.0, 1.0)
    envelope = tau_p_s - (tau_p_s - tau_res) * frac
    k_soft = envelope / u_max_s
    k = jnp.where(softening_zone, k_soft, stiffness)
    return jnp.where(broken, 0.0, k)


RAMP_EPS = 1e-6  # [-] ramp intervals shorter than this are taken as points


def _mean_ramp(a: Any, d: Any) -> Any:
    """Mean of clip(z, 0, 1) over z in [a, a + d], d >= 0, without cancellation: the
    parts of the interval below 0, inside [0, 1] and above 1 are measured separately
    (a difference of antiderivatives loses all digits in float32 when d << 1)."""
    # below 1e-6 the mean is clip(a) to 1e-6; the cut keeps 1 / d^2 in reverse mode finite
    # (d^2 underflows in float32 for d < 1e-19 and turned the gradient into NaN)
    pos = d > RAMP_EPS
    d_s = jnp.where(pos, d, 1.0)
    below = jnp.clip(-a, 0.0, d_s)
    above = jnp.clip((a - 1.0) + d_s, 0.0, d_s)
    inside = d_s - below - above
    mean = (inside / d_s) * (jnp.clip(a, 0.0, 1.0) + 0.5 * inside) + above / d_s
    return jnp.where(pos, mean, jnp.clip(a, 0.0, 1.0))


def front_width(u_break: Any, spacing: Any, elastic_length: Any) -> Any:
    """Slip range w [m] over a particle's footprint where the crack front crosses it.

    A particle stands for a segment of weak layer of length `spacing` [m]; near a crack
    tip the slip falls off over the elastic length Lambda [m], so across the segment it
    varies by about w = u_r spacing / Lambda. The segment fails progressively while its
    centre slip goes from u_r - w/2 to u_r + w/2 (`failed_fraction`).
    """
    finite = jnp.isfinite(u_break)
    return jnp.where(finite, u_break, 1.0) * (spacing / elastic_length)


def uniform_failure_stress(
    tau_peak: Any, stiffness: Any, u_break: Any, width: Any, xp: Any = jnp
) -> Any:
    """Shear stress [Pa] at which a uniformly loaded segment of weak layer starts to fail:
    its peak tau_p, or K (u_r - w/2) where that is lower. `failed_fraction` lets a
    segment fail from a centre slip of u_r - w/2 on, for the slip gradient of a crack
    front across it; under a uniform load (the slab's own weight, no front) there is no
    gradient, so a layer that softens less than w / (2 u_c) = (1 + delta) spacing /
    (2 Lambda) fails there at a stress below tau_p: by spacing / (2 Lambda) at delta = 0
    (1.9 % on dx 0.05 m with two particles per cell, 7.6 % on dx 0.2 m with two, 15 % with
    one, at the baseline Lambda 0.66 m). ``xp``: numpy for host checks."""
    return xp.minimum(tau_peak, stiffness * (u_break - 0.5 * width))


def failed_fraction(u: Any, u_break: Any, width: Any) -> Any:
    """Failed fraction in [0, 1] of a particle's segment of weak layer at centre
    (maximum) slip u [m]: the part of the segment whose slip, varying linearly by
    `width` [m] across it, has reached u_break [m] (inf: never fails)."""
    finite = jnp.isfinite(u_break)
    u_b = jnp.where(finite, u_break, 1.0)
    return jnp.where(finite, jnp.clip((u - u_b) / width + 0.5, 0.0, 1.0), 0.0)


def failed_fraction_in_step(
    u_max: Any, slip: Any, slip_rate: Any, u_break: Any, width: Any, dt: Any
) -> Any:
    """Failed fraction of a particle's segment averaged over a step of dt [s].

    The slip [m] grows at slip_rate [m/s] through the step, the damage history u_max [m]
    follows it once it passes, and the failed fraction is `failed_fraction` of that
    history. The average over the step is exact for a linear slip path (the integral
    of the clipped ramp), so the impulse of the step and the state after it move
    continuously with the time at which the front crosses the particle, including a
    front that crosses it within one step (time-of-impact treatment).
    """
    finite = jnp.isfinite(u_break)
    u_b = jnp.where(finite, u_break, 1.0)
    rise = jnp.maximum(slip_rate, 0.0) * dt  # slip gained over the step
    # a rise below RAMP_EPS x width changes the failed fraction by less than RAMP_EPS:
    # treated as none, which keeps 1 / rise^2 in reverse mode finite (see _mean_ramp)
    moving = rise > RAMP_EPS * width
    rise_s = jnp.where(moving, rise, 1.0)
    past = jnp.where(moving, jnp.maximum(slip + rise - u_max, 0.0), 0.0)  # past the history
    # part of the step before the slip passes the history: failed fraction of u_max
    t_pass = jnp.where(past > 0.0, 1.0 - past / rise_s, 1.0)
    t_pass = jnp.clip(t_pass, 0.0, 1.0)  # u_max lags the slip by round-off at most
    z_m = (u_max - u_b) / width + 0.5
    avg = t_pass * jnp.clip(z_m, 0.0, 1.0) + (1.0 - t_pass) * _mean_ramp(z_m, past / width)
    return jnp.where(finite, avg, 0.0)


def sawn_fraction(coord: Any, saw_before: Any, saw_after: Any) -> Any:
    """Fraction in [0, 1] of a step before a saw moving from saw_before to saw_after [m]
    reaches a particle at saw coordinate coord [m] (1 ahead of it, 0 behind it)."""
    moving = saw_after > saw_before
    den = jnp.where(moving, saw_after - saw_before, 1.0)
    s = jnp.clip((coord - saw_before) / den, 0.0, 1.0)
    return jnp.where(moving, s, jnp.where(coord < saw_before, 0.0, 1.0))


def strength_profile(x: Any, tau_peak: Any, steady_length: Any, gradient: Any) -> Any:
    """tau_p(x) [Pa]: tau_peak for x < L_ss, then tau_peak + theta (x - L_ss)."""
    return tau_peak + gradient * jnp.maximum(x - steady_length, 0.0)
