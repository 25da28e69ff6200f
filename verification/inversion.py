"""Joint inversion of the weak-layer softening delta and the slab tensile
strength sigma_t from noisy observed arrest positions, through the solver.

    python -m verification.inversion                  # defaults below, a few minutes on 1 core
    python -m verification.inversion --steps 20       # shorter descent

Observations (honest: another grid, event-based, noisy): PSTs with the true parameters
(delta = 1, sigma_t = 6 kPa, elasto-plastic slab) at several strength gradients theta,
run at dx = 0.01 m; the event-based arrest position L_ca of each plus N(0, 1 m) noise
(seeded) is the observation.

Model: the same PSTs at dx = 0.04 m, L = 30 m (L_ss = 10 m), the smooth surrogate
`damjax.arrest_position_smooth` (pure differentiable path `pst.run_pure`) with a damage
ramp of width 0.5 (the whole softening branch at delta = 1; the default 0.1 is flat where
a slab fracture stops the crack: see `damjax.diagnostics`), and
`damjax.calibrate.invert`: optax Adam on log(delta), log(sigma_t), from two starting
points. One observation cannot identify two parameters; several theta can, when delta
and sigma_t move the arrest differently from one theta to the next.

Printed (JSON lines): every observation; at the truth, the model's prediction and its
gradient by AD against central finite differences (the regime check: a flat surrogate
has AD = FD = 0); each inversion's estimates, standard errors, Gauss-Newton Hessian
eigenvalues and condition number; a profile of the misfit along each parameter and along
the weakest Hessian eigenvector through the first optimum.

Measured (defaults, commit a618928; 1575 s in all on a CPU shared with other jobs, of
which 666 s and 768 s for the two 40-step descents):

- observations (dx 0.01 m, each with one slab fracture at the tip): theta 150, 300,
  1000 Pa/m: L_ca 19.54, 14.91, 11.48 m; observed (noise) 19.66, 14.78, 12.12 m.
- regime check at the truth (dx 0.04 m, AD vs central differences with 2 % steps),
  dL/d delta [m] and dL/d sigma_t [m/kPa]: width 0.5: -3.26/-3.30 and 1.92/1.97
  (theta 150), -1.53/-1.74 and 0.87/0.98 (theta 300), -0.63/-0.63 and 0.20/0.21
  (theta 1000). The default width 0.1 gives -2.92, -2.78, 0 and 1.71, 1.58, 0: wrong
  where a particle happens to sit in the narrow ramp, exactly 0 where none does.
- descent from (delta 0.4, sigma_t 3.5 kPa): (0.26, 4.54 kPa), misfit 0.17 m^2;
  from (2.5, 9 kPa): (2.32, 7.81 kPa), misfit 0.66 m^2 (truth: 1, 6 kPa). Both end on
  one valley, sigma_t ~ delta^0.25, that passes through the truth (delta 1 on it:
  sigma_t ~ 6.3 kPa). Adam at a constant rate oscillates along it (loss history).
- identifiability: Gauss-Newton Hessian in (log delta, log sigma_t), eigenvalues
  0.012 and 260 (condition number 2.2e4) at the first optimum, 0.54 and 495 (923) at
  the second; weak direction mostly log delta (-0.99, -0.12). Standard errors with 1 m
  noise: delta +-3.4, sigma_t +-7.3 kPa. Profile through the first optimum: +-0.4 in
  log sigma_t alone raises the misfit from 0.17 to 17-40 m^2; +-0.4 along the weak
  eigenvector changes it by less than 0.02 m^2. So sigma_t is well constrained for a
  given delta, delta is not: with fracture-stopped arrests at these theta, delta and
  sigma_t move the arrest positions in nearly the same ratio (dL/dlog sigma_t over
  dL/dlog delta = -3.5, -3.4, -1.9 at the truth), and 1 m noise cannot separate them.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax import PSTParams, PSTSetup, calibrate, pst
from damjax.sweep import sweep

FIELDS = ("softening", "tensile_strength")
TRUTH = {"softening": 1.0, "tensile_strength": 6000.0}
STARTS = (
    {"softening": 0.4, "tensile_strength": 3500.0},
    {"softening": 2.5, "tensile_strength": 9000.0},
)


def emit(obj: dict[str, Any]) -> None:
    """One JSON line on stdout."""
    print(json.dumps(obj), flush=True)


def observe(
    thetas: list[float], base: PSTParams, setup: PSTSetup, noise: float, seed: int
) -> list[dict[str, Any]]:
    """Event-based L_ca [m] of the true PSTs on the fine setup, plus N(0, noise) [m]."""
    batch = dataclasses.replace(base, strength_gradient=np.asarray(thetas, float))
    res = sweep(batch, setup)
    rng = np.random.default_rng(seed)
    out = []
    for t, r in zip(thetas, res, strict=True):
        eps = float(rng.normal(0.0, noise))
        l_ca = r.arrest_position
        out.append(
            {
                "theta": t,
                "L_ca_fine_m": None if math.isnan(l_ca) else l_ca,
                "L_smooth_fine_m": r.arrest_position_smooth,
                "n_fractures": len(r.fractures),
                "fracture_x_m": [round(f["x_m"], 2) for f in r.fractures],
                "noise_m": eps,
                "observed_m": None if math.isnan(l_ca) else l_ca + eps,
            }
        )
    return out


def gradient_check(
    theta: float, base: PSTParams, fns: tuple[Any, Any, Any], rel: float = 0.02
) -> dict[str, Any]:
    """L_smooth at the truth and d L_smooth / d field by AD and central differences
    (relative step ``rel``); ``fns`` = (jitted value_and_grad, jitted value, jitted
    gradient with the default ramp width)."""
    vg, fj, g_default = fns
    params = dataclasses.replace(base, strength_gradient=theta)
    val, grad = vg(params)
    g0 = g_default(params)
    row: dict[str, Any] = {"theta": theta, "L_smooth_m": float(val)}
    for name in FIELDS:
        row[f"dL_d{name}_ad_default_width"] = float(getattr(g0, name))
    for name in FIELDS:
        v = float(getattr(params, name))
        h = rel * v
        up = float(fj(dataclasses.replace(params, **{name: v + h})))
        dn = float(fj(dataclasses.replace(params, **{name: v - h})))
        row[f"dL_d{name}_ad"] = float(getattr(grad, name))
        row[f"dL_d{name}_fd"] = (up - dn) / (2 * h)
    return row


def misfit(
    values: dict[str, float],
    obs: list[tuple[dict[str, float], float]],
    base: PSTParams,
    fj: Any,
) -> float:
    """Sum of squared residuals [m^2] of the smooth surrogate (``fj``: jitted L_smooth)."""
    p0 = dataclasses.replace(base, **values)
    preds = [float(fj(dataclasses.replace(p0, **o))) for o, _ in obs]
    return float(sum((a - b) ** 2 for a, (_, b) in zip(preds, obs, strict=True)))


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--thetas", default="150,300,1000", help="strength gradients [Pa/m]")
    ap.add_argument("--length", type=float, default=30.0, help="PST length [m]")
    ap.add_argument("--steady-length", type=float, default=10.0, help="L_ss [m]")
    ap.add_argument("--duration", type=float, default=1.0, help="simulated time [s]")
    ap.add_argument("--dx", type=float, default=0.04, help="model grid spacing [m]")
    ap.add_argument("--dx-obs", type=float, default=0.01, help="observation grid [m]")
    ap.add_argument("--noise", type=float, default=1.0, help="observation noise std [m]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=40, help="Adam steps per start")
    ap.add_argument("--lr", type=float, default=0.08, help="Adam learning rate (log space)")
    ap.add_argument("--no-profile", action="store_true")
    ap.add_argument(
        "--smooth-width",
        type=float,
        default=0.5,
        help="damage-ramp width of the surrogate (0.5: the softening branch at delta 1)",
    )
    a = ap.parse_args(argv)
    t_start = time.perf_counter()
    thetas = [float(t) for t in a.thetas.split(",")]
    base = PSTParams(steady_length=a.steady_length, **TRUTH)
    fine = PSTSetup(length=a.length, dx=a.dx_obs, duration=a.duration, chunk_steps=2000)
    model_setup = PSTSetup(length=a.length, dx=a.dx, duration=a.duration, chunk_steps=250)

    t0 = time.perf_counter()
    obs_rows = observe(thetas, base, fine, a.noise, a.seed)
    for r in obs_rows:
        emit({"case": "observation", "dx": a.dx_obs, **r})
    emit({"case": "observations_wall_s", "value": round(time.perf_counter() - t0, 1)})
    obs = [({"strength_gradient": r["theta"]}, r["observed_m"]) for r in obs_rows]
    if any(L is None for _, L in obs):
        emit({"case": "error", "message": "a true PST did not arrest; choose other thetas"})
        return 1

    layout = pst.make_layout(base, model_setup)  # E is not inverted: one layout

    def smooth(p: PSTParams) -> Any:
        return pst.arrest_position_smooth(p, model_setup, layout, width=a.smooth_width)

    def smooth_default(p: PSTParams) -> Any:
        return pst.arrest_position_smooth(p, model_setup, layout)

    fns = (
        jax.jit(jax.value_and_grad(smooth)),
        jax.jit(smooth),
        jax.jit(jax.grad(smooth_default)),
    )
    for t in thetas:  # the regime check at the truth, on the model grid
        t0 = time.perf_counter()
        row = gradient_check(t, base, fns)
        row["wall_s"] = round(time.perf_counter() - t0, 1)
        emit({"case": "truth_gradient", "dx": a.dx, **row})

    fits = []
    for k, start in enumerate(STARTS):
        t0 = time.perf_counter()
        p0 = dataclasses.replace(base, **start)
        inv = calibrate.invert(
            obs,
            p0,
            model_setup,
            list(FIELDS),
            noise_std=a.noise,
            steps=a.steps,
            learning_rate=a.lr,
            smooth_width=a.smooth_width,
        )
        eig = np.linalg.eigvalsh(inv.hessian)
        vec = np.linalg.eigh(inv.hessian)[1][:, 0]
        fits.append((inv, vec))
        emit(
            {
                "case": "inversion",
                "start": start,
                "estimates": inv.estimates,
                "std_errors": inv.std_errors,
                "truth": TRUTH,
                "loss_m2": inv.loss,
                "loss_history": [round(v, 3) for v in inv.history],
                "hessian_log_params": np.asarray(inv.hessian).tolist(),
                "hessian_eigenvalues": eig.tolist(),
                "weak_direction_log_params": dict(zip(FIELDS, vec.tolist(), strict=True)),
                "condition_number": inv.condition_number,
                "wall_s": round(time.perf_counter() - t0, 1),
                "run": k,
            }
        )

    if not a.no_profile:  # misfit through the first optimum (forward runs only)
        inv, vec = fits[0]
        best = np.log([inv.estimates[f] for f in FIELDS])
        for label, direction in (
            ("softening", np.array([1.0, 0.0])),
            ("tensile_strength", np.array([0.0, 1.0])),
            ("weak_eigenvector", vec),
        ):
            prof = []
            for s in (-0.4, -0.2, -0.1, 0.0, 0.1, 0.2, 0.4):
                x = best + s * direction
                vals = {f: float(np.exp(x[i])) for i, f in enumerate(FIELDS)}
                prof.append({"step_log": s, **vals, "loss_m2": misfit(vals, obs, base, fns[1])})
            emit({"case": "profile", "direction": label, "points": prof})
    emit({"case": "total_wall_s", "value": round(time.perf_counter() - t_start, 1)})
    return 0


if __name__ == "__main__":
    jnp.zeros(1)  # initialise the backend before timing
    sys.exit(main(sys.argv[1:]))
