"""The paper's slope-scale case (Fig. 13): a generic slope with a random weak layer.

`GenericSlopeCase` collects what the paper specifies for Fig. 13 a (50 m x 60 m and
50 m x 100 m generic slopes, a concave toe reaching 35 deg and a convex roll at the top,
Gaussian-random-field weak-layer strength with a mean gradient of 20 Pa/m up-slope,
E = 4 MPa, sigma_t = 4 kPa, softening delta = 1, a crack started at a weak spot with the
PST sawing procedure) and the choices the paper leaves open, each stated here:

- geometry: 50 m down-slope and 60 m (Fig. 13a) or 100 m (Fig. 13b) across, measured
  along the surface (the paper's Sec. 2: "50 m (down-slope) by 60 m (cross-slope)");
- slope profile: `damjax.terrain.generic_slope_angle` with its defaults, evaluated along the
  surface: a concave toe from 30 deg at the lower edge to 35 deg at 10 m, planar 35 deg,
  and a convex roll over the top 10 m to 20 deg. The paper starts the crack "at the bottom
  of the slope" and puts the crown "at the beginning of the artificial convex roll",
  40-50 m up-slope of it, on a 50 m slope: so the toe must already be steeper than the
  friction angle (27 deg; below it friction holds a released slab and no shear crack runs;
  30 deg is also the usual lower bound of potential release areas) and the roll can take
  only the top ~10 m. The toe and roll lengths and the end angles remain our choice; the
  arrest follows the roll (`verification.slope_acceptance` reports the sensitivity);
- strength: expected tau_p = 1000 Pa (the PSTs' tau_p on L_ss, where their crack starts)
  up to the bottom of the start window (x = 2 m, `mean_at`), rising `trend` = 20 Pa/m
  up-slope above it (the PSTs' arrangement: constant strength where the crack starts,
  then the gradient), plus a stationary Gaussian field (gstools' Gaussian covariance) of
  standard deviation `grf_std` = 100 Pa and correlation length `grf_length` = 8 m. The
  paper gives neither: 100 Pa is a 10 % coefficient of variation of the base strength, and
  8 m makes the "increase of around 400 Pa over 20 m" of the text visible above the noise
  (the same values as the shipped synthetic map, `damjax/data/synthetic_strength_map.csv`).
  Fig. 13b ("heterogeneity mostly oriented in the cross-slope direction") turns the trend
  across the slope (`trend_deg` = -90: rising from the y = width edge);
- start (the paper's star): the weakest point of the (2 m box-smoothed) field inside a
  start window: Fig. 13a at the bottom of the slope, x in [2, 8] m (psi 30.5-34.6 deg)
  and the middle half of the width; Fig. 13b near the top right corner, x in [34, 40] m
  (just below the roll) and y in [92, 98] m. A start at psi near phi needs a long sawn
  length before the crack runs by itself (8.4 m at 29 deg, measured).

`FIG12A` and `FIG12B` are the two cases (the shipped scenarios ``slope-generic-50x60`` and
``slope-generic-50x100`` describe the same fields and starts).

`run_generic_slope` runs it through `damjax.simulate_slope` (the shared
2D step) and adds the up-slope arrest *position* (from the lower edge) to the summary,
next to `upslope_arrest_distance_m` (from the start, along the surface).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

import jax
import numpy as np

from damjax.params import PSTParams, SlopeSetup
from damjax.slope.simulation import SlopeResult, simulate_slope


@dataclasses.dataclass(frozen=True)
class GenericSlopeCase:
    """Geometry, strength field and numerics of a Fig. 13-type run.

    Attributes:
        length: down-slope extent along the surface [m].
        width: cross-slope extent [m].
        dx: grid spacing [m].
        duration: simulated time [s].
        seed: PRNG seed of the Gaussian random field.
        mean: expected tau_p up to x = `mean_at` [Pa].
        mean_at: where the trend starts [m, along `trend_deg`]; None: the start window's
            first edge along the trend (its lower edge for an up-slope trend), so that the
            crack starts where the strength is `mean`, as in the PST.
        trend: mean strength gradient [Pa/m] (0: stationary field), up-slope unless
            `trend_deg` turns it.
        trend_deg: direction of the rising strength [deg, counter-clockwise from up-slope]:
            0 up-slope from the lower edge, -90 across from the y = width edge (Fig. 13b);
            `mean_at` is measured along it (`damjax.fields.plateau_trend_field`).
        grf_std: standard deviation of the random part [Pa] (0: no randomness).
        grf_length: correlation length (gstools' Gaussian convention) [m].
        field_dx: spacing of the grid the random field is drawn on [m]; None: the
            simulation grid (`dx`). The field is a different sample on every grid, so a
            grid-convergence study fixes `field_dx` (the field is then interpolated
            bilinearly to the cell centres, and the same seed gives the same field).
        planar: True: a planar slope at `max_slope_deg` (no toe, no roll).
        max_slope_deg: slope angle of the planar part [deg].
        toe_slope_deg: slope angle at the lower edge [deg].
        top_slope_deg: slope angle at the top edge [deg].
        toe_length: length of the concave toe [m] (`damjax.terrain.generic_slope_angle`).
        roll_length: length of the convex roll at the top [m]; toe + roll <= length.
        start: crack start (x, y) [m]; None: the weakest spot in the start window.
        start_window: (x_min, x_max) [m] of the start window, y in the middle half of the
            width; or (x_min, x_max, y_min, y_max) [m].
        particles_per_cell: particles per cell and dimension.
        chunk_steps: steps per jitted chunk (one snapshot per chunk).
        dtype: "float32" or "float64".
    """

    length: float = 50.0
    width: float = 60.0
    dx: float = 0.2
    duration: float = 4.0  # sawing ~0.3-1 s, the up-slope run ~1 s, quiet after ~2.8 s
    seed: int = 0
    mean: float = 1000.0
    mean_at: float | None = None
    trend: float = 20.0
    trend_deg: float = 0.0
    grf_std: float = 100.0
    grf_length: float = 8.0
    field_dx: float | None = None
    planar: bool = False
    max_slope_deg: float = 35.0
    toe_slope_deg: float = 30.0
    top_slope_deg: float = 20.0
    toe_length: float = 10.0
    roll_length: float = 10.0
    start: tuple[float, float] | None = None
    start_window: tuple[float, ...] = (2.0, 8.0)
    particles_per_cell: int = 2
    chunk_steps: int = 100
    dtype: str = "float32"

    def __post_init__(self) -> None:
        # the area and the seed first: the window and the profile are checked against them
        for name in ("length", "width", "dx"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not 0 < v < math.inf:
                raise ValueError(
                    f"GenericSlopeCase: {name} = {v!r}: must be a number in (0, inf) m"
                )
        seed = self.seed
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
            raise ValueError(f"GenericSlopeCase: seed = {seed!r}: must be an integer >= 0")
        if self.start is None:
            problem = window_problem(self.start_window, self.length, self.width)
            if problem:
                raise ValueError(f"GenericSlopeCase: start_window = {self.start_window}: {problem}")
        from damjax import fields, terrain

        try:
            fields.trend_direction(self.trend_deg)
        except ValueError as exc:
            raise ValueError(f"GenericSlopeCase: {exc}") from None
        if not self.planar:
            problem = terrain.profile_problem(self.length, self.toe_length, self.roll_length)
            if problem:
                raise ValueError(f"GenericSlopeCase: {problem}")


FIG12_PARAMS = dict(youngs_modulus=4.0e6, tensile_strength=4000.0, softening=1.0)


def fig12_params(**overrides: Any) -> PSTParams:
    """The paper's Fig. 13 slab and weak layer: E = 4 MPa, sigma_t = 4 kPa, delta = 1
    (the rest the PST baseline: h = 0.5 m, rho = 250 kg/m^3, phi = 27 deg, ...)."""
    return PSTParams(**{**FIG12_PARAMS, **overrides})


def cell_centres(case: GenericSlopeCase) -> tuple[np.ndarray, np.ndarray]:
    """Cell-centre coordinates x (nx,), y (ny,) [m] of the release area."""
    nx, ny = int(round(case.length / case.dx)), int(round(case.width / case.dx))
    return (np.arange(nx) + 0.5) * case.dx, (np.arange(ny) + 0.5) * case.dx


def slope_field(case: GenericSlopeCase) -> np.ndarray:
    """Local slope angle psi at the cell centres (nx, ny) [deg]."""
    from damjax import terrain

    x, y = cell_centres(case)
    if case.planar:
        psi = np.full(x.shape, case.max_slope_deg)
    else:
        psi = np.asarray(
            terrain.generic_slope_angle(
                x,
                length=case.length,
                max_slope_deg=case.max_slope_deg,
                toe_slope_deg=case.toe_slope_deg,
                top_slope_deg=case.top_slope_deg,
                toe_length=case.toe_length,
                roll_length=case.roll_length,
            ),
            dtype=float,
        )
    return np.repeat(psi[:, None], y.size, axis=1)


def strength_field(case: GenericSlopeCase) -> np.ndarray:
    """Weak-layer strength tau_p at the cell centres (nx, ny) [Pa] (`damjax.fields.grf`)."""
    from damjax import fields

    x, y = cell_centres(case)
    return fields.plateau_trend_field(
        jax.random.key(case.seed),
        x,
        y.size,
        case.dx,
        mean=case.mean,
        mean_at=_default_mean_at(case) if case.mean_at is None else case.mean_at,
        trend=case.trend,
        trend_deg=case.trend_deg,
        std=case.grf_std,
        length_scale=case.grf_length,
        field_dx=case.field_dx,
    )


def full_window(window: tuple[float, ...], width: float) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max) [m] of a start window given as (x_min, x_max) (y: the
    middle half of the width) or as (x_min, x_max, y_min, y_max)."""
    if len(window) == 2:
        return (float(window[0]), float(window[1]), 0.25 * width, 0.75 * width)
    x_lo, x_hi, y_lo, y_hi = (float(v) for v in window)
    return x_lo, x_hi, y_lo, y_hi


def window_problem(window: Any, length: float, width: float) -> str | None:
    """Why a start window is invalid on a length x width area (None: it is valid)."""
    shape = "must be (x_min, x_max) or (x_min, x_max, y_min, y_max) of finite numbers [m]"
    if not isinstance(window, (tuple, list)) or len(window) not in (2, 4):
        return shape
    for v in window:
        real = isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
        if not real or not math.isfinite(float(v)):
            return shape
    x_lo, x_hi, y_lo, y_hi = full_window(tuple(window), width)
    if not 0 <= x_lo < x_hi <= length:
        return f"must have 0 <= x_min < x_max <= length = {length:g} m"
    if not 0 <= y_lo < y_hi <= width:
        return f"must have 0 <= y_min < y_max <= width = {width:g} m"
    return None


def _default_mean_at(case: GenericSlopeCase) -> float:
    """Where the trend starts by default: the start window's first edge along the trend
    (its lower edge for an up-slope trend), so that the crack starts where the strength is
    `mean`, as in a PST."""
    from damjax import fields

    x_lo, x_hi, y_lo, y_hi = full_window(case.start_window, case.width)
    # the distance is linear: its minimum over the window is at a corner
    d = fields.trend_distance(
        np.array([[x_lo], [x_hi]]),
        np.array([[y_lo, y_hi]]),
        case.length,
        case.width,
        case.trend_deg,
    )
    return max(0.0, float(d.min()))


def weak_spot(case: GenericSlopeCase, tau: np.ndarray) -> tuple[float, float]:
    """The weakest point of tau (box-smoothed over 2 m) in the start window [m]. Cells
    of infinite strength (no snow there, or an unbreakable layer) are left out of the
    boxes' means and are never the start: a cumulative sum over an inf gave NaN boxes,
    and argmin the first of them."""
    from damjax.release_area import smoothed_strength

    x, y = cell_centres(case)
    smooth = smoothed_strength(tau, case.dx)
    ok = np.isfinite(smooth)
    x_lo, x_hi, y_lo, y_hi = full_window(case.start_window, case.width)
    sel = (x[:, None] >= x_lo) & (x[:, None] <= x_hi) & (y[None, :] >= y_lo) & (y[None, :] <= y_hi)
    if not np.any(sel):
        raise ValueError(
            f"start_window = {list(case.start_window)}: no cell centre inside it on the "
            f"dx = {case.dx} m grid (cell centres at (k + 0.5) dx: x from {x[0]:.4g} to "
            f"{x[-1]:.4g} m, y from {y[0]:.4g} to {y[-1]:.4g} m; the window spans x "
            f"[{x_lo:g}, {x_hi:g}], y [{y_lo:g}, {y_hi:g}] m); widen it"
        )
    if not np.any(sel & ok):
        raise ValueError(
            f"start_window = {list(case.start_window)}: every cell in it has an infinite "
            "strength (no snow-covered cell there, or an unbreakable layer); move or widen "
            "it onto the slab"
        )
    i, j = np.unravel_index(np.argmin(np.where(sel, smooth, np.inf)), smooth.shape)
    return float(x[i]), float(y[j])


def setup_of(case: GenericSlopeCase, start: tuple[float, float]) -> SlopeSetup:
    """The `SlopeSetup` of a case with the given start point [m]."""
    return SlopeSetup(
        length=case.length,
        width=case.width,
        dx=case.dx,
        duration=case.duration,
        start=start,
        particles_per_cell=case.particles_per_cell,
        chunk_steps=case.chunk_steps,
        dtype=case.dtype,
    )


def run_generic_slope(
    case: GenericSlopeCase | None = None,
    params: PSTParams | None = None,
    *,
    progress: bool = False,
) -> SlopeResult:
    """Run a Fig. 13-type release; the summary gains the case description and
    ``upslope_arrest_position_m`` (highest released point on the start's up-slope band,
    from the lower edge, along the surface [m]; None where the up-slope front did not
    arrest), ``start_m`` and ``start_slope_deg``."""
    case = GenericSlopeCase() if case is None else case
    params = fig12_params() if params is None else params
    psi = slope_field(case)
    tau = strength_field(case)
    start = case.start if case.start is not None else weak_spot(case, tau)
    res = simulate_slope(
        params, setup_of(case, start), slope_deg=psi, tau_peak=tau, progress=progress
    )
    s = res.summary
    # from the lower edge, where the up-slope front arrested (None otherwise)
    d = s["upslope_arrest_distance_m"]
    s["upslope_arrest_position_m"] = None if d is None else start[0] + d
    s["start_m"] = [start[0], start[1]]
    # front_quiet_at_end and last_upslope_failure_time_s: `simulate_slope`'s summary
    at = res.arrival_time[np.isfinite(res.arrival_time)]
    s["last_failure_time_s"] = float(at.max()) if at.size else math.nan
    i = min(int(start[0] / case.dx), psi.shape[0] - 1)
    s["start_slope_deg"] = float(psi[i, 0])
    s["case"] = {
        k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(case).items()
    }
    return res


# the paper's two slopes (the shipped scenarios slope-generic-50x60 and -50x100)
FIG12A = GenericSlopeCase()
FIG12B = GenericSlopeCase(width=100.0, trend_deg=-90.0, start_window=(34.0, 40.0, 92.0, 98.0))
