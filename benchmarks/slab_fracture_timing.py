"""Per-step cost of the slab fracture models against the step without a particle lattice.

The "paper" slab built without its lattice moves exactly as before the fracture models
(the lattice only counts fractures; tests/test_slab_length_scale.py checks it bit for bit),
so its step is today's default step. The three models run 400 steps each, interleaved,
``--repeats`` times; the minimum per step is reported (robust on a shared machine), as a
ratio to that step. 100 m PST, dx 0.02 m, sigma_t 6 kPa, theta 150 Pa/m.

    python -m benchmarks.slab_fracture_timing --repeats 7

Measured 2026-11-25 on an idle 2-core machine at commit 1137f3f (results_slab_fracture/
step_timing.jsonl): paper 1.03 x, crack_band 1.85 x (0.288 / 0.515 / 0.279 ms per step): the
crack-band return map's coupled Newton iteration (4 steps with a window sum each) costs the
difference; 2 or 3 steps measured 1.66-1.94 x. Before it (commit 45944bb, explicit softening,
a load of 7-11): paper 1.01 / 1.02 x, crack_band 1.16 / 1.04 x; with reduce_window for the
band opening (before 45944bb) 1.19 / 1.72 x.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time

import jax
import numpy as np

from damjax import PSTParams, PSTSetup
from damjax.core.model import build, make_layout
from damjax.core.step import step

BASE = "paper without lattice"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--dx", type=float, default=0.02)
    a = ap.parse_args(argv)
    p = PSTParams(tensile_strength=6000.0, strength_gradient=150.0, steady_length=20.0)
    models = {}
    for mode in ("paper", "crack_band"):
        s = PSTSetup(length=100.0, dx=a.dx, duration=0.6, slab_fracture=mode)
        models[mode] = build(p, s, make_layout(p, s))
    m, st = models["paper"]
    bare = dataclasses.replace(m, lattice=(), lattice_spacing=0.0, opening_window=0)
    models[BASE] = (bare, st)
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
        row = {"model": k, "ms_per_step_min": round(v, 4), "ratio": round(v / best[BASE], 3)}
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
