"""Per-step cost of the slab fracture models against the step without a particle lattice.

The "paper" slab built without its lattice moves exactly as before the fracture models
(the lattice only counts fractures; tests/test_slab_length_scale.py checks it bit for bit),
so its step is today's default step. The three models run 400 steps each, interleaved,
``--repeats`` times; the minimum per step is reported (robust on a shared machine), as a
ratio to that step. 100 m PST, dx 0.02 m, sigma_t 6 kPa, theta 150 Pa/m.

    python -m benchmarks.slab_fracture_timing --repeats 7

Measured 2026-11-25 on an idle 2-core machine on the code of commit 569ccad: per step (this loop,
the first 400 steps, all elastic; results/slab_fracture/step_timing.jsonl) paper 1.10 x,
crack_band 1.50 x (0.283 / 0.387 / 0.257 ms); whole 3 s runs (``--full 150 30 --repeats
3``, results/slab_fracture/full_run_timing.jsonl) crack_band 9.9 / 10.8 s, paper 9.8 /
10.9 s, without the lattice 10.3 / 12.6 s at theta 150 / 30. At commit 1137f3f, before the
Newton steps of settled bands were skipped and before softened_p0 lost its asinh, the
per-step ratio was 1.85 x (step_timing_1137f3f.jsonl), and a whole crack_band run at
theta 150 took 23.0 s at commit 3b19f82.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from benchmarks.cases import at_least, emit
from damjax import PSTParams, PSTSetup
from damjax.core.loop import integrate
from damjax.core.model import build, make_layout
from damjax.core.step import step
from damjax.pst import slab_fractures

BASE = "paper without lattice"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks slab_fracture_timing", description=__doc__.splitlines()[0]
    )
    ap.add_argument(
        "--repeats", type=at_least(int, 1), default=7, help="interleaved rounds (default 7)"
    )
    ap.add_argument(
        "--steps", type=at_least(int, 1), default=400, help="steps per timed loop (default 400)"
    )
    ap.add_argument(
        "--dx",
        type=at_least(float, 0.0, strict=True),
        default=0.02,
        help="grid spacing [m] (default 0.02; at most Lambda/2 = 0.33 m)",
    )
    ap.add_argument(
        "--full",
        type=float,
        nargs="*",
        metavar="THETA",
        help="time whole 3 s runs (the time loop, no compile) at these theta [Pa/m] instead",
    )
    ap.add_argument(
        "--seed", type=at_least(int, 0), default=0, help="crack-band strength field (--full)"
    )
    a = ap.parse_args(argv)
    if a.dx > 0.33:
        ap.error(f"--dx {a.dx}: must be at most Lambda/2 = 0.33 m (the weak layer's length)")
    if a.full is not None:
        for theta in a.full or [150.0, 30.0]:
            full_runs(theta, a.dx, a.seed, a.repeats)
        return
    p = PSTParams(tensile_strength=6000.0, strength_gradient=150.0, steady_length=20.0)
    models = _models(p, a.dx, 0.6, 0)
    n = a.steps

    def runner(model):
        return jax.jit(lambda s: jax.lax.fori_loop(0, n, lambda i, x: step(model, x), s))

    fns = {k: runner(m) for k, (m, _) in models.items()}
    states = {k: jax.block_until_ready(fns[k](s)) for k, (_, s) in models.items()}
    best = dict.fromkeys(models, np.inf)
    for _ in range(a.repeats):
        for k in models:
            t = time.perf_counter()
            jax.block_until_ready(fns[k](states[k]))
            best[k] = min(best[k], (time.perf_counter() - t) / n * 1e3)
    for k, v in best.items():
        emit(model=k, ms_per_step_min=round(v, 4), ratio=round(v / best[BASE], 3), dx=a.dx)


def _models(p: PSTParams, dx: float, duration: float, seed: int) -> dict:
    """The three models (and states) on one 100 m PST: paper, crack_band, and the paper
    slab without its lattice (the step before the fracture models, `BASE`)."""
    models = {}
    for mode in ("paper", "crack_band"):
        s = PSTSetup(length=100.0, dx=dx, duration=duration, slab_fracture=mode, seed=seed)
        models[mode] = build(p, s, make_layout(p, s))
    m, st = models["paper"]
    models[BASE] = (m.with_fields(lattice=(), lattice_spacing=0.0, opening_window=0), st)
    return models


def full_runs(theta: float, dx: float, seed: int, repeats: int) -> None:
    """Wall time of the whole time loop of a 3 s, 100 m PST per model (the fastest of
    ``repeats`` interleaved runs, compile excluded), with its arrest and fracture count:
    the cost a user sees, fractures and all (the crack-band Newton steps run only while
    a band softens)."""
    p = PSTParams(tensile_strength=6000.0, strength_gradient=theta, steady_length=20.0)
    s = PSTSetup(length=100.0, dx=dx, duration=3.0)
    layout = make_layout(p, s)
    models = _models(p, dx, 3.0, seed)
    best = dict.fromkeys(models, np.inf)
    rows = {}
    for _ in range(max(1, repeats)):
        for k, (m, st) in models.items():
            # a copy: the time loop donates (deletes) the state it starts from
            start = jax.tree.map(jnp.copy, st)
            final, _, _, info = integrate(m, start, layout.n_chunks, layout.chunk_steps)
            best[k] = min(best[k], info.wall_time_s)
            if k != BASE:
                frac = slab_fractures(m, final)
                rows[k] = {"tip_m": round(float(final.tip), 3), "fractures": len(frac)}
    for k, v in best.items():
        row = {
            "model": k,
            "theta": theta,
            "dx": dx,
            "seed": seed,
            "steps": layout.n_chunks * layout.chunk_steps,
        }
        row |= {"loop_s_min": round(v, 3), "ratio": round(v / best[BASE], 3), **rows.get(k, {})}
        emit(**row)


if __name__ == "__main__":
    main()
