"""GIS and AvaFrame export of a small slope run on a georeferenced DEM."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rasterio")
pytest.importorskip("geopandas")
pytest.importorskip("pyogrio")

import geopandas as gpd  # noqa: E402
import rasterio  # noqa: E402
from rasterio.crs import CRS  # noqa: E402

from damjax import terrain  # noqa: E402
from damjax.export import avaframe as ava_export  # noqa: E402
from damjax.export import gis  # noqa: E402

PSI = 35.0  # slope of the plane DEM [deg]
X0, Y0 = 2783000.0, 1186000.0  # LV95 corner of the DEM [m]
ORIGIN = (X0 + 20.0, Y0 + 5.0)  # the release area's lower left corner
DX = 0.2

SCENARIO = """
type = "slope"
name = "export-test"

[params]
slope_deg = 35.0

[setup]
length = 4.0
width = 3.0
dx = 0.2
duration = 0.06
start = [1.0, 1.5]
chunk_steps = 20

[terrain]
kind = "dem"
file = "plane.asc"
origin = [{ox}, {oy}]
upslope = "+y"

[strength]
kind = "constant"
tau_peak = 1000.0
trend = 150.0

[output]
plot = false
snapshots = false
"""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """A 4 m x 3 m release area on a 35 deg plane DEM (LV95, 1 m cells, up-slope north),
    run for 0.06 s: the crack has spread part of the way from its start."""
    from damjax import runner

    d = tmp_path_factory.mktemp("export")
    xs = X0 + 0.5 + np.arange(40.0)
    ys = Y0 + 0.5 + np.arange(30.0)
    z = 2000.0 + math.tan(math.radians(PSI)) * (ys[None, :] - Y0) + 0.0 * xs[:, None]
    terrain.save_esri_ascii(terrain.Terrain(xs, ys, z), d / "plane.asc")
    (d / "plane.prj").write_text(CRS.from_epsg(2056).to_wkt(version="WKT1_ESRI"))
    (d / "scn.toml").write_text(SCENARIO.format(ox=ORIGIN[0], oy=ORIGIN[1]))
    with pytest.warns(UserWarning):  # dx above Lambda/5
        runner.run(d / "scn.toml", d / "run")
    return d / "run"


def _boundary_cells(mask: np.ndarray) -> int:
    """Released cells with a 4-neighbour that is not released (or the area's edge)."""
    p = np.pad(mask, 1, constant_values=False)
    inner = p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    return int(np.sum(mask & ~inner))


def test_frame_maps_the_area_onto_the_dem(run_dir):
    ds = gis.open_run(run_dir)
    fr = gis.frame_of(ds)
    assert fr.crs.to_epsg() == 2056 and not fr.local
    assert (fr.nx, fr.ny) == (20, 15)
    # along x the surface of a 35 deg plane is 1/cos(35 deg) longer than the map
    np.testing.assert_allclose(fr.cos_along(), math.cos(math.radians(PSI)), rtol=1e-4)
    X, Y = fr.to_map(np.array([0.0, 4.0]), np.array([0.0, 3.0]))
    # up-slope is north (+y); the area's y axis is the DEM's -x
    np.testing.assert_allclose(X, [ORIGIN[0], ORIGIN[0] - 3.0])
    np.testing.assert_allclose(Y, [ORIGIN[1], ORIGIN[1] + 4.0 * math.cos(math.radians(PSI))])
    x, y = fr.from_map(X, Y)
    np.testing.assert_allclose(x, [0.0, 4.0], atol=1e-9)
    np.testing.assert_allclose(y, [0.0, 3.0], atol=1e-9)


def test_geotiffs_and_polygons_have_the_dem_crs_and_area(run_dir, tmp_path):
    files = gis.export_gis(run_dir, tmp_path / "gis", formats=("gpkg", "shp", "geojson"))
    ds = gis.open_run(run_dir)
    released = np.isfinite(ds["arrival_time"].values)
    n = int(released.sum())
    assert 4 < n < released.size  # a partial release: the outline is not the area's
    cell_map = DX * DX * math.cos(math.radians(PSI))  # a cell's area on the map [m^2]
    expected = n * cell_map
    tol = _boundary_cells(released) * cell_map  # one cell's area per boundary cell
    for name in ("released", "arrival_time", "thickness_change"):
        with rasterio.open(files[name]) as src:
            assert src.crs.to_epsg() == 2056
            img = src.read(1)
            px = abs(src.res[0] * src.res[1])
            assert src.bounds.left >= X0 and src.bounds.top <= Y0 + 30.0
            if name == "released":
                assert abs(np.sum(img == 1) * px - expected) <= tol
                assert np.sum(img == 255) > 0  # the pixels outside the area are nodata
            if name == "arrival_time":
                t = img[np.isfinite(img)]
                assert t.size and np.all((t >= 0) & (t <= 0.07))
    for fmt in ("gpkg", "shp", "geojson"):
        zones = gpd.read_file(files[f"zones_{fmt}"])
        assert zones.crs.to_epsg() == 2056
        assert abs(float(zones.geometry.area.sum()) - expected) <= tol
        assert abs(float(zones["area_m2"].sum()) - expected) <= tol
        assert float(zones["surf_m2"].sum()) == pytest.approx(n * DX * DX)
        h = ds["height"].values[released]
        assert float(zones["thickness"].iloc[0]) == pytest.approx(float(np.mean(h)), rel=1e-6)
    meta = json.loads((tmp_path / "gis" / "export.json").read_text())
    assert meta["crs"] == "EPSG:2056"


def test_cells_without_snow_are_no_data_in_the_geotiffs(run_dir, tmp_path):
    """A cell without snow (rock above the slope limit, a mask) has no slab: its thickness
    change is nodata and its released pixel 255, not -h0 and 0 (a slab that left)."""

    def pixels(ds, folder):
        files = gis.write_geotiffs(ds, gis.frame_of(ds), tmp_path / folder, resolution=DX / 2)
        with rasterio.open(files["thickness_change"]) as a, rasterio.open(files["released"]) as b:
            return a.read(1), b.read(1)

    ds = gis.open_run(run_dir)
    dh0, rel0 = pixels(ds, "all")
    bare = np.zeros(ds["snow"].shape, bool)
    bare[:, -5:] = True  # the five columns at the area's far side: no snow there
    ds["snow"].values[bare] = False
    ds["thickness"].values[bare] = 0.0
    ds["height"].values[bare] = 0.0
    dh, rel = pixels(ds, "bare")
    assert np.sum(rel == 255) > np.sum(rel0 == 255)  # the bare cells joined the nodata
    for d, r in ((dh0, rel0), (dh, rel)):
        np.testing.assert_array_equal(np.isnan(d), r == 255)  # one nodata in both layers
    assert np.nanmin(dh) == pytest.approx(np.nanmin(dh0))  # no "-h0" pixel


def test_a_dem_whose_wkt_lacks_its_authority_exports_its_epsg_code(tmp_path):
    """The shipped avaKot DEM's WKT names MGI / Austria Lambert without an AUTHORITY: the
    zones must still carry EPSG:31287 (GeoJSON without a "crs" member is read as WGS84,
    GeoPackage as an unknown custom system)."""
    from shapely.geometry import box

    dem = Path(gis.__file__).parents[1] / "data" / "paths" / "avaKot" / "dem.tif"
    with rasterio.open(dem) as src:
        assert src.crs.to_epsg() == 31287  # rasterio identifies it ...
    crs = gis.dem_crs(dem)
    assert crs.to_epsg() == 31287 and crs == CRS.from_epsg(31287)  # ... and we keep the code
    zones = gpd.GeoDataFrame({"id": [1]}, geometry=[box(0, 0, 10, 10)], crs=crs)
    for name in ("z.geojson", "z.gpkg"):
        zones.to_file(tmp_path / name)
        assert gpd.read_file(tmp_path / name).crs.to_epsg() == 31287, name


def test_local_frame_without_a_dem(run_dir, tmp_path):
    ds = gis.open_run(run_dir)
    fr = gis.frame_of(ds, scenario={"terrain": {"kind": "plane"}})
    assert fr.local and fr.crs is None
    # a local frame is on no map: a CRS stated for it would put it on one silently
    with pytest.raises(ValueError, match="crs = 'EPSG:2056': a run on terrain.kind = 'plane'"):
        gis.frame_of(ds, scenario={"terrain": {"kind": "plane"}}, crs="EPSG:2056")
    files = gis.write_geotiffs(ds, fr, tmp_path)
    with rasterio.open(files["released"]) as src:
        assert src.crs is None and "DAMJAX_FRAME" in src.tags()
        assert src.res == pytest.approx((DX, DX))
        img = src.read(1)
        assert np.sum(img == 1) == int(np.isfinite(ds["arrival_time"].values).sum())
    zones = gis.release_zones(ds, fr)
    assert float(zones.geometry.area.sum()) == pytest.approx(float(zones["surf_m2"].sum()))
    # no advice to state a CRS (--crs), which a local frame refuses (above)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gis.write_release_zones(zones, tmp_path / "zones", formats=("gpkg",), local=True)
    with pytest.warns(UserWarning, match="the run's DEM has none"):
        gis.write_release_zones(zones, tmp_path / "zones2", formats=("gpkg",))
    with pytest.raises(ValueError, match="not a DEM"):
        ava_export.export_avaframe(run_dir, tmp_path / "ava", scenario={"terrain": {}})


def test_ensemble_probability_and_zones(run_dir, tmp_path):
    import xarray as xr

    ds = gis.open_run(run_dir)
    rel = np.isfinite(ds["arrival_time"].values)
    members = np.stack([rel, rel, np.zeros_like(rel)])  # released in 2 of 3 members
    ens = xr.Dataset(
        {
            "released": (("member", "x", "y"), members.astype(np.int8)),
            "height": (("member", "x", "y"), np.stack([ds["height"].values] * 3)),
            "release_probability": (("x", "y"), members.mean(0).astype(np.float32)),
            "snow": (("x", "y"), np.ones(rel.shape, np.int8)),
        },
        coords={"x": ds["x"].values, "y": ds["y"].values},
    )
    path = tmp_path / "ensemble.nc"
    ens.to_netcdf(path, engine="h5netcdf")
    scn = run_dir.parent / "scn.toml"
    with pytest.raises(ValueError, match="pass scenario="):
        gis.export_gis(path, tmp_path / "gis")
    files = gis.export_gis(path, tmp_path / "gis", scenario=scn)
    with rasterio.open(files["release_probability"]) as src:
        p = src.read(1)
        assert src.crs.to_epsg() == 2056
        assert np.nanmax(p) == pytest.approx(2 / 3)
    zones = gpd.read_file(files["zones_gpkg"])
    assert zones["mean_prob"].iloc[0] == pytest.approx(2 / 3)
    assert len(gis.release_zones(ens, gis.frame_of(ens, scn), threshold=0.7)) == 0
    # cells without snow: no data, not a probability of 0
    ens["snow"][:, : ens.sizes["y"] // 2] = 0
    ens.to_netcdf(tmp_path / "ensemble2.nc", engine="h5netcdf")
    files = gis.export_gis(tmp_path / "ensemble2.nc", tmp_path / "gis2", scenario=scn)
    with rasterio.open(files["release_probability"]) as src:
        q = src.read(1)
    assert np.isnan(q).sum() > np.isnan(p).sum() and np.nanmin(q) >= 0.0


def test_missing_inputs_are_one_line_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="no results.nc or ensemble.nc"):
        gis.open_run(tmp_path)
    with pytest.raises(FileNotFoundError, match="no such file"):
        gis.open_run(tmp_path / "none.nc")


AVAFRAME_READBACK = textwrap.dedent(
    """
    import json, sys
    from avaframe.in1Data import getInput
    from avaframe.in2Trans import shpConversion
    avadir = sys.argv[1]
    files = getInput.getThicknessInputSimFiles(getInput.getInputDataCom1DFA(avadir))
    dem = getInput.readDEM(avadir)
    rel = files["relFiles"][0]
    line = shpConversion.readLine(rel, "rel", dem)
    print(json.dumps({
        "dem": str(files["demFile"]), "rel": [str(r) for r in files["relFiles"]],
        "thickness": files[rel.stem]["thickness"], "names": list(line["Name"]),
        "crs": str(dem["header"]["crs"]), "cellsize": float(dem["header"]["cellsize"]),
        "npoints": int(len(line["x"])),
    }))
    """
)


def _avaframe_python() -> str | None:
    """A Python that imports AvaFrame: this one, or DAMJAX_AVAFRAME_PYTHON (AvaFrame pins
    numpy < 2, so it usually lives in its own environment)."""
    try:
        from avaframe.in1Data import getInput  # noqa: F401

        return sys.executable
    except Exception:  # ImportError, or its compiled parts built against numpy 1
        pass
    exe = os.environ.get("DAMJAX_AVAFRAME_PYTHON")
    if exe and shutil.which(exe):
        return exe
    return None


def test_avaframe_directory_reads_back_with_avaframe(run_dir, tmp_path):
    files = ava_export.export_avaframe(run_dir, tmp_path / "ava")
    inputs = tmp_path / "ava" / "Inputs"
    assert files["dem"] == inputs / "plane.asc" and (inputs / "plane.prj").exists()
    assert files["release"] == inputs / "REL" / "export-test.shp"
    zones = gpd.read_file(files["release"])
    assert list(zones["name"]) == ["rel1"] and zones.crs.to_epsg() == 2056
    exe = _avaframe_python()
    if exe is None:
        pytest.skip("AvaFrame not importable (set DAMJAX_AVAFRAME_PYTHON to its python)")
    proc = subprocess.run(
        [exe, "-c", AVAFRAME_READBACK, str(tmp_path / "ava")], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert Path(got["dem"]).name == "plane.asc" and got["cellsize"] == 1.0
    assert [Path(r).name for r in got["rel"]] == ["export-test.shp"]
    assert got["names"] == ["rel1"]
    assert float(got["thickness"][0]) == pytest.approx(float(zones["thickness"].iloc[0]))
    assert ("LV95" in got["crs"] or "2056" in got["crs"]) and got["npoints"] >= 5


def test_cli_export_gis_and_avaframe(run_dir, tmp_path, capsys):
    from damjax.cli import main

    out = tmp_path / "gis"
    assert main(["export", str(run_dir), "--to", "gis", str(out), "--formats", "geojson"]) == 0
    text = capsys.readouterr().out
    assert "released" in text and str(out / "release_zones.geojson") in text
    with rasterio.open(out / "released.tif") as src:
        assert src.crs.to_epsg() == 2056
    zones = gpd.read_file(out / "release_zones.geojson")
    assert zones.crs.to_epsg() == 2056 and len(zones) == 1
    assert not (out / "release_zones.gpkg").exists()  # only the formats asked for
    ava = tmp_path / "ava"
    argv = ["export", str(run_dir), "--to", "avaframe", str(ava), "--name", "rel", "--json"]
    assert main(argv) == 0
    got = json.loads(capsys.readouterr().out)
    assert Path(got["release"]) == ava / "Inputs" / "REL" / "rel.shp"
    rel = gpd.read_file(got["release"])
    assert float(rel["thickness"].iloc[0]) == pytest.approx(float(zones["thickness"].iloc[0]))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--to", "gis"], "no results.nc or ensemble.nc"),
        (["--to", "kml"], "invalid choice: 'kml'"),
        (["--to", "gis", "--threshold", "2"], "'2': must be in (0, 1]"),
        (["--to", "avaframe", "--thickness", "-1"], "'-1': must be a number > 0"),
    ],
)
def test_cli_export_errors_are_one_line(tmp_path, capsys, argv, message):
    from damjax.cli import main

    assert main(["export", str(tmp_path), str(tmp_path / "out"), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("damjax: error: ") and message in err[0], err


def test_an_unknown_crs_is_one_line_without_gdal_s_own(run_dir, capfd):
    """--crs EPSG:999999 is refused in damjax's words, and GDAL prints nothing beside them."""
    ds = gis.open_run(run_dir)
    with pytest.raises(ValueError, match=r"crs = 'EPSG:999999': not a coordinate reference"):
        gis.frame_of(ds, crs="EPSG:999999")
    assert "ERROR" not in capfd.readouterr().err
    assert gis.frame_of(ds, crs="EPSG:2056").crs.to_epsg() == 2056
    # a stated CRS labels the DEM's grid: degrees, or another CRS than the DEM's own,
    # relabelled the files silently
    with pytest.raises(ValueError, match=r"crs = 'EPSG:4326': a geographic CRS \(degrees\)"):
        gis.frame_of(ds, crs="EPSG:4326")
    with pytest.raises(ValueError, match=r"crs = 'EPSG:31287': the DEM \(plane.asc\) states"):
        gis.frame_of(ds, crs="EPSG:31287")


def test_release_zones_without_a_crs_warn_of_geojson(tmp_path):
    """GeoJSON without a CRS is read as WGS 84 (RFC 7946): metres of a local frame became
    degrees in GIS tools; the writer says so (the .gpkg / .shp state no CRS)."""
    import warnings

    import shapely

    zones = gpd.GeoDataFrame({"name": ["z"]}, geometry=[shapely.box(0, 0, 12, 6)], crs=None)
    with pytest.warns(UserWarning, match=r"z.geojson: has no CRS, which GeoJSON readers take"):
        gis.write_release_zones(zones, tmp_path, stem="z", formats=("geojson",), local=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gis.write_release_zones(zones, tmp_path / "g", stem="z", formats=("gpkg",), local=True)
