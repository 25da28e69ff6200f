"""A documented avalanche path end to end: damjax's release on AvaFrame's avaAlr / avaKot.

For each path (``damjax/data/paths``, from AvaFrame, EUPL-1.2):

1. damjax runs the shipped scenario ``real-path-ava<path>`` (the terrain within 150 m of
   the documented release polygon on its DEM, no slab above 60 deg, slab thickness from
   the polygon, a stability-ratio weak layer, dx 0.46 m, the coarsest the model accepts)
   as an ensemble of ``--members`` seeds (``--members 1``: a single run, seed 0);
2. the release (cells released in >= half the members) against the documented polygon:
   area ratio, overlap (intersection over union), recall / precision, crown position
   relative to the polygon's upper edge along the surface;
3. that release, exported to an AvaFrame avalanche directory (`damjax.export.avaframe`,
   thickness the polygon's), runs out in com1DFA (AvaFrame's environment,
   ``DAMJAX_AVAFRAME_PYTHON``; null simulation, the reference's friction model), and the
   documented polygon runs out the same way (a re-run of the reference on the cropped DEM);
4. the runouts against AvaFrame's reference peak flow thickness of the documented release:
   runout length along the thalweg (``path_aimec``, from its upper end) and overlap of the
   areas with peak flow thickness > 1 cm;
5. a figure per path (``docs/images/real_path_<path>.png``) and one JSON line per path
   (printed, appended to ``results/real_path.jsonl``).

    python -m verification.real_path                      # both paths, 16 members
    python -m verification.real_path --path avaKot --members 1
    python -m verification.real_path --path avaKot --run-dir DIR  # reuse a run / ensemble
    python verification/real_path.py --com1dfa AVADIR --frict samosATSmall  # AvaFrame's env

Cost on a 2-core CPU (2026-11-27): one avaAlr member (1.31e6 particles, 4 s, 2800 steps)
took 25 min with other jobs beside it and 8.2 min on a quiet one (`python -m benchmarks
real_path_member`); avaKot's 16
members (1.0e6 particles, 3 s, 2000 steps each) took 97 min, one at a time
(docs/guide/real-path.md has what was run).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "damjax" / "data" / "paths"
IMAGES = ROOT / "docs" / "images"
RESULTS = ROOT / "results" / "real_path.jsonl"
PATHS = ("avaAlr", "avaKot")
PFT_MIN = 0.01  # [m] runout footprint: peak flow thickness above 1 cm


def scenario_name(path: str) -> str:
    """The shipped scenario of a path ("avaAlr" -> "real-path-avaalr")."""
    return f"real-path-{path.lower()}"


def reference_friction(path: str) -> str:
    """The com1DFA friction model of AvaFrame's reference run of a path."""
    desc = json.loads((DATA / path / "reference_desDict.json").read_text())
    return desc["Simulation Parameters"]["Friction model"]


# ------------------------------------------------------------------ AvaFrame's side


def run_com1dfa(avadir: str, frict: str | None = None) -> dict:
    """Run com1DFA (null simulation, default configuration but the friction model) on an
    avalanche directory; AvaFrame's environment."""
    from avaframe.com1DFA import com1DFA
    from avaframe.in3Utils import cfgUtils, initializeProject, logUtils

    cfg_main = cfgUtils.getGeneralConfig()
    cfg_main["MAIN"]["avalancheDir"] = avadir
    cfg_main["MAIN"]["nCPU"] = "1"
    logUtils.initiateLogger(avadir, "damjax_com1DFA")
    initializeProject.cleanSingleAvaDir(avadir, deleteOutput=True)
    cfg = cfgUtils.getModuleConfig(com1DFA, avadir, toPrint=False)
    cfg["GENERAL"]["simTypeList"] = "null"
    if frict:
        cfg["GENERAL"]["frictModel"] = frict
    t0 = time.perf_counter()
    _, _, _, sim_df = com1DFA.com1DFAMain(cfg_main, cfgInfo=cfg)
    wall = time.perf_counter() - t0
    peak = sorted(str(p) for p in Path(avadir, "Outputs", "com1DFA", "peakFiles").glob("*"))
    return {"com1dfa_wall_s": wall, "peak_files": peak, "simulations": len(sim_df)}


def com1dfa(avadir: Path, frict: str, python: str) -> dict:
    """`run_com1dfa` in AvaFrame's environment (a subprocess of ``python``)."""
    # a Jupyter kernel sets MPLBACKEND to its inline backend, which AvaFrame's matplotlib
    # (another environment, without matplotlib_inline) refuses at import: plain Agg there
    proc = subprocess.run(
        [python, str(Path(__file__).resolve()), "--com1dfa", str(avadir), "--frict", frict],
        capture_output=True,
        text=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    if proc.returncode != 0:
        raise RuntimeError(f"com1DFA failed on {avadir}:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def documented_avadir(path: str, avadir: Path) -> Path:
    """An AvaFrame avalanche directory of the documented release on the cropped DEM."""
    import shutil

    from damjax import terrain
    from damjax.export.avaframe import INPUT_FOLDERS

    inputs = avadir / "Inputs"
    for sub in INPUT_FOLDERS:
        (inputs / sub).mkdir(parents=True, exist_ok=True)
    terrain.save_esri_ascii(terrain.load_dem(DATA / path / "dem.tif"), inputs / "dem.asc")
    shutil.copyfile(DATA / path / "release.prj", inputs / "dem.prj")
    for ext in (".shp", ".shx", ".dbf", ".prj", ".cpg"):
        src = DATA / path / f"release{ext}"
        if src.exists():
            shutil.copyfile(src, inputs / "REL" / f"documented{ext}")
    return avadir


# ------------------------------------------------------------------ comparisons


def _raster(file: str | Path) -> tuple[np.ndarray, Any]:
    import rasterio

    with rasterio.open(file) as src:
        a = src.read(1).astype(float)
        if src.nodata is not None:
            a[a == src.nodata] = np.nan
        return np.nan_to_num(a), src.transform


def _sample(a: np.ndarray, tr: Any, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Nearest-cell values of raster a (transform tr) at map points X, Y (0 outside)."""
    inv = ~tr
    col, row = inv * (X, Y)
    col, row = np.floor(col).astype(int), np.floor(row).astype(int)
    ok = (row >= 0) & (row < a.shape[0]) & (col >= 0) & (col < a.shape[1])
    out = np.zeros(X.shape)
    out[ok] = a[row[ok], col[ok]]
    return out


def thalweg(path: str) -> Any:
    """AvaFrame's ``path_aimec`` line, oriented from its upper end (shapely LineString)."""
    import geopandas as gpd
    import shapely

    from damjax import terrain

    line = gpd.read_file(DATA / path / "thalweg.shp").geometry.iloc[0]
    dem = terrain.load_dem(DATA / path / "dem.tif")
    (x0, y0), (x1, y1) = line.coords[0], line.coords[-1]
    if dem.sample(x0, y0) < dem.sample(x1, y1):
        line = shapely.LineString(list(line.coords)[::-1])
    return line


def runout_metrics(path: str, pft_file: str | Path, ref_file: str | Path) -> dict[str, float]:
    """A runout's peak flow thickness against a reference one: footprints (> 1 cm) on the
    reference's grid, their overlap, and runout lengths along the thalweg (the largest
    distance from its upper end of a footprint cell, projected on it) [m]."""
    import shapely

    ref, tr = _raster(ref_file)
    pft, tr_p = _raster(pft_file)
    rows, cols = np.indices(ref.shape)
    X, Y = tr * (cols + 0.5, rows + 0.5)
    X, Y = np.asarray(X), np.asarray(Y)
    a = _sample(pft, tr_p, X, Y) > PFT_MIN
    b = ref > PFT_MIN
    cell = abs(tr.a * tr.e)
    line = thalweg(path)

    def reach(mask: np.ndarray) -> float:
        if not mask.any():
            return float("nan")
        return float(np.max(shapely.line_locate_point(line, shapely.points(X[mask], Y[mask]))))

    inter, union = float(np.sum(a & b)), float(np.sum(a | b))
    ra, rb = reach(a), reach(b)
    return {
        "runout_area_m2": float(a.sum()) * cell,
        "reference_runout_area_m2": float(b.sum()) * cell,
        "runout_overlap_iou": inter / union if union else float("nan"),
        "runout_length_m": ra,
        "reference_runout_length_m": rb,
        "runout_length_diff_m": ra - rb,
    }


def release_metrics(scn: Any, prob: np.ndarray, x: np.ndarray, y: np.ndarray) -> dict:
    """The release (prob >= 0.5) against the documented polygon on the run's grid."""
    from damjax import release_area
    from damjax.scenario.slope_fields import release_area_of

    area = release_area_of(scn)
    inside = area.mask(x, y)
    out = release_area.compare_release(prob >= 0.5, inside, x, scn.setup.dx)
    out["released_any_member_m2"] = float(np.sum(prob > 0)) * scn.setup.dx**2
    return out


def terrain_metrics(folder: Path, ds: Any) -> dict[str, Any]:
    """Per member (a run's ``summary.json``, an ensemble's member variables): the share
    of the release's boundary on the domain's edge, the sources of the arrival-time map,
    the area failing at t = 0 and the outflow; for an ensemble also how many members
    stay below 5 % on the edge and have one source."""
    keys = ("domain_edge_fraction", "arrival_sources", "initial_failure_area_m2",
            "outflow_area_m2")  # fmt: skip
    if "member" in ds.dims:
        out: dict[str, Any] = {
            k: [None if not np.isfinite(v) else float(v) for v in ds[k].values]
            for k in keys
            if k in ds
        }
        if "domain_edge_fraction" in ds:
            edge = np.asarray(ds["domain_edge_fraction"].values, float)
            out["members_edge_below_5pc"] = int(np.sum(np.nan_to_num(edge, nan=1.0) <= 0.05))
        if "arrival_sources" in ds:
            out["members_one_source"] = int(np.sum(ds["arrival_sources"].values == 1))
        return out
    summ = Path(folder, "summary.json")
    if not summ.is_file():
        return {}
    sj = json.loads(summ.read_text())
    return {k: sj.get(k) for k in keys if k in sj}


def recount_sources(scn: Any, ds: Any) -> dict[str, Any]:
    """The sources of each member's stored arrival-time map counted again with the
    current `damjax.slope.simulation.arrival_sources` and the scenario's reach (the
    model's `source_reach` from its values: dx, E, nu, the thickest slab, K)."""
    from damjax import scenario as scenarios
    from damjax.slope.simulation import arrival_sources, reach_of

    prep = scenarios.prepared(scn)
    p, dx = prep.params, float(prep.setup.dx)
    th = prep.snow()["thickness"]
    h = float(p.thickness) if th is None else float(np.nanmax(np.asarray(th, float)))
    reach = reach_of(
        dx, float(p.youngs_modulus), float(p.poisson), h,
        float(p.wl_shear_modulus) / float(p.wl_thickness),
    )  # fmt: skip
    t = np.asarray(ds["arrival_time"].values, float)
    counts = [arrival_sources(m, dx, reach) for m in (t if t.ndim == 3 else t[None])]
    return {
        "source_reach_m": round(reach, 3),
        "arrival_sources": counts,
        "members_one_source": int(sum(c == 1 for c in counts)),
    }


# ------------------------------------------------------------------ damjax's side


def toy_scenario(path: str, folder: Path, size: float = 20.0, duration: float = 0.2) -> Any:
    """A toy version of a path's scenario (seconds on a CPU): a ``size`` m square release
    polygon (GeoJSON in ``folder``, the documented polygon's CRS and thickness) around the
    documented polygon's representative point, 2 m of terrain around it, ``duration`` s."""
    import tomllib
    import warnings

    import geopandas as gpd
    import shapely

    from damjax import scenario as scenarios

    doc = gpd.read_file(DATA / path / "release.shp")
    c = doc.geometry.iloc[0].representative_point()
    h = 0.5 * size
    toy = gpd.GeoDataFrame(
        {"thickness": [float(doc["thickness"].iloc[0])]},
        geometry=[shapely.box(c.x - h, c.y - h, c.x + h, c.y + h)],
        crs=doc.crs,
    )
    folder.mkdir(parents=True, exist_ok=True)
    poly = folder / f"toy_{path}.geojson"
    toy.to_file(poly, driver="GeoJSON")
    lib = scenarios.resolve(scenario_name(path))
    data = tomllib.loads(lib.read_text())
    data["name"] = f"{scenario_name(path)}-toy"
    data["terrain"]["file"] = str((lib.parent / data["terrain"]["file"]).resolve())
    data["terrain"]["release"] = str(poly)
    data["terrain"]["buffer"] = 2.0
    data["setup"]["duration"] = duration
    data["setup"]["chunk_steps"] = 50
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return scenarios.parse(data, base_dir=lib.parent)


def run_damjax(scn: Any, out: Path, members: int) -> tuple[Path, Any, dict]:
    """The run (members == 1) or ensemble of a scenario into ``out``; (folder, the
    release probability dataset, timing)."""
    import resource

    from damjax import ensemble, runner
    from damjax.export import gis

    t0 = time.perf_counter()
    # hours on a CPU: a bar over the steps, and a line on stderr for each member on disk
    if members == 1:
        runner.run(scn, out, progress=True)
        ds = gis.open_run(out)
        prob = np.isfinite(np.asarray(ds["arrival_time"].values)).astype(float)
        res = ds.assign(release_probability=(("x", "y"), prob))
    else:
        res = ensemble.run(
            ensemble.from_scenario(scn, members=members),
            out,
            plot=False,
            progress=True,
            log=lambda line: print(f"{scn.name}: {line}", file=sys.stderr, flush=True),
        )
    wall = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return out, res, {"damjax_wall_s": round(wall, 1), "damjax_peak_rss_mib": round(rss)}


def load_run(run_dir: Path) -> Any:
    """A finished run or ensemble folder's dataset with ``release_probability``."""
    from damjax.export import gis

    ds = gis.open_run(run_dir)
    if "release_probability" not in ds:
        prob = np.isfinite(np.asarray(ds["arrival_time"].values)).astype(float)
        ds = ds.assign(release_probability=(("x", "y"), prob))
    return ds


def plot(path: str, scn: Any, ds: Any, pfts: dict[str, Path], file: Path) -> None:
    """DEM hillshade, documented polygon, release probability, runout outlines."""
    import geopandas as gpd
    from matplotlib.colors import LightSource
    from matplotlib.figure import Figure  # no pyplot: the caller's backend stays as it is
    from matplotlib.ticker import MaxNLocator

    from damjax import terrain
    from damjax.scenario.slope_fields import release_area_of

    dem = terrain.load_dem(DATA / path / "dem.tif")
    z = np.where(np.isfinite(dem.z), dem.z, np.nanmin(dem.z))
    hs = LightSource(azdeg=315, altdeg=45).hillshade(z.T[::-1], dx=dem.dx, dy=dem.dy)
    ext = (dem.x[0], dem.x[-1], dem.y[0], dem.y[-1])
    poly = gpd.read_file(DATA / path / "release.shp")
    area = release_area_of(scn)
    x, y = np.asarray(ds["x"].values), np.asarray(ds["y"].values)
    prob = np.asarray(ds["release_probability"].values, dtype=float)
    k = max(1, int(round(2.0 / scn.setup.dx)))  # ~2 m pixels for the figure
    px, py = area.to_map(x[::k, None], y[None, ::k])
    fig = Figure(figsize=(10, 6.2))
    axes = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1]})
    for i, ax in enumerate(axes):
        ax.imshow(hs, extent=ext, cmap="gray", origin="upper")
        cs = ax.contour(dem.x, dem.y, z.T, levels=np.arange(0, 4000, 50), colors="0.35",
                        linewidths=0.3)  # fmt: skip
        if i == 1:
            ax.clabel(cs, levels=cs.levels[::4], fontsize=5)
        ax.set_aspect("equal")
        ax.set_xlabel("easting [m] (EPSG:31287)")
    ax = axes[0]
    p = np.ma.masked_less_equal(prob[::k, ::k], 0.0)
    sc = ax.pcolormesh(px, py, p, cmap="magma_r", vmin=0, vmax=1, shading="nearest")
    fig.colorbar(sc, ax=ax, shrink=0.6, label="damjax release probability")
    poly.boundary.plot(ax=ax, color="tab:cyan", lw=1.2)
    bx, by = area.to_map([0, area.length, area.length, 0, 0], [0, 0, area.width, area.width, 0])
    ax.plot(bx, by, color="w", lw=0.6, ls="--")
    pad = 60.0
    ax.set_xlim(min(bx) - pad, max(bx) + pad)
    ax.set_ylim(min(by) - pad, max(by) + pad)
    ax.set_ylabel("northing [m]")
    ax.set_title(f"{path}: documented polygon (cyan), damjax domain (dashed)", fontsize=9)
    ax = axes[1]
    poly.boundary.plot(ax=ax, color="tab:cyan", lw=1.0)
    colors = {"reference": "tab:blue", "documented rerun": "tab:green", "damjax": "tab:red"}
    for name, f in pfts.items():
        a, tr = _raster(f)
        rows, cols = np.arange(a.shape[0]), np.arange(a.shape[1])
        xs = tr.c + (cols + 0.5) * tr.a
        ys = tr.f + (rows + 0.5) * tr.e
        ax.contour(xs, ys, (a > PFT_MIN).astype(float), levels=[0.5], colors=colors[name],
                   linewidths=1.0)  # fmt: skip
        ax.plot([], [], color=colors[name], label=f"{name}: pft > 1 cm")
    line = thalweg(path)
    ax.plot(*line.xy, color="k", lw=0.6, ls=":", label="thalweg")
    ax.legend(fontsize=7, loc="best")
    ax.set_title("com1DFA runouts", fontsize=9)
    for ax in axes:
        ax.xaxis.set_major_locator(MaxNLocator(3))
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    file.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(file, dpi=80)


def _avaframe_python() -> str | None:
    return os.environ.get("DAMJAX_AVAFRAME_PYTHON") or None


def run_path(
    path: str,
    out: Path,
    members: int = 16,
    run_dir: Path | None = None,
    scenario: Any = None,
    avaframe: bool = True,
    figure: Path | None = None,
    rerun: bool = True,
) -> dict[str, Any]:
    """The chain for one path; the JSON row (without writing it). ``rerun``: also run the
    documented polygon through com1DFA (a check of the crop and AvaFrame's version)."""
    import warnings

    from damjax import scenario as scenarios
    from damjax.export import avaframe as ava_export

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scn = scenario if scenario is not None else scenarios.load(scenario_name(path))
    row: dict[str, Any] = {"benchmark": "real_path", "path": path, "scenario": scn.name}
    s = scn.setup
    cover = scenarios.prepared(scn).cover  # the snow-covered cells hold the particles
    n_cells = int(round(s.length / s.dx)) * int(round(s.width / s.dx))
    n_particles = n_cells if cover is None else int(cover.sum())
    row.update(dx_m=s.dx, duration_s=s.duration, particles=n_particles, members=members)
    if run_dir is not None:
        folder, ds = run_dir, load_run(run_dir)
        row["reused_run"] = str(run_dir)
        # a run's summary.json, or an ensemble's ensemble_summary.json
        summ = next(
            (
                f
                for f in (Path(run_dir, "summary.json"), Path(run_dir, "ensemble_summary.json"))
                if f.is_file()
            ),
            None,
        )
        if summ is not None:
            sj = json.loads(summ.read_text())
            for key in ("wall_time_s", "compile_time_s", "n_steps", "particle_steps_per_s"):
                if key in sj:
                    row[f"damjax_{key}"] = sj[key]
    else:
        folder, ds, timing = run_damjax(scn, out / "damjax", members)
        ds = load_run(folder)
        row.update(timing)
    x, y = np.asarray(ds["x"].values), np.asarray(ds["y"].values)
    prob = np.asarray(ds["release_probability"].values, dtype=float)
    row.update({k: round(v, 4) for k, v in release_metrics(scn, prob, x, y).items()})
    row.update(terrain_metrics(folder, ds))
    if "arrival_time" in ds:  # the sources by the current criterion (a reused run's too)
        rc = recount_sources(scn, ds)
        counts = rc["arrival_sources"] if "member" in ds.dims else rc["arrival_sources"][0]
        stored = row.get("arrival_sources")
        if stored is not None and np.any(np.asarray(stored) != np.asarray(counts)):
            row["arrival_sources_as_run"] = stored
        row["arrival_sources"] = counts
        if "member" in ds.dims:
            row["members_one_source"] = rc["members_one_source"]
    pfts: dict[str, Path] = {"reference": DATA / path / "reference_pft.tif"}
    python = _avaframe_python() if avaframe else None
    if python:
        frict = reference_friction(path)
        row["com1dfa_friction"] = frict
        thickness = scn.params.thickness
        avadir = out / "avaframe_damjax"
        ava_export.export_avaframe(
            folder, avadir, scenario=scn.to_toml(), thickness=thickness, name="damjax"
        )
        com = com1dfa(avadir, frict, python)
        pfts["damjax"] = Path(next(p for p in com["peak_files"] if p.endswith("_pft.asc")))
        row["com1dfa_wall_s"] = round(com["com1dfa_wall_s"], 1)
        ref = DATA / path / "reference_pft.tif"
        for key, v in runout_metrics(path, pfts["damjax"], ref).items():
            row[key] = round(v, 2)
        if rerun:
            doc = documented_avadir(path, out / "avaframe_documented")
            com = com1dfa(doc, frict, python)
            pfts["documented rerun"] = Path(
                next(p for p in com["peak_files"] if p.endswith("_pft.asc"))
            )
            rr = runout_metrics(path, pfts["documented rerun"], ref)
            row["rerun_runout_overlap_iou"] = round(rr["runout_overlap_iou"], 4)
            row["rerun_runout_length_diff_m"] = round(rr["runout_length_diff_m"], 2)
    else:
        row["avaframe"] = "skipped (DAMJAX_AVAFRAME_PYTHON unset)"
    if figure is not None:
        plot(path, scn, ds, pfts, figure)
        row["figure"] = (
            str(figure.relative_to(ROOT)) if figure.is_relative_to(ROOT) else str(figure)
        )
    return row


def _with_duration(path: str, duration: float | None) -> Any:
    """The path's shipped scenario, with ``duration`` [s] when given (else None: the
    scenario as shipped)."""
    if duration is None:
        return None
    import dataclasses
    import warnings

    from damjax import scenario as scenarios

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scn = scenarios.load(scenario_name(path))
    return dataclasses.replace(scn, setup=dataclasses.replace(scn.setup, duration=duration))


def recount(path: str, run_dir: Path, members: int, commit: str | None) -> None:
    """`recount_sources` of a finished run folder, printed and added under ``recount`` to
    the latest row of ``path`` with ``members`` members."""
    import warnings

    from damjax import scenario as scenarios

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scn = scenarios.load(scenario_name(path))
    rc = recount_sources(scn, load_run(run_dir))
    rc.update(date=time.strftime("%Y-%m-%d"), commit=commit, run_dir=str(run_dir))
    print(json.dumps(rc))
    lines = RESULTS.read_text(encoding="utf-8").splitlines()
    rows = [json.loads(line) for line in lines]
    hits = [i for i, r in enumerate(rows) if r.get("path") == path and r.get("members") == members]
    if not hits:
        raise SystemExit(f"no row of {path} with {members} members in {RESULTS}")
    rows[hits[-1]]["recount"] = rc
    RESULTS.write_text("".join(json.dumps(r) + "\n" for r in rows), encoding="utf-8")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--path", choices=(*PATHS, "all"), default="all")
    ap.add_argument("--members", type=int, default=16, help="ensemble members (1: one run)")
    ap.add_argument("--out", default="damjax-out/real-path", help="output folder")
    ap.add_argument("--run-dir", default=None, help="reuse this run / ensemble folder")
    ap.add_argument("--no-figure", action="store_true", help="no docs/images figure")
    ap.add_argument(
        "--duration",
        type=float,
        default=None,
        help="simulated time [s] instead of the scenario's (an ensemble on a CPU: the time "
        "by which one member's release stopped growing)",
    )
    ap.add_argument(
        "--recount",
        action="store_true",
        help="with --run-dir: count the sources of the stored arrival-time maps again with "
        "the current criterion and add them (with commit and date) to the path's latest "
        "row of that many members in results/real_path.jsonl; nothing else runs",
    )
    ap.add_argument("--com1dfa", metavar="AVADIR", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--frict", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.com1dfa:
        print(json.dumps(run_com1dfa(args.com1dfa, args.frict)))
        return
    paths = PATHS if args.path == "all" else (args.path,)
    if args.duration is not None and not args.duration > 0:
        raise SystemExit(f"--duration {args.duration}: must be > 0 s")
    from benchmarks.cases import git_commit

    commit = git_commit()  # the code that runs (taken before the runs: they take hours)
    if args.recount:
        if not args.run_dir or len(paths) != 1:
            raise SystemExit("--recount needs --run-dir and one --path")
        recount(paths[0], Path(args.run_dir), args.members, commit)
        return
    for path in paths:
        out = Path(args.out) / path
        fig = None if args.no_figure else IMAGES / f"real_path_{path.lower()}.png"
        row = run_path(
            path,
            out,
            members=args.members,
            run_dir=Path(args.run_dir) if args.run_dir else None,
            scenario=_with_duration(path, args.duration),
            figure=fig,
        )
        row["date"] = time.strftime("%Y-%m-%d")
        row["commit"] = commit
        print(json.dumps(row))
        with open(RESULTS, "a", encoding="utf-8") as f:
            f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
