"""Strength maps on a regular grid: reading (CSV, NetCDF, GeoTIFF), interpolation onto a
simulation grid (`map_on_grid`) and transects along a line (`transect`) [Pa, m]."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from jax.typing import ArrayLike

from damjax.fields.tables import _check_nonnegative, _read_csv


def load_strength_map(
    path: str | os.PathLike, **kwargs
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a strength map on a regular grid: CSV (columns x_m, y_m, tau_peak_pa), NetCDF
    (.nc) or GeoTIFF (.tif, needs rasterio), chosen by the suffix.

    NetCDF and GeoTIFF go through the DEM readers (`damjax.terrain.load_netcdf`,
    `damjax.terrain.load_geotiff`, same conventions: metric coordinates, north-up rasters,
    nodata as NaN); keyword arguments go to them (``variable=``, ``band=``). The values
    are tau_p [Pa].

    Rows may come in any order but must fill a complete grid, each node once; tau_peak_pa
    must be >= 0. Errors are one-line ValueErrors naming the file and line.

    Returns:
        ``(x, y, tau)``: node coordinates x (nx,) and y (ny,) [m], ascending, and tau_p
        (nx, ny) [Pa], indexed ``[ix, iy]``.
    """
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    if suffix in (".nc", ".nc4", ".cdf", ".netcdf", ".tif", ".tiff", ".gtiff"):
        from damjax import terrain

        ter = terrain.load_dem(path, **kwargs)
        if np.any(ter.z[np.isfinite(ter.z)] < 0):
            raise ValueError(f"{os.fspath(path)}: negative strength values")
        return ter.x, ter.y, ter.z
    names = ("x_m", "y_m", "tau_peak_pa")
    cols, linenos, index = _read_csv(path, names)
    if cols["x_m"].size == 0:
        raise ValueError(f"{os.fspath(path)}: no data rows (a header alone)")
    _check_nonnegative(path, cols, ("tau_peak_pa",), linenos, index)
    xs, ix = np.unique(cols["x_m"], return_inverse=True)
    ys, iy = np.unique(cols["y_m"], return_inverse=True)
    tau = np.full((xs.size, ys.size), np.nan)
    seen = np.full((xs.size, ys.size), -1)
    for r, (i, j) in enumerate(zip(ix, iy, strict=True)):
        if seen[i, j] >= 0:
            raise ValueError(
                f"{os.fspath(path)}:{linenos[r]}: duplicate node ({xs[i]:g}, {ys[j]:g}) "
                f"(also on line {linenos[seen[i, j]]})"
            )
        seen[i, j] = r
        tau[i, j] = cols["tau_peak_pa"][r]
    if np.any(seen < 0):
        i, j = np.argwhere(seen < 0)[0]
        raise ValueError(
            f"{os.fspath(path)}: node ({xs[i]:g}, {ys[j]:g}) is missing; the map must fill a "
            f"{xs.size} x {ys.size} grid"
        )
    for name, v in (("x_m", xs), ("y_m", ys)):
        d = np.diff(v)
        if d.size and np.ptp(d) > 1e-6 * max(float(np.max(np.abs(v))), 1.0):
            raise ValueError(
                f"{os.fspath(path)}: column '{name}' is not evenly spaced (steps "
                f"{float(d.min()):g} to {float(d.max()):g} m); the map must be a regular grid"
            )
    return xs, ys, tau


def map_on_grid(
    x: ArrayLike, y: ArrayLike, tau: ArrayLike, xq: ArrayLike, yq: ArrayLike
) -> np.ndarray:
    """A strength map (nodes x (nx,), y (ny,) [m], tau (nx, ny) [Pa]) on another grid.

    Bilinear interpolation at the nodes ``xq`` (mx,), ``yq`` (my,) [m] (e.g. the cell
    centres of a slope run, `damjax.simulate_slope`'s ``tau_peak``);
    points beyond the map take the value of its nearest edge (constant extrapolation).

    Returns:
        tau_p (mx, my) [Pa].
    """
    from damjax.terrain import Terrain

    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    xq = np.clip(np.asarray(xq, dtype=float), x[0], x[-1])
    yq = np.clip(np.asarray(yq, dtype=float), y[0], y[-1])
    # sample, not resample: clipped query nodes repeat, so they are no regular grid
    xx, yy = np.meshgrid(xq, yq, indexing="ij")
    return Terrain(x, y, np.asarray(tau, dtype=float)).sample(xx, yy)


def transect(
    x: ArrayLike,
    y: ArrayLike,
    tau: ArrayLike,
    start: Sequence[float],
    end: Sequence[float],
    num: int = 101,
) -> tuple[np.ndarray, np.ndarray]:
    """Sample a strength map along the straight line from ``start`` to ``end`` (x, y) [m].

    For a slope-parallel transect pass points of equal y. The result feeds
    `fit_linear_profile` / `fit_power_law_profile` (the paper's in-situ gradients).

    Returns:
        ``(s, tau)``: distance from ``start`` (num,) [m] and bilinear tau_p (num,) [Pa].
    """
    from damjax.terrain import Terrain

    t = np.linspace(0.0, 1.0, int(num))
    px = start[0] + t * (end[0] - start[0])
    py = start[1] + t * (end[1] - start[1])
    ter = Terrain(np.asarray(x, float), np.asarray(y, float), np.asarray(tau, float))
    return t * float(np.hypot(end[0] - start[0], end[1] - start[1])), ter.sample(px, py)
