"""Paper Fig. 13a's generic slope over 5 GRF seeds, and 2 controls.

The 50 m x 60 m generic slope (`damjax.slope.generic.FIG12A`) and the two controls
(the same slope without the up-slope trend; a planar 35 deg slope with the trend).

    python -m verification.slope_acceptance            # dx 0.2 m, 4 s, seeds 0-4
    python -m verification.slope_acceptance --ppc 2    # 2 x 2 particles per cell
    python -m verification.slope_acceptance --seeds 3 --dx 0.3

Prints one JSON line per run (keys of `benchmarks.cases.slope_row`, plus ``run``:
"seed", "no_trend" or "planar"), then one summary line with the spread of the up-slope
arrest over the seeds and the target checks. Distances are along the surface:
``upslope_arrest_distance_m`` from the start, ``upslope_arrest_position_m`` from the
lower edge. Crack speeds: the peak of 4 m sliding-window fits along a 2 m band through
the start (``*_crack_speed_over_cs``, the counterpart of a PST's maximum crack speed) and
the least-squares mean over the whole run (``*_mean_over_cs``, which averages the
acceleration after the saw and the deceleration before the arrest in). All runs share
one compiled step (same shapes), so only the first pays the compilation.

What it measured, the geometry and the earlier geometry it replaced: the page
docs/verification/slopes.md (rows in ``results/slope_acceptance*.jsonl``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import sys

import numpy as np

from benchmarks.cases import emit, slope_row
from damjax.slope.generic import GenericSlopeCase, fig12_params

# the case fields each row records (with its start window)
_CASE_KEYS = (
    "seed",
    "trend",
    "planar",
    "length",
    "width",
    "duration",
    "toe_slope_deg",
    "toe_length",
    "roll_length",
)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--seeds", type=int, default=5, help="number of GRF seeds (0, 1, ...)")
    ap.add_argument("--dx", type=float, default=0.2, help="grid spacing [m]")
    ap.add_argument("--duration", type=float, default=4.0, help="simulated time [s]")
    ap.add_argument("--ppc", type=int, default=1, help="particles per cell and dimension")
    ap.add_argument("--length", type=float, default=50.0, help="up-slope length [m]")
    ap.add_argument("--width", type=float, default=60.0, help="cross-slope width [m]")
    ap.add_argument(
        "--mean-at",
        type=float,
        default=None,
        help="where the 1 kPa plateau ends and the trend starts [m] (default: the start "
        "window's lower edge)",
    )
    ap.add_argument("--toe-length", type=float, default=10.0, help="concave toe length [m]")
    ap.add_argument("--roll-length", type=float, default=10.0, help="convex roll length [m]")
    ap.add_argument("--toe-slope", type=float, default=30.0, help="slope at the lower edge [deg]")
    ap.add_argument(
        "--start-window",
        type=float,
        nargs="+",
        default=[2.0, 8.0],
        metavar="M",
        help="X_MIN X_MAX (y: the middle half of the width) or X_MIN X_MAX Y_MIN Y_MAX [m]: "
        "the crack starts at the weakest spot in it",
    )
    ap.add_argument(
        "--field-dx",
        type=float,
        default=None,
        help="grid spacing the GRF is drawn on [m] (default: dx; fix it to compare grids)",
    )
    ap.add_argument(
        "--fracture-energy",
        type=float,
        default=math.inf,
        help="slab fracture energy G_f [J/m^2] (default inf: the paper's plastic slab)",
    )
    ap.add_argument("--no-controls", action="store_true", help="skip the two controls")
    ap.add_argument("--only", default="", help="comma-separated run names (seed0,...,planar)")
    a = ap.parse_args(argv)
    # flags checked before anything compiles: an argparse error (exit 2) names the flag
    for flag, value, ok, valid in (
        ("--seeds", a.seeds, a.seeds >= 1, "[1, inf)"),
        ("--ppc", a.ppc, 1 <= a.ppc <= 8, "[1, 8]"),
        ("--dx", a.dx, 0 < a.dx < math.inf, "(0, inf) m"),
        ("--duration", a.duration, 0 < a.duration < math.inf, "(0, inf) s"),
        ("--length", a.length, 0 < a.length < math.inf, "(0, inf) m"),
        ("--width", a.width, 0 < a.width < math.inf, "(0, inf) m"),
        ("--toe-slope", a.toe_slope, 0 < a.toe_slope < 90, "(0, 90) deg"),
        ("--fracture-energy", a.fracture_energy, a.fracture_energy > 0, "(0, inf] J/m^2"),
    ):
        if not ok:  # also false for nan
            ap.error(f"{flag} = {value}: must be in {valid}")
    try:
        base = GenericSlopeCase(
            dx=a.dx,
            duration=a.duration,
            particles_per_cell=a.ppc,
            length=a.length,
            width=a.width,
            mean_at=a.mean_at,
            field_dx=a.field_dx,
            toe_length=a.toe_length,
            roll_length=a.roll_length,
            toe_slope_deg=a.toe_slope,
            start_window=tuple(a.start_window),
        )
    except ValueError as exc:
        flags = {
            "toe_length": "--toe-length",
            "roll_length": "--roll-length",
            "start_window": "--start-window",
            "length": "--length",
        }
        msg = str(exc).removeprefix("GenericSlopeCase: ")
        for key, flag in flags.items():  # whole names only: "length" is in "toe_length"
            msg = re.sub(rf"(?<![\w-]){key} = ", f"{flag} = ", msg)
        ap.error(msg)
    runs = [(f"seed{k}", dataclasses.replace(base, seed=k)) for k in range(a.seeds)]
    if not a.no_controls:
        runs += [
            ("no_trend", dataclasses.replace(base, trend=0.0)),
            ("planar", dataclasses.replace(base, planar=True)),
        ]
    if a.only:
        keep = set(a.only.split(","))
        runs = [(n, c) for n, c in runs if n in keep]
    params = fig12_params(slab_fracture_energy=a.fracture_energy)
    rows = []
    for name, case in runs:
        row = dict(
            slope_row("slope_acceptance", case, params),
            # JSON has no infinity: null is the perfectly plastic slab
            slab_fracture_energy=a.fracture_energy if math.isfinite(a.fracture_energy) else None,
            run=name,
            **{k: getattr(case, k) for k in _CASE_KEYS},
            start_window=list(case.start_window),
        )
        emit(**row)
        rows.append(row)
    seeds = [r for r in rows if r["run"].startswith("seed")]
    if not seeds:
        return 0
    # the distance reached (the arrest distance where the front arrested, which
    # ok_arrest asks for; None in the summary otherwise)
    up = np.array([r["upslope_extent_m"] for r in seeds])
    pos = np.array([r["start_m"][0] + r["upslope_extent_m"] for r in seeds])
    cross = [r["crossslope_crack_speed_over_cs"] for r in seeds]
    upv = [r["upslope_crack_speed_over_cs"] for r in seeds]
    ok_arrest = [
        bool(r["arrested_before_top"] and 40.0 <= r["upslope_arrest_distance_m"] <= 50.0)
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
