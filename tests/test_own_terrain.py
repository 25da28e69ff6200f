"""A user's own DEM and polygons: map units, the raster's bounds, a window partly off the
DEM, a polygon across a ridge, a polygon's thickness attribute, a slab from [snow] beside
a polygon's thickness field. Scenarios are only checked (no run): seconds in all."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")
gpd = pytest.importorskip("geopandas")
shapely = pytest.importorskip("shapely")

from damjax import scenario, terrain  # noqa: E402

X0, Y0 = 600000.0, 5200000.0  # a UTM 32N corner [m]
RES = 5.0
PSI = 38.0


def _tif(path, z, res=RES, crs="EPSG:32632", x0=X0, y0=Y0):
    """A north-up GeoTIFF of rows z[row, col] (row 0 the northernmost), lower-left x0, y0."""
    from rasterio.transform import Affine

    rows, cols = z.shape
    with rasterio.open(
        path, "w", driver="GTiff", height=rows, width=cols, count=1, dtype="float64",
        crs=crs, transform=Affine(res, 0.0, x0, 0.0, -res, y0 + rows * res),
    ) as dst:  # fmt: skip
        dst.write(z, 1)
    return str(path)


def _nodes(cols=20, rows=30, res=RES, x0=X0, y0=Y0):
    x = x0 + (np.arange(cols) + 0.5) * res
    y = y0 + rows * res - (np.arange(rows) + 0.5) * res
    return np.meshgrid(x, y)


def _plane(tmp_path, name="plane.tif", **kw):
    """A 100 m x 150 m plane rising at PSI to the north."""
    _, y = _nodes()
    return _tif(tmp_path / name, 2000.0 + np.tan(np.radians(PSI)) * (y - Y0), **kw)


def _polygon(tmp_path, box, name="rel.gpkg", crs="EPSG:32632", **attrs):
    g = gpd.GeoDataFrame(
        {k: [v] for k, v in attrs.items()} or {"id": [0]},
        geometry=[shapely.box(*box)],
        crs=crs,
    )
    g.to_file(tmp_path / name)
    return str(tmp_path / name)


def _doc(dem, release=None, **terrain_keys) -> dict:
    doc = {
        "type": "slope",
        "name": "own",
        "params": {"thickness": 1.0, "tensile_strength": 4000.0, "softening": 1.0},
        "setup": {"dx": 0.46, "duration": 0.05, "particles_per_cell": 1},
        "terrain": {"kind": "dem", "file": dem, **terrain_keys},
        "snow": {"kind": "uniform"},
        "strength": {"kind": "stability", "mean": 1.42, "cov": 0.1, "length_scale": 8.0},
    }
    if release is not None:
        doc["terrain"].update(release=release, buffer=10.0)
    return doc


def _parse(doc, tmp_path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scn = scenario.parse(doc, base_dir=tmp_path)
    return scn, [str(w.message) for w in caught]


def test_a_dem_in_feet_is_refused_naming_its_unit(tmp_path):
    """Slopes come out right in feet, so nothing else would show that every length, area
    and thickness is 3.3 times off: the DEM's CRS units are checked (GeoTIFF and .prj)."""
    ft = 0.3048
    _, y = _nodes()
    z = (2000.0 + np.tan(np.radians(PSI)) * (y - Y0)) / ft
    feet = _tif(tmp_path / "feet.tif", z, res=RES / ft, crs="EPSG:2229", x0=6.5e6, y0=2e6)
    with pytest.raises(ValueError, match="feet.tif: CRS .*ftUS.* is in US survey foot"):
        terrain.load_dem(feet)
    asc = tmp_path / "feet.asc"
    xs, ys = 6.5e6 + (np.arange(20) + 0.5) * RES / ft, 2e6 + (np.arange(30) + 0.5) * RES / ft
    terrain.save_esri_ascii(terrain.Terrain(xs, ys, z[::-1].T), asc)
    from pyproj import CRS

    asc.with_suffix(".prj").write_text(CRS("EPSG:2229").to_wkt())
    with pytest.raises(ValueError, match="feet.asc: CRS .* is in US survey foot"):
        terrain.load_dem(asc)
    release = _polygon(tmp_path, (6.5e6 + 100, 2e6 + 200, 6.5e6 + 230, 2e6 + 330), crs="EPSG:2229")
    with pytest.raises(ValueError, match=r"terrain.file = .*US survey foot"):
        _parse(_doc(feet, release=release), tmp_path)
    asc.with_suffix(".prj").write_text(CRS("EPSG:32632").to_wkt())
    assert terrain.load_dem(asc).z.shape == (20, 30)  # metres: read


def test_a_polygon_drawn_to_the_rasters_bounds_is_on_the_dem(tmp_path):
    """GIS tools show a raster's bounds half a cell beyond its nodes: a polygon drawn to
    them lies on the DEM; one beyond them is refused with those bounds."""
    dem = _plane(tmp_path)
    at_edge = _polygon(tmp_path, (X0, Y0 + 60, X0 + 40, Y0 + 100), thickness=1.0)
    scn, _ = _parse(_doc(dem, release=at_edge), tmp_path)
    assert scn.terrain["upslope"] == "+y"
    beyond = _polygon(tmp_path, (X0 - 3, Y0 + 60, X0 + 40, Y0 + 100), "far.gpkg", thickness=1.0)
    with pytest.raises(ValueError, match=r"outside the DEM's x \[600000.0, 600100.0\]"):
        _parse(_doc(dem, release=beyond), tmp_path)


def test_a_polygon_thickness_in_centimetres_is_said(tmp_path):
    """The polygon's attribute is read in metres: 100 (meant as cm) gets the unit hint a
    params.thickness of 100 gets."""
    dem = _plane(tmp_path)
    rel = _polygon(tmp_path, (X0 + 30, Y0 + 60, X0 + 70, Y0 + 100), thickness=100.0)
    doc = _doc(dem, release=rel, thickness_field="thickness")
    del doc["params"]["thickness"]
    scn, said = _parse(doc, tmp_path)
    assert scn.params.thickness == 100.0
    assert any("polygon's thickness = 100 m" in s and "100 cm = 1 m" in s for s in said), said


def test_a_slab_from_the_snow_table_beside_a_polygon_thickness_field(tmp_path):
    """terrain.thickness_field written out (as the shipped real paths do) and the slab from
    [snow]: the run goes ahead on the snow table's slab and says the field is not used."""
    dem = _plane(tmp_path)
    rel = _polygon(tmp_path, (X0 + 30, Y0 + 60, X0 + 70, Y0 + 100), thickness=1.0)
    doc = _doc(dem, release=rel, thickness_field="thickness")
    del doc["params"]["thickness"]
    doc["snow"] = {"kind": "slope_corrected", "reference_thickness": 1.2}
    doc["setup"]["dx"] = 0.25
    scn, said = _parse(doc, tmp_path)
    assert scn.snow["kind"] == "slope_corrected"
    assert any('thickness_field = "thickness" is not used' in s for s in said), said


def test_a_polygon_across_a_ridge_has_no_up_slope_axis(tmp_path):
    """Both sides of a crest: the fall lines cancel, one line says so (not an error about
    an axis the user never gave); one side of it runs."""
    x, _ = _nodes(cols=40)
    dem = _tif(tmp_path / "ridge.tif", 2200.0 - np.tan(np.radians(PSI)) * np.abs(x - X0 - 100))
    across = _polygon(tmp_path, (X0 + 80, Y0 + 50, X0 + 120, Y0 + 90))
    doc = _doc(dem, release=across)
    with pytest.raises(ValueError, match="slopes face opposite ways .* split the release"):
        _parse(doc, tmp_path)
    one_side = _polygon(tmp_path, (X0 + 110, Y0 + 50, X0 + 150, Y0 + 90), "east.gpkg")
    scn, _ = _parse(_doc(dem, release=one_side), tmp_path)
    assert scn.terrain["upslope"] == "-x"


def test_an_up_slope_axis_across_the_fall_line_is_warned_not_refused_by_rounding(tmp_path):
    """A DEM-alone window whose default up-slope axis (+x) runs across the slope: its
    mean fall line is 90 deg off the axis, warned as such (a rounding below 90 deg gave
    "the DEM descends along +x"); one that descends along it is refused as such."""
    doc = _doc(_plane(tmp_path), origin=[X0 + 20, Y0 + 40])
    doc["setup"].update(length=40.0, width=40.0, start=[10.0, 10.0])
    _, said = _parse(doc, tmp_path)
    assert any(
        re.match(r'terrain.upslope = "\+x": the mean fall line is -?90 deg', m) for m in said
    )
    doc["terrain"].update(upslope="-y", origin=[X0 + 60, Y0 + 100])
    doc["setup"]["start"] = [10.0, 20.0]
    with pytest.raises(ValueError, match=r'upslope = "-y": the terrain descends along this axis'):
        _parse(doc, tmp_path)


def test_a_window_partly_off_the_dem_is_said(tmp_path):
    """Without a polygon the window's cells off the DEM hold no snow: said, with the
    share and the DEM's extent, instead of a silently smaller domain."""
    doc = _doc(_plane(tmp_path), origin=[X0 + 30, Y0 + 40], upslope="+y")
    # the window's y axis is the map's -x: 12.5 m of its 40 m width lie off the DEM
    doc["setup"].update(length=50.0, width=40.0, start=[10.0, 10.0])
    scn, said = _parse(doc, tmp_path)
    off = [s for s in said if "of the window lies off the DEM" in s]
    assert off and off[0].startswith("terrain.origin, setup.length, setup.width: 31 %"), said
    doc["terrain"]["origin"] = [X0 + 50, Y0 + 40]  # wholly on it: nothing said
    _, said = _parse(doc, tmp_path)
    assert not any("lies off the DEM" in s for s in said), said


def test_a_slab_thinner_than_the_minimum_is_named(tmp_path):
    dem = _plane(tmp_path)
    rel = _polygon(tmp_path, (X0 + 30, Y0 + 60, X0 + 70, Y0 + 100), thickness=0.02)
    doc = _doc(dem, release=rel, thickness_field="thickness")
    del doc["params"]["thickness"]
    with pytest.raises(ValueError, match=r"at most 0.02 m thick .* below snow.min_thickness"):
        _parse(doc, tmp_path)
