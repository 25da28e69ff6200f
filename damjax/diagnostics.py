"""Crack tip, crack speed, arrest, slab-tension and slab-fracture diagnostics of a PST run.

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

These are discrete events: piecewise constant in the parameters, they carry no gradient.
What is differentiated instead is `smooth_arrest_position`, the event-based crack length
made continuous. Each particle stands for a segment of weak layer of length Delta x_p
(the particle spacing), and the weak-layer law lets that segment fail progressively as
the crack front crosses it (`damjax.materials.weak_layer.failed_fraction`: its failed
fraction goes from 0 to 1 while the maximum slip goes from u_r - w/2 to u_r + w/2,
w = u_r Delta x_p / Lambda). The mechanics uses that fraction (cohesion on the intact
part, friction on the rest, averaged over each step), so the state after each failure is
continuous in the parameters and reverse mode carries the shift of every failure, also at
delta = 0. The continuous crack length counts each segment by a C1 ramp of its maximum
slip centred on the same u_r but `LENGTH_RAMP` front widths wide:

    L_smooth = sum_p  max(r((u_max,p - u_r,p) / (LENGTH_RAMP w_p)), c_p)  Delta x_p   [m]

with r(z) = 2 (z + 1/2)^2 below z = 0 and 1 - 2 (1/2 - z)^2 above (0 below -1/2, 1 above
1/2) and c_p the sawn fraction of the segment. The ramp is odd about u_r (r(z) + r(-z) =
1), so where the maximum slip falls linearly across the last few segments the sum is the
position of the point where it equals u_r: the event-based tip (the centre of the furthest
segment with u_max >= u_r) made continuous; they differ by at most one particle spacing
(measured on 40 m PSTs at softening 0 and 0.3, 2026-11-25), and equal when u_r is reached
exactly at a particle. Why wider than the mechanics' ramp: near the tip the maximum slip
of neighbouring segments differs by about w at softening 0 but less when the weak layer
softens (about w / 1.15 at delta = 0.3), so one or two segments were partly failed in
turn and the derivative of the sum alternated by a factor up to 2 from one parameter
value to the next (0.05 Pa/m apart in theta); spread over about four segments with a
C1 ramp, whose derivative is a hat, the overlapping hats add up to a nearly constant
derivative: the spread of d L / d theta over theta 800-804 Pa/m (81 runs) falls from
25 % to 1.5 % at delta = 0.3, and from 3.1 % to 1.9 % at delta = 0.

Measured (40 m PST, L_ss 10 m, theta 800 Pa/m, dx 0.04 m, 1 s, float64, 2026-11-25;
d L / d theta by AD against the least-squares slope of the event-based L_ca over theta
720-880 Pa/m, 11 runs; `damjax.gradient_check`): softening 0: AD -0.01716 m/(Pa/m)
averaged over the window (-0.01647 at theta 800) against -0.01723 (the event-based
failure of earlier versions gave -0.00073). On the paper's brittle baseline (100 m,
dx 0.02 m, 3 s, float32, theta 450-550 Pa/m, 11 runs; `python -m
verification.gradients full`): AD -0.2487 averaged over the window (-0.2252 at theta 500)
against -0.2472 (earlier versions: -0.0012). `python -m verification.gradients events`
measures the other fields and softening 0.3.

When a slab fracture stops the crack the tip freezes abruptly: the maximum slip jumps
from above u_r to about 0.84 u_r between neighbouring particles, no segment lies on
the ramp (u_r +- 2 front widths), and the gradient is zero although the arrest moves
(20 m PST, L_ss 8 m, theta 300 Pa/m, sigma_t 6 kPa, delta 1, dx 0.04 m, 1.5 s,
float64, 2026-11-25: d L / d sigma_t = 0 by AD against 0.92 m/kPa by central
differences over +-2 %). There a damage ramp over the softening branch keeps the
sensitivity: ``width`` = w_r switches to
L = sum_p s((u_max,p / u_r,p - (1 - w_r)) / w_r) Delta x_p with s the C1 smoothstep;
w_r = 0.5 (= delta / (1 + delta) at delta = 1, the whole softening branch) gives
0.89 m/kPa by AD against 0.98 m/kPa by differences, for a length 0.14 m above the
continuous one.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from damjax import theory
from damjax.params import is_plastic

SPEED_WINDOW = 0.02  # [s]
ARREST_QUIET = 0.3  # [s]
ARREST_MARGIN = 2.0  # [m] below the upper end
# tensile plastic strain [-] from which a particle counts as yielded: the return mapping
# leaves round-off of up to ~5e-9 (float32) on slab that never came near sigma_t, while the
# elastic strain at yield is sigma_t / E ~ 1e-3
YIELD_STRAIN = 1e-6


def _pair(fn: str, names: tuple[str, str], first: Any, second: Any) -> list[np.ndarray]:
    """``first`` and ``second`` as finite 1-D float arrays of one length, the first
    increasing where it is ``time``: ValueError (TypeError for what is no array of
    numbers) naming ``fn`` and the argument otherwise."""
    out = []
    for arg, value in zip(names, (first, second), strict=True):
        try:  # float32 stays float32: the arrest's comparisons as the run's own
            a = np.asarray(value)
            if a.dtype.kind not in "fiu":
                a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(
                f"{fn}: {arg} must be a 1-D array of numbers (e.g. a PSTResult's .{arg}), "
                f"got {type(value).__name__}"
            ) from None
        if a.ndim != 1:
            raise ValueError(f"{fn}: {arg} has shape {a.shape}; must be 1-D")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{fn}: {arg} holds NaN or inf; must be finite")
        out.append(a)
    if out[0].size != out[1].size:
        raise ValueError(
            f"{fn}: {names[0]} has {out[0].size} values and {names[1]} {out[1].size}; "
            "must be as many"
        )
    if names[0] == "time" and not np.all(np.diff(out[0]) > 0):
        raise ValueError(f"{fn}: time must increase from one value to the next [s]")
    return out


def _positive(fn: str, name: str, value: Any, unit: str) -> float:
    """``value`` as a finite float > 0, else ValueError naming ``fn`` and ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (v > 0 and math.isfinite(v)):
        raise ValueError(f"{fn}: {name} = {value!r}; must be a finite number > 0 {unit}")
    return v


def crack_speed(time: np.ndarray, tip: np.ndarray, window: float = SPEED_WINDOW) -> np.ndarray:
    """Crack speed [m/s] at each time, central difference over ``window`` seconds.

    Args:
        time: (n,) increasing times [s], evenly spaced (a run's history).
        tip: (n,) crack-tip positions [m] at those times.
        window: the difference's width [s], > 0 (shortened, one-sided, at the ends).
    """
    time, tip = _pair("crack_speed", ("time", "tip"), time, tip)
    window = _positive("crack_speed", "window", window, "s")
    if time.size < 3:
        return np.zeros_like(tip)
    dt = float(time[1] - time[0])
    k = max(1, int(round(0.5 * window / dt)))
    # the ends (and a record shorter than the window) see a one-sided, shorter window
    i = np.arange(tip.size)
    lo, hi = np.maximum(i - k, 0), np.minimum(i + k, tip.size - 1)
    speed = (tip[hi] - tip[lo]) / ((hi - lo) * dt)
    return speed


def arrest(
    time: np.ndarray, tip: np.ndarray, length: float, dx: float
) -> tuple[bool, float, float]:
    """(arrested, arrest position L_ca [m] or nan, time the tip stopped [s]) of a tip
    history: ``time`` (n,) [s] and ``tip`` (n,) [m] of a strip ``length`` [m] on cells of
    ``dx`` [m] (the tip counts as stopped within one cell of its final value)."""
    time, tip = _pair("arrest", ("time", "tip"), time, tip)
    length = _positive("arrest", "length", length, "m")
    dx = _positive("arrest", "dx", dx, "m")
    if tip.size == 0:
        return False, math.nan, math.nan
    final = float(tip[-1])
    stopped = np.nonzero(tip >= final - dx)[0]
    t_stop = float(time[stopped[0]])
    arrested = (time[-1] - t_stop >= ARREST_QUIET - 1e-9) and (final <= length - ARREST_MARGIN)
    return bool(arrested), (final if arrested else math.nan), t_stop


def tension_gradient(x: np.ndarray, sigma_xx: np.ndarray, cut: float) -> float:
    """Least-squares slope of sigma_xx(x) over [0.3, 0.8] x cut [Pa/m]: ``x`` (n,) the
    particles' positions [m], ``sigma_xx`` (n,) their slab tension [Pa], ``cut`` [m] > 0
    the saw's cut. NaN where fewer than three particles lie in the window."""
    x, sigma_xx = _pair("tension_gradient", ("x", "sigma_xx"), x, sigma_xx)
    cut = _positive("tension_gradient", "cut", cut, "m")
    sel = (x >= 0.3 * cut) & (x <= 0.8 * cut)
    if sel.sum() < 3:
        return math.nan
    return float(np.polyfit(x[sel], sigma_xx[sel], 1)[0])


def slab_fractures(
    x: np.ndarray, opening: np.ndarray, t_fracture: np.ndarray, threshold: float, gap: float
) -> list[dict[str, float]]:
    """Slab tensile fractures of a model without a particle lattice (`band_fractures` with
    one): connected bands where the tensile plastic strain exceeds ``threshold``, bands
    closer than ``gap`` [m] merged; one entry per band with the
    position of its largest opening and the time its first particle crossed the threshold.
    """
    order = np.argsort(x)
    x, opening, t_fracture = x[order], opening[order], t_fracture[order]
    idx = np.nonzero(opening >= threshold)[0]
    out = [
        {"x_m": float(x[k]), "t_s": float(np.min(t_fracture[band]))}
        for k, band in _bands(x, opening, idx, gap)
    ]
    return sorted(out, key=lambda f: f["t_s"])


def _bands(x: np.ndarray, opening: np.ndarray, idx: np.ndarray, gap: float) -> list[Any]:
    """(k, band) for each run of the particles ``idx`` (sorted along x) closer than ``gap``
    [m]: the band's indices and its particle k of the largest opening."""
    if idx.size == 0:
        return []
    splits = np.nonzero(np.diff(x[idx]) > gap)[0] + 1
    return [(band[np.argmax(opening[band])], band) for band in np.split(idx, splits)]


# --------------------------------------------------------------------------------------
# Slab fractures of a finished run (the fracture law and the strength field are
# `damjax.materials.slab_fracture`): the "crack_band" slab's bands (`band_fractures`), the
# crack speed around each (`fracture_speed_changes`), and the perfectly plastic ("paper")
# slab's fractures counted by what they do to the crack (`crack_fractures`).
# --------------------------------------------------------------------------------------

FRACTURE_GAP = 1.0  # fractures closer than this are one [m]
FRACTURE_SPEED_WINDOW = 0.05  # crack speed before / after a fracture: mean over this time [s]
SEPARATION_WINDOW = 1.0  # the slab's stretch is its displacement difference over this [m]
SEPARATION_OPENING = 0.1  # a stretch over SEPARATION_WINDOW this large is a separation [m]
DROP_SAMPLE = 0.01  # crack speed: mean over consecutive intervals of this length [s]
DROP_HORIZON = 0.02  # trend of the crack speed over this time, extrapolated as far [s]
DROP_SPEED = 0.1  # a speed drop: the speed falls this far below its trend [c_s]


def band_fractures(
    x: np.ndarray,
    opening: np.ndarray,
    t_fracture: np.ndarray,
    gap: float = FRACTURE_GAP,
) -> list[dict[str, float]]:
    """Slab fractures from the band openings at the end of a run.

    ``opening``: band opening per particle [m] (`damjax.materials.slab_fracture.band_opening`);
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
    out = [
        {"x_m": float(x[k]), "t_s": float(np.min(t_fracture[band])), "opening_m": float(opening[k])}
        for k, band in _bands(x, opening, idx, gap)
    ]
    return sorted(out, key=lambda f: f["t_s"])


def fracture_speed_changes(
    time: np.ndarray, tip: np.ndarray, fracture_list: list[dict[str, float]]
) -> list[dict[str, float]]:
    """Crack speed before and after each fracture [m/s] (the paper's Fig. 8d).

    The mean speed of the crack tip over `FRACTURE_SPEED_WINDOW` seconds before the
    fracture time and over the same time after it: ``{x_m, t_s, speed_before_m_per_s,
    speed_after_m_per_s, speed_drop_m_per_s}``.
    """
    time, tip = np.asarray(time, dtype=float), np.asarray(tip, dtype=float)
    out = []
    for f in fracture_list:
        t = f["t_s"]
        if time.size < 2 or not math.isfinite(t):
            continue
        tip_at = lambda s: float(np.interp(s, time, tip))  # noqa: E731
        t0, t1 = (
            max(float(time[0]), t - FRACTURE_SPEED_WINDOW),
            min(float(time[-1]), t + FRACTURE_SPEED_WINDOW),
        )
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


def separations(
    x: np.ndarray,
    slip: np.ndarray,
    window: float = SEPARATION_WINDOW,
    threshold: float = SEPARATION_OPENING,
    gap: float = FRACTURE_GAP,
) -> list[dict[str, float]]:
    """Places where the slab came apart: ``{x_m, opening_m}`` sorted by x.

    The slab's stretch at x is the difference of its slope-parallel displacement ``slip``
    [m] across a window of ``window`` metres centred on x (particles at the same x, as
    across a 2D strip, averaged first). A separation is a local maximum of the stretch of
    at least ``threshold`` [m]; maxima closer than ``gap`` [m] are one. Perfectly plastic
    stretching spreads a few millimetres per metre (sigma_t / E and plastic flow), so a
    stretch of decimetres over a metre is an opening slab, whatever the grid.
    """
    x, slip = np.asarray(x, dtype=float).ravel(), np.asarray(slip, dtype=float).ravel()
    xs, inv = np.unique(x, return_inverse=True)
    if xs.size < 2:
        return []
    us = np.bincount(inv, weights=slip) / np.bincount(inv)
    half = 0.5 * window
    stretch = np.interp(xs + half, xs, us) - np.interp(xs - half, xs, us)
    # the stretch is flat while the window slides over one jump: the separation lies at
    # the steepest step of the displacement inside the window of the largest stretch
    step = np.diff(us) / np.maximum(np.diff(xs), 1e-12)
    mid = 0.5 * (xs[1:] + xs[:-1])
    out: list[dict[str, float]] = []
    for i in np.argsort(-stretch, kind="stable"):
        if stretch[i] < threshold:
            break
        inside = np.nonzero(np.abs(mid - xs[i]) <= half)[0]
        x_f = float(mid[inside[np.argmax(step[inside])]]) if inside.size else float(xs[i])
        if all(abs(x_f - f["x_m"]) > gap for f in out):
            out.append({"x_m": x_f, "opening_m": float(stretch[i])})
    return sorted(out, key=lambda f: f["x_m"])


def speed_drops(
    time: np.ndarray,
    tip: np.ndarray,
    shear_wave_speed: float,
    sample: float = DROP_SAMPLE,
    horizon: float = DROP_HORIZON,
    drop: float = DROP_SPEED,
) -> list[dict[str, float]]:
    """Sudden drops of the crack speed: ``{t_s, tip_m, speed_drop_m_per_s}``.

    The crack speed is the tip's mean speed over consecutive ``sample`` seconds. At each
    sample, the speed's trend over the previous ``horizon`` seconds (a straight line through
    the speeds ``horizon`` apart, capped at the current speed) is extrapolated ``horizon``
    seconds ahead; a drop is where the crack then runs at least ``drop`` shear-wave speeds
    slower than its trend. A steady
    deceleration (a strength gradient) follows its trend and is no drop; so is the crack
    coming to rest (the trend then falls below zero). ``t_s``: start of the slower
    interval [s]; ``tip_m``: the tip then [m]; drops closer than ``horizon`` in time are one
    (the largest).
    """
    time, tip = np.asarray(time, dtype=float), np.asarray(tip, dtype=float)
    if time.size < 2:
        return []
    grid = np.arange(float(time[0]), float(time[-1]) + 1e-12, sample)
    pos = np.interp(grid, time, tip)
    v = np.diff(pos) / sample  # speed over [grid[k], grid[k + 1]]
    n = max(1, int(round(horizon / sample)))
    limit = drop * float(shear_wave_speed)
    events: list[tuple[float, int]] = []
    for k in range(2 * n, v.size):
        before, earlier = v[k - n], v[k - 2 * n]
        # linear, n samples further; never above the current speed: a crack whose
        # acceleration levels off keeps its speed, which is no drop
        trend = min(before + (before - earlier), before)
        lost = trend - v[k]
        if trend > 0.0 and lost >= limit:
            events.append((lost, k))
    out: list[dict[str, float]] = []
    for lost, k in sorted(events, key=lambda e: (e[0], -e[1]), reverse=True):
        # the drop starts with the first interval after the trend's that lost half of it
        j = next(i for i in range(k - n + 1, k + 1) if v[k - n] - v[i] >= 0.5 * lost)
        t = float(grid[j])
        if all(abs(t - e["t_s"]) > horizon for e in out):
            out.append({"t_s": t, "tip_m": float(pos[j]), "speed_drop_m_per_s": float(lost)})
    return sorted(out, key=lambda e: e["t_s"])


def crack_fractures(
    time: np.ndarray,
    tip: np.ndarray,
    x: np.ndarray,
    slip: np.ndarray,
    shear_wave_speed: float,
    arrest_position: float | None,
    arrest_time: float | None,
    wave_speed: float | None = None,
) -> list[dict[str, float]]:
    """Slab fractures that the crack feels, ``{x_m, t_s, opening_m}`` sorted by time.

    The count of a slab without a length scale of its own (the perfectly plastic
    ``"paper"`` slab), whose localised openings have no width of their own and whose number
    of openings depends on dx. What is counted does not: a fracture is

    - a sudden drop of the crack speed (`speed_drops`: 0.1 c_s below its 20 ms trend
      within 20 ms) with a slab separation (`separations`: a stretch of 0.1 m over 1 m of
      the final slab) at most ``wave_speed`` x 2 x `DROP_HORIZON` metres behind the tip
      (how far the slab's longitudinal wave, ``wave_speed`` [m/s], carries the news of a
      fracture while the drop shows; default 2 c_s), located at the one nearest the tip.
      A drop without a separation there (the onset of a strength gradient) is none;
    - the crown: when the crack arrested, the separation within `FRACTURE_GAP` of the
      arrest position (at the arrest time), unless a drop already stands there.

    ``opening_m`` is the separation's stretch. A separation
    that formed behind the crack without changing its speed (a perfectly plastic slab
    carries sigma_y h wherever it yields, so the force at the tip does not change) is not
    a fracture of the crack; `separations` lists them all.
    """
    seps = separations(x, slip)
    c_l = 2.0 * float(shear_wave_speed) if wave_speed is None else float(wave_speed)
    reach = 2.0 * DROP_HORIZON * c_l
    out: list[dict[str, float]] = []
    for d in speed_drops(time, tip, shear_wave_speed):
        near = [s for s in seps if -reach <= s["x_m"] - d["tip_m"] <= FRACTURE_GAP]
        if not near:
            continue
        f = min(near, key=lambda s: abs(s["x_m"] - d["tip_m"]))
        if all(abs(f["x_m"] - o["x_m"]) > FRACTURE_GAP for o in out):
            out.append({"x_m": f["x_m"], "t_s": d["t_s"], "opening_m": f["opening_m"]})
    if arrest_position is not None and math.isfinite(arrest_position):
        crown = [s for s in seps if abs(s["x_m"] - arrest_position) <= FRACTURE_GAP]
        if crown and all(abs(crown[0]["x_m"] - o["x_m"]) > FRACTURE_GAP for o in out):
            t = float(arrest_time) if arrest_time is not None else math.nan
            out.append({"x_m": crown[0]["x_m"], "t_s": t, "opening_m": crown[0]["opening_m"]})
    return sorted(out, key=lambda f: f["t_s"])


def smoothstep(z: Any) -> Any:
    """C1 ramp: 0 for z <= 0, 3 z^2 - 2 z^3 on [0, 1], 1 for z >= 1."""
    import jax.numpy as jnp

    z = jnp.clip(z, 0.0, 1.0)
    return z * z * (3.0 - 2.0 * z)


LENGTH_RAMP = 4.0  # [front widths] width of the ramp that counts a segment in L_smooth


def c1_ramp(z: Any) -> Any:
    """C1 ramp odd about 0: 0 for z <= -1/2, 2 (z + 1/2)^2 up to 0, 1 - 2 (1/2 - z)^2 up
    to 1/2, 1 above; its derivative is a hat of unit area."""
    import jax.numpy as jnp

    t = jnp.clip(z + 0.5, 0.0, 1.0)
    return jnp.where(t < 0.5, 2.0 * t * t, 1.0 - 2.0 * (1.0 - t) * (1.0 - t))


def smooth_arrest_position(model: Any, state: Any, width: float | None = None) -> Any:
    """Continuous crack length [m] (JAX): the event-based crack tip made continuous.

    Sum over particles of the failed (or sawn) fraction of each particle's segment of
    weak layer times its length (see the module doc). In 2D it is the failed area divided
    by the strip width. ``width`` [-], when given, replaces the failed fraction by a C1
    damage ramp over u_max / u_r in [1 - width, 1] (the choice where a slab fracture
    freezes the crack tip; see the module doc).
    """
    import jax.numpy as jnp

    area = failed_area(model, state, width)
    if model.dim == 2:  # divide by the strip width (particle centres span [s/2, L - s/2])
        length = jnp.max(model.saw.saw_coord) + jnp.min(model.saw.saw_coord)
        area = area / (model.saw.saw_coord.size * model.slab.area0 / length)
    return area


def weak_layer_damage(model: Any, state: Any, width: float | None = None) -> Any:
    """Per-particle weak-layer damage in [0, 1] from the maximum slip (JAX; 0 where the
    layer is unbreakable, sawing not included): the C1 ramp `LENGTH_RAMP` front widths
    wide about u_r (`smooth_arrest_position`), or with ``width`` [-] the smoothstep over
    u_max / u_r in [1 - width, 1]."""
    import jax.numpy as jnp

    from damjax.core.step import front_width

    finite = jnp.isfinite(model.weak_layer.u_res)
    u_r = jnp.where(finite, model.weak_layer.u_res, 1.0)
    if width is None:
        ramp = c1_ramp((state.u_max - u_r) / (LENGTH_RAMP * front_width(model)))
    else:
        ramp = smoothstep((state.u_max / u_r - (1.0 - width)) / width)
    return jnp.where(finite, ramp, 0.0)


def failed_area(model: Any, state: Any, width: float | None = None) -> Any:
    """Failed (or sawn) weak-layer area [m^2; m in 1D] (JAX): each particle's area times
    the ramp of its segment's maximum slip about u_r (`smooth_arrest_position`,
    `weak_layer_damage`); the continuous counterpart of the event-based released area
    (particles with u_max >= u_r)."""
    import jax.numpy as jnp

    spacing = model.slab.area0 if model.dim == 1 else jnp.sqrt(model.slab.area0)
    cut = jnp.clip((state.saw_pos - model.saw.saw_coord) / spacing + 0.5, 0.0, 1.0)
    damage = jnp.maximum(weak_layer_damage(model, state, width), cut)
    return jnp.sum(damage) * model.slab.area0  # 1D: area0 is the particle spacing [m]


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
    ``n_steps``).

    A crack arrests only after it ran by itself: while the saw still cuts (it stops once
    the tip leads it, `damjax.core.model`), a tip standing still is a slow saw, not an
    arrest. ``crack_front`` says which of these happened: "arrested", "reached_end" (the
    tip came within `ARREST_MARGIN` of the far end), "moving" (still running at the end
    of the run), "sawn_only" (the crack never ran ahead of the saw) or "controlled" (an
    unbreakable layer sawn on purpose). ``critical_cut_length_theory_m`` is the bar
    model's cut at which the crack runs (`damjax.theory.pst_critical_cut_length`, which
    accounts for the strength rising beyond L_ss): None where that model predicts no cut
    starts a crack. With a ``strength_profile`` the closed forms' L_ss, tau_p and theta do not
    describe the run, so ``arrest_length_m`` (L_ca - L_ss) and the theory values
    (``critical_cut_length_theory_m``, ``runaway_gradient_pa_per_m``) are None; so are
    the theory values with a softening weak layer (they are the brittle closed forms). A
    controlled run's ``tension_gradient_pa_per_m`` is the elastic ramp k_x: None where the
    slab yielded in tension (``opening`` > `YIELD_STRAIN`) over the fitted window. ``slab_yielded``:
    whether any of the slab did. ``max_crack_speed_over_cs`` is taken from the
    event-based tip, the furthest broken particle: where the layer fails ahead of the
    front (past a strong band, say) the tip jumps, and the ratio can exceed the strip's
    wave speed ratio c_p / c_s; it is None where no crack ran by itself ("sawn_only",
    "controlled": the tip moved with the saw)."""
    timed = n_steps if timed_steps is None else timed_steps
    p, s = result.params, result.setup
    cs = float(theory.shear_wave_speed(p))
    speed = crack_speed(result.time, result.tip)
    arrested, l_ca, t_stop = arrest(result.time, result.tip, s.length, s.dx)
    if s.controlled or not saw_stopped:
        arrested, l_ca = False, math.nan
    profiled = p.strength_profile is not None
    # the closed forms a_c and theta_run are those of a brittle weak layer (delta = 0)
    brittle = float(np.max(np.asarray(p.softening))) == 0.0
    max_speed = float(np.max(speed)) if speed.size else 0.0
    kx = kx_th = None
    if s.controlled:
        # once the cut has left the domain the whole slab hangs free: no tension ramp
        # the elastic ramp k_x only where the slab did not yield over the fitted window
        x = np.asarray(result.x)
        window = (x >= 0.3 * saw_position) & (x <= 0.8 * saw_position)
        ramp_yielded = bool(np.any(np.asarray(result.opening)[window] > YIELD_STRAIN))
        if saw_position < s.length and not ramp_yielded:
            kx = _none(tension_gradient(result.x, result.sigma_xx, saw_position))
        kx_th = float(theory.dynamic_gradient(p, float(p.saw_speed), s.lateral))
    lss = float(p.steady_length)
    # the bar model behind a_c and theta_run needs a slab that slides once released
    psi = float(np.max(p.slope_profile)) if p.slope_profile is not None else float(p.slope_deg)
    slides = psi > float(p.friction_deg)
    final_tip = float(result.tip[-1]) if result.tip.size else math.nan
    if s.controlled:
        front = "controlled"
    elif not saw_stopped:
        front = "sawn_only"
    elif arrested:
        front = "arrested"
    elif final_tip > s.length - ARREST_MARGIN:
        front = "reached_end"
    else:
        front = "moving"
    # a tip that only followed the saw moved at the saw's speed: no crack speed
    followed_saw = front in ("sawn_only", "controlled")
    a_c_th = (
        None
        if s.controlled or not slides or profiled or not brittle
        else float(theory.pst_critical_cut_length(p, s.lateral))
    )
    return {
        "lateral": s.lateral,
        "controlled": bool(s.controlled),
        "arrested": arrested,
        "crack_front": front,
        "arrest_position_m": _none(l_ca),
        "arrest_length_m": _none(l_ca - lss) if arrested and not profiled else None,
        "arrest_time_s": _none(t_stop) if arrested else None,
        "final_tip_m": _none(final_tip),
        "critical_cut_length_m": _none(saw_position) if saw_stopped else None,
        # None also where the closed form says no cut starts a crack (inf)
        "critical_cut_length_theory_m": None if a_c_th is None else _none(a_c_th),
        # an elastic brittle slab cannot arrest below this gradient (theory.runaway_gradient)
        "runaway_gradient_pa_per_m": None
        if s.controlled or is_plastic(p) or not slides or profiled or not brittle
        else float(theory.runaway_gradient(p, s.lateral)),
        "max_crack_speed_m_per_s": None if followed_saw else max_speed,
        "max_crack_speed_over_cs": None if followed_saw else max_speed / cs,
        "wave_speed_over_cs": float(theory.longitudinal_wave_speed(p, s.lateral)) / cs,
        "shear_wave_speed_m_per_s": cs,
        "slab_fractures": result.fractures,
        "tension_gradient_pa_per_m": kx,
        "tension_gradient_theory_pa_per_m": kx_th,
        "slab_yielded": bool(np.any(np.asarray(result.opening) > YIELD_STRAIN)),
        "fault": result.fault,
        "n_particles": int(n_particles),
        "n_steps": int(n_steps),
        "dt_s": float(result.time[0]) if result.time.size else None,
        "compile_time_s": float(compile_time_s),
        "wall_time_s": float(wall_time_s),
        "particle_steps_per_s": n_particles * timed / wall_time_s if wall_time_s > 0 else None,
    }


@dataclasses.dataclass(frozen=True)
class GradientCheck:
    """AD gradient of the continuous crack length against the event-based arrest.

    The event-based L_ca is a staircase in every parameter (steps of one particle
    spacing), so what it can be compared with is its trend: the least-squares slope over
    a window. The AD derivative varies across the window with the curvature of L_ca, so
    the verdict compares the window mean of the AD derivative (by the fundamental theorem
    of calculus, what a continuous surrogate's derivative must average to) with that
    slope; the derivative at the centre is reported beside it.

    Attributes:
        field: the `PSTParams` field differentiated.
        at: its value at the centre of the window [field units].
        ad: d L_smooth / d field by reverse mode at the centre [m per field unit].
        ad_mean: mean of d L_smooth / d field over the window's values where the crack
            arrested (those the event-based slope is fitted to) [m per field unit].
        event_slope: least-squares slope of the event-based L_ca over the window's runs
            that arrested [m per field unit].
        values: the field values of the window.
        arrests: event-based L_ca at each value [m] (nan: no arrest).
        ad_values: d L_smooth / d field at each value [m per field unit].
        lengths: L_smooth at each value [m] (nan where not given).
        length_slope: least-squares slope of L_smooth over the same runs (nan where not
            given) [m per field unit]: equal to ``event_slope`` when the continuous
            length has the event-based trend.
        relative_error: |ad_mean - event_slope| / |event_slope| [-]; nan where the
            event-based arrest is the same in every run (no trend to compare with).
        tolerance: the relative error accepted [-].
        ok: the verdict, relative_error <= tolerance; where the arrest is the same in
            every run, whether the change the AD mean predicts over the window stays
            below ``resolution``.
        resolution: the event-based arrest's step [m] (one particle spacing; nan where
            not given).
    """

    field: str
    at: float
    ad: float
    ad_mean: float
    event_slope: float
    values: tuple[float, ...]
    arrests: tuple[float, ...]
    ad_values: tuple[float, ...]
    lengths: tuple[float, ...]
    length_slope: float
    relative_error: float
    tolerance: float
    ok: bool
    resolution: float = math.nan

    def __str__(self) -> str:
        verdict = "agrees" if self.ok else "DISAGREES"
        n_ok = sum(math.isfinite(a) for a in self.arrests)
        runs = f"{len(self.values)} runs" + (
            f", {n_ok} arrested" if n_ok < len(self.values) else ""
        )
        if math.isnan(self.relative_error):  # the arrest did not move over the window
            change = abs(self.ad_mean) * (self.values[-1] - self.values[0])
            arrest = next(a for a in self.arrests if math.isfinite(a))
            return (
                f"d L / d {self.field} over [{self.values[0]:.6g}, {self.values[-1]:.6g}] "
                f"({runs}): the event-based arrest is {arrest:.6g} m in every run, no "
                f"trend to compare with; AD mean {self.ad_mean:.5g} (at {self.at:.6g}: "
                f"{self.ad:.5g}) predicts a change of {change:.3g} m over the window: "
                f"{verdict} (below one particle spacing, {self.resolution:.3g} m, "
                "is agreement)"
            )
        return (
            f"d L / d {self.field} over [{self.values[0]:.6g}, {self.values[-1]:.6g}] "
            f"({runs}): AD mean {self.ad_mean:.5g} (at {self.at:.6g}: "
            f"{self.ad:.5g}) vs event-based slope {self.event_slope:.5g}: {verdict} within "
            f"{self.tolerance:.0%} (error {self.relative_error:.1%}); slope of the "
            f"continuous length {self.length_slope:.5g}"
        )


def compare_gradient(
    field: str,
    values: Any,
    ad_values: Any,
    arrests: Any,
    tolerance: float = 0.1,
    lengths: Any = None,
    resolution: float = math.nan,
) -> GradientCheck:
    """Verdict on AD derivatives [m per field unit] at a window of parameter ``values``
    (equally spaced, odd count: the centre is the middle one) against the least-squares
    slope of the event-based arrests [m] there (at least 3 runs that arrested). Where
    the arrest is the same in every run there is no slope to compare with: the verdict
    is whether the change the AD mean predicts over the window stays below
    ``resolution`` [m] (one particle spacing; nan: it never does)."""
    values = np.asarray(values, float)
    ad_values = np.asarray(ad_values, float)
    arrests = np.asarray(arrests, float)
    ok = np.isfinite(arrests)
    if ok.sum() < 3:
        raise ValueError(
            f"gradient check of {field}: {int(ok.sum())} of {values.size} runs arrested; "
            "at least 3 are needed (a longer duration or PST, or a narrower window)"
        )
    slope = float(np.polyfit(values[ok], arrests[ok], 1)[0])
    lengths = np.full(values.shape, np.nan) if lengths is None else np.asarray(lengths, float)
    length_slope = (
        float(np.polyfit(values[ok], lengths[ok], 1)[0])
        if np.all(np.isfinite(lengths[ok]))
        else math.nan
    )
    # the same runs on both sides: where some runs did not arrest (the crack stopped at
    # the saw, or ran through), the event-based slope covers only the others
    ad_mean = float(np.mean(ad_values[ok]))
    if np.ptp(arrests[ok]) == 0.0:  # the staircase did not step: no trend (slope ~1e-16)
        slope, err = 0.0, math.nan
        verdict = abs(ad_mean) * (values[-1] - values[0]) < resolution
    else:
        err = abs(ad_mean - slope) / max(abs(slope), 1e-300)
        verdict = err <= tolerance
    mid = values.size // 2
    return GradientCheck(
        field=field,
        at=float(values[mid]),
        ad=float(ad_values[mid]),
        ad_mean=ad_mean,
        event_slope=slope,
        values=tuple(float(v) for v in values),
        arrests=tuple(float(a) for a in arrests),
        ad_values=tuple(float(a) for a in ad_values),
        lengths=tuple(float(v) for v in lengths),
        length_slope=length_slope,
        relative_error=float(err),
        tolerance=float(tolerance),
        ok=bool(verdict),
        resolution=float(resolution),
    )
