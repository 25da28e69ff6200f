"""Issue 5 acceptance: the 50 m x 60 m generic slope (paper Fig. 12a) over 5 GRF seeds,
and the two controls (the same slope without the up-slope trend; a planar 35 deg slope
with the trend).

    python -m benchmarks.slope_acceptance            # dx 0.2 m, 2 s, seeds 0-4
    python -m benchmarks.slope_acceptance --ppc 2    # 2 x 2 particles per cell
    python -m benchmarks.slope_acceptance --seeds 3 --dx 0.3

Prints one JSON line per run (keys of `benchmarks.cases.slope_row`, plus ``run``:
"seed", "no_trend" or "planar"), then one summary line with the spread of the up-slope
arrest over the seeds and the target checks. Distances are along the surface:
``upslope_arrest_distance_m`` from the start, ``upslope_arrest_position_m`` from the
lower edge (the reading of the paper's "stopped between 40-50 m"). All runs share one
compiled step (same shapes), so only the first pays the compilation.

Measured (commit 9bb6f15 + MCC '3d' invariants of a618928; dx 0.2 m, 1 particle per cell,
75 000 particles, 2800 steps, float32; 2 CPU cores at load average ~7 from other jobs;
rows in `slope_acceptance_results.jsonl`):

| run | from start | position | up/c_s | cross/c_s | area m^2 | crown m^2 | wall s |
|---|---|---|---|---|---|---|---|
| seed 0 | 29.2 | 41.3 | 0.82 | 0.74 | 2110 | 56 | 150 (+11 compile) |
| seed 1 | 21.2 | 33.3 | 0.68 | 0.63 | 818 | 0 | 144 |
| seed 2 | 29.6 | 41.7 | 0.76 | 0.73 | 1285 | 0 | 139 |
| seed 3 | 29.8 | 41.9 | 0.80 | 0.74 | 2076 | 65 | 130 |
| seed 4 | 27.0 | 39.1 | 0.68 | 0.53 | 1999 | 93 | 109 |
| no trend | 32.0 | 49.9 (top) | 1.43 | 0.86 | 2709 | 131 | 72 |
| planar | 37.8 | 49.9 (top) | 0.59 | 0.82 | 2926 | 289 | 75 |

All five seeds stay below the top edge and both controls run to it (the trend and the
roll together stop the crack, neither alone), the up-slope extent ends at 39-42 m from
the lower edge in 4 of 5 seeds (the start of the roll: psi falls below 30 deg at 41 m),
i.e. the paper's "between 40-50 m" read as a position; but 21-30 m from the start
(mean 27.4, std 3.3 m), so the issue's "40-50 m from the start" is met by 0 of 5 (on this
50 m slope the start cannot lie below x = 9.3 m, where psi < phi). The front was still
moving somewhere at 2.0 s in every run (``front_quiet_at_end`` false), partly because the
disc-shaped saw needs 5.6-10.6 m (0.9-1.8 s at 6 m/s) before the crack leads it: 2 s
does not establish an arrest. Cross-slope speeds 0.53-0.74 c_s are below the up-slope
speeds in all seeds but below the 0.8-1.2 c_s target. Wall time < 3 min per run on 2
busy cores (1 particle per cell; 2 x 2 per cell took 343 s).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys

import numpy as np

from benchmarks.cases import emit, slope_row
from damjax.scenarios.generic_slope import GenericSlopeCase


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5, help="number of GRF seeds (0, 1, ...)")
    ap.add_argument("--dx", type=float, default=0.2, help="grid spacing [m]")
    ap.add_argument("--duration", type=float, default=2.0, help="simulated time [s]")
    ap.add_argument("--ppc", type=int, default=1, help="particles per cell and dimension")
    ap.add_argument("--width", type=float, default=60.0, help="cross-slope width [m]")
    ap.add_argument("--no-controls", action="store_true", help="skip the two controls")
    ap.add_argument("--only", default="", help="comma-separated run names (seed0,...,planar)")
    a = ap.parse_args(argv)
    base = GenericSlopeCase(dx=a.dx, duration=a.duration, particles_per_cell=a.ppc, width=a.width)
    runs = [(f"seed{k}", dataclasses.replace(base, seed=k)) for k in range(a.seeds)]
    if not a.no_controls:
        runs += [
            ("no_trend", dataclasses.replace(base, trend=0.0)),
            ("planar", dataclasses.replace(base, planar=True)),
        ]
    if a.only:
        keep = set(a.only.split(","))
        runs = [(n, c) for n, c in runs if n in keep]
    rows = []
    for name, case in runs:
        row = dict(
            slope_row("slope_acceptance", case),
            run=name,
            seed=case.seed,
            trend=case.trend,
            planar=case.planar,
        )
        emit(**row)
        rows.append(row)
    seeds = [r for r in rows if r["run"].startswith("seed")]
    if not seeds:
        return 0
    up = np.array([r["upslope_arrest_distance_m"] for r in seeds])
    pos = np.array([r["upslope_arrest_position_m"] for r in seeds])
    cross = [r["crossslope_crack_speed_over_cs"] for r in seeds]
    upv = [r["upslope_crack_speed_over_cs"] for r in seeds]
    ok_arrest = [
        bool(40.0 <= r["upslope_arrest_distance_m"] <= 50.0 and r["arrested_before_top"])
        for r in seeds
    ]
    ok_speed = [
        c is not None and u is not None and 0.8 <= c <= 1.2 and c < u
        for c, u in zip(cross, upv, strict=True)
    ]
    print(
        json.dumps(
            dict(
                case="slope_acceptance_summary",
                n_seeds=len(seeds),
                upslope_arrest_distance_m_mean=float(up.mean()),
                upslope_arrest_distance_m_std=float(up.std()),
                upslope_arrest_distance_m_range=[float(up.min()), float(up.max())],
                upslope_arrest_position_m_range=[float(pos.min()), float(pos.max())],
                arrested_before_top=[r["arrested_before_top"] for r in seeds],
                target_arrest_40_50_m_before_top=sum(ok_arrest),
                target_crossslope_0p8_1p2_below_upslope=sum(ok_speed),
                max_wall_time_s=max(r["wall_time_s"] for r in rows),
            )
        ),
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
