"""Slope scale: the 2D step on a plane strip against the 1D PST, slope scenarios (schema,
validation, `damjax run` / `damjax show`), terrain and strength inputs on the grid.

Runs are small (seconds each): the shipped 50 m slopes are only validated here.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest

from damjax import (
    PSTParams,
    PSTSetup,
    SlopeSetup,
    fields,
    plot,
    scenario,
    simulate_slope,
    terrain,
)
from damjax.cli import main
from damjax.materials import weak_layer
from damjax.pst import simulate_pst
from damjax.scenario import slope_fields
from damjax.slope import results as slope_results
from damjax.slope.generic import (
    FIG12B,
    GenericSlopeCase,
    full_window,
    slope_field,
    strength_field,
    weak_spot,
)

SLOPE_NAMES = ["slope-quick", "slope-generic-50x60", "slope-generic-50x100"]
JSON_KEYS = (
    "upslope_front",
    "crossslope_front",
    "upslope_extent_m",
    "upslope_arrest_distance_m",
    "upslope_crack_speed_over_cs",
    "crossslope_crack_speed_over_cs",
    "release_area_m2",
    "n_particles",
    "n_steps",
    "wall_time_s",
)


def raw(name: str) -> dict:
    with open(scenario.shipped()[name], "rb") as fh:
        return tomllib.load(fh)


def quiet_parse(doc: dict, **kw) -> scenario.Scenario:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return scenario.parse(doc, **kw)


# --------------------------------------------------------------------------- physics


@pytest.mark.min_versions
def test_plane_strip_reproduces_the_1d_pst_arrest():
    """A 12 m x 0.6 m strip on a uniform plane, sawn from its lower edge, arrests where the
    1D PST (free lateral condition) does, with the same critical cut length."""
    p = PSTParams(steady_length=4.0, strength_gradient=2000.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r1 = simulate_pst(
            p, PSTSetup(length=12.0, dx=0.05, duration=0.6, particles_per_cell=1, chunk_steps=200)
        )
    setup = SlopeSetup(
        length=12.0,
        width=0.6,
        dx=0.05,
        duration=0.6,
        start=(0.0, 0.3),
        particles_per_cell=1,
        chunk_steps=200,
    )
    x = (np.arange(240) + 0.5) * 0.05
    tau = np.asarray(weak_layer.strength_profile(x, 1000.0, 4.0, 2000.0))
    r2 = simulate_slope(p, setup, tau_peak=np.repeat(tau[:, None], 12, axis=1))
    assert r1.summary["arrested"] and r2.summary["arrested_before_top"]
    assert r1.summary["crack_front"] == "arrested" and r2.summary["upslope_front"] == "arrested"
    assert r2.summary["upslope_arrest_distance_m"] == r2.summary["upslope_extent_m"]
    l1d = r1.summary["arrest_position_m"]
    assert 4.0 < l1d < 11.0
    assert r2.summary["upslope_arrest_distance_m"] == pytest.approx(l1d, abs=2 * setup.dx)
    assert r2.summary["critical_cut_radius_m"] == pytest.approx(
        r1.summary["critical_cut_length_m"], abs=setup.dx
    )


def test_a_crossslope_arrest_is_summarised_as_one():
    """A plane whose strength rises steeply across from 1.5 m beside the start: the crack
    runs to the top and lower edges and to the near side edge, and stops across on the
    strong side, more than 2 m inside the far edge. Up-slope it reached the edge (no
    arrest distance), across it arrested (the distance is the extent on the band through
    the start)."""
    setup = SlopeSetup(
        length=6.0,
        width=8.0,
        dx=0.1,
        duration=1.0,
        start=(3.0, 1.5),
        particles_per_cell=1,
        chunk_steps=200,
    )
    y = (np.arange(80) + 0.5) * 0.1
    tau = np.repeat((1000.0 + 2000.0 * np.maximum(y - 3.0, 0.0))[None, :], 60, axis=0)
    s = simulate_slope(PSTParams(), setup, tau_peak=tau).summary
    assert s["upslope_front"] == "reached_edge" and s["upslope_arrest_distance_m"] is None
    assert s["crossslope_front"] == "arrested"
    assert s["crossslope_arrest_distance_m"] == s["crossslope_extent_m"]
    # stopped where the strength has risen, short of the far edge (6.5 m away); measured
    # 3.55 m on 2026-11-27
    assert 1.5 < s["crossslope_arrest_distance_m"] < 4.5
    assert s["crossslope_front_end_speed_over_cs"] is None
    assert "cross-slope arrest" in plot.slope_outcome(s)
    assert "up-slope: reached the top edge" in plot.slope_outcome(s)


@pytest.mark.parametrize(
    ("arrivals", "state"),
    [
        # the outline stopped 1 s before the end, 5 m inside the edge
        ({3.0: 0.5, 4.0: 1.0}, "arrested"),
        # it advanced 0.5 m (5 cells) in the last 0.3 s
        ({3.0: 0.5, 4.0: 1.0, 4.5: 1.9}, "moving"),
        # one cell in the last 0.3 s is within a PST's tolerance
        ({3.0: 0.5, 4.0: 1.0, 4.1: 1.95}, "arrested"),
        # within 2 m of the edge
        ({3.0: 0.5, 8.5: 1.0}, "reached_edge"),
    ],
)
def test_front_state_of_an_outline(arrivals, state):
    from damjax.slope.simulation import _front_state

    dist = np.array(list(arrivals), float)
    t = np.array(list(arrivals.values()), float)
    got, speed = _front_state(np.append(dist, 1.0), np.append(t, np.inf), 10.0, 2.0, 0.1)
    assert got == state
    if state == "moving":
        assert speed == pytest.approx(0.5 / 0.3)
    else:
        assert speed is None


def test_outcome_line_says_what_happened():
    moving = {
        "upslope_front": "reached_edge",
        "crossslope_front": "moving",
        "crossslope_extent_m": 37.8,
        "crossslope_front_end_speed_over_cs": 0.0255,
    }
    line = plot.slope_outcome(moving)
    assert "reached the top edge" in line and "still moving at the end at 0.03" in line
    assert "37.8 m" in line
    sawn = {"upslope_front": "sawn_only", "crossslope_front": "sawn_only"}
    assert "never ran ahead of the saw" in plot.slope_outcome(sawn)
    old = {"arrested_before_top": True, "upslope_arrest_distance_m": 41.8}
    assert plot.slope_outcome(old) == "up-slope arrest 41.8 m from the start"


def test_crack_speed_map_has_no_speed_where_cells_failed_together():
    """A front at 50 m/s across a strip whose last metre fails at once: the fit reads a
    speed far above the slab's wave speed there; the map gives none and flags the cells."""
    from types import SimpleNamespace

    from damjax import theory

    params = PSTParams()
    limit = slope_results.front_speed_limit(params)
    assert limit == pytest.approx(float(theory.plane_stress_wave_speed(params)))
    assert limit / float(theory.shear_wave_speed(params)) == pytest.approx(1.69, abs=0.01)
    dx = 0.1
    x = (np.arange(100) + 0.5) * dx
    t = x / 50.0
    t[x > 9.0] = 9.0 / 50.0  # the last metre at once
    result = SimpleNamespace(
        x=x,
        y=(np.arange(20) + 0.5) * dx,
        arrival_time=np.repeat(t[:, None], 20, 1),
        params=params,
    )
    v = slope_results.crack_speed_map(result)
    flags = slope_results.simultaneous_failure_map(result)
    assert np.nanmax(v) <= limit
    inner = x < 8.0
    np.testing.assert_allclose(v[inner], 50.0, rtol=1e-6)
    assert flags[x > 9.5].all() and not flags[inner].any()
    assert np.isnan(v[flags]).all()
    # no cell has both a speed and the flag, and every failed cell with a fit has one
    assert not (np.isfinite(v) & flags).any()


# --------------------------------------------------------------------------- scenarios


@pytest.mark.parametrize("name", SLOPE_NAMES)
def test_shipped_slope_scenarios_validate_and_round_trip(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # dx > Lambda/5 (as for PSTs)
        warnings.simplefilter("error", scenario.ScenarioWarning)
        scn = scenario.load(name)
    assert scn.type == "slope" and scn.name == name
    text = scn.to_toml()
    again = scenario.loads(text, warn=False)
    assert again == scn and again.to_toml() == text


def test_shipped_fig12a_scenario_is_the_papers_case():
    scn = scenario.load("slope-generic-50x60", warn=False)
    p, s = scn.params, scn.setup
    assert (p.youngs_modulus, p.tensile_strength, p.softening) == (4.0e6, 4000.0, 1.0)
    # the paper's "50 m (down-slope) by 60 m (cross-slope)"
    assert (s.length, s.width, s.dx, s.duration) == (50.0, 60.0, 0.2, 4.0)
    assert scn.terrain["kind"] == "generic"
    assert scn.strength["kind"] == "grf" and scn.strength["trend"] == 20.0
    slope, fall, tau, start = slope_fields.resolve_fields(scn)
    assert slope.shape == tau.shape == (250, 300) and fall == 0.0
    assert slope.max() == pytest.approx(35.0, abs=1e-3) and 29.9 < slope[0, 0] < 30.1
    assert slope[-1, 0] < 21.0  # the convex roll
    # 1 kPa up to x = 2 m (the bottom of the start window, as a PST's L_ss), then +20 Pa/m
    x = (np.arange(250) + 0.5) * 0.2
    above = x > 4.0
    trend = np.polyfit(x[above], tau.mean(axis=1)[above], 1)[0]
    assert trend == pytest.approx(20.0, abs=5.0)
    assert 2.0 <= start[0] <= 8.0 and 15.0 <= start[1] <= 45.0
    # the TOML and the Python case describe the same field and start
    case = GenericSlopeCase()
    assert np.allclose(strength_field(case), tau, atol=1e-3)
    assert weak_spot(case, tau) == pytest.approx(start)
    assert np.allclose(slope_field(case), slope, atol=1e-4)
    # Fig. 13b: 50 m down-slope, 100 m across, strength rising across from y = 100 m, the
    # start near the top right corner; the TOML and FIG12B agree
    wide = scenario.load("slope-generic-50x100", warn=False)
    assert (wide.setup.length, wide.setup.width) == (50.0, 100.0)
    _, _, tau_b, start_b = slope_fields.resolve_fields(wide)
    y = (np.arange(500) + 0.5) * 0.2
    across = np.polyfit(y[y < 96.0], tau_b.mean(axis=0)[y < 96.0], 1)[0]
    assert across == pytest.approx(-20.0, abs=5.0)
    along = np.polyfit(x, tau_b.mean(axis=1), 1)[0]
    assert abs(along) < 5.0
    assert 34.0 <= start_b[0] <= 40.0 and 92.0 <= start_b[1] <= 98.0
    assert np.allclose(strength_field(FIG12B), tau_b, atol=1e-3)
    assert weak_spot(FIG12B, tau_b) == pytest.approx(start_b)


def test_the_weakest_spot_skips_cells_without_snow():
    """Cells of infinite strength (no snow) in a start window: the box sums turned their
    neighbourhood into NaN and the start became the window's first cell, or a cell
    without snow; now the weakest snow-covered spot, and a window without snow is one
    line."""
    case = GenericSlopeCase(length=10.0, width=6.0, dx=0.5, start_window=(0.0, 10.0), planar=True)
    x = (np.arange(20) + 0.5) * 0.5
    y = (np.arange(12) + 0.5) * 0.5
    tau = 1000.0 + 10.0 * (x[:, None] - 7.0) ** 2 + 5.0 * (y[None, :] - 3.0) ** 2
    tau[:4, :] = np.inf  # no snow on the lowest 2 m
    tau[10:12, 4:8] = np.inf  # a rock
    sx, sy = weak_spot(case, tau)
    assert np.isfinite(tau[int(sx / 0.5), int(sy / 0.5)])
    assert abs(sx - 7.0) <= 1.0 and abs(sy - 3.0) <= 1.0  # the minimum, not the first cell
    # all finite: the plain box mean (2 m boxes: k = 2 cells each side, edges repeated)
    finite = np.where(np.isfinite(tau), tau, 900.0 + x[:, None] + y[None, :])
    smooth = fields.box_sum(finite, 2, mode="edge") / 25.0
    x_lo, x_hi, y_lo, y_hi = full_window(case.start_window, case.width)
    sel = (x[:, None] >= x_lo) & (x[:, None] <= x_hi) & (y >= y_lo) & (y <= y_hi)
    i, j = np.unravel_index(np.argmin(np.where(sel, smooth, np.inf)), smooth.shape)
    assert weak_spot(case, finite) == (x[i], y[j])
    tau[:, :] = np.inf
    with pytest.raises(ValueError, match="every cell in it has an infinite strength"):
        weak_spot(case, tau)


@pytest.mark.min_versions
def test_slope_quick_runs_through_the_cli(tmp_path, capsys):
    out = tmp_path / "q"
    assert main(["run", "slope-quick", "--out", str(out), "--json", "--quiet"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    # the release fills the drawn rectangle: the warning names what grows it (the area's
    # length and width; a buffer only exists around a release polygon on a DEM)
    assert summary["domain_edge_fraction"] == pytest.approx(1.0)
    assert "enlarge the area (setup.length, setup.width)" in captured.err
    assert "terrain.buffer" not in captured.err
    for key in JSON_KEYS:
        assert key in summary, key
    assert summary["n_particles"] == 120 * 60 and summary["n_steps"] > 0
    assert summary["fault"] is None
    assert summary["release_area_m2"] > 10.0 and summary["upslope_extent_m"] > 2.0
    # the whole 12 m x 6 m area releases: the fronts reached the edges, nothing arrested,
    # and no arrest distance or position is reported
    assert summary["release_area_m2"] == pytest.approx(72.0, rel=1e-6)
    assert summary["upslope_front"] == "reached_edge"
    assert summary["crossslope_front"] == "reached_edge"
    assert summary["arrested_before_top"] is False
    for key in (
        "upslope_arrest_distance_m",
        "upslope_arrest_position_m",
        "crossslope_arrest_distance_m",
        "upslope_front_end_speed_over_cs",
        "crossslope_front_end_speed_over_cs",
    ):
        assert summary[key] is None, key
    for name in ("results.nc", "summary.json", "slope.png", "release.gif"):
        assert (out / name).is_file(), name
    from damjax import io

    ds = io.open_dataset(out / "results.nc")
    for name in ("height", "arrival_time", "crack_speed", "tau_peak", "slope_angle"):
        assert "units" in ds[name].attrs and "long_name" in ds[name].attrs
    assert np.all(np.isfinite(ds["height"].values))
    assert 'type = "slope"' in ds.attrs["scenario"] and ds.attrs["damjax_version"]
    assert ds["slope_angle"].values == pytest.approx(35.0, abs=1e-3)
    assert ds["released"].values.sum() * 0.01 == pytest.approx(summary["release_area_m2"])
    (out / "slope.png").unlink()
    assert main(["show", str(out), "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["release_area_m2"] == summary["release_area_m2"]
    assert (out / "slope.png").is_file()
    from damjax import runner

    scn, result = runner.load_result(out)  # a slope folder gives its slope result
    assert scn.name == "slope-quick" and type(result).__name__ == "SlopeResult"
    assert result.summary["release_area_m2"] == summary["release_area_m2"]


BAD = [
    ({"setup": {"width": -1.0}}, "setup.width = -1.0: must be in (0, inf) m"),
    ({"setup": {"start": [1.0, 2.0, 3.0]}}, "setup.start"),
    ({"setup": {"start": [30.0, 3.0]}}, "setup.start = [30.0, 3.0]: must lie in"),
    ({"setup": {"controlled": True}}, "setup.controlled: unknown key"),
    ({"setup": {"dx": 0.5}}, "setup.dx = 0.5: must be at most Lambda/2"),
    ({"setup": {"particles_per_cell": 1.5}}, "setup.particles_per_cell = 1.5"),
    ({"params": {"poisson": 0.7}}, "params.poisson = 0.7: must be in (0, 0.5)"),
    ({"terrain": {"kind": "moon"}}, 'terrain.kind = "moon": must be one of'),
    ({"terrain": {"kind": "plane", "slope_deg": 95.0}}, "terrain.slope_deg = 95.0"),
    ({"terrain": {"kind": "plane", "max_slope_deg": 30.0}}, "terrain.max_slope_deg: unknown"),
    ({"terrain": {"kind": "generic", "toe_length": 10.0}}, "terrain.toe_length = 10.0"),
    ({"terrain": {"kind": "dem"}}, "terrain.file: missing"),
    ({"terrain": {"kind": "dem", "file": "nowhere.asc"}}, "terrain.file = "),
    ({"terrain": {"kind": "dem", "file": "x.asc", "upslope": "up"}}, "terrain.upslope"),
    ({"strength": {"kind": "grf", "std": -5.0}}, "strength.std = -5.0"),
    ({"strength": {"kind": "grf", "model": "cubic"}}, 'strength.model = "cubic"'),
    ({"strength": {"kind": "grf", "seed": 1.5}}, "strength.seed = 1.5"),
    ({"strength": {"kind": "grf", "length_scale": [1.0, 2.0, 3.0]}}, "strength.length_scale"),
    ({"strength": {"kind": "constant", "tau_peak": math.nan}}, "strength.tau_peak = nan"),
    ({"strength": {"kind": "constant", "seed": 3}}, "strength.seed: unknown key"),
    ({"strength": {"kind": "map", "file": "nowhere.csv"}}, "strength.file = "),
    ({"strength": {"start_window": [8.0, 30.0]}}, "strength.start_window = [8.0, 30.0]"),
    ({"strength": 3}, "strength = 3: must be a table"),
]


@pytest.mark.parametrize(("change", "expected"), BAD)
def test_bad_slope_scenarios_give_one_line_errors(change, expected, tmp_path):
    doc = raw("slope-quick")
    for sec, table in change.items():
        if isinstance(table, dict) and isinstance(doc.get(sec), dict) and "kind" not in table:
            doc[sec] = {**doc[sec], **table}
        else:
            doc[sec] = table
    with pytest.raises(ValueError) as exc:
        quiet_parse(doc, base_dir=tmp_path)
    lines = str(exc.value).splitlines()
    assert any(expected in line for line in lines), lines
    assert "Traceback" not in str(exc.value)
    assert lines == scenario.problems(doc) or any("file" in line for line in lines)


def test_bad_slope_scenario_exits_2_on_the_cli(tmp_path, capsys):
    doc = raw("slope-quick")
    doc["setup"]["width"] = 0.0
    doc["terrain"]["slpoe_deg"] = 30.0
    path = tmp_path / "bad.toml"
    path.write_text(scenario.dumps(doc))
    assert main(["run", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(e.startswith("damjax: error: bad.toml: ") for e in err)
    assert "setup.width = 0.0" in err[1] or "setup.width = 0.0" in err[0]
    assert any("did you mean 'terrain.slope_deg'" in e for e in err)
    assert not (tmp_path / "o").exists()


def test_every_slope_key_rejects_a_wrong_type():
    """Retype every key of the shipped slope scenarios: each gives a clean error naming it."""
    for name in ("slope-quick", "slope-generic-50x60"):
        base = raw(name)
        for sec in ("params", "setup", "terrain", "strength", "output"):
            for key in list(base.get(sec, {})):
                doc = copy.deepcopy(base)
                doc[sec][key] = {"a": 1}
                with pytest.raises(ValueError) as exc:
                    quiet_parse(doc)
                assert f"{sec}.{key}" in str(exc.value), (name, sec, key, str(exc.value))


def test_terrain_only_for_slopes():
    doc = raw("quick")
    doc["terrain"] = {"kind": "plane"}
    with pytest.raises(ValueError, match='terrain: only for type = "slope"'):
        quiet_parse(doc)


# --------------------------------------------------------------------------- inputs


def _plane_dem(path: Path, gx: float, gy: float) -> Path:
    x = np.arange(0.0, 40.01, 1.0)
    y = np.arange(0.0, 30.01, 1.0)
    xx, yy = np.meshgrid(x, y, indexing="ij")
    terrain.save_esri_ascii(terrain.Terrain(x, y, 100.0 + gx * xx + gy * yy), path)
    return path


@pytest.mark.parametrize(
    ("gx", "gy", "upslope", "fall"),
    [
        (math.tan(math.radians(30.0)), 0.0, "+x", 0.0),
        (0.0, -math.tan(math.radians(30.0)), "-y", 0.0),
        (-math.tan(math.radians(30.0)), 0.0, "-x", 0.0),
    ],
)
def test_tilted_plane_dem_gives_its_slope_angle(tmp_path, gx, gy, upslope, fall):
    _plane_dem(tmp_path / "plane.asc", gx, gy)
    origin = {"+x": [1.0, 2.0], "-y": [30.0, 29.0], "-x": [39.0, 28.0]}[upslope]
    doc = raw("slope-quick")
    doc["terrain"] = {"kind": "dem", "file": "plane.asc", "origin": origin, "upslope": upslope}
    scn = quiet_parse(doc, base_dir=tmp_path)
    assert Path(scn.terrain["file"]).is_absolute()
    slope, fall_deg, tau, _ = slope_fields.resolve_fields(scn)
    assert slope.shape == (120, 60)
    assert slope == pytest.approx(30.0, abs=1e-3)  # the .asc file keeps 6 decimals
    assert np.asarray(fall_deg) == pytest.approx(fall, abs=1e-3)


def test_an_upslope_axis_across_the_fall_line_is_warned(tmp_path):
    _plane_dem(tmp_path / "plane.asc", 0.0, math.tan(math.radians(30.0)))  # rises along +y
    doc = raw("slope-quick")
    doc["terrain"] = {"kind": "dem", "file": "plane.asc", "origin": [1.0, 2.0], "upslope": "+x"}
    scn = quiet_parse(doc, base_dir=tmp_path)
    with pytest.warns(
        UserWarning, match=r'terrain.upslope = "\+x": the mean fall line is -?90 deg'
    ):
        slope_fields.resolve_fields(scn)


def test_dem_cross_tilt_sets_the_fall_direction():
    x = np.arange(0.0, 40.01, 1.0)
    y = np.arange(0.0, 30.01, 1.0)
    xx, yy = np.meshgrid(x, y, indexing="ij")
    ter = terrain.Terrain(x, y, 0.6 * xx + 0.2 * yy)
    xs, ys = slope_fields.cell_centres(SlopeSetup(length=10.0, width=8.0, dx=0.5))
    slope, fall = slope_fields.dem_fields(ter, xs, ys, (2.0, 2.0), "+x")
    assert slope == pytest.approx(math.degrees(math.atan(math.hypot(0.6, 0.2))), abs=1e-6)
    assert fall == pytest.approx(math.degrees(math.atan2(0.2, 0.6)), abs=1e-6)


def test_dem_smaller_than_the_release_area_is_an_error(tmp_path):
    _plane_dem(tmp_path / "plane.asc", 0.5, 0.0)
    doc = raw("slope-quick")
    doc["terrain"] = {"kind": "dem", "file": "plane.asc", "origin": [35.0, 0.0]}
    with pytest.raises(ValueError, match=r"^terrain.file = .*leaves the terrain"):
        quiet_parse(doc, base_dir=tmp_path)


def test_generic_terrain_and_strength_map_on_the_grid():
    doc = raw("slope-quick")
    # the shipped map spans 48 m x 58 m (nodes every 2 m): the area must lie inside it
    doc["setup"].update(length=48.0, width=6.0, dx=0.25)
    doc["terrain"] = {"kind": "generic"}
    data = Path(scenario.library_dir()).parent.parent / "data" / "synthetic_strength_map.csv"
    doc["strength"] = {"kind": "map", "file": str(data)}
    scn = quiet_parse(doc)
    slope, _, tau, _ = slope_fields.resolve_fields(scn)
    x, _ = slope_fields.cell_centres(scn.setup)
    psi = terrain.generic_slope_angle(x, length=48.0)
    assert slope[:, 0] == pytest.approx(np.asarray(psi), abs=1e-4)
    assert np.all(np.isfinite(tau)) and 500.0 < tau.mean() < 2500.0


def test_a_netcdf_strength_map_with_several_variables_names_one(tmp_path):
    import xarray as xr

    x, y = np.arange(0.0, 13.0, 1.0), np.arange(0.0, 9.0, 1.0)
    tau = 1000.0 + 50.0 * x[None, :] + 0.0 * y[:, None]
    xr.Dataset(
        {"tau_peak": (("y", "x"), tau), "other": (("y", "x"), -tau)}, coords={"x": x, "y": y}
    ).to_netcdf(tmp_path / "map.nc")
    doc = raw("slope-quick")
    doc["setup"].update(length=12.0, width=8.0, dx=0.25)
    doc["terrain"] = {"kind": "plane"}
    doc["strength"] = {"kind": "map", "file": "map.nc"}
    with pytest.raises(ValueError, match="name the variable .*strength.variable in a scenario"):
        slope_fields.resolve_fields(quiet_parse(doc, base_dir=tmp_path))
    doc["strength"]["variable"] = "tau_peak"
    _, _, got, _ = slope_fields.resolve_fields(quiet_parse(doc, base_dir=tmp_path))
    xc, _ = slope_fields.cell_centres(quiet_parse(doc, base_dir=tmp_path).setup)
    np.testing.assert_allclose(got[:, 0], 1000.0 + 50.0 * xc, rtol=1e-6)


# --------------------------------------------------------------------------- 1D psi(x)


def _roll_params(top_deg: float, **kw) -> PSTParams:
    xs = np.linspace(0.0, 40.0, 81)
    prof = terrain.pst_slope_angle(
        xs, slope_deg=35.0, roll_start=12.0, roll_length=8.0, top_slope_deg=top_deg
    )
    return PSTParams(strength_gradient=0.0, steady_length=5.0, slope_profile=np.asarray(prof), **kw)


def test_pst_on_a_convex_roll_arrests_where_the_plane_does_not():
    """Terrain-driven arrest: uniform strength (1 kPa everywhere), the Fig. 13 slab
    (sigma_t = 4 kPa, delta = 1); on a 35 deg plane the crack runs through 40 m, on a
    convex roll from 35 to 20 deg (x = 12-20 m) it arrests after one slab fracture
    (measured 23.8 m). The paper's perfectly plastic slab: the brittle crack-band slab
    stops the crack on the plane too."""
    setup = PSTSetup(
        length=40.0,
        dx=0.05,
        duration=1.0,
        particles_per_cell=1,
        chunk_steps=250,
        slab_fracture="paper",
    )
    slab = dict(tensile_strength=4000.0, softening=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        roll = simulate_pst(_roll_params(20.0, **slab), setup)
        plane = simulate_pst(_roll_params(35.0, **slab), setup)
    assert roll.summary["arrested"] and 20.0 < roll.summary["arrest_position_m"] < 30.0
    assert not plane.summary["arrested"]
    assert roll.summary["arrest_position_smooth_m"] < plane.summary["arrest_position_smooth_m"]


def test_constant_slope_profile_equals_the_scalar_slope():
    setup = PSTSetup(length=8.0, dx=0.05, duration=0.2, particles_per_cell=1, chunk_steps=100)
    base = PSTParams(steady_length=2.0, strength_gradient=1500.0, slope_deg=38.0)
    prof = PSTParams(
        steady_length=2.0, strength_gradient=1500.0, slope_deg=20.0, slope_profile=[38.0, 38.0]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, b = simulate_pst(base, setup), simulate_pst(prof, setup)
    # the same maths by two compiled programs (equal on XLA:CPU), which a GPU may round
    # differently (fusion, FMA contraction): float32 round-off carried over the 1100 steps.
    # Measured 2026-11-26 (CPU): a 1-ulp change of the slope angle moves sigma_xx by at most
    # 2.7e-6 max|sigma_xx| and no tip sample; allowed: 4x that, and one particle spacing
    # for a tip sample (a failure moved by one step)
    np.testing.assert_allclose(a.tip, b.tip, rtol=0, atol=setup.dx / setup.particles_per_cell)
    scale = float(np.max(np.abs(a.sigma_xx)))
    np.testing.assert_allclose(a.sigma_xx, b.sigma_xx, rtol=0, atol=1e-5 * scale)


def test_slope_profile_is_validated_and_differentiable():
    import jax

    from damjax.pst import arrest_position_smooth, make_layout
    from damjax.validation import param_problems

    for bad in ([35.0], [35.0, 95.0], [35.0, math.nan]):
        lines = [str(p) for p in param_problems(PSTParams(slope_profile=bad))]
        assert len(lines) == 1 and lines[0].startswith("slope_profile"), lines
    doc = raw("quick")
    doc["params"]["slope_profile"] = [35.0, 0.0]
    with pytest.raises(ValueError, match=r"^params.slope_profile = 0.0: must be in \(0, 90\)"):
        quiet_parse(doc)
    setup = PSTSetup(length=6.0, dx=0.05, duration=0.15, particles_per_cell=1, chunk_steps=50)
    p = PSTParams(steady_length=2.0, strength_gradient=1500.0, slope_profile=np.full(7, 35.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        layout = make_layout(p, setup)
        g = jax.grad(lambda q: arrest_position_smooth(q, setup, layout))(p)
    assert g.slope_profile.shape == (7,) and np.all(np.isfinite(g.slope_profile))
    assert np.any(g.slope_profile != 0.0)


def test_slope_run_interrupted_and_resumed_is_identical(tmp_path):
    """Checkpoint every chunk, stop after chunk 5 (of 11), resume: the same results.nc
    (`Dataset.identical`) and a bitwise-equal final state as an uninterrupted run."""
    from damjax import io, runner

    scn = scenario.load("slope-quick", warn=False).replace(
        setup={"duration": 0.4}, output={"plot": False}
    )
    full = runner.run(scn, tmp_path / "full")

    def stop(c: int) -> None:
        if c == 4:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        runner.run(scn, tmp_path / "cut", checkpoint_every=0.0, on_chunk=stop)
    assert (tmp_path / "cut" / runner.CHECKPOINT).is_file()
    assert not (tmp_path / "cut" / runner.RESULTS).exists()
    resumed = runner.resume(tmp_path / "cut")
    assert resumed.resumed_from_chunk == 5
    assert not (tmp_path / "cut" / runner.CHECKPOINT).exists()
    a = io.open_dataset(tmp_path / "full" / runner.RESULTS)
    b = io.open_dataset(tmp_path / "cut" / runner.RESULTS)
    assert a.identical(b)
    sa = io.read_npz(tmp_path / "full" / runner.FINAL_STATE)
    sb = io.read_npz(tmp_path / "cut" / runner.FINAL_STATE)
    assert sa.keys() == sb.keys()
    for k in sa:
        assert np.array_equal(sa[k], sb[k], equal_nan=True), k
    assert full.summary["n_steps"] == resumed.summary["n_steps"]
    state = runner.load_final_state(tmp_path / "cut")
    assert np.array_equal(np.asarray(state.t_broken), sb["state.t_broken"], equal_nan=True)


def test_random_invalid_slope_mutations_give_clean_errors(tmp_path, capsys):
    """100 slope scenarios each broken once (a key renamed, retyped, set out of range, or
    an unknown key added): every one a clean one-line-per-problem error naming the key,
    also through the CLI (exit 2)."""
    import random
    import re

    line_re = re.compile(r"^[A-Za-z_][\w.-]*( = .+)?: \S.*$")
    wrong = ["12", True, {"a": 1}, ["a", 1]]
    out_of_range = {
        "length": -1.0,
        "width": 0.0,
        "dx": -0.1,
        "duration": 0.0,
        "cfl": 1.5,
        "particles_per_cell": 0,
        "chunk_steps": 0,
        "poisson": 0.6,
        "density": -5.0,
        "slope_deg": 95.0,
        "std": -1.0,
        "length_scale": 0.0,
        "mean": -3.0,
        "tau_peak": 0.0,
    }
    rng = random.Random(5)
    for i in range(100):
        doc = raw(["slope-quick", "slope-generic-50x60"][i % 2])
        paths = [(s, k) for s in ("params", "setup", "terrain", "strength") for k in doc[s]]
        sec, key = paths[rng.randrange(len(paths))]
        op = rng.choice(["rename", "retype", "range", "add"])
        if op == "range" and key not in out_of_range:
            op = "retype"
        if op == "rename":
            doc[sec][key + "x"] = doc[sec].pop(key)
            named = f"{sec}.{key}x"
        elif op == "retype":
            doc[sec][key] = rng.choice(wrong if key != "kind" else [3, "nope"])
            named = f"{sec}.{key}"
        elif op == "range":
            doc[sec][key] = out_of_range[key]
            named = f"{sec}.{key}"
        else:
            doc[sec]["unknown_" + key] = 1.0
            named = f"{sec}.unknown_{key}"
        with pytest.raises(ValueError) as exc:
            quiet_parse(doc)
        lines = str(exc.value).splitlines()
        assert lines and all(line_re.match(x) for x in lines), lines
        if key != "kind" or op != "retype":  # a bad kind makes the table's keys moot
            assert named in str(exc.value), (named, lines)
        if i % 10 == 0:
            path = tmp_path / f"s{i}.toml"
            path.write_text(scenario.dumps(doc))
            assert main(["run", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
            err = capsys.readouterr().err
            assert "Traceback" not in err and len(err.strip().splitlines()) == len(lines)
    assert not (tmp_path / "o").exists()


def test_front_speed_peak_and_mean():
    """Peak = the fastest 4 m stretch of the front; mean = the fit over the whole range."""
    from damjax.slope.simulation import _front_speed

    # front at 40 m/s up to 10 m, 120 m/s from 10 to 22 m, 20 m/s beyond (arrest)
    c = np.arange(0.05, 30.0, 0.1)
    t = np.where(c < 10, c / 40, 0.25 + (c - 10) / 120)
    t = np.where(c > 22, 0.35 + (c - 22) / 20, t)
    mean, peak = _front_speed(c, t, 0.0, 30.0)
    assert peak == pytest.approx(120.0, rel=0.02)
    assert 20.0 < mean < 80.0
    # late failures behind the front do not count: only the earliest per 0.5 m bin
    mean2, peak2 = _front_speed(np.r_[c, c[::7]], np.r_[t, t[::7] + 1.0], 0.0, 30.0)
    assert (mean2, peak2) == pytest.approx((mean, peak))
    assert all(math.isnan(v) for v in _front_speed(c[:3], t[:3], 0.0, 30.0))


def test_grf_strength_plateau_below_mean_at():
    """strength.mean_at: the expected strength is `mean` below it and rises `trend` above."""
    doc = raw("slope-generic-50x60")
    doc["setup"].update(length=30.0, width=10.0, dx=0.25, start=[5.0, 5.0])
    doc["strength"].update(std=0.0, mean_at=8.0, trend=50.0)
    del doc["strength"]["start_window"]
    scn = quiet_parse(doc)
    _, _, tau, _ = slope_fields.resolve_fields(scn)
    x = (np.arange(120) + 0.5) * 0.25
    assert tau[:, 0] == pytest.approx(1000.0 + 50.0 * np.maximum(x - 8.0, 0.0))
    doc["strength"]["mean_at"] = "low"
    with pytest.raises(ValueError, match="strength.mean_at"):
        quiet_parse(doc)


def test_generic_slope_field_dx_gives_the_same_field_on_every_grid():
    """field_dx fixes the GRF's grid: the same seed is the same field at dx 0.25 and 0.125."""
    from damjax.slope.generic import cell_centres

    base = GenericSlopeCase(length=20.0, width=10.0, dx=0.25, trend=0.0, grf_length=4.0)
    plain = strength_field(base)
    # on its own grid, field_dx = dx is the plain field (interpolation at the nodes)
    assert strength_field(dataclasses.replace(base, field_dx=0.25)) == pytest.approx(plain)
    # dx = 0.25 / 3: every third fine centre is a coarse centre, where the interpolated
    # field must equal the coarse one
    fine = strength_field(dataclasses.replace(base, dx=0.25 / 3, field_dx=0.25))
    assert fine.shape == (240, 120)
    assert fine[1::3, 1::3] == pytest.approx(plain, rel=1e-6)
    # without field_dx the finer grid draws a different sample
    other = strength_field(dataclasses.replace(base, dx=0.25 / 3))
    assert np.corrcoef(other[1::3, 1::3].ravel(), plain.ravel())[0, 1] < 0.9
    x, _ = cell_centres(base)
    assert x.size == 80
    with pytest.raises(ValueError, match="field_dx"):
        strength_field(dataclasses.replace(base, field_dx=3.0))


def test_scenario_grf_field_dx_fixes_the_sample_across_grids():
    """[strength] field_dx in a slope scenario: the same seed, the same field on any dx."""
    doc = raw("slope-generic-50x60")
    doc["setup"].update(length=30.0, width=10.0, dx=0.25, start=[5.0, 5.0])
    doc["strength"].update(length_scale=4.0, field_dx=0.25, trend=0.0)
    del doc["strength"]["start_window"]
    _, _, coarse, _ = slope_fields.resolve_fields(quiet_parse(doc))
    doc["setup"]["dx"] = 0.25 / 3
    _, _, fine, _ = slope_fields.resolve_fields(quiet_parse(doc))
    assert fine[1::3, 1::3] == pytest.approx(coarse, rel=1e-6)
    doc["strength"]["field_dx"] = 3.0
    with pytest.raises(ValueError, match="strength.field_dx = 3.0: must be at most half"):
        slope_fields.resolve_fields(quiet_parse(doc))
    doc["strength"]["field_dx"] = -1.0
    with pytest.raises(ValueError, match="strength.field_dx"):
        quiet_parse(doc)


def test_strength_map_must_cover_the_release_area_and_start_window_cells(tmp_path):
    """A map that misses part of the area used to be extended from its edges without a
    word; a start window between cell centres started the crack in the corner."""
    doc = raw("slope-quick")  # 12 m x 6 m at dx 0.1 m
    small = tmp_path / "small.csv"
    small.write_text(
        "x_m,y_m,tau_peak_pa\n"
        + "\n".join(f"{x},{y},{1000 + 10 * x}" for x in range(5) for y in range(5))
    )
    doc["strength"] = {"kind": "map", "file": str(small)}
    with pytest.raises(ValueError, match=r"^strength.file = .*the map spans x in \[0, 4\] m"):
        quiet_parse(doc)
    big = tmp_path / "big.csv"
    big.write_text(
        "x_m,y_m,tau_peak_pa\n"
        + "\n".join(f"{x},{y},{1000 + 10 * x}" for x in range(13) for y in range(7))
    )
    doc["strength"] = {"kind": "map", "file": str(big)}
    slope_fields.resolve_fields(quiet_parse(doc))  # covers: fine
    doc["strength"] = {"kind": "map", "file": str(big), "origin": [100.0, 100.0]}
    with pytest.raises(ValueError, match="check strength.origin"):
        quiet_parse(doc)
    doc["strength"] = {"kind": "constant", "tau_peak": 1000.0, "start_window": [3.01, 3.02]}
    with pytest.raises(ValueError, match=r"^strength.start_window = \[3.01, 3.02\]: no cell"):
        quiet_parse(doc)


def test_dem_whose_upslope_axis_goes_downhill_is_an_error(tmp_path):
    """A DEM falling along the declared up-slope axis ran as if it rose (fall 180 deg)."""
    _plane_dem(tmp_path / "plane.asc", -math.tan(math.radians(30.0)), 0.0)
    doc = raw("slope-quick")
    doc["terrain"] = {"kind": "dem", "file": "plane.asc", "origin": [1.0, 2.0], "upslope": "+x"}
    with pytest.raises(
        ValueError, match=r'^terrain.upslope = "\+x": the terrain descends along this'
    ):
        quiet_parse(doc, base_dir=tmp_path)


def test_start_window_with_a_y_range_and_its_errors():
    """[strength] start_window takes [x_min, x_max] or [x_min, x_max, y_min, y_max]."""
    doc = raw("slope-quick")
    doc["setup"].update(length=20.0, width=12.0, dx=0.25)
    # softening 1 (the paper's slopes): a brittle layer on 0.25 m particles fails under its
    # own slab below 1.23 tau_g (`uniform_failure_stress`), which this field reaches
    doc["params"]["softening"] = 1.0
    doc["strength"] = {
        "kind": "grf",
        "std": 100.0,
        "length_scale": 3.0,
        "seed": 1,
        "start_window": [3.0, 6.0, 8.0, 11.0],
    }
    _, _, tau, start = slope_fields.resolve_fields(quiet_parse(doc))
    assert 3.0 <= start[0] <= 6.0 and 8.0 <= start[1] <= 11.0
    # the weakest 2 m box-smoothed spot of the window, not of the middle half of the width
    two = copy.deepcopy(doc)
    two["strength"]["start_window"] = [3.0, 6.0]
    assert start != pytest.approx(slope_fields.resolve_fields(quiet_parse(two))[3])
    for bad, needle in (
        ([3.0, 6.0, 8.0], "start_window = \\[3.0, 6.0, 8.0\\]: must be \\[x_min, x_max\\] or"),
        ([3.0, 6.0, 11.0, 8.0], "0 <= y_min < y_max <= width = 12 m"),
        ([3.0, 6.0, 8.0, 13.0], "0 <= y_min < y_max <= width = 12 m"),
        ([6.0, 3.0], "0 <= x_min < x_max <= length = 20 m"),
    ):
        doc["strength"]["start_window"] = bad
        with pytest.raises(ValueError, match=needle):
            quiet_parse(doc)
    with pytest.raises(ValueError, match="y_min < y_max"):
        GenericSlopeCase(start_window=(2.0, 8.0, 30.0, 10.0))


@pytest.mark.parametrize(
    "kw, needle",
    [
        (dict(trend_deg=math.nan), "trend_deg = nan: must be a finite number"),
        (dict(trend_deg="45"), "trend_deg = '45': must be a finite number"),
        (dict(start_window=("2", "6")), "of finite numbers"),
        (dict(start_window=((2, 6), (7, 11))), "of finite numbers"),
        (dict(length=19.0), "must be at most length = 19 m"),
        (dict(roll_length=-1.0), "roll_length = -1.0: must be in \\(0, inf\\) m"),
        # the area before the window that is checked against it
        (dict(length=-5.0), "length = -5.0: must be a number in \\(0, inf\\) m"),
        (dict(seed=-1), "seed = -1: must be an integer >= 0"),
    ],
)
def test_generic_slope_case_checks_its_fields_when_built(kw, needle):
    with pytest.raises(ValueError, match=needle):
        GenericSlopeCase(**kw)
    # a toe running straight into the roll is a valid profile (no planar part)
    assert GenericSlopeCase(length=20.0, start_window=(2.0, 8.0)).length == 20.0


def test_slope_acceptance_flags_are_checked_before_any_run(capsys):
    from verification import slope_acceptance

    for argv, needle in (
        (["--roll-length", "45"], "--toe-length = 10 m + --roll-length = 45 m: must be at most"),
        (["--start-window", "6", "2"], "--start-window = (6.0, 2.0): must have"),
        (["--start-window", "2", "6", "7"], "--start-window = (2.0, 6.0, 7.0): must be"),
        (["--dx", "0"], "--dx = 0.0: must be in (0, inf) m"),
        (["--toe-slope", "nan"], "--toe-slope = nan: must be in (0, 90) deg"),
        (["--seeds", "0"], "--seeds = 0: must be in [1, inf)"),
    ):
        with pytest.raises(SystemExit) as exc:
            slope_acceptance.main(argv)
        assert exc.value.code == 2
        assert needle in capsys.readouterr().err, argv


def test_crack_speed_map_is_exact_for_plane_and_radial_fronts_up_to_the_edges():
    """The map is the least-squares gradient of the arrival time over 1 m: a plane front
    at 90 m/s must read 90 m/s everywhere, along the area's edges and next to intact cells
    too (a box-smoothed difference read up to 3x too fast there)."""
    from types import SimpleNamespace

    dx = 0.2
    x = (np.arange(100) + 0.5) * dx
    y = (np.arange(60) + 0.5) * dx
    X, Y = np.meshgrid(x, y, indexing="ij")
    angle = np.radians(30.0)
    t = (X * np.cos(angle) + Y * np.sin(angle)) / 90.0
    t[X > 15.0] = np.inf  # intact beyond the front
    p = PSTParams()  # c_p = 132 m/s: both fronts are slower
    v = slope_results.crack_speed_map(SimpleNamespace(arrival_time=t, x=x, y=y, params=p))
    released = np.isfinite(t)
    assert np.all(np.isnan(v[~released]))
    np.testing.assert_allclose(v[released], 90.0, rtol=1e-6)
    # a radial front from a corner: the speed is exact wherever the front is locally
    # straight over the 1 m window (away from the start itself)
    r = np.hypot(X, Y)
    v = slope_results.crack_speed_map(SimpleNamespace(arrival_time=r / 60.0, x=x, y=y, params=p))
    far = r > 5.0
    np.testing.assert_allclose(v[far], 60.0, rtol=0.01)


def test_a_slope_below_the_friction_angle_reports_the_saw_cut_not_a_release():
    """At 20 deg (phi 27 deg) a released slab does not slide: the crack never runs ahead of
    the saw. Warned before the run (the start's slope) and after it (saw_stopped False,
    release = the sawn area); at 35 deg the saw stops and the release exceeds the cut."""
    setup = SlopeSetup(
        length=12.0, width=6.0, dx=0.25, duration=0.6, start=(3.0, 3.0), chunk_steps=50
    )
    p = dict(tau_peak=1200.0, strength_gradient=150.0)
    with pytest.warns(UserWarning) as caught:
        flat = simulate_slope(PSTParams(slope_deg=20.0, **p), setup)
    text = " ".join(str(w.message) for w in caught)
    assert "at or below friction_deg = 27" in text and "never ran ahead of the saw" in text
    assert flat.summary["saw_stopped"] is False
    assert flat.summary["release_area_m2"] == pytest.approx(flat.summary["sawn_area_m2"])
    steep = simulate_slope(PSTParams(slope_deg=35.0, **p), setup)
    assert steep.summary["saw_stopped"] is True
    assert steep.summary["release_area_m2"] > 2 * steep.summary["sawn_area_m2"]


def test_front_speeds_of_arrivals_that_fall_with_distance_are_none():
    from damjax.slope.simulation import _front_speed

    coord = np.linspace(0.0, 8.0, 81)
    mean, peak = _front_speed(coord, 1.0 + coord / 50.0, 0.0, 8.0)
    assert mean == pytest.approx(50.0, rel=1e-6) and peak == pytest.approx(50.0, rel=1e-6)
    mean, peak = _front_speed(coord, 1.0 - coord / 50.0, 0.0, 8.0)
    assert math.isnan(mean) and math.isnan(peak)


def test_a_strength_map_below_the_slab_weight_is_warned_in_python():
    setup = SlopeSetup(
        length=8.0, width=4.0, dx=0.25, duration=0.05, start=(2.0, 2.0), chunk_steps=50
    )
    tau = np.full((32, 16), 1.2)  # kPa given as Pa
    with pytest.warns(UserWarning, match="at or below the gravitational shear .* on 100 %"):
        simulate_slope(PSTParams(), setup, tau_peak=tau)


def test_a_fall_line_beyond_90_degrees_is_warned():
    from damjax.slope.simulation import _slope_notes

    assert _slope_notes(PSTParams(), SlopeSetup(), 35.0, 30.0) == []
    (note,) = _slope_notes(PSTParams(), SlopeSetup(), 35.0, 120.0)
    assert note.startswith("fall_deg: the fall line is more than 90 deg from -x")
