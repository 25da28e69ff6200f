"""The declarations of `damjax.params` (one per field) and what reads them: the checks, the
scenario loader, the command line, the ensemble's units; plausible ranges warned with a
unit hint; a run's input checked once."""

import dataclasses
import math
import warnings

import numpy as np
import pytest

import damjax
from damjax import PSTParams, PSTSetup, SlopeSetup, scenario, validation
from damjax.cli import build_parser, main
from damjax.params import Range, specs

CLASSES = (PSTParams, PSTSetup, SlopeSetup)
TINY = 'type = "pst"\nname = "tiny"\n[params]\nsteady_length = 2.0\n{params}\n[setup]\n'
TINY += "length = 5.0\ndx = 0.05\nduration = 0.02\nchunk_steps = 20\n[output]\nplot = false\n"


@pytest.mark.parametrize("cls", CLASSES)
def test_every_field_is_declared_with_a_meaning_a_kind_and_a_valid_range(cls):
    for f in dataclasses.fields(cls):
        spec = specs(cls)[f.name]
        assert spec.name == f.name and spec.doc, f.name
        assert spec.kind in ("float", "int", "bool", "choice", "profile", "point"), f.name
        assert spec.valid is not None or spec.kind == "point", f.name
        default = f.default
        if default is not None and spec.kind in ("float", "int"):  # the default is valid
            assert (
                spec.valid.holds(default)
                if isinstance(spec.valid, Range)
                else (default in spec.valid)
            ), f.name
        if spec.kind == "choice":
            assert default in spec.valid, f.name
        if spec.plausible is not None:  # the default is plausible, the range named
            assert spec.plausible.holds(default) and spec.plausible_why, f.name


def test_ranges_read_as_the_messages_write_them():
    assert str(Range(0.0, math.inf)) == "(0, inf)"
    assert str(Range(0.0, math.inf, hi_in=True)) == "(0, inf]"
    assert str(Range(1, 1e7, True, True)) == "[1, 10^7]"
    assert str(Range(0, 2**31 - 1, True, True)) == "[0, 2^31 - 1]"
    assert specs(PSTParams)["strength_gradient"].valid_text == "[0, inf) Pa/m"
    assert specs(PSTSetup)["lateral"].valid_text == "{free, constrained}"
    r = Range(0.0, 1.0)
    assert r.holds(0.5) and not r.holds(0.0) and not r.holds(math.nan)
    assert np.array_equal(r.holds(np.array([0.5, 1.0, np.nan])), [True, False, False])


def test_the_command_line_has_a_flag_for_each_declared_one_and_no_other():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    flags = {o for a in sub.choices["pst"]._actions for o in a.option_strings}
    for cls in (PSTParams, PSTSetup):
        for name, spec in specs(cls).items():
            assert (spec.flag in flags) == spec.cli, name
    help_text = " ".join(sub.choices["pst"].format_help().split())
    assert "per dimension, an integer in [1, 64]; default 2" in help_text  # from its range


def test_the_scenario_keys_read_the_declarations():
    """The drift the format description had: particles_per_cell and chunk_steps as
    "integer >= 1", mcc_invariants missing; the keys are the declarations now."""
    from damjax.scenario import schema

    assert schema.valid_words(PSTSetup, "particles_per_cell") == "must be an integer in [1, 64]"
    assert schema.valid_words(PSTSetup, "chunk_steps") == "must be an integer in [1, 10^7]"
    assert schema.valid_words(PSTSetup, "mcc_invariants") == 'must be one of {"3d", "plane"}'
    doc = scenario.schema.tomllib.loads(TINY.format(params=""))
    doc["setup"]["particles_per_cell"] = 65
    with pytest.raises(ValueError, match=r"^setup.particles_per_cell = 65: must be an integer"):
        scenario.parse(doc)
    doc["setup"]["particles_per_cell"] = 2
    doc["setup"]["mcc_invariants"] = "plane"
    assert scenario.parse(doc, warn=False).setup.mcc_invariants == "plane"


def test_one_problem_in_the_words_of_each_reader():
    """The API and the command line name the flag, a scenario file its key; the structure
    (field, value, valid range) is the same."""
    problems = validation.param_problems(PSTParams(poisson=0.7))
    assert [(p.field, p.value, p.valid) for p in problems] == [("poisson", 0.7, "(0, 0.5)")]
    assert str(problems[0]) == "poisson (--poisson) = 0.7: must be in (0, 0.5)"
    from damjax.scenario.schema import toml_lines

    assert toml_lines(problems, {"poisson": 0.7}) == ["params.poisson = 0.7: must be in (0, 0.5)"]
    # a second field named in the line is worded by its reader too
    slip = validation.param_problems(PSTParams(wl_shear_modulus=1.0))
    assert "wl_thickness (--wl-thickness) = 0.04" in str(slip[0])
    assert "params.wl_thickness = 0.04" in toml_lines(slip, {})[0]


def test_the_ensembles_units_are_the_declared_ones():
    from damjax.ensemble.products import _param_units

    assert _param_units("density") == "kg m-3"
    assert _param_units("slope_deg") == "degree"
    assert _param_units("strength_gradient") == "Pa m-1"
    assert _param_units("softening") == "1"


# --------------------------------------------------------------------------- plausibility


@pytest.mark.parametrize(
    "field, value, hint",
    [
        ("youngs_modulus", 4.0, "did you mean 4 MPa = 4e6 Pa?"),
        ("youngs_modulus", 4000.0, "did you mean 4000 kPa = 4e6 Pa?"),
        ("density", 0.25, "did you mean 0.25 g/cm^3 = 250 kg/m^3?"),
        ("thickness", 50.0, "did you mean 50 cm = 0.5 m?"),
        ("slope_deg", 0.6, "did you mean 0.6 rad = 34.4 deg?"),
        ("density", 5000.0, ""),  # no unit makes it plausible: no hint
    ],
)
def test_implausible_values_are_noted_with_the_unit_they_were_probably_given_in(field, value, hint):
    notes = validation.implausible(PSTParams(**{field: value}))
    assert [n.field for n in notes] == [field]
    text = str(notes[0])
    assert text.startswith(f"{specs(PSTParams)[field].label} = {value!r}: outside ")
    assert text.endswith(hint) if hint else "did you mean" not in text
    assert validation.implausible(PSTParams()) == []


def test_an_implausible_value_warns_before_the_run_on_the_command_line(monkeypatch, capsys):
    """`damjax pst --density 0.25` planned 1.2 M steps and warned only after them; the
    warning, with its unit hint, now comes before the run starts."""
    from damjax import pst

    def no_run(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pst, "run", no_run)
    assert main(["pst", "--density", "0.25", "--quiet"]) == 130
    err = capsys.readouterr().err
    assert "density (--density) = 0.25: outside [50, 550] kg/m^3" in err
    assert "did you mean 0.25 g/cm^3 = 250 kg/m^3?" in err


def test_an_implausible_value_is_named_beside_the_error_it_causes(capsys):
    """`--youngs-modulus 4` (MPa meant) fails on dx against Lambda; the warning says why."""
    assert main(["pst", "--youngs-modulus", "4", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == (
        "damjax: warning: youngs_modulus (--youngs-modulus) = 4.0: outside [10^5, 10^9] Pa, "
        "Young's moduli of snow: did you mean 4 MPa = 4e6 Pa?"
    )
    assert err[1].startswith("damjax: error: dx (--dx) = 0.02: must be at most Lambda/2")
    with pytest.warns(validation.DubiousInputWarning, match="did you mean 4 MPa"):
        with pytest.raises(ValueError, match="Lambda/2"):
            damjax.simulate_pst(PSTParams(youngs_modulus=4.0), PSTSetup(length=5.0))


def test_an_implausible_scenario_value_warns_in_the_files_words():
    with pytest.warns(scenario.ScenarioWarning, match=r"^params.density = 0.25: .*g/cm\^3"):
        scenario.loads(TINY.format(params="density = 0.25"))


# --------------------------------------------------------------------------- once


def _count_checks(monkeypatch) -> dict[str, int]:
    counts: dict[str, int] = {}
    check = validation.check_value

    def counted(spec, value, setup=PSTSetup):
        counts[spec.name] = counts.get(spec.name, 0) + 1
        return check(spec, value, setup)

    monkeypatch.setattr(validation, "check_value", counted)
    return counts


def test_a_scenario_run_checks_each_value_once(tmp_path, monkeypatch):
    """Reading and running a scenario checks each field once (`damjax run quick` checked
    each five times): the loader's checked run is what the runner runs."""
    from damjax import runner

    counts = _count_checks(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scn = scenario.loads(TINY.format(params=""))
        outcome = runner.run(scn, tmp_path / "out")
    assert outcome.fault is None
    fields = [*specs(PSTParams), *specs(PSTSetup)]
    assert counts == {name: 1 for name in fields}


def test_a_slope_scenario_reads_its_fields_and_builds_its_model_once(tmp_path, monkeypatch):
    from damjax import runner
    from damjax.core import model
    from damjax.scenario import slope_fields

    calls = {"resolve_inputs": 0, "build_slope": 0}

    def counted(module, name):
        f = getattr(module, name)

        def wrapper(*args, **kwargs):
            calls[name] += 1
            return f(*args, **kwargs)

        monkeypatch.setattr(module, name, wrapper)

    counted(slope_fields, "resolve_inputs")
    counted(model, "build_slope")
    # the names bound where they are called
    monkeypatch.setattr("damjax.scenario.slope.resolve_inputs", slope_fields.resolve_inputs)
    monkeypatch.setattr("damjax.slope.simulation.build_slope", model.build_slope)
    doc = scenario.schema.tomllib.loads(scenario.shipped()["slope-quick"].read_text())
    doc["setup"].update(duration=0.05, chunk_steps=20)
    doc["output"] = {"plot": False}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runner.run(scenario.parse(doc), tmp_path / "out")
    assert calls == {"resolve_inputs": 1, "build_slope": 1}
