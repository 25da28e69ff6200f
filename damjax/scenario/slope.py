"""Slope scenarios (``type = "slope"``): schema, validation and resolution to fields.

A slope scenario runs `damjax.simulate_slope` (the shared 2D step) over a
release area of ``length`` x ``width`` metres measured along the surface (x up-slope from
the lower edge, y across). Format (SI units, angles in degrees)::

    type = "slope"
    name = "slope-generic-50x60"
    description = "one line"

    [params]                    # fields of damjax.PSTParams (slab and weak layer);
    youngs_modulus = 4.0e6      # steady_length, strength_gradient and strength_profile
    tensile_strength = 4000.0   # are PST-only and ignored here; slope_deg is the angle
    softening = 1.0             # of a "plane" terrain, tau_peak the default strength

    [setup]                     # fields of damjax.SlopeSetup, e.g.
    length = 50.0               # down-slope extent along the surface [m]
    width = 60.0                # cross-slope extent [m]
    dx = 0.2                    # grid spacing [m] (at most Lambda/2)
    start = [15.0, 30.0]        # crack start (x, y) [m] (see strength.start_window)
    # every field of [params] and [setup], with its unit, valid range, kind and default:
    # `damjax.params` (the reference page "Scenario-file keys" is generated from it)

    [terrain]                   # optional (default: kind = "plane")
    kind = "plane"              # "plane": slope_deg [deg] (default params.slope_deg)
    # kind = "generic": the paper's Fig. 13 profile (damjax.terrain.generic_slope_angle)
    #   over the release length: max_slope_deg (35), toe_slope_deg (30),
    #   top_slope_deg (20), toe_length (10 m), roll_length (10 m)
    # kind = "dem": file (.asc ESRI ASCII grid, .nc NetCDF, .tif GeoTIFF with rasterio;
    #   relative to the scenario file), origin = [x, y] map coordinates of the release
    #   area's lower (down-slope) left corner [m], upslope = "+x" | "-x" | "+y" | "-y"
    #   (the DEM axis pointing up-slope; y of the release area is that axis turned
    #   90 deg counter-clockwise). Local slope angle and fall direction come from the DEM
    #   gradient; x distances follow the surface along the area's centre line.
    #   release = "polygon.shp": a release polygon (the DEM's CRS) sets origin, upslope,
    #   length and width; thickness_field names its thickness attribute ("thickness").
    #   buffer = 150.0 [m] (default with a polygon): the domain is the terrain within
    #   this map distance of the polygon, clipped to the DEM (cells without DEM data
    #   hold no slab); or margin = 10.0 [m]: the rectangle of the polygon plus a margin
    #   (earlier versions; give one of the two)

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
                                #   the area's (0, 0) corner in the map's
                                #   coordinates (default [0, 0]). The map must cover
                                #   the area (to half a map spacing). NetCDF: a 2D
                                #   variable on dimensions named x/y (or easting/
                                #   northing, ...); variable = "name" picks it where
                                #   the file holds several.
                                # "stability" (2026-11-27): a weak layer that holds its
                                #   own slab, tau_p = S rho g h0 sin(psi) with each
                                #   particle's own h0 and psi; S - 1 a log-normal random
                                #   field, S > 1: mean [-] (> 1, default 1.42, the paper's
                                #   1000 / 703), cov [-] (default 0.1), length_scale,
                                #   angle_deg, model, seed, field_dx (as "grf");
                                #   optional friction_coefficient [-]: adds its times
                                #   rho g h0 cos(psi), a floor that follows the normal
                                #   load (S tau_g vanishes on near-flat snow)
                                # "coulomb" (2026-11-27): tau_p = cohesion [Pa] +
                                #   friction_coefficient [-] x rho g h0 cos(psi) (both
                                #   required); std [Pa] > 0 makes the cohesion a random
                                #   field (length_scale, angle_deg, model, seed, field_dx)
    start_window = [2.0, 8.0]   # optional, any kind: start the crack at the weakest
                                # (2 m box-smoothed) spot with x in this window and y in
                                # the middle half of the width (the paper's star),
                                # instead of setup.start; or [x_min, x_max, y_min, y_max]
                                # ("stability" and "coulomb": the lowest tau_p / tau_g)
    natural_release = false     # optional, any kind (2026-11-27): a scenario in which
                                # the weak layer of a snow-covered cell farther than 2 m
                                # from the start fails under its own slab at t = 0 stops
                                # with one line (how many cells, where); true runs it
    trigger = "weakest"         # optional (2026-11-27): "random" starts the crack at a
                                # random cell of the start zone ([snow]), drawn with
                                # strength.seed (an ensemble's members: their own spots)

    [snow]                      # optional (2026-11-27; damjax.snow_cover): the snow cover.
                                # Without it every cell holds params.thickness
    kind = "uniform"            # "uniform": params.thickness (or the polygon's)
                                # "slope_corrected": reference_thickness d0* [m] (default
                                #   params.thickness) x 0.291 / (sin psi - 0.202 cos psi)
                                #   (Swiss guidelines; held at 1 below 28 deg)
                                # "depth_map": file = raster of the vertical snow depth HS
                                #   [m] (.tif, .asc, .nc; the DEM's CRS): h0 = HS cos(psi)
    max_slope_deg = 60.0        # [deg], (0, 90]: no slab on steeper cells
    min_thickness = 0.1         # [m], > 0: no slab on thinner cells (any kind)
    start_min_slope_deg = 28.0  # [deg]: the start zone is the snow in this..max_slope_deg
    mask = "forest.tif"         # optional raster (the DEM's CRS): nonzero cells hold no
                                # snow (forest, rock); or polygons (.shp, .gpkg, .geojson):
                                # no snow inside them. Cells without snow hold no particle
                                # (no particle work) and are free edges. Files: DEM only

    [output]                    # as for PSTs: dir, plot, snapshots

Validation follows `damjax.scenario`: one line per problem naming the key, the value and
the valid range; unknown keys are rejected; files are read (and their coverage of the
release area checked) when the scenario is read. Released slab that slides over the
grid's edge leaves the run (summary ``outflow_area_m2``).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from damjax import snow_cover, theory
from damjax.params import PSTParams, PSTSetup, SlopeSetup, specs
from damjax.scenario import slope_fields
from damjax.scenario.schema import (
    MAX_PARTICLES,
    Output,
    Scenario,
    _check_section,
    _fmt,
    _is_number,
    register,
    toml_lines,
)
from damjax.scenario.slope_fields import (
    _GENERIC_DEFAULTS,
    NATURAL_RELEASE_ADVICE,
    _FieldProblem,
    natural_release_problem,
    resolve_inputs,
)
from damjax.slope import simulation
from damjax.slope.generic import window_problem
from damjax.validation import InputError, Problem, implausible, same_value

TERRAIN_KINDS = ("plane", "generic", "dem")
STRENGTH_KINDS = ("constant", "grf", "map", "stability", "coulomb")
SNOW_KINDS = ("uniform", "slope_corrected", "depth_map")
TRIGGERS = ("weakest", "random")
UPSLOPE_AXES = ("+x", "-x", "+y", "-y")
COVARIANCE_MODELS = ("gaussian", "exponential")
# PSTParams fields with no meaning on a slope (a PST strength profile)
PST_ONLY_PARAMS = tuple(name for name, spec in specs(PSTParams).items() if spec.pst_only)

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
        "release": ("str", None, ""),
        "margin": ("float", _NONNEG, "m"),
        "thickness_field": ("str", None, ""),
        # a domain the terrain bounds (2026-11-27): the terrain within this map distance
        # of the release polygon, clipped to the DEM (default BUFFER_DEFAULT with a
        # polygon, unless a margin is given: the rectangle of earlier versions)
        "buffer": ("float", _POS, "m"),
    },
}
BUFFER_DEFAULT = 150.0  # [m] around a release polygon
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
    "map": {
        "file": ("str", None, ""),
        "origin": ("pair", _ANY, "m"),
        "variable": ("str", None, ""),
    },
    # --- a weak layer that holds its own slab (2026-11-27) ---------------------------
    # "stability": S = tau_p / tau_g, tau_g = rho g h0 sin(psi) each particle's own load;
    # S - 1 a log-normal random field (damjax.fields.stability_field), S > 1 everywhere
    "stability": {
        "mean": ("float", (lambda v: v > 1 and math.isfinite(v), "(1, inf)"), ""),
        "cov": ("float", _NONNEG, ""),
        # optional: + friction_coefficient x rho g h0 cos(psi), a floor on near-flat snow
        "friction_coefficient": ("float", _NONNEG, ""),
    },
    # "coulomb": tau_p = cohesion + friction_coefficient x rho g h0 cos(psi); the cohesion
    # a constant or (std > 0) a Gaussian random field as "grf"'s
    "coulomb": {
        "cohesion": ("float", _NONNEG, "Pa"),
        "friction_coefficient": ("float", _NONNEG, ""),
        "std": ("float", _NONNEG, "Pa"),
    },
}
# the random field's correlation, as "grf"'s, for the kinds of 2026-11-27
for _kind in ("stability", "coulomb"):
    _STRENGTH_KEYS[_kind].update(
        {
            k: _STRENGTH_KEYS["grf"][k]
            for k in ("length_scale", "angle_deg", "model", "seed", "field_dx")
        }
    )
_STRENGTH_COMMON = {
    "start_window": ("window", _NONNEG, "m"),
    # a run in which a snow-covered cell outside the trigger fails under its own slab at
    # t = 0 stops before it starts, unless this is true (2026-11-27)
    "natural_release": ("bool", None, ""),
    # "weakest" (default): the weakest spot (start_window, polygon) or setup.start;
    # "random": a random cell of the start zone, drawn with strength.seed (2026-11-27)
    "trigger": ("str", TRIGGERS, ""),
}
COV_PLAUSIBLE = 0.5  # [-] of the stability ratio: above it a scenario notes the value
# --- the snow cover (2026-11-27; damjax.snow_cover) -----------------------------------
_ANGLE_TO_90 = (lambda v: 0 < v <= 90, "(0, 90]")
_SNOW_KEYS: dict[str, dict[str, tuple[str, Any, str]]] = {
    "uniform": {},  # params.thickness (or the polygon's attribute) everywhere
    # d = reference_thickness x 0.291 / (sin psi - 0.202 cos psi) (Swiss guidelines)
    "slope_corrected": {"reference_thickness": ("float", _POS, "m")},
    # a raster of the vertical snow depth HS [m] in the DEM's CRS: d = HS cos(psi)
    "depth_map": {"file": ("str", None, "")},
}
_SNOW_COMMON = {
    "max_slope_deg": ("float", _ANGLE_TO_90, "deg"),  # no slab steeper (default 60)
    "min_thickness": ("float", _POS, "m"),  # no slab thinner (default 0.1)
    "start_min_slope_deg": ("float", _ANGLE, "deg"),  # start zone's lower edge (28)
    "mask": ("str", None, ""),  # raster or polygons in the DEM's CRS: no snow there
}


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
                kinds_ = " or ".join(f'"{k}"' for k in others)
                more = f' (only for {section}.kind = {kinds_}, not "{kind}")'
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
        if typ == "bool":
            if not isinstance(value, bool):
                problems.append(f"{name} = {_fmt(value)}: must be true or false")
                continue
            out[key] = value
        elif typ == "str":
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


def _place_release(
    terrain: dict[str, Any],
    base_dir: str | Path | None,
    pvals: dict[str, Any],
    pgiven: Any,
    svals: dict[str, Any],
    problems: list[str],
    notes: list[str],
    thickness_from_snow: bool = False,
) -> None:
    """``terrain.release``: the polygon (plus terrain.margin) sets the release area's
    origin, up-slope axis, length and width, and the slab thickness (its attribute)."""
    from damjax import release_area
    from damjax import terrain as dem_io

    # origin, length and width come from the polygon; given ones (a stored scenario read
    # back) must agree with it
    given = {f"terrain.{k}": terrain.pop(k) for k in ("origin",) if k in terrain}
    given.update({f"setup.{k}": svals.pop(k) for k in ("length", "width") if k in svals})
    if "file" not in terrain or problems:
        return
    dem_file = _resolve_path(terrain["file"], base_dir)
    rel_file = _resolve_path(terrain["release"], base_dir)
    terrain["release"] = str(rel_file)
    try:
        dem = dem_io.load_dem(dem_file)
    except (OSError, ValueError, ImportError, KeyError) as exc:
        msg = " ".join(str(exc).split())
        problems.append(f"terrain.file = {_fmt(terrain['file'])}: {msg}")
        return
    # the slab's thickness from the [snow] table (a depth map, or a reference thickness
    # corrected for the slope), not from the polygon's attribute
    thickness_given = "thickness" in pgiven or thickness_from_snow
    field = terrain.get("thickness_field", "thickness")
    if "buffer" in terrain and "margin" in terrain:
        problems.append(
            "terrain.margin: give terrain.buffer (the terrain around the polygon) or "
            "terrain.margin (the rectangle of the polygon plus a margin), not both"
        )
        return
    if "buffer" not in terrain and "margin" not in terrain:
        terrain["buffer"] = BUFFER_DEFAULT
    buffer = terrain.get("buffer")
    try:
        area = release_area.read_release_area(
            rel_file,
            dem,
            dem_file=dem_file,
            margin=float(terrain.get("margin", 10.0)),
            upslope=terrain.pop("upslope", None),  # re-added after origin (key order)
            thickness_field=(
                ""
                if thickness_from_snow or (thickness_given and "thickness_field" not in terrain)
                else field
            ),
            buffer=None if buffer is None else float(buffer),
        )
    except release_area.ReleaseAreaError as exc:
        problems.append(str(exc))
        return
    placed = {
        "terrain.origin": list(area.origin),
        "setup.length": area.length,
        "setup.width": area.width,
    }
    for key, value in given.items():
        if not np.allclose(np.asarray(value, float), placed[key], rtol=1e-9, atol=1e-6):
            problems.append(
                f"{key} = {_fmt(value)}: set by terrain.release (the polygon plus "
                f"terrain.buffer or terrain.margin gives {_fmt(placed[key])}); remove it"
            )
    terrain["origin"] = list(area.origin)
    terrain["upslope"] = area.upslope
    svals["length"] = area.length
    svals["width"] = area.width
    if thickness_from_snow and "thickness_field" in terrain:
        notes.append(
            f"terrain.thickness_field = {_fmt(field)} is not used: the slab's thickness "
            "comes from the [snow] table"
        )
    if area.thickness is not None and not thickness_given:
        pvals["thickness"] = area.thickness
        # the attribute is read as metres: a value in cm is said as a PST's would be
        for p in implausible(PSTParams(thickness=area.thickness), {"thickness"}):
            notes.append(
                f"terrain.release: the polygon's {field} = {area.thickness:g} m: {p.reason}"
            )
    elif area.thickness is not None and abs(pvals["thickness"] - area.thickness) > 1e-9:
        notes.append(
            f"params.thickness = {pvals['thickness']:g} m is used, not the polygon's "
            f"{field} = {area.thickness:g} m"
        )


def check(
    data: dict[str, Any], base_dir: str | Path | None, problems: list[str]
) -> tuple[Any, list[str]]:
    """The Scenario of a ``type = "slope"`` document (None with problems appended), and
    its dubious-value notes. Top-level keys, type and name are checked by the caller."""
    if "profile" in data:
        problems.append('profile: only for type = "pst" scenarios (set params.thickness, ...)')
    known_setup = {f.name for f in dataclasses.fields(SlopeSetup)}
    setup_table = data.get("setup", {})
    if isinstance(setup_table, dict):
        clean = {}
        for key, value in setup_table.items():
            if key in known_setup:
                clean[key] = value
                continue
            if key in {f.name for f in dataclasses.fields(PSTSetup)}:
                more = " (a PST setting: not used by slope scenarios)"
            elif key in {f.name for f in dataclasses.fields(PSTParams)}:
                more = f" (did you mean 'params.{key}'?)"
            else:
                hit = difflib.get_close_matches(key, sorted(known_setup), n=1)
                param = [f.name for f in dataclasses.fields(PSTParams)]
                phit = difflib.get_close_matches(key, param, n=1, cutoff=0.8)
                more = (
                    f" (did you mean 'setup.{hit[0]}'?)"
                    if hit
                    else f" (did you mean 'params.{phit[0]}'?)"
                    if phit
                    else " (not a field of SlopeSetup; see damjax.params)"
                )
            problems.append(f"setup.{key}: unknown key{more}")
        setup_table = clean
    pvals, pbad, pgiven = _check_section("params", data.get("params", {}), PSTParams, problems)
    svals, sbad, _ = _check_section("setup", setup_table, SlopeSetup, problems)
    ovals, _, _ = _check_section("output", data.get("output", {}), Output, problems)
    if not all(isinstance(data.get(t, {}), dict) for t in ("params", "setup", "output")):
        return None, []  # a section that is no table: the rest would check its defaults
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
    snow = None
    if "snow" in data:
        snow = _check_table(
            "snow", data["snow"], _SNOW_KEYS, SNOW_KINDS, "uniform", _SNOW_COMMON, problems
        )
    notes: list[str] = []
    _snow_strength_rules(terrain, strength, snow, base_dir, problems)
    cov = (strength or {}).get("cov")
    if isinstance(cov, (int, float)) and cov > COV_PLAUSIBLE:
        # valid, but a field that wide puts much of the slope at S just above 1
        notes.append(
            f"strength.cov = {_fmt(cov)}: far above the 10-30 % of measured strength maps "
            f"(Kronholm and Schweizer 2003); plausible up to {COV_PLAUSIBLE:g}"
        )
    if terrain is not None and terrain["kind"] == "dem" and "release" in terrain:
        from_snow = snow is not None and (
            snow["kind"] == "depth_map"
            or (snow["kind"] == "slope_corrected" and "reference_thickness" in snow)
        )
        _place_release(terrain, base_dir, pvals, pgiven, svals, problems, notes, from_snow)
    # given away from the default: a file written by `Scenario.to_toml` lists every field
    ignored = [
        k
        for k in PST_ONLY_PARAMS
        if k in pgiven and not same_value(pvals.get(k), getattr(PSTParams(), k))
    ]
    if ignored:
        notes.append(
            ", ".join(f"params.{k}" for k in ignored)
            + ": a PST's, ignored by slope scenarios (their strength: [strength]; their "
            "slope: [terrain])"
        )
    if "start" in svals:
        st = np.asarray(svals["start"], dtype=float)
        if st.shape != (2,):
            problems.append(
                f"setup.start = {_fmt(data['setup']['start'])}: must be [x, y], two finite "
                "numbers [m]"
            )
            del svals["start"]
        else:
            svals["start"] = (float(st[0]), float(st[1]))
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
    scn = Scenario(
        name=data.get("name"),
        params=PSTParams(**pvals),
        setup=SlopeSetup(**svals),
        description=data.get("description", ""),
        output=Output(**ovals),
        type="slope",
        terrain=terrain,
        strength=strength,
        snow=snow,
    )
    given = {**pvals, **svals}
    n0 = len(problems)

    def fields(setup: SlopeSetup) -> Any:
        """The fields on the checked grid, once the tables are (else `_Unread`)."""
        if n0 or terrain is None or strength is None:
            raise _Unread
        _grid_problems(terrain, strength, setup)
        # the natural release is checked on the prepared run (its particles' load ratio)
        return resolve_inputs(dataclasses.replace(scn, setup=setup), natural_release=False)

    try:
        prep = simulation.prepare(scn.params, scn.setup, fields=fields, max_particles=MAX_PARTICLES)
    except _Unread:
        return None, []
    except _FieldProblem as exc:
        problems.append(str(exc))
        return None, []
    except InputError as exc:
        bad = pbad | sbad  # their kind was reported: the checks saw the default
        reported = [p for p in exc.problems if p.field not in bad]
        problems += _lines(reported, given, terrain or {"kind": "plane"}, "start" in svals)
        return None, toml_lines(exc.notes, given)  # a unit mix-up explains the problems
    if problems:
        return None, []
    # a weak layer that fails under its own slab outside the trigger: a natural release
    problem = natural_release_problem(prep.setup, prep.load_ratio, prep.cover, prep.source)
    if problem and not strength.get("natural_release", False):
        problems.append(problem + NATURAL_RELEASE_ADVICE)
        return None, []
    if problem:
        notes.append(f"{problem} (strength.natural_release = true: run as a natural release)")
    object.__setattr__(scn, "_prepared", prep)
    if "start" in svals and "start_window" in strength:
        start = prep.setup.start
        notes.append(
            f"setup.start = {_fmt(list(scn.setup.start))} is not used: strength.start_window "
            f"picks the start, ({start[0]:.4g}, {start[1]:.4g}) m"
        )
    # values outside their plausible ranges, as a PST scenario says them (a unit hint)
    return scn, toml_lines(implausible(scn.params, pgiven), given) + notes


class _Unread(Exception):
    """The terrain and strength are not read: the tables have problems already."""


def _grid_problems(terrain: dict, strength: dict, setup: SlopeSetup) -> None:
    """_FieldProblem for the tables' values that do not fit the (valid) release area: the
    start window, the generic profile's lengths."""
    if "start_window" in strength:
        win = strength["start_window"]
        problem = window_problem(win, setup.length, setup.width)
        if problem:
            raise _FieldProblem(f"strength.start_window = {_fmt(win)}: {problem}")
    if terrain["kind"] == "generic":
        t = {**_GENERIC_DEFAULTS, **terrain}
        # the rule of damjax.terrain.profile_problem, quoting the values as written
        if t["toe_length"] + t["roll_length"] > setup.length:
            raise _FieldProblem(
                f"terrain.toe_length = {_fmt(t['toe_length'])}: toe_length + roll_length = "
                f"{t['toe_length'] + t['roll_length']:g} m must be at most setup.length = "
                f"{setup.length:g} m"
            )


def _lines(
    problems: list[Problem], given: dict[str, Any], terrain: dict, start_given: bool
) -> list[str]:
    """The problems of `damjax.slope.simulation.prepare` worded with the file's keys (the
    slope-angle map as the terrain's, the start with the ways to give it)."""
    out = []
    for p in problems:
        if p.form == "map" and p.field == "slope_deg":
            where = "terrain" if terrain["kind"] != "plane" else "params.slope_deg"
            lo, hi = p.value
            out.append(
                f"{where}: local slope angles from {lo:.3g} to {hi:.3g} deg: must all be in "
                "(0, 90) deg"
            )
            continue
        choices = specs(SlopeSetup).get(p.field or "")
        if choices is not None and choices.kind == "choice" and p.valid:
            valid = "{" + ", ".join(f'"{c}"' for c in choices.valid) + "}"
            value = given.get(p.field, p.value)
            out.append(f"setup.{p.field} = {_fmt(value)}: must be one of {valid}")
            continue
        if p.field == "start" and not start_given:
            p = dataclasses.replace(p, what="(the default: give setup.start)")
        line = toml_lines([p], given)[0]
        if p.field == "start":
            line += ", or give strength.start_window"
        out.append(line)
    return out


def warn_resolution(scn: Any) -> None:
    """UserWarning (as `damjax.pst.prepare` notes for PSTs) when dx > Lambda/5 (at the
    thinnest slab of a snow cover), with how to check it (half the dx, the same random
    field). A weak layer that fails under its own slab is the loader's
    (`natural_release_problem`)."""
    params, where = scn.params, ""
    prep = scn._prepared
    if prep is not None and prep.thickness is not None:  # a snow cover: at its thinnest slab
        h = np.asarray(prep.thickness, dtype=float)
        if prep.cover is not None and h.ndim == 2:
            h = h[np.asarray(prep.cover, bool)]
        if h.size and float(np.min(h)) < params.thickness:
            params = dataclasses.replace(params, thickness=float(np.min(h)))
            where = f" at the thinnest slab, {params.thickness:.3g} m"
    lam = float(theory.elastic_length(params))
    if scn.setup.dx > lam / 5:
        # the shipped slopes run at dx 0.2 m (Lambda/5 = 0.133 m): the guide's "Grid
        # resolution" section gives what halving dx changed for them
        grf = (scn.strength or {}).get("kind") == "grf"
        same = f" and strength.field_dx = {scn.setup.dx:g}, the same field," if grf else ""
        warnings.warn(
            f"dx = {scn.setup.dx} m is larger than Lambda/5 = {lam / 5:.3g} m{where}: the "
            "crack-tip stress concentration is under-resolved; results may depend on dx "
            "(check with "
            f"dx = {scn.setup.dx / 2:g} m{same} as the docs' Slopes page did for the "
            "shipped slopes)",
            stacklevel=3,
        )


def _snow_strength_rules(
    terrain: Any, strength: Any, snow: Any, base_dir: Any, problems: list[str]
) -> None:
    """The rules between [snow], [strength] and [terrain] keys (files resolved)."""
    dem = terrain is not None and terrain["kind"] == "dem"
    if snow is not None:
        for key in ("file", "mask"):
            if key in snow:
                if not dem:
                    what = "a raster or polygons" if key == "mask" else "a raster"
                    problems.append(
                        f'snow.{key}: {what} in the DEM\'s coordinates needs terrain.kind = "dem"'
                    )
                snow[key] = str(_resolve_path(snow[key], base_dir))
        if snow["kind"] == "depth_map" and "file" not in snow:
            problems.append("snow.file: missing (a raster of the vertical snow depth HS [m])")
        lo = snow.get("start_min_slope_deg", snow_cover.START_MIN_SLOPE_DEG)
        hi = snow.get("max_slope_deg", snow_cover.MAX_SLOPE_DEG)
        if isinstance(lo, (int, float)) and isinstance(hi, (int, float)) and lo > hi:
            problems.append(
                f"snow.start_min_slope_deg = {_fmt(lo)}: must be at most snow.max_slope_deg "
                f"= {_fmt(hi)} (the start zone is the snow between them)"
            )
    if terrain is not None and "buffer" in terrain and "release" not in terrain:
        problems.append(
            "terrain.buffer: the terrain around a release polygon; give terrain.release too "
            "(without a polygon the domain is setup.length x setup.width from terrain.origin)"
        )
    if strength is not None:
        if strength["kind"] == "coulomb":
            for key in ("cohesion", "friction_coefficient"):
                if key not in strength:
                    problems.append(f'strength.{key}: missing (strength.kind = "coulomb")')
        if strength.get("trigger") == "random" and "start_window" in strength:
            problems.append(
                'strength.trigger = "random": draws the start in the start zone; give no '
                "strength.start_window"
            )


register("slope", check, warn_resolution, slope_fields.prepare)
