"""Slope runs the docs quote: the paper's Fig. 13b and the grid check of the shipped slopes.

- ``fig12b``: the shipped ``slope-generic-50x100`` as it is (dx 0.2 m, 4 s): its summary,
  the release's outline over time from the snapshots (``y_min_m``: the released weak layer
  nearest the y = 0 edge, anywhere on the map; ``x_min_m``, ``x_max_m``; ``area_m2``) and
  the local crack speeds (10 / 50 / 90 % of the cells) below, above and across from the
  start (docs/verification/slopes-fig12b.md);
- ``grid``: ``slope-generic-50x100`` over its first 2 s and ``slope-dem-gully`` as
  shipped (2 s), each at its dx (0.2 m) and at half of it on the same random field
  (``strength.field_dx`` = the shipped dx; docs/guide/slopes.md, "Grid resolution").

One JSON line per run, printed and appended to ``results/slope_runs.jsonl``; a run's
folder (results.nc, summary.json, slope.png) is kept under ``--out``; the ``fig12b``
run's slope.png also becomes the page's figure (docs/images/slope_fig12b.png).

    python -m verification.slope_runs                 # all: about 45 min on 2 shared cores
    python -m verification.slope_runs --only fig12b   # the 4 s run alone, about 8 min

Cost on the 2-core development machine shared with other work (2026-11-27): the 4 s run
of Fig. 13b 5.6 min of steps, its first 2 s at dx 0.1 m 11 min, the gully at dx 0.1 m
5.7 min.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "slope_runs.jsonl"
FIGURE = ROOT / "docs" / "images" / "slope_fig12b.png"  # the Fig. 13b page's plot
OUTLINE_TIMES = (0.5, 0.7, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0)  # [s]
SUMMARY_KEYS = (
    "upslope_front",
    "crossslope_front",
    "upslope_extent_m",
    "upslope_arrest_distance_m",
    "crossslope_extent_m",
    "crossslope_arrest_distance_m",
    "upslope_front_end_speed_over_cs",
    "crossslope_front_end_speed_over_cs",
    "upslope_crack_speed_over_cs",
    "crossslope_crack_speed_over_cs",
    "upslope_crack_speed_mean_over_cs",
    "crossslope_crack_speed_mean_over_cs",
    "release_area_m2",
    "crown_area_m2",
    "stauchwall_area_m2",
    "slab_fracture_area_m2",
    "critical_cut_radius_m",
    "start_m",
    "n_particles",
    "n_steps",
    "compile_time_s",
    "wall_time_s",
)


def outline(ds: Any, times: tuple[float, ...] = OUTLINE_TIMES) -> list[dict[str, float]]:
    """The released area's extent at the snapshots nearest ``times`` (those within the
    run): time [s], y_min, x_min, x_max [m] and area [m^2]."""
    t_snap = ds["snapshot_time"].values
    y, x = ds["y"].values, ds["x"].values
    dx = float(x[1] - x[0])
    out = []
    half = 0.5 * float(t_snap[-1] - t_snap[-2]) if len(t_snap) > 1 else 1e-6
    for t in times:
        if t > t_snap[-1] + half:  # past the run (its last snapshot may fall just short)
            break
        k = int(np.argmin(np.abs(t_snap - t)))
        rel = ds["released_snapshots"].values[k] > 0.5
        cols, rows = rel.any(axis=0), rel.any(axis=1)
        out.append(
            dict(
                t_s=round(float(t_snap[k]), 3),
                y_min_m=round(float(y[cols].min()), 2) if cols.any() else None,
                x_min_m=round(float(x[rows].min()), 2) if rows.any() else None,
                x_max_m=round(float(x[rows].max()), 2) if rows.any() else None,
                area_m2=round(float(rel.sum()) * dx * dx, 1),
            )
        )
    return out


def speed_percentiles(ds: Any, start: list[float], cs: float) -> dict[str, list[float]]:
    """10 / 50 / 90 % of the crack-speed map over c_s below the start (x < 30 m, within
    15 m across of it), above it (x from 2 m above it to 2 m below the top) and across
    (from 10 to 35 m across, x from 20 to 45 m): the regions of Fig. 13b."""
    v = ds["crack_speed"].values / cs
    x, y = ds["x"].values, ds["y"].values
    X, Y = np.meshgrid(x, y, indexing="ij")
    x0, y0 = start
    d = np.abs(Y - y0)
    regions = {
        "below": (X < 30.0) & (d < 15.0) & (Y < y[-1]),
        "above": (X > x0 + 2.0) & (X < x[-1] - 2.0) & (d < 15.0) & (Y < y[-1]),
        "across": (d > 10.0) & (d < 35.0) & (X > 20.0) & (X < 45.0),
    }
    out = {}
    for name, m in regions.items():
        vals = v[m & np.isfinite(v)]
        out[name] = [round(float(q), 3) for q in np.percentile(vals, [10, 50, 90])]
    return out


def run(
    name: str, scn: Any, out: Path, extra: dict[str, Any] | None = None, save: bool = True
) -> dict:
    """Run a scenario into ``out`` and make its row (appended to the results when ``save``)."""
    from benchmarks.cases import peak_rss_mb, stamp
    from damjax import io, runner

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the dx warning: this is its check
        outcome = runner.run(scn, out, progress=False)
    s = outcome.summary
    ds = io.open_dataset(out / "results.nc")
    row = dict(
        case="slope_runs",
        run=name,
        scenario=scn.name,
        dx=scn.setup.dx,
        duration_s=scn.setup.duration,
        field_dx=(scn.strength or {}).get("field_dx"),
        **{k: s.get(k) for k in SUMMARY_KEYS},
        outline=outline(ds) if "snapshot_time" in ds else None,
        simultaneous_failure_fraction=float(ds["simultaneous_failure"].values.mean()),
        **(extra or {}),
    )
    if name == "fig12b":
        row["crack_speed_over_cs_p10_p50_p90"] = speed_percentiles(
            ds, s["start_m"], s["shear_wave_speed_m_per_s"]
        )
    row["peak_rss_mb"] = round(peak_rss_mb(), 1)
    row.update(stamp())
    print(json.dumps(row), flush=True)
    if save:  # row by row: a stopped run keeps what it measured
        RESULTS.parent.mkdir(exist_ok=True)
        with open(RESULTS, "a", encoding="utf-8") as fh:
            fh.write(json.dumps(row) + "\n")
    if name == "fig12b" and save:  # the page shows this run's own plot
        shutil.copyfile(out / "slope.png", FIGURE)
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m verification.slope_runs", description=__doc__)
    ap.add_argument("--only", choices=("fig12b", "grid"), help="one part (default: both)")
    ap.add_argument("--out", default="runs/slope_runs", help="folder for the runs' outputs")
    ap.add_argument("--no-save", action="store_true", help=f"do not append to {RESULTS}")
    a = ap.parse_args(argv)
    from damjax import scenario

    out, save = Path(a.out), not a.no_save
    rows = []
    if a.only in (None, "fig12b"):
        rows.append(run("fig12b", scenario.load("slope-generic-50x100"), out / "fig12b", save=save))
    if a.only in (None, "grid"):
        for shipped, duration in (("slope-generic-50x100", 2.0), ("slope-dem-gully", 2.0)):
            base = scenario.load(shipped, warn=False)
            dx = base.setup.dx
            for k, this_dx in enumerate((dx, dx / 2)):
                scn = base.replace(
                    setup={"dx": this_dx, "duration": duration}, strength={"field_dx": dx}
                )
                name = f"grid_{shipped}_dx{this_dx:g}"
                extra = {"grid_of": shipped, "half_dx": k == 1}
                rows.append(run(name, scn, out / name, extra, save=save))
    return 0 if rows else 1


if __name__ == "__main__":
    sys.exit(main())
