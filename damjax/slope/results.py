"""Slope results after the run: the crack-speed map, the NetCDF dataset written by
`damjax run` (with crown / stauchwall / released masks) and a `SlopeResult` read back
from it.
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from damjax import io
from damjax.fields.grf import box_sum
from damjax.params import PSTParams, SlopeSetup
from damjax.slope.simulation import SlopeResult, initial_thickness


def _speed_fit(result: Any, smooth_m: float) -> np.ndarray:
    """|grad t_arrival|^-1 [m/s] of the least-squares plane through the failed cells of a
    ``smooth_m`` window around each cell (NaN where intact or the fit is singular)."""
    t = np.where(np.isfinite(result.arrival_time), result.arrival_time, np.nan)
    if t.shape[0] < 2 or t.shape[1] < 2:
        return np.full(t.shape, np.nan)
    dx = float(result.x[1] - result.x[0])
    k = max(1, int(round(0.5 * smooth_m / dx)))
    valid = np.isfinite(t)
    w = valid.astype(float)
    tt = np.where(valid, t, 0.0)
    # cell offsets in cells (the fit is shift-invariant; small numbers keep it exact)
    ii, jj = np.meshgrid(
        np.arange(t.shape[0], dtype=float), np.arange(t.shape[1], dtype=float), indexing="ij"
    )

    def box(a: np.ndarray) -> np.ndarray:  # window sums, zero outside the area
        return box_sum(a, k)

    n = box(w)
    si, sj, st = box(w * ii), box(w * jj), box(tt)
    with np.errstate(divide="ignore", invalid="ignore"):
        sii = box(w * ii * ii) - si * si / n
        sjj = box(w * jj * jj) - sj * sj / n
        sij = box(w * ii * jj) - si * sj / n
        sit = box(tt * ii) - si * st / n
        sjt = box(tt * jj) - sj * st / n
        det = sii * sjj - sij * sij
        ok = valid & (n >= 3) & (det > 1e-9 * np.maximum(sii * sjj, 1e-300))
        gx = (sjj * sit - sij * sjt) / det / dx  # [s/m]
        gy = (sii * sjt - sij * sit) / det / dx
        g = np.hypot(gx, gy)
        return np.where(ok & (g > 0), 1.0 / g, np.inf * ok)


def front_speed_limit(params: Any) -> float:
    """The fastest a crack front can run under a 2D slab [m/s]: the slab's plane-stress
    wave speed sqrt(E / ((1 - nu^2) rho)) (1.69 c_s at nu = 0.3), which carries the load
    from the failed weak layer to the intact one."""
    from damjax import theory

    return float(theory.plane_stress_wave_speed(params))


def crack_speed_map(result: Any, smooth_m: float = 1.0) -> np.ndarray:
    """Local crack speed |grad t_arrival|^-1 [m/s] on the cell grid (NaN where intact, and
    where the weak layer failed faster than a front can run: `simultaneous_failure_map`).

    The gradient of the arrival time is the least-squares plane through the failed cells
    of a ``smooth_m`` window around each cell (the front is resolved to a cell; a raw
    finite difference is noisy). A fit, unlike smoothing then differencing, stays unbiased
    where the window is cut by the area's edges or by intact cells: a box average there
    flattens the field and made the speed up to 3 times too high along the edges.

    A front is carried by the slab, so it cannot outrun the slab's fastest wave
    (`front_speed_limit`). Where the arrival times rise more slowly than that over the
    window, the cells did not fail one after the other as a front passed but (nearly)
    together, and the fit's speed is no front's: on slope-quick (2026-11-27) the cells at
    the lower edge below the start (10 cells within 0.7 ms) and the two rows under the
    free top edge (the whole 6 m width within 3 ms) read up to 2.85 c_s. Those cells are
    NaN here and 1 in `simultaneous_failure_map` (1.6 % of slope-quick's area).
    """
    v = _speed_fit(result, smooth_m)
    limit = front_speed_limit(result.params)
    return np.where(np.isfinite(v) & (v <= limit), v, np.nan)


def simultaneous_failure_map(result: Any, smooth_m: float = 1.0) -> np.ndarray:
    """Failed cells (bool, on the cell grid) whose arrival times over the ``smooth_m``
    window rise more slowly than a front can run (`front_speed_limit`): the weak layer
    there failed (nearly) at once rather than as a front passed, and
    `crack_speed_map` gives no speed."""
    v = _speed_fit(result, smooth_m)
    with np.errstate(invalid="ignore"):
        return ~np.isnan(v) & (v > front_speed_limit(result.params))


def read_setup_params(text: str) -> tuple[Any, PSTParams]:
    """SlopeSetup and PSTParams of a stored (already validated) slope scenario's TOML,
    without re-reading its files (for `damjax show`)."""
    data = tomllib.loads(text)
    sv = {k: v for k, v in data.get("setup", {}).items() if k in _setup_fields()}
    if "start" in sv:
        sv["start"] = tuple(sv["start"])
    pfields = {f.name for f in dataclasses.fields(PSTParams)}
    pv = {k: v for k, v in data.get("params", {}).items() if k in pfields}
    return SlopeSetup(**sv), PSTParams(**pv)


def _setup_fields() -> set[str]:
    return {f.name for f in dataclasses.fields(SlopeSetup)}


def _leaf(v: Any) -> Any:
    """A stored parameter: a number, None, or an array (a profile) as numpy ("inf",
    "-inf" and "nan": strict JSON's non-finite numbers; files before 2026-11-28 wrote
    Infinity, which json reads itself)."""
    if isinstance(v, str) and v in ("inf", "-inf", "nan"):
        return float(v)
    if isinstance(v, list):
        return np.asarray([_leaf(x) for x in v], dtype=float)
    return v


def _flags(meanings: str) -> dict[str, Any]:
    """CF flag attributes of a 0/1 map: values of its type (int8), one meaning each."""
    return {"flag_values": np.array([0, 1], np.int8), "flag_meanings": meanings}


def result_dataset(result: Any, snapshots: bool = True) -> Any:
    """`SlopeResult.to_dataset` with the crack-speed map, crown / stauchwall / released
    masks (0/1 on the cell grid), float32 snapshots (or none)."""
    ds = result.to_dataset()
    ds["crack_speed"] = (("x", "y"), crack_speed_map(result))
    ds["crack_speed"].attrs = {
        "units": "m s-1",
        "long_name": "local crack speed |grad arrival_time|^-1 (plane fit over 1 m); "
        "NaN where intact or where the cells failed together (simultaneous_failure)",
    }
    ds["simultaneous_failure"] = (("x", "y"), simultaneous_failure_map(result).astype(np.int8))
    ds["simultaneous_failure"].attrs = {
        "units": "1",
        "long_name": "weak layer failed faster than the slab's plane-stress wave speed "
        "over 1 m: no front, no crack speed",
        **_flags("front simultaneous"),
    }
    h0 = initial_thickness(result)
    for name, mask, what, meanings in (
        ("crown", result.height < 0.98 * h0, "tensile fracture (crown): h < 0.98 h0", "no crown"),
        (
            "stauchwall",
            result.height > 1.02 * h0,
            "compression (stauchwall): h > 1.02 h0",
            "no stauchwall",
        ),
        ("released", np.isfinite(result.arrival_time), "weak layer failed", "intact failed"),
    ):
        ds[name] = (("x", "y"), mask.astype(np.int8))
        ds[name].attrs = {"units": "1", "long_name": what, **_flags(meanings)}
    names = [n for n in ds.variables if "snapshot" in ds[n].dims]
    if not snapshots:
        ds = ds.drop_vars(names)
    else:
        for n in names:
            if ds[n].dtype == np.float64 and n != "snapshot_time":
                ds[n] = ds[n].astype(np.float32)
    return ds


def load_result(path: str | Path) -> Any:
    """A `SlopeResult` rebuilt from a slope run's ``results.nc``, or from a file of
    `SlopeResult.to_netcdf` or `SlopeResult.to_dataset` (ValueError if the file is not
    a slope result)."""
    ds = io.open_dataset(path)
    text = ds.attrs.get("scenario", "")
    if "arrival_time" in ds and 'type = "slope"' in text:
        setup, params = read_setup_params(text)
    elif "arrival_time" in ds and {"setup", "params"} <= set(ds.attrs):  # to_dataset's
        sv = json.loads(ds.attrs["setup"])
        if sv.get("start") is not None:
            sv["start"] = tuple(sv["start"])
        pv = json.loads(ds.attrs["params"])
        known = {f.name for f in dataclasses.fields(PSTParams)}
        setup = SlopeSetup(**{k: v for k, v in sv.items() if k in _setup_fields()})
        params = PSTParams(**{k: _leaf(v) for k, v in pv.items() if k in known})
    else:
        raise ValueError(
            f"{path}: not a slope result (no arrival_time map, or neither a slope scenario "
            "nor the setup and params of SlopeResult.to_dataset in its attributes)"
        )
    summary = json.loads(ds.attrs.get("summary", "{}"))
    start = summary.get("start_m")
    if start is not None:
        setup = dataclasses.replace(setup, start=tuple(start))
    at = ds["arrival_time"].values
    snaps: dict[str, np.ndarray] = {}
    if "snapshot_time" in ds:
        snaps = {
            "time": ds["snapshot_time"].values,
            "height": ds["height_snapshots"].values,
            "broken": ds["released_snapshots"].values,
        }
    return SlopeResult(
        thickness=ds["thickness"].values if "thickness" in ds else None,
        snow=ds["snow"].values.astype(bool) if "snow" in ds else None,
        x=ds["x"].values,
        y=ds["y"].values,
        height=ds["height"].values,
        arrival_time=np.where(np.isnan(at), np.inf, at),
        tension=ds["tension"].values,
        opening=ds["opening"].values,
        tau_peak=ds["tau_peak"].values,
        slope_deg=ds["slope_angle"].values,
        snapshots=snaps,
        summary=summary,
        setup=setup,
        params=params,
    )
