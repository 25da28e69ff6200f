"""GIS export of slope runs: GeoTIFFs and release-zone polygons in the DEM's CRS.

A slope run computes its fields on the release area's own grid: x up-slope along the
surface from the lower edge, y across, cells of ``dx`` metres (`damjax.scenario`'s slope
format). On a DEM the area is placed by ``terrain.origin`` (map coordinates of its lower
left corner) and ``terrain.upslope`` (the DEM axis x points along; y is that axis turned 90
deg counter-clockwise), and x follows the surface along the area's centre line, as in the
simulation. `Frame` is that map; this module uses it to write

- GeoTIFFs (north-up, in the DEM's CRS, pixels of about dx on the map):
  ``thickness_change.tif`` (h - h0 [m]), ``arrival_time.tif`` (weak-layer failure time
  [s], NaN where intact), ``released.tif`` (1 released, 0 intact, 255 outside the area)
  and, for an ensemble, ``release_probability.tif`` ([0, 1]);
- release zones: one polygon per connected released region (4-connected cells), vertices
  on the cell corners mapped exactly to the map (the map of the area's grid is separable:
  a rectilinear outline stays rectilinear), in ``release_zones.gpkg`` and
  ``release_zones.shp`` (optionally ``.geojson``), attributes: ``name``, ``cells``,
  ``area_m2`` (planimetric area on the map), ``surf_m2`` (area along the surface),
  ``thickness`` (mean final slab column height over the zone [m], the release thickness
  AvaFrame reads: slab volume / zone area), ``h0_m`` (initial slab thickness),
  ``t_first_s`` (earliest failure time) and, for ensembles, ``mean_prob``.

The CRS is the DEM's: read from a GeoTIFF, the ``.prj`` beside an ESRI ASCII grid, or a
NetCDF ``crs_wkt`` / ``spatial_ref`` attribute; ``crs=`` overrides it. Runs on a "plane" or
"generic" terrain have no map: they are written in the stated local frame (X = x up-slope
along the surface, Y = y across, metres, no CRS, and ``crs=`` is refused; a
``DAMJAX_FRAME`` tag says so); their ``area_m2`` is the area in that frame, along the
surface.

Needs ``pip install 'damjax[geo]'`` (rasterio, geopandas, pyogrio, shapely).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

RESULTS = "results.nc"
ENSEMBLE = "ensemble.nc"
UPSLOPE_AXES = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}
LOCAL_FRAME = "local release-area frame: X up-slope along the surface [m], Y across [m]"
FORMATS = ("gpkg", "shp", "geojson")
_DRIVERS = {"gpkg": "GPKG", "shp": "ESRI Shapefile", "geojson": "GeoJSON"}


def need(module: str, extra: str = "geo") -> Any:
    """Import an optional module, or an ImportError naming the extra to install."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(
            f"this export needs {module.split('.')[0]}: pip install 'damjax[{extra}]'"
        ) from e


# ----------------------------------------------------------------------------- reading


def open_run(path: str | os.PathLike) -> Any:
    """The xarray Dataset of a slope run folder (``results.nc``), an ensemble folder
    (``ensemble.nc``) or either file."""
    from damjax import io

    p = Path(path)
    if p.is_dir():
        for name in (RESULTS, ENSEMBLE):
            if (p / name).exists():
                p = p / name
                break
        else:
            raise FileNotFoundError(f"{path}: no {RESULTS} or {ENSEMBLE} in this folder")
    if not p.exists():
        raise FileNotFoundError(f"{path}: no such file or folder")
    ds = io.open_dataset(p)
    if (
        "x" not in ds.dims
        or "y" not in ds.dims
        or not ("arrival_time" in ds or "release_probability" in ds)
    ):
        raise ValueError(
            f"{p}: not a slope result (needs x, y and arrival_time or release_probability)"
        )
    return ds


def _scenario_table(ds: Any, scenario: Any) -> dict[str, Any]:
    """The scenario as a dict: ``scenario`` (a dict, TOML text or a .toml path) or the
    dataset's ``scenario`` attribute (slope runs store their scenario there)."""
    if scenario is None:
        text = ds.attrs.get("scenario")
        if not text:
            raise ValueError(
                "the dataset has no scenario attribute (an ensemble?): pass scenario= (the "
                "scenario file) so the release area can be placed on its terrain"
            )
        return tomllib.loads(text)
    if isinstance(scenario, dict):
        return scenario
    s = str(scenario)
    if "\n" not in s and Path(s).suffix == ".toml":
        data = tomllib.loads(Path(s).read_text(encoding="utf-8"))
        ter = data.get("terrain", {})
        if ter.get("kind") == "dem" and "file" in ter and not Path(ter["file"]).is_absolute():
            ter["file"] = str((Path(s).parent / ter["file"]).resolve())
        return data
    if hasattr(scenario, "to_toml"):
        return tomllib.loads(scenario.to_toml())
    return tomllib.loads(s)


def _with_code(crs: Any) -> Any:
    """``crs`` as its EPSG definition where rasterio identifies one: a WKT without its
    AUTHORITY (the shipped avaKot DEM's) reached GeoJSON without a "crs" member (read as
    WGS84) and GeoPackage as an unknown custom system."""
    if crs is None:
        return None
    code = crs.to_epsg()
    return need("rasterio.crs").CRS.from_epsg(code) if code else crs


def dem_crs(path: str | os.PathLike) -> Any:
    """The CRS of a DEM file (a `rasterio.crs.CRS`, its EPSG definition where it has a
    code), or None if it has none.

    GeoTIFF: its own; ESRI ASCII: the ``.prj`` beside it; NetCDF: a ``crs_wkt`` or
    ``spatial_ref`` attribute of any variable.
    """
    return _with_code(_file_crs(path))


def _file_crs(path: str | os.PathLike) -> Any:
    crs_mod = need("rasterio.crs")
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".tif", ".tiff", ".gtiff", ".asc"):
        prj = p.with_suffix(".prj")
        if suffix == ".asc" and prj.exists():
            return crs_mod.CRS.from_wkt(prj.read_text(encoding="utf-8").strip())
        if suffix == ".asc":
            return None
        rasterio = need("rasterio")
        with rasterio.open(p) as src:
            return src.crs
    if suffix in (".nc", ".nc4", ".cdf", ".netcdf"):
        import xarray as xr

        with xr.open_dataset(p) as ds:
            for v in list(ds.variables.values()) + [ds]:
                for key in ("crs_wkt", "spatial_ref"):
                    wkt = v.attrs.get(key)
                    if wkt:
                        return crs_mod.CRS.from_wkt(str(wkt))
        return None
    return None


@dataclasses.dataclass(frozen=True)
class Frame:
    """The release area's grid and its map: (x up-slope along the surface, y across) ->
    map (X, Y) = origin + u a(x) + v y, a(x) the map distance along u whose surface
    distance along the area's centre line is x (`damjax.scenario` slope format).

    Attributes:
        dx: cell size [m]; nx, ny: cells along x and y.
        origin: map coordinates of the area's (0, 0) corner (down-slope, on the right
            looking up-slope) [m].
        u, v: unit map vectors of the area's x (up-slope) and y axes.
        a_grid, s_grid: map distance a and surface distance s along the centre line [m]
            (ascending; identity for a local frame).
        crs: the CRS (rasterio) or None; local: True for the stated local frame.
        dem: the DEM file, or None.
    """

    dx: float
    nx: int
    ny: int
    origin: tuple[float, float]
    u: tuple[float, float]
    v: tuple[float, float]
    a_grid: np.ndarray
    s_grid: np.ndarray
    crs: Any = None
    local: bool = True
    dem: str | None = None

    @property
    def length(self) -> float:
        """Extent along x (surface) [m]."""
        return self.nx * self.dx

    @property
    def width(self) -> float:
        """Extent along y [m]."""
        return self.ny * self.dx

    def map_distance(self, s: Any) -> np.ndarray:
        """Map distance a along u of surface distance s [m]."""
        return np.interp(s, self.s_grid, self.a_grid)

    def surface_distance(self, a: Any) -> np.ndarray:
        """Surface distance s of map distance a along u [m]."""
        return np.interp(a, self.a_grid, self.s_grid)

    def to_map(self, x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
        """Map coordinates of release-area points (x, y) [m]."""
        a = self.map_distance(np.asarray(x, dtype=float))
        y = np.asarray(y, dtype=float)
        return (
            self.origin[0] + self.u[0] * a + self.v[0] * y,
            self.origin[1] + self.u[1] * a + self.v[1] * y,
        )

    def from_map(self, X: Any, Y: Any) -> tuple[np.ndarray, np.ndarray]:
        """Release-area coordinates (x, y) of map points (X, Y) [m]."""
        dX = np.asarray(X, dtype=float) - self.origin[0]
        dY = np.asarray(Y, dtype=float) - self.origin[1]
        a = dX * self.u[0] + dY * self.u[1]
        y = dX * self.v[0] + dY * self.v[1]
        s = np.where(
            (a >= self.a_grid[0]) & (a <= self.a_grid[-1]), self.surface_distance(a), np.nan
        )
        return s, y

    def cos_along(self) -> np.ndarray:
        """da/ds at the cell centres (nx,): the map length of a unit of surface along x."""
        xs = (np.arange(self.nx) + 0.5) * self.dx
        h = 0.25 * self.dx
        return (self.map_distance(xs + h) - self.map_distance(xs - h)) / (2 * h)


def frame_of(
    ds: Any,
    scenario: Any = None,
    *,
    dem: str | os.PathLike | None = None,
    crs: Any = None,
) -> Frame:
    """The `Frame` of a slope result or ensemble dataset.

    Args:
        ds: the dataset (`open_run`).
        scenario: the scenario (dict, TOML text, .toml path or Scenario); default the
            dataset's ``scenario`` attribute.
        dem: the DEM file, if it moved since the run (default the scenario's
            ``terrain.file``).
        crs: CRS to state (anything ``rasterio.crs.CRS.from_user_input`` takes); default
            the DEM's.
    """
    x = np.asarray(ds["x"].values, dtype=float)
    y = np.asarray(ds["y"].values, dtype=float)
    if x.size < 2 or y.size < 2:
        raise ValueError("the result grid needs at least 2 cells along x and y")
    dx = float(x[1] - x[0])
    nx, ny = x.size, y.size
    data = _scenario_table(ds, scenario)
    ter = data.get("terrain") or {"kind": "plane"}
    user_crs = None
    if crs is not None:
        crs_mod = need("rasterio.crs")
        try:
            try:  # pyproj first: it refuses an unknown code without GDAL printing a line
                import pyproj

                wkt = pyproj.CRS.from_user_input(crs).to_wkt() if isinstance(crs, str) else crs
            except ImportError:  # pragma: no cover
                wkt = crs
            user_crs = crs_mod.CRS.from_user_input(wkt)
        except Exception as exc:  # noqa: BLE001 - pyproj's or rasterio's CRSError
            raise ValueError(
                f"crs = {crs!r}: not a coordinate reference system rasterio reads "
                f"(e.g. EPSG:2056, or WKT; {' '.join(str(exc).split())})"
            ) from None
    if ter.get("kind") != "dem":
        if user_crs is not None:  # its X, Y are metres along the surface, on no map
            raise ValueError(
                f"crs = {crs!r}: a run on terrain.kind = {ter.get('kind', 'plane')!r} has no "
                "map (X up-slope along the surface, Y across, in metres); a CRS belongs to "
                "a DEM run's files"
            )
        s = np.array([0.0, nx * dx])
        return Frame(dx, nx, ny, (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), s, s, None, True)
    from damjax import terrain

    file = Path(dem) if dem is not None else Path(ter["file"])
    if not file.exists():
        raise FileNotFoundError(
            f"terrain.file = {str(file)!r}: no such file (the DEM of the run; pass dem=...)"
        )
    t = terrain.load_dem(file)
    upslope = ter.get("upslope", "+x")
    if upslope not in UPSLOPE_AXES:
        raise ValueError(f"terrain.upslope = {upslope!r}: must be one of {list(UPSLOPE_AXES)}")
    u = UPSLOPE_AXES[upslope]
    v = (-u[1], u[0])
    o = tuple(float(c) for c in ter.get("origin", (0.0, 0.0)))
    # the centre-line surface profile the run was built on (`dem_fields`). Clipped to the
    # DEM, with missing cells bridged: the run's own profile where its domain is the
    # terrain within a buffer (a rectangle that may leave the DEM), and the same as
    # unclipped for a rectangle on the DEM (a run over missing cells did not start)
    from damjax.scenario.slope_fields import centre_line_profile

    try:
        a, s = centre_line_profile(
            t, float(x[-1]) + dx, 0.5 * (float(y[0]) + float(y[-1])), o, upslope, nodata=True
        )
    except ValueError:
        raise ValueError(
            f"{file}: missing DEM cells under the release area's centre line"
        ) from None
    if s[-1] < nx * dx:
        raise ValueError(f"{file}: the release area's centre line leaves the DEM")
    own = dem_crs(file)
    if user_crs is not None:
        # the files are on the DEM's grid, in its units: a stated CRS labels them, it does
        # not reproject them, so it must be a projected one, and the DEM's where it has one
        if user_crs.is_geographic:
            raise ValueError(
                f"crs = {crs!r}: a geographic CRS (degrees); the run's files are in the "
                "DEM's metres: state a projected CRS (the DEM's)"
            )
        if own is not None and user_crs != own:
            raise ValueError(
                f"crs = {crs!r}: the DEM ({file.name}) states {own.to_string()}; a CRS stated "
                "at export labels the files, it does not reproject them: leave it out (the "
                "DEM's is used), or reproject the exported files afterwards"
            )
    return Frame(
        dx,
        nx,
        ny,
        (o[0], o[1]),
        u,
        v,
        a,
        s,
        user_crs if user_crs is not None else own,
        False,
        str(file),
    )


# ----------------------------------------------------------------------------- rasters


def _pixel_grid(frame: Frame, resolution: float | None) -> tuple[Any, int, int, float]:
    """(affine transform, width, height, resolution) of a north-up grid over the area."""
    from affine import Affine

    if frame.local:
        res = frame.dx
        return Affine(res, 0.0, 0.0, 0.0, -res, frame.width), frame.nx, frame.ny, res
    res = resolution or frame.dx * float(np.min(frame.cos_along()))
    if not (res > 0 and math.isfinite(res)):
        raise ValueError(f"resolution = {resolution}: must be a positive number of metres")
    xs, ys = frame.to_map(
        np.array([0.0, frame.length, 0.0, frame.length]),
        np.array([0.0, 0.0, frame.width, frame.width]),
    )
    x0 = math.floor(np.min(xs) / res) * res
    y1 = math.ceil(np.max(ys) / res) * res
    w = int(math.ceil((np.max(xs) - x0) / res))
    h = int(math.ceil((y1 - np.min(ys)) / res))
    return Affine(res, 0.0, x0, 0.0, -res, y1), w, h, res


def _to_pixels(frame: Frame, field: np.ndarray, tr: Any, w: int, h: int, fill: Any) -> Any:
    """Nearest-cell resampling of a release-area field (nx, ny) onto the pixel grid."""
    if frame.local:  # rows from the top (y descending), columns along x
        return np.asarray(field).T[::-1, :].copy()
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    X = tr.c + tr.a * cols
    Y = tr.f + tr.e * rows
    s, yy = frame.from_map(X, Y)
    i = np.floor(s / frame.dx)
    j = np.floor(yy / frame.dx)
    ok = np.isfinite(i) & (i >= 0) & (i < frame.nx) & (j >= 0) & (j < frame.ny)
    out = np.full((h, w), fill, dtype=np.asarray(field).dtype)
    out[ok] = np.asarray(field)[i[ok].astype(int), j[ok].astype(int)]
    return out


def _h0(ds: Any, data: dict[str, Any] | None) -> float:
    params = (data or {}).get("params", {})
    if "thickness" in params:
        return float(params["thickness"])
    if "params" in ds.attrs:
        try:
            return float(json.loads(ds.attrs["params"])["thickness"])
        except (KeyError, TypeError, ValueError):
            pass
    from damjax.params import PSTParams

    return float(PSTParams().thickness)


def _maybe_table(ds: Any, scenario: Any) -> dict[str, Any] | None:
    try:
        return _scenario_table(ds, scenario)
    except ValueError:
        return None


def write_geotiffs(
    ds: Any,
    frame: Frame,
    out_dir: str | os.PathLike,
    *,
    resolution: float | None = None,
    scenario: Any = None,
) -> dict[str, Path]:
    """GeoTIFFs of a slope result (thickness change, arrival time, released mask) or of an
    ensemble (release probability, member-mean released fraction), see the module doc.

    Args:
        ds: the dataset; frame: its `Frame` (`frame_of`).
        out_dir: folder for the files (created).
        resolution: pixel size on the map [m]; default dx times the smallest cos(psi)
            along the area's centre line (no cell is skipped); a local frame uses dx.
        scenario: as for `frame_of` (to read h0 when the dataset lacks it).

    Returns {name: path}.
    """
    rasterio = need("rasterio")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tr, w, h, res = _pixel_grid(frame, resolution)
    layers: list[tuple[str, np.ndarray, Any, str, str]] = []
    if "release_probability" in ds:
        prob = np.asarray(ds["release_probability"].values, dtype=np.float32)
        if "snow" in ds:  # no snow: no data, not a probability of 0
            prob = np.where(np.asarray(ds["snow"].values, dtype=bool), prob, np.float32(np.nan))
        layers.append(
            ("release_probability", prob, np.nan, "1", "release probability (member mean)")
        )
    if "arrival_time" in ds and "member" not in ds["arrival_time"].dims:
        h0 = _h0(ds, _maybe_table(ds, scenario))
        height = np.asarray(ds["height"].values, dtype=np.float32)
        # each cell's own h0 where the file has it (a thickness map, cells without snow)
        if "thickness" in ds:
            h0_map = np.asarray(ds["thickness"].values, dtype=np.float32)
            h0_text = "h0 the cell's initial thickness"
        else:
            h0_map = np.full_like(height, np.float32(h0))
            h0_text = f"h0 = {h0} m"
        dh = height - h0_map
        at = np.asarray(ds["arrival_time"].values, dtype=np.float32)
        rel = np.isfinite(at).astype(np.uint8)
        if "snow" in ds:  # no snow, no slab: no data, not a slab that left
            bare = ~np.asarray(ds["snow"].values, dtype=bool)
            dh[bare] = np.nan
            rel[bare] = 255
        layers += [
            ("thickness_change", dh, np.nan, "m", f"slab thickness change h - h0 ({h0_text})"),
            ("arrival_time", at, np.nan, "s", "weak-layer failure time (NaN: intact)"),
            ("released", rel, 255, "1", "weak layer failed: 1, intact: 0, no snow or outside: 255"),
        ]
    if not layers:
        raise ValueError("nothing to write: the dataset has no single-run fields or probability")
    files = {}
    for name, field, nodata, units, long_name in layers:
        img = _to_pixels(frame, field, tr, w, h, nodata)
        path = out / f"{name}.tif"
        with rasterio.open(
            path,
            "w",
            driver="GTiff",
            width=img.shape[1],
            height=img.shape[0],
            count=1,
            dtype=img.dtype,
            crs=frame.crs,
            transform=tr,
            nodata=nodata,
            compress="deflate",
        ) as dst:
            dst.write(img, 1)
            tags = {"units": units, "long_name": long_name, "damjax_dx_m": str(frame.dx)}
            if frame.local:
                tags["DAMJAX_FRAME"] = LOCAL_FRAME
            dst.update_tags(**tags)
            dst.set_band_description(1, long_name)
        files[name] = path
    return files


# ----------------------------------------------------------------------------- polygons


def release_zones(
    ds: Any,
    frame: Frame,
    *,
    threshold: float = 0.5,
    min_cells: int = 4,
    scenario: Any = None,
    fill_holes: bool = False,
) -> Any:
    """The release zones as a GeoDataFrame (one row per 4-connected released region).

    Args:
        ds: a slope result (released = weak layer failed) or an ensemble dataset (released
            = release_probability >= threshold); frame: its `Frame`.
        threshold: probability threshold of an ensemble's zones.
        min_cells: regions of fewer cells are dropped (isolated failed cells).
        scenario: as for `frame_of` (for h0).
        fill_holes: drop interior rings (intact islands) from the polygons.

    Columns: name, cells, area_m2 (planimetric), surf_m2, thickness (mean final column
    height [m]), h0_m, t_first_s, mean_prob (ensembles), geometry (map coordinates).
    """
    gpd = need("geopandas")
    shapely = need("shapely")
    features = need("rasterio.features")
    from affine import Affine
    from scipy import ndimage

    if not (isinstance(min_cells, int) and min_cells >= 1):
        raise ValueError(f"min_cells = {min_cells!r}: must be an integer >= 1")
    ensemble = "release_probability" in ds and (
        "arrival_time" not in ds or "member" in ds["arrival_time"].dims
    )
    if ensemble:
        if not 0 < threshold <= 1:
            raise ValueError(f"threshold = {threshold}: must be in (0, 1]")
        prob = np.asarray(ds["release_probability"].values, dtype=float)
        mask = prob >= threshold
        height = ds["height"].mean("member").values if "height" in ds else None
        at = ds["arrival_time"].min("member").values if "arrival_time" in ds else None
    else:
        prob = None
        at = np.asarray(ds["arrival_time"].values, dtype=float)
        mask = np.isfinite(at)
        height = ds["height"].values
    labels, n = ndimage.label(mask)  # 4-connectivity, as rasterio's shapes
    h0 = _h0(ds, _maybe_table(ds, scenario))
    dx = frame.dx
    cosx = frame.cos_along()
    rows = []
    geoms = []
    k = 0
    shapes = features.shapes(
        labels.T.astype(np.int32),
        mask=labels.T > 0,
        connectivity=4,
        transform=Affine(dx, 0.0, 0.0, 0.0, dx, 0.0),
    )
    by_label: dict[int, list[Any]] = {}
    for geom, value in shapes:
        by_label.setdefault(int(value), []).append(shapely.geometry.shape(geom))
    for lab in range(1, n + 1):
        cells = labels == lab
        count = int(cells.sum())
        if count < min_cells or lab not in by_label:
            continue
        poly = shapely.ops.unary_union(by_label[lab])
        if fill_holes:
            poly = shapely.geometry.Polygon(poly.exterior) if poly.geom_type == "Polygon" else poly

        def to_map(coords: np.ndarray) -> np.ndarray:
            X, Y = frame.to_map(coords[:, 0], coords[:, 1])
            return np.column_stack([X, Y])

        mapped = shapely.transform(poly, to_map)
        k += 1
        row = {
            "name": f"rel{k}",
            "cells": count,
            "area_m2": float(mapped.area),
            "surf_m2": count * dx * dx,
            "map_m2": float(np.sum(cells * cosx[:, None]) * dx * dx),
            "thickness": float(np.mean(np.asarray(height)[cells])) if height is not None else h0,
            "h0_m": h0,
            "t_first_s": float(np.nanmin(np.asarray(at, dtype=float)[cells]))
            if at is not None
            else math.nan,
        }
        if prob is not None:
            row["mean_prob"] = float(np.mean(prob[cells]))
        rows.append(row)
        geoms.append(mapped)
    columns = ["name", "cells", "area_m2", "surf_m2", "map_m2", "thickness", "h0_m", "t_first_s"]
    if prob is not None:
        columns.append("mean_prob")
    return gpd.GeoDataFrame(rows, columns=columns, geometry=geoms, crs=frame.crs)


def write_release_zones(
    zones: Any,
    out_dir: str | os.PathLike,
    *,
    stem: str = "release_zones",
    formats: tuple[str, ...] = ("gpkg", "shp"),
    local: bool = False,
) -> dict[str, Path]:
    """Write release zones (`release_zones`) as GeoPackage / ESRI shapefile / GeoJSON.
    ``local``: the zones lie in the local frame of a run on no map (a plane or generic
    slope), which has no CRS to state."""
    import warnings

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if zones.crs is None and not local:
        warnings.warn(
            "release zones without a CRS (the run's DEM has none): the files state none; "
            "pass crs= (--crs EPSG:...) to state one",
            stacklevel=2,
        )
    if zones.crs is None and "geojson" in formats:
        # RFC 7946: a GeoJSON without a CRS is WGS 84, so GIS tools put these metres in
        # degrees (the GeoPackage and the shapefile state no CRS instead)
        warnings.warn(
            f"{stem}.geojson: has no CRS, which GeoJSON readers take as WGS 84 (degrees); "
            "its coordinates are metres"
            + (" in the run's local frame" if local else " (pass crs= / --crs EPSG:...)")
            + ": use the .gpkg or .shp",
            stacklevel=2,
        )
    files = {}
    for fmt in formats:
        if fmt not in FORMATS:
            raise ValueError(f"format {fmt!r}: must be one of {list(FORMATS)}")
        path = out / f"{stem}.{fmt}"
        if path.exists():
            path.unlink()
        with warnings.catch_warnings():  # said above, in our words
            warnings.filterwarnings("ignore", message=".*'crs' was not provided.*")
            zones.to_file(path, driver=_DRIVERS[fmt], engine="pyogrio")
        files[f"zones_{fmt}"] = path
    return files


def export_gis(
    run: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    scenario: Any = None,
    dem: str | os.PathLike | None = None,
    crs: Any = None,
    resolution: float | None = None,
    threshold: float = 0.5,
    min_cells: int = 4,
    formats: tuple[str, ...] = ("gpkg", "shp"),
) -> dict[str, Path]:
    """GeoTIFFs and release-zone polygons of a slope run or ensemble into ``out_dir``.

    ``run`` is a run folder (``results.nc``), an ensemble folder (``ensemble.nc``; give
    ``scenario=`` its scenario file) or either file. Also writes ``export.json`` (the frame,
    CRS and the zones' areas). Returns {name: path}. See `frame_of`, `write_geotiffs`,
    `release_zones` for the options.
    """
    ds = open_run(run)
    frame = frame_of(ds, scenario, dem=dem, crs=crs)
    files = write_geotiffs(ds, frame, out_dir, resolution=resolution, scenario=scenario)
    zones = release_zones(ds, frame, threshold=threshold, min_cells=min_cells, scenario=scenario)
    files.update(write_release_zones(zones, out_dir, formats=formats, local=frame.local))
    meta = {
        "source": str(Path(run).resolve()),
        "crs": frame.crs.to_string() if frame.crs is not None else None,
        "frame": LOCAL_FRAME if frame.local else "DEM map coordinates",
        "dem": frame.dem,
        "origin": list(frame.origin),
        "upslope_vector": list(frame.u),
        "dx_m": frame.dx,
        "zones": [
            {k: v for k, v in r.items() if k != "geometry"}
            for r in zones.drop(columns="geometry").to_dict("records")
        ],
    }
    path = Path(out_dir) / "export.json"
    from damjax import io

    io.write_json(path, meta)
    files["metadata"] = path
    return files
