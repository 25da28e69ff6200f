"""Slope scenarios resolved to fields: the slope angle, fall-line direction and strength
[deg, deg, Pa] at the cell centres of the release area, from a plane, the generic slope
or a DEM and from a constant, a Gaussian random field or a strength map; `prepare`, the
checked run of a slope scenario (`damjax.slope.simulation.prepare` on these fields), and
`simulate`, its run.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from typing import Any

import numpy as np

from damjax import snow_cover
from damjax.constants import G_ACC
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


# below this mean resultant length of the fall directions (1: one aspect; 0.64: a half
# bowl) the release area spans a ridge or a whole bowl and has no up-slope axis
RIDGE_RESULTANT = 0.3
_AXES = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}


def centre_line_profile(
    ter: Any,
    a_max: float,
    yc: float,
    origin: tuple[float, float] = (0.0, 0.0),
    upslope: str = "+x",
    *,
    nodata: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """The surface profile of a release area's centre line: map distance a [m] from the
    origin along ``upslope`` (0 to ``a_max``, 5 cm apart) and the surface distance s(a) [m],
    on the line ``yc`` [m] across (`dem_fields`; `damjax.export.gis.frame_of` maps a run's
    cells back to the map through the same profile).

    With ``nodata`` (a domain the terrain bounds: a rectangle clipped to the DEM), the line
    is clipped to the DEM, so the profile's tail beyond it is flat, and missing DEM cells
    are bridged; without it, they are a ValueError.
    """
    u = np.array(_AXES[upslope])
    v = np.array([-u[1], u[0]])
    o = np.asarray(origin, dtype=float)
    a = np.linspace(0.0, a_max, max(2, int(math.ceil(a_max / 0.05)) + 1))
    line = o[:, None] + u[:, None] * a[None, :] + v[:, None] * yc
    if nodata:
        line = np.stack(
            [np.clip(line[0], ter.x[0], ter.x[-1]), np.clip(line[1], ter.y[0], ter.y[-1])]
        )
    z = ter.sample(line[0], line[1])
    if nodata and np.any(np.isfinite(z)):
        ok = np.isfinite(z)
        z = np.interp(a, a[ok], z[ok])
    if not np.all(np.isfinite(z)):
        raise ValueError("missing DEM cells (nodata) under the release area")
    return a, np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(a), np.diff(z)))])


def dem_fields(
    ter: Any,
    x: np.ndarray,
    y: np.ndarray,
    origin: tuple[float, float] = (0.0, 0.0),
    upslope: str = "+x",
    *,
    nodata: bool = False,
    map_points: bool = False,
) -> Any:
    """Local slope angle and fall direction [deg] of a DEM at release-area points.

    The release area's x axis points along the DEM axis ``upslope``, its y axis 90 deg
    counter-clockwise from it (to the left, looking up-slope), its (0, 0) (the down-slope
    corner on the right, looking up-slope) at the map point ``origin`` [m].
    x is a distance along the surface (mapped to the map through the surface profile of
    the area's centre line), y a map distance.

    Args:
        ter: a `damjax.terrain.Terrain` (x, y map coordinates [m], z elevation [m]).
        x: up-slope surface coordinates (nx,) [m]; y: cross-slope coordinates (ny,) [m].
        origin: map coordinates of the release area's (0, 0) [m].
        upslope: "+x", "-x", "+y" or "-y".

        nodata: missing DEM cells give NaN slope and fall (the caller masks them: a
            domain the terrain bounds) instead of a ValueError; the centre line's
            surface profile bridges them.
        map_points: also return the cells' map coordinates (px, py), each (nx, ny) [m].

    Returns:
        (slope_deg, fall_deg), each (nx, ny): the slope angle psi and the direction of the
        local fall line relative to -x (0: straight down the release area's x axis);
        with ``map_points``, (slope_deg, fall_deg, px, py).
        ValueError if the area leaves the DEM or hits missing cells.
    """
    u = np.array(_AXES[upslope])
    v = np.array([-u[1], u[0]])
    o = np.asarray(origin, dtype=float)
    a_max = float(x[-1]) + float(x[1] - x[0] if x.size > 1 else 1.0)
    yc = 0.5 * (float(y[0]) + float(y[-1]))
    a, s = centre_line_profile(ter, a_max, yc, origin, upslope, nodata=nodata)
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

    qx, qy = px, py
    if nodata:  # cells off the DEM: no data
        qx, qy = np.clip(px, ter.x[0], ter.x[-1]), np.clip(py, ter.y[0], ter.y[-1])
        off = (qx != px) | (qy != py)
        gx, gy = np.where(np.isfinite(ter.z), gx, np.nan), np.where(np.isfinite(ter.z), gy, np.nan)
    gxs = Terrain(ter.x, ter.y, gx).sample(qx, qy)
    gys = Terrain(ter.x, ter.y, gy).sample(qx, qy)
    if nodata:
        gxs, gys = np.where(off, np.nan, gxs), np.where(off, np.nan, gys)
    if not nodata and not (np.all(np.isfinite(gxs)) and np.all(np.isfinite(gys))):
        raise ValueError("missing DEM cells (nodata) under the release area")
    gu = gxs * u[0] + gys * u[1]
    gv = gxs * v[0] + gys * v[1]
    slope = np.degrees(np.arctan(np.hypot(gu, gv)))
    fall = np.degrees(np.arctan2(gv, gu))
    return (slope, fall, px, py) if map_points else (slope, fall)


@dataclasses.dataclass
class SlopeInputs:
    """What a slope scenario gives `damjax.simulate_slope` (`resolve_inputs`), on the
    cell centres of the release area.

    Attributes:
        slope_deg, fall_deg: slope angle and fall direction [deg] (scalars for a plane).
        tau_peak: weak-layer strength [Pa] (nx, ny): the absolute strength of the
            "constant", "grf" and "map" kinds, the cohesion of "coulomb", and, for
            "stability", S rho g h0 sin(psi) (plus mu rho g h0 cos(psi) with a
            ``friction_coefficient`` mu) on the cells (the particles take S times their own
            load: `damjax.core.model.slope_particle_fields`).
        start: the crack start (x, y) [m].
        thickness: slab thickness h0 normal to the slope [m] (nx, ny); None: uniform
            ``params.thickness`` (the model of earlier versions).
        cover: snow-covered cells (nx, ny) bool; None: every cell.
        stability: the stability ratio S = tau_p / tau_g (nx, ny) ("stability").
        wl_friction: the friction coefficient of the weak layer's strength ("coulomb").
        domain: cells of the domain (the buffer around a release polygon, within the DEM's
            data), None: the rectangle; its edge is where a release counts as bounded by
            the domain (summary ``domain_edge_fraction``).
        map_x, map_y: map coordinates of the cell centres [m] (DEM terrain), else None.
        start_zone: snow-covered cells in the slope band of release areas (with [snow]).
        dx: the cells' size [m].
        area_from_polygon: the area's length and width are a release polygon's (plus its
            buffer or margin), not the user's.
        terrain_slope_deg: the terrain's slope angle [deg] on every cell, also where no
            snow lies (NaN off the DEM's data); None: ``slope_deg`` (every cell holds snow).
            The run's slope map shows it where no slab lies.
    Cells without snow carry their nearest snow-covered neighbour's values (they enter
    the interpolation of the particles beside them).
    """

    slope_deg: Any
    fall_deg: Any
    tau_peak: np.ndarray
    start: tuple[float, float]
    thickness: np.ndarray | None = None
    cover: np.ndarray | None = None
    stability: np.ndarray | None = None
    wl_friction: float | None = None
    domain: np.ndarray | None = None
    map_x: np.ndarray | None = None
    map_y: np.ndarray | None = None
    start_zone: np.ndarray | None = None
    dx: float = 1.0
    area_from_polygon: bool = False
    terrain_slope_deg: np.ndarray | None = None

    def snow_kwargs(self) -> dict[str, Any]:
        """`damjax.core.model.build_slope`'s snow and weak-layer keywords."""
        return {
            "thickness": self.thickness,
            "cover": self.cover,
            "stability": self.stability,
            "wl_friction": self.wl_friction,
        }

    def build(self, scn: Any, layout: Any) -> tuple[Any, Any]:
        """(model, initial state) of scenario ``scn`` on ``layout`` (an ensemble member's,
        on the members' shared layout), started at `start` (`damjax.core.model.build_slope`
        with these inputs; a prepared run builds with `damjax.slope.simulation.build`)."""
        from damjax.core.model import build_slope

        setup = dataclasses.replace(scn.setup, start=self.start)
        model, state, _, _ = build_slope(
            scn.params,
            setup,
            layout,
            self.slope_deg,
            self.tau_peak,
            self.fall_deg,
            **self.snow_kwargs(),
        )
        return model, state

    @property
    def max_slope_deg(self) -> float:
        """The steepest snow-covered cell [deg] (it sets the layout's padding)."""
        from damjax.slope.simulation import steepest_covered

        return steepest_covered(self.slope_deg, self.cover)

    def to_map(self, x: float, y: float) -> tuple[float, float] | None:
        """Map coordinates of the cell centre nearest to (x, y) [m] (None off a DEM)."""
        if self.map_x is None or self.map_y is None:
            return None
        nx, ny = self.map_x.shape
        i = int(np.clip(np.floor(x / self.dx), 0, nx - 1))
        j = int(np.clip(np.floor(y / self.dx), 0, ny - 1))
        return float(self.map_x[i, j]), float(self.map_y[i, j])


def resolve_fields(scn: Any) -> tuple[Any, Any, np.ndarray, tuple[float, float]]:
    """(slope_deg, fall_deg, tau_peak, start) of a slope scenario on its cell centres.

    slope_deg and fall_deg are scalars for a plane, (nx, ny) arrays [deg] otherwise;
    tau_peak is (nx, ny) [Pa]; start (x, y) [m] is ``setup.start`` or the weak spot in
    ``strength.start_window``. Raises a one-line ValueError for unreadable files.
    `resolve_inputs` has the rest: the snow cover and the weak layer's own load.
    """
    inp = resolve_inputs(scn)
    return inp.slope_deg, inp.fall_deg, inp.tau_peak, inp.start


def resolve_inputs(scn: Any, natural_release: bool = True) -> SlopeInputs:
    """Every input a slope scenario gives `damjax.simulate_slope` (`SlopeInputs`): the
    terrain, snow cover and weak-layer fields and the crack start, read on its grid.

    Raises a one-line ValueError for unreadable files, and, with ``natural_release``
    (the default) unless ``strength.natural_release`` is true, when the weak layer of a
    snow-covered particle outside the trigger fails under its own slab at t = 0
    (`natural_release_problem`). A scenario's loader reads its inputs once, with
    ``natural_release = False``, and checks that on the prepared run
    (`damjax.slope.simulation.PreparedSlope.load_ratio`).
    """
    inp = _resolve(scn)
    if natural_release and not (scn.strength or {}).get("natural_release", False):
        setup = dataclasses.replace(scn.setup, start=inp.start)
        ratio = simulation.load_ratio(
            scn.params, setup, inp.slope_deg, inp.tau_peak, inp.fall_deg, **inp.snow_kwargs()
        )
        problem = natural_release_problem(setup, ratio, inp.cover, inp)
        if problem:
            raise _FieldProblem(problem + NATURAL_RELEASE_ADVICE)
    return inp


def _resolve(scn: Any) -> SlopeInputs:
    from damjax import fields, terrain

    setup, params = scn.setup, scn.params
    x, y = cell_centres(setup)
    ter = scn.terrain or {"kind": "plane"}
    snow = scn.snow
    fall: Any = 0.0
    map_x = map_y = None
    domain = None
    area = None
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
        if ter.get("release"):
            area = release_area_of(scn)
        # a domain the terrain bounds (a release polygon's buffer, or a snow cover on a
        # DEM): missing DEM cells are outside it instead of an error
        nodata = snow is not None or (area is not None and area.buffer is not None)
        try:
            dem = terrain.load_dem(ter["file"])
            slope, fall, map_x, map_y = dem_fields(
                dem,
                x,
                y,
                tuple(ter.get("origin", (0.0, 0.0))),
                ter.get("upslope", "+x"),
                nodata=nodata,
                map_points=True,
            )
        except FileNotFoundError:
            raise _FieldProblem(f"terrain.file = {_fmt(ter['file'])}: no such file") from None
        except (OSError, ValueError, ImportError, KeyError) as exc:
            msg = " ".join(str(exc).split())
            raise _FieldProblem(f"terrain.file = {_fmt(ter['file'])}: {msg}") from None
        if nodata:
            domain = np.isfinite(slope) & np.isfinite(fall)
            if area is not None:
                domain &= area.domain_mask(x, y)
            if not domain.any():
                o = [float(c) for c in ter.get("origin", (0.0, 0.0))]
                raise _FieldProblem(
                    f"terrain.origin = {o}: no DEM data in the domain: the release area "
                    "is laid on the DEM along its centre line from terrain.origin, which "
                    f"must run over the DEM's data ({_fmt(ter['file'])} spans x "
                    f"[{dem.x[0]:.10g}, {dem.x[-1]:.10g}], y [{dem.y[0]:.10g}, {dem.y[-1]:.10g}] "
                    "in its CRS)"
                )
            slope = np.where(domain, slope, np.nan)
            fall = np.where(domain, fall, np.nan)
            off = _off_dem(dem, map_x, map_y)
            if area is None and off.any():
                warnings.warn(
                    f"terrain.origin, setup.length, setup.width: {100 * off.mean():.0f} % of "
                    f"the window lies off the DEM ({_fmt(ter['file'])} spans x "
                    f"[{dem.x[0]:.10g}, {dem.x[-1]:.10g}], y [{dem.y[0]:.10g}, {dem.y[-1]:.10g}]"
                    " in its CRS): those cells hold no snow",
                    stacklevel=2,
                )
        # fall 0 deg: straight down -x; over 90 deg the "up-slope" axis goes downhill
        sel = np.isfinite(fall)
        f = np.radians(np.asarray(fall, dtype=float)[sel])
        mean_up = float(np.mean(np.cos(f) * np.sin(np.radians(np.asarray(slope)[sel]))))
        mean_fall = float(np.degrees(np.angle(np.mean(np.exp(1j * f)))))
        up = ter.get("upslope", "+x")
        # a ridge or a whole bowl: fall lines that cancel leave no up-slope direction
        resultant = float(np.abs(np.mean(np.exp(1j * f)))) if f.size else 1.0
        if resultant < RIDGE_RESULTANT:
            raise _FieldProblem(
                f"terrain: the release area's slopes face opposite ways (across a ridge "
                f"or around a bowl: their fall directions' mean resultant length is "
                f"{resultant:.2f}, 1 for one aspect), so no up-slope axis fits it; split "
                "the release polygon (or the window) where the aspect turns"
            )
        if mean_up < 0 and abs(mean_fall) > 91.0:  # across it (90 +- 1): warned below
            how = "falls across" if abs(mean_fall) < 135.0 else "descends along"
            raise _FieldProblem(
                f'terrain.upslope = "{up}": the terrain {how} this axis over the release '
                f"area (its mean fall line is {mean_fall:.0f} deg from the release area's "
                "down-slope direction); give terrain.upslope as the DEM axis that points "
                'up-slope ("+x", "-x", "+y" or "-y")'
            )
        if abs(mean_fall) > 45.0:
            up = ter.get("upslope", "+x")
            warnings.warn(
                f'terrain.upslope = "{up}": the mean fall line is {mean_fall:.0f} deg off this '
                "axis over the release area, so 'up-slope' and 'cross-slope' results follow "
                "the axis, not the terrain (the DEM axis closest to the fall line: leave "
                "upslope out with a release polygon, or pick it)",
                stacklevel=2,
            )

    # snow cover: thickness and the cells that hold a slab
    thickness = None
    cover = domain
    zone = None
    terrain_slope = None
    if snow is not None:
        thickness, cover = _snow_cover(scn, slope, map_x, map_y, domain)
        s = {**_SNOW_DEFAULTS, **snow}
        zone = snow_cover.start_zone(
            slope,
            cover,
            min_slope_deg=float(s["start_min_slope_deg"]),
            max_slope_deg=float(s["max_slope_deg"]),
        )
    if cover is not None:
        if not cover.any():
            raise _FieldProblem(_no_slab_problem(scn, thickness, domain))
        terrain_slope = np.asarray(slope, float)
        slope = snow_cover.fill_from_nearest(slope, cover)
        fall = snow_cover.fill_from_nearest(fall, cover)
        if thickness is not None:
            thickness = snow_cover.fill_from_nearest(thickness, cover)
        if cover.all():
            cover = None
    if isinstance(fall, np.ndarray) and not np.any(fall):
        fall = 0.0
    h_cells = float(params.thickness) if thickness is None else thickness
    tau_g = float(params.density) * G_ACC * h_cells * np.sin(np.radians(slope))
    # the slab's normal stress on the weak layer [Pa] (a friction coefficient's load)
    sigma_n = float(params.density) * G_ACC * h_cells * np.cos(np.radians(slope))

    # the weak layer
    st = scn.strength or {"kind": "constant"}
    stability = wl_friction = None
    if st["kind"] == "constant":
        tau0 = float(st.get("tau_peak", params.tau_peak))
        tau = np.repeat((tau0 + float(st.get("trend", 0.0)) * x)[:, None], y.size, axis=1)
    elif st["kind"] in ("grf", "coulomb"):
        import jax

        g = {**_GRF_DEFAULTS, **st}
        mean_key = "mean" if st["kind"] == "grf" else "cohesion"
        mean = float(st.get(mean_key, params.tau_peak))
        if st["kind"] == "coulomb" and "std" not in st:
            g["std"] = 0.0
        try:
            tau = fields.plateau_trend_field(
                jax.random.key(int(g["seed"])),
                x,
                y.size,
                setup.dx,
                mean=mean,
                mean_at=float(g["mean_at"]),
                trend=float(g["trend"]),
                std=float(g["std"]),
                trend_deg=float(g["trend_deg"]),
                **_correlation(g, st),
            )
        except ValueError as exc:  # field_dx coarser than the correlation allows
            raise _FieldProblem(f"strength.{exc}") from None
        if st["kind"] == "coulomb":
            wl_friction = float(st["friction_coefficient"])
            if not np.all(tau + wl_friction * sigma_n > 0):
                raise _FieldProblem(
                    f"strength.cohesion = {_fmt(st.get('cohesion'))}, "
                    f"strength.friction_coefficient = {_fmt(st['friction_coefficient'])}: "
                    "the strength must stay > 0 Pa"
                )
    elif st["kind"] == "stability":
        import jax

        g = {**_GRF_DEFAULTS, **_STABILITY_DEFAULTS, **st}
        try:
            stability = fields.stability_field(
                jax.random.key(int(g["seed"])),
                x,
                y.size,
                setup.dx,
                mean=float(g["mean"]),
                cov=float(g["cov"]),
                **_correlation(g, st),
            )
        except ValueError as exc:
            raise _FieldProblem(f"strength.{exc}") from None
        tau = stability * tau_g
        if "friction_coefficient" in st:  # a floor that follows the normal load
            wl_friction = float(st["friction_coefficient"])
            tau = tau + wl_friction * sigma_n
        flat = (tau <= 0) if cover is None else (tau <= 0) & cover
        if np.any(flat):
            raise _FieldProblem(
                f'strength.kind = "stability": {int(np.sum(flat))} snow-covered cells are '
                "flat (0 deg), where S tau_g = S rho g h0 sin(psi) gives the weak layer no "
                "strength; give strength.friction_coefficient (a floor mu rho g h0 cos(psi) "
                "that follows the slab's weight) or leave them out with snow.mask"
            )
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
    if st["kind"] not in ("stability", "coulomb") and not np.min(tau) > 0:
        # a falling trend (or a wide GRF)
        i, j = np.unravel_index(np.argmin(tau), tau.shape)
        keys = ", ".join(
            f"strength.{k} = {_fmt(st[k])}" for k in ("tau_peak", "mean", "trend", "std") if k in st
        )
        raise _FieldProblem(
            f"{keys}: these give tau_peak = {float(tau[i, j]):.4g} Pa at x = {x[i]:.3g} m, "
            f"y = {y[j]:.3g} m; the strength must stay > 0 Pa over the release area"
        )

    # the crack start: the weakest spot (tau_p for the absolute kinds as in earlier
    # versions; tau_p / tau_g where the strength follows the load), or a random one
    weakness = tau
    if st["kind"] == "stability":
        weakness = stability
    elif st["kind"] == "coulomb":
        tau_c = tau + wl_friction * sigma_n
        with np.errstate(divide="ignore", invalid="ignore"):  # flat cells: never the weakest
            weakness = np.where(tau_g > 0, tau_c / np.where(tau_g > 0, tau_g, 1.0), np.inf)
    snow_cells = np.ones((x.size, y.size), bool) if cover is None else cover
    start = tuple(float(c) for c in setup.start)
    if st.get("trigger") == "random":
        start = random_trigger(scn, zone if zone is not None else snow_cells, x, y)
    elif ter.get("release") and "start_window" not in st:
        start = release_start(scn, weakness, None if cover is None else snow_cells, area)
    elif "start_window" in st:
        case = GenericSlopeCase(  # only its grid and window: no generic profile
            length=setup.length,
            width=setup.width,
            dx=setup.dx,
            start_window=tuple(st["start_window"]),
            planar=True,
        )
        w = weakness if cover is None else np.where(snow_cells, weakness, np.inf)
        try:
            start = weak_spot(case, w)
        except ValueError as exc:
            raise _FieldProblem(f"strength.{exc}") from None
    inp = SlopeInputs(
        slope_deg=slope,
        fall_deg=fall,
        tau_peak=tau,
        start=start,
        thickness=thickness,
        cover=cover,
        stability=stability,
        wl_friction=wl_friction,
        domain=domain,
        map_x=map_x,
        map_y=map_y,
        start_zone=zone,
        dx=float(setup.dx),
        area_from_polygon=bool(ter.get("release")),
        terrain_slope_deg=terrain_slope,
    )
    return inp


# [snow] defaults (`damjax.snow_cover`)
_SNOW_DEFAULTS = {
    "max_slope_deg": snow_cover.MAX_SLOPE_DEG,
    "min_thickness": snow_cover.MIN_THICKNESS,
    "start_min_slope_deg": snow_cover.START_MIN_SLOPE_DEG,
}
# [strength] kind = "stability" defaults: the paper's baseline ratio tau_p / tau_g =
# 1000 Pa / 703 Pa and the low end of the 10-30 % variation of penetrometer strength maps
_STABILITY_DEFAULTS = {"mean": 1.42, "cov": 0.1}


def _snow_cover(
    scn: Any, slope: Any, map_x: Any, map_y: Any, domain: Any
) -> tuple[np.ndarray | None, np.ndarray]:
    """(thickness map or None for a uniform slab, cover) of a scenario's [snow] table."""
    sn = {**_SNOW_DEFAULTS, **scn.snow}
    kind = sn.get("kind", "uniform")
    psi = np.broadcast_to(np.asarray(slope, dtype=float), cell_shape(scn.setup))
    thickness = None
    if kind == "slope_corrected":
        d0 = float(sn.get("reference_thickness", scn.params.thickness))
        thickness = d0 * snow_cover.slope_correction(psi)
    elif kind == "depth_map":
        hs = _snow_raster(scn, "file", map_x, map_y, domain)
        negative = np.isfinite(hs) & (hs < 0)
        if domain is not None:
            negative &= domain
        if np.any(negative):
            raise _FieldProblem(
                f"snow.file = {os.path.basename(sn['file'])!r}: snow depths down to "
                f"{np.min(hs[negative]):.3g} m on {int(np.sum(negative))} cells of the "
                "domain: must be >= 0 m (no snow: 0 or nodata)"
            )
        thickness = snow_cover.depth_to_thickness(hs, psi)
    if thickness is not None:  # valid, but beyond the slabs of dry-snow slab avalanches
        from damjax.params import PSTParams, specs

        plausible = specs(PSTParams)["thickness"].plausible
        cells = np.isfinite(thickness) if domain is None else np.isfinite(thickness) & domain
        thick = float(np.max(thickness[cells])) if np.any(cells) else 0.0
        if thick > plausible.hi:
            hint = ""
            if kind == "depth_map" and thick / 100.0 <= plausible.hi:
                hint = (
                    ": did you mean centimetres? snow.file must hold the depth HS in m "
                    "(divide a raster in cm by 100)"
                )
            warnings.warn(
                f"snow: slab thicknesses up to {thick:.3g} m, above the {plausible.hi:g} m "
                f'of dry-snow slab avalanches ({plausible}; snow.kind = "{kind}"){hint}',
                stacklevel=2,
            )
    mask = None
    if "mask" in sn and str(sn["mask"]).lower().endswith(snow_cover.POLYGON_SUFFIXES):
        mask = _snow_polygons(scn, map_x, map_y, domain)
    elif "mask" in sn:
        m = _snow_raster(scn, "mask", map_x, map_y, domain, nearest=True)
        mask = np.isfinite(m) & (m != 0)
    # a uniform slab thinner than snow.min_thickness is no slab either
    h_min_test = thickness
    if thickness is None:
        h_min_test = np.full(psi.shape, float(scn.params.thickness))
    cov = snow_cover.cover(
        psi,
        max_slope_deg=float(sn["max_slope_deg"]),
        mask=mask,
        thickness=h_min_test,
        min_thickness=float(sn["min_thickness"]),
    )
    if domain is not None:
        cov &= domain
    return thickness, cov


def _snow_polygons(scn: Any, map_x: Any, map_y: Any, domain: Any) -> np.ndarray:
    """The cells inside the polygons of ``snow.mask`` (a vector layer in the DEM's CRS):
    no snow there (`damjax.snow_cover.polygon_mask`); a warning when none lies in the
    domain (a layer of another region, or in another CRS without a .prj)."""
    file = scn.snow["mask"]
    name = repr(os.path.basename(str(file)))
    if map_x is None or map_y is None:
        raise _FieldProblem('snow.mask: polygons need a DEM terrain (terrain.kind = "dem")')
    try:
        inside, crs, bounds = snow_cover.polygon_mask(file, map_x, map_y)
    except ValueError as exc:
        raise _FieldProblem(str(exc)) from None
    _check_crs(scn, "mask", name, crs)
    cells = np.ones(np.shape(map_x), bool) if domain is None else np.asarray(domain, bool)
    if not np.any(inside & cells):
        x0, y0, x1, y1 = bounds
        warnings.warn(
            f"snow.mask = {name}: no polygon reaches the domain, nothing is masked (the "
            f"polygons span x [{x0:.1f}, {x1:.1f}], y [{y0:.1f}, {y1:.1f}]; the domain x "
            f"[{np.min(map_x[cells]):.1f}, {np.max(map_x[cells]):.1f}], y "
            f"[{np.min(map_y[cells]):.1f}, {np.max(map_y[cells]):.1f}] m, the DEM's CRS"
            f"{'' if crs else '; the layer names no CRS'})",
            stacklevel=2,
        )
    return inside


def _no_slab_problem(scn: Any, thickness: Any, domain: Any) -> str:
    """The line for a domain without a slab, naming the slab's thickness where it is
    below snow.min_thickness everywhere."""
    sn = {**_SNOW_DEFAULTS, **(scn.snow or {})}
    h = np.full(cell_shape(scn.setup), float(scn.params.thickness))
    if thickness is not None:
        h = np.asarray(thickness, float)
    cells = np.isfinite(h) if domain is None else np.isfinite(h) & np.asarray(domain, bool)
    h_max = float(np.max(h[cells])) if np.any(cells) else None
    if h_max is not None and h_max < float(sn["min_thickness"]):
        where = "params.thickness" if thickness is None else f'snow.kind = "{sn.get("kind")}"'
        if thickness is None and (scn.terrain or {}).get("release"):
            where = "the release polygon's thickness attribute, or params.thickness"
        return (
            f"snow: no cell of the domain holds a slab: the slab is at most {h_max:.3g} m "
            f"thick ({where}), below snow.min_thickness = {float(sn['min_thickness']):g} m"
        )
    return (
        "snow: no cell of the domain holds a slab (snow.max_slope_deg, snow.mask, "
        "snow.min_thickness, or the DEM's nodata)"
    )


def _off_dem(dem: Any, map_x: Any, map_y: Any) -> Any:
    """The cells whose map point lies outside the DEM's nodes (not its nodata holes)."""
    mx, my = np.asarray(map_x, float), np.asarray(map_y, float)
    return (mx < dem.x[0]) | (mx > dem.x[-1]) | (my < dem.y[0]) | (my > dem.y[-1])


def _check_crs(scn: Any, key: str, name: str, crs: str | None) -> None:
    """_FieldProblem when snow.<key>'s CRS (WKT; None: it names none) is not the DEM's."""
    try:
        from damjax.release_area import _same_crs, dem_crs

        dcrs = dem_crs(scn.terrain["file"])
        if crs is None and dcrs is not None:  # read as the DEM's: said, not silently
            import pyproj

            warnings.warn(
                f"snow.{key} = {name}: states no CRS; read in the DEM's "
                f"({pyproj.CRS(dcrs).name!r}): give the file its CRS (a .prj, or the "
                "GeoTIFF's) if it is another",
                stacklevel=2,
            )
        if crs is not None and dcrs is not None and not _same_crs(crs, dcrs):
            import pyproj

            raise _FieldProblem(
                f"snow.{key} = {name}: CRS {pyproj.CRS(crs).name!r} differs from the "
                f"DEM's (terrain.file, {pyproj.CRS(dcrs).name!r}); reproject one of them"
            )
    except ImportError:  # without the GIS extra no file names a CRS damjax can read
        pass


def _snow_raster(
    scn: Any, key: str, map_x: Any, map_y: Any, domain: Any, *, nearest: bool = False
) -> np.ndarray:
    """The [snow] raster ``snow.<key>`` (a depth map or a mask) at the cells' map points
    (`damjax.snow_cover.sample_raster`), once it is read, in the DEM's CRS and covering
    every cell of the domain (nodata inside a depth map: no snow; inside a mask: not
    masked; outside the raster: an error)."""
    from damjax import terrain

    file = scn.snow[key]
    name = repr(os.path.basename(str(file)))  # as a polygon's (the path is resolved)
    if map_x is None or map_y is None:
        raise _FieldProblem(f'snow.{key}: a raster needs a DEM terrain (terrain.kind = "dem")')
    try:
        r = terrain.load_dem(file)
    except FileNotFoundError:
        raise _FieldProblem(f"snow.{key} = {name}: no such file") from None
    except (OSError, ValueError, ImportError, KeyError) as exc:
        msg = " ".join(str(exc).split())
        raise _FieldProblem(f"snow.{key} = {name}: {msg}") from None
    try:
        from damjax.release_area import dem_crs

        crs = dem_crs(file)
    except ImportError:  # without the GIS extra no file names a CRS damjax can read
        crs = None
    _check_crs(scn, key, name, crs)
    cells = np.ones(np.shape(map_x), bool) if domain is None else np.asarray(domain, bool)
    out = cells & ~snow_cover.raster_covers(r, map_x, map_y)
    if np.any(out):
        raise _FieldProblem(
            f"snow.{key} = {name}: covers {int(np.sum(cells) - np.sum(out))} of the "
            f"domain's {int(np.sum(cells))} cells (its extent x [{r.x[0] - 0.5 * r.dx:.1f}, "
            f"{r.x[-1] + 0.5 * r.dx:.1f}], y [{r.y[0] - 0.5 * r.dy:.1f}, "
            f"{r.y[-1] + 0.5 * r.dy:.1f}] m; the domain's x [{np.min(map_x[cells]):.1f}, "
            f"{np.max(map_x[cells]):.1f}], y [{np.min(map_y[cells]):.1f}, "
            f"{np.max(map_y[cells]):.1f}] m): it must cover the whole domain (nodata inside "
            f"it: {'not masked' if key == 'mask' else 'no snow there'})"
        )
    return snow_cover.sample_raster(r, map_x, map_y, nearest=nearest)


def _correlation(g: dict, st: dict) -> dict[str, Any]:
    """The random field's correlation keys of a strength table ``st`` (``g``: with its
    defaults), as `damjax.fields.plateau_trend_field` and `stability_field` take them."""
    return dict(
        length_scale=g["length_scale"],
        angle_deg=float(g["angle_deg"]),
        model=g["model"],
        field_dx=None if "field_dx" not in st else float(st["field_dx"]),
    )


def cell_shape(setup: Any) -> tuple[int, int]:
    """(nx, ny): the cells of a slope run's release area."""
    return int(round(setup.length / setup.dx)), int(round(setup.width / setup.dx))


TRIGGER_RADIUS = 2.0  # [m] the trigger: cells within it of the start may fail at t = 0


NATURAL_RELEASE_ADVICE = (
    ": a natural release, not a triggered one; make the weak layer hold its slab "
    '(strength.kind = "stability"), or set strength.natural_release = true to run it'
)


def natural_release_problem(
    setup: Any, ratio: np.ndarray, cover: Any = None, inputs: Any = None
) -> str | None:
    """One line when the weak layer of a snow-covered particle farther than
    `TRIGGER_RADIUS` from the crack start (``setup.start``) fails under its own slab at
    t = 0: ``ratio``, each particle's tau_p / tau_g in the model's own values
    (`damjax.slope.simulation.load_ratio`, particles of
    `damjax.core.model.slope_particles` on ``cover``), at most 1. The line gives how many
    cells, the area, their extent and the worst one (map coordinates on a DEM, from the
    `SlopeInputs` ``inputs``). Such a weak layer did not hold its slab until the trigger:
    the run would release the slope from every such cell at once (a natural release).
    None when there is none (and for traced runs, ``ratio`` None)."""
    from damjax.core.model import slope_particles

    if ratio is None:
        return None
    _, _, xp, yp = slope_particles(setup, cover=cover)
    far = np.hypot(xp - setup.start[0], yp - setup.start[1]) > TRIGGER_RADIUS
    fails = far & (np.asarray(ratio) <= 1.0)
    if not fails.any():
        return None
    dx = setup.dx
    cells = np.unique(np.floor(xp[fails] / dx).astype(int) * 10**7 + np.floor(yp[fails] / dx))
    worst_ratio = np.where(fails, ratio, np.inf)
    k = int(np.argmin(worst_ratio))
    worst = f"x = {xp[k]:.1f} m, y = {yp[k]:.1f} m"
    m = None if inputs is None else inputs.to_map(float(xp[k]), float(yp[k]))
    if m is not None:
        worst += f" (map {m[0]:.1f}, {m[1]:.1f})"
    box = (
        f"x {xp[fails].min():.1f}-{xp[fails].max():.1f} m, "
        f"y {yp[fails].min():.1f}-{yp[fails].max():.1f} m"
    )
    return (
        "strength: the weak layer fails under its own slab at t = 0 (rho g h sin psi "
        "reaches the stress at which it starts to fail: tau_p, or less for a brittle layer "
        "on coarse particles, damjax.materials.weak_layer.uniform_failure_stress) on "
        f"{cells.size} snow-covered cells ({cells.size * dx * dx:.4g} m^2) outside the "
        f"trigger, {box}, worst ratio {worst_ratio[k]:.3g} at {worst}"
    )


def release_area_of(scn: Any) -> Any:
    """The `damjax.release_area.ReleaseArea` of a scenario with ``terrain.release``."""
    from damjax import release_area, terrain

    ter = scn.terrain
    buffer = ter.get("buffer")
    return release_area.read_release_area(
        ter["release"],
        terrain.load_dem(ter["file"]),
        margin=float(ter.get("margin", 10.0)),
        upslope=ter.get("upslope"),
        thickness_field="",
        buffer=None if buffer is None else float(buffer),
    )


def release_start(
    scn: Any, tau: np.ndarray, snow: np.ndarray | None = None, area: Any = None
) -> tuple[float, float]:
    """The crack start of a ``terrain.release`` scenario: the weakest (2 m smoothed) spot
    of tau at least 2 m inside the polygon (anywhere inside it if it is narrower) [m];
    only on snow-covered cells where ``snow`` is given."""
    from damjax import release_area

    x, y = cell_centres(scn.setup)
    area = release_area_of(scn) if area is None else area
    inside = area.mask(x, y, buffer=2.0)
    if snow is not None:
        inside &= snow
    if not np.any(inside):
        inside = area.mask(x, y) if snow is None else area.mask(x, y) & snow
    try:
        return release_area.weakest_inside(tau, x, y, scn.setup.dx, inside)
    except release_area.ReleaseAreaError as exc:
        raise _FieldProblem(str(exc)) from None


def random_trigger(scn: Any, zone: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """A random crack start (``strength.trigger = "random"``): a cell of the start zone
    (at least 2 m inside it where it is wide enough), drawn with ``strength.seed``, so an
    ensemble's members start at their own random weak spots [m]."""
    from scipy import ndimage

    zone = np.asarray(zone, bool)
    k = max(1, int(round(2.0 / scn.setup.dx)))
    inner = ndimage.binary_erosion(zone, iterations=k, border_value=0)
    cand = inner if inner.any() else zone
    if not cand.any():
        raise _FieldProblem(
            'strength.trigger = "random": no snow-covered cell in the start zone '
            "(snow.start_min_slope_deg to snow.max_slope_deg)"
        )
    rng = np.random.default_rng(int((scn.strength or {}).get("seed", 0)))
    i, j = np.nonzero(cand)
    c = int(rng.integers(i.size))
    return float(x[i[c]]), float(y[j[c]])


def prepare(scn: Any) -> simulation.PreparedSlope:
    """`damjax.slope.simulation.prepare` of a slope scenario: its inputs read
    (`resolve_inputs`) once the parameters and the grid are checked, and the weak layer
    checked for a natural release (`natural_release_problem`; ValueError unless
    ``strength.natural_release`` is true)."""
    prep = simulation.prepare(
        scn.params,
        scn.setup,
        fields=lambda setup: resolve_inputs(
            dataclasses.replace(scn, setup=setup), natural_release=False
        ),
    )
    problem = natural_release_problem(prep.setup, prep.load_ratio, prep.cover, prep.source)
    if problem and not (scn.strength or {}).get("natural_release", False):
        raise ValueError(problem + NATURAL_RELEASE_ADVICE)
    return prep


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
    m = None if prep.source is None else prep.source.to_map(start[0], start[1])
    if m is not None:
        s["start_map_m"] = [m[0], m[1]]
    return res
