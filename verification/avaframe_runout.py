"""The runout chain: a release zone computed by damjax on a shipped DEM, run out by AvaFrame.

1. damjax runs the shipped DEM scenario ``slope-dem-gully`` (a 30 m x 20 m release area on
   a parabolic gully, LV95; ~1-2 min on 2 cores) into ``OUT/run``;
2. `damjax.export.avaframe.export_avaframe` writes the AvaFrame avalanche directory
   ``OUT/avaframe`` (DEM, release zones with their thickness) and
   `damjax.export.gis.export_gis` the GeoTIFFs and polygons into ``OUT/gis``;
3. AvaFrame's com1DFA (default configuration, samosATAuto friction, 5 m mesh) runs the
   release zones out, in AvaFrame's own Python environment (AvaFrame pins numpy < 2, jax
   needs numpy >= 2): ``DAMJAX_AVAFRAME_PYTHON=/path/to/avaframe-env/bin/python``, or the
   current interpreter if it imports avaframe;
4. a figure of the DEM, the release zone and the peak flow thickness, and one JSON line.

    DAMJAX_AVAFRAME_PYTHON=~/ava/bin/python python -m verification.avaframe_runout
    python -m verification.avaframe_runout --run-dir damjax-out/slope-dem-gully  # reuse a run
    python verification/avaframe_runout.py --com1dfa AVADIR   # step 3 only (AvaFrame's env)

Measured (2026-11-25, 2-core Xeon shared with other jobs, AvaFrame 2.1): damjax 51 s,
com1DFA 45 s, one zone of 385 m^2 (map), 0.49 m thick, runout 7600 m^2 reaching 268 m
below the release; the JSON line in ``results/avaframe_runout.jsonl``, the
figure ``docs/images/avaframe_runout.png`` and docs/guide/profiles-gis.md.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

SCENARIO = "slope-dem-gully"
FIGURE = Path(__file__).resolve().parents[1] / "docs" / "images" / "avaframe_runout.png"
RESULTS = Path(__file__).resolve().parents[1] / "results" / "avaframe_runout.jsonl"


def run_com1dfa(avadir: str) -> dict:
    """Run com1DFA (default configuration) on an avalanche directory; AvaFrame's env."""
    from avaframe.com1DFA import com1DFA
    from avaframe.in3Utils import cfgUtils, initializeProject, logUtils

    cfg_main = cfgUtils.getGeneralConfig()
    cfg_main["MAIN"]["avalancheDir"] = avadir
    cfg_main["MAIN"]["nCPU"] = "2"
    logUtils.initiateLogger(avadir, "damjax_com1DFA")
    initializeProject.cleanSingleAvaDir(avadir, deleteOutput=True)
    cfg = cfgUtils.getModuleConfig(com1DFA, avadir, toPrint=False)
    cfg["GENERAL"]["simTypeList"] = "null"  # no entrainment or resistance areas
    t0 = time.perf_counter()
    _, _, _, sim_df = com1DFA.com1DFAMain(cfg_main, cfgInfo=cfg)
    wall = time.perf_counter() - t0
    peak = sorted(str(p) for p in Path(avadir, "Outputs", "com1DFA", "peakFiles").glob("*"))
    return {"com1dfa_wall_s": wall, "peak_files": peak, "simulations": len(sim_df)}


def _avaframe_python() -> str:
    env = os.environ.get("DAMJAX_AVAFRAME_PYTHON")
    if env:
        return env
    try:
        import avaframe  # noqa: F401
    except ImportError:
        sys.exit(
            "AvaFrame is not importable here: install it in its own environment "
            "(pip install avaframe) and set DAMJAX_AVAFRAME_PYTHON to its python"
        )
    return sys.executable


def _read_asc(path: Path):
    import numpy as np

    from damjax import terrain

    t = terrain.load_esri_ascii(path)
    return t.x, t.y, np.asarray(t.z)


def plot(out: Path, zones, files: dict, peak_pft: Path | None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    xs, ys, z = _read_asc(Path(files["dem"]))
    fig, axes = plt.subplots(1, 2, figsize=(11, 6.5), gridspec_kw={"width_ratios": [1.1, 1]})
    x0, y0 = xs[0], ys[0]
    ax = axes[0]
    cs = ax.contour(xs - x0, ys - y0, z.T, levels=np.arange(1900, 2200, 10), colors="0.6",
                    linewidths=0.5)  # fmt: skip
    ax.clabel(cs, levels=cs.levels[::5], fontsize=6)
    if peak_pft is not None:
        px, py, pft = _read_asc(peak_pft)
        pft = np.where(pft > 0.0, pft, np.nan)
        im = ax.pcolormesh(px - x0, py - y0, pft.T, cmap="Blues", shading="nearest")
        fig.colorbar(im, ax=ax, label="AvaFrame com1DFA peak flow thickness [m]", shrink=0.7)
    for geom in zones.geometry:
        gx, gy = geom.exterior.xy
        ax.fill(np.asarray(gx) - x0, np.asarray(gy) - y0, color="tab:red", alpha=0.8, lw=0)
    ax.set_aspect("equal")
    ax.set_xlabel(f"easting - {x0:.0f} m (LV95)")
    ax.set_ylabel(f"northing - {y0:.0f} m (LV95)")
    ax.set_title("release zone (damjax, red) and runout (AvaFrame)")
    ax = axes[1]
    import rasterio

    with rasterio.open(files["arrival_time"]) as src:
        at = src.read(1)
        b = src.bounds
    im = ax.imshow(at, extent=(b.left - x0, b.right - x0, b.bottom - y0, b.top - y0),
                   cmap="viridis")  # fmt: skip
    fig.colorbar(im, ax=ax, label="weak-layer failure time [s]", shrink=0.7)
    for geom in zones.geometry:
        gx, gy = geom.exterior.xy
        ax.plot(np.asarray(gx) - x0, np.asarray(gy) - y0, color="tab:red", lw=1)
    ax.set_title("damjax crack arrival (GeoTIFF) and zone outline")
    ax.set_xlabel(f"easting - {x0:.0f} m")
    fig.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURE, dpi=110)
    fig.savefig(out / "avaframe_runout.png", dpi=110)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="damjax-out/avaframe-runout", help="output folder")
    ap.add_argument("--run-dir", default=None, help="reuse this damjax run folder")
    ap.add_argument("--com1dfa", metavar="AVADIR", default=None,
                    help="only run com1DFA on AVADIR (in AvaFrame's environment)")  # fmt: skip
    args = ap.parse_args(argv)
    if args.com1dfa:
        print(json.dumps(run_com1dfa(args.com1dfa)))
        return
    ava_python = _avaframe_python()
    from damjax import runner
    from damjax.export import avaframe, gis

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    run_dir = Path(args.run_dir) if args.run_dir else out / "run"
    if not args.run_dir:
        runner.run(SCENARIO, run_dir)
    damjax_wall = time.perf_counter() - t0
    files = gis.export_gis(run_dir, out / "gis")
    ava = avaframe.export_avaframe(run_dir, out / "avaframe")
    proc = subprocess.run(
        [ava_python, str(Path(__file__).resolve()), "--com1dfa", str(out / "avaframe")],
        capture_output=True,
        text=True,
    )
    if proc.returncode != 0:
        sys.exit(f"com1DFA failed:\n{proc.stderr[-3000:]}")
    com = json.loads(proc.stdout.strip().splitlines()[-1])
    pft = [p for p in com["peak_files"] if p.endswith("_pft.asc")]
    ppr = [p for p in com["peak_files"] if p.endswith("_ppr.asc")]
    zones = gis.release_zones(gis.open_run(run_dir), gis.frame_of(gis.open_run(run_dir)))
    plot(out, zones, {**files, "dem": ava["dem"]}, Path(pft[0]) if pft else None)
    import numpy as np

    row = {
        "benchmark": "avaframe_runout",
        "scenario": SCENARIO,
        "damjax_wall_s": round(damjax_wall, 1),
        "com1dfa_wall_s": round(com["com1dfa_wall_s"], 1),
        "zones": len(zones),
        "release_area_map_m2": round(float(zones["area_m2"].sum()), 2),
        "release_area_surface_m2": round(float(zones["surf_m2"].sum()), 2),
        "release_thickness_m": round(float(zones["thickness"].iloc[0]), 4),
    }
    if pft:
        px, py, p = _read_asc(Path(pft[0]))
        wet = p > 0.0
        yy = np.broadcast_to(py[None, :], p.shape)
        cell = float(px[1] - px[0]) * float(py[1] - py[0])
        ox, oy = zones.geometry.iloc[0].exterior.xy
        row.update(
            runout_area_m2=round(float(wet.sum()) * cell, 1),
            max_pft_m=round(float(p.max()), 3),
            release_lowest_northing_m=round(float(np.min(oy)), 1),
            runout_lowest_northing_m=round(float(yy[wet].min()), 1),
        )
    if ppr:
        row["max_ppr_kpa"] = round(float(np.max(_read_asc(Path(ppr[0]))[2])), 2)
    print(json.dumps(row))
    with open(RESULTS, "a", encoding="utf-8") as f:
        f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
