"""Slope scenarios resolved to fields: the slope angle, fall-line direction and strength
[deg, deg, Pa] at the cell centres of the release area, from a plane, the generic slope
or a DEM and from a constant, a Gaussian random field or a strength map; `prepare`, the
checked run of a slope scenario (`damjax.slope.simulation.prepare` on these fields), and
`simulate`, its run.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any

import numpy as np

from damjax.scenario.schema import _fmt, prepared
from damjax.slope import simulation
from damjax.slope.generic import GenericSlopeCase, weak_spot
from damjax.slope.simulation import SlopeRunWarning

_GENERIC_DEFAULTS = {
    "max_slope_deg": 35.0,
    "toe_slope_deg": 30.0,
    "top_slope_deg": 20.0,
    "toe_length": 10.0,
    "roll_length": 10.0,
}
_GRF_DEFAULTS = {
    "mean_at": 0.0,
    "trend": 0.0,
    "std": 100.0,
    "length_scale": 8.0,
    "angle_deg": 0.0,
    "trend_deg": 0.0,
    "model": "gaussian",
    "seed": 0,
}


class _FieldProblem(ValueError):
    """A one-line problem found while reading a terrain or strength file."""


def _check_map_covers(file: Any, mx: np.ndarray, my: np.ndarray, x: Any, y: Any) -> None:
    """_FieldProblem unless the map's nodes (release-area frame) span the cell centres x,
    y to half a map spacing: beyond it the map would be extended from its edges."""
    if mx.size < 2 or my.size < 2:
        raise _FieldProblem(
            f"strength.file = {_fmt(file)}: the map needs >= 2 nodes along x and y "
            f"(has {mx.size} x {my.size})"
        )
    hx, hy = 0.5 * float(np.min(np.diff(mx))), 0.5 * float(np.min(np.diff(my)))
    if x[0] < mx[0] - hx or x[-1] > mx[-1] + hx or y[0] < my[0] - hy or y[-1] > my[-1] + hy:
        raise _FieldProblem(
            f"strength.file = {_fmt(file)}: the map spans x in [{mx[0]:.4g}, {mx[-1]:.4g}] m, "
            f"y in [{my[0]:.4g}, {my[-1]:.4g}] m of the release area (after origin), which "
            f"needs x in [{x[0]:.4g}, {x[-1]:.4g}] m, y in [{y[0]:.4g}, {y[-1]:.4g}] m "
            "(cell centres); check strength.origin or the map's extent"
        )


def cell_centres(setup: Any) -> tuple[np.ndarray, np.ndarray]:
    """Cell-centre coordinates x (nx,), y (ny,) [m] of a slope run's release area."""
    nx, ny = int(round(setup.length / setup.dx)), int(round(setup.width / setup.dx))
    return (np.arange(nx) + 0.5) * setup.dx, (np.arange(ny) + 0.5) * setup.dx


_AXES = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}


def dem_fields(
    ter: Any,
    x: np.ndarray,
    y: np.ndarray,
    origin: tuple[float, float] = (0.0, 0.0),
    upslope: str = "+x",
) -> tuple[np.ndarray, np.ndarray]:
    """Local slope angle and fall direction [deg] of a DEM at release-area points.

    The release area's x axis points along the DEM axis ``upslope``, its y axis 90 deg
    counter-clockwise from it, its lower left corner at the map point ``origin`` [m].
    x is a distance along the surface (mapped to the map through the surface profile of
    the area's centre line), y a map distance.

    Args:
        ter: a `damjax.terrain.Terrain` (x, y map coordinates [m], z elevation [m]).
        x: up-slope surface coordinates (nx,) [m]; y: cross-slope coordinates (ny,) [m].
        origin: map coordinates of the release area's (0, 0) [m].
        upslope: "+x", "-x", "+y" or "-y".

    Returns:
        (slope_deg, fall_deg), each (nx, ny): the slope angle psi and the direction of the
        local fall line relative to -x (0: straight down the release area's x axis).
        ValueError if the area leaves the DEM or hits missing cells.
    """
    u = np.array(_AXES[upslope])
    v = np.array([-u[1], u[0]])
    o = np.asarray(origin, dtype=float)
    # surface profile along the centre line: s(a) for map distance a
    a_max = float(x[-1]) + float(x[1] - x[0] if x.size > 1 else 1.0)
    a = np.linspace(0.0, a_max, max(2, int(math.ceil(a_max / 0.05)) + 1))
    yc = 0.5 * (float(y[0]) + float(y[-1]))
    line = o[:, None] + u[:, None] * a[None, :] + v[:, None] * yc
    z = ter.sample(line[0], line[1])
    if not np.all(np.isfinite(z)):
        raise ValueError("missing DEM cells (nodata) under the release area")
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(a), np.diff(z)))])
    if s[-1] < x[-1]:
        raise ValueError(
            f"the release area's centre line is {s[-1]:.4g} m long along the surface "
            f"inside the DEM, shorter than its {x[-1]:.4g} m"
        )
    am = np.interp(x, s, a)
    px = o[0] + u[0] * am[:, None] + v[0] * y[None, :]
    py = o[1] + u[1] * am[:, None] + v[1] * y[None, :]
    gx, gy = ter.gradient()
    from damjax.terrain import Terrain

    gxs = Terrain(ter.x, ter.y, gx).sample(px, py)
    gys = Terrain(ter.x, ter.y, gy).sample(px, py)
    if not (np.all(np.isfinite(gxs)) and np.all(np.isfinite(gys))):
        raise ValueError("missing DEM cells (nodata) under the release area")
    gu = gxs * u[0] + gys * u[1]
    gv = gxs * v[0] + gys * v[1]
    slope = np.degrees(np.arctan(np.hypot(gu, gv)))
    fall = np.degrees(np.arctan2(gv, gu))
    return slope, fall


def resolve_fields(scn: Any) -> tuple[Any, Any, np.ndarray, tuple[float, float]]:
    """(slope_deg, fall_deg, tau_peak, start) of a slope scenario on its cell centres.

    slope_deg and fall_deg are scalars for a plane, (nx, ny) arrays [deg] otherwise;
    tau_peak is (nx, ny) [Pa]; start (x, y) [m] is ``setup.start`` or the weak spot in
    ``strength.start_window``. Raises a one-line ValueError for unreadable files.
    """
    from damjax import fields, terrain

    setup, params = scn.setup, scn.params
    x, y = cell_centres(setup)
    ter = scn.terrain or {"kind": "plane"}
    fall: Any = 0.0
    if ter["kind"] == "plane":
        slope: Any = np.full((x.size, y.size), float(ter.get("slope_deg", params.slope_deg)))
    elif ter["kind"] == "generic":
        t = {**_GENERIC_DEFAULTS, **ter}
        psi = np.asarray(
            terrain.generic_slope_angle(
                x,
                length=setup.length,
                max_slope_deg=t["max_slope_deg"],
                toe_slope_deg=t["toe_slope_deg"],
                top_slope_deg=t["top_slope_deg"],
                toe_length=t["toe_length"],
                roll_length=t["roll_length"],
            ),
            dtype=float,
        )
        slope = np.repeat(psi[:, None], y.size, axis=1)
    else:
        try:
            dem = terrain.load_dem(ter["file"])
            slope, fall = dem_fields(
                dem, x, y, tuple(ter.get("origin", (0.0, 0.0))), ter.get("upslope", "+x")
            )
        except FileNotFoundError:
            raise _FieldProblem(f"terrain.file = {_fmt(ter['file'])}: no such file") from None
        except (OSError, ValueError, ImportError, KeyError) as exc:
            msg = " ".join(str(exc).split())
            raise _FieldProblem(f"terrain.file = {_fmt(ter['file'])}: {msg}") from None
        # fall 0 deg: straight down -x; over 90 deg the "up-slope" axis goes downhill
        f = np.radians(np.asarray(fall, dtype=float))
        if float(np.mean(np.cos(f) * np.sin(np.radians(slope)))) < 0:
            up = ter.get("upslope", "+x")
            raise _FieldProblem(
                f'terrain.upslope = "{up}": the DEM descends along {up} over the release '
                f"area (mean fall direction {np.degrees(np.angle(np.mean(np.exp(1j * f)))):.0f}"
                " deg from down-slope); the release area's x axis must point up-slope"
            )
        mean_fall = float(np.degrees(np.angle(np.mean(np.exp(1j * f)))))
        if abs(mean_fall) > 45.0:
            up = ter.get("upslope", "+x")
            warnings.warn(
                f'terrain.upslope = "{up}": the mean fall line is {mean_fall:.0f} deg off this '
                "axis over the release area, so 'up-slope' and 'cross-slope' results follow "
                "the axis, not the terrain (the DEM axis closest to the fall line: leave "
                "upslope out with a release polygon, or pick it)",
                stacklevel=2,
            )
    st = scn.strength or {"kind": "constant"}
    if st["kind"] == "constant":
        tau0 = float(st.get("tau_peak", params.tau_peak))
        tau = np.repeat((tau0 + float(st.get("trend", 0.0)) * x)[:, None], y.size, axis=1)
    elif st["kind"] == "grf":
        import jax

        g = {**_GRF_DEFAULTS, **st}
        try:
            tau = fields.plateau_trend_field(
                jax.random.key(int(g["seed"])),
                x,
                y.size,
                setup.dx,
                mean=float(st.get("mean", params.tau_peak)),
                mean_at=float(g["mean_at"]),
                trend=float(g["trend"]),
                std=float(g["std"]),
                length_scale=g["length_scale"],
                angle_deg=float(g["angle_deg"]),
                model=g["model"],
                field_dx=None if "field_dx" not in st else float(st["field_dx"]),
                trend_deg=float(g["trend_deg"]),
            )
        except ValueError as exc:  # field_dx coarser than the correlation allows
            raise _FieldProblem(f"strength.{exc}") from None
    else:
        try:
            kw = {"variable": st["variable"]} if "variable" in st else {}
            mx, my, mtau = fields.load_strength_map(st["file"], **kw)
        except FileNotFoundError:
            raise _FieldProblem(f"strength.file = {_fmt(st['file'])}: no such file") from None
        except (OSError, ValueError, ImportError, KeyError) as exc:
            msg = " ".join(str(exc).split())
            raise _FieldProblem(f"strength.file = {_fmt(st['file'])}: {msg}") from None
        ox, oy = st.get("origin", (0.0, 0.0))
        mx, my = np.asarray(mx, float) - ox, np.asarray(my, float) - oy
        _check_map_covers(st["file"], mx, my, x, y)
        tau = fields.map_on_grid(mx, my, mtau, x, y)
        if not np.all(np.isfinite(tau)) or np.min(tau) <= 0:
            raise _FieldProblem(
                f"strength.file = {_fmt(st['file'])}: tau_peak on the release area must be "
                "finite and > 0 Pa (missing map cells?)"
            )
    if st["kind"] != "file" and not np.min(tau) > 0:  # a falling trend (or a wide GRF)
        i, j = np.unravel_index(np.argmin(tau), tau.shape)
        keys = ", ".join(
            f"strength.{k} = {_fmt(st[k])}" for k in ("tau_peak", "mean", "trend", "std") if k in st
        )
        raise _FieldProblem(
            f"{keys}: these give tau_peak = {float(tau[i, j]):.4g} Pa at x = {x[i]:.3g} m, "
            f"y = {y[j]:.3g} m; the strength must stay > 0 Pa over the release area"
        )
    start = tuple(float(c) for c in setup.start)
    if ter.get("release") and "start_window" not in st:
        start = release_start(scn, tau)
    elif "start_window" in st:
        case = GenericSlopeCase(  # only its grid and window: no generic profile
            length=setup.length,
            width=setup.width,
            dx=setup.dx,
            start_window=tuple(st["start_window"]),
            planar=True,
        )
        try:
            start = weak_spot(case, tau)
        except ValueError as exc:
            raise _FieldProblem(f"strength.{exc}") from None
    if isinstance(fall, np.ndarray) and not np.any(fall):
        fall = 0.0
    return slope, fall, tau, start


def release_area_of(scn: Any) -> Any:
    """The `damjax.release_area.ReleaseArea` of a scenario with ``terrain.release``."""
    from damjax import release_area, terrain

    ter = scn.terrain
    return release_area.read_release_area(
        ter["release"],
        terrain.load_dem(ter["file"]),
        margin=float(ter.get("margin", 10.0)),
        upslope=ter.get("upslope"),
        thickness_field="",
    )


def release_start(scn: Any, tau: np.ndarray) -> tuple[float, float]:
    """The crack start of a ``terrain.release`` scenario: the weakest (2 m smoothed) spot
    of tau at least 2 m inside the polygon (anywhere inside it if it is narrower) [m]."""
    from damjax import release_area

    x, y = cell_centres(scn.setup)
    area = release_area_of(scn)
    inside = area.mask(x, y, buffer=2.0)
    if not np.any(inside):
        inside = area.mask(x, y)
    try:
        return release_area.weakest_inside(tau, x, y, scn.setup.dx, inside)
    except release_area.ReleaseAreaError as exc:
        raise _FieldProblem(str(exc)) from None


def prepare(scn: Any) -> simulation.PreparedSlope:
    """`damjax.slope.simulation.prepare` of a slope scenario: its fields read
    (`resolve_fields`) once the parameters and the grid are checked."""
    return simulation.prepare(
        scn.params,
        scn.setup,
        fields=lambda setup: resolve_fields(dataclasses.replace(scn, setup=setup)),
    )


def simulate(scn: Any, progress: bool = False, **resume: Any) -> Any:
    """Run a slope scenario: its checked run (`damjax.scenario.prepared`: the fields read
    and checked when the scenario was) integrated by `damjax.slope.simulation.run`
    (`SlopeResult`).

    ``resume``: `simulate_slope`'s state, start_chunk, history and callback (checkpoints).
    The summary gains ``upslope_arrest_position_m`` (from the lower edge [m]; None
    where the up-slope front did not arrest), ``start_m`` and ``start_slope_deg``.
    """
    prep = prepared(scn)
    setup, slope, start = prep.setup, prep.slope_deg, prep.setup.start
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        warnings.simplefilter("default", SlopeRunWarning)  # matched first: passed on
        for note in prep.notes:
            if note.category == "slope":
                warnings.warn(note.text(), SlopeRunWarning, stacklevel=2)
        res = simulation.run(prep, progress=progress, **resume)
    s = res.summary
    # from the lower edge, where the up-slope front arrested (None otherwise)
    d = s["upslope_arrest_distance_m"]
    s["upslope_arrest_position_m"] = None if d is None else start[0] + d
    s["start_m"] = [start[0], start[1]]
    i = min(int(start[0] / setup.dx), np.shape(slope)[0] - 1)
    j = min(int(start[1] / setup.dx), np.shape(slope)[1] - 1)
    s["start_slope_deg"] = float(np.asarray(slope)[i, j])
    return res
