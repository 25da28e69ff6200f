"""Terrain: generic slopes, slope and aspect, DEM round trips and bilinear resampling."""

from __future__ import annotations

import math
import sys

import jax
import numpy as np
import pytest

from damjax import terrain
from damjax.terrain import Terrain


def _plane(a: float = 0.2, b: float = -0.1, c: float = 3.0, dx=2.0, dy=1.5) -> Terrain:
    """z = c + a x + b y on a 6 x 5 grid with an offset origin."""
    x = 100.0 + dx * np.arange(6)
    y = 200.0 + dy * np.arange(5)
    return Terrain(x, y, c + a * x[:, None] + b * y[None, :])


@pytest.mark.parametrize("width", [60.0, 100.0])
def test_generic_slope_shape_and_angles(width):
    ter = terrain.generic_slope(length=50.0, width=width, dx=0.5)
    assert ter.y[-1] == width and ter.dx == 0.5
    psi = ter.slope_deg()
    assert psi.max() == pytest.approx(35.0, abs=0.05)  # the concave toe reaches 35 deg
    np.testing.assert_allclose(psi, np.broadcast_to(psi[:, :1], psi.shape), atol=1e-9)
    profile = psi[:, 0]
    assert profile[0] < 31.0 and profile[-1] < 22.0  # flatter at the toe and at the top
    s = terrain.surface_distance(ter, (0.0, 0.0), (ter.x[-1], 0.0))[-1]
    assert 49.0 < s <= 50.0  # length is along the surface; the last node is < dx below
    top = ter.x > ter.x[-1] - 7.0  # the 10 m roll spans ~8 m horizontally
    assert np.all(np.diff(profile[top]) < 0)  # convex roll: the angle falls to the top
    toe = ter.x < 7.0
    assert np.all(np.diff(profile[toe]) > 0)  # concave toe: it rises
    # the aspect of a slope rising along +x (east) faces west
    np.testing.assert_allclose(ter.aspect_deg()[1:-1, 1:-1], 270.0, atol=1e-6)


def test_generic_slope_angle_profile_and_pst_roll():
    psi = terrain.generic_slope_angle(np.array([0.0, 5.0, 10.0, 25.0, 40.0, 45.0, 50.0]))
    # 30 deg at the toe, 35 deg from 10 m to 40 m, 20 deg at the top; half-cosine ramps
    np.testing.assert_allclose(psi, [30.0, 32.5, 35.0, 35.0, 35.0, 27.5, 20.0], atol=1e-5)
    old = terrain.generic_slope_angle(15.0, toe_slope_deg=10.0, toe_length=15.0)
    assert float(old) == pytest.approx(35.0)
    horizontal = terrain.generic_slope(along_surface=False, dx=1.0, width=2.0)
    assert horizontal.x[-1] == 50.0
    assert horizontal.slope_deg().max() == pytest.approx(35.0, abs=0.05)
    pst = terrain.pst_slope_angle(np.array([0.0, 35.0, 42.5, 50.0, 100.0]))
    np.testing.assert_allclose(pst, [35.0, 35.0, 27.5, 20.0, 20.0], atol=1e-5)
    g = jax.grad(lambda r: terrain.pst_slope_angle(45.0, roll_start=r))(35.0)
    assert np.isfinite(float(g)) and float(g) > 0  # a later roll leaves x = 45 m steeper


def test_slope_aspect_and_surface_distance_on_planes():
    ter = _plane(a=0.2, b=-0.1)
    np.testing.assert_allclose(ter.slope_deg(), np.degrees(np.arctan(np.hypot(0.2, 0.1))))
    gx, gy = ter.gradient()
    np.testing.assert_allclose(gx, 0.2)
    np.testing.assert_allclose(gy, -0.1)
    # descent direction (-0.2, +0.1): west-north-west, clockwise from north
    np.testing.assert_allclose(ter.aspect_deg(), np.degrees(np.arctan2(-0.2, 0.1)) % 360.0)
    north_facing = _plane(a=0.0, b=-0.3)  # falls towards +y
    aspect = np.radians(north_facing.aspect_deg())  # 0 deg, i.e. 360 up to rounding
    np.testing.assert_allclose(np.cos(aspect), 1.0, atol=1e-12)
    assert np.all(np.isnan(_plane(a=0.0, b=0.0).aspect_deg()))
    s = terrain.surface_distance(ter, (100.0, 200.0), (110.0, 200.0), num=3)
    np.testing.assert_allclose(s, [0.0, 5.0 * np.hypot(1, 0.2), 10.0 * np.hypot(1, 0.2)])


def test_resampling_is_exact_on_a_linear_field():
    ter = _plane()
    fine = ter.regrid(0.37, 0.29)
    assert fine.x[0] == ter.x[0] and fine.x[-1] <= ter.x[-1]
    expect = 3.0 + 0.2 * fine.x[:, None] - 0.1 * fine.y[None, :]
    np.testing.assert_allclose(fine.z, expect, rtol=0, atol=1e-12)
    pts = ter.sample([100.0, 103.3, 110.0], [200.0, 204.1, 206.0])
    np.testing.assert_allclose(
        pts,
        3.0 + 0.2 * np.array([100, 103.3, 110]) - 0.1 * np.array([200.0, 204.1, 206.0]),
        atol=1e-12,
    )
    with pytest.raises(ValueError, match="leaves the terrain's x range"):
        ter.sample(99.0, 201.0)
    with pytest.raises(ValueError, match="regularly spaced"):
        Terrain([0.0, 1.0, 3.0], [0.0, 1.0], np.zeros((3, 2)))


def test_esri_ascii_round_trip(tmp_path):
    ter = _plane()
    z = ter.z.copy()
    z[2, 3] = np.nan
    ter = Terrain(ter.x, ter.y, z)
    path = tmp_path / "dem.asc"
    terrain.save_esri_ascii(ter, path)  # non-square cells: GDAL's dx/dy
    back = terrain.load_dem(path)
    np.testing.assert_allclose(back.x, ter.x, atol=1e-12)
    np.testing.assert_allclose(back.y, ter.y, atol=1e-12)
    np.testing.assert_allclose(back.z, ter.z, atol=1e-6, equal_nan=True)


def test_esri_ascii_orientation_and_errors(tmp_path):
    path = tmp_path / "hand.asc"
    path.write_text(
        "ncols 3\nnrows 2\nxllcorner 100\nyllcorner 200\ncellsize 10\nNODATA_value -9999\n"
        "1 2 3\n4 5 -9999\n"
    )
    ter = terrain.load_esri_ascii(path)
    np.testing.assert_array_equal(ter.x, [105.0, 115.0, 125.0])  # nodes at cell centres
    np.testing.assert_array_equal(ter.y, [205.0, 215.0])
    np.testing.assert_array_equal(ter.z[:, 1], [1.0, 2.0, 3.0])  # first row is north
    np.testing.assert_array_equal(ter.z[:2, 0], [4.0, 5.0])
    assert np.isnan(ter.z[2, 0])
    path.write_text("ncols 3\nnrows 2\nxllcenter 0\nyllcenter 0\ncellsize 1\n1 2 3\n4 5\n")
    with pytest.raises(ValueError, match="5 elevation values, the header says 2 x 3"):
        terrain.load_esri_ascii(path)


def test_netcdf_round_trip_and_coordinate_detection(tmp_path):
    xr = pytest.importorskip("xarray")
    ter = _plane()
    path = tmp_path / "dem.nc"
    terrain.save_netcdf(ter, path, variable="elevation")
    back = terrain.load_dem(path)
    np.testing.assert_array_equal(back.x, ter.x)
    np.testing.assert_array_equal(back.y, ter.y)
    np.testing.assert_array_equal(back.z, ter.z)
    # north-up (descending y), other names, an extra variable and a band dimension
    ds = xr.Dataset(
        {
            "band_data": (("band", "northing", "easting"), ter.z.T[None, ::-1, :]),
            "mask": (("northing",), np.ones(ter.y.size)),
        },
        coords={"easting": ter.x, "northing": ter.y[::-1], "band": [1]},
    )
    other = tmp_path / "north_up.nc"
    ds.to_netcdf(other, engine="h5netcdf")
    back = terrain.load_netcdf(other)
    np.testing.assert_array_equal(back.y, ter.y)
    np.testing.assert_array_equal(back.z, ter.z)
    geo = tmp_path / "geo.nc"
    xr.Dataset({"z": (("lat", "lon"), ter.z.T)}, coords={"lat": ter.y, "lon": ter.x}).to_netcdf(
        geo, engine="h5netcdf"
    )
    with pytest.raises(ValueError, match="geographic"):
        terrain.load_netcdf(geo)


def test_geotiff_needs_rasterio(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rasterio", None)  # as if it were not installed
    with pytest.raises(ImportError, match="pip install"):
        terrain.load_dem(tmp_path / "dem.tif")


def test_geotiff_round_trip(tmp_path):
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import Affine

    ter = _plane(dx=2.0, dy=2.0)
    path = tmp_path / "dem.tif"
    # north-up: origin at the north-west corner, rows run south; a metric CRS (UTM 32N)
    transform = Affine(2.0, 0.0, ter.x[0] - 1.0, 0.0, -2.0, ter.y[-1] + 1.0)
    profile = dict(
        driver="GTiff",
        width=ter.x.size,
        height=ter.y.size,
        count=1,
        dtype="float64",
        transform=transform,
        crs="EPSG:32632",
        nodata=-9999.0,
    )
    z = ter.z.copy()
    z[1, 2] = np.nan
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(np.where(np.isnan(z), -9999.0, z).T[::-1, :], 1)
    back = terrain.load_dem(path)
    np.testing.assert_allclose(back.x, ter.x)
    np.testing.assert_allclose(back.y, ter.y)
    np.testing.assert_allclose(back.z, z, equal_nan=True)  # nodata -> NaN
    with rasterio.open(path, "w", **(profile | {"crs": "EPSG:4326"})) as dst:
        dst.write(ter.z.T, 1)
    with pytest.raises(ValueError, match="geographic CRS"):
        terrain.load_geotiff(path)


def test_generic_profile_must_fit_its_length():
    """toe + roll longer than the slope used to give an overlapping profile silently."""
    with pytest.raises(ValueError, match="must be at most length = 15 m"):
        terrain.generic_slope_angle(np.linspace(0.0, 15.0, 7), length=15.0)
    with pytest.raises(ValueError, match="length = nan: must be in"):
        terrain.generic_slope(length=math.nan)
    # toe + roll = length: the toe runs straight into the roll
    psi = terrain.generic_slope_angle(np.array([0.0, 10.0, 20.0]), length=20.0)
    np.testing.assert_allclose(psi, [30.0, 35.0, 20.0], atol=1e-5)
