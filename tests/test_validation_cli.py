"""Bad input gives one clear line per problem (API: ValueError; CLI: exit status 2)."""

import json
import math
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from damjax import PSTParams, PSTSetup, simulate_pst
from damjax.cli import main

BAD_PARAMS = [
    ("thickness", 0.0, "--thickness"),
    ("density", -250.0, "--density"),
    ("youngs_modulus", 0.0, "--youngs-modulus"),
    ("poisson", 0.5, "--poisson"),
    ("poisson", 0.0, "--poisson"),
    ("slope_deg", 90.0, "--slope-deg"),
    ("slope_deg", math.nan, "--slope-deg"),
    ("friction_deg", -1.0, "--friction-deg"),
    ("tau_peak", -5.0, "--tau-peak"),
    ("strength_gradient", -1.0, "--strength-gradient"),
    ("softening", -0.1, "--softening"),
    ("saw_speed", -6.0, "--saw-speed"),
    ("tensile_strength", -1.0, "--tensile-strength"),
    ("wl_thickness", math.nan, "--wl-thickness"),
    ("slab_fracture_energy", 0.0, "--slab-fracture-energy"),
    ("slab_fracture_energy", math.nan, "--slab-fracture-energy"),
]
BAD_SETUP = [
    ("length", 0.0, "--length"),
    ("dx", -0.02, "--dx"),
    ("duration", 0.0, "--duration"),
    ("cfl", 1.0, "--cfl"),
    ("cfl", 0.0, "--cfl"),
    ("particles_per_cell", 0, "--particles-per-cell"),
    ("lateral", "sideways", "--lateral"),
    ("dtype", "float16", "--dtype"),
]


@pytest.mark.parametrize("field,value,flag", BAD_PARAMS)
def test_api_rejects_bad_params(field, value, flag):
    with pytest.raises(ValueError) as exc:
        simulate_pst(PSTParams(**{field: value}), PSTSetup(length=5.0, dx=0.05))
    msg = str(exc.value)
    assert len(msg.splitlines()) == 1
    assert field in msg and flag in msg and "must be in" in msg


@pytest.mark.parametrize("field,value,flag", BAD_SETUP)
def test_api_rejects_bad_setup(field, value, flag):
    with pytest.raises(ValueError) as exc:
        simulate_pst(PSTParams(), PSTSetup(**{"length": 5.0, "dx": 0.05, field: value}))
    assert flag in str(exc.value)


def test_dx_must_resolve_the_elastic_length():
    with pytest.raises(ValueError, match="Lambda/2"):
        simulate_pst(PSTParams(), PSTSetup(length=5.0, dx=0.4))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulate_pst(
            PSTParams(steady_length=1.0),
            PSTSetup(length=3.0, dx=0.2, duration=0.05, chunk_steps=10),
        )
    assert any("Lambda/5" in str(w.message) for w in caught)


def test_a_run_too_large_for_memory_fails_at_once_naming_the_fields(capsys):
    """A 1e9 m PST is rejected before any allocation, with the fields that set its size
    (it used to end in a numpy allocation traceback)."""
    with pytest.raises(ValueError, match=r"--length.*GiB.*memory"):
        simulate_pst(PSTParams(), PSTSetup(length=1.0e9))
    assert main(["pst", "--length", "1e9"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "--length" in err and "coarser dx" in err
    from damjax import SlopeSetup, simulate_slope

    with pytest.raises(ValueError, match="slope.*GiB"):
        simulate_slope(
            PSTParams(), SlopeSetup(length=1.0e5, width=1.0e5, dx=0.1, start=(10.0, 10.0))
        )


def test_a_vanishing_dx_is_one_line_not_an_overflow(capsys):
    """dx = 1e-314 (a denormal) gave "cannot convert float infinity to integer" from the
    grid's size; it asks for more cells than any run can hold."""
    from damjax import SlopeSetup, simulate_slope

    assert main(["pst", "--dx", "1e-314"]) == 2
    assert "dx (--dx) = 1e-314: must be at least length (--length) / 1e+15" in (
        capsys.readouterr().err
    )
    with pytest.raises(ValueError, match=r"dx = 1e-300: must be at least length / 1e\+15"):
        simulate_slope(PSTParams(), SlopeSetup(length=10.0, width=5.0, dx=1e-300))


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(particles_per_cell=0), "particles_per_cell"),
        (dict(chunk_steps=0), "chunk_steps"),
        (dict(dtype="float16"), "dtype"),
        (dict(p0_rule="guess"), "p0_rule"),
    ],
)
def test_slope_setup_problems_are_named(kw, match):
    from damjax import SlopeSetup, simulate_slope

    with pytest.raises(ValueError, match=match):
        simulate_slope(PSTParams(), SlopeSetup(length=10.0, width=10.0, start=(5.0, 5.0), **kw))


def test_slope_field_of_the_wrong_shape_is_rejected():
    """A field that does not cover the release area cell by cell used to be clamped
    silently at its edge."""
    import numpy as np

    from damjax import SlopeSetup, simulate_slope

    setup = SlopeSetup(length=10.0, width=10.0, dx=0.2, start=(5.0, 5.0))
    for name in ("slope_deg", "tau_peak", "fall_deg"):
        with pytest.raises(ValueError, match=rf"{name} field: shape \(7, 3\) must be .*\(50, 50\)"):
            simulate_slope(PSTParams(), setup, **{name: np.full((7, 3), 35.0)})


def test_slope_maps_of_bools_strings_or_nan_are_rejected_with_where():
    """A map argument is numbers: a bool or a numeric string is not silently converted,
    and a NaN cell is named."""
    import numpy as np

    from damjax import SlopeSetup, simulate_slope

    setup = SlopeSetup(length=4.0, width=4.0, dx=0.2, start=(2.0, 2.0))
    for kw in (dict(tau_peak=True), dict(tau_peak="1e3"), dict(slope_deg="35")):
        name = next(iter(kw))
        with pytest.raises(ValueError, match=rf"{name} field: must be a number or a 2D array"):
            simulate_slope(PSTParams(), setup, **kw)
    tau = np.full((20, 20), 1000.0)
    tau[3, 5] = np.nan
    with pytest.raises(ValueError, match=r"1 not, the first nan at cell \(3, 5\)"):
        simulate_slope(PSTParams(), setup, tau_peak=tau)


def test_inconsistent_values_are_rejected():
    with pytest.raises(ValueError, match="steady_length"):
        simulate_pst(PSTParams(steady_length=30.0), PSTSetup(length=20.0, dx=0.05))
    with pytest.raises(ValueError, match="tau_g"):
        simulate_pst(PSTParams(tau_peak=500.0), PSTSetup(length=5.0, dx=0.05))


def test_several_problems_one_line_each(capsys):
    rc = main(["pst", "--dx", "-1", "--poisson", "0.7", "--lateral", "x", "--cfl", "2", "--json"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 4
    assert all(line.startswith("damjax: error: ") for line in err)
    for flag in ("--dx", "--poisson", "--lateral", "--cfl"):
        assert any(flag in line for line in err)


@pytest.mark.parametrize("text", ["-1e3", "-inf", "-NaN", "-.5E+1"])
def test_cli_negative_numbers_in_any_notation_reach_the_range_check(text, capsys):
    # argparse alone reads "-1e3" or "-inf" as a flag: "expected one argument"
    rc = main(["pst", "--tensile-strength", text, "--json"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert "tensile_strength (--tensile-strength) = " in err[0] and "must be in (0, inf]" in err[0]


def test_cli_non_numeric_value_exits_2_without_traceback():
    proc = subprocess.run(
        [sys.executable, "-m", "damjax", "pst", "--dx", "abc"], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "--dx" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_cli_json_summary_and_plot(tmp_path, capsys):
    png = tmp_path / "pst.png"
    rc = main(
        [
            "pst",
            "--length",
            "8",
            "--dx",
            "0.05",
            "--duration",
            "0.5",
            "--steady-length",
            "3",
            "--strength-gradient",
            "3000",
            "--chunk-steps",
            "200",
            "--json",
            "--quiet",
            "--plot",
            str(png),
        ]
    )
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    for key in [
        "lateral",
        "arrested",
        "arrest_position_m",
        "arrest_length_m",
        "critical_cut_length_m",
        "max_crack_speed_over_cs",
        "slab_fractures",
        "tension_gradient_pa_per_m",
        "tension_gradient_theory_pa_per_m",
        "n_particles",
        "n_steps",
        "compile_time_s",
        "wall_time_s",
        "particle_steps_per_s",
    ]:
        assert key in out
    assert out["slab_fractures"] == []
    assert out["tension_gradient_pa_per_m"] is None
    assert png.stat().st_size > 10_000


@pytest.mark.parametrize(
    "field, value, hint",
    [
        ("tensile_strength", 6.0, "did you mean 6 kPa = 6000 Pa?"),
        ("wl_thickness", 4.0, "did you mean 4 cm = 0.04 m?"),
        ("tau_peak", 1e6, "weak-layer shear strengths"),
    ],
)
def test_unit_mixups_of_strengths_and_the_weak_layer_are_noted(field, value, hint):
    from damjax.validation import implausible

    notes = implausible(PSTParams(**{field: value}))
    assert [n.field for n in notes] == [field] and hint in notes[0].text()
    # inf is the documented unbreakable layer / elastic slab: no note
    if field != "wl_thickness":
        assert implausible(PSTParams(**{field: math.inf})) == []


def test_dubious_api_input_warns_and_theory_below_friction_is_null():
    """A slope at or below the friction angle runs (low-angle terrain is a valid question),
    with a warning naming both fields; the bar-model theory values, negative there, are
    null."""
    setup = PSTSetup(length=6.0, dx=0.05, duration=0.05)
    params = PSTParams(slope_deg=25.0, steady_length=3.0)
    with pytest.warns(UserWarning, match=r"slope_deg \(--slope-deg\) = 25.0: at or below"):
        res = simulate_pst(params, setup)
    assert res.summary["critical_cut_length_theory_m"] is None
    assert res.summary["runaway_gradient_pa_per_m"] is None
    ok = simulate_pst(PSTParams(steady_length=3.0), setup)
    assert ok.summary["critical_cut_length_theory_m"] > 0


def test_controlled_cut_leaving_the_domain_warns_and_has_no_tension_gradient():
    setup = PSTSetup(length=3.0, dx=0.05, duration=0.1, controlled=True)
    with pytest.warns(UserWarning, match="leaves the 3 m domain"):
        res = simulate_pst(PSTParams(saw_speed=60.0), setup)
    assert res.summary["tension_gradient_pa_per_m"] is None
    assert res.summary["tension_gradient_theory_pa_per_m"] > 0


def test_chunk_longer_than_the_run_keeps_the_cfl_time_step():
    from damjax import make_layout
    from damjax.core.model import time_step

    params = PSTParams(steady_length=3.0)
    short = PSTSetup(length=6.0, dx=0.05, duration=0.05, chunk_steps=100_000)
    lay = make_layout(params, short)
    dt = short.duration / lay.n_steps
    assert lay.n_chunks == 1 and lay.chunk_steps < 1000
    assert 0.99 * time_step(params, short) <= dt <= time_step(params, short)


def test_smooth_arrest_checks_its_layout_and_parameters():
    """A layout made for another setup (a longer run would get a dt beyond the CFL limit
    and silently return NaN), for a softer slab, or invalid concrete parameters: one
    clear ValueError each."""
    import dataclasses

    from damjax import arrest_position_smooth, make_layout

    params = PSTParams(steady_length=3.0)
    setup = PSTSetup(length=6.0, dx=0.05, duration=0.05)
    lay = make_layout(params, setup)
    with pytest.raises(ValueError, match="made for another setup .*duration 0.05 vs 0.2"):
        arrest_position_smooth(params, dataclasses.replace(setup, duration=0.2), lay)
    with pytest.raises(ValueError, match="exceeds the stable"):
        arrest_position_smooth(dataclasses.replace(params, youngs_modulus=4e7), setup, lay)
    with pytest.raises(ValueError, match=r"thickness \(--thickness\)"):
        arrest_position_smooth(dataclasses.replace(params, thickness=-1.0), setup, lay)
    with pytest.raises(ValueError, match="elastic slab"):
        arrest_position_smooth(dataclasses.replace(params, tensile_strength=5e3), setup, lay)


def test_float64_in_a_traced_run_needs_x64_switched_on():
    """In a fresh process (other tests switch 64-bit mode on in this one)."""
    code = (
        "from damjax import PSTParams, PSTSetup, arrest_position_smooth\n"
        "try:\n"
        "    arrest_position_smooth(PSTParams(), PSTSetup(length=6.0, dx=0.05, dtype='float64'))\n"
        "except ValueError as e:\n"
        "    print('ERR', e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.startswith("ERR dtype (--dtype) = 'float64'"), out.stdout + out.stderr
    assert "jax_enable_x64" in out.stdout


def test_cli_checks_outputs_and_sizes_before_running(tmp_path, capsys):
    """Problems found only after a run lose the run: the figure format, an --out that is a
    file, absurd chunk sizes and a weak layer that lets the slab slip metres are one-line
    errors (status 2) before anything is compiled."""
    small = ["pst", "--length", "6", "--steady-length", "3", "--duration", "0.02", "--quiet"]
    cases = [
        (["--plot", str(tmp_path / "fig.xyz")], "unsupported figure format 'xyz'"),
        (["--plot", str(tmp_path)], "is a folder; give a file"),
        (["--plot", str(tmp_path / "afile" / "fig.png")], "(not a folder)"),
        (["--chunk-steps", "1e30"], "chunk_steps (--chunk-steps) = 1e+30: must be an integer"),
        (["--wl-shear-modulus", "1"], "elastic slip under the slab"),
        (["--strength-fit", "linear"], "needs --strength-profile"),
        (["--length", "0.1", "--dx", "0.05"], "must be at least 4 cells"),
    ]
    (tmp_path / "afile").write_text("")
    for extra, needle in cases:
        assert main(small + extra) == 2, extra
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], (extra, err)
    afile = tmp_path / "afile"
    assert main(["run", "quick", "--out", str(afile), "--quiet"]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    # a figure in a folder that does not exist yet: made, as `damjax show` does
    fig = tmp_path / "new" / "sub" / "pst.png"
    assert main(small + ["--plot", str(fig)]) == 0
    assert fig.stat().st_size > 0


def test_api_type_and_batch_errors_name_the_field():
    import jax.numpy as jnp
    import numpy as np

    from damjax import sweep

    setup = PSTSetup(length=6.0, dx=0.05, duration=0.02)
    base = dict(steady_length=3.0)
    for kw, needle in [
        ({"density": "250"}, "density (--density) = '250'"),
        ({"density": True}, "density (--density) = True"),
        ({"strength_gradient": jnp.array([500.0, 900.0])}, "a batch of runs is damjax.sweep"),
        ({"strength_profile": np.full((2, 10), 1500.0)}, "strength_profile (--strength-profile)"),
    ]:
        with pytest.raises(ValueError, match=re.escape(needle)):
            simulate_pst(PSTParams(**base, **kw), setup)
    with pytest.raises(ValueError, match=r"length \(--length\) = '10'"):
        simulate_pst(PSTParams(**base), PSTSetup(length="10"))
    batch = PSTParams(**base, strength_gradient=np.array([100.0, 200.0]))
    for bad in (0, -1, 1.5):
        with pytest.raises(ValueError, match="batch_size"):
            sweep(batch, setup, batch_size=bad)
    with pytest.raises(ValueError, match="one leading axis"):
        sweep(PSTParams(**base, strength_gradient=np.ones((2, 2))), setup)
    with pytest.raises(ValueError, match="is empty"):
        sweep(PSTParams(**base, strength_gradient=np.array([])), setup)


def test_swapped_or_foreign_arguments_are_type_errors_naming_them():
    from damjax import SlopeSetup, make_layout, simulate_slope, sweep

    p, s = PSTParams(steady_length=3.0), PSTSetup(length=6.0, dx=0.05, duration=0.02)
    for call, needle in [
        (lambda: simulate_pst(s, p), "simulate_pst: params must be damjax.PSTParams, got PSTSetup"),
        (lambda: simulate_pst(p, {"length": 6.0}), "setup must be damjax.PSTSetup, got dict"),
        (lambda: simulate_pst(p, SlopeSetup()), "setup must be damjax.PSTSetup, got SlopeSetup"),
        (lambda: simulate_pst(p, s, layout="abc"), "layout must be a Layout (damjax.make_layout)"),
        (lambda: simulate_slope(p, s), "simulate_slope: setup must be damjax.SlopeSetup"),
        (lambda: sweep(p, SlopeSetup()), "sweep: setup must be damjax.PSTSetup"),
        (lambda: make_layout(s, p), "make_layout: params must be damjax.PSTParams"),
    ]:
        with pytest.raises(TypeError, match=re.escape(needle)):
            call()
    with pytest.raises(
        TypeError, match=re.escape("unknown field 'poison' (did you mean 'poisson'?)")
    ):
        PSTParams(poison=0.3)
    with pytest.raises(TypeError, match=re.escape("PSTSetup: unknown field 'lenght'")):
        PSTSetup(lenght=6.0)
    # make_layout checks the values it sizes the grid from
    with pytest.raises(ValueError, match=re.escape("dx (--dx) = -1.0: must be in (0, inf) m")):
        make_layout(p, PSTSetup(dx=-1.0))
    with pytest.raises(ValueError, match=re.escape("youngs_modulus (--youngs-modulus) = nan")):
        make_layout(PSTParams(youngs_modulus=float("nan")), s)


def test_traced_parameters_stiffer_than_the_layout_stop_with_a_message():
    """Under jit/grad the values cannot be checked before tracing; a slab stiffer than the
    layout's (dt beyond the Courant limit) used to return NaN silently."""
    import dataclasses

    import jax

    from damjax import arrest_position_smooth, make_layout

    params = PSTParams(steady_length=3.0)
    setup = PSTSetup(length=6.0, dx=0.05, duration=0.05)
    lay = make_layout(params, setup)
    f = jax.jit(jax.value_and_grad(lambda p: arrest_position_smooth(p, setup, lay)))
    value, _ = f(params)
    assert math.isfinite(float(value))
    # twice as stiff: within the bare Courant limit dt c_p <= dx, but beyond the layout's
    # cfl bound, which the concrete check (`check_layout`) applies too
    stiff = dataclasses.replace(params, youngs_modulus=2 * params.youngs_modulus)
    with pytest.raises(ValueError, match="exceeds the stable"):
        arrest_position_smooth(stiff, setup, lay)
    with pytest.raises(Exception, match="exceeds the stable"):
        jax.block_until_ready(f(stiff))


def test_settings_a_slab_law_does_not_use_are_reported_as_ignored(capsys):
    small = ["pst", "--length", "6", "--steady-length", "3", "--duration", "0.02", "--quiet"]
    cases = [
        (
            ["--mcc-xi", "0.5"],
            "tensile_strength (--tensile-strength) = inf (an elastic slab): "
            "mcc_xi (--mcc-xi) is ignored",
        ),
        (
            ["--tensile-strength", "6000", "--slab-strength-cov", "0.5", "--seed", "3"],
            "slab_fracture (--slab-fracture) = 'paper': slab_strength_cov (--slab-strength-cov), "
            "seed (--seed) are ignored",
        ),
    ]
    for extra, needle in cases:
        assert main(small + extra) == 0, extra
        assert needle in capsys.readouterr().err, extra
    assert main(small + ["--tensile-strength", "6000", "--mcc-xi", "0.5"]) == 0
    assert "ignored" not in capsys.readouterr().err  # the plastic slab uses mcc_xi


def test_set_overrides_a_scenario_key_and_is_checked_like_the_file(tmp_path, capsys):
    """`--set KEY=VALUE` changes a scenario key for one run (TOML values, bare words as
    strings, nested tables made), the run's stored scenario keeps it, and a wrong key,
    value or form is the scenario's one-line error."""
    from damjax import scenario

    data = scenario.override(
        {"setup": {"dx": 0.1}},
        [
            "setup.duration=0.25",
            "setup.chunk_steps=40",
            "strength.kind=grf",
            'strength.model="exponential"',
            "setup.start=[3.0, 2.0]",
            "output.plot=false",
            "ensemble.params.softening.dist = uniform",
        ],
    )
    assert data["setup"] == {"dx": 0.1, "duration": 0.25, "chunk_steps": 40, "start": [3.0, 2.0]}
    assert data["strength"] == {"kind": "grf", "model": "exponential"}
    assert data["output"]["plot"] is False
    assert data["ensemble"]["params"]["softening"]["dist"] == "uniform"
    # nothing after "=": the key goes (a key of the strength's former kind)
    gone = scenario.override(
        {"strength": {"kind": "constant", "tau_peak": 1e3}}, ["strength.tau_peak="]
    )
    assert gone == {"strength": {"kind": "constant"}}
    for bad, match in (
        ("duration", "must be KEY=VALUE"),
        ("=1", "must be KEY=VALUE"),
        ("setup..dx=1", "must be KEY=VALUE"),
        ("setup.dx.x=1", "setup.dx = 0.1 is a value, not a table"),
    ):
        with pytest.raises(ValueError, match=match):
            scenario.override({"setup": {"dx": 0.1}}, [bad])
    # a relative file path from the command line is the working directory's (the shipped
    # scenarios' own files are beside them, in the package): absolute paths stay
    paths = scenario.override(
        {}, ["strength.file=my.csv", "snow.mask=gis/forest.shp", "terrain.release=/r.shp"]
    )
    assert paths["strength"]["file"] == str(Path.cwd() / "my.csv")
    assert paths["snow"]["mask"] == str(Path.cwd() / "gis" / "forest.shp")
    assert paths["terrain"]["release"] == "/r.shp"
    out = tmp_path / "run"
    rc = main(["run", "quick", "--set", "setup.duration=0.05", "--out", str(out), "--quiet"])
    assert rc == 0
    from damjax import runner

    assert runner.load_result(out)[0].setup.duration == 0.05  # the run's stored scenario
    capsys.readouterr()
    for bad, needle in (
        ("setup.durtion=0.1", "setup.durtion: unknown key (did you mean 'setup.duration'?)"),
        ("setup.duration=abc", 'setup.duration = "abc": must be a number in (0, inf) s'),
        ("duration", "--set duration: must be KEY=VALUE"),
        ("setup.poison=0.3", "setup.poison: unknown key (did you mean 'params.poisson'?)"),
    ):
        rc = main(["run", "quick", "--set", bad, "--out", str(tmp_path / "bad"), "--quiet"])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and needle in err[0], err


def test_a_unit_mix_up_in_a_scenario_is_said_beside_the_problems_it_causes(capsys):
    """E = 4 (MPa meant) makes dx too coarse for Lambda: the scenario's error line came
    alone, without the unit hint the Python API warns (docs/api/params.md)."""
    from damjax import scenario

    data = {"type": "pst", "name": "x", "params": {"youngs_modulus": 4}}
    assert any("did you mean 4 MPa = 4e6 Pa?" in n for n in scenario.dubious(data))
    with pytest.warns(scenario.ScenarioWarning, match="did you mean 4 MPa"):
        with pytest.raises(ValueError, match="setup.dx = .*must be at most Lambda/2"):
            scenario.load("quick", sets=["params.youngs_modulus=4"])
    assert main(["run", "quick", "--set", "params.youngs_modulus=4", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "did you mean 4 MPa = 4e6 Pa?" in err and "Lambda/2" in err


def test_a_controlled_sweep_reports_only_the_strength_fields_it_was_given():
    """`damjax.sweep` broadcasts every field of a batch: a controlled sweep over saw
    speeds reported the default strength fields it never set as ignored."""
    import numpy as np

    from damjax.sweep import broadcast_batch
    from damjax.validation import dubious

    setup = PSTSetup(length=10.0, dx=0.05, duration=0.05, controlled=True)

    def ignored(params):
        lines = [p.reason for p in dubious(broadcast_batch(params, 2), setup)]
        return [ln for ln in lines if "ignored" in ln]

    assert ignored(PSTParams(saw_speed=np.array([10.0, 20.0]))) == []
    (line,) = ignored(PSTParams(saw_speed=np.array([10.0, 20.0]), tau_peak=np.array([9e2, 1e3])))
    assert "tau_peak" in line and "steady_length" not in line and "softening" not in line
