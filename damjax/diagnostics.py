"""Crack tip, crack speed, arrest and slab-tension diagnostics of a PST run.

Definitions (all event-based, computed on the host from the tip history):

- crack tip: the furthest x where the weak layer has lost all cohesion (sawn, or
  u_max >= u_r, which is u_max >= u_c for delta = 0); non-decreasing in time;
- crack speed: central difference of the tip over a window of `SPEED_WINDOW` seconds;
- arrested: the tip stopped advancing (it came within one cell of its final value) at
  least `ARREST_QUIET` seconds before the end, and 2 m or more below the upper end;
- L_ca (arrest position): the final tip when arrested (NaN otherwise);
  A_ca = L_ca - L_ss;
- critical cut length: the saw position when the saw stopped (crack leading by 0.5 m);
- k_x (controlled runs): least-squares slope of sigma_xx against x over 30 %-80 % of the
  cut length at the end of the run.

These are discrete events: they are piecewise constant in the parameters and carry no
useful gradient. What is differentiated instead is `smooth_arrest_position`: the
integral along x of a smooth weak-layer damage indicator at the end of the run,

    L_smooth = sum_p  s((u_max,p / u_r,p - (1 - w)) / w)  Delta x_p,

with s the C1 smoothstep (0 below, 1 above), w = `SMOOTH_WIDTH` = 0.1 (damage ramps
from 0 to 1 as the maximum slip goes from 0.9 u_r to u_r), Delta x_p the particle
spacing; sawn particles count as fully damaged. It equals the length of weak layer that
lost its cohesion, so it tracks the final tip (and L_ca when the crack arrested), while
varying continuously with the slips of the particles around the tip.

When its gradient means something (measured at full size, `python -m benchmarks
pst_grad_fd`): with a softening weak layer (delta > 0) the particles of the process zone
soften gradually and the gradient agrees with central differences of the whole run
(baseline with delta = 1: within 0.2 % for theta and 0.04 % for delta). With a brittle
weak layer (delta = 0) each particle snaps from peak strength to zero: the arrest moves
in particle-sized jumps, and the gradient only sees the tiny drift between jumps (baseline
theta = 500, delta = 0: d L / d theta = -0.0012 m per Pa/m by AD against -0.238 by central
differences over 2.5-5 Pa/m). A wider ramp does not help there (10 m PST, L_ss 4 m, theta
800 Pa/m, dx 0.05 m: AD -6.6e-4 / -6.8e-4 / -8.7e-4 for w = 0.1 / 0.5 / 0.9 against
-4.8e-3 to -6.0e-3 by differences): the missing part is the crack's advance itself, a
sequence of discrete events in time. Use delta > 0 for gradient-based work.

When a slab fracture stops the crack, the tip freezes abruptly: the maximum slip jumps
from above u_r to about 0.84 u_r between neighbouring particles, no particle sits in the
default ramp (0.9-1.0 u_r) and the gradient is exactly zero although the arrest moves
(measured like the regime check of `benchmarks/inversion.py`, on a 20 m PST, L_ss 8 m,
theta 300 Pa/m, sigma_t 6 kPa, delta 1, dx 0.04 m: d L / d sigma_t = 0 by AD against 0.99 m/kPa by
central differences, d L / d delta = 0 against -1.75 m). A wider ramp, ``width`` = 0.5
(= delta / (1 + delta) for delta = 1: damage over the whole softening branch u_c..u_r),
restores it: 0.89 m/kPa and -1.64 m by AD against 0.98 m/kPa and -1.79 m by differences,
for a surrogate 0.14 m above the event-based L_ca.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from damjax import theory
from damjax.validation import is_plastic

SPEED_WINDOW = 0.02  # [s]
SMOOTH_WIDTH = 0.1  # relative width of the damage ramp of the smooth arrest position
ARREST_QUIET = 0.3  # [s]
ARREST_MARGIN = 2.0  # [m] below the upper end


def crack_speed(time: np.ndarray, tip: np.ndarray, window: float = SPEED_WINDOW) -> np.ndarray:
    """Crack speed [m/s] at each time, central difference over ``window`` seconds."""
    if time.size < 3:
        return np.zeros_like(tip)
    dt = float(time[1] - time[0])
    k = max(1, int(round(0.5 * window / dt)))
    padded = np.concatenate([np.full(k, tip[0]), tip, np.full(k, tip[-1])])
    speed = (padded[2 * k :] - padded[: -2 * k]) / (2 * k * dt)
    # the ends see a one-sided window
    speed[:k] *= 2 * k / (np.arange(k) + k)
    speed[-k:] *= 2 * k / (np.arange(k, 0, -1) + k - 1)
    return speed


def arrest(
    time: np.ndarray, tip: np.ndarray, length: float, dx: float
) -> tuple[bool, float, float]:
    """(arrested, arrest position L_ca [m] or nan, time the tip stopped [s])."""
    if tip.size == 0:
        return False, math.nan, math.nan
    final = float(tip[-1])
    stopped = np.nonzero(tip >= final - dx)[0]
    t_stop = float(time[stopped[0]])
    arrested = (time[-1] - t_stop >= ARREST_QUIET - 1e-9) and (final <= length - ARREST_MARGIN)
    return bool(arrested), (final if arrested else math.nan), t_stop


def tension_gradient(x: np.ndarray, sigma_xx: np.ndarray, cut: float) -> float:
    """Least-squares slope of sigma_xx(x) over [0.3, 0.8] x cut [Pa/m]."""
    sel = (x >= 0.3 * cut) & (x <= 0.8 * cut)
    if sel.sum() < 3:
        return math.nan
    return float(np.polyfit(x[sel], sigma_xx[sel], 1)[0])


def slab_fractures(
    x: np.ndarray, opening: np.ndarray, t_fracture: np.ndarray, threshold: float, gap: float
) -> list[dict[str, float]]:
    """Slab tensile fractures: connected bands where the tensile plastic strain exceeds
    ``threshold``, bands closer than ``gap`` [m] merged; one entry per band with the
    position of its largest opening and the time its first particle crossed the threshold.
    """
    order = np.argsort(x)
    x, opening, t_fracture = x[order], opening[order], t_fracture[order]
    idx = np.nonzero(opening >= threshold)[0]
    if idx.size == 0:
        return []
    splits = np.nonzero(np.diff(x[idx]) > gap)[0] + 1
    out = []
    for band in np.split(idx, splits):
        k = band[np.argmax(opening[band])]
        out.append({"x_m": float(x[k]), "t_s": float(np.min(t_fracture[band]))})
    return sorted(out, key=lambda f: f["t_s"])


def smoothstep(z: Any) -> Any:
    """C1 ramp: 0 for z <= 0, 3 z^2 - 2 z^3 on [0, 1], 1 for z >= 1."""
    import jax.numpy as jnp

    z = jnp.clip(z, 0.0, 1.0)
    return z * z * (3.0 - 2.0 * z)


def smooth_arrest_position(model: Any, state: Any, width: float = SMOOTH_WIDTH) -> Any:
    """Differentiable surrogate of the arrest position [m] (JAX; see the module doc).

    Works on the model and final state of a 1D run; in 2D it is the damaged area
    divided by the strip width. ``width`` [-] is the relative width w of the damage
    ramp (default `SMOOTH_WIDTH`); w = delta / (1 + delta) ramps over the whole
    softening branch u_c..u_r, which keeps a gradient where a slab fracture freezes the
    crack tip (see the module doc).
    """
    import jax.numpy as jnp

    finite = jnp.isfinite(model.u_res)
    u_r = jnp.where(finite, model.u_res, 1.0)
    z = (state.u_max / u_r - (1.0 - width)) / width
    damage = jnp.where(finite, smoothstep(z), 0.0)
    cut = jnp.clip((state.saw_pos - model.saw_coord) / (model.dx * 0.5) + 0.5, 0.0, 1.0)
    damage = jnp.maximum(damage, cut)
    area = jnp.sum(damage) * model.area0  # 1D: area0 is the particle spacing [m]
    if model.dim == 2:  # divide by the strip width (particle centres span [s/2, L - s/2])
        length = jnp.max(model.saw_coord) + jnp.min(model.saw_coord)
        area = area / (model.saw_coord.size * model.area0 / length)
    return area


def _none(v: float) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def summarize(
    result: Any,
    *,
    saw_position: float,
    saw_stopped: bool,
    n_particles: int,
    n_steps: int,
    compile_time_s: float,
    wall_time_s: float,
    timed_steps: int | None = None,
) -> dict[str, Any]:
    """The JSON summary of a PST run (None where not applicable). ``timed_steps``: the
    steps that ``wall_time_s`` covers (a resumed run: those after the restart; default
    ``n_steps``)."""
    timed = n_steps if timed_steps is None else timed_steps
    p, s = result.params, result.setup
    cs = float(theory.shear_wave_speed(p))
    speed = crack_speed(result.time, result.tip)
    arrested, l_ca, t_stop = arrest(result.time, result.tip, s.length, s.dx)
    if s.controlled:
        arrested, l_ca = False, math.nan
    max_speed = float(np.max(speed)) if speed.size else 0.0
    kx = kx_th = None
    if s.controlled:
        # once the cut has left the domain the whole slab hangs free: no tension ramp
        if saw_position < s.length:
            kx = _none(tension_gradient(result.x, result.sigma_xx, saw_position))
        kx_th = float(theory.dynamic_gradient(p, float(p.saw_speed), s.lateral))
    lss = float(p.steady_length)
    # the bar model behind a_c and theta_run needs a slab that slides once released
    psi = float(np.max(p.slope_profile)) if p.slope_profile is not None else float(p.slope_deg)
    slides = psi > float(p.friction_deg)
    return {
        "lateral": s.lateral,
        "controlled": bool(s.controlled),
        "arrested": arrested,
        "arrest_position_m": _none(l_ca),
        "arrest_length_m": _none(l_ca - lss) if arrested else None,
        "arrest_time_s": _none(t_stop) if arrested else None,
        "final_tip_m": _none(float(result.tip[-1]) if result.tip.size else math.nan),
        "critical_cut_length_m": _none(saw_position) if saw_stopped else None,
        "critical_cut_length_theory_m": None
        if s.controlled or not slides
        else _none(float(theory.critical_cut_length(p, s.lateral))),
        # an elastic brittle slab cannot arrest below this gradient (theory.runaway_gradient)
        "runaway_gradient_pa_per_m": None
        if s.controlled or is_plastic(p) or not slides
        else float(theory.runaway_gradient(p, s.lateral)),
        "max_crack_speed_m_per_s": max_speed,
        "max_crack_speed_over_cs": max_speed / cs,
        "wave_speed_over_cs": float(theory.longitudinal_wave_speed(p, s.lateral)) / cs,
        "shear_wave_speed_m_per_s": cs,
        "slab_fractures": result.fractures,
        "tension_gradient_pa_per_m": kx,
        "tension_gradient_theory_pa_per_m": kx_th,
        "fault": result.fault,
        "n_particles": int(n_particles),
        "n_steps": int(n_steps),
        "dt_s": float(result.time[0]) if result.time.size else None,
        "compile_time_s": float(compile_time_s),
        "wall_time_s": float(wall_time_s),
        "particle_steps_per_s": n_particles * timed / wall_time_s if wall_time_s > 0 else None,
    }
