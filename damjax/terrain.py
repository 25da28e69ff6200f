"""Terrain: a height field z(x, y) on a regular grid, the paper's generic slopes and DEMs.

A `Terrain` holds node coordinates x (nx,), y (ny,) [m], both ascending and regularly
spaced, and elevations z (nx, ny) [m] indexed ``[ix, iy]`` (axis 0 is x), as float64 numpy
arrays: DEM preprocessing happens once, before anything is traced, and float64 keeps
millimetre differences of kilometre elevations. x and y are horizontal map coordinates
(east, north for a DEM); for the generic slopes x points up-slope, as in a PST.

- `generic_slope`: the paper's 50 m x 60 m (or 100 m) slopes (Fig. 13): a concave toe up to
  35 deg and a convex roll at the top, from the analytic angle profile `generic_slope_angle`.
- `pst_slope_angle`: a slope angle psi(x) along a 1D PST with a convex roll.
- `load_esri_ascii`, `load_netcdf`, `load_geotiff` (rasterio, optional), `load_dem`, and
  `Terrain.resample` (bilinear) onto a simulation grid; `save_esri_ascii`, `save_netcdf`.
- `Terrain.slope_deg`, `Terrain.aspect_deg`, `Terrain.gradient` (central differences) and
  `surface_distance` along a line.

One module of ~620 lines on purpose: the class, the analytic profiles and the DEM readers
and writers share one grid convention (ascending regular nodes, ``[ix, iy]``, float64) and
one `_regular_spacing` check, and users find every terrain source in one place.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array
from jax.typing import ArrayLike

_SPACING_RTOL = 1e-6  # relative tolerance of "regularly spaced" coordinates


def _regular_spacing(c: np.ndarray, name: str) -> float:
    """The spacing of an ascending, regularly spaced coordinate (1.0 for a single node)."""
    if c.ndim != 1 or c.size == 0:
        raise ValueError(f"Terrain: {name} must be a non-empty 1D array, got shape {c.shape}")
    if c.size == 1:
        return 1.0
    d = np.diff(c)
    h = float(d.mean())
    if h <= 0 or np.max(np.abs(d - h)) > _SPACING_RTOL * max(h, np.max(np.abs(c))):
        raise ValueError(
            f"Terrain: {name} must be ascending and regularly spaced "
            f"(spacings from {d.min():g} to {d.max():g} m); resample the DEM first"
        )
    return h


@dataclasses.dataclass(frozen=True)
class Terrain:
    """A height field on a regular grid.

    Attributes:
        x: node x coordinates (nx,) [m], ascending, regularly spaced.
        y: node y coordinates (ny,) [m], ascending, regularly spaced.
        z: elevation (nx, ny) [m], indexed ``[ix, iy]``; NaN marks missing DEM cells.
    """

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "x", np.asarray(self.x, dtype=float))
        object.__setattr__(self, "y", np.asarray(self.y, dtype=float))
        object.__setattr__(self, "z", np.asarray(self.z, dtype=float))
        _regular_spacing(self.x, "x")
        _regular_spacing(self.y, "y")
        if self.z.shape != (self.x.size, self.y.size):
            raise ValueError(
                f"Terrain: z has shape {self.z.shape}, expected (nx, ny) = "
                f"({self.x.size}, {self.y.size})"
            )

    @property
    def dx(self) -> float:
        """Node spacing along x [m]."""
        return _regular_spacing(self.x, "x")

    @property
    def dy(self) -> float:
        """Node spacing along y [m]."""
        return _regular_spacing(self.y, "y")

    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape (nx, ny)."""
        return self.z.shape

    def gradient(self) -> tuple[np.ndarray, np.ndarray]:
        """Surface gradient (dz/dx, dz/dy) [-] at the nodes.

        Central differences inside, second-order one-sided differences on the edges (zero
        along an axis with a single node).
        """
        grads = []
        for axis, (c, n) in enumerate(((self.x, self.x.size), (self.y, self.y.size))):
            if n == 1:
                grads.append(np.zeros_like(self.z))
            else:
                grads.append(np.gradient(self.z, c, axis=axis, edge_order=2 if n > 2 else 1))
        return grads[0], grads[1]

    def slope_deg(self) -> np.ndarray:
        """Local slope angle psi = atan(|grad z|) at the nodes [deg]."""
        gx, gy = self.gradient()
        return np.degrees(np.arctan(np.hypot(gx, gy)))

    def aspect_deg(self) -> np.ndarray:
        """Aspect: azimuth of the steepest descent, clockwise from +y (north) [deg, 0-360).

        With x east and y north this is the GIS convention (a slope facing east is 90).
        Flat nodes (zero gradient) are NaN.
        """
        gx, gy = self.gradient()
        aspect = np.degrees(np.arctan2(-gx, -gy)) % 360.0
        return np.where((gx == 0) & (gy == 0), np.nan, aspect)

    def sample(self, xq: ArrayLike, yq: ArrayLike) -> np.ndarray:
        """Elevation at arbitrary points by bilinear interpolation [m].

        Exact for fields linear in x and y. Points outside the grid raise a ValueError; NaN
        cells propagate to the points next to them.

        Args:
            xq, yq: coordinates [m], broadcast together.
        """
        xq, yq = np.broadcast_arrays(np.asarray(xq, dtype=float), np.asarray(yq, dtype=float))
        for q, c, name in ((xq, self.x, "x"), (yq, self.y, "y")):
            tol = 1e-9 * max(1.0, np.max(np.abs(c)))
            if q.size and (q.min() < c[0] - tol or q.max() > c[-1] + tol):
                raise ValueError(
                    f"Terrain.sample: {name} from {q.min():g} to {q.max():g} m leaves the "
                    f"terrain's {name} range [{c[0]:g}, {c[-1]:g}] m"
                )
        ix, tx = _cell(xq, self.x)
        iy, ty = _cell(yq, self.y)
        jx = np.minimum(ix + 1, self.x.size - 1)
        jy = np.minimum(iy + 1, self.y.size - 1)
        z = self.z
        return (
            (1 - tx) * (1 - ty) * z[ix, iy]
            + tx * (1 - ty) * z[jx, iy]
            + (1 - tx) * ty * z[ix, jy]
            + tx * ty * z[jx, jy]
        )

    def resample(self, x: ArrayLike, y: ArrayLike) -> Terrain:
        """The terrain on another regular grid (bilinear interpolation).

        Args:
            x, y: node coordinates of the new grid [m], inside this terrain's extent.
        """
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        xx, yy = np.meshgrid(x, y, indexing="ij")
        return Terrain(x, y, self.sample(xx, yy))

    def regrid(self, dx: float, dy: float | None = None) -> Terrain:
        """The terrain on a grid of spacing (dx, dy) [m] from the first node, within the extent."""
        dy = dx if dy is None else dy
        nx = int(math.floor((self.x[-1] - self.x[0]) / dx * (1 + 1e-12))) + 1
        ny = int(math.floor((self.y[-1] - self.y[0]) / dy * (1 + 1e-12))) + 1
        return self.resample(self.x[0] + dx * np.arange(nx), self.y[0] + dy * np.arange(ny))


def _cell(q: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the cell left of q and the fractional position in it (regular grid)."""
    if c.size == 1:
        return np.zeros(q.shape, dtype=int), np.zeros(q.shape)
    h = (c[-1] - c[0]) / (c.size - 1)
    i = np.clip(np.floor((q - c[0]) / h).astype(int), 0, c.size - 2)
    return i, np.clip((q - c[i]) / h, 0.0, 1.0)


def surface_distance(
    terrain: Terrain,
    start: Sequence[float],
    end: Sequence[float],
    num: int = 501,
) -> np.ndarray:
    """Distance along the terrain surface over the straight map line from start to end [m].

    The line is sampled at `num` points, z bilinearly interpolated, and the 3D lengths of
    the chords summed (converges as num^-2 for a smooth surface).

    Args:
        terrain: the terrain.
        start, end: map points (x, y) [m].
        num: number of sample points (>= 2).

    Returns:
        The cumulative surface distance from `start` at the `num` points, shape (num,) [m];
        the last value is the surface length of the line.
    """
    if num < 2:
        raise ValueError(f"surface_distance: num={num}, need >= 2")
    t = np.linspace(0.0, 1.0, num)
    px = start[0] + t * (end[0] - start[0])
    py = start[1] + t * (end[1] - start[1])
    pz = terrain.sample(px, py)
    seg = np.sqrt(np.diff(px) ** 2 + np.diff(py) ** 2 + np.diff(pz) ** 2)
    return np.concatenate([[0.0], np.cumsum(seg)])


# --------------------------------------------------------------------------------------
# generic slopes
# --------------------------------------------------------------------------------------


def _ramp(t: Array) -> Array:
    """0 for t <= 0, 1 for t >= 1, a half cosine between (C1: no kink in the surface)."""
    return 0.5 - 0.5 * jnp.cos(jnp.pi * jnp.clip(t, 0.0, 1.0))


def profile_problem(length: float, toe_length: float, roll_length: float) -> str | None:
    """Why a generic slope's toe and roll do not fit its length (None: they fit).

    The toe and the roll must be finite and > 0, and toe_length + roll_length <= length
    (equal: no planar part, the toe runs straight into the roll)."""
    for name, v in (("length", length), ("toe_length", toe_length), ("roll_length", roll_length)):
        if not (math.isfinite(v) and v > 0):
            return f"{name} = {v!r}: must be in (0, inf) m"
    if toe_length + roll_length > length * (1 + 1e-12):
        return (
            f"toe_length = {toe_length:g} m + roll_length = {roll_length:g} m: must be at most "
            f"length = {length:g} m (defaults: toe 10 m, roll 10 m)"
        )
    return None


def generic_slope_angle(
    s: ArrayLike,
    *,
    length: ArrayLike = 50.0,
    max_slope_deg: ArrayLike = 35.0,
    toe_slope_deg: ArrayLike = 30.0,
    top_slope_deg: ArrayLike = 20.0,
    toe_length: ArrayLike = 10.0,
    roll_length: ArrayLike = 10.0,
) -> Array:
    """Slope angle psi(s) of the generic slope along its down-slope profile [deg].

    psi(s) = psi_toe + (psi_max - psi_toe) R(s / L_toe)
                     - (psi_max - psi_top) R((s - (L - L_roll)) / L_roll),

    R the half-cosine ramp from 0 to 1: a concave toe (psi rising from psi_toe at s = 0 to
    psi_max at s = L_toe), a planar part at psi_max, and a convex roll (psi falling to
    psi_top at the top, s = L). psi is C1, so the surface curvature is continuous. The
    paper (Fig. 13) gives only "a concave toe reaching 35 deg and a convex roll at the
    top"; the toe, roll and end angles are our choice.

    Args:
        s: distance from the toe [m] (along the surface for `generic_slope`).
        length: profile length L [m].
        max_slope_deg: slope angle of the planar middle part psi_max [deg].
        toe_slope_deg: slope angle at the toe psi_toe [deg].
        top_slope_deg: slope angle at the top psi_top [deg].
        toe_length: length of the concave transition L_toe [m].
        roll_length: length of the convex roll L_roll [m].

    Returns:
        psi(s) [deg] (a jax array, differentiable in every argument).
    """
    for name, v in (("toe_length", toe_length), ("roll_length", roll_length)):
        if not isinstance(v, jax.core.Tracer) and not np.all(np.asarray(v, dtype=float) > 0):
            raise ValueError(f"generic_slope_angle: {name} = {v!r}: must be in (0, inf) m")
    concrete = (length, toe_length, roll_length)
    if not any(isinstance(v, jax.core.Tracer) for v in concrete) and all(
        np.ndim(v) == 0 for v in concrete
    ):
        problem = profile_problem(float(length), float(toe_length), float(roll_length))
        if problem:
            raise ValueError(f"generic_slope_angle: {problem}")
    s = jnp.asarray(s)
    rise = (max_slope_deg - toe_slope_deg) * _ramp(s / toe_length)
    fall = (max_slope_deg - top_slope_deg) * _ramp((s - (length - roll_length)) / roll_length)
    return toe_slope_deg + rise - fall


def generic_slope(
    length: float = 50.0,
    width: float = 60.0,
    dx: float = 0.5,
    dy: float | None = None,
    *,
    along_surface: bool = True,
    max_slope_deg: float = 35.0,
    toe_slope_deg: float = 30.0,
    top_slope_deg: float = 20.0,
    toe_length: float = 10.0,
    roll_length: float = 10.0,
) -> Terrain:
    """The paper's generic slope (Fig. 13) as a height field: uniform across, x up-slope.

    The angle profile `generic_slope_angle` is integrated numerically (trapezoid rule on a
    1 cm grid): with s the surface distance from the toe, dx/ds = cos psi, dz/ds = sin psi
    (``along_surface=True``, default: `length` is measured along the surface, as the
    slab sees it); or with s the horizontal coordinate, dz/dx = tan psi
    (``along_surface=False``). z is then interpolated onto the regular grid
    x = 0, dx, 2 dx, ... up to the top of the profile (the last node lies less than dx
    below it). z = 0 at the toe.

    Args:
        length: down-slope length of the profile [m] (50 m in the paper).
        width: cross-slope width [m] (60 m or 100 m in the paper).
        dx, dy: grid spacing [m] (dy defaults to dx).
        along_surface: whether `length` (and s in the angle profile) is along the surface.
        max_slope_deg, toe_slope_deg, top_slope_deg, toe_length, roll_length: the angle
            profile, see `generic_slope_angle` [deg, m].
    """
    dy = dx if dy is None else dy
    if min(length, width, dx, dy) <= 0:
        raise ValueError(
            f"generic_slope: length, width, dx, dy must be > 0, got {length}, {width}, {dx}, {dy}"
        )
    problem = profile_problem(length, toe_length, roll_length)
    if problem:
        raise ValueError(f"generic_slope: {problem}")
    s = np.linspace(0.0, length, int(math.ceil(length / 0.01)) + 1)
    psi = np.radians(
        np.asarray(
            generic_slope_angle(
                s,
                length=length,
                max_slope_deg=max_slope_deg,
                toe_slope_deg=toe_slope_deg,
                top_slope_deg=top_slope_deg,
                toe_length=toe_length,
                roll_length=roll_length,
            ),
            dtype=float,
        )
    )
    if along_surface:
        xs = _cumtrapz(np.cos(psi), s)
        zs = _cumtrapz(np.sin(psi), s)
    else:
        xs, zs = s, _cumtrapz(np.tan(psi), s)
    x = dx * np.arange(int(math.floor(xs[-1] / dx * (1 + 1e-12))) + 1)
    y = dy * np.arange(int(math.floor(width / dy * (1 + 1e-12))) + 1)
    z = np.interp(x, xs, zs)
    return Terrain(x, y, np.repeat(z[:, None], y.size, axis=1))


def _cumtrapz(f: np.ndarray, s: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(s))])


def pst_slope_angle(
    x: ArrayLike,
    *,
    slope_deg: ArrayLike = 35.0,
    roll_start: ArrayLike = 35.0,
    roll_length: ArrayLike = 15.0,
    top_slope_deg: ArrayLike = 20.0,
) -> Array:
    """Slope angle psi(x) along a 1D PST with a convex roll at the top [deg].

    psi = slope_deg up to `roll_start`, then falls along a half-cosine ramp to
    `top_slope_deg` at ``roll_start + roll_length`` and stays there (the same roll as the
    top of `generic_slope`'s default profile).

    Args:
        x: position along the PST from its bottom end [m].
        slope_deg: slope angle below the roll [deg].
        roll_start: where the roll begins [m].
        roll_length: length of the roll [m].
        top_slope_deg: slope angle above the roll [deg].

    Returns:
        psi(x) [deg] (a jax array, differentiable in every argument).
    """
    x = jnp.asarray(x)
    return slope_deg - (slope_deg - top_slope_deg) * _ramp((x - roll_start) / roll_length)


# --------------------------------------------------------------------------------------
# DEM files
# --------------------------------------------------------------------------------------

_ESRI_KEYS = {
    "ncols",
    "nrows",
    "xllcorner",
    "yllcorner",
    "xllcenter",
    "yllcenter",
    "cellsize",
    "dx",
    "dy",
    "nodata_value",
}


def load_esri_ascii(path: str | os.PathLike) -> Terrain:
    """Read an ESRI ASCII grid (.asc): header, then rows from north (top) to south.

    Supports ``xllcorner``/``yllcorner`` (cell corners: nodes at the cell centres) and
    ``xllcenter``/``yllcenter``, ``cellsize`` or GDAL's ``dx``/``dy``, and
    ``NODATA_value`` (read as NaN). Units are those of the file (metres expected).
    """
    path = os.fspath(path)
    with open(path, encoding="utf-8-sig") as f:
        lines = f.read().splitlines()
    header: dict[str, float] = {}
    data_start = len(lines)
    for k, line in enumerate(lines):
        parts = line.split()
        if not parts:
            continue
        key = parts[0].lower()
        if key not in _ESRI_KEYS:
            data_start = k
            break
        if len(parts) != 2:
            raise ValueError(f"{path}:{k + 1}: header line {line.strip()!r} is not 'key value'")
        try:
            header[key] = float(parts[1])
        except ValueError:
            raise ValueError(
                f"{path}:{k + 1}: {parts[0]} value {parts[1]!r} is not a number"
            ) from None
    for need in ("ncols", "nrows"):
        if need not in header:
            raise ValueError(f"{path}: ESRI ASCII header lacks {need}")
    ncols, nrows = int(header["ncols"]), int(header["nrows"])
    if "cellsize" in header:
        hx = hy = header["cellsize"]
    elif "dx" in header and "dy" in header:
        hx, hy = header["dx"], header["dy"]
    else:
        raise ValueError(f"{path}: ESRI ASCII header lacks cellsize (or dx and dy)")
    if "xllcenter" in header and "yllcenter" in header:
        x0, y0 = header["xllcenter"], header["yllcenter"]
    elif "xllcorner" in header and "yllcorner" in header:
        x0, y0 = header["xllcorner"] + 0.5 * hx, header["yllcorner"] + 0.5 * hy
    else:
        raise ValueError(f"{path}: ESRI ASCII header lacks xllcorner/yllcorner (or *center)")
    try:
        values = np.array(" ".join(lines[data_start:]).split(), dtype=float)
    except ValueError as e:
        raise ValueError(f"{path}: non-numeric elevation value ({e})") from None
    if values.size != nrows * ncols:
        raise ValueError(
            f"{path}: {values.size} elevation values, the header says {nrows} x {ncols} = "
            f"{nrows * ncols}"
        )
    rows = values.reshape(nrows, ncols)
    if "nodata_value" in header:
        rows = np.where(rows == header["nodata_value"], np.nan, rows)
    # row 0 is the north edge: flip to ascending y, then transpose to [ix, iy]
    z = rows[::-1, :].T
    return Terrain(x0 + hx * np.arange(ncols), y0 + hy * np.arange(nrows), z)


def save_esri_ascii(
    terrain: Terrain, path: str | os.PathLike, *, nodata: float = -9999.0, decimals: int = 6
) -> None:
    """Write a terrain as an ESRI ASCII grid (NaN -> `nodata`, elevations to `decimals`).

    Square cells are written with ``cellsize``, others with GDAL's ``dx``/``dy``.
    """
    dx, dy = terrain.dx, terrain.dy
    x0, y0 = float(terrain.x[0] - 0.5 * dx), float(terrain.y[0] - 0.5 * dy)
    head = [f"ncols {terrain.x.size}", f"nrows {terrain.y.size}"]
    head += [f"xllcorner {x0!r}", f"yllcorner {y0!r}"]  # repr: exact round trip
    if math.isclose(dx, dy, rel_tol=1e-12):
        head.append(f"cellsize {dx!r}")
    else:
        head += [f"dx {dx!r}", f"dy {dy!r}"]
    head.append(f"NODATA_value {nodata:g}")
    rows = np.where(np.isnan(terrain.z), nodata, terrain.z).T[::-1, :]
    with open(os.fspath(path), "w", encoding="utf-8") as f:
        f.write("\n".join(head) + "\n")
        np.savetxt(f, rows, fmt=f"%.{decimals}f")


_X_NAMES = ("x", "easting", "east", "e", "projection_x_coordinate")
_Y_NAMES = ("y", "northing", "north", "n", "projection_y_coordinate")
_GEOGRAPHIC = ("lon", "longitude", "lat", "latitude")


def _axis_of(name: str, attrs: dict) -> str | None:
    """'x', 'y', 'geo' (lon/lat: not metric) or None, from a coordinate's name and attrs."""
    low = name.lower()
    std = str(attrs.get("standard_name", "")).lower()
    units = str(attrs.get("units", "")).lower()
    if low in _GEOGRAPHIC or std in ("longitude", "latitude") or units.startswith("degree"):
        return "geo"
    if low in _X_NAMES or std == "projection_x_coordinate" or attrs.get("axis") == "X":
        return "x"
    if low in _Y_NAMES or std == "projection_y_coordinate" or attrs.get("axis") == "Y":
        return "y"
    return None


def load_netcdf(
    path: str | os.PathLike,
    variable: str | None = None,
    *,
    x: str | None = None,
    y: str | None = None,
) -> Terrain:
    """Read a DEM from a NetCDF file (xarray).

    Args:
        path: the file.
        variable: the elevation variable [m]; default: the only data variable with two
            (non-degenerate) dimensions.
        x, y: names of the x and y dimensions; default: detected from the names (x,
            easting, ...), CF ``axis`` or ``standard_name`` attributes. Geographic
            coordinates (lon/lat, degrees) are refused: reproject to a metric grid first.
    """
    import xarray as xr

    path = os.fspath(path)
    with xr.open_dataset(path) as ds:
        if variable is None:
            cands = [v for v in ds.data_vars if ds[v].squeeze(drop=True).ndim == 2]
            if len(cands) != 1:
                raise ValueError(
                    f"{path}: name the variable (variable=... in Python, strength.variable "
                    f"in a scenario); 2D data variables: {cands or 'none'}"
                )
            variable = str(cands[0])
        if variable not in ds.data_vars:
            raise ValueError(f"{path}: no variable {variable!r} (found {list(ds.data_vars)})")
        da = ds[variable].squeeze(drop=True).load()
    if da.ndim != 2:
        raise ValueError(f"{path}: {variable} has dimensions {da.dims}, expected 2")
    dims = [str(d) for d in da.dims]
    names = {}
    for d in dims:
        attrs = dict(da[d].attrs) if d in da.coords else {}
        names[d] = _axis_of(d, attrs)
    if "geo" in names.values() and not (x and y):
        raise ValueError(
            f"{path}: {variable} has geographic coordinates {dims} (degrees); reproject the "
            "DEM to a metric grid, or name metric dimensions with x=..., y=..."
        )
    xd = x or next((d for d in dims if names[d] == "x"), None)
    yd = y or next((d for d in dims if names[d] == "y"), None)
    if xd is None or yd is None or xd == yd or {xd, yd} != set(dims):
        raise ValueError(
            f"{path}: cannot tell x from y in the dimensions {dims} of {variable}; "
            "pass x=... and y=..."
        )
    da = da.transpose(xd, yd)
    xs = np.asarray(da[xd].values if xd in da.coords else np.arange(da.shape[0]), dtype=float)
    ys = np.asarray(da[yd].values if yd in da.coords else np.arange(da.shape[1]), dtype=float)
    z = np.asarray(da.values, dtype=float)
    # ascending coordinates (north-up files store y descending)
    if xs.size > 1 and xs[1] < xs[0]:
        xs, z = xs[::-1], z[::-1, :]
    if ys.size > 1 and ys[1] < ys[0]:
        ys, z = ys[::-1], z[:, ::-1]
    return Terrain(xs, ys, z)


def save_netcdf(terrain: Terrain, path: str | os.PathLike, variable: str = "z") -> None:
    """Write a terrain to NetCDF (h5netcdf), dimensions (y, x) as GIS tools expect."""
    import xarray as xr

    da = xr.DataArray(
        terrain.z.T,
        dims=("y", "x"),
        coords={
            "y": ("y", terrain.y, {"units": "m", "axis": "Y"}),
            "x": ("x", terrain.x, {"units": "m", "axis": "X"}),
        },
        attrs={"units": "m", "long_name": "elevation"},
    )
    da.to_dataset(name=variable).to_netcdf(os.fspath(path), engine="h5netcdf")


def load_geotiff(path: str | os.PathLike, band: int = 1) -> Terrain:
    """Read a DEM from a GeoTIFF (needs rasterio: ``pip install 'damjax[geo]'``).

    The raster must be north-up (no rotation) in a projected (metric) CRS; nodata cells
    become NaN; nodes are the pixel centres.
    """
    try:
        import rasterio
    except ImportError as e:
        raise ImportError(
            "reading GeoTIFF DEMs needs rasterio: pip install 'damjax[geo]' (or pip install "
            "rasterio); or convert the DEM to ESRI ASCII (.asc) or NetCDF"
        ) from e
    path = os.fspath(path)
    with rasterio.open(path) as src:
        tr = src.transform
        if tr.b != 0 or tr.d != 0:
            raise ValueError(f"{path}: rotated rasters are not supported; warp it north-up")
        if src.crs is not None and src.crs.is_geographic:
            raise ValueError(f"{path}: geographic CRS (degrees); reproject to a metric CRS")
        if src.crs is not None:
            check_metric_crs(path, src.crs.to_wkt())
        rows = src.read(band, masked=True).astype(float).filled(np.nan)
        ncols, nrows = src.width, src.height
    xs = tr.c + tr.a * (np.arange(ncols) + 0.5)
    ys = tr.f + tr.e * (np.arange(nrows) + 0.5)
    z = rows.T  # [col, row] = [ix, iy]
    if tr.e < 0:  # north-up: rows run south
        ys, z = ys[::-1], z[:, ::-1]
    if tr.a < 0:
        xs, z = xs[::-1], z[::-1, :]
    return Terrain(xs, ys, z)


def check_metric_crs(path: str | os.PathLike, crs: str | None) -> None:
    """ValueError when a DEM's CRS (WKT, or None: nothing to check) is geographic or its
    map units are not metres: damjax reads coordinates and heights as metres, so a DEM in
    feet would give slopes right and every length, area and thickness 3.3 times off.
    Without pyproj (the ``geo`` extra) nothing is checked."""
    if not crs:
        return
    try:
        import pyproj
    except ImportError:
        return
    try:
        c = pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError:
        return  # an unreadable .prj: the reader of release polygons says so
    if c.is_geographic:
        raise ValueError(
            f"{os.fspath(path)}: geographic CRS {c.name!r} (degrees); reproject to a metric CRS"
        )
    units = {a.unit_name for a in c.axis_info[:2] if a.unit_conversion_factor != 1.0}
    if units:
        raise ValueError(
            f"{os.fspath(path)}: CRS {c.name!r} is in {', '.join(sorted(units))}; damjax "
            "reads map coordinates and heights in metres: reproject the DEM to a CRS in "
            "metres and convert its heights to m"
        )


def load_dem(path: str | os.PathLike, **kwargs) -> Terrain:
    """Read a DEM, choosing the reader from the suffix (.asc, .nc/.nc4/.cdf, .tif/.tiff).

    Keyword arguments go to the reader (e.g. ``variable=`` for NetCDF, ``band=`` for TIFF).
    """
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    prj = os.path.splitext(os.fspath(path))[0] + ".prj"  # a GeoTIFF's own CRS: below
    if suffix in (".asc", ".grd", ".txt", ".nc", ".nc4", ".cdf", ".netcdf") and os.path.isfile(prj):
        # read here, not through damjax.release_area, which imports damjax.fields (a cycle)
        with open(prj, encoding="utf-8") as fh:
            check_metric_crs(path, fh.read().strip())
    if suffix in (".asc", ".grd", ".txt"):
        return load_esri_ascii(path, **kwargs)
    if suffix in (".nc", ".nc4", ".cdf", ".netcdf"):
        return load_netcdf(path, **kwargs)
    if suffix in (".tif", ".tiff", ".gtiff"):
        return load_geotiff(path, **kwargs)
    raise ValueError(f"{os.fspath(path)}: unknown DEM format {suffix!r} (.asc, .nc, .tif)")
