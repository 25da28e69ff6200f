"""Deliverable 8 acceptance: recover the slab tensile strength from a release zone.

The synthetic field case (small, so it runs in minutes on 2 cores):

- truth: a 30 m x 8 m planar 35 deg release area, weak-layer strength a Gaussian random
  field (1000 Pa at the lower edge, 125 Pa/m up-slope, std 100 Pa, correlation length
  4 m) on a fine 0.125 m grid; slab sigma_t = 4 kPa, E = 4 MPa, delta = 1;
- "observed" release polygon: the truth run on a *finer grid* (dx 0.125 m, 2 x 2
  particles per cell), rasterised on 0.5 m observation cells, with Gaussian noise of
  0.2 on each cell's released fraction before thresholding (mapping errors at the edge);
- "measured" strength map: the true field sampled every 1 m with 20 Pa white noise,
  put on the calibration grid with `damjax.fields.map_on_grid`;
- calibration: dx 0.125 m (`--dx`), 1 particle per cell, sigma_t from `--start` (2.5 kPa)
  by `damjax.slope_calibration.calibrate_slope`.

    python -m benchmarks.slope_calibration_case [--start 2500] [--steps 12] [--dx 0.125]

Prints JSON lines: the reference run, each iteration, and the result with the relative
error of sigma_t.

Measured on the default dx 0.125 m calibration grid (quiet 2-core Intel Xeon, 2026-11-23):
reference 37.8 s; calibration 15 360 particles, 3250 steps, 59 s per gradient, 12 Adam
steps in 706 s: sigma_t 2500 -> 3290 -> 3838 (loss 0.0103, iteration 5) -> overshoot to
4184 -> 4011 -> final estimate 3899 Pa, **-2.5 %** of the true 4000 Pa (target 10 %).
START2

Earlier, on the coarser dx 0.25 m grid (2 busy CPU cores, MCC '3d' invariants of a618928): the
reference (dx 0.125 m, 61 440 particles, 3250 steps, 86 s) releases 75.6 m^2 (arrest
7.2 m up-slope of the start, after a slab fracture); the calibration (3840 particles,
1650 steps, ~20-30 s per gradient) went 2500 -> 3292 Pa in 3 Adam steps (loss 0.0097),
overshot to 3590 and ended at 3127 Pa after 13 iterations: -22 %, the 10 % target is
**not met**. A forward scan of the loss on the calibration grid (sigma_t 2500-6000 Pa in
250 Pa steps) is smooth and unimodal with its minimum at 3250 Pa, where the coarse run
releases 74.9 m^2, the reference's area; at the true 4000 Pa the coarse grid releases
85.8 m^2. So the optimiser finds the minimum; the misfit is the grid dependence of the
slab fracture between dx 0.25 m / 1 ppc and dx 0.125 m / 2 x 2 ppc (about -19 % in
sigma_t), which the calibration absorbs into sigma_t. The same forward scan on a
dx 0.125 m, 1 particle-per-cell calibration grid (15 360 particles, ``--dx 0.125``):
loss 0.0406 / 0.0109 / 0.0155 / 0.0305 / 0.0618 at sigma_t 3250 / 3750 / 4000 / 4250 /
4750 Pa (areas 66.6 / 74.3 / 77.7 / 81.3 / 88.8 m^2): the minimum moves to 3750-4000 Pa,
within 10 % of the truth, which is why dx 0.125 m is the default (the run above).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import jax
import numpy as np

from damjax import fields
from damjax import slope_calibration as sc
from damjax.scenarios.generic_slope import fig12_params
from damjax.scenarios.slope import SlopeSetup, simulate_slope

L, W, THETA, TRUE_SIGMA_T = 30.0, 8.0, 125.0, 4000.0


def synthetic_case(
    dx: float = 0.25, fine_dx: float = 0.125, obs_cell: float = 0.5, seed: int = 7
) -> dict:
    """Truth field, reference (fine) run, observed map, measured map, coarse problem."""
    xf = np.arange(0.0, L + 1e-9, 0.125)
    yf = np.arange(0.0, W + 1e-9, 0.125)
    true_tau = np.asarray(
        fields.grf(
            jax.random.key(seed),
            (xf.size, yf.size),
            0.125,
            mean=1000.0,
            std=100.0,
            length_scale=4.0,
            trend=(THETA, 0.0),
        )
    )

    def centres(h: float) -> tuple[np.ndarray, np.ndarray]:
        return (np.arange(round(L / h)) + 0.5) * h, (np.arange(round(W / h)) + 0.5) * h

    start = (2.0, W / 2)
    fine = SlopeSetup(
        length=L,
        width=W,
        dx=fine_dx,
        duration=1.5,
        start=start,
        particles_per_cell=2,
        chunk_steps=50,
    )
    t0 = time.perf_counter()
    ref = simulate_slope(
        fig12_params(tensile_strength=TRUE_SIGMA_T),
        fine,
        slope_deg=35.0,
        tau_peak=fields.map_on_grid(xf, yf, true_tau, *centres(fine_dx)),
    )
    ref_time = time.perf_counter() - t0
    coarse = SlopeSetup(
        length=L, width=W, dx=dx, duration=1.5, start=start, particles_per_cell=1, chunk_steps=50
    )
    grid = sc.observation_grid(coarse, obs_cell)
    observed = sc.observed_release(ref, grid, noise_std=0.2, seed=seed)
    rng = np.random.default_rng(seed + 1)
    xm, ym = np.arange(0.0, L + 1e-9, 1.0), np.arange(0.0, W + 1e-9, 1.0)
    measured = fields.map_on_grid(xf, yf, true_tau, xm, ym) + rng.normal(
        0, 20.0, (xm.size, ym.size)
    )
    tau = fields.map_on_grid(xm, ym, measured, *centres(dx))
    problem = sc.slope_problem(fig12_params(), coarse, slope_deg=35.0, tau_peak=tau)
    return dict(
        reference=ref,
        reference_time_s=ref_time,
        observed=observed,
        grid=grid,
        problem=problem,
        measured_map=(xm, ym, measured),
        true_map=(xf, yf, true_tau),
    )


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--start", type=float, default=2500.0, help="initial sigma_t [Pa]")
    ap.add_argument("--steps", type=int, default=12, help="Adam iterations")
    ap.add_argument("--lr", type=float, default=0.1, help="learning rate (log space)")
    ap.add_argument("--dx", type=float, default=0.125, help="calibration grid spacing [m]")
    a = ap.parse_args(argv)
    c = synthetic_case(dx=a.dx)
    s = c["reference"].summary
    print(
        json.dumps(
            dict(
                case="slope_calibration_reference",
                release_area_m2=s["release_area_m2"],
                upslope_arrest_distance_m=s["upslope_arrest_distance_m"],
                n_particles=s["n_particles"],
                n_steps=s["n_steps"],
                wall_time_s=round(c["reference_time_s"], 2),
                observed_released_cells=int(c["observed"].sum()),
            )
        ),
        flush=True,
    )
    fit = sc.calibrate_slope(
        c["problem"],
        c["observed"],
        c["grid"],
        initial={"tensile_strength": a.start},
        steps=a.steps,
        learning_rate=a.lr,
        progress=True,
    )
    est = fit.estimates["tensile_strength"]
    print(
        json.dumps(
            dict(
                case="slope_calibration",
                true_sigma_t=TRUE_SIGMA_T,
                start=a.start,
                sigma_t=est,
                rel_error=est / TRUE_SIGMA_T - 1,
                loss=fit.loss,
                iterations=len(fit.history),
                best_iteration=fit.best_iteration,
                history=fit.history,
                n_particles=int(c["problem"].xp.size),
                n_steps=c["problem"].layout.n_steps,
                wall_time_s=round(fit.wall_time_s, 1),
            )
        ),
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
