"""Where a slope run's time goes on a small CPU host: why an ensemble of slope members
gains little over running them one after another (``ensemble16``).

    python -m benchmarks.slope_cores [--duration 2.0]

The Fig. 12a slope (50 m x 60 m, dx 0.2 m, one particle per cell as in ``ensemble16``,
seed 0) runs in fresh processes:

- ``slope_cores``: on every core of this process's affinity, and pinned to one core
  (``os.sched_setaffinity`` before JAX starts). ``speedup`` = one-core time / all-core
  time: how much of the host one run already uses. An ensemble can only beat sequential
  runs by the part a single run leaves idle, or by a smaller cost per member;
- ``slope_width``: the same slope 60, 15 and 4 m wide (75 000, 18 750 and 5 000
  particles) on all cores: the time per step against the particle count, whose intercept
  is the fixed cost per step that batching members would share.

One JSON line per run; timings exclude compilation.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys


def _one(width: float, duration: float, cores: int | None) -> dict:
    if cores is not None:
        os.sched_setaffinity(0, set(sorted(os.sched_getaffinity(0))[:cores]))
    from damjax.slope.generic import GenericSlopeCase, run_generic_slope

    case = GenericSlopeCase(width=width, duration=duration, particles_per_cell=1)
    s = run_generic_slope(case).summary
    return dict(
        width_m=width,
        cores=len(os.sched_getaffinity(0)),
        n_particles=s["n_particles"],
        n_steps=s["n_steps"],
        wall_time_s=round(s["wall_time_s"], 3),
        ms_per_step=round(1e3 * s["wall_time_s"] / s["n_steps"], 4),
        ns_per_particle_step=round(1e9 * s["wall_time_s"] / (s["n_steps"] * s["n_particles"]), 2),
    )


def _run(width: float, duration: float, cores: int | None) -> dict:
    code = (
        "import json, sys, warnings; warnings.simplefilter('ignore');"
        "from benchmarks.slope_cores import _one;"
        f"print(json.dumps(_one({width!r}, {duration!r}, {cores!r})))"
    )
    out = subprocess.run([sys.executable, "-c", code], stdout=subprocess.PIPE, check=True)
    return json.loads(out.stdout.decode().strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.slope_cores")
    p.add_argument("--duration", type=float, default=2.0)
    ns = p.parse_args(argv)
    every = _run(60.0, ns.duration, None)
    one = _run(60.0, ns.duration, 1)
    row = dict(case="slope_cores", all_cores=every, one_core=one)
    row["speedup"] = round(one["wall_time_s"] / every["wall_time_s"], 3)
    print(json.dumps(row), flush=True)
    rows = [every] + [_run(w, ns.duration, None) for w in (15.0, 4.0)]
    n = [r["n_particles"] for r in rows]
    t = [r["ms_per_step"] for r in rows]
    # least squares t = a + b n: a is the fixed cost of a step [ms]
    mn, mt = sum(n) / len(n), sum(t) / len(t)
    b = sum((x - mn) * (y - mt) for x, y in zip(n, t, strict=True)) / sum((x - mn) ** 2 for x in n)
    a = mt - b * mn
    print(
        json.dumps(
            dict(
                case="slope_width",
                runs=rows,
                fixed_ms_per_step=round(a, 4),
                ns_per_particle_step_marginal=round(1e6 * b, 2),
                fixed_share_at_75000=round(a / rows[0]["ms_per_step"], 3),
            )
        ),
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
