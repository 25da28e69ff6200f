"""Snow cover from the terrain: where a slab lies and how thick it is.

A slope run's slab need not be a uniform sheet over every cell (`damjax.simulate_slope`'s
``thickness`` and ``cover``). This module turns terrain and snow data into those maps:

- `slope_correction`: the Swiss guidelines' slope factor of the release thickness
  (Salm, Burkard and Gubler 1990): d0 = d0* f(psi), f(psi) = 0.291 / (sin psi - 0.202
  cos psi), d0* the depth on flat ground; 1.00 at 28 deg, 0.71 at 35, 0.52 at 45, 0.41 at 55.
- `depth_to_thickness`: a measured vertical snow depth HS (a depth map from lidar or
  photogrammetry) as the slab thickness normal to the slope, HS cos psi.
- `cover`: the cells that hold a slab: not steeper than a limit (default 60 deg: the
  upper cut of release-area methods, Veitinger et al. 2016 and its open successors), not
  under a mask (forest, rock), not thinner than a minimum, with terrain data.
- `start_zone`: the snow-covered cells in the slope band of potential release areas (28-60
  deg), where a run without a release polygon places its random triggers.
- `sample_raster`: a raster (snow depth, mask; GeoTIFF, ESRI ASCII, NetCDF) at map points.
- `polygon_mask`: a polygon layer (forest, rock; shapefile, GeoPackage, GeoJSON) at map
  points: which lie inside a polygon.

Sources and numbers: docs/guide/real-path.md ("Snow cover and weak layer on terrain").
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

# the Swiss guidelines' slope factor (Salm, Burkard and Gubler 1990)
SLOPE_FACTOR_A = 0.291
SLOPE_FACTOR_B = 0.202
SLOPE_FACTOR_FROM_DEG = 28.0  # f = 1 here; the formula is meant for release slopes above

# defaults of the snow cover (scenario table [snow])
MAX_SLOPE_DEG = 60.0  # no slab steeper than this (Veitinger et al. 2016: 28 / 60 deg cuts)
START_MIN_SLOPE_DEG = 28.0  # lower edge of the start zone (SLF 28-30, Veitinger 28 deg)
MIN_THICKNESS = 0.1  # [m] thinner cover holds no slab (our choice, not from a source)


def slope_correction(slope_deg: Any) -> np.ndarray:
    """The slope factor f(psi) = 0.291 / (sin psi - 0.202 cos psi) of the Swiss
    guidelines (Salm, Burkard and Gubler 1990): the release thickness on a slope of
    angle psi is the flat-ground depth d0* times f(psi).

    The formula is meant for release slopes (28 deg and steeper) and diverges at 11.4 deg:
    below 28 deg, where it gives 1.00, f is held at its 28 deg value (no thickening on
    gentle ground). f(35) = 0.71, f(45) = 0.52, f(55) = 0.41, f(60) = 0.38.
    """
    psi = np.radians(np.maximum(np.asarray(slope_deg, dtype=float), SLOPE_FACTOR_FROM_DEG))
    return SLOPE_FACTOR_A / (np.sin(psi) - SLOPE_FACTOR_B * np.cos(psi))


def depth_to_thickness(depth: Any, slope_deg: Any) -> np.ndarray:
    """Slab thickness normal to the slope [m] from a vertical snow depth HS [m]:
    HS cos(psi) (a depth map measures along the vertical)."""
    return np.asarray(depth, dtype=float) * np.cos(np.radians(np.asarray(slope_deg, float)))


def cover(
    slope_deg: np.ndarray,
    *,
    max_slope_deg: float = MAX_SLOPE_DEG,
    mask: np.ndarray | None = None,
    thickness: np.ndarray | None = None,
    min_thickness: float = MIN_THICKNESS,
) -> np.ndarray:
    """(nx, ny) bool: the cells that hold a slab. Not where the slope is NaN (no terrain
    data) or steeper than ``max_slope_deg``, where ``mask`` is True (no snow: forest,
    rock), or where ``thickness`` [m] is NaN or below ``min_thickness``."""
    psi = np.asarray(slope_deg, dtype=float)
    out = np.isfinite(psi) & (psi <= max_slope_deg)
    if mask is not None:
        out &= ~np.asarray(mask, bool)
    if thickness is not None:
        h = np.asarray(thickness, dtype=float)
        out &= np.isfinite(h) & (h >= min_thickness)
    return out


def start_zone(
    slope_deg: np.ndarray,
    snow: np.ndarray,
    *,
    min_slope_deg: float = START_MIN_SLOPE_DEG,
    max_slope_deg: float = MAX_SLOPE_DEG,
) -> np.ndarray:
    """(nx, ny) bool: snow-covered cells with min_slope_deg <= psi <= max_slope_deg (the
    slope band of potential release areas, Veitinger et al. 2016; Buehler et al. 2018)."""
    psi = np.asarray(slope_deg, dtype=float)
    with np.errstate(invalid="ignore"):
        band = (psi >= min_slope_deg) & (psi <= max_slope_deg)
    return np.asarray(snow, bool) & band


def fill_from_nearest(values: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """``values`` with every cell outside ``keep`` set to the value of the nearest cell in
    ``keep`` (cells without snow still enter the bilinear interpolation of the particles
    beside them, so they get their neighbours' values, never NaN)."""
    from scipy import ndimage

    keep = np.asarray(keep, bool)
    a = np.asarray(values, dtype=float)
    if keep.all() or not keep.any():
        return a.copy()
    _, (ii, jj) = ndimage.distance_transform_edt(~keep, return_indices=True)
    return a[ii, jj]


def sample_raster(
    file: Any, px: np.ndarray, py: np.ndarray, *, nearest: bool = False
) -> np.ndarray:
    """Values of a raster (a file in `damjax.terrain.load_dem`'s formats: GeoTIFF, ESRI
    ASCII, NetCDF; or a loaded `damjax.terrain.Terrain`) at map points px, py [m], in the
    raster's own coordinates (its CRS must be the DEM's). Bilinear, or the nearest pixel
    (``nearest``: masks); NaN at nodata and outside the raster (`raster_covers`)."""
    from damjax.terrain import load_dem

    r = load_dem(file) if isinstance(file, (str, os.PathLike)) else file
    px, py = np.broadcast_arrays(np.asarray(px, float), np.asarray(py, float))
    inside = raster_covers(r, px, py)
    qx = np.clip(px, r.x[0], r.x[-1])
    qy = np.clip(py, r.y[0], r.y[-1])
    if nearest:
        i = np.clip(np.rint((qx - r.x[0]) / r.dx).astype(int), 0, r.x.size - 1)
        j = np.clip(np.rint((qy - r.y[0]) / r.dy).astype(int), 0, r.y.size - 1)
        v = r.z[i, j]
    else:
        v = r.sample(qx, qy)
    return np.where(inside, v, math.nan)


# the vector formats a mask may come as (anything else is read as a raster)
POLYGON_SUFFIXES = (".shp", ".gpkg", ".geojson", ".json", ".fgb")


def polygon_mask(
    file: str | os.PathLike, px: np.ndarray, py: np.ndarray, *, key: str = "snow.mask"
) -> tuple[np.ndarray, str | None, tuple[float, float, float, float]]:
    """Which map points px, py [m] lie inside a polygon of a vector layer (a forest or
    rock layer as GIS data holds it: .shp, .gpkg, .geojson; points and lines are ignored,
    the polygons of geometry collections kept, invalid polygons repaired), the layer's CRS
    as WKT (None: it names none) and the polygons' bounds (xmin, ymin, xmax, ymax) [m].
    Unlike a raster mask the layer need not cover the domain: outside its polygons is
    snow.

    Raises:
        ValueError: no such file, unreadable, or no polygon in it (naming ``key``).
    """
    try:
        import geopandas as gpd
        import shapely
    except ImportError:  # pragma: no cover
        raise ValueError(f"{key}: a polygon mask needs geopandas and shapely") from None
    name = repr(os.path.basename(str(file)))
    if os.path.isdir(file):
        raise ValueError(
            f"{key} = {name}: is a folder; give the layer's file (.shp, .gpkg, .geojson)"
        )
    if not os.path.isfile(file):
        raise ValueError(f"{key} = {name}: no such file")
    base, ext = os.path.splitext(str(file))
    if ext.lower() == ".shp" and not any(os.path.isfile(base + e) for e in (".shx", ".SHX")):
        raise ValueError(
            f"{key} = {name}: its index file {os.path.basename(base)}.shx is missing beside "
            "it (a shapefile is the .shp with its .shx, .dbf and .prj)"
        )
    try:
        gdf = gpd.read_file(file)
    except Exception as exc:  # noqa: BLE001 (any reader failure is the file's problem)
        # GDAL's own advice (a driver prefix, a config option) does not apply to a key
        msg = " ".join(str(exc).split()).split("; It might help")[0]
        raise ValueError(f"{key} = {name}: not a polygon layer GDAL can read ({msg})") from None
    parts = shapely.get_parts(np.asarray([g for g in gdf.geometry if g is not None]))
    while parts.size and np.any(shapely.get_num_geometries(parts) > 1):  # nested
        parts = shapely.get_parts(parts)
    polys = [g for g in parts if g.geom_type == "Polygon" and not g.is_empty]
    if not polys:
        raise ValueError(
            f"{key} = {name}: holds no polygon (a mask layer of polygons: forest, rock)"
        )
    try:
        # a self-intersecting polygon (a bow tie) is repaired, as GIS tools do
        geom = shapely.union_all(shapely.make_valid(np.asarray(polys)))
    except shapely.errors.GEOSException as exc:
        raise ValueError(f"{key} = {name}: its polygons cannot be merged ({exc})") from None
    shapely.prepare(geom)
    px, py = np.broadcast_arrays(np.asarray(px, float), np.asarray(py, float))
    # a point on a polygon's boundary counts as inside, as a rasterised cell would
    inside = np.asarray(shapely.intersects_xy(geom, px, py), bool)
    crs = gdf.crs.to_wkt() if gdf.crs is not None else None
    return inside, crs, tuple(float(b) for b in geom.bounds)


def raster_covers(r: Any, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """Which map points px, py [m] lie within a loaded raster's pixels (a
    `damjax.terrain.Terrain`: its nodes are the pixel centres)."""
    px, py = np.broadcast_arrays(np.asarray(px, float), np.asarray(py, float))
    return (
        (px >= r.x[0] - 0.5 * r.dx)
        & (px <= r.x[-1] + 0.5 * r.dx)
        & (py >= r.y[0] - 0.5 * r.dy)
        & (py <= r.y[-1] + 0.5 * r.dy)
    )
