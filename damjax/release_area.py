"""A documented release-area polygon on a DEM as a slope run's domain.

A release area (a polygon file: shapefile, GeoJSON, GeoPackage; one or more polygons) on a
DEM becomes the rectangle a slope run simulates: its x axis points up-slope along one DEM
axis (the one closest to the mean up-slope direction over the polygon, or the one given),
its y axis 90 deg counter-clockwise from it, and the rectangle spans the polygon plus a
buffer [m] on every side, clipped to the DEM; the domain is the terrain within the buffer
(`ReleaseArea.domain_mask`; without a buffer: the whole rectangle of the polygon plus a
margin, as in earlier versions). The DEM's CRS is kept: the polygon's CRS must be the DEM's (no
reprojection; a mismatch is an error naming both). The slab thickness is the polygon's
thickness attribute (AvaFrame's ``thickness`` convention; several polygons must agree), and
the crack starts at the weakest spot of the weak layer inside the polygon.

`read_release_area` reads and checks; `ReleaseArea.mask` rasterises the polygon on the run's
cell grid; `ReleaseArea.to_map` maps release-area coordinates to the DEM's;
`compare_release` gives area ratio, overlap and crown position of a released map against
the polygon.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

_AXES = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}
_PROFILE_STEP = 0.05  # [m] map spacing of the centre-line surface profile (as dem_fields)


class ReleaseAreaError(ValueError):
    """A one-line problem with a release-area polygon, naming the scenario key."""


@dataclasses.dataclass(frozen=True)
class ReleaseArea:
    """A release-area polygon placed on a DEM.

    Attributes:
        geometry: the polygon(s) in map coordinates (a shapely geometry, the DEM's CRS).
        thickness: slab thickness from the polygon's attribute [m] (None: no attribute).
        crs: the CRS (WKT or authority string; None when neither file names one).
        upslope: the DEM axis the release area's x points along ("+x", "-x", "+y", "-y").
        origin: map coordinates of the rectangle's (0, 0) corner (down-slope, on the
            right looking up-slope) [m].
        length: up-slope extent of the rectangle along the surface [m].
        width: cross-slope extent of the rectangle [m] (a map distance).
        margin: margin around the polygon [m] (the buffer, where one is given).
        profile_a: map distances along the centre line [m] (for `to_map`).
        profile_s: surface distances at profile_a [m].
        buffer: with a buffer [m], the run's domain is the terrain within this map
            distance of the polygon (`domain_mask`), the rectangle around it clipped to
            the DEM; None: the rectangle of the polygon plus ``margin`` (earlier versions).
    """

    geometry: Any
    thickness: float | None
    crs: str | None
    upslope: str
    origin: tuple[float, float]
    length: float
    width: float
    margin: float
    profile_a: np.ndarray
    profile_s: np.ndarray
    buffer: float | None = None

    def to_map(self, x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
        """Map coordinates of release-area points (x up-slope along the surface, y across)
        [m], broadcast together."""
        u = np.array(_AXES[self.upslope])
        v = np.array([-u[1], u[0]])
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        a = np.interp(x, self.profile_s, self.profile_a)
        return self.origin[0] + u[0] * a + v[0] * y, self.origin[1] + u[1] * a + v[1] * y

    def mask(self, x: np.ndarray, y: np.ndarray, buffer: float = 0.0) -> np.ndarray:
        """(nx, ny) bool: cell centres x (nx,), y (ny,) [m] inside the polygon (shrunk by
        ``buffer`` [m] when > 0)."""
        import shapely

        px, py = self.to_map(np.asarray(x)[:, None], np.asarray(y)[None, :])
        geom = self.geometry.buffer(-buffer) if buffer > 0 else self.geometry
        return np.asarray(shapely.contains_xy(geom, px, py))

    def domain_mask(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """(nx, ny) bool: cell centres within ``buffer`` [m] (map distance) of the polygon;
        every cell of the rectangle when there is no buffer."""
        import shapely

        if self.buffer is None:
            return np.ones((np.size(x), np.size(y)), bool)
        px, py = self.to_map(np.asarray(x)[:, None], np.asarray(y)[None, :])
        geom = shapely.buffer(self.geometry, self.buffer, quad_segs=16)
        shapely.prepare(geom)
        return np.asarray(shapely.contains_xy(geom, px, py))


def dem_crs(dem_file: str | os.PathLike) -> str | None:
    """The DEM's CRS as WKT: the GeoTIFF's own, or the ``.prj`` beside an ``.asc`` / ``.nc``
    (None when there is none)."""
    path = Path(dem_file)
    if path.suffix.lower() in (".tif", ".tiff"):
        import rasterio

        with rasterio.open(path) as src:
            return src.crs.to_wkt() if src.crs is not None else None
    prj = path.with_suffix(".prj")
    return prj.read_text().strip() if prj.is_file() else None


def _same_crs(a: str, b: str) -> bool:
    import pyproj

    ca, cb = pyproj.CRS.from_user_input(a), pyproj.CRS.from_user_input(b)
    if ca == cb or ca.equals(cb, ignore_axis_order=True):
        return True
    ea, eb = ca.to_epsg(min_confidence=70), cb.to_epsg(min_confidence=70)
    if ea is not None and ea == eb:
        return True

    def proj4(c: Any) -> set[str]:  # the projection's terms (an ESRI .prj drops TOWGS84)
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            text = c.to_proj4()
        return {t for t in text.split() if not t.startswith(("+towgs84", "+no_defs"))}

    return ca.name.replace("_", " ") == cb.name.replace("_", " ") and proj4(ca) == proj4(cb)


def read_release_area(
    file: str | os.PathLike,
    terrain: Any,
    dem_file: str | os.PathLike | None = None,
    margin: float = 10.0,
    upslope: str | None = None,
    thickness_field: str = "thickness",
    key: str = "terrain.release",
    buffer: float | None = None,
) -> ReleaseArea:
    """Read a release-area polygon and place it on a DEM.

    Args:
        file: the polygon file (anything geopandas reads: .shp, .geojson, .gpkg).
        terrain: the DEM (`damjax.terrain.Terrain`, map coordinates [m]).
        dem_file: the DEM's file, for its CRS (None: not checked).
        margin: margin around the polygon [m], >= 0.
        upslope: DEM axis pointing up-slope; None: the one closest to the mean up-slope
            direction over the polygon.
        thickness_field: the attribute holding the slab thickness [m] ("": not read).
        key: the scenario key named in errors.
        buffer: the domain is the terrain within this distance [m] of the polygon
            (`ReleaseArea.domain_mask`), in the rectangle of the polygon plus ``buffer``
            clipped to the DEM (``margin`` is not used); None: the rectangle of the
            polygon plus ``margin``, which must lie on the DEM.

    Raises:
        ReleaseAreaError: unreadable file, no polygon, a CRS mismatch, a polygon (plus
            margin) leaving the DEM or over nodata, or a bad thickness attribute.
    """
    try:
        import geopandas as gpd
        import shapely
    except ImportError:  # pragma: no cover
        raise ReleaseAreaError(f"{key}: reading polygons needs geopandas and shapely") from None
    path = Path(file)
    if not path.is_file():
        raise ReleaseAreaError(f"{key} = {str(file)!r}: no such file")
    try:
        gdf = gpd.read_file(path)
    except Exception as exc:  # noqa: BLE001 (any reader failure is the file's problem)
        raise ReleaseAreaError(f"{key} = {path.name!r}: unreadable ({exc})") from None
    kinds = ("Polygon", "MultiPolygon")
    polys = [g for g in gdf.geometry if g is not None and g.geom_type in kinds]
    if not polys:
        raise ReleaseAreaError(f"{key} = {path.name!r}: holds no polygon")
    geom = shapely.union_all(polys)
    crs = gdf.crs.to_wkt() if gdf.crs is not None else None
    if dem_file is not None:
        dcrs = dem_crs(dem_file)
        if crs is not None and dcrs is not None and not _same_crs(crs, dcrs):
            import pyproj

            raise ReleaseAreaError(
                f"{key} = {path.name!r}: CRS {pyproj.CRS(crs).name!r} differs from the DEM's "
                f"(terrain.file, {pyproj.CRS(dcrs).name!r}); reproject one of them"
            )
        if crs is None and dcrs is not None:  # read as the DEM's: said, not silently
            import pyproj

            warnings.warn(
                f"{key} = {path.name!r}: states no CRS (no .prj); read in the DEM's "
                f"({pyproj.CRS(dcrs).name!r}): give the file its CRS if it is another",
                stacklevel=2,
            )
        crs = crs or dcrs
    thickness: float | None = None
    if thickness_field:
        if thickness_field not in gdf.columns:
            cols = ", ".join(c for c in gdf.columns if c != "geometry")
            raise ReleaseAreaError(
                f"terrain.thickness_field = {thickness_field!r}: {path.name} has no such "
                f"attribute (has: {cols}); name the thickness attribute, or give "
                "params.thickness (and no thickness_field)"
            )
        vals = np.asarray(gdf[thickness_field], dtype=float)
        if not (np.all(np.isfinite(vals)) and np.all(vals > 0)):
            raise ReleaseAreaError(
                f"terrain.thickness_field = {thickness_field!r}: {path.name} has thickness "
                f"values {vals.tolist()}: must be finite and > 0 m"
            )
        if np.ptp(vals) > 1e-9 * np.max(vals):
            raise ReleaseAreaError(
                f"terrain.thickness_field = {thickness_field!r}: {path.name} has several "
                f"thicknesses {vals.tolist()} m; damjax runs one slab thickness: give "
                "params.thickness (and no thickness_field)"
            )
        thickness = float(vals[0])
    xmin, ymin, xmax, ymax = geom.bounds
    if buffer is not None:
        margin = float(buffer)
        # the raster's own bounds, half a cell beyond its nodes, as GIS tools show them
        # (the cells there, without data on both sides, hold no snow)
        hx = 0.5 * float(terrain.x[1] - terrain.x[0]) if terrain.x.size > 1 else 0.0
        hy = 0.5 * float(terrain.y[1] - terrain.y[0]) if terrain.y.size > 1 else 0.0
        bounds = (terrain.x[0] - hx, terrain.y[0] - hy, terrain.x[-1] + hx, terrain.y[-1] + hy)
        tol = 1e-6 * max(hx, hy, 1.0)  # [m]: rounding, not a margin
        if not (
            xmin >= bounds[0] - tol
            and xmax <= bounds[2] + tol
            and ymin >= bounds[1] - tol
            and ymax <= bounds[3] + tol
        ):
            raise ReleaseAreaError(
                f"{key} = {path.name!r}: the polygon spans x [{xmin:.1f}, {xmax:.1f}], y "
                f"[{ymin:.1f}, {ymax:.1f}] m and reaches outside the DEM's x "
                f"[{bounds[0]:.1f}, {bounds[2]:.1f}], y [{bounds[1]:.1f}, "
                f"{bounds[3]:.1f}] m: the whole polygon must lie on the DEM"
            )
    inside = buffer is not None or (
        xmin - margin >= terrain.x[0]
        and xmax + margin <= terrain.x[-1]
        and ymin - margin >= terrain.y[0]
        and ymax + margin <= terrain.y[-1]
    )
    if not inside:
        raise ReleaseAreaError(
            f"{key} = {path.name!r}: the polygon plus terrain.margin = {margin:g} m spans x "
            f"[{xmin - margin:.1f}, {xmax + margin:.1f}], y [{ymin - margin:.1f}, "
            f"{ymax + margin:.1f}] m and reaches outside the DEM's x [{terrain.x[0]:.1f}, "
            f"{terrain.x[-1]:.1f}], y [{terrain.y[0]:.1f}, {terrain.y[-1]:.1f}] m: the whole "
            "polygon and its margin must lie on the DEM"
        )
    if upslope is None:
        gx, gy = terrain.gradient()
        xx, yy = np.meshgrid(terrain.x, terrain.y, indexing="ij")
        sel = np.asarray(shapely.contains_xy(geom, xx, yy))
        if not np.any(sel):
            c = geom.centroid
            sel = np.zeros_like(xx, dtype=bool)
            sel[np.argmin(np.abs(terrain.x - c.x)), np.argmin(np.abs(terrain.y - c.y))] = True
        mx, my = float(np.nanmean(gx[sel])), float(np.nanmean(gy[sel]))
        upslope = max(_AXES, key=lambda k: _AXES[k][0] * mx + _AXES[k][1] * my)
    u = np.array(_AXES[upslope])
    v = np.array([-u[1], u[0]])
    pts = np.asarray(shapely.get_coordinates(geom))
    a, b = pts @ u, pts @ v
    a0, b0 = float(a.min()) - margin, float(b.min()) - margin
    a_span = float(a.max()) - float(a.min()) + 2 * margin
    width = float(b.max()) - float(b.min()) + 2 * margin
    if buffer is not None:  # clipped to the DEM's extent
        (da0, da1), (db0, db1) = _dem_range(terrain, u), _dem_range(terrain, v)
        a1, b1 = min(float(a.max()) + margin, da1), min(float(b.max()) + margin, db1)
        a0, b0 = max(a0, da0), max(b0, db0)
        a_span, width = a1 - a0, b1 - b0
    origin = (float(u[0] * a0 + v[0] * b0), float(u[1] * a0 + v[1] * b0))
    # the surface length of the centre line over the map span
    pa = np.linspace(0.0, a_span, max(2, int(math.ceil(a_span / _PROFILE_STEP)) + 1))
    line = np.asarray(origin)[:, None] + u[:, None] * pa[None, :] + v[:, None] * (0.5 * width)
    z = terrain.sample(line[0], line[1])
    if buffer is not None and np.any(np.isfinite(z)):  # nodata on the line: bridged
        ok = np.isfinite(z)
        z = np.interp(pa, pa[ok], z[ok])
    if not np.all(np.isfinite(z)):
        raise ReleaseAreaError(f"{key} = {path.name!r}: missing DEM cells (nodata) under it")
    ps = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(pa), np.diff(z)))])
    return ReleaseArea(
        geometry=geom,
        thickness=thickness,
        crs=crs,
        upslope=upslope,
        origin=origin,
        length=float(ps[-1]) * (1 - 1e-9),
        width=width,
        margin=float(margin),
        profile_a=pa,
        profile_s=ps,
        buffer=None if buffer is None else float(buffer),
    )


def _dem_range(terrain: Any, axis: np.ndarray) -> tuple[float, float]:
    """The range of the DEM's nodes projected on a map axis (+-x or +-y) [m]."""
    c = terrain.x if axis[0] != 0 else terrain.y
    sign = axis[0] if axis[0] != 0 else axis[1]
    lo, hi = sorted((sign * float(c[0]), sign * float(c[-1])))
    return lo, hi


def weakest_inside(
    tau: np.ndarray, x: np.ndarray, y: np.ndarray, dx: float, inside: np.ndarray
) -> tuple[float, float]:
    """The weakest point of tau (box-smoothed over 2 m, as `damjax.slope.generic.weak_spot`)
    among the cells ``inside`` [m]."""
    if not np.any(inside):
        raise ReleaseAreaError("terrain.release: no cell centre of the run inside the polygon")
    smooth = smoothed_strength(tau, dx)
    if not np.any(inside & np.isfinite(smooth)):
        raise ReleaseAreaError(
            "terrain.release: every cell inside the polygon has an infinite strength (no "
            "snow there, or an unbreakable layer): no weak spot to start the crack"
        )
    i, j = np.unravel_index(np.argmin(np.where(inside, smooth, np.inf)), smooth.shape)
    return float(x[i]), float(y[j])


def smoothed_strength(tau: np.ndarray, dx: float) -> np.ndarray:
    """tau [any unit] averaged over 2 m boxes ((2k + 1) cells of ``dx`` [m] a side, the
    edges repeated), over the finite cells of each box only; inf on the cells of infinite
    strength (no snow, an unbreakable layer), which are never the weakest (a cumulative
    sum over an inf gave NaN boxes, and argmin took the first of them). Where every cell
    is finite, the plain box mean."""
    from damjax import fields

    tau = np.asarray(tau, dtype=float)
    k = max(1, int(round(1.0 / dx)))
    ok = np.isfinite(tau)
    count = fields.box_sum(ok.astype(float), k, mode="edge")  # (2k + 1)^2 where all are
    total = fields.box_sum(np.where(ok, tau, 0.0), k, mode="edge")
    return np.where(ok, total / np.maximum(count, 1.0), np.inf)


def compare_release(
    released: np.ndarray, inside: np.ndarray, x: np.ndarray, dx: float
) -> dict[str, float]:
    """A released map against the polygon, both (nx, ny) bool on the run's cell grid.

    Returns:
        ``area_ratio`` (released / polygon area), ``overlap_iou`` (intersection over
        union), ``recall`` (share of the polygon released), ``precision`` (share of the
        release inside the polygon), ``crown_offset_m`` (up-slope-most released cell minus
        the polygon's up-slope-most cell, along the surface [m]; > 0: the crown lies above
        the polygon's upper edge) and ``crown_offset_median_m`` (the same per column of y
        where both have cells, median).
    """
    released, inside = np.asarray(released, bool), np.asarray(inside, bool)
    cell = dx * dx
    inter = float(np.sum(released & inside))
    union = float(np.sum(released | inside))
    n_rel, n_in = float(released.sum()), float(inside.sum())
    out = {
        "released_area_m2": n_rel * cell,
        "polygon_area_m2": n_in * cell,
        "area_ratio": n_rel / n_in if n_in else math.nan,
        "overlap_iou": inter / union if union else math.nan,
        "recall": inter / n_in if n_in else math.nan,
        "precision": inter / n_rel if n_rel else math.nan,
    }
    xr = np.where(released, x[:, None], -np.inf).max(axis=0)
    xp = np.where(inside, x[:, None], -np.inf).max(axis=0)
    both = np.isfinite(xr) & np.isfinite(xp)
    out["crown_offset_m"] = float(xr.max() - xp.max()) if n_rel and n_in else math.nan
    out["crown_offset_median_m"] = (
        float(np.median(xr[both] - xp[both])) if np.any(both) else math.nan
    )
    return out
