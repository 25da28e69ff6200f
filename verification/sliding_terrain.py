"""What can bound a release on the shipped avalanche paths: the slidable snow of the terrain.

For each shipped real-path scenario (``real-path-avaalr``, ``real-path-avakot``) and each
buffer around its release polygon (``--buffers``, metres of terrain, clipped to the DEM;
a buffer larger than the DEM is the whole DEM), with the scenario's snow cover (no slab
steeper than 60 deg) and its weak layer's residual friction angle:

- the snow-covered area in the domain, and the share of it at or below the friction
  angle (where a released slab does not slide, so a crack stops if nothing else does);
- `damjax.slope.simulation.sliding_region`: the snow steeper than the friction angle that
  the scenario's start connects to, the terrain a crack from the trigger releases if
  only the terrain stops it, and its `domain_edge_fraction`: the share of its boundary on
  the domain's edge.

A release bounded by the terrain needs that share small (the real-path acceptance line
is 5 %); it is a property of the DEM, the snow limit and the friction angle, measured
without a run. One JSON line per (path, buffer), printed and appended to
``results/sliding_terrain.jsonl``.

    python -m verification.sliding_terrain           # 150, 300, 600 m, the whole DEM (10 km)
    python -m verification.sliding_terrain --path avaAlr --buffers 150 1000
    python -m verification.sliding_terrain --max-slope 55   # SLF's upper cut
    python -m verification.sliding_terrain --path avaAlr --field-dx 2 \
        --dem AVAFRAME/avaframe/data/avaAlr/Inputs/avaAlr.tif  # AvaFrame's whole DEM
    python -m verification.sliding_terrain --path avaKot \
        --mask AVAFRAME/avaframe/data/avaKot/Inputs/RES/resistance.shp  # its forest

Cost (2026-11-27, 2-core CPU): seconds per buffer, a minute for a whole DEM (AvaFrame's
avaAlr DEM: 81 s, 10 GB peak memory).
"""

from __future__ import annotations

import argparse
import json
import time
import tomllib
import warnings
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "sliding_terrain.jsonl"
PATHS = ("avaAlr", "avaKot")
WHOLE_DEM = 10000.0  # [m] a buffer beyond every DEM of these paths (AvaFrame's: at most 4.6 km)


def with_buffer(
    name: str,
    buffer: float,
    dem: str | None = None,
    field_dx: float | None = None,
    max_slope: float | None = None,
    mask: str | None = None,
) -> Any:
    """The shipped scenario ``name`` with ``terrain.buffer`` [m] (its domain made anew)
    and, given, another DEM file of the same CRS (``dem``: e.g. AvaFrame's whole DEM of
    the path, of which the shipped one is a crop); ``field_dx`` [m]: the grid of the
    stability field, which here only places the trigger (None: the scenario's, the run's
    grid; a coarser one where a large domain's field would not fit); ``max_slope`` [deg]:
    the snow cover's upper slope limit (None: the scenario's 60 deg); ``mask``: a
    ``snow.mask`` file (a raster or polygons of forest or rock; None: none)."""
    from damjax import scenario as scenarios

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        doc = tomllib.loads(scenarios.load(name).to_toml())
        doc["terrain"]["buffer"] = float(buffer)
        # nothing runs: a short duration keeps a whole DEM's layout within the memory
        # check (the maps, the domain and the trigger do not depend on it)
        doc["setup"]["duration"] = 0.01
        if dem is not None:
            doc["terrain"]["file"] = str(Path(dem).resolve())
        if field_dx is not None:
            doc["strength"]["field_dx"] = float(field_dx)
        if max_slope is not None:
            doc["snow"]["max_slope_deg"] = float(max_slope)
        if mask is not None:
            doc["snow"]["mask"] = str(Path(mask).resolve())
        # set by the polygon and its buffer: made anew
        doc["terrain"].pop("origin", None)
        for key in ("length", "width", "start"):
            doc["setup"].pop(key, None)
        return scenarios.parse(doc, base_dir=scenarios.shipped()[name].parent)


def measure(
    path: str,
    buffer: float,
    dem: str | None = None,
    field_dx: float | None = None,
    max_slope: float | None = None,
    mask: str | None = None,
) -> dict[str, Any]:
    """One row: the domain's snow, its share below the friction angle, and the start's
    sliding region with its share of boundary on the domain's edge."""
    from damjax import scenario as scenarios
    from damjax.slope.simulation import domain_edge_fraction, sliding_region

    t0 = time.perf_counter()
    scn = with_buffer(f"real-path-{path.lower()}", buffer, dem, field_dx, max_slope, mask)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prep = scenarios.prepared(scn)
    dx = float(prep.setup.dx)
    slope = np.asarray(prep.slope_deg, float)
    dom = np.ones(slope.shape, bool) if prep.domain is None else np.asarray(prep.domain, bool)
    snow = dom if prep.cover is None else dom & np.asarray(prep.cover, bool)
    phi = float(prep.params.friction_deg)
    region = sliding_region(slope, phi, prep.setup.start, dx, snow, dom)
    cell = dx * dx
    gentle = float((snow & (slope <= phi)).sum() / snow.sum())
    return {
        "benchmark": "sliding_terrain",
        "path": path,
        "buffer_m": buffer,
        "whole_dem": buffer >= WHOLE_DEM,
        "dem": "shipped" if dem is None else Path(dem).name,
        "field_dx_m": field_dx,
        "start_m": [round(float(c), 2) for c in prep.setup.start],
        "friction_deg": phi,
        "max_slope_deg": float(scn.snow.get("max_slope_deg", 60.0)),
        "mask": None if mask is None else Path(mask).name,
        "domain_m": [round(float(prep.setup.length), 1), round(float(prep.setup.width), 1)],
        "snow_m2": round(float(snow.sum()) * cell),
        "snow_at_or_below_friction_share": round(gentle, 4),
        "sliding_region_m2": round(float(region.sum()) * cell),
        "sliding_region_particles": int(region.sum()),
        "sliding_region_edge_fraction": round(float(domain_edge_fraction(region, dom)), 4),
        # the scenario's own pre-run warning (`damjax.slope.simulation.sliding_region`)
        "warns_before_run": any("not the terrain" in n.text() for n in prep.notes),
        "wall_s": round(time.perf_counter() - t0, 1),
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--path", choices=(*PATHS, "all"), default="all", help="the shipped path (default: all)"
    )
    ap.add_argument(
        "--buffers",
        type=float,
        nargs="+",
        default=[150.0, 300.0, 600.0, WHOLE_DEM],
        help=f"buffers around the polygon [m] ({WHOLE_DEM:g}: the whole DEM)",
    )
    ap.add_argument(
        "--dem",
        default=None,
        help="another DEM file of the path's CRS instead of the shipped crop (e.g. "
        "AvaFrame's avaframe/data/avaAlr/Inputs/avaAlr.tif; one --path)",
    )
    ap.add_argument(
        "--field-dx",
        type=float,
        default=None,
        help="grid of the stability field [m], which places the trigger (default: the "
        "scenario's; a coarser one where a whole DEM's field would not fit)",
    )
    ap.add_argument(
        "--max-slope",
        type=float,
        default=None,
        help="no snow steeper than this [deg] (default: the scenario's 60; SLF's "
        "release-area method cuts at 55)",
    )
    ap.add_argument(
        "--mask",
        default=None,
        help="no snow under this mask (snow.mask: a raster or polygons in the DEM's CRS, "
        "e.g. AvaFrame's forest of avaKot, avaframe/data/avaKot/Inputs/RES/resistance.shp)",
    )
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args(argv)
    from benchmarks.cases import git_commit

    commit, date = git_commit(), time.strftime("%Y-%m-%d")
    if args.dem is not None and args.path == "all":
        raise SystemExit("--dem needs one --path")
    if args.dem is not None and not Path(args.dem).is_file():
        raise SystemExit(f"--dem {args.dem}: no such file")
    if not all(b > 0 for b in args.buffers):
        raise SystemExit(f"--buffers {' '.join(map(str, args.buffers))}: each must be > 0 m")
    if args.field_dx is not None and not args.field_dx > 0:
        raise SystemExit(f"--field-dx {args.field_dx}: must be > 0 m")
    if args.mask is not None and not Path(args.mask).is_file():
        raise SystemExit(f"--mask {args.mask}: no such file")
    if args.max_slope is not None and not 0 < args.max_slope <= 90:
        raise SystemExit(f"--max-slope {args.max_slope}: must be in (0, 90] deg")
    for path in PATHS if args.path == "all" else (args.path,):
        for buffer in args.buffers:
            row = measure(path, buffer, args.dem, args.field_dx, args.max_slope, args.mask)
            row.update(date=date, commit=commit)
            print(json.dumps(row), flush=True)
            if not args.no_write:
                with open(RESULTS, "a", encoding="utf-8") as f:
                    f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
