"""A documented avalanche path (AvaFrame's avaKot, damjax/data/paths) at toy size: a small
polygon inside the documented release as the domain of a DEM slope run, the comparison with
the documented polygon, the reader's errors, and (with DAMJAX_AVAFRAME_PYTHON) the com1DFA
runout against AvaFrame's reference."""

from __future__ import annotations

import os
import shutil
import warnings

import numpy as np
import pytest

gpd = pytest.importorskip("geopandas")
shapely = pytest.importorskip("shapely")

from damjax import release_area, scenario  # noqa: E402
from damjax.scenario import prepared  # noqa: E402
from damjax.scenario.slope_fields import cell_centres, release_area_of, resolve_fields  # noqa: E402
from verification import real_path as rp  # noqa: E402

KOT = rp.DATA / "avaKot"


def _load(data: dict, base) -> object:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return scenario.parse(data, base_dir=base)


def _toy_data(tmp_path, **terrain) -> dict:
    import tomllib

    lib = scenario.resolve("real-path-avakot")
    data = tomllib.loads(lib.read_text())
    data["terrain"]["file"] = str(KOT / "dem.tif")
    data["terrain"].pop("buffer", None)  # the rectangle of the polygon plus a margin
    data["terrain"]["margin"] = 2.0
    data["terrain"].update(terrain)
    data["setup"]["duration"] = 0.1
    return data


def _square(tmp_path, name="p.geojson", size=20.0, crs=None, **attrs) -> str:
    doc = gpd.read_file(KOT / "release.shp")
    c = doc.geometry.iloc[0].representative_point()
    h = size / 2
    g = gpd.GeoDataFrame(
        {k: [v] for k, v in attrs.items()} or {"id": [0]},
        geometry=[shapely.box(c.x - h, c.y - h, c.x + h, c.y + h)],
        crs=doc.crs,
    )
    if crs is not None:
        g = g.to_crs(crs)
    g.to_file(tmp_path / name, driver="GeoJSON")
    return str(tmp_path / name)


def test_shipped_scenarios_place_the_documented_polygons():
    for name, up in (("real-path-avaalr", "+y"), ("real-path-avakot", "-y")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scn = scenario.load(name)
        assert scn.params.thickness == 1.0  # the polygon's attribute
        assert scn.terrain["upslope"] == up
        area = release_area_of(scn)
        x, y = cell_centres(scn.setup)
        inside = area.mask(x, y)
        # the polygon's surface area on the grid: at least its map area
        assert inside.sum() * scn.setup.dx**2 >= area.geometry.area
        # and a stored scenario reads back (origin, length and width agree)
        back = _load(__import__("tomllib").loads(scn.to_toml()), None)
        assert back.setup.length == scn.setup.length


def test_toy_path_runs_and_compares(tmp_path):
    scn = rp.toy_scenario("avaKot", tmp_path, size=16.0, duration=0.1)
    _, _, tau, start = resolve_fields(scn)
    area = release_area_of(scn)
    x, y = cell_centres(scn.setup)
    inside = area.mask(x, y, buffer=2.0)
    i, j = np.argmin(np.abs(x - start[0])), np.argmin(np.abs(y - start[1]))
    assert inside[i, j]  # the crack starts inside the polygon
    # its length and width are the polygon's (not whole cells): no note to the user of them
    assert scn.setup.length / scn.setup.dx % 1 > 0.01
    assert not any("whole number of cells" in n.text() for n in prepared(scn).notes)
    row = rp.run_path("avaKot", tmp_path / "out", members=1, scenario=scn, avaframe=False)
    assert row["polygon_area_m2"] > 16.0**2  # surface area of a 16 m x 16 m map square
    assert 0 < row["released_area_m2"] and 0 <= row["overlap_iou"] <= 1
    assert np.isfinite(row["crown_offset_m"]) and row["avaframe"].startswith("skipped")


def test_compare_release_counts():
    x = (np.arange(10) + 0.5) * 1.0
    inside = np.zeros((10, 4), bool)
    inside[2:6] = True
    rel = np.zeros_like(inside)
    rel[4:8] = True
    out = release_area.compare_release(rel, inside, x, 1.0)
    assert out["area_ratio"] == 1.0 and out["overlap_iou"] == pytest.approx(8 / 24)
    assert out["crown_offset_m"] == 2.0 and out["crown_offset_median_m"] == 2.0


def test_missing_thickness_attribute_is_named(tmp_path):
    data = _toy_data(tmp_path, release=_square(tmp_path, name_="x"))
    with pytest.raises(ValueError, match="terrain.thickness_field = 'thickness'.*no such"):
        _load(data, tmp_path)
    data["params"]["thickness"] = 1.2  # a given thickness (and no field) needs none
    del data["terrain"]["thickness_field"]
    assert _load(data, tmp_path).params.thickness == 1.2


def test_crs_mismatch_is_named(tmp_path):
    data = _toy_data(tmp_path, release=_square(tmp_path, crs="EPSG:4326", thickness=1.0))
    with pytest.raises(ValueError, match="terrain.release.*CRS.*differs from the DEM"):
        _load(data, tmp_path)


def test_a_polygon_without_a_crs_is_read_in_the_dems_with_a_warning(tmp_path):
    square = gpd.read_file(_square(tmp_path, thickness=1.0))
    square.set_crs(None, allow_override=True).to_file(tmp_path / "bare.shp")
    assert not (tmp_path / "bare.prj").exists()
    data = _toy_data(tmp_path, release=str(tmp_path / "bare.shp"))
    with pytest.warns(UserWarning, match=r"terrain.release = 'bare.shp': states no CRS"):
        scn = scenario.parse(data, base_dir=tmp_path)
    assert scn.params.thickness == 1.0


def test_polygon_outside_the_dem_is_named(tmp_path):
    g = gpd.GeoDataFrame(
        {"thickness": [1.0]}, geometry=[shapely.box(0, 0, 50, 50)], crs="EPSG:31287"
    )
    g.to_file(tmp_path / "far.geojson", driver="GeoJSON")
    data = _toy_data(tmp_path, release=str(tmp_path / "far.geojson"))
    with pytest.raises(ValueError, match="terrain.release.*outside the DEM"):
        _load(data, tmp_path)


def test_cli_flag_sets_the_release(tmp_path):
    from damjax import cli

    poly = _square(tmp_path, thickness=1.2)
    scn = cli._load_with_release(scenario.resolve("real-path-avakot"), poly)
    assert scn.terrain["release"] == poly and scn.params.thickness == 1.2
    with pytest.raises(ValueError, match="CRS"):  # slope-dem-gully is LV95
        cli._load_with_release(scenario.resolve("slope-dem-gully"), poly)


def _avaframe_python() -> str | None:
    exe = os.environ.get("DAMJAX_AVAFRAME_PYTHON")
    return exe if exe and shutil.which(exe) else None


def test_toy_release_runs_out_in_com1dfa(tmp_path, monkeypatch):
    exe = _avaframe_python()
    if exe is None:
        pytest.skip("AvaFrame not available (set DAMJAX_AVAFRAME_PYTHON to its python)")
    # as from a Jupyter kernel (notebook 14): its inline backend is not in AvaFrame's
    # environment, whose matplotlib refuses it at import
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    scn = rp.toy_scenario("avaKot", tmp_path, size=16.0, duration=0.1)
    row = rp.run_path("avaKot", tmp_path / "out", members=1, scenario=scn, rerun=False)
    assert row["com1dfa_friction"] == "samosATSmall"
    assert row["runout_area_m2"] > 0 and 0 <= row["runout_overlap_iou"] <= 1
    assert np.isfinite(row["runout_length_m"]) and row["reference_runout_length_m"] > 1000


def test_the_shipped_avakot_release_can_only_be_bounded_by_its_buffer():
    """`verification.sliding_terrain` on the shipped avaKot scenario (150 m buffer): the
    snow steeper than the friction angle that the trigger connects to is nearly all the
    snow in the domain, and a third of its boundary is the buffer's edge (the guide's
    "What can bound a release on these DEMs"); the scenario says so before a run."""
    from verification import sliding_terrain as st

    row = st.measure("avaKot", 150.0)
    assert row["dem"] == "shipped" and row["friction_deg"] == 27.0
    assert row["max_slope_deg"] == 60.0  # the scenario's snow limit, unless --max-slope
    assert st.with_buffer("real-path-avakot", 150.0, max_slope=55.0).snow["max_slope_deg"] == 55
    assert 0.9 * row["snow_m2"] < row["sliding_region_m2"] <= row["snow_m2"]
    assert 0.3 < row["sliding_region_edge_fraction"] < 0.4 and row["warns_before_run"]
