"""Slope-scale release on terrain: the 2D DA-MPM step over a release area.

Coordinates are surface coordinates: x along the fall line of the mean slope (up-slope
positive, as in the PST), y across the slope, both measured along the surface [m]. The
terrain enters through the local slope angle psi(x, y) (and optionally the local fall
direction): gravity has the slope-parallel component g sin(psi) along the local fall
line and the normal component g cos(psi), which sets the friction cap
tau_r = rho g h cos(psi) tan(phi). For release areas whose curvature radius is much
larger than the slab thickness this is the depth-averaged model of the paper's
Sect. 3.4; the slope angle is evaluated at each particle's reference position (slabs
slide metres, the terrain varies over tens of metres).

The crack starts at a weak spot (the paper's star) with the PST sawing procedure: the
cohesion is removed inside a disc whose radius grows at `saw_speed` until the crack
leads the saw by 0.5 m. All release-area edges are free.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from damjax import io, theory
from damjax._tracing import concrete_members, concrete_value, eager_if_concrete, is_traced
from damjax._version import __version__
from damjax.constants import G_ACC
from damjax.core.loop import integrate, integrate_pure
from damjax.core.model import (  # noqa: F401  (SlopeLayout: public here too)
    SlopeLayout,
    build_slope,
    make_slope_layout,
    slope_particle_fields,
    slope_particles,
    uniform_value,
)
from damjax.core.state import FAULT_MESSAGES, Model, State, raise_on_fault
from damjax.core.step import column_height
from damjax.diagnostics import ARREST_MARGIN, ARREST_QUIET, weak_layer_damage
from damjax.materials.slab_fracture import (
    FRACTURE_OPENING,
    band_opening,
    fracture_opening,
    fracture_strain,
)
from damjax.materials.weak_layer import uniform_failure_stress
from damjax.params import PSTParams, SlopeSetup
from damjax.validation import (
    InputError,
    Problem,
    concrete_only,
    ensure_x64,
    expect_types,
    lambda_problem,
    map_shape_problems,
    partial_cells,
    raise_if,
    require_x64,
    same_value,
    shape_problems,
    size_problem,
    slope_field_problems,
    slope_problems,
    slope_setup_problems,
    uniform_failure_stress_of,
)

SPEED_BAND = 1.0  # half-width of the bands along which crack speeds are measured [m]
SPEED_WINDOW_M = 4.0  # length of the sliding windows of the peak crack speed [m]


def _snapshot(model: Model, state: State) -> dict[str, Any]:
    return {
        "time": state.time,
        "height": column_height(model, state),
        "broken": jnp.isfinite(state.t_broken),
    }


@dataclasses.dataclass
class SlopeResult:
    """Maps on the cell grid (nx, ny) of the release area, and summary numbers; a pytree,
    so `jax.vmap` of `simulate_slope` returns one batched result.

    The maps are Lagrangian: each cell shows the particles that started in it, wherever
    they have slid since (``height`` is the final height of the slab that lay on the
    cell at t = 0, not of what lies there now); a released slab's displacement is in the
    final state (``final_state.npz``: ``state.u``).

    Attributes:
        x: (nx,) cell centres up-slope along the surface [m].
        y: (ny,) cell centres across the slope [m].
        height: (nx, ny) final slab column height h [m].
        arrival_time: (nx, ny) weak-layer failure time [s] (inf: intact).
        tension: (nx, ny) final slab tension sigma_xx [Pa].
        opening: (nx, ny) accumulated tensile plastic strain of the slab [-].
        tau_peak: (nx, ny) weak-layer peak shear strength tau_p [Pa].
        slope_deg: (nx, ny) local slope angle psi [deg].
        snapshots: per chunk: ``time`` [s], the height map [m] and the broken map (0/1).
        summary: diagnostics by name, units in the key (``release_area_m2``,
            ``upslope_extent_m``, ``wall_time_s``, ...); the slopes guide's "The summary"
            explains every key. ``upslope_front`` and ``crossslope_front`` say what the
            fronts did ("arrested", "reached_edge", "moving", "sawn_only"); the arrest
            distances are None unless that front arrested. ``release_area_m2`` counts
            the failed weak layer, each broken particle's area, the saw's cut included
            (``sawn_area_m2``; the maps mark a cell from its first failed particle, so
            with several particles per cell their failed cells can add up to more); where
            ``saw_stopped`` is False the crack never ran ahead of the saw and the
            release is the cut (a warning says so). ``initial_failure_area_m2``: the
            weak layer failing under the slab's own weight at t = 0 (tau_p <= rho g h0
            sin psi); ``outflow_particles`` / ``outflow_area_m2``: slab that slid out over
            the grid's edge (it leaves the run); ``domain_edge_fraction``: the share of the
            released area's boundary on the domain's edge (a warning above
            `DOMAIN_EDGE_WARN`); ``snow_area_m2``: the snow-covered area.
        setup: the `SlopeSetup` that was run.
        params: the `PSTParams` that were run.
        thickness: (nx, ny) initial slab thickness h0 normal to the slope [m] (0 where no
            snow lies; None in results read from files written before 2026-11-27).
        snow: (nx, ny) bool, the snow-covered cells (those that hold particles).
    """

    x: np.ndarray  # (nx,) cell centres up-slope [m]
    y: np.ndarray  # (ny,) cell centres across [m]
    height: np.ndarray  # final column height h [m]
    arrival_time: np.ndarray  # weak-layer failure time [s] (inf: intact)
    tension: np.ndarray  # final sigma_xx [Pa]
    opening: np.ndarray  # accumulated tensile plastic strain [-]
    tau_peak: np.ndarray  # weak-layer strength [Pa]
    slope_deg: np.ndarray  # local slope angle [deg]
    snapshots: dict[str, np.ndarray]  # per chunk: time, height map, broken map
    summary: dict[str, Any]
    setup: SlopeSetup
    params: PSTParams
    thickness: np.ndarray | None = None  # initial h0 [m] (0: no snow)
    snow: np.ndarray | None = None  # snow-covered cells (bool)

    def to_dataset(self) -> Any:
        """xarray Dataset of the maps and snapshots, CF-style units and long names.
        `damjax.slope.results.result_dataset` adds what a run's ``results.nc`` holds
        besides: the crack-speed map and the released / crown / stauchwall masks.
        Global attributes: ``setup`` and ``params`` (JSON; ``slope_deg`` and
        ``tau_peak`` are those of the maps where these hold one value, else the
        parameters' own), ``summary`` (JSON, without the timings) and the version."""
        import json

        import xarray as xr

        def var(dims: tuple[str, ...], data: Any, units: str, long_name: str) -> Any:
            return xr.Variable(dims, np.asarray(data), {"units": units, "long_name": long_name})

        at = np.where(np.isfinite(self.arrival_time), self.arrival_time, np.nan)
        ds = xr.Dataset(
            {
                "height": var(("x", "y"), self.height, "m", "slab column height"),
                "arrival_time": var(
                    ("x", "y"), at, "s", "weak-layer failure time (NaN: intact at the end)"
                ),
                "tension": var(("x", "y"), self.tension, "Pa", "slab tension sigma_xx"),
                "opening": var(("x", "y"), self.opening, "1", "tensile plastic strain"),
                "tau_peak": var(("x", "y"), self.tau_peak, "Pa", "weak-layer shear strength"),
                "slope_angle": var(("x", "y"), self.slope_deg, "degree", "local slope angle"),
                **(
                    {}
                    if self.thickness is None
                    else {
                        "thickness": var(
                            ("x", "y"), self.thickness, "m", "initial slab thickness h0"
                        )
                    }
                ),
                **(
                    {}
                    if self.snow is None
                    else {
                        "snow": var(
                            ("x", "y"), np.asarray(self.snow, np.int8), "1", "snow-covered cell"
                        )
                    }
                ),
            },
            coords={
                "x": var(("x",), self.x, "m", "up-slope distance along the surface"),
                "y": var(("y",), self.y, "m", "cross-slope distance along the surface"),
            },
        )
        if self.snapshots:
            # a coordinate, as a PST's: ds.swap_dims(snapshot="snapshot_time").sel(...)
            ds = ds.assign_coords(
                snapshot_time=var(
                    ("snapshot",), self.snapshots["time"], "s", "time of the snapshot"
                )
            )
            ds["height_snapshots"] = var(
                ("snapshot", "x", "y"), self.snapshots["height"], "m", "slab column height"
            )
            ds["released_snapshots"] = var(
                ("snapshot", "x", "y"),
                self.snapshots["broken"].astype(np.float32),
                "1",
                "released fraction of the weak layer",
            )
        ds.attrs = {
            "title": "damjax slope-scale release",
            "damjax_version": __version__,
            "setup": json.dumps(dataclasses.asdict(self.setup)),
            # strict JSON: inf (an elastic slab) as the string "inf", read back as float
            "params": json.dumps(
                _strict(
                    {
                        f.name: (
                            None
                            if getattr(self.params, f.name) is None
                            else np.asarray(getattr(self.params, f.name)).tolist()
                        )
                        for f in dataclasses.fields(self.params)
                    }
                    # a uniform slope or strength given as a map or argument is what ran
                    | _uniform_maps(self)
                ),
                allow_nan=False,
            ),
            "summary": io.to_json(
                {k: v for k, v in self.summary.items() if k not in io.TIMING_KEYS}
            ),
            "Conventions": "CF-1.10",
        }
        return ds

    def to_netcdf(self, path: str | os.PathLike[str]) -> None:
        """Write `to_dataset` to ``path`` (atomically: a temporary file, then a rename).
        `damjax.slope.results.load_result` reads it back; a run's ``results.nc`` also
        holds the crack-speed map and the crown, stauchwall and released masks
        (`damjax.slope.results.result_dataset`)."""
        if is_traced(self.height) or not isinstance(self.height, np.ndarray):
            raise TypeError(
                "SlopeResult.to_netcdf: a result of one concrete run only (not from "
                "inside jax.grad / jax.jit / jax.vmap)"
            )
        io.write_dataset(path, self.to_dataset())


def _uniform_maps(result: SlopeResult) -> dict[str, float]:
    """``slope_deg`` and ``tau_peak`` of a result whose maps hold one value on the
    snow-covered cells: the value that ran, not the parameters' default."""
    out = {}
    snow = None if result.snow is None else np.asarray(result.snow, bool)
    for name, grid in (("slope_deg", result.slope_deg), ("tau_peak", result.tau_peak)):
        v = np.asarray(grid, dtype=float)
        if snow is not None and snow.shape == v.shape:
            v = v[snow]
        v = v[np.isfinite(v)]
        # one value up to float32 round-off (a plane's map is computed, 38.000004 for 38):
        # 6 significant digits of it
        if v.size and np.ptp(v) <= 1e-6 * np.max(np.abs(v)):
            out[name] = float(f"{np.mean(v):.6g}")
    return out


jax.tree_util.register_dataclass(
    SlopeResult,
    data_fields=[
        "x",
        "y",
        "height",
        "arrival_time",
        "tension",
        "opening",
        "tau_peak",
        "slope_deg",
        "snapshots",
        "summary",
        "params",
        "thickness",
        "snow",
    ],
    meta_fields=["setup"],
)


def _fractured_cells(model: Any, final: Any, cm: Any) -> np.ndarray:
    """Cells (nx, ny) where the slab fractured: with a particle lattice (the "crack_band"
    slab) where a particle's band opening reached the fracture opening
    (`damjax.materials.slab_fracture.fracture_opening`, the same on every grid), else
    where the cell's mean opening strain reached
    `damjax.materials.slab_fracture.fracture_strain`."""
    if model.fracture.lattice:
        return cm(np.isfinite(np.asarray(final.t_fracture)).astype(float)) > 0.0
    return cm(final.opening) >= float(np.min(np.asarray(fracture_strain(model.fracture))))


def _crown_and_stauchwall(
    model: Any, final: Any, height: np.ndarray, h0: Any, cm: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Crown and stauchwall cells (nx, ny). With a particle lattice (the "crack_band"
    slab) from band openings, fixed in metres: the crown where the tensile band opening
    reached the fracture opening (`damjax.materials.slab_fracture.fracture_opening`), the stauchwall
    where the compressive band closure (the volumetric plastic compaction times the
    particle spacing, summed across the band as `damjax.materials.slab_fracture.band_opening` does)
    reached `FRACTURE_OPENING` (1 mm). Without one: the column height changed by more
    than 2 % of the initial thickness h0 (a scalar or the cells' (nx, ny) map; thresholds
    on h, which depend on dx)."""
    if not model.fracture.lattice:
        return height < 0.98 * h0, height > 1.02 * h0
    w = band_opening(model.fracture, final.opening, opening_y=final.opening_y)
    crown = np.asarray(w >= fracture_opening(model.fracture), float)
    closure = band_opening(model.fracture, jnp.maximum(-(final.eps_p[0] + final.eps_p[1]), 0.0))
    stauch = np.asarray(closure >= FRACTURE_OPENING, float)
    return cm(crown) > 0.0, cm(stauch) > 0.0


def _cell_map(
    values: np.ndarray,
    cell0: np.ndarray,
    pad: tuple[int, int],
    n_cells: tuple[int, int],
    reduce: str = "mean",
) -> np.ndarray:
    ix = cell0[0] - pad[0]
    iy = cell0[1] - pad[1]
    flat = ix * n_cells[1] + iy
    size = n_cells[0] * n_cells[1]
    if reduce == "min":
        out = np.full(size, np.inf)
        np.minimum.at(out, flat, values)
    else:
        out = np.bincount(flat, weights=values, minlength=size) / np.maximum(
            np.bincount(flat, minlength=size), 1
        )
    return out.reshape(n_cells)


def _front_speed(
    coord: np.ndarray,
    t: np.ndarray,
    lo: float,
    hi: float,
    window: float = SPEED_WINDOW_M,
    limit: float = math.inf,
) -> tuple[float, float]:
    """(mean, peak) speed [m/s] of the crack front along a band between ``lo`` and ``hi``.

    The front is the earliest arrival per 0.5 m bin (not late failures behind it). Mean:
    least squares of coordinate against arrival over the whole range (it averages the
    acceleration after the saw and the deceleration before the arrest in). Peak: the
    largest of the least-squares speeds over sliding windows of ``window`` metres, the
    counterpart of the PST's maximum crack speed (`damjax.diagnostics.crack_speed`).

    Speeds above ``limit`` [m/s] (the slab's fastest wave, `damjax.slope.results.
    front_speed_limit`) are no front's run along the band: there the cells failed together,
    or a front that came round from elsewhere crossed the band at a slant (an apparent
    speed; a real path's avaKot member of 2026-11-27 gave 25 c_s where the up-slope front
    met fronts from the sides). Such windows are left out, and a mean above it is NaN.
    """
    sel = np.isfinite(t) & (coord >= lo) & (coord <= hi)
    if sel.sum() < 5 or np.ptp(t[sel]) <= 0:
        return math.nan, math.nan
    bins = np.floor(coord[sel] / 0.5).astype(int)
    tb: dict[int, float] = {}
    for b, tt in zip(bins, t[sel], strict=True):
        tb[b] = min(tb.get(b, np.inf), tt)
    if len(tb) < 3:
        return math.nan, math.nan
    keys = sorted(tb)
    cb = np.array(keys) * 0.5 + 0.25
    tt = np.array([tb[k] for k in keys])
    # arrival times that fall with distance (a front from elsewhere, a noisy strength
    # field) have no speed along this band
    slope = float(np.polyfit(cb, tt, 1)[0])
    mean = 1.0 / slope if slope > 0 and 1.0 / slope <= limit else math.nan
    n_win = int(round(window / 0.5))
    speeds = []
    for i in range(cb.size):
        j = np.searchsorted(cb, cb[i] + window - 1e-9)
        if j - i >= max(3, n_win - 1) and np.ptp(tt[i:j]) > 0:
            slope = np.polyfit(cb[i:j], tt[i:j], 1)[0]
            if slope > 0 and 1.0 / slope <= limit:
                speeds.append(float(1.0 / slope))
    return mean, max(speeds, default=math.nan)


class SlopeRunWarning(UserWarning):
    """A slope run whose inputs or outcome need a look: a start at or below the friction
    angle, an area that is not a whole number of cells, a crack that never ran ahead of
    the saw (its release is the cut). Scenario runs pass these on (other warnings of
    `simulate_slope` are the scenario loader's to give)."""


def _slope_notes(
    params: PSTParams,
    setup: SlopeSetup,
    slope_deg: Any,
    fall_deg: Any = 0.0,
    area_given: bool = True,
) -> list[str]:
    """Valid but dubious slope inputs: a start at or below the friction angle (a released
    slab does not slide there, so the crack cannot run away from the saw), a length or
    width that is not a whole number of cells (the grid rounds it; not said where a
    release polygon, not the user, gave them: ``area_given`` False)."""
    notes = []
    psi = np.asarray(slope_deg, dtype=float)
    phi = float(params.friction_deg)
    x0, y0 = setup.start
    if psi.ndim == 2:
        i = min(max(int(x0 / setup.dx), 0), psi.shape[0] - 1)
        j = min(max(int(y0 / setup.dx), 0), psi.shape[1] - 1)
        psi_start = float(psi[i, j])
    else:
        psi_start = float(psi)
    if psi_start <= phi:
        notes.append(
            f"slope_deg = {psi_start:.3g} at the start ({x0:g}, {y0:g}) m: at or below "
            f"friction_deg = {phi:g}, a released slab does not slide there, so the crack "
            "does not run away from the saw (the paper's mechanism needs slope > friction)"
        )
    # as the scenario loader tests a DEM: over the area, not a ridge's single cells
    fall = np.radians(np.asarray(fall_deg, dtype=float))
    if float(np.mean(np.cos(fall) * np.sin(np.radians(psi)))) < 0:
        notes.append(
            "fall_deg: the fall line is more than 90 deg from -x over the area, so its x "
            "axis points down the slope and 'up-slope' results follow x"
        )
    for name, v, grid in partial_cells(setup, ("length", "width")) if area_given else ():
        notes.append(
            f"{name} = {v:g}: not a whole number of cells of dx = {setup.dx:g}; the "
            f"area is {grid:.6g} m {'long' if name == 'length' else 'wide'}"
        )
    return notes


def _domain_notes(
    params: PSTParams, setup: SlopeSetup, slope_deg: Any, cover: Any, domain: Any
) -> list[Problem]:
    """A domain the terrain should bound (``domain``: a release polygon's buffer within
    the DEM) whose edge the start's `sliding_region` reaches above `DOMAIN_EDGE_WARN`:
    unless the weak layer or the slab stops the crack inside it, the release will end on
    the domain's edge (said before the run, not after it)."""
    phi = float(params.friction_deg)
    # the start within the area (checked) may lie beyond the grid's last cell where the
    # area is not a whole number of cells (30 m at dx 0.46: 65 cells, 29.9 m): that cell
    size = np.shape(slope_deg)
    start = tuple(min(float(c), n * setup.dx) for c, n in zip(setup.start, size, strict=True))
    region = sliding_region(slope_deg, phi, start, setup.dx, cover, domain)
    frac = domain_edge_fraction(region, domain)  # None when the region is empty
    if frac is None or frac <= DOMAIN_EDGE_WARN:
        return []
    area = float(region.sum()) * setup.dx**2
    return [
        Problem(
            None,
            frac,
            f"the snow steeper than friction_deg = {phi:g} that the start connects to "
            f"({area:.6g} m^2, where a released slab slides) has {100 * frac:.3g} % of its "
            "boundary on the domain's edge: unless the weak layer or the slab stops the "
            "crack inside it, the release is bounded by the domain, not the terrain "
            "(a larger domain, e.g. a release polygon's terrain.buffer, or what bounds it "
            "on the ground: a snow-depth map, a mask)",
            form="line",
            setup=SlopeSetup,
            category="slope",
        )
    ]


def overloaded_fraction(
    params: PSTParams, slope_deg: Any, tau_peak: Any, thickness: Any = None
) -> float:
    """Share of the cells where tau_p <= rho g h sin(psi): the weak layer fails there
    under the slab's weight (scalars or (nx, ny) maps, broadcast; ``thickness`` [m]:
    default ``params.thickness``)."""
    psi = np.radians(np.asarray(slope_deg, dtype=float))
    h = float(params.thickness) if thickness is None else np.asarray(thickness, dtype=float)
    tau_g = float(params.density) * G_ACC * h * np.sin(psi)
    return float(np.mean(np.asarray(tau_peak, dtype=float) <= tau_g))


def initial_failures(model: Model) -> Any:
    """(n,) bool: particles whose weak layer fails under the slab's own weight at t = 0,
    rho g h0 sin(psi) at or above the stress at which the uniformly loaded layer starts
    to fail (`damjax.materials.weak_layer.uniform_failure_stress`: tau_p, or less for a
    brittle layer on coarse particles), in the model's own values (h0 and psi at each
    particle)."""
    from damjax.core.step import front_width

    wl = model.weak_layer
    g_t = jnp.sqrt(model.g_tangent[0] ** 2 + model.g_tangent[1] ** 2)
    fails_at = uniform_failure_stress(wl.tau_peak, wl.stiffness, wl.u_res, front_width(model))
    return fails_at <= model.slab.density * model.slab.thickness * g_t


def source_reach(model: Model) -> float:
    """How far [m] one failure reaches within the same front: 3 dx, the reach of one step
    of the quadratic B-spline stencil along an axis (a particle's slip moves the nodes
    within 1.5 dx of it, and they the particles within 1.5 dx of them), plus the slab's
    elastic length Lambda = sqrt(E h0 / ((1 - nu^2) K)) at its thickest, over which a
    crack tip's shear stress decays ahead of it: a cell with next to no strength to spare
    (S close to 1, or a near-flat cell of a stability-ratio layer) fails there a step
    before the tip arrives."""
    slab = model.slab
    return reach_of(
        model.grid.dx,
        float(np.max(np.asarray(slab.youngs_modulus))),
        float(np.min(np.asarray(slab.poisson))),
        float(np.max(np.asarray(slab.thickness))),
        float(np.min(np.asarray(model.weak_layer.stiffness))),
    )


def reach_of(dx: float, youngs_modulus: float, poisson: float, thickness: float, k: float) -> float:
    """`source_reach` from its values: dx [m], E [Pa], nu [-], the largest h0 [m] and the
    weak layer's stiffness K = G_wl / D_wl [Pa/m]."""
    lam = math.sqrt(youngs_modulus * thickness / ((1.0 - poisson * poisson) * k))
    return 3.0 * dx + lam


def arrival_sources(arrival_time: np.ndarray, dx: float, reach_m: float | None = None) -> int:
    """How many sources the arrival-time map ((nx, ny) failure times [s] on cells of
    ``dx`` [m]; inf or NaN: never failed) has: places whose cells failed with no earlier
    failure within ``reach_m`` [m] of them (the reach of one failure within the same
    front, `source_reach`; None: 3 dx, the B-spline stencil's alone). Such cells that are
    neighbours or no farther than ``reach_m`` apart (between cell centres) are one source.
    A crack that ran from the trigger alone has one (the trigger); every weak spot that
    failed by itself adds one. 0 when nothing released."""
    from scipy import ndimage, sparse
    from scipy.spatial import cKDTree

    t = np.asarray(arrival_time)
    if t.dtype == bool or t.ndim != 2:
        raise ValueError(
            f"arrival_sources: arrival_time is {t.dtype} of shape {t.shape}; must be a map "
            "(nx, ny) of failure times [s] (inf or NaN: never failed)"
        )
    if not (dx > 0 and math.isfinite(dx)):
        raise ValueError(f"arrival_sources: dx = {dx}; must be a finite number > 0 m")
    if reach_m is not None and not (reach_m >= 0 and math.isfinite(reach_m)):
        raise ValueError(f"arrival_sources: reach_m = {reach_m}; must be a finite number >= 0 m")
    t = np.asarray(t, dtype=float)
    t = np.where(np.isfinite(t), t, np.inf)
    if not np.isfinite(t).any():
        return 0
    reach = 3.0 * dx if reach_m is None else float(reach_m)
    # a disc of the reach, no wider than the map
    r = min(int(math.floor(reach / dx + 1e-9)), max(t.shape))
    i, j = np.mgrid[-r : r + 1, -r : r + 1]
    disc = np.hypot(i, j) * dx <= reach + 1e-9 * dx
    earliest = ndimage.minimum_filter(t, footprint=disc, mode="constant", cval=np.inf)
    first = np.isfinite(t) & (t <= earliest)
    # neighbouring first cells are one place; places whose cells lie within the reach of
    # one another are one source (the closest cells of two places lie on their outlines)
    places, n = ndimage.label(first, structure=np.ones((3, 3), bool))
    if n <= 1:
        return n
    outline = first & ~ndimage.binary_erosion(first, structure=np.ones((3, 3), bool))
    pts = np.argwhere(outline)
    a, b = cKDTree(pts * dx).query_pairs(reach + 1e-9 * dx, output_type="ndarray").T
    la, lb = places[tuple(pts[a].T)] - 1, places[tuple(pts[b].T)] - 1
    graph = sparse.coo_matrix((np.ones(la.size), (la, lb)), shape=(n, n))
    return int(sparse.csgraph.connected_components(graph, directed=False)[0])


# share of the released area's boundary on the domain's edge above which a run warns
DOMAIN_EDGE_WARN = 0.05


def sliding_region(
    slope_deg: Any,
    friction_deg: float,
    start: tuple[float, float],
    dx: float,
    cover: Any = None,
    domain: Any = None,
) -> np.ndarray:
    """(nx, ny) bool: the terrain a crack from ``start`` (x, y) [m] can release if nothing
    but the terrain stops it: the snow-covered cells (``cover``, within ``domain``: bool
    maps, NaN counting as False; None: every cell) of ``slope_deg`` (nx, ny) [deg] on
    cells of ``dx`` [m] steeper than the weak layer's residual friction angle
    ``friction_deg`` [deg] (there a released slab slides, so the crack runs on),
    connected (8 neighbours) to the start's cell. Empty when the start's cell is not one
    of them. Its `domain_edge_fraction` before a run says whether the domain or the
    terrain can bound the release."""
    from scipy import ndimage

    psi = np.asarray(slope_deg, dtype=float)
    if psi.ndim != 2:
        raise ValueError(
            f"sliding_region: slope_deg has shape {psi.shape}; must be a map (nx, ny) [deg]"
        )
    if not (dx > 0 and math.isfinite(dx)):
        raise ValueError(f"sliding_region: dx = {dx}; must be a finite number > 0 m")
    try:
        phi = float(friction_deg)
    except (TypeError, ValueError):
        phi = math.nan
    if not 0 <= phi < 90:  # NaN too: it would compare False everywhere, an empty region
        raise ValueError(
            f"sliding_region: friction_deg = {friction_deg!r}; must be an angle in [0, 90) deg"
        )
    size = (psi.shape[0] * dx, psi.shape[1] * dx)
    try:
        x0, y0 = (float(c) for c in start)
    except (TypeError, ValueError):
        raise ValueError(f"sliding_region: start = {start!r}; must be a point (x, y) [m]") from None
    if not (0 <= x0 <= size[0] and 0 <= y0 <= size[1]):
        raise ValueError(
            f"sliding_region: start = ({x0:g}, {y0:g}) m; must lie in [0, {size[0]:g}] x "
            f"[0, {size[1]:g}] m, the map"
        )
    ok = np.isfinite(psi) & (psi > phi)
    for name, mask in (("cover", cover), ("domain", domain)):
        m = _cell_mask("sliding_region", name, mask, psi.shape)
        if m is not None:
            ok &= m
    i = min(int(x0 / dx), psi.shape[0] - 1)
    j = min(int(y0 / dx), psi.shape[1] - 1)
    if not ok[i, j]:
        return np.zeros_like(ok)
    labels, _ = ndimage.label(ok, structure=np.ones((3, 3), bool))
    return labels == labels[i, j]


def _cell_mask(fn: str, name: str, mask: Any, shape: tuple[int, ...] | None = None) -> Any:
    """A bool map of cells (NaN, no data: False), of ``shape`` where given; None as None.
    ValueError naming ``fn`` and ``name`` for another shape."""
    if mask is None:
        return None
    m = np.asarray(mask)
    if m.dtype.kind == "f":
        m = np.isfinite(m) & (m != 0)
    m = m.astype(bool)
    if shape is not None and m.shape != shape:
        raise ValueError(f"{fn}: {name} has shape {m.shape}; must be {shape}, the map's")
    return m


def domain_edge_fraction(released: np.ndarray, domain: np.ndarray | None = None) -> float | None:
    """Share of the released area's boundary that lies on the domain's edge.

    The boundary is counted in cell faces between a released cell and one that is not
    (``released``: (nx, ny) bool); a face is on the domain's edge where the other cell
    lies outside the rectangle or outside ``domain`` ((nx, ny) bool: the terrain the run
    may release, e.g. the buffer around a release polygon within the DEM's data; None:
    the whole rectangle). Cells inside the domain without snow (steep rock, a mask) are
    terrain, not domain edge. None when nothing released.
    """
    rel = _cell_mask("domain_edge_fraction", "released", released)
    if rel.ndim != 2:
        raise ValueError(
            f"domain_edge_fraction: released has shape {rel.shape}; must be a map (nx, ny)"
        )
    dom = _cell_mask("domain_edge_fraction", "domain", domain, rel.shape)
    if not rel.any():
        return None
    dom = np.ones_like(rel) if dom is None else dom
    rel_p = np.pad(rel, 1)
    out_p = ~np.pad(dom, 1, constant_values=False)  # outside the rectangle: edge
    total = edge = 0
    for ax, sh in ((0, 1), (0, -1), (1, 1), (1, -1)):
        nb_rel = np.roll(rel_p, sh, axis=ax)[1:-1, 1:-1]
        nb_out = np.roll(out_p, sh, axis=ax)[1:-1, 1:-1]
        face = rel & ~nb_rel
        total += int(face.sum())
        edge += int((face & nb_out).sum())
    return edge / total if total else 0.0


def initial_thickness(result: Any) -> Any:
    """A slope result's initial slab thickness h0 [m]: its (nx, ny) map (0 where no snow
    lies), or ``params.thickness`` for results written before 2026-11-27."""
    if getattr(result, "thickness", None) is not None:
        return np.asarray(result.thickness, dtype=float)
    return float(result.params.thickness)


def _ratio_or_none(v: float, cs: float) -> float | None:
    return v / cs if math.isfinite(v) else None


# states of a front in the summary (``upslope_front``, ``crossslope_front``)
FRONT_STATES = ("arrested", "reached_edge", "moving", "sawn_only")


def _front_state(
    dist: np.ndarray, t_b: np.ndarray, edge: float, t_end: float, dx: float
) -> tuple[str, float | None]:
    """(state, speed at the end [m/s] or None) of the release's outline in one direction.

    ``dist``: each particle's distance from the start in that direction [m]; ``edge``:
    the area's edge in it [m]. The outline is the failed particle farthest from the start
    over the whole map. As a PST's tip (`damjax.diagnostics.arrest`): "reached_edge" when
    the outline lies within `ARREST_MARGIN` (2 m) of the edge, "moving" when it advanced by
    more than one cell in the last `ARREST_QUIET` s (the speed is that advance over
    `ARREST_QUIET`), "arrested" otherwise. Failures behind the outline (the released slab
    loading its toe, say) move no outline.
    """
    failed = np.isfinite(t_b)
    if not failed.any():
        return "sawn_only", None
    now = float(np.max(dist[failed]))
    if edge - now < ARREST_MARGIN:
        return "reached_edge", None
    early = failed & (t_b <= t_end - ARREST_QUIET + 1e-9)
    before = float(np.max(dist[early])) if early.any() else -math.inf
    if now - before > dx * (1.0 + 1e-6):
        return "moving", (now - before) / ARREST_QUIET if math.isfinite(before) else None
    return "arrested", None


def _crossslope_state(states: list[str]) -> str:
    """One state for both sides: moving if either side moves, else arrested if either side
    arrested (the other reached its edge), else the common state."""
    for state in ("sawn_only", "moving", "arrested"):
        if state in states:
            return state
    return "reached_edge"


RELEASE_DAMAGE_WIDTH = 0.5  # relative width w of the smooth damage ramp (see particle_damage)


def particle_damage(model: Model, state: State, width: float = RELEASE_DAMAGE_WIDTH) -> Any:
    """Smooth weak-layer damage per particle in [0, 1]: s((u_max / u_r - (1 - w)) / w), s
    the C1 smoothstep, 1 where sawn, 0 where the layer is unbreakable. A differentiable
    stand-in for "released" (the event itself is discrete). The ramp is wide (w = 0.5):
    after an arrest the particles just ahead of the front sit well below u_r, and a narrow
    ramp gives them no gradient (measured: exactly 0 at w = 0.1)."""
    cut = jnp.clip((state.saw_pos - model.saw.saw_coord) / (model.grid.dx * 0.5) + 0.5, 0.0, 1.0)
    return jnp.maximum(weak_layer_damage(model, state, width), cut)


def release_area_smooth(model: Model, state: State) -> Any:
    """Smooth release area [m^2]: the particles' `particle_damage` times their area (a JAX
    scalar, differentiable; close to ``release_area_m2`` where the ramp is narrow in x).
    Intact weak layer loaded beyond u_r / 2 counts partly: an intact brittle layer
    (softening 0) at a stability ratio S = tau_p / tau_g < 2 has u_max / u_r = 1 / S and
    counts s(2 / S - 1) of its area (0.36 at S = 1.42); read ``release_area_m2`` for the
    area itself."""
    return jnp.sum(particle_damage(model, state)) * model.slab.area0


def simulate_slope(
    params: PSTParams,
    setup: SlopeSetup | None = None,
    *,
    slope_deg: Any = None,
    tau_peak: Any = None,
    fall_deg: Any = 0.0,
    layout: SlopeLayout | None = None,
    progress: bool = False,
    state: State | None = None,
    start_chunk: int = 0,
    history: tuple[list[Any], list[Any]] | None = None,
    callback: Any = None,
    thickness: Any = None,
    cover: Any = None,
    stability: Any = None,
    wl_friction: Any = None,
    domain: Any = None,
) -> SlopeResult:
    """Run a slope-scale release.

    Works on concrete inputs (validated, run chunk by chunk with progress, snapshots and
    every diagnostic) and on traced ones (`params`, `tau_peak`, `slope_deg` inside
    `jax.grad`, `jax.vmap`, `jax.jit`), like `damjax.simulate_pst`: the layout is made
    from the concrete values JAX holds behind the tracers (under `jax.grad` and
    `jax.vmap`), or passed in (``layout=damjax.core.model.make_slope_layout(params,
    setup, max_slope_deg)``). Inside `jax.jit` it is made from the inputs that are not
    traced; it needs a layout only where a traced input fixes it (`SLOPE_LAYOUT_FIELDS`:
    youngs_modulus, density, poisson, friction_deg; and slope_deg): a traced strength map
    tau_peak, softening or wl_shear_modulus needs none. A traced result holds JAX maps
    and a summary of JAX scalars: ``release_area_smooth_m2`` (differentiable, see
    `release_area_smooth`), ``release_area_m2`` (event-based), ``saw_radius_m`` and
    ``fault_code``.

    Args:
        params: slab and weak-layer parameters (`slope_deg` and `tau_peak` are used when
            the corresponding field is not given).
        setup: geometry and numerics.
        slope_deg: local slope angle [deg], scalar in (0, 90) or (nx, ny) at cell centres
            in [0, 90) (a flat cell holds a slab that cannot slide).
        tau_peak: weak-layer strength [Pa], scalar or (nx, ny) at cell centres (e.g. a
            Gaussian random field from `damjax.fields`).
        fall_deg: local fall-line direction relative to -x [deg], scalar or (nx, ny):
            the slope descends along (-cos, -sin)(fall_deg), so a positive angle turns
            the fall line from -x towards -y; beyond +-90 deg (over the area) x no longer
            points up-slope (warned).
        progress: tqdm progress bar.
        state: resume from this saved state (with ``start_chunk`` and ``history``).
        start_chunk: number of chunks run before ``state``.
        history: the per-chunk tip arrays and snapshots recorded before ``state`` (as
            `damjax.simulate_pst`).
        layout: static layout (`damjax.core.model.make_slope_layout`); default: made
            from the inputs.
        callback: ``callback(chunk, state, tips, snaps)`` after every chunk, with the
            whole history so far (checkpointing; see `damjax.core.loop.integrate`).
        thickness: initial slab thickness h0 normal to the slope [m], (nx, ny) at cell
            centres (`damjax.snow_cover`); None (default): ``params.thickness``
            everywhere, the uniform slab of earlier versions (bitwise the same run).
        cover: (nx, ny) bool, the snow-covered cells: only they hold particles (a cell
            without snow costs no particle work and is a free edge); None: every cell.
        stability: stability ratio S = tau_p / tau_g [-], (nx, ny) or a scalar, instead
            of ``tau_peak`` (which is then not used, and warned): each particle's
            strength is S times the shear its own slab loads it with, rho g h0 sin(psi).
        wl_friction: friction coefficient mu [-] of the weak layer's strength (a scalar or
            (nx, ny)): tau_p = tau_peak + mu rho g h0 cos(psi), ``tau_peak`` the cohesion.
        domain: (nx, ny) bool, the cells the run may release (a release polygon's buffer
            within the DEM's data); its edge, with the rectangle's, is where the summary's
            ``domain_edge_fraction`` counts the release as bounded by the domain. None:
            the rectangle.

    Slab that slides over the grid's edge leaves the run (outflow, counted in the
    summary) instead of stopping it.
    """
    if stability is not None and tau_peak is not None:
        warnings.warn(
            "simulate_slope: tau_peak is not used with stability (the strength is S times "
            "each particle's own load; with wl_friction, plus mu times its normal load)",
            UserWarning,
            stacklevel=2,
        )
    snow = dict(thickness=thickness, cover=cover, stability=stability, wl_friction=wl_friction)
    traced = is_traced((params, slope_deg, tau_peak, fall_deg, snow))
    resume = dict(state=state, start_chunk=start_chunk, history=history, callback=callback)
    concrete_only("simulate_slope", traced, progress, resume)
    with eager_if_concrete((params, slope_deg, tau_peak, fall_deg, snow, domain)):
        prep = prepare(
            params,
            setup,
            slope_deg=slope_deg,
            tau_peak=tau_peak,
            fall_deg=fall_deg,
            layout=layout,
            domain=domain,
            **snow,
        )
        warn_notes(prep, stacklevel=3)
        if traced:
            return _simulate_slope_traced(prep)
        return run(prep, progress=progress, **resume)


def _pst_only_notes(params: PSTParams) -> list[Problem]:
    """A note naming the parameters a slope run does not use that differ from their
    defaults (a PST's strength profile, steady length and gradient, its slope profile):
    the slope and the strength of a slope run are its maps (category "pst_only"; a
    scenario says it for its own keys)."""
    from damjax.params import specs

    default = PSTParams()
    unused = []
    for name, spec in specs(PSTParams).items():
        if spec.pst_only and not same_value(getattr(params, name), getattr(default, name)):
            unused.append(name)
    if not unused:
        return []
    return [
        Problem(
            None,
            reason=f"simulate_slope: {', '.join(unused)} not used: a PST's; a slope run's "
            "strength is tau_peak (a scalar or an (nx, ny) map) and its slope slope_deg",
            form="line",
            setup=SlopeSetup,
            category="pst_only",
        )
    ]


def warn_notes(prep: PreparedSlope, stacklevel: int = 2) -> None:
    """Warn the input's notes of a prepared run (`PreparedSlope.notes`): slope notes as
    `SlopeRunWarning`, the rest (a strength at or below the slab's weight) as
    UserWarning."""
    for note in prep.notes:
        category = SlopeRunWarning if note.category == "slope" else UserWarning
        warnings.warn(note.text(), category, stacklevel=stacklevel + 1)


def _strict(v: Any) -> Any:
    """JSON-ready values with inf, -inf and nan as strings ("inf", ...): strict JSON."""
    if isinstance(v, dict):
        return {k: _strict(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_strict(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return str(v)
    return v


@dataclasses.dataclass(frozen=True)
class PreparedSlope:
    """A slope run checked once, at the edge (`prepare`): what `run` integrates.

    Attributes:
        params: the parameters.
        setup: the setup (with the start a scenario's ``fields`` gave).
        slope_deg, tau_peak, fall_deg: the maps (or scalars) [deg, Pa, deg].
        layout: the static layout (grid, step count, slab law).
        notes: the warnings of the input, not yet warned (`damjax.validation.Problem`s;
            category "slope": a `SlopeRunWarning`, "overloaded": the strength at or below
            the slab's weight, with the share of the snow-covered area as ``value``).
        thickness, cover, stability, wl_friction, domain: the snow cover and the weak
            layer's own load (`simulate_slope`'s; None: not given).
        load_ratio: (n,) tau_p / tau_g of each particle at t = 0 (at most 1: its weak layer
            fails under its own slab), in the order of
            `damjax.core.model.slope_particles`; None for traced inputs.
        source: what ``fields`` returned (a scenario's
            `damjax.scenario.slope_fields.SlopeInputs`: map coordinates, start zone), else
            None.
    """

    params: PSTParams
    setup: SlopeSetup
    slope_deg: Any
    tau_peak: Any
    fall_deg: Any
    layout: SlopeLayout
    notes: tuple[Problem, ...] = ()
    thickness: Any = None
    cover: Any = None
    stability: Any = None
    wl_friction: Any = None
    domain: Any = None
    load_ratio: Any = None
    source: Any = None

    def snow(self) -> dict[str, Any]:
        """`damjax.core.model.build_slope`'s snow and weak-layer keywords."""
        return dict(
            thickness=self.thickness,
            cover=self.cover,
            stability=self.stability,
            wl_friction=self.wl_friction,
        )


def build(prep: PreparedSlope, layout: SlopeLayout | None = None) -> tuple[Model, State, Any, Any]:
    """Model, initial state and particle positions (x, y) [m] of a prepared run
    (`damjax.core.model.build_slope` on its maps and snow cover; ``layout``: default the
    prepared one)."""
    return build_slope(
        prep.params,
        prep.setup,
        prep.layout if layout is None else layout,
        prep.slope_deg,
        prep.tau_peak,
        prep.fall_deg,
        **prep.snow(),
    )


def prepare(
    params: PSTParams,
    setup: SlopeSetup | None = None,
    *,
    slope_deg: Any = None,
    tau_peak: Any = None,
    fall_deg: Any = 0.0,
    layout: SlopeLayout | None = None,
    fields: Any = None,
    max_particles: int | None = None,
    thickness: Any = None,
    cover: Any = None,
    stability: Any = None,
    wl_friction: Any = None,
    domain: Any = None,
) -> PreparedSlope:
    """Check a slope run's input once and make its layout: the types, every value (those
    JAX holds behind traced inputs under `jax.grad` and `jax.vmap`, member by member; inside
    `jax.jit` none), the start and the maps, the 64-bit switch, the layout and the run's
    size. `damjax.validation.InputError` (a ValueError, one line per problem) on invalid
    input.

    Args:
        params: slab and weak-layer parameters.
        setup: geometry and numerics (default: `SlopeSetup()`).
        slope_deg: local slope angle [deg], scalar or (nx, ny) (default params.slope_deg).
        tau_peak: weak-layer strength [Pa], scalar or (nx, ny) (default params.tau_peak).
        fall_deg: local fall-line direction relative to -x [deg], scalar or (nx, ny).
        layout: static layout (`damjax.core.model.make_slope_layout`); default: made
            from the inputs.
        fields: instead of the maps, ``fields(setup) -> (slope_deg, fall_deg, tau_peak,
            start)``, or an object with these attributes and those of the snow cover
            (``thickness``, ``cover``, ``stability``, ``wl_friction``, ``domain``; kept
            as `PreparedSlope.source`), called once the parameters and the grid are valid
            (a scenario's terrain, snow and strength tables, read on the grid).
        max_particles: the most particles a run may have (scenario files).
        thickness: initial slab thickness h0 [m], scalar or (nx, ny) (`simulate_slope`).
        cover: (nx, ny) bool, the snow-covered cells (`simulate_slope`).
        stability: stability ratio S = tau_p / tau_g [-], scalar or (nx, ny).
        wl_friction: friction coefficient of the weak layer's strength [-].
        domain: (nx, ny) bool, the cells the run may release (`simulate_slope`).
    """
    setup = SlopeSetup() if setup is None else setup
    expect_types(
        "simulate_slope",
        params=(params, PSTParams),
        setup=(setup, SlopeSetup),
        layout=(layout, (SlopeLayout, type(None))),
    )
    slope_deg = params.slope_deg if slope_deg is None else slope_deg
    tau_peak = params.tau_peak if tau_peak is None else tau_peak
    snow = dict(thickness=thickness, cover=cover, stability=stability, wl_friction=wl_friction)
    inputs = (params, slope_deg, tau_peak, fall_deg, snow)
    if is_traced(inputs):
        require_x64(setup.dtype)
        if is_traced((cover, domain)):
            raise TypeError(
                "simulate_slope: cover and domain (bool maps of cells: cover fixes which "
                "particles exist) must be concrete arrays, not traced"
            )
        # the values JAX holds behind the tracers, one set per member of a jax.vmap batch
        members = concrete_members(inputs)
        for i, m in enumerate(members or ()):
            problems = slope_problems(m[0], setup, *m[1:4], **m[4], domain=domain)
            if len(members) > 1:  # a jax.vmap batch: which member
                problems = [
                    dataclasses.replace(p, reason=f"{p.reason} (batch member {i})")
                    for p in problems
                ]
            raise_if(problems)
        if members is None:  # inside jax.jit: the setup and the shapes are known
            raise_if(shape_problems(params) + slope_setup_problems(setup))
            maps = dict(slope_deg=slope_deg, tau_peak=tau_peak, fall_deg=fall_deg)
            raise_if(map_shape_problems(setup, **maps, **snow))
        if layout is None:
            if members is None:
                layout = _layout_from_known(params, setup, slope_deg, cover)
            else:
                layout = _batch_layout(members, setup, cover)
            _check_size(layout, setup, max_particles, cover)
        return PreparedSlope(
            params, setup, slope_deg, tau_peak, fall_deg, layout, domain=domain, **snow
        )
    source = None
    if fields is None:
        raise_if(
            slope_problems(params, setup, slope_deg, tau_peak, fall_deg, **snow, domain=domain)
        )
    else:  # the maps read once the parameters and the grid are valid
        raise_if(slope_problems(params, setup, defer_lambda=True))
        source = fields(setup)
        if isinstance(source, tuple):
            slope_deg, fall_deg, tau_peak, start = source
            source = None
        else:
            slope_deg, fall_deg = source.slope_deg, source.fall_deg
            tau_peak, start = source.tau_peak, source.start
            snow = {k: getattr(source, k, None) for k in snow}
            domain = getattr(source, "domain", None)
        setup = dataclasses.replace(setup, start=start)
        if snow["thickness"] is None:  # else at the thinnest slab (slope_field_problems)
            lam = float(theory.elastic_length(params))
            raise_if([p for p in [lambda_problem(setup.dx, lam, SlopeSetup)] if p])
        raise_if(
            slope_field_problems(
                setup, slope_deg, tau_peak, fall_deg, params=params, **snow, domain=domain
            )
        )
    notes = [
        Problem(None, reason=note, form="line", setup=SlopeSetup, category="slope")
        for note in _slope_notes(
            params, setup, slope_deg, fall_deg, not getattr(source, "area_from_polygon", False)
        )
    ]
    notes.extend(_pst_only_notes(params))
    if domain is not None and np.ndim(slope_deg) == 2:
        notes.extend(_domain_notes(params, setup, slope_deg, snow["cover"], domain))
    if layout is None:
        layout = make_slope_layout(params, setup, steepest_covered(slope_deg, snow["cover"]))
        _check_size(layout, setup, max_particles, snow["cover"])
    # (the run's size checked first: the load ratio is an array over its particles)
    ensure_x64(setup.dtype)
    ratio = load_ratio(params, setup, slope_deg, tau_peak, fall_deg, **snow)
    frac = float(np.mean(ratio <= 1.0)) if ratio.size else 0.0
    if frac > 0:
        plain = load_ratio(params, setup, slope_deg, tau_peak, fall_deg, uniform=False, **snow)
        if np.mean(plain <= 1.0) >= frac:
            why = (
                f"tau_peak is at or below the gravitational shear rho g h sin(psi) on "
                f"{100 * frac:.3g} % of the area: the weak layer fails there under the "
                "slab's weight at once (a strength map in kPa instead of Pa?)"
            )
        else:  # a brittle layer's segments on coarse particles: below tau_p
            spacing = setup.dx / int(setup.particles_per_cell)
            why = (
                f"the weak layer starts failing under the slab's weight at once on "
                f"{100 * frac:.3g} % of the area: its strength there exceeds rho g h "
                f"sin(psi) by less than a layer that softens so little needs on particles "
                f"{spacing:.3g} m apart (under a uniform load it fails from tau_p (1 + "
                "delta) (1 - spacing / (2 Lambda)) on, "
                "damjax.materials.weak_layer.uniform_failure_stress): a finer dx, more "
                "particles_per_cell or some softening hold it"
            )
        notes.append(
            Problem(
                None,
                frac,
                why,
                form="line",
                setup=SlopeSetup,
                category="overloaded",
            )
        )
    return PreparedSlope(
        params,
        setup,
        slope_deg,
        tau_peak,
        fall_deg,
        layout,
        tuple(notes),
        domain=domain,
        load_ratio=ratio,
        source=source,
        **snow,
    )


def load_ratio(
    params: PSTParams,
    setup: SlopeSetup,
    slope_deg: Any,
    tau_peak: Any,
    fall_deg: Any = 0.0,
    uniform: bool = True,
    **snow: Any,
) -> np.ndarray:
    """(n,) tau_p / tau_g of each particle at t = 0: its weak layer's strength over the
    shear its own slab loads it with, rho g h0 sin(psi), in the model's own values (at
    most 1: the layer fails under its slab before any cut). The strength is the stress
    at which the uniformly loaded layer starts to fail
    (`damjax.materials.weak_layer.uniform_failure_stress`: tau_p, or less for a layer
    that softens less than its particles' spacing over 2 Lambda). Particles in the order
    of `damjax.core.model.slope_particles`; ``snow``: `build_slope`'s snow keywords;
    ``uniform`` False: tau_p itself."""
    pf = slope_particle_fields(params, setup, slope_deg, tau_peak, fall_deg, **snow)
    tau_p, tau_g = np.asarray(pf["tau_peak"], float), np.asarray(pf["tau_g"], float)
    tau_g = np.broadcast_to(tau_g, tau_p.shape)
    if uniform:
        spacing = setup.dx / int(setup.particles_per_cell)
        tau_p = uniform_failure_stress_of(params, spacing, tau_p, pf["thickness"])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(tau_g > 0, tau_p / np.where(tau_g > 0, tau_g, 1.0), np.inf)


def _check_size(
    layout: SlopeLayout, setup: SlopeSetup, max_particles: int | None, cover: Any = None
) -> None:
    """InputError when a slope run has more than ``max_particles`` particles or cannot
    fit in this machine's memory (``cover``: only the snow-covered cells hold particles)."""
    ppc = int(setup.particles_per_cell)
    cells = layout.n_cells[0] * layout.n_cells[1]
    if cover is not None:
        cells = int(np.sum(np.asarray(cover, bool)))
    n = cells * ppc * ppc
    if max_particles is not None and n > max_particles:
        raise InputError(
            [
                Problem(
                    "dx",
                    setup.dx,
                    f"with ${{length}} = {setup.length:g}, ${{width}} = {setup.width:g} and "
                    f"${{particles_per_cell}} = {ppc} the run has {n:.3g} particles: must be "
                    f"at most {max_particles:.0e}",
                    setup=SlopeSetup,
                )
            ]
        )
    problem = size_problem(
        n,
        layout.grid_shape[0] * layout.grid_shape[1],
        layout.n_chunks,
        np.dtype(setup.dtype).itemsize,
        ("length", "width", "dx", "duration", "particles_per_cell"),
        " of the slope",
        SlopeSetup,
    )
    raise_if([problem] if problem is not None else [])


def run(
    prep: PreparedSlope,
    *,
    progress: bool = False,
    state: State | None = None,
    start_chunk: int = 0,
    history: tuple[list[Any], list[Any]] | None = None,
    callback: Any = None,
) -> SlopeResult:
    """Integrate a prepared slope run of concrete inputs (`prepare`): the model built once,
    the run chunk by chunk, the maps and every diagnostic. The arguments are
    `simulate_slope`'s."""
    params, setup, layout, domain = prep.params, prep.setup, prep.layout, prep.domain
    model, state0, xp, yp = build(prep)
    # (the notes of `prepare` warned of it; a scenario's loader words it itself)
    fails0 = np.asarray(initial_failures(model))
    final, _, snaps, info = integrate(
        model,
        state0 if state is None else state,
        layout.n_chunks,
        layout.chunk_steps,
        snapshot=_snapshot,
        progress=progress,
        callback=callback,
        start_chunk=start_chunk,
        history=history,
    )
    cell0 = np.asarray(model.grid.cell0)

    def cm(v: Any, r: str = "mean") -> np.ndarray:
        return _cell_map(np.asarray(v, float), cell0, layout.pad, layout.n_cells, r)

    t_b = np.asarray(final.t_broken, float)
    broken = np.isfinite(t_b)
    x0, y0 = setup.start
    band_x = np.abs(yp - y0) <= SPEED_BAND
    band_y = np.abs(xp - x0) <= SPEED_BAND
    up = np.max(np.where(broken & band_x, xp - x0, 0.0))
    cs = float(theory.shear_wave_speed(params))
    saw_r = float(final.saw_pos)
    # a crack front's speed, from the failures it caused: the weak layer that failed
    # under its own slab at t = 0 was no front's doing (all at once: no speed)
    t_front = np.where(fails0, np.inf, t_b)
    # no front under the slab outruns its fastest wave (`results.front_speed_limit`)
    c_max = float(theory.plane_stress_wave_speed(params))
    v_up, v_up_peak = _front_speed(
        xp[band_x] - x0, t_front[band_x], saw_r + 2.0, max(up - 2.0, saw_r + 3.0), limit=c_max
    )
    dy = np.abs(yp[band_y] - y0)
    across = np.max(np.where(np.isfinite(t_b[band_y]), dy, 0.0))
    # each side of the start on its own (the farther one is ``across``)
    side_extent = {
        side: float(
            np.max(np.where(np.isfinite(t_b[band_y]) & (sign * (yp[band_y] - y0) >= 0), dy, 0.0))
        )
        for side, sign in (("-y", -1.0), ("+y", 1.0))
    }
    v_cross, v_cross_peak = _front_speed(
        dy, t_front[band_y], saw_r + 2.0, max(across - 2.0, saw_r + 3.0), limit=c_max
    )
    height = cm(column_height(model, final))
    nx, ny = layout.n_cells
    snow_map = (
        np.bincount(
            (cell0[0] - layout.pad[0]) * ny + cell0[1] - layout.pad[1], minlength=nx * ny
        ).reshape(nx, ny)
        > 0
    )
    if np.ndim(model.slab.thickness) == 0:
        h0 = np.where(snow_map, float(model.slab.thickness), 0.0)
    else:
        h0 = cm(model.slab.thickness)
    crown, stauch = _crown_and_stauchwall(model, final, height, h0, cm)
    released_map = cm(t_b, "min") < np.inf
    edge_frac = domain_edge_fraction(released_map, domain)
    n_out = 0 if final.outflow is None else int(np.sum(np.asarray(final.outflow)))
    fault = None
    if int(final.fault):
        fault = f"run stopped at t = {float(final.fault_time):.4f} s: " + "; ".join(
            m for b, m in FAULT_MESSAGES.items() if int(final.fault) & b
        )
    # `front_quiet_at_end`: no weak layer up-slope of the start failed in the last
    # ARREST_QUIET s (failures below the start are left out: the released slab keeps
    # loading the toe long after the front stopped; Fig. 13 seed 0, 5 s: 2900 cells at
    # x < 5 m failed after 3 s, none up-slope of the start)
    up_t = t_b[broken & (xp >= x0)]
    last_up = float(up_t.max()) if up_t.size else math.nan
    t_end = float(final.time)
    quiet = bool(not up_t.size or t_end - last_up >= ARREST_QUIET - 1e-9)
    # the fronts' states from the release's outline over the whole map: its top for the
    # up-slope front, its farthest points on either side of the start across
    sawn_only = bool(final.saw_active)
    if sawn_only:
        up_state, up_end = "sawn_only", None
        side_states = {"-y": ("sawn_only", None), "+y": ("sawn_only", None)}
    else:
        up_state, up_end = _front_state(xp - x0, t_b, setup.length - x0, t_end, setup.dx)
        side_states = {
            "-y": _front_state(y0 - yp, t_b, y0, t_end, setup.dx),
            "+y": _front_state(yp - y0, t_b, setup.width - y0, t_end, setup.dx),
        }
    cross_state = _crossslope_state([st for st, _ in side_states.values()])
    cross_end = max(
        (v for st, v in side_states.values() if st == "moving" and v is not None), default=None
    )
    cross_arrest = max(
        (side_extent[side] for side, (st, _) in side_states.items() if st == "arrested"),
        default=None,
    )
    summary = {
        "upslope_front": up_state,
        "crossslope_front": cross_state,
        "upslope_extent_m": float(up),
        "upslope_arrest_distance_m": float(up) if up_state == "arrested" else None,
        "crossslope_extent_m": float(across),
        "crossslope_arrest_distance_m": cross_arrest if cross_state == "arrested" else None,
        "upslope_front_end_speed_over_cs": None if up_end is None else up_end / cs,
        "crossslope_front_end_speed_over_cs": None if cross_end is None else cross_end / cs,
        "arrested_before_top": up_state == "arrested",
        "front_quiet_at_end": quiet,
        "last_upslope_failure_time_s": last_up if up_t.size else None,
        # None where a band had too few failures to fit (JSON has no NaN)
        "upslope_crack_speed_over_cs": _ratio_or_none(v_up_peak, cs),
        "crossslope_crack_speed_over_cs": _ratio_or_none(v_cross_peak, cs),
        "upslope_crack_speed_mean_over_cs": _ratio_or_none(v_up, cs),
        "crossslope_crack_speed_mean_over_cs": _ratio_or_none(v_cross, cs),
        "release_area_m2": float(broken.sum() * float(model.slab.area0)),
        "crown_area_m2": float(np.sum(crown) * setup.dx**2),
        "stauchwall_area_m2": float(np.sum(stauch) * setup.dx**2),
        "slab_fracture_area_m2": float(np.sum(_fractured_cells(model, final, cm)) * setup.dx**2),
        "release_area_smooth_m2": float(release_area_smooth(model, final)),
        # a weak layer failing at t = 0 leads the saw at once: no cut was critical
        "critical_cut_radius_m": (
            saw_r if not bool(final.saw_active) and not fails0.any() else None
        ),
        # the saw stops once the crack leads it: until then the release is the cut
        "saw_stopped": not bool(final.saw_active),
        "sawn_area_m2": float(
            np.sum(np.asarray(model.saw.saw_coord) < saw_r) * float(model.slab.area0)
        ),
        # the weak layer failing under the slab's own weight at t = 0 (before any cut)
        "initial_failure_area_m2": float(fails0.sum() * float(model.slab.area0)),
        # slab that slid out over the grid's edge (it left the run; counted as released)
        "outflow_particles": n_out,
        "outflow_area_m2": float(n_out * float(model.slab.area0)),
        # share of the released area's boundary on the domain's edge (None: no release)
        "domain_edge_fraction": edge_frac,
        # sources of the arrival-time map (1: the trigger alone)
        "arrival_sources": arrival_sources(cm(t_b, "min"), setup.dx, source_reach(model)),
        "snow_area_m2": float(xp.size * float(model.slab.area0)),
        "shear_wave_speed_m_per_s": cs,
        "fault": fault,
        "n_particles": int(xp.size),
        "n_steps": int(start_chunk * layout.chunk_steps + info.steps_done),
        "compile_time_s": info.compile_time_s,
        "wall_time_s": info.wall_time_s,
        "particle_steps_per_s": xp.size * info.steps_done / max(info.wall_time_s, 1e-9),
    }
    if edge_frac is not None and edge_frac > DOMAIN_EDGE_WARN:
        # a domain the terrain bounds (a polygon's buffer, the DEM's data) grows with the
        # buffer or the window; a rectangle the user drew with its length and width
        grow = (
            "enlarge the domain (a release polygon's terrain.buffer, or the DEM window's "
            "setup.length and setup.width)"
            if domain is not None
            else "enlarge the area (setup.length, setup.width) if the release should end inside it"
        )
        warnings.warn(
            f"simulate_slope: {100 * edge_frac:.3g} % of the released area's boundary lies on "
            "the domain's edge (summary domain_edge_fraction): bounded by the domain, not "
            f"the terrain: {grow}",
            SlopeRunWarning,
            stacklevel=2,
        )
    if bool(final.saw_active) and not fault:
        warnings.warn(
            f"simulate_slope: the crack never ran ahead of the saw in {float(final.time):.3g} "
            f"s: release_area_m2 ({summary['release_area_m2']:.4g} m^2) is the saw cut and "
            "the weak layer it loaded, not a self-propagating release (summary "
            "saw_stopped = False; a longer duration, or a slope steeper than the friction "
            "angle at the start)",
            SlopeRunWarning,
            stacklevel=3,
        )
    snapshots = {}
    if snaps:
        snapshots = {
            "time": np.array([s["time"] for s in snaps]),
            "height": np.stack([cm(s["height"]) for s in snaps]),
            "broken": np.stack([cm(s["broken"]) for s in snaps]),
        }
    return SlopeResult(
        x=(np.arange(nx) + 0.5) * setup.dx,
        y=(np.arange(ny) + 0.5) * setup.dx,
        height=height,
        arrival_time=cm(t_b, "min"),
        tension=cm(final.sigma[0]),
        opening=cm(final.opening),
        tau_peak=cm(model.weak_layer.tau_peak),
        slope_deg=_terrain_slope(
            cm(
                np.degrees(np.arcsin(np.clip(np.hypot(*np.asarray(model.g_tangent)) / G_ACC, 0, 1)))
            ),
            snow_map,
            # a scenario's source keeps the terrain's angle where it filled the input's
            getattr(prep.source, "terrain_slope_deg", None),
            prep.slope_deg,
        ),
        snapshots=snapshots,
        summary=summary,
        setup=setup,
        params=params,
        thickness=h0,
        snow=snow_map,
    )


def _terrain_slope(
    particle_map: np.ndarray, snow_map: np.ndarray, terrain_deg: Any, slope_deg: Any
) -> np.ndarray:
    """The slope-angle map [deg] of a run: the particles' own angle where snow lies, the
    terrain's where it does not (a rock face has its angle though no slab lies on it):
    ``terrain_deg`` (a map of the cells; NaN off the DEM's data), else the run's input
    ``slope_deg`` (scalar or map)."""
    src = slope_deg if terrain_deg is None else terrain_deg
    terrain = np.broadcast_to(np.asarray(src, float), particle_map.shape)
    return np.where(snow_map, particle_map, terrain)


def steepest_covered(slope_deg: Any, cover: Any = None) -> float:
    """The steepest slope angle [deg] of the snow-covered cells (all with ``cover`` None):
    what a released slab may accelerate on (`make_slope_layout`)."""
    psi = np.asarray(slope_deg, dtype=float)
    if cover is None or psi.ndim == 0:
        return float(np.max(psi))
    c = np.asarray(cover, bool)
    return float(np.max(psi[c])) if c.any() else float(np.max(psi))


# compiled once per model structure and layout: a repeated jax.grad / jax.vmap of a function
# that calls simulate_slope does not recompile the time loop
_integrate_pure_jit = eqx.filter_jit(integrate_pure)


def _batch_layout(members: list[Any], setup: SlopeSetup, cover: Any = None) -> SlopeLayout:
    """One layout that fits every member of a batch: the widest padding, the most steps,
    plastic if any member is."""
    layouts = [make_slope_layout(m[0], setup, steepest_covered(m[1], cover)) for m in members]
    pad_x = max(lay.pad[0] for lay in layouts)
    pad_y = max(lay.pad[1] for lay in layouts)
    nx, ny = layouts[0].n_cells
    most = max(layouts, key=lambda lay: lay.n_steps)
    return dataclasses.replace(
        most,
        grid_shape=(pad_x + nx + pad_y, 2 * pad_y + ny),
        pad=(pad_x, pad_y),
        plastic=any(lay.plastic for lay in layouts),
    )


# the fields of PSTParams that make_slope_layout reads (with the steepest slope_deg): the
# time step (the slab's wave speed) and the padding (the slide of a released slab)
SLOPE_LAYOUT_FIELDS = ("youngs_modulus", "density", "poisson", "friction_deg")


def _layout_from_known(
    params: PSTParams, setup: SlopeSetup, slope_deg: Any, cover: Any = None
) -> SlopeLayout:
    """`make_slope_layout` inside `jax.jit` (or nested `jax.vmap`) from the inputs whose
    values are known: `SLOPE_LAYOUT_FIELDS` and the slope angle must be, the others (the
    strength map tau_peak, fall_deg, tensile_strength, softening, wl_shear_modulus, ...)
    may be traced; a traced tensile strength gives a plastic layout. TypeError naming the
    traced inputs that fix the layout otherwise."""
    from damjax.pst import known_params, unknown_fields

    unknown = unknown_fields(params)
    fixing = [f for f in SLOPE_LAYOUT_FIELDS if f in unknown]
    slope = [concrete_value(x) for x in jax.tree.leaves(slope_deg)]
    if any(v is None for v in slope):
        fixing.append("slope_deg")
    if fixing:
        raise TypeError(
            f"simulate_slope: inside jax.jit (or nested jax.vmap) the values of "
            f"{', '.join(fixing)} are unknown, and they fix the grid and the step count; "
            "make the layout from concrete values and pass it: layout = "
            "damjax.core.model.make_slope_layout(params, setup, max_slope_deg); then "
            "simulate_slope(..., layout=layout). Traced inputs that do not fix it need no "
            "layout"
        )
    steepest = max(steepest_covered(v, cover) for v in slope)
    return make_slope_layout(known_params(params, unknown), setup, steepest)


def _simulate_slope_traced(prep: PreparedSlope) -> SlopeResult:
    """`simulate_slope` on traced inputs: the pure run, JAX maps (`SlopeResult`)."""
    params, setup, layout = prep.params, prep.setup, prep.layout
    model, state0, xp, yp = build(prep)
    final, _ = _integrate_pure_jit(model, state0, layout.n_chunks, layout.chunk_steps)
    nx, ny = layout.n_cells
    # each particle's cell from its reference position (host values: model.grid.cell0 may be
    # traced inside jax.jit)
    flat = np.floor(xp / setup.dx).astype(int) * ny + np.floor(yp / setup.dx).astype(int)
    counts = np.maximum(np.bincount(flat, minlength=nx * ny), 1)

    def cm(v: Any, reduce: str = "mean") -> Any:
        if reduce == "min":
            out = jax.ops.segment_min(v, flat, nx * ny)
        else:
            out = jax.ops.segment_sum(v, flat, nx * ny) / counts
        return out.reshape(nx, ny)

    g_t = jnp.sqrt(model.g_tangent[0] ** 2 + model.g_tangent[1] ** 2)
    summary = {
        "release_area_smooth_m2": raise_on_fault(release_area_smooth(model, final), final.fault),
        "release_area_m2": jnp.sum(jnp.isfinite(final.t_broken)) * model.slab.area0,
        "saw_radius_m": final.saw_pos,
        "fault_code": final.fault,
        "outflow_particles": jnp.sum(final.outflow) if final.outflow is not None else 0,
    }
    thickness = None if jnp.ndim(model.slab.thickness) == 0 else cm(model.slab.thickness)
    return SlopeResult(
        x=(np.arange(nx) + 0.5) * setup.dx,
        y=(np.arange(ny) + 0.5) * setup.dx,
        height=cm(column_height(model, final)),
        arrival_time=cm(final.t_broken, "min"),
        tension=cm(final.sigma[0]),
        opening=cm(final.opening),
        tau_peak=cm(model.weak_layer.tau_peak),
        slope_deg=cm(jnp.degrees(jnp.arcsin(jnp.clip(g_t / G_ACC, 0.0, 1.0)))),
        snapshots={},
        summary=summary,
        setup=setup,
        params=params,
        thickness=thickness,
    )
