"""Scenario files: the shipped library, validation at the edge, mutation-based properties.

The property tests mutate the shipped scenarios (drop, rename, retype, perturb keys) and
throw them at the validator: an invalid one must give a `ValueError` whose every line
names a TOML key (never another exception), and a valid one must run.
"""

import copy
import dataclasses
import datetime
import math
import random
import re
import tempfile
import tomllib
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from damjax import PSTParams, PSTSetup, runner, scenario, theory
from damjax.cli import main
from damjax.params import specs
from damjax.scenario import schema

SHIPPED = scenario.shipped()
NAMES = sorted(SHIPPED)
# the property tests mutate PST scenarios (their keys are PSTParams/PSTSetup fields); slope
# scenarios have their own schema and checks in tests/test_slope.py
PST_NAMES = [n for n in NAMES if tomllib.loads(SHIPPED[n].read_text())["type"] == "pst"]
SECTION_CLS = {"params": PSTParams, "setup": PSTSetup, "output": scenario.Output}
KNOWN = {
    None: set(scenario.TOP_KEYS),
    **{s: {f.name for f in dataclasses.fields(c)} for s, c in SECTION_CLS.items()},
}
# a problem line: a TOML key, optionally "= value", then ": what is wrong"; or the keys
# that together set a size, then what they give ("setup.length, setup.dx and ... give")
LINE = re.compile(
    r"^[A-Za-z_][\w.-]*( = .+)?: \S.*$"
    r"|^([A-Za-z_][\w.-]*, )*[A-Za-z_][\w.-]* and [A-Za-z_][\w.-]* give \S.*$"
)
TINY_SETUP = {"length": 5.0, "dx": 0.05, "duration": 0.05, "chunk_steps": 50}


def raw(name: str) -> dict:
    with open(SHIPPED[name], "rb") as fh:
        return tomllib.load(fh)


def assert_clean(exc: ValueError, must_name: str | None = None) -> list[str]:
    msg = str(exc)
    lines = msg.splitlines()
    assert lines, "empty error message"
    for line in lines:
        assert LINE.match(line), f"not a one-line problem: {line!r}"
    assert "Traceback" not in msg
    if must_name is not None:
        assert must_name in msg, f"{must_name!r} not named in {msg!r}"
    return lines


# --------------------------------------------------------------------------- the library


def test_library_has_the_papers_cases():
    expected = {
        "quick",
        "controlled-0.2cs",
        "controlled-0.8cs",
        "controlled-1.4cs",
        "elastic-delta0",
        "elastic-delta2",
        "plastic-theta30",
        "plastic-theta150",
    }
    assert expected <= set(NAMES)


@pytest.mark.parametrize("name", NAMES)
def test_shipped_scenarios_are_valid_and_round_trip(name):
    data = raw(name)
    assert data["name"] == name and data["type"] in scenario.SCENARIO_TYPES
    assert data["description"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", scenario.ScenarioWarning)  # no dubious value shipped
        scn = scenario.load(name)
    text = scn.to_toml()
    again = scenario.loads(text, warn=False)
    assert again.to_toml() == text  # canonical and idempotent
    assert scn.name == name


@pytest.mark.parametrize("ratio", [0.2, 0.8, 1.4])
def test_controlled_scenarios_saw_at_the_papers_speeds_inside_the_domain(ratio):
    scn = scenario.load(f"controlled-{ratio}cs")
    cs = float(theory.shear_wave_speed(scn.params))
    assert scn.setup.controlled
    assert scn.params.saw_speed / cs == pytest.approx(ratio, rel=1e-4)
    assert scn.params.saw_speed * scn.setup.duration < scn.setup.length
    assert (scn.setup.length, scn.setup.dx) == (100.0, 0.02)


def test_elastic_and_plastic_scenarios():
    for delta in (0, 2):
        p = scenario.load(f"elastic-delta{delta}").params
        assert (p.strength_gradient, p.steady_length, p.softening) == (500.0, 20.0, delta)
        assert math.isinf(p.tensile_strength)
    for theta in (30, 150):
        p = scenario.load(f"plastic-theta{theta}").params
        assert (p.tensile_strength, p.strength_gradient, p.softening) == (6000.0, theta, 0.0)
    s = scenario.load("quick").setup
    assert (s.length, s.dx, s.duration) == (15.0, 0.05, 1.0)


def test_cli_lists_the_shipped_scenarios(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == len(NAMES)
    for name, line in zip(NAMES, out, strict=True):
        assert line.split()[0] == name and len(line.split()) > 3


def test_every_params_and_setup_field_is_a_valid_key():
    """Generic over the dataclass fields: new PSTParams/PSTSetup fields need no edit."""
    data = scenario.Scenario("all", PSTParams(), PSTSetup(length=50.0, dx=0.05)).to_dict()
    p = PSTParams()
    fields = {f.name for f in dataclasses.fields(PSTParams) if getattr(p, f.name) is not None}
    assert fields <= set(data["params"])
    assert {f.name for f in dataclasses.fields(PSTSetup)} == set(data["setup"])
    scenario.parse(data, warn=False)


# --------------------------------------------------------------------------- examples


def scn_text(params: str = "", setup: str = "", extra: str = "") -> str:
    return f'type = "pst"\nname = "t"\n{extra}\n[params]\n{params}\n[setup]\n{setup}\n'


@pytest.mark.parametrize(
    "params,setup,extra,expected",
    [
        ("poison = 0.3", "", "", "params.poison: unknown key (did you mean 'params.poisson'?)"),
        ("dx = 0.05", "", "", "params.dx: unknown key (did you mean 'setup.dx'?)"),
        ("", "", "nme = 'x'", "nme: unknown key (did you mean 'name'?)"),
        ('density = "250"', "", "", 'params.density = "250": must be a number in (0, inf)'),
        ("", "chunk_steps = 50.0", "", "setup.chunk_steps = 50.0: must be an integer in [1, 10^7]"),
        ("", "controlled = 1", "", "setup.controlled = 1: must be true or false"),
        ("", 'lateral = "sideways"', "", 'setup.lateral = "sideways": must be in {free, const'),
        ("slope_deg = nan", "", "", "params.slope_deg = nan: must be a number in (0, 90) deg"),
        ("poisson = 0.7", "", "", "params.poisson = 0.7: must be in (0, 0.5)"),
        ("tau_peak = 500.0", "", "", "params.tau_peak = 500.0: must exceed"),
        ("steady_length = 30.0", "length = 20.0", "", "params.steady_length = 30.0"),
        ("", "dx = 0.5", "", "setup.dx = 0.5: must be at most Lambda/2"),
        ("", "length = 1e5\ndx = 0.001", "", "particles: must be at most"),
        ("tensile_strength = -inf", "", "", "params.tensile_strength = -inf: must be in"),
    ],
)
def test_problem_lines_name_key_value_and_range(params, setup, extra, expected):
    with pytest.raises(ValueError) as exc:
        scenario.loads(scn_text(params, setup, extra))
    lines = assert_clean(exc.value)
    assert len(lines) == 1
    assert expected in lines[0]


def test_all_problems_reported_at_once():
    text = scn_text('poisson = 0.7\ndensity = "x"\nfoo = 1', "dim = 3\ncfl = 2.0")
    with pytest.raises(ValueError) as exc:
        scenario.loads(text)
    lines = assert_clean(exc.value)
    for key in ("params.poisson", "params.density", "params.foo", "setup.dim", "setup.cfl"):
        assert sum(key in line for line in lines) == 1, key


def test_a_misspelt_table_is_one_problem():
    """[param] for [params]: its L_ss 5 m was not read, and the default 20 m does not fit
    the 10 m PST; that follows from the misspelling and is not a second problem."""
    text = 'type = "pst"\nname = "t"\n[param]\nsteady_length = 5.0\n[setup]\nlength = 10.0\n'
    with pytest.raises(ValueError) as exc:
        scenario.loads(text)
    assert assert_clean(exc.value) == ["param: unknown key (did you mean 'params'?)"]


def test_missing_and_wrong_top_level_keys():
    with pytest.raises(ValueError) as exc:
        scenario.loads('name = "x y"\ntype = "avalanche"\ndescription = 3\nparams = 5')
    lines = assert_clean(exc.value)
    assert {line.split()[0].rstrip(":") for line in lines} == {
        "name",
        "type",
        "description",
        "params",
    }
    with pytest.raises(ValueError, match="^type: missing"):
        scenario.loads('name = "x"')
    with pytest.raises(ValueError, match="^invalid TOML: "):
        scenario.loads("type = \n")
    with pytest.raises(ValueError, match="did you mean 'quick'"):
        scenario.load("quik")


def test_infinite_strengths_are_valid():
    scn = scenario.loads(scn_text("tau_peak = inf\ntensile_strength = inf", "length = 30.0"))
    assert math.isinf(scn.params.tau_peak) and math.isinf(scn.params.tensile_strength)
    # integers are fine where floats are expected, and come back as floats
    scn = scenario.loads(scn_text("density = 300", "length = 30"))
    assert isinstance(scn.params.density, float) and scn.setup.length == 30.0


def test_dubious_values_warn():
    text = scn_text("slope_deg = 15.0\ndensity = 600.0", "controlled = true\nduration = 30.0")
    with pytest.warns(scenario.ScenarioWarning) as rec:
        scenario.loads(text)
    msgs = " | ".join(str(w.message) for w in rec)
    assert "params.slope_deg = 15.0" in msgs and "params.density = 600.0" in msgs
    assert "leaves the 100 m domain" in msgs


def test_replace_overrides_and_revalidates():
    scn = scenario.load("quick").replace(setup={"dx": 0.1})
    assert scn.setup.dx == 0.1
    with pytest.raises(ValueError, match="setup.dx"):
        scenario.load("quick").replace(setup={"dx": -1.0})


# --------------------------------------------------------------------------- mutations


def _paths(data: dict) -> list[tuple[str | None, str]]:
    """(section or None, key) of every key of a scenario dict."""
    out: list[tuple[str | None, str]] = [(None, k) for k in data]
    for sec in scenario.SECTIONS:
        if isinstance(data.get(sec), dict):
            out += [(sec, k) for k in data[sec]]
    return out


def _table(data: dict, sec: str | None) -> dict:
    return data if sec is None else data[sec]


def _name(sec: str | None, key: str) -> str:
    return key if sec is None else f"{sec}.{key}"


def _expected_kind(sec: str | None, key: str) -> str:
    if sec is None:
        return "table" if key in scenario.SECTIONS else "str"
    default = getattr(SECTION_CLS[sec](), key, None)
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "int"
    if isinstance(default, float):
        return "float"
    if isinstance(default, str) or (sec == "output" and key == "dir"):
        return "str"
    return "array"


WRONG = {
    "float": ["12", True, ["a"], {"a": 1}, datetime.date(2020, 1, 1)],
    "int": [2.0, "2", False, [1]],
    "bool": [1, "true", 0.0],
    "str": [3, 1.5, True, ["free"]],
    "table": [3, "x", [1, 2]],
    "array": ["1", True, {"a": 1}, ["a", 1]],
}


def _typo(key: str, how: int) -> str:
    if how == 0 and len(key) > 2:
        return key[:-1]
    if how == 1:
        return key + key[-1]
    if how == 2 and len(key) > 3:
        return key[0] + key[2] + key[1] + key[3:]
    return key + "_x"


def _out_of_range(sec: str, key: str, kind: str) -> list:
    decl = specs(SECTION_CLS[sec]).get(key) if sec in ("params", "setup") else None
    if decl is None or decl.kind not in ("float", "int"):
        return []

    def ok(v: float) -> bool:
        if isinstance(decl.valid, tuple):
            return v in decl.valid
        return bool(decl.valid.holds(v)) and (decl.kind != "int" or v.is_integer())

    cands = [-1, 0, 3, 1000] if kind == "int" else [-1.0, 0.0, 0.7, 1.5, 95.0, -1e6, math.inf]
    return [v for v in cands if not ok(float(v))]


def invalid_mutation(data: dict, draw_index, draw_bool) -> str:
    """Apply one mutation that certainly makes ``data`` invalid; return the key it names."""
    paths = _paths(data)
    sec, key = paths[draw_index(len(paths))]
    table = _table(data, sec)
    kind = _expected_kind(sec, key)
    choices = ["rename", "retype", "add"]
    if kind in ("float", "array"):
        choices.append("nan")
    if sec in ("params", "setup") and _out_of_range(sec, key, kind):
        choices.append("range")
    op = choices[draw_index(len(choices))]
    if op == "rename":
        valid = KNOWN[sec]
        for how in (draw_index(4), 3):
            new = _typo(key, how)
            if new not in valid and new not in table:
                break
        else:  # pragma: no cover
            new = key + "_zz"
        table[new] = table.pop(key)
        return _name(sec, new)
    if op == "retype":
        wrong = WRONG[kind]
        table[key] = copy.deepcopy(wrong[draw_index(len(wrong))])
        return _name(sec, key)
    if op == "nan":
        table[key] = math.nan
        return _name(sec, key)
    if op == "range":
        vals = _out_of_range(sec, key, kind)
        table[key] = vals[draw_index(len(vals))]
        return _name(sec, key)
    # add an unknown key to a section (or the top level)
    target = sec if sec is not None and isinstance(data.get(sec), dict) else None
    new = "unknown_" + key.lower()
    _table(data, target)[new] = 1.0 if draw_bool() else "x"
    return _name(target, new)


def neutral_mutation(data: dict, draw_index, draw_float) -> None:
    """Drop a key or perturb a number: the result may be valid or not."""
    paths = _paths(data)
    sec, key = paths[draw_index(len(paths))]
    table = _table(data, sec)
    value = table[key]
    if isinstance(value, (int, float)) and not isinstance(value, bool) and draw_float() > 0:
        factor = draw_float()
        new = value * factor
        table[key] = int(new) if isinstance(value, int) else float(new)
    else:
        del table[key]


@settings(
    max_examples=150,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(name=st.sampled_from(PST_NAMES), data=st.data())
def test_mutated_scenarios_give_clean_errors(name, data):
    doc = raw(name)
    idx = lambda n: data.draw(st.integers(0, n - 1))  # noqa: E731
    flt = lambda: data.draw(st.floats(-3.0, 3.0, allow_nan=False))  # noqa: E731
    for _ in range(data.draw(st.integers(0, 2))):
        if _paths(doc):
            neutral_mutation(doc, idx, flt)
    invalid = data.draw(st.booleans())
    named = invalid_mutation(doc, idx, lambda: data.draw(st.booleans())) if invalid else None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scenario.parse(doc)
    except ValueError as exc:
        lines = assert_clean(exc, named)
        assert lines == scenario.problems(doc)
    else:
        assert not invalid, f"accepted an invalid scenario: {doc}"


@settings(
    max_examples=6,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    name=st.sampled_from(PST_NAMES),
    factors=st.dictionaries(
        st.sampled_from(["slope_deg", "density", "youngs_modulus", "tau_peak", "softening"]),
        st.floats(0.9, 1.1),
        max_size=2,
    ),
)
def test_valid_mutations_run_without_nan(name, factors):
    doc = raw(name)
    params = doc.setdefault("params", {})
    for key, f in factors.items():
        params[key] = float(params.get(key, getattr(PSTParams(), key))) * f
    doc["setup"] = {**doc.get("setup", {}), **TINY_SETUP}
    if not doc["setup"].get("controlled"):
        params["steady_length"] = min(float(params.get("steady_length", 20.0)), 2.0)
    doc["output"] = {"plot": False, "snapshots": False}
    try:
        scn = scenario.parse(doc, warn=False)
    except ValueError as exc:
        assert_clean(exc)
        assume(False)
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        outcome = runner.run(scn, Path(tmp) / "out")
        assert (Path(tmp) / "out" / runner.RESULTS).is_file()
    r = outcome.result
    assert r.fault is None
    for arr in (r.sigma_xx, r.height, r.slip, r.u_max, r.tip):
        assert np.all(np.isfinite(arr))


def test_200_invalid_scenarios_through_the_cli(tmp_path, capsys):
    rng = random.Random(20261122)
    out = tmp_path / "out"
    for i in range(200):
        doc = raw(PST_NAMES[i % len(PST_NAMES)])
        for _ in range(rng.randint(0, 2)):
            neutral_mutation(doc, lambda n: rng.randrange(n), lambda: rng.uniform(-3, 3))
        named = invalid_mutation(doc, lambda n: rng.randrange(n), lambda: rng.random() < 0.5)
        # datetimes cannot be written back by scenario.dumps's TOML writer: use a string
        for table in [doc] + [v for v in doc.values() if isinstance(v, dict)]:
            for k, v in table.items():
                if isinstance(v, datetime.date):
                    table[k] = "2020-01-01"
        path = tmp_path / f"s{i}.toml"
        path.write_text(scenario.dumps(doc))
        problems = scenario.problems(tomllib.loads(path.read_text()))
        rc = main(["run", str(path), "--out", str(out), "--quiet"])
        err = capsys.readouterr().err
        assert rc == 2, (i, doc)
        assert "Traceback" not in err
        lines = err.strip().splitlines()
        assert len(lines) == len(problems) >= 1
        assert all(line.startswith(f"damjax: error: s{i}.toml: ") for line in lines)
        assert named in err
    assert not out.exists()  # nothing ran, nothing was written


def test_array_valued_params_fields_take_numbers_or_arrays():
    """A PSTParams field whose default is not a float (e.g. a strength profile, None by
    default) takes a number or a rectangular TOML array of numbers."""

    class WithProfile(PSTParams):
        strength_profile: object = None

    problems: list[str] = []
    table = {"strength_profile": [[0.0, 1000.0], [5.0, 2000.0]], "density": 250}
    vals, _, _ = schema._check_section("params", table, WithProfile, problems)
    assert not problems
    assert vals["strength_profile"].shape == (2, 2) and vals["density"] == 250.0
    for wrong in (["a"], [1, [2]], [], "x", True, [math.nan], {"a": 1}):
        problems = []
        schema._check_section("params", {"strength_profile": wrong}, WithProfile, problems)
        assert len(problems) == 1, wrong
        assert problems[0].startswith("params.strength_profile = "), problems
        assert "a number or an array of numbers" in problems[0]
    # and back to TOML
    text = scenario.dumps({"params": {"strength_profile": np.array([[0.0, 1.0], [2.0, np.inf]])}})
    assert tomllib.loads(text)["params"]["strength_profile"] == [[0.0, 1.0], [2.0, math.inf]]


def test_a_written_slope_scenario_reads_back_without_warnings():
    """`to_toml` writes every field, the PST-only defaults included: not "given" then."""
    import warnings as _w

    scn = scenario.load("slope-quick").replace(setup={"duration": 1.0})
    with _w.catch_warnings(record=True) as caught:
        _w.simplefilter("always")
        back = scenario.loads(scenario.dumps(scn))
    assert [str(w.message) for w in caught] == []
    assert back.to_toml() == scn.to_toml()
    text = scn.to_toml().replace("steady_length = 20.0", "steady_length = 5.0")
    with pytest.warns(
        UserWarning, match="params.steady_length: a PST's, ignored by slope scenarios"
    ):
        scenario.loads(text)


@pytest.mark.parametrize("key", ["slope_profile", "strength_profile"])
def test_a_pst_profile_on_a_slope_is_said_not_a_crash(key):
    scn = scenario.load("slope-quick")
    with pytest.warns(UserWarning, match=f"params.{key}: a PST's, ignored by slope scenarios"):
        back = scn.replace(params={key: [10.0, 80.0]})
    assert back.setup == scn.setup


@pytest.mark.parametrize("name", ["quick", "slope-quick"])
def test_a_section_that_is_no_table_is_one_line(name):
    import tomllib

    data = tomllib.loads(scenario.resolve(name).read_text())
    data["params"] = 3
    with pytest.raises(ValueError) as exc:
        scenario.parse(data)
    assert str(exc.value) == "params = 3: must be a table ([params])"
