"""The ensemble's files: one NetCDF per finished slice of members (`slice_dataset`) and
``ensemble.nc`` with every member and the products (`assemble`): the release probability
per cell and the quantiles of the release area and of the up-slope arrest distance."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from damjax import io
from damjax.ensemble.spec import Ensemble, key_of, member_draws, member_seed

ENSEMBLE_FILE = "ensemble.nc"
FIGURE = "ensemble.png"
SUMMARY_FILE = "ensemble_summary.json"
SLICE_DIR = "slices"
QUANTILES = (0.05, 0.5, 0.95)
# the per-member summaries with quantiles (the arrest distance: over the members that
# arrested; NaN where none did)
QUANTILE_KEYS = ("release_area_m2", "upslope_extent_m", "upslope_arrest_distance_m")
TIMING_KEYS = ("compile_time_s", "wall_time_s", "particle_steps_per_s")
SUMMARY_KEYS = (
    "release_area_m2",
    "upslope_extent_m",
    "upslope_arrest_distance_m",
    "upslope_arrest_position_m",
    "crossslope_extent_m",
    "crossslope_arrest_distance_m",
    "crown_area_m2",
    "stauchwall_area_m2",
    "slab_fracture_area_m2",
    "arrested_before_top",
    "front_quiet_at_end",
    "last_upslope_failure_time_s",
    "critical_cut_radius_m",
    "upslope_crack_speed_over_cs",
    "crossslope_crack_speed_over_cs",
    "start_slope_deg",
    # a release on terrain (2026-11-27)
    "domain_edge_fraction",
    "initial_failure_area_m2",
    "outflow_area_m2",
    "arrival_sources",
)
# the fronts' states (strings: "arrested", "reached_edge", "moving", "sawn_only")
STATE_KEYS = ("upslope_front", "crossslope_front")
_UNITS = {
    "release_area_m2": ("m2", "area of failed weak layer"),
    "upslope_extent_m": (
        "m",
        "up-slope extent of the release from the start, within 1 m across of it",
    ),
    "upslope_arrest_distance_m": (
        "m",
        "up-slope arrest distance from the start (NaN where upslope_front is not arrested)",
    ),
    "upslope_arrest_position_m": (
        "m",
        "up-slope arrest position from the lower edge (NaN where not arrested)",
    ),
    "crossslope_extent_m": (
        "m",
        "cross-slope extent of the release from the start, within 1 m up or down slope of it",
    ),
    "crossslope_arrest_distance_m": (
        "m",
        "cross-slope arrest distance from the start (NaN where crossslope_front is not arrested)",
    ),
    "crown_area_m2": ("m2", "area of slab with h < 0.98 h0 (crown)"),
    "stauchwall_area_m2": ("m2", "area of slab with h > 1.02 h0 (stauchwall)"),
    "slab_fracture_area_m2": ("m2", "area of fractured slab"),
    "arrested_before_top": ("1", "up-slope front arrested (upslope_front is arrested)"),
    "front_quiet_at_end": ("1", "no up-slope failure in the last 0.3 s"),
    "last_upslope_failure_time_s": ("s", "time of the last up-slope failure"),
    "critical_cut_radius_m": ("m", "sawn radius when the crack ran by itself"),
    "upslope_crack_speed_over_cs": ("1", "peak up-slope crack speed over c_s"),
    "crossslope_crack_speed_over_cs": ("1", "peak cross-slope crack speed over c_s"),
    "start_slope_deg": ("degree", "slope angle at the start"),
    "domain_edge_fraction": ("1", "share of the release's boundary on the domain's edge"),
    "initial_failure_area_m2": ("m2", "weak layer failing under its own slab at t = 0"),
    "outflow_area_m2": ("m2", "slab that slid out over the grid's edge"),
    "arrival_sources": ("1", "sources of the arrival-time map (1: the trigger alone)"),
}


def slice_dataset(ens: Ensemble, idx: list[int], results: list[Any]) -> Any:
    """The dataset of members ``idx`` from their `SlopeResult` s: per-member summaries,
    seeds, drawn parameters and the maps ``released``, ``arrival_time``, ``height`` and
    ``tau_peak`` (no wall-clock numbers)."""
    import xarray as xr

    r0 = results[0]

    def var(dims: tuple[str, ...], data: Any, units: str | None, long_name: str) -> Any:
        # text (a front's state) has no units (CF: units are for numbers)
        attrs = {} if units is None else {"units": units}
        return xr.Variable(dims, np.asarray(data), {**attrs, "long_name": long_name})

    data: dict[str, Any] = {
        "seed": var(("member",), [member_seed(ens, i) for i in idx], "1", "GRF seed"),
        "start_x": var(
            ("member",), [r.summary["start_m"][0] for r in results], "m", "crack start x"
        ),
        "start_y": var(
            ("member",), [r.summary["start_m"][1] for r in results], "m", "crack start y"
        ),
        "faulted": var(
            ("member",),
            np.array([r.summary.get("fault") is not None for r in results], np.int8),
            "1",
            "run stopped by a runtime fault",
        ),
    }
    for key in SUMMARY_KEYS:
        vals = []
        for r in results:
            v = r.summary.get(key)
            vals.append(math.nan if v is None else float(v))
        units, long_name = _UNITS[key]
        arr = np.array(vals, np.float64)
        if units == "1" and key in ("arrested_before_top", "front_quiet_at_end"):
            arr = arr.astype(np.int8)
        data[key] = var(("member",), arr, units, long_name)
    for key in STATE_KEYS:
        data[key] = var(
            ("member",),
            np.array([str(r.summary.get(key, "")) for r in results], dtype=str),
            None,
            f"state of the {key.split('_')[0]} front: arrested, reached_edge, moving or sawn_only",
        )
    for part, pre in ((0, "param_"), (1, "strength_")):
        names = sorted(ens.params if part == 0 else ens.strength)
        for name in names:
            vals = [member_draws(ens, i)[part][name] for i in idx]
            kind = (ens.scenario.strength or {"kind": "constant"})["kind"]
            units = (
                _param_units(name)
                if part == 0
                else _KIND_UNITS.get((kind, name), _STRENGTH_UNITS.get(name, ""))
            )
            data[pre + name] = var(("member",), vals, units, f"drawn {name}")
    stack = lambda f: np.stack([f(r) for r in results])  # noqa: E731
    data["released"] = var(
        ("member", "x", "y"),
        stack(lambda r: np.isfinite(r.arrival_time)).astype(np.int8),
        "1",
        "weak layer failed (0/1)",
    )
    data["arrival_time"] = var(
        ("member", "x", "y"),
        stack(lambda r: np.where(np.isfinite(r.arrival_time), r.arrival_time, np.nan)).astype(
            np.float32
        ),
        "s",
        "weak-layer failure time",
    )
    data["height"] = var(
        ("member", "x", "y"), stack(lambda r: r.height).astype(np.float32), "m", "final slab height"
    )
    data["tau_peak"] = var(
        ("member", "x", "y"),
        stack(lambda r: r.tau_peak).astype(np.float32),
        "Pa",
        "weak-layer shear strength",
    )
    data["slope_angle"] = var(
        ("x", "y"), r0.slope_deg.astype(np.float32), "degree", "local slope angle"
    )
    if r0.snow is not None:  # the terrain's snow cover: the same in every member
        data["snow"] = var(
            ("x", "y"), np.asarray(r0.snow).astype(np.int8), "1", "cell holds a slab (0/1)"
        )
    summaries = [{k: v for k, v in r.summary.items() if k not in TIMING_KEYS} for r in results]
    ds = xr.Dataset(
        data,
        coords={
            "member": var(("member",), np.asarray(idx, np.int64), "1", "member index"),
            "x": var(("x",), r0.x, "m", "up-slope distance along the surface"),
            "y": var(("y",), r0.y, "m", "cross-slope distance along the surface"),
        },
        attrs={"summaries": io.to_json(summaries), "key": key_of(ens)},
    )
    return ds


# CF units of the drawn strength-field settings (`damjax.ensemble.spec.STRENGTH_DRAWS`)
_STRENGTH_UNITS = {
    "mean": "Pa",
    "mean_at": "m",
    "trend": "Pa m-1",
    "std": "Pa",
    "length_scale": "m",
    "angle_deg": "degree",
    "trend_deg": "degree",
    "tau_peak": "Pa",
    "cov": "1",
    "cohesion": "Pa",
    "friction_coefficient": "1",
}
# per strength kind where a setting's unit differs (a stability ratio's mean)
_KIND_UNITS = {("stability", "mean"): "1"}


def _param_units(name: str) -> str:
    """CF units of a drawn PSTParams field (its declaration, `damjax.params`)."""
    from damjax.params import PSTParams, specs

    return specs(PSTParams)[name].cf_unit


def slice_name(a: int, b: int) -> str:
    """File name of the slice of members a..b-1."""
    return f"members_{a:05d}-{b:05d}.nc"


def done_slices(folder: Path) -> dict[tuple[int, int], Path]:
    """The finished slice files of an output folder, by (first, end) member."""
    out = {}
    for p in sorted((folder / SLICE_DIR).glob("members_*-*.nc")):
        a, b = p.stem.split("_", 1)[1].split("-")
        out[(int(a), int(b))] = p
    return out


def drop_string_widths(ds: Any) -> Any:
    """``ds`` without the string widths its variables were read with: a concatenation keeps
    the first part's (a slice whose fronts were all "moving" read as 6 characters), and
    writing it would cut the longer values of the other parts ("reached_edge" became
    "reache" in ensemble.nc)."""
    for v in ds.variables.values():
        if v.dtype.kind in "US":
            v.encoding.pop("dtype", None)
    return ds


def assemble(out_dir: str | os.PathLike[str], members: int, key: str | None = None) -> Any:
    """The ensemble dataset of members 0..members-1 from the slice files of ``out_dir``,
    with its products: ``release_probability`` (x, y) and the quantiles (``quantile``)
    of `QUANTILE_KEYS`: ``release_area_m2_quantiles``, ``upslope_extent_m_quantiles`` and
    ``upslope_arrest_distance_m_quantiles`` (over the members that arrested)."""
    import xarray as xr

    parts = []
    seen: set[int] = set()  # slices of earlier plans may overlap: each member once
    for (a, b), p in done_slices(Path(out_dir)).items():
        if a >= members:
            continue
        d = io.open_dataset(p)
        if key is not None and d.attrs.get("key") != key:
            raise ValueError(f"{p}: a slice of another ensemble (key {d.attrs.get('key')})")
        d = d.sel(member=slice(a, min(b, members) - 1))
        keep = [i for i, m in enumerate(d["member"].values) if int(m) not in seen]
        if not keep:
            continue
        seen.update(int(m) for m in d["member"].values[keep])
        summ = json.loads(d.attrs["summaries"])
        d = d.isel(member=keep)
        d.attrs["summaries"] = io.to_json([summ[i] for i in keep])
        parts.append(d)
    if not parts:
        raise ValueError(f"{out_dir}: no finished members")
    summaries = sum((json.loads(p.attrs["summaries"])[: p.sizes["member"]] for p in parts), [])
    # maps of the terrain, not of a member: kept once
    shared = [v for v in ("slope_angle", "snow") if v in parts[0]]
    kept = {v: parts[0][v] for v in shared}
    ds = drop_string_widths(xr.concat([p.drop_vars(shared) for p in parts], dim="member"))
    ds = ds.sortby("member")
    have = ds["member"].values
    if have.size != members or not np.array_equal(have, np.arange(members)):
        missing = sorted(set(range(members)) - set(have.tolist()))
        raise ValueError(f"{out_dir}: members {missing[:10]} not finished")
    for v, a in kept.items():
        ds[v] = a
    prob = ds["released"].astype(np.float64).mean("member")
    ds["release_probability"] = prob.astype(np.float32)
    ds["release_probability"].attrs = {
        "units": "1",
        "long_name": "release probability (member mean of released)",
    }
    q = np.asarray(QUANTILES)
    ds = ds.assign_coords(quantile=("quantile", q, {"units": "1", "long_name": "probability"}))
    for name in QUANTILE_KEYS:
        vals = ds[name].values
        over = " over the members whose up-slope front arrested" if "arrest" in name else ""
        ds[f"{name}_quantiles"] = (
            ("quantile",),
            np.quantile(vals[np.isfinite(vals)], q) if np.any(np.isfinite(vals)) else q * np.nan,
            {"units": ds[name].attrs["units"], "long_name": f"quantiles of {name}{over}"},
        )
    ds.attrs = {
        "title": "damjax slope release ensemble",
        "damjax_version": _version(),
        "members": members,
        "summaries": io.to_json(summaries),
        "key": key or parts[0].attrs.get("key", ""),
        "Conventions": "CF-1.10",
    }
    return ds


def _version() -> str:
    from damjax._version import __version__

    return __version__


def quantile_summary(ds: Any) -> dict[str, Any]:
    """``members``, ``upslope_arrested_members`` (how many members' up-slope front
    arrested) and the quantile objects (q05, q50, q95; None where no member had a value)
    of the release area [m^2], the up-slope extent [m] and the up-slope arrest distance
    [m] (over the members that arrested) of an ensemble dataset."""

    def obj(name: str) -> dict[str, float | None]:
        return {
            f"q{round(100 * q):02d}": float(v) if np.isfinite(v) else None
            for q, v in zip(QUANTILES, ds[f"{name}_quantiles"].values, strict=True)
        }

    if "upslope_front" in ds:
        arrested = int(np.sum(ds["upslope_front"].values.astype(str) == "arrested"))
    else:  # an ensemble.nc of an earlier version
        arrested = int(np.sum(np.isfinite(ds["upslope_arrest_distance_m"].values)))
    return {
        "members": int(ds.sizes["member"]),
        "upslope_arrested_members": arrested,
        **{f"{name}_quantiles": obj(name) for name in QUANTILE_KEYS if f"{name}_quantiles" in ds},
    }
