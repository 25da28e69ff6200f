"""Slope calibration: recover the slab tensile strength from a release zone.

The synthetic field case (small, so it runs in minutes on 2 cores):

- truth: a 30 m x 8 m planar 35 deg release area, weak-layer strength a Gaussian random
  field (1000 Pa at the lower edge, 125 Pa/m up-slope, std 100 Pa, correlation length
  4 m) on a fine 0.125 m grid; slab sigma_t = 4 kPa, E = 4 MPa, delta = 1, and a slab
  fracture energy G_f = 1 J/m^2 (`--fracture-energy`; crack-band softening, known to the
  calibration; `--fracture-energy inf` is the paper's perfectly plastic slab);
- "observed" release polygon: the truth run on a *finer grid* (`--fine-dx`, default half
  the calibration's, 2 x 2 particles per cell), rasterised on 0.5 m observation cells, with
  Gaussian noise of 0.2 on each cell's released fraction before thresholding (mapping
  errors at the edge);
- "measured" strength map: the true field sampled every 1 m with 20 Pa white noise,
  put on the calibration grid with `damjax.fields.map_on_grid`;
- calibration: dx 0.125 m (`--dx`), 1 particle per cell, sigma_t from `--start` (2.5 kPa)
  by `damjax.calibrate.slope.calibrate_slope` (the lowest-loss evaluated iterate).

    python -m verification.slope_calibration_case [--start 2500] [--steps 12] [--dx 0.125]
        [--fine-dx 0.0625] [--fracture-energy 1.0]

Prints JSON lines: the reference run, each iteration, and the result with the relative
error of sigma_t.

Measured with crack-band softening (G_f = 1 J/m^2, 2026-11-24, 2-core Intel Xeon, other jobs
running during the reference run): the reference (dx 0.0625 m, 245 760 particles, 6500
steps, 348 s) releases 58.5 m^2, arrest 5.48 m up-slope of the start (the truth releases
57.7 / 56.9 / 57.8 m^2 on dx 0.25 / 0.125 m with 1 particle per cell and 0.125 m with
2 x 2: grid-independent); calibration 15 360 particles, 3250 steps, 12 Adam steps in
770 s: sigma_t 2500 -> 2763 -> 3027 -> 3289 -> 3555 -> 3818 (loss 0.0107, the estimate)
-> 4091 -> 4239 -> 4296 -> 4280 -> 4226 -> 4136: **-4.6 %** of the true 4000 Pa (target
10 %: met); every iterate from the sixth on lies within 7.4 % of the truth. Re-run at commit
5f73c49 (same machine type, nothing else running): the same reference (58.5 m^2, 5.48 m; 184.7 s)
and iterates to 1 Pa, the estimate 3817.9 Pa (-4.55 %) at iteration 5; 12 min 30 s in all.

Measured with the crack-band slab (`--slab-fracture crack_band`: its own G_f 0.12 J/m^2 and
the same seeded tensile-strength field on both grids; 2026-11-25, commit 02ee6cc; JSON lines
in results/slab_fracture/slope_calibration_crack_band.jsonl): the reference releases
43.5 m^2, arrest 3.45 m up-slope of the start. From 2500 Pa, 12 Adam steps: 2500 -> 2262 ->
... -> 2901 Pa (loss 0.043 -> 0.027, still falling; the first gradient points away from
the truth): -27.5 %, not within 10 %. Restarted from 2901 Pa (`--start 2901 --steps 20`,
stopped after 16): 3206 -> 3435 -> 3629 -> 3814 -> 3974 Pa (loss 0.0088, the estimate,
-0.6 %) -> 4094 ... 4542 (loss 0.015-0.021): within 10 % after 17 steps in all (899 s).
With central differences (`--slab-fracture crack_band --gradient fd`, the code of commit b4722b0,
2026-11-25): 2500 -> 2763 -> ... -> 3955 Pa (loss 0.0085, the estimate, -1.1 %) -> 4032,
stopped after 10 iterations, 353 s. With the energy-consistent 2D crack-band map (commit
e796b67; re-run at commit ad6a4df, other jobs on the machine): the reference releases
43.3 m^2, arrest 3.39 m; 2500 -> 2763 -> 3014 -> 3233 -> 3443 -> 3656 -> 3876 Pa (loss
0.0096, the estimate, -3.1 %) -> 4084 -> 4244 -> 4377, 10 iterations, 414 s.
Reverse mode at 2500 Pa gives d loss / d log sigma_t
= +3e-4 where differences give -0.064 (2 %) / -0.20 (0.5 %): it misses how the slab
fractures move with sigma_t.

Measured with the perfectly plastic slab (`--fracture-energy inf`; quiet 2-core AMD EPYC,
2026-11-23): reference dx 0.0625 m (245 760
particles, 6500 steps, 241 s) releases 65.9 m^2, arrest 6.17 m up-slope of the start;
calibration 15 360 particles, 3250 steps, 58 s per gradient, 12 Adam steps in 693 s:
sigma_t 2500 -> 3289 (loss 0.0124) -> 3461 -> 3217 (loss 0.0103, the estimate) -> 3046:
**-19.6 %** of the true 4000 Pa. Re-run on 2026-11-23 (the
per-step reverse-mode scheme and the row layout of strains): reference 201.9 s, iterates
within 2 Pa of the ones above, the estimate 3218 Pa at iteration 8 (-19.6 %), 740.6 s for
the 12 gradients (short test runs overlapped part of it).

That error is the grid dependence of the perfectly plastic slab fracture, not the
optimiser, and is what the crack-band softening removes: the truth run (sigma_t = 4000 Pa)
releases 85.8 m^2 on dx 0.25 m (1 particle per cell), 77.7 m^2 on
0.125 m (1 per cell), 75.6 m^2 on 0.125 m (2 x 2 per cell) and 65.9 m^2 on 0.0625 m (2 x 2):
about 10 m^2 less per halving of dx, with no sign of convergence. The slab's tensile failure
is perfectly plastic (MCC, no softening length; see docs/model/slab.md on the theta-30 fracture
count): the opening localises in one cell, so a finer grid fracture is cheaper and stops the
crack earlier, and a calibration on a coarser grid absorbs the difference into sigma_t. The
same calibration against a reference of the *same* grid spacing (`--fine-dx 0.125`, 2 x 2
particles per cell, i.e. a different discretisation but not a finer grid) lands within
10 %: 2500 -> 3838 Pa (loss 0.0103, iteration 5), -4.1 % (706 s); from 6000 Pa -> 3733 Pa
(loss 0.0115, iteration 6), -6.7 % (652 s) (the lowest-loss iterates of those two runs,
made before `calibrate_slope` returned them; its last iterates were 3899 and 3373 Pa).
On dx 0.25 m against the 0.125 m reference (earlier stop, busy machine): 3127 Pa, -22 %; a
forward scan on that grid put the loss minimum at 3250 Pa, where the coarse run releases
the reference's 74.9 m^2.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import jax
import numpy as np

from damjax import SlopeSetup, fields, simulate_slope
from damjax.calibrate import slope as sc
from damjax.slope.generic import fig12_params

L, W, THETA, TRUE_SIGMA_T = 30.0, 8.0, 125.0, 4000.0
G_F = 1.0  # slab fracture energy [J/m^2] of the truth and of the calibrated model


def synthetic_case(
    dx: float = 0.125,
    fine_dx: float | None = None,
    obs_cell: float = 0.5,
    seed: int = 7,
    fracture_energy: float | None = G_F,
    slab_fracture: str = "paper",
) -> dict:
    """Truth field, reference (fine) run, observed map, measured map, coarse problem.

    The reference runs on ``fine_dx`` (default dx / 2) with 2 x 2 particles per cell; the
    slab's fracture energy ``fracture_energy`` [J/m^2] (inf: perfectly plastic; None: the
    slab model's own) and its model ``slab_fracture`` ("paper" or "crack_band", with the
    same seeded tensile-strength field on both grids) are known to the calibration."""
    fine_dx = 0.5 * dx if fine_dx is None else fine_dx
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

    def slope_setup(h: float, particles_per_cell: int) -> SlopeSetup:
        return SlopeSetup(
            length=L,
            width=W,
            dx=h,
            duration=1.5,
            start=(2.0, W / 2),  # crack initiation, 2 m up-slope of the lower edge
            particles_per_cell=particles_per_cell,
            chunk_steps=50,
            slab_fracture=slab_fracture,
        )

    fine = slope_setup(fine_dx, 2)
    t0 = time.perf_counter()
    ref = simulate_slope(
        fig12_params(tensile_strength=TRUE_SIGMA_T, slab_fracture_energy=fracture_energy),
        fine,
        slope_deg=35.0,
        tau_peak=fields.map_on_grid(xf, yf, true_tau, *centres(fine_dx)),
    )
    ref_time = time.perf_counter() - t0
    coarse = slope_setup(dx, 1)
    grid = sc.observation_grid(coarse, obs_cell)
    observed = sc.observed_release(ref, grid, noise_std=0.2, seed=seed)
    rng = np.random.default_rng(seed + 1)
    xm, ym = np.arange(0.0, L + 1e-9, 1.0), np.arange(0.0, W + 1e-9, 1.0)
    measured = fields.map_on_grid(xf, yf, true_tau, xm, ym) + rng.normal(
        0, 20.0, (xm.size, ym.size)
    )
    tau = fields.map_on_grid(xm, ym, measured, *centres(dx))
    problem = sc.slope_problem(
        fig12_params(slab_fracture_energy=fracture_energy), coarse, slope_deg=35.0, tau_peak=tau
    )
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
    ap.add_argument(
        "--fine-dx", type=float, default=None, help="reference grid spacing [m] (default dx/2)"
    )
    ap.add_argument(
        "--fracture-energy",
        type=float,
        default=None,
        help=f"slab fracture energy G_f [J/m^2] (inf: the perfectly plastic slab; default "
        f"{G_F} for the paper slab, the model's own for crack_band)",
    )
    ap.add_argument(
        "--slab-fracture",
        default="paper",
        help="slab fracture model: paper (one-cell softening with --fracture-energy) or "
        "crack_band (its own G_f, 0.12 J/m^2, unless --fracture-energy is given)",
    )
    ap.add_argument(
        "--gradient",
        choices=("ad", "fd"),
        default="ad",
        help="ad: reverse mode through the run; fd: central differences of forward runs",
    )
    ap.add_argument("--fd-step", type=float, default=0.02, help="fd step in log sigma_t")
    a = ap.parse_args(argv)
    g_f = a.fracture_energy
    if g_f is None and a.slab_fracture == "paper":
        g_f = G_F
    c = synthetic_case(
        dx=a.dx, fine_dx=a.fine_dx, fracture_energy=g_f, slab_fracture=a.slab_fracture
    )
    s = c["reference"].summary
    print(
        json.dumps(
            dict(
                case="slope_calibration_reference",
                slab_fracture=a.slab_fracture,
                fracture_energy=g_f,
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
        gradient=a.gradient,
        fd_step=a.fd_step,
    )
    est = fit.estimates["tensile_strength"]
    print(
        json.dumps(
            dict(
                case="slope_calibration",
                slab_fracture=a.slab_fracture,
                gradient=a.gradient,
                fracture_energy=g_f,
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
