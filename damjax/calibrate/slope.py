"""Calibrating slab parameters against an observed release zone, through the 2D solver.

Given a weak-layer strength map (measured, put on the simulation grid with
`damjax.fields.map_on_grid`), the terrain, and an observed release polygon (or the
area inside a mapped crown line) rasterised on an observation grid, `calibrate_slope`
fits the slab tensile strength sigma_t (and optionally the weak-layer softening delta)
by gradient descent (optax Adam, over the logarithms) on a differentiable misfit between
the simulated and the observed release maps.

What is differentiated. Which particles' weak layer fails is a discrete event; the
smooth stand-in is the per-particle damage of `damjax.diagnostics` (the 1D smooth arrest
surrogate, here kept as a map):

    D_p = s((u_max,p / u_r,p - (1 - w)) / w),  s the C1 smoothstep, w = 0.5,

(1 where sawn), averaged over the particles of each observation cell, D_c in [0, 1]. The
loss is the mean squared difference sum_c (D_c - O_c)^2 / n_c against the observed
release fraction O_c (the Brier score of the release map), which is the area of the
symmetric difference between the two release zones for sharp maps, per cell.
`calibrate_slope` evaluates it per particle (each particle's damage D_p against the
observed value of the observation cell it sits in), which keeps the sub-cell position of
the simulated front in the loss. Gradients come from reverse mode through the whole run
(`damjax.core.loop.integrate_pure`, one state stored per segment of ~sqrt(n_steps) steps),
or, with ``calibrate_slope(..., gradient="fd")``, from central differences of forward runs.
The run is the host-loop solver's step (`damjax.core.step.step`) and initial state
(`damjax.core.model.build_slope`); only the slab/weak-layer leaves that depend on the
calibrated parameters (p0, delta, u_r) are replaced by traced values.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax.calibrate.inversion import (
    _positive_scalar,
    _stopped_early,
    _zero_gradient,
    optimizer_problems,
)
from damjax.core.loop import cpu_compiler_options, integrate_pure
from damjax.core.model import SlopeLayout, build_slope
from damjax.core.state import Model, State
from damjax.materials import mcc, weak_layer
from damjax.params import PSTParams, SlopeSetup
from damjax.slope.simulation import SlopeResult, prepare, warn_notes
from damjax.slope.simulation import particle_damage as slope_particle_damage
from damjax.validation import (
    DubiousInputWarning,
    as_number,
    expect_types,
    implausible,
    param_problems,
)

CALIBRATED = ("tensile_strength", "softening")
# relative width w of the damage ramp: wider than the 1D surrogate's 0.1, because after an
# arrest the particles just ahead of the front sit well below u_r and a narrow ramp gives
# them (and the loss) no gradient (measured: exactly 0 at w = 0.1, useful at w = 0.5)
DAMAGE_WIDTH = 0.5


@dataclasses.dataclass(frozen=True)
class SlopeProblem:
    """A slope run prepared once (static layout, model template, initial state).

    Attributes:
        params: the parameters the template was built with.
        setup: geometry and numerics.
        layout: grid and step counts.
        model: model template (its sigma_t- and delta-dependent leaves are replaced).
        state: initial state.
        xp, yp: particle reference positions [m] (numpy, (n,)).
        p0_rule: MCC p0 rule.
    """

    params: PSTParams
    setup: SlopeSetup
    layout: SlopeLayout
    model: Model
    state: State
    xp: np.ndarray
    yp: np.ndarray


def slope_problem(
    params: PSTParams,
    setup: SlopeSetup,
    *,
    slope_deg: Any,
    tau_peak: Any,
    fall_deg: Any = 0.0,
) -> SlopeProblem:
    """Build a `SlopeProblem` (the same model and initial state as `simulate_slope`).

    Args:
        params: slab and weak-layer parameters; tensile_strength must be finite (the
            plastic branch is compiled in).
        setup: geometry and numerics.
        slope_deg: local slope angle [deg], scalar or (nx, ny) at the cell centres.
        tau_peak: weak-layer strength [Pa], scalar or (nx, ny) at the cell centres.
        fall_deg: local fall direction relative to -x [deg].
    """
    if not math.isfinite(float(params.tensile_strength)):
        raise ValueError("slope_problem: tensile_strength must be finite (elasto-plastic slab)")
    prep = prepare(params, setup, slope_deg=slope_deg, tau_peak=tau_peak, fall_deg=fall_deg)
    warn_notes(prep, stacklevel=2)  # as simulate_slope does (a strength map in kPa?)
    layout = prep.layout
    model, state, xp, yp = build_slope(params, setup, layout, slope_deg, tau_peak, fall_deg)
    return SlopeProblem(params, setup, layout, model, state, xp, yp)


def with_slab(problem: SlopeProblem, tensile_strength: Any, softening: Any) -> Model:
    """The problem's model with sigma_t [Pa] and delta [-] (traceable) substituted."""
    m = problem.model
    dt = m.fracture.p0_init.dtype
    if m.fracture.crack_band:
        # p0 is proportional to sigma_t (both p0 rules): scaling the built p0 keeps the
        # slab's strength field, with tensile_strength as its new mean
        mean = float(problem.params.tensile_strength)
        p0 = m.fracture.p0_init * (jnp.asarray(tensile_strength, dt) / mean)
    else:
        p0 = mcc.p0_from_tensile_strength(
            jnp.asarray(tensile_strength, dt),
            m.fracture.mcc_m,
            m.fracture.mcc_beta,
            problem.setup.p0_rule,
            problem.setup.mcc_invariants,
        )
    delta = jnp.asarray(softening, dt)
    layer = m.weak_layer
    _, u_res = weak_layer.critical_displacements(layer.tau_peak, layer.stiffness, delta)
    # with_fields: the front width (from u_r) and w_c (from p0) are derived again
    return m.with_fields(p0_init=p0, softening=delta, u_res=u_res)


def particle_damage(model: Model, state: State, width: float = DAMAGE_WIDTH) -> Any:
    """Smooth weak-layer damage per particle in [0, 1] (module doc; 1 where sawn);
    `damjax.slope.simulation.particle_damage`."""
    return slope_particle_damage(model, state, width)


@dataclasses.dataclass(frozen=True)
class ObservationGrid:
    """Cells of size `cell` [m] covering the release area: the grid observations live on."""

    cell: float
    shape: tuple[int, int]

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre coordinates x (nx,), y (ny,) [m]."""
        return (np.arange(self.shape[0]) + 0.5) * self.cell, (
            np.arange(self.shape[1]) + 0.5
        ) * self.cell


def observation_grid(setup: SlopeSetup, cell: float) -> ObservationGrid:
    """Observation cells of size `cell` [m] over the setup's release area."""
    if isinstance(cell, bool) or not _positive_scalar(cell):
        raise ValueError(f"observation_grid: cell = {cell!r}: must be a number in (0, inf) m")
    if float(cell) > max(setup.length, setup.width):
        raise ValueError(
            f"observation_grid: cell = {cell!r}: must be at most the release area's longer "
            f"side, {max(setup.length, setup.width):g} m ({setup.length:g} m x "
            f"{setup.width:g} m): one cell larger than the area maps nothing"
        )
    return ObservationGrid(
        float(cell),
        (int(math.ceil(setup.length / cell - 1e-9)), int(math.ceil(setup.width / cell - 1e-9))),
    )


def _bins(xp: np.ndarray, yp: np.ndarray, grid: ObservationGrid) -> tuple[np.ndarray, np.ndarray]:
    ix = np.clip((xp / grid.cell).astype(int), 0, grid.shape[0] - 1)
    iy = np.clip((yp / grid.cell).astype(int), 0, grid.shape[1] - 1)
    flat = ix * grid.shape[1] + iy
    return flat, np.bincount(flat, minlength=grid.shape[0] * grid.shape[1])


def cell_average(values: Any, xp: np.ndarray, yp: np.ndarray, grid: ObservationGrid) -> Any:
    """Average of per-particle values over the observation cells, (nx, ny) (JAX,
    differentiable; empty cells are 0)."""
    flat, count = _bins(xp, yp, grid)
    n = grid.shape[0] * grid.shape[1]
    s = jax.ops.segment_sum(values, jnp.asarray(flat), num_segments=n)
    return jnp.reshape(s / jnp.maximum(jnp.asarray(count, s.dtype), 1.0), grid.shape)


def damage_map(
    problem: SlopeProblem,
    tensile_strength: Any,
    softening: Any,
    grid: ObservationGrid,
    width: float = DAMAGE_WIDTH,
) -> Any:
    """Smooth released fraction per observation cell (nx, ny) at the end of the run
    (JAX; differentiable in sigta_t [Pa] and delta [-])."""
    model = with_slab(problem, tensile_strength, softening)
    final, _ = integrate_pure(
        model, problem.state, problem.layout.n_chunks, problem.layout.chunk_steps
    )
    return cell_average(particle_damage(model, final, width), problem.xp, problem.yp, grid)


def release_loss(damage: Any, observed: Any) -> Any:
    """Mean squared difference between damage and observed release (maps, or per
    particle with the observed map sampled at each particle's cell) [-]."""
    obs = jnp.asarray(observed, damage.dtype)
    return jnp.mean((damage - obs) ** 2)


def observed_release(
    result: SlopeResult,
    grid: ObservationGrid,
    *,
    noise_std: float = 0.0,
    seed: int = 0,
) -> np.ndarray:
    """An observed release map from a (finer) reference run: the released fraction of each
    observation cell, plus Gaussian noise of `noise_std`, thresholded at 1/2 (a mapped
    release polygon with mapping errors near its edge) [0/1 float array]."""
    cx = np.repeat(result.x, result.y.size)
    noise = as_number(noise_std)
    if noise is None or not (math.isfinite(noise) and noise >= 0.0):
        raise ValueError(f"observed_release: noise_std = {noise_std!r}: must be a number >= 0")
    cy = np.tile(result.y, result.x.size)
    broken = np.isfinite(result.arrival_time).ravel().astype(float)
    flat, count = _bins(cx, cy, grid)
    frac = np.bincount(flat, weights=broken, minlength=count.size) / np.maximum(count, 1)
    frac = frac.reshape(grid.shape)
    if noise_std > 0:
        frac = frac + np.random.default_rng(seed).normal(0.0, noise_std, frac.shape)
    return (frac > 0.5).astype(float)


@dataclasses.dataclass
class SlopeCalibration:
    """Result of `calibrate_slope`.

    Attributes:
        estimates: fitted values (sigma_t [Pa], delta [-]): the evaluated iterate with the
            lowest loss (Adam's momentum can carry the last iterates past the minimum).
        loss: misfit at the estimates [-].
        history: per iteration, the loss and the parameter values.
        gradient: d loss / d log(parameter) at the estimates.
        wall_time_s: wall time of the whole calibration, compilation included [s].
        best_iteration: index in `history` of the estimates.
        stop_reason: why the iterations ended: "steps" (all of them ran), "tol" (every
            parameter's relative change fell below ``tol``), "zero_gradient" (the loss
            does not change with the fitted fields there: not a fit, warned) or
            "invalid_iterate" (an iterate left the valid range, warned).
    """

    estimates: dict[str, float]
    loss: float
    history: list[dict[str, float]]
    gradient: dict[str, float]
    wall_time_s: float
    best_iteration: int = 0
    stop_reason: str = "steps"


def _release_loss_fn(
    problem: SlopeProblem,
    observed: Any,
    grid: ObservationGrid,
    fields: Sequence[str],
    width: float,
) -> Any:
    """``loss(log_values (k,), fixed (2,))``: the per-particle release loss of a run."""
    idx = [CALIBRATED.index(f) for f in fields]
    flat, _ = _bins(problem.xp, problem.yp, grid)
    obs_p = jnp.asarray(np.asarray(observed, dtype=float).ravel()[flat])

    def loss(logv: Any, fixed: Any) -> Any:
        vals = fixed
        for k, i in enumerate(idx):
            vals = vals.at[i].set(jnp.exp(logv[k]))
        model = with_slab(problem, vals[0], vals[1])
        final, _ = integrate_pure(
            model, problem.state, problem.layout.n_chunks, problem.layout.chunk_steps
        )
        return release_loss(particle_damage(model, final, width), obs_p)

    return loss


def loss_and_grad(
    problem: SlopeProblem,
    observed: Any,
    grid: ObservationGrid,
    fields: Sequence[str],
    width: float = DAMAGE_WIDTH,
) -> Any:
    """jitted ``f(log_values (k,), fixed (2,)) -> (loss, d loss / d log_values)``, the
    per-particle release loss (module doc), for the
    calibrated `fields` (a subset of ("tensile_strength", "softening")); ``fixed`` holds
    (sigma_t, delta) for the fields not calibrated."""
    loss = _release_loss_fn(problem, observed, grid, fields, width)
    return jax.jit(jax.value_and_grad(loss), compiler_options=cpu_compiler_options())


def loss_and_fd_grad(
    problem: SlopeProblem,
    observed: Any,
    grid: ObservationGrid,
    fields: Sequence[str],
    step: float = 0.02,
    width: float = DAMAGE_WIDTH,
) -> Any:
    """`loss_and_grad` with central differences in the log values instead of reverse mode:
    ``f(log_values, fixed) -> (loss, gradient)`` from 1 + 2 k forward runs, ``step`` the
    difference in log space (0.02: +-2 %). For slabs whose fractures stop the crack (the
    "crack_band" slab), where reverse mode does not see how the released area moves with
    sigma_t (docs/verification/slope-calibration.md)."""
    loss = jax.jit(
        _release_loss_fn(problem, observed, grid, fields, width),
        compiler_options=cpu_compiler_options(),
    )

    def value_and_fd_grad(logv: Any, fixed: Any) -> tuple[Any, Any]:
        g = [
            (loss(logv.at[k].add(step), fixed) - loss(logv.at[k].add(-step), fixed)) / (2.0 * step)
            for k in range(logv.shape[0])
        ]
        return loss(logv, fixed), jnp.stack(g)

    return value_and_fd_grad


def calibrate_slope(
    problem: SlopeProblem,
    observed: Any,
    grid: ObservationGrid,
    *,
    fields: Sequence[str] = ("tensile_strength",),
    initial: dict[str, float] | None = None,
    steps: int = 20,
    learning_rate: float = 0.1,
    tol: float = 1e-3,
    progress: bool = False,
    gradient: str = "ad",
    fd_step: float = 0.02,
) -> SlopeCalibration:
    """Fit `fields` (sigma_t [Pa], delta [-]) so the simulated release map matches
    `observed` (an (nx, ny) map on `grid`, 1 = released).

    Adam (optax) over the logarithms (positivity, relative steps), learning rate
    `learning_rate` decaying as 1 / sqrt(1 + k / 5); stops after `steps` iterations or
    when the relative change of every parameter falls below `tol`, and returns the
    evaluated iterate with the lowest loss. The fields not fitted keep their `initial`
    value or the problem's parameters. ``gradient``: "ad" (reverse mode through the run,
    `loss_and_grad`) or "fd" (central differences of ``fd_step`` in the log values,
    `loss_and_fd_grad`: 3 forward runs per step for one field; for the "crack_band" slab,
    whose reverse-mode gradient misses the motion of its fractures).
    """
    import time

    expect_types("calibrate_slope", problem=(problem, SlopeProblem), grid=(grid, ObservationGrid))
    if isinstance(fields, str):  # one name, not its letters
        fields = (fields,)
    bad = [f for f in fields if f not in CALIBRATED]
    if bad:
        raise ValueError(f"calibrate_slope: cannot fit {bad}; choose from {CALIBRATED}")
    problems = optimizer_problems(steps, learning_rate, tol)
    if not fields:
        problems.append(f"fields: empty; name at least one of {CALIBRATED}")
    if len(set(fields)) != len(fields):
        problems.append(f"fields: {list(fields)} names a field more than once")
    if problems:
        raise ValueError("calibrate_slope: " + "\ncalibrate_slope: ".join(problems))
    p = problem.params
    start = {"tensile_strength": float(p.tensile_strength), "softening": float(p.softening)}
    unknown = sorted(k for k in (initial or {}) if k not in start)
    if unknown:
        raise ValueError(f"calibrate_slope: initial {unknown}: not one of {CALIBRATED}")
    for k, v in (initial or {}).items():
        value = as_number(v)
        if value is None:
            raise ValueError(f"calibrate_slope: initial {k} = {v!r}: must be a number in (0, inf)")
        start[k] = value
    for f in fields:  # the fit runs on the logarithms
        if not (math.isfinite(start[f]) and start[f] > 0):
            raise ValueError(
                f"calibrate_slope: initial {f} = {start[f]!r}: must be a number in (0, inf)"
            )
    # every start value, fitted or not, as simulate_slope checks them (a softening of -1;
    # a sigma_t of 4, meant in kPa, is noted)
    trial = dataclasses.replace(p, **start)
    errors = param_problems(trial)
    if errors:
        raise ValueError(
            "\n".join(f"calibrate_slope: initial {e.text(lambda f: f)}" for e in errors)
        )
    for note in implausible(trial, given=set(initial or {}) | set(fields)):
        warnings.warn(
            f"calibrate_slope: initial {note.text(lambda f: f)}", DubiousInputWarning, stacklevel=2
        )
    made = observation_grid(problem.setup, grid.cell)
    if made.shape != tuple(grid.shape):
        raise ValueError(
            f"calibrate_slope: grid has {grid.shape} cells of {grid.cell:g} m, the problem's "
            f"release area ({problem.setup.length:g} m x {problem.setup.width:g} m) "
            f"needs {made.shape}: make it with "
            "calibrate.slope.observation_grid(problem.setup, cell)"
        )
    obs = np.asarray(observed, float)
    if obs.shape != tuple(grid.shape):
        raise ValueError(
            f"calibrate_slope: observed has shape {obs.shape}: must be the observation grid's "
            f"{tuple(grid.shape)} (calibrate.slope.observation_grid)"
        )
    if not np.all(np.isfinite(obs)):
        raise ValueError(
            f"calibrate_slope: observed has {int(np.sum(~np.isfinite(obs)))} non-finite "
            "cells: must be 0 (not released) to 1 (released) everywhere"
        )
    if np.any((obs < 0) | (obs > 1)):
        raise ValueError(
            f"calibrate_slope: observed holds values from {float(obs.min()):g} to "
            f"{float(obs.max()):g}: must be 0 (not released) to 1 (released) everywhere"
        )
    dtype = problem.model.fracture.p0_init.dtype
    fixed = jnp.asarray([start[f] for f in CALIBRATED], dtype)
    x = jnp.asarray([math.log(start[f]) for f in fields], dtype)
    if gradient not in ("ad", "fd"):
        raise ValueError(f"calibrate_slope: gradient must be 'ad' or 'fd', got {gradient!r}")
    if as_number(fd_step) is None or not (math.isfinite(fd_step) and 0.0 < fd_step <= 0.5):
        raise ValueError(f"calibrate_slope: fd_step must be in (0, 0.5] (log space), got {fd_step}")
    if gradient == "fd":
        vg = loss_and_fd_grad(problem, observed, grid, fields, fd_step)
    else:
        vg = loss_and_grad(problem, observed, grid, fields)
    import optax  # deferred: importing damjax stays light

    sched = optax.scale_by_schedule(lambda k: 1.0 / jnp.sqrt(1.0 + k / 5.0))
    opt = optax.chain(optax.adam(learning_rate), sched)
    st = opt.init(x)
    hist: list[dict[str, float]] = []
    t0 = time.perf_counter()
    best: tuple[float, Any, Any, int] = (math.inf, x, jnp.full_like(x, jnp.nan), 0)
    reason = "steps"
    for k in range(steps):
        try:
            val, g = vg(x, fixed)
        except (ValueError, RuntimeError) as exc:  # an iterate outside the valid range
            if not hist:
                raise
            _stopped_early("calibrate_slope", k, exc)
            reason = "invalid_iterate"
            break
        row = {"loss": float(val), **{f: math.exp(float(x[i])) for i, f in enumerate(fields)}}
        hist.append(row)
        if progress:
            print(f"[calibrate_slope] {k}: {row}", flush=True)
        if float(val) < best[0]:
            best = (float(val), x, g, k)
        if _zero_gradient("calibrate_slope", k, g, row):
            reason = "zero_gradient"
            break
        upd, st = opt.update(g, st)
        x_new = optax.apply_updates(x, upd)
        done = bool(jnp.all(jnp.abs(x_new - x) < tol))
        x = x_new
        if done:
            reason = "tol"
            break
    loss_best, x_best, g_best, k_best = best
    est = dict(start)
    est.update({f: math.exp(float(x_best[i])) for i, f in enumerate(fields)})
    return SlopeCalibration(
        estimates={f: est[f] for f in CALIBRATED},
        loss=loss_best if math.isfinite(loss_best) else math.nan,
        history=hist,
        gradient={f: float(g_best[i]) for i, f in enumerate(fields)},
        best_iteration=k_best,
        wall_time_s=time.perf_counter() - t0,
        stop_reason=reason,
    )
