"""Make the shipped avalanche-path data (damjax/data/paths/avaAlr, avaKot) from AvaFrame.

From a checkout of AvaFrame (EUPL-1.2) at a given commit: the DEM of each path, cropped to
the extent of the path's thalweg (``Inputs/LINES/path_aimec.shp``) and of the runout of
AvaFrame's own com1DFA reference (``benchmarks/ava*NullTest``, peak flow thickness > 0),
plus a 150 m margin, stored as a float32 GeoTIFF (deflate) in the DEM's CRS; the release
polygon (``Inputs/REL``), the thalweg and the reference peak flow thickness (same crop).

    python verification/real_path_data.py AVAFRAME_CHECKOUT [--commit SHA]
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "damjax" / "data" / "paths"
PATHS = {
    "avaAlr": {
        "dem": "avaframe/data/avaAlr/Inputs/avaAlr.tif",
        "rel": "avaframe/data/avaAlr/Inputs/REL/relAlr",
        "line": "avaframe/data/avaAlr/Inputs/LINES/path_aimec",
        "pft": "benchmarks/avaAlrNullTest/relAlr_c544043f9e_C_M_null_dfa_pft.tif",
        "desc": "benchmarks/avaAlrNullTest/avaAlrNullTest_desDict.json",
    },
    "avaKot": {
        "dem": "avaframe/data/avaKot/Inputs/avaKot.asc",
        "rel": "avaframe/data/avaKot/Inputs/REL/relKot",
        "line": "avaframe/data/avaKot/Inputs/LINES/path_aimec",
        "pft": "benchmarks/avaKotNullTest/relKot_989874a9be_C_S_null_dfa_pft.asc",
        "desc": "benchmarks/avaKotNullTest/avaKotNullTest_desDict.json",
    },
}
MARGIN = 150.0  # [m] around the thalweg and the reference runout


def _read(path: Path, crs_from: Path | None = None):
    import rasterio

    with rasterio.open(path) as src:
        a = src.read(1).astype(np.float64)
        if src.nodata is not None and np.isfinite(src.nodata):
            a[a == src.nodata] = np.nan
        return a, src.transform, src.crs


def _write(path: Path, a: np.ndarray, transform, crs) -> None:
    import rasterio

    with rasterio.open(
        path, "w", driver="GTiff", height=a.shape[0], width=a.shape[1], count=1,
        dtype="float32", crs=crs, transform=transform, nodata=-9999.0,
        compress="deflate", predictor=3,
    ) as dst:  # fmt: skip
        dst.write(np.where(np.isfinite(a), a, -9999.0).astype(np.float32), 1)


def make(src: Path, name: str, commit: str) -> dict:
    import geopandas as gpd
    from rasterio.transform import from_origin
    from rasterio.windows import Window, from_bounds

    spec = PATHS[name]
    out = OUT / name
    out.mkdir(parents=True, exist_ok=True)
    rel = gpd.read_file(src / (spec["rel"] + ".shp"))
    line = gpd.read_file(src / (spec["line"] + ".shp"))
    dem, t_dem, crs = _read(src / spec["dem"])
    pft, t_pft, _ = _read(src / spec["pft"])
    if crs is None:
        import pyproj

        crs = pyproj.CRS.from_wkt((src / (spec["rel"] + ".prj")).read_text())
    # extent: thalweg, release and reference runout (pft > 0), plus the margin
    rows, cols = np.nonzero(np.nan_to_num(pft) > 0.0)
    xs = t_pft.c + (cols + 0.5) * t_pft.a
    ys = t_pft.f + (rows + 0.5) * t_pft.e
    b = np.array([*line.total_bounds[:2], *line.total_bounds[2:]])
    rb = rel.total_bounds
    x0 = min(b[0], rb[0], xs.min()) - MARGIN
    y0 = min(b[1], rb[1], ys.min()) - MARGIN
    x1 = max(b[2], rb[2], xs.max()) + MARGIN
    y1 = max(b[3], rb[3], ys.max()) + MARGIN
    files = {}
    for key, a, t in (("dem", dem, t_dem), ("pft", pft, t_pft)):
        w = from_bounds(x0, y0, x1, y1, t).round_offsets().round_lengths()
        r0, c0 = max(int(w.row_off), 0), max(int(w.col_off), 0)
        r1 = min(int(w.row_off + w.height), a.shape[0])
        c1 = min(int(w.col_off + w.width), a.shape[1])
        win = Window(c0, r0, c1 - c0, r1 - r0)
        sub = a[r0:r1, c0:c1]
        tt = from_origin(t.c + c0 * t.a, t.f + r0 * t.e, t.a, -t.e)
        fname = "dem.tif" if key == "dem" else "reference_pft.tif"
        _write(out / fname, sub, tt, crs)
        files[key] = {"file": fname, "shape": list(sub.shape), "window": str(win)}
    for stem, dst in ((spec["rel"], "release"), (spec["line"], "thalweg")):
        for ext in (".shp", ".shx", ".dbf", ".prj", ".cpg"):
            p = src / (stem + ext)
            if p.exists():
                shutil.copyfile(p, out / (dst + ext))
    shutil.copyfile(src / spec["desc"], out / "reference_desDict.json")
    meta = {
        "path": name,
        "source": "https://github.com/avaframe/AvaFrame",
        "commit": commit,
        "licence": "EUPL-1.2",
        "from": {k: spec[k] for k in ("dem", "rel", "line", "pft", "desc")},
        "crop_bounds_m": [round(v, 3) for v in (x0, y0, x1, y1)],
        "crs": crs.to_string() if hasattr(crs, "to_string") else str(crs),
        "files": files,
    }
    (out / "source.json").write_text(json.dumps(meta, indent=1) + "\n")
    return meta


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("avaframe", help="an AvaFrame checkout (a work tree)")
    ap.add_argument("--commit", default="unknown", help="its commit")
    args = ap.parse_args(argv)
    src = Path(args.avaframe)
    shutil.copyfile(src / "LICENSE.txt", OUT / "LICENSE-EUPL-1.2.txt")
    for name in PATHS:
        print(json.dumps(make(src, name, args.commit)))


if __name__ == "__main__":
    main()
