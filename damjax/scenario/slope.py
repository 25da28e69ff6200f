"""Slope scenarios (``type = "slope"``): schema, validation and resolution to fields.

A slope scenario runs `damjax.scenarios.slope.simulate_slope` (the shared 2D step) over a
release area of ``length`` x ``width`` metres measured along the surface (x up-slope from
the lower edge, y across). Format (SI units, angles in degrees)::

    type = "slope"
    name = "slope-generic-50x60"
    description = "one line"

    [params]                    # fields of damjax.PSTParams (slab and weak layer);
    youngs_modulus = 4.0e6      # steady_length, strength_gradient and strength_profile
    tensile_strength = 4000.0   # are PST-only and ignored here; slope_deg is the angle
    softening = 1.0             # of a "plane" terrain, tau_peak the default strength

    [setup]                     # fields of damjax.scenarios.slope.SlopeSetup
    length = 50.0               # down-slope extent along the surface [m]
    width = 60.0                # cross-slope extent [m]
    dx = 0.2                    # grid spacing [m] (at most Lambda/2)
    duration = 2.0              # simulated time [s]
    start = [15.0, 30.0]        # crack start (x, y) [m] (see strength.start_window)
    cfl = 0.5                   # Courant number, (0, 1)
    particles_per_cell = 1      # per cell and dimension, integer >= 1
    dtype = "float32"           # "float32" or "float64"
    chunk_steps = 100           # steps per jitted chunk (one animation frame each)
    p0_rule = "paper"           # "paper" or "uniaxial"

    [terrain]                   # optional (default: kind = "plane")
    kind = "plane"              # "plane": slope_deg [deg] (default params.slope_deg)
    # kind = "generic": the paper's Fig. 12 profile (damjax.terrain.generic_slope_angle)
    #   over the release length: max_slope_deg (35), toe_slope_deg (30),
    #   top_slope_deg (20), toe_length (10 m), roll_length (10 m)
    # kind = "dem": file (.asc ESRI ASCII grid, .nc NetCDF, .tif GeoTIFF with rasterio;
    #   relative to the scenario file), origin = [x, y] map coordinates of the release
    #   area's lower (down-slope) left corner [m], upslope = "+x" | "-x" | "+y" | "-y"
    #   (the DEM axis pointing up-slope; y of the release area is that axis turned
    #   90 deg counter-clockwise). Local slope angle and fall direction come from the DEM
    #   gradient; x distances follow the surface along the area's centre line.

    [strength]                  # optional (default: kind = "constant", params.tau_peak)
    kind = "grf"                # "constant": tau_peak [Pa] (default params.tau_peak)
                                #   plus trend [Pa/m] up-slope (default 0)
                                # "grf": expected strength mean [Pa] (default
                                #   params.tau_peak) up to x = mean_at [m] (default 0),
                                #   rising trend [Pa/m] up-slope above it (as a PST's
                                #   L_ss; trend_deg [deg, counter-clockwise from
                                #   up-slope] turns it: -90 across from the y = width
                                #   edge, mean_at then measured from that edge), std [Pa],
                                #   length_scale [m] (number or [l1, l2]), angle_deg,
                                #   model ("gaussian" | "exponential"), seed (integer),
                                #   field_dx [m] (draw the field on this grid and
                                #   interpolate: the same seed, the same field on any dx)
                                # "map": file (CSV x_m, y_m, tau_peak_pa; NetCDF;
                                #   GeoTIFF) in the release area's frame: x up-slope
                                #   along the surface, y across (as measured on a
                                #   slope; not rotated like a DEM); origin = [x, y] of
                                #   the area's lower left corner in the map's
                                #   coordinates (default [0, 0]). The map must cover
                                #   the area (to half a map spacing).
    start_window = [2.0, 8.0]   # optional, any kind: start the crack at the weakest
                                # (2 m box-smoothed) spot with x in this window and y in
                                # the middle half of the width (the paper's star),
                                # instead of setup.start; or [x_min, x_max, y_min, y_max]

    [output]                    # as for PSTs: dir, plot, snapshots

Validation follows `damjax.scenario`: one line per problem naming the key, the value and
the valid range; unknown keys are rejected; files are read (and their coverage of the
release area checked) when the scenario is read.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from damjax import config
from damjax.config import PSTParams

TERRAIN_KINDS = ("plane", "generic", "dem")
STRENGTH_KINDS = ("constant", "grf", "map")
UPSLOPE_AXES = ("+x", "-x", "+y", "-y")
COVARIANCE_MODELS = ("gaussian", "exponential")
# PSTParams fields with no meaning on a slope (a PST strength profile)
PST_ONLY_PARAMS = ("steady_length", "strength_gradient", "strength_profile")

_POS = (lambda v: v > 0 and math.isfinite(v), "(0, inf)")
_NONNEG = (lambda v: v >= 0 and math.isfinite(v), "[0, inf)")
_ANY = (lambda v: math.isfinite(v), "(-inf, inf)")
_ANGLE = (lambda v: 0 < v < 90, "(0, 90)")

# key -> (kind, (check, valid range), unit) per terrain / strength kind; kinds:
# "float", "int", "str", "pair" (two numbers), "window" (two or four numbers),
# "floats" (a number or two numbers)
_TERRAIN_KEYS: dict[str, dict[str, tuple[str, Any, str]]] = {
    "plane": {"slope_deg": ("float", _ANGLE, "deg")},
    "generic": {
        "max_slope_deg": ("float", _ANGLE, "deg"),
        "toe_slope_deg": ("float", _ANGLE, "deg"),
        "top_slope_deg": ("float", _ANGLE, "deg"),
        "toe_length": ("float", _POS, "m"),
        "roll_length": ("float", _POS, "m"),
    },
    "dem": {
        "file": ("str", None, ""),
        "origin": ("pair", _ANY, "m"),
        "upslope": ("str", UPSLOPE_AXES, ""),
    },
}
_STRENGTH_KEYS: dict[str, dict[str, tuple[str, Any, str]]] = {
    "constant": {"tau_peak": ("float", _POS, "Pa"), "trend": ("float", _ANY, "Pa/m")},
    "grf": {
        "mean": ("float", _POS, "Pa"),
        "mean_at": ("float", _ANY, "m"),
        "trend": ("float", _ANY, "Pa/m"),
        "std": ("float", _NONNEG, "Pa"),
        "length_scale": ("floats", _POS, "m"),
        "angle_deg": ("float", _ANY, "deg"),
        "trend_deg": ("float", _ANY, "deg"),
        "model": ("str", COVARIANCE_MODELS, ""),
        "seed": ("int", (lambda v: v >= 0, "integers >= 0"), ""),
        "field_dx": ("float", _POS, "m"),
    },
    "map": {"file": ("str", None, ""), "origin": ("pair", _ANY, "m")},
}
_STRENGTH_COMMON = {"start_window": ("window", _NONNEG, "m")}
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


def _fmt(value: Any) -> str:
    from damjax.scenario import _fmt as fmt

    return fmt(value)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_table(
    section: str,
    table: Any,
    schema: dict[str, dict[str, tuple[str, Any, str]]],
    kinds: tuple[str, ...],
    default_kind: str,
    common: dict[str, tuple[str, Any, str]],
    problems: list[str],
) -> dict[str, Any] | None:
    """A ``[terrain]`` / ``[strength]`` table checked against its kind's keys."""
    if not isinstance(table, dict):
        problems.append(f"{section} = {_fmt(table)}: must be a table ([{section}])")
        return None
    n0 = len(problems)
    kind = table.get("kind", default_kind)
    if kind not in kinds:
        valid = "{" + ", ".join(f'"{k}"' for k in kinds) + "}"
        problems.append(f"{section}.kind = {_fmt(kind)}: must be one of {valid}")
        return None
    keys = {**schema[kind], **common}
    out: dict[str, Any] = {"kind": kind}
    for key, value in table.items():
        if key == "kind":
            continue
        if key not in keys:
            others = [k for k, s in schema.items() if key in s]
            if others:
                more = f' (only for {section}.kind = "{others[0]}")'
            else:
                hit = difflib.get_close_matches(key, ["kind", *keys], n=1)
                more = (
                    f" (did you mean '{section}.{hit[0]}'?)"
                    if hit
                    else f' (valid for kind "{kind}": {", ".join(["kind", *keys])})'
                )
            problems.append(f"{section}.{key}: unknown key{more}")
            continue
        typ, rule, unit = keys[key]
        name = f"{section}.{key}"
        u = f" {unit}" if unit else ""
        if typ == "str":
            if rule is None:
                if not isinstance(value, str) or not value:
                    problems.append(f"{name} = {_fmt(value)}: must be a path (a string)")
                    continue
            elif value not in rule:
                valid = "{" + ", ".join(f'"{c}"' for c in rule) + "}"
                problems.append(f"{name} = {_fmt(value)}: must be one of {valid}")
                continue
            out[key] = value
        elif typ == "int":
            ok, valid = rule
            if not isinstance(value, int) or isinstance(value, bool) or not ok(value):
                problems.append(f"{name} = {_fmt(value)}: must be an integer {valid[9:]}")
                continue
            out[key] = int(value)
        else:
            ok, valid = rule
            if typ == "float":
                vals = [value]
                shape_ok = True
                what = "a number"
            else:
                vals = value if isinstance(value, list) else [value]
                sizes = {"pair": (2,), "window": (2, 4), "floats": (1, 2)}[typ]
                shape_ok = len(vals) in sizes
                if typ != "floats" and not isinstance(value, list):
                    shape_ok = False
                what = {
                    "pair": "two numbers [a, b]",
                    "window": "[x_min, x_max] or [x_min, x_max, y_min, y_max]",
                    "floats": "a number or [l1, l2]",
                }[typ]
            if not shape_ok or not all(_is_number(v) for v in vals):
                problems.append(f"{name} = {_fmt(value)}: must be {what} in {valid}{u}")
                continue
            try:
                fv = [float(v) for v in vals]
            except OverflowError:
                fv = [math.inf]
            if not all(ok(v) for v in fv):
                nan = ", not nan" if any(math.isnan(v) for v in fv) else ""
                problems.append(f"{name} = {_fmt(value)}: must be {what} in {valid}{u}{nan}")
                continue
            out[key] = fv[0] if typ == "float" or not isinstance(value, list) else fv
    if len(problems) > n0:
        return None
    return out


def _resolve_path(file: str, base_dir: str | Path | None) -> Path:
    path = Path(file).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    return path.resolve()


def check(
    data: dict[str, Any], base_dir: str | Path | None, problems: list[str]
) -> tuple[Any, list[str]]:
    """The Scenario of a ``type = "slope"`` document (None with problems appended), and
    its dubious-value notes. Top-level keys, type and name are checked by the caller."""
    from damjax import scenario
    from damjax.scenarios.slope import SlopeSetup

    known_setup = {f.name for f in dataclasses.fields(SlopeSetup)}
    setup_table = data.get("setup", {})
    if isinstance(setup_table, dict):
        clean = {}
        for key, value in setup_table.items():
            if key in known_setup:
                clean[key] = value
                continue
            if key in {f.name for f in dataclasses.fields(config.PSTSetup)}:
                more = " (a PST setting: not used by slope scenarios)"
            elif key in {f.name for f in dataclasses.fields(PSTParams)}:
                more = f" (did you mean 'params.{key}'?)"
            else:
                hit = difflib.get_close_matches(key, sorted(known_setup), n=1)
                more = (
                    f" (did you mean 'setup.{hit[0]}'?)"
                    if hit
                    else " (not a field of SlopeSetup; see the damjax.slope_scenario docstring)"
                )
            problems.append(f"setup.{key}: unknown key{more}")
        setup_table = clean
    pvals, pbad, pgiven = scenario._check_section(
        "params", data.get("params", {}), PSTParams, problems
    )
    svals, sbad, _ = scenario._check_section("setup", setup_table, SlopeSetup, problems)
    ovals, _, _ = scenario._check_section(
        "output", data.get("output", {}), scenario.Output, problems
    )
    terrain = _check_table(
        "terrain", data.get("terrain", {}), _TERRAIN_KEYS, TERRAIN_KINDS, "plane", {}, problems
    )
    strength = _check_table(
        "strength",
        data.get("strength", {}),
        _STRENGTH_KEYS,
        STRENGTH_KINDS,
        "constant",
        _STRENGTH_COMMON,
        problems,
    )
    notes: list[str] = []
    # params: ranges (config's rules), retargeted to TOML keys
    params = PSTParams(**pvals)
    plines = config.param_problems(params, None)
    given = {f"params.{k}": v for k, v in pvals.items()}
    reported = {f"params.{k}" for k in pbad}
    problems += scenario._retarget(plines, reported, given)
    ignored = [k for k in PST_ONLY_PARAMS if k in pgiven]
    if ignored:
        notes.append(
            ", ".join(f"params.{k}" for k in ignored)
            + ": PST strength profile, ignored by slope scenarios (use [strength])"
        )
    # setup: types done; ranges and choices
    if "start" in svals:
        st = np.asarray(svals["start"], dtype=float)
        if st.shape != (2,):
            problems.append(f"setup.start = {_fmt(data['setup']['start'])}: must be [x, y] in m")
            sbad.add("start")
        else:
            svals["start"] = (float(st[0]), float(st[1]))
    for key in ("length", "width", "dx", "duration", "cfl", "particles_per_cell", "chunk_steps"):
        if key in svals and key not in sbad:
            ok, valid = config.SETUP_RULES[key]
            v = svals[key]
            if not ok(float(v)):
                problems.append(f"setup.{key} = {_fmt(v)}: {config.must_text(valid)}")
                sbad.add(key)
    for key, choices in (
        ("dtype", config.DTYPES),
        ("p0_rule", config.P0_RULES),
        ("mcc_invariants", getattr(config, "MCC_INVARIANTS", ("3d",))),
    ):
        if key in svals and key not in sbad and svals[key] not in choices:
            valid = "{" + ", ".join(f'"{c}"' for c in choices) + "}"
            problems.append(f"setup.{key} = {_fmt(svals[key])}: must be one of {valid}")
            sbad.add(key)
    if problems:
        return None, []
    setup = SlopeSetup(**svals)
    for key in ("length", "width"):
        if getattr(setup, key) / setup.dx < config.MIN_CELLS:
            problems.append(
                f"setup.{key} = {_fmt(getattr(setup, key))}: must be at least "
                f"{config.MIN_CELLS} cells of setup.dx = {_fmt(setup.dx)}"
            )
    if problems:
        return None, []
    x0, y0 = setup.start
    if strength is None or "start_window" not in strength:
        if not (0 <= x0 <= setup.length and 0 <= y0 <= setup.width):
            given = "" if "start" in svals else " (the default: give setup.start)"
            problems.append(
                f"setup.start = {_fmt(list(setup.start))}{given}: must lie in "
                f"[0, {setup.length:g}] x [0, {setup.width:g}] m (the release area), or give "
                "strength.start_window"
            )
    else:
        from damjax.scenarios.generic_slope import window_problem

        win = strength["start_window"]
        problem = window_problem(win, setup.length, setup.width)
        if problem:
            problems.append(f"strength.start_window = {_fmt(win)}: {problem}")
    from damjax import theory

    lam = float(theory.elastic_length(params))
    if setup.dx > lam / 2:
        problems.append(
            f"setup.dx = {_fmt(setup.dx)}: must be at most Lambda/2 = {lam / 2:.4g} m "
            f"(Lambda = {lam:.4g} m, the weak-layer elastic length, must be resolved)"
        )
    ppc = setup.particles_per_cell
    n = max(1.0, setup.length / setup.dx) * max(1.0, setup.width / setup.dx) * ppc * ppc
    if n > scenario.MAX_PARTICLES:
        problems.append(
            f"setup.dx = {_fmt(setup.dx)}: with setup.length = {setup.length:g}, setup.width "
            f"= {setup.width:g} and setup.particles_per_cell = {ppc} the run has {n:.3g} "
            f"particles: must be at most {scenario.MAX_PARTICLES:.0e}"
        )
    if terrain is not None and terrain["kind"] == "generic":
        t = {**_GENERIC_DEFAULTS, **terrain}
        # the rule of damjax.terrain.profile_problem, quoting the values as written
        if t["toe_length"] + t["roll_length"] > setup.length:
            problems.append(
                f"terrain.toe_length = {_fmt(t['toe_length'])}: toe_length + roll_length = "
                f"{t['toe_length'] + t['roll_length']:g} m must be at most setup.length = "
                f"{setup.length:g} m"
            )
    if terrain is not None and terrain["kind"] == "dem":
        if "file" not in terrain:
            problems.append("terrain.file: missing (a DEM: .asc, .nc or .tif)")
        else:
            terrain["file"] = str(_resolve_path(terrain["file"], base_dir))
    if strength is not None and strength["kind"] == "map":
        if "file" not in strength:
            problems.append("strength.file: missing (a strength map: .csv, .nc or .tif)")
        else:
            strength["file"] = str(_resolve_path(strength["file"], base_dir))
    if problems:
        return None, []
    scn = scenario.Scenario(
        name=data.get("name"),
        params=params,
        setup=setup,
        description=data.get("description", ""),
        output=scenario.Output(**ovals),
        type="slope",
        terrain=terrain,
        strength=strength,
    )
    # read the files and check the fields (before anything compiles)
    try:
        fields = resolve_fields(scn)
    except _FieldProblem as exc:
        problems.append(str(exc))
        return None, []
    slope, _, tau, start = fields
    if not np.all(np.isfinite(slope)) or np.min(slope) <= 0 or np.max(slope) >= 90:
        where = "terrain" if terrain and terrain["kind"] != "plane" else "params.slope_deg"
        problems.append(
            f"{where}: local slope angles from {np.nanmin(slope):.3g} to "
            f"{np.nanmax(slope):.3g} deg: must all be in (0, 90) deg"
        )
        return None, []
    tau_g = (
        float(params.density) * config.G_ACC * float(params.thickness) * np.sin(np.radians(slope))
    )
    frac = float(np.mean(tau <= tau_g))
    if frac > 0:
        notes.append(
            f"strength: tau_p is below the gravitational shear rho g h sin(psi) on "
            f"{100 * frac:.3g} % of the release area (the weak layer fails there under the "
            "slab's weight)"
        )
    if "start" in svals and strength is not None and "start_window" in strength:
        notes.append(
            f"setup.start = {_fmt(list(setup.start))} is not used: strength.start_window "
            f"picks the start, ({start[0]:.4g}, {start[1]:.4g}) m"
        )
    return scn, notes


def warn_resolution(scn: Any) -> None:
    """UserWarning (as `damjax.config.validate` gives PSTs) when dx > Lambda/5."""
    from damjax import theory

    lam = float(theory.elastic_length(scn.params))
    if scn.setup.dx > lam / 5:
        warnings.warn(
            f"dx = {scn.setup.dx} m is larger than Lambda/5 = {lam / 5:.3g} m: the crack-tip "
            "stress concentration is under-resolved; results may depend on dx",
            stacklevel=3,
        )


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
            mx, my, mtau = fields.load_strength_map(st["file"])
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
            f"{keys}: give tau_peak = {float(tau[i, j]):.4g} Pa at x = {x[i]:.3g} m, "
            f"y = {y[j]:.3g} m: the strength must stay > 0 Pa over the release area"
        )
    start = tuple(float(c) for c in setup.start)
    if "start_window" in st:
        from damjax.scenarios.generic_slope import GenericSlopeCase, weak_spot

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


def simulate(scn: Any, progress: bool = False, **resume: Any) -> Any:
    """Run a slope scenario: `simulate_slope` on the resolved fields (`SlopeResult`).

    ``resume``: `simulate_slope`'s state, start_chunk, history and callback (checkpoints).
    The summary gains ``upslope_arrest_position_m`` (from the lower edge [m]),
    ``start_m`` and ``start_slope_deg``.
    """
    from damjax.scenarios.slope import simulate_slope

    slope, fall, tau, start = resolve_fields(scn)
    setup = dataclasses.replace(scn.setup, start=start)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        res = simulate_slope(
            scn.params,
            setup,
            slope_deg=slope,
            tau_peak=tau,
            fall_deg=fall,
            progress=progress,
            **resume,
        )
    s = res.summary
    s["upslope_arrest_position_m"] = start[0] + s["upslope_arrest_distance_m"]
    s["start_m"] = [start[0], start[1]]
    i = min(int(start[0] / setup.dx), np.shape(slope)[0] - 1)
    j = min(int(start[1] / setup.dx), np.shape(slope)[1] - 1)
    s["start_slope_deg"] = float(np.asarray(slope)[i, j])
    return res


def crack_speed_map(result: Any, smooth_m: float = 1.0) -> np.ndarray:
    """Local crack speed |grad t_arrival|^-1 [m/s] on the cell grid (NaN where intact).

    The gradient of the arrival time is the least-squares plane through the failed cells
    of a ``smooth_m`` window around each cell (the front is resolved to a cell; a raw
    finite difference is noisy). A fit, unlike smoothing then differencing, stays unbiased
    where the window is cut by the area's edges or by intact cells: a box average there
    flattens the field and made the speed up to 3 times too high along the edges.
    """
    from damjax.fields import box_sum

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
        return np.where(ok & (g > 0), 1.0 / g, np.nan)


def read_setup_params(text: str) -> tuple[Any, PSTParams]:
    """SlopeSetup and PSTParams of a stored (already validated) slope scenario's TOML,
    without re-reading its files (for `damjax show`)."""
    import tomllib

    from damjax.scenarios.slope import SlopeSetup

    data = tomllib.loads(text)
    sfields = {f.name for f in dataclasses.fields(SlopeSetup)}
    sv = {k: v for k, v in data.get("setup", {}).items() if k in sfields}
    if "start" in sv:
        sv["start"] = tuple(sv["start"])
    pfields = {f.name for f in dataclasses.fields(PSTParams)}
    pv = {k: v for k, v in data.get("params", {}).items() if k in pfields}
    return SlopeSetup(**sv), PSTParams(**pv)


def result_dataset(result: Any, snapshots: bool = True) -> Any:
    """`SlopeResult.to_dataset` with the crack-speed map, crown / stauchwall / released
    masks (0/1 on the cell grid), float32 snapshots (or none)."""
    ds = result.to_dataset()
    ds["crack_speed"] = (("x", "y"), crack_speed_map(result))
    ds["crack_speed"].attrs = {
        "units": "m s-1",
        "long_name": "local crack speed |grad arrival_time|^-1 (1 m box-smoothed)",
    }
    h0 = float(result.params.thickness)
    for name, mask, what in (
        ("crown", result.height < 0.98 * h0, "tensile fracture (crown): h < 0.98 h0"),
        ("stauchwall", result.height > 1.02 * h0, "compression (stauchwall): h > 1.02 h0"),
        ("released", np.isfinite(result.arrival_time), "weak layer failed"),
    ):
        ds[name] = (("x", "y"), mask.astype(np.int8))
        ds[name].attrs = {"units": "1", "long_name": what, "flag_values": "0 1"}
    names = [n for n in ds.variables if "snapshot" in ds[n].dims]
    if not snapshots:
        ds = ds.drop_vars(names)
    else:
        for n in names:
            if ds[n].dtype == np.float64 and n != "snapshot_time":
                ds[n] = ds[n].astype(np.float32)
    return ds


def load_result(path: str | Path) -> Any:
    """A `SlopeResult` rebuilt from a slope run's ``results.nc`` (ValueError if the file
    is not a slope result)."""
    import json

    from damjax import io
    from damjax.scenarios.slope import SlopeResult

    ds = io.open_dataset(path)
    text = ds.attrs.get("scenario", "")
    if "arrival_time" not in ds or 'type = "slope"' not in text:
        raise ValueError(f"{path}: not a slope result")
    setup, params = read_setup_params(text)
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
