"""Strength maps: NetCDF loading, interpolation onto a simulation grid, transects."""

import numpy as np
import pytest

from damjax import fields, terrain


def _linear_map():
    x = np.arange(0.0, 50.0, 2.0)
    y = np.arange(0.0, 60.0, 2.0)
    tau = 1000.0 + 20.0 * x[:, None] + 3.0 * y[None, :]
    return x, y, tau


def test_netcdf_strength_map_round_trip(tmp_path):
    x, y, tau = _linear_map()
    path = tmp_path / "map.nc"
    terrain.save_netcdf(terrain.Terrain(x, y, tau), path, variable="tau_peak")
    x2, y2, tau2 = fields.load_strength_map(path)
    np.testing.assert_allclose(x2, x)
    np.testing.assert_allclose(y2, y)
    np.testing.assert_allclose(tau2, tau)


def test_map_on_grid_is_exact_for_linear_maps_and_clamps_outside():
    x, y, tau = _linear_map()
    xq = (np.arange(50) + 0.5) * 0.9
    yq = (np.arange(40) + 0.5) * 1.3
    got = fields.map_on_grid(x, y, tau, xq, yq)
    xc, yc = np.clip(xq, x[0], x[-1]), np.clip(yq, y[0], y[-1])
    np.testing.assert_allclose(got, 1000.0 + 20.0 * xc[:, None] + 3.0 * yc[None, :], rtol=1e-12)


def test_transect_feeds_the_linear_fit():
    x, y, tau = _linear_map()
    s, t = fields.transect(x, y, tau, (4.0, 30.0), (44.0, 30.0), num=41)
    assert s[-1] == pytest.approx(40.0)
    fit = fields.fit_linear_profile(s, t)
    assert fit.theta == pytest.approx(20.0, rel=1e-9)


def test_shipped_synthetic_map_transect_gradient():
    x, y, tau = fields.load_strength_map(
        __import__("damjax.data", fromlist=["x"]).synthetic_strength_map_path()
    )
    s, t = fields.transect(x, y, tau, (0.0, 30.0), (48.0, 30.0), num=49)
    fit = fields.fit_linear_profile(s, t)
    # one sample of a 100 Pa, 8 m field: the fitted gradient is the 20 Pa/m trend +- noise
    assert 10.0 < fit.theta < 30.0


def test_geotiff_strength_map_round_trip(tmp_path):
    """A north-up GeoTIFF strength map loads as (x, y, tau) with tau[i, j] at (x_i, y_j)."""
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import Affine

    x = np.arange(20) + 0.5
    y = np.arange(10) + 0.5
    tau = 1000.0 + 20.0 * x[:, None] - 3.0 * y[None, :]
    path = tmp_path / "tau.tif"
    profile = dict(
        driver="GTiff", width=x.size, height=y.size, count=1, dtype="float64",
        transform=Affine(1.0, 0.0, 0.0, 0.0, -1.0, 10.0), crs="EPSG:32632",
    )  # fmt: skip
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(tau.T[::-1, :], 1)  # rows run south
    mx, my, mtau = fields.load_strength_map(path)
    np.testing.assert_allclose(mx, x)
    np.testing.assert_allclose(my, y)
    np.testing.assert_allclose(mtau, tau)
