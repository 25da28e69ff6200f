"""Strength profiles from CSV files (CLI flag and scenario table) and the in-situ presets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from damjax import fields, runner, scenario
from damjax.cli import main

GOOD = "x_m,tau_peak_pa\n0,1000\n20,1000\n100,13000\n"
BAD_CSV = [
    ("unsorted", "x_m,tau_peak_pa\n0,1000\n30,1000\n20,3000\n", ":4: column 'x_m' (1): unsorted"),
    ("duplicate", "x_m,tau_peak_pa\n0,1000\n20,1000\n20,3000\n", ":4: column 'x_m' (1): duplicate"),
    ("missing", "x_m,tau_peak_pa\n0,1000\n20,\n30,3000\n", ":3: column 'tau_peak_pa' (2): missing"),
    (
        "negative",
        "x_m,tau_peak_pa\n0,1000\n20,-5\n30,3000\n",
        ":3: column 'tau_peak_pa' (2): negative",
    ),
    ("no_column", "x_m,tau\n0,1000\n20,1200\n", "header has no column 'tau_peak_pa'"),
]
SMALL = ["--length", "10", "--dx", "0.05", "--duration", "0.02", "--quiet"]


@pytest.mark.parametrize("kind,body,needle", BAD_CSV, ids=[b[0] for b in BAD_CSV])
def test_cli_strength_profile_errors(tmp_path, capsys, kind, body, needle):
    path = tmp_path / f"{kind}.csv"
    path.write_text(body)
    assert main(["pst", "--strength-profile", str(path), *SMALL]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"damjax: error: --strength-profile {path}"), err
    assert needle in err[0], err


def test_cli_strength_profile_missing_file(tmp_path, capsys):
    assert main(["pst", "--strength-profile", str(tmp_path / "nope.csv"), *SMALL]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such file" in err[0], err


def test_cli_strength_profile_runs(tmp_path, capsys):
    path = tmp_path / "ok.csv"
    path.write_text(GOOD)
    assert main(["pst", "--strength-profile", str(path), *SMALL, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["fault"] is None


def test_pst_strength_profile_modes(tmp_path):
    path = tmp_path / "t.csv"
    s = np.arange(0.0, 25.0, 1.0)
    path.write_text("x_m,tau_peak_pa\n" + "\n".join(f"{a},{1500 + 30 * a}" for a in s))
    raw = fields.pst_strength_profile(path, 24.0, 25)
    np.testing.assert_allclose(raw, 1500 + 30 * s)
    lin = fields.pst_strength_profile(path, 40.0, 41, fit="linear", steady_length=10.0)
    xs = np.linspace(0, 40, 41)
    np.testing.assert_allclose(lin, 1000 + 30 * np.maximum(xs - 10, 0), rtol=1e-9)
    with pytest.raises(ValueError, match="fit 'cubic'"):
        fields.pst_strength_profile(path, 40.0, 41, fit="cubic")


PRESETS = {
    "plastic-theta30": dict(strength_gradient=30.0, tensile_strength=6000.0, softening=0.0),
    "plastic-theta150": dict(strength_gradient=150.0, tensile_strength=6000.0, softening=0.0),
    "insitu-jim-bay-corner": dict(
        strength_gradient=15.0, tensile_strength=6000.0, softening=1.0, steady_length=20.0
    ),
    "insitu-arete-de-roc": dict(tensile_strength=6000.0, softening=1.0, steady_length=20.0),
}


@pytest.mark.parametrize("name", list(PRESETS))
def test_presets_validate(name):
    assert name in scenario.shipped()
    scn = scenario.load(name)
    assert scn.name == name and scn.setup.length == 100.0 and scn.setup.dx == 0.02
    for key, value in PRESETS[name].items():
        assert float(getattr(scn.params, key)) == value, key


def test_arete_de_roc_profile_is_a_shifted_power_law():
    scn = scenario.load("insitu-arete-de-roc")
    prof = np.asarray(scn.params.strength_profile)
    x = np.linspace(0.0, scn.setup.length, prof.size)
    assert prof.size == round(scn.setup.length / scn.setup.dx) + 1
    np.testing.assert_allclose(prof[x <= 20.0], 1000.0)
    assert np.all(np.diff(prof) >= 0) and prof[-1] > 5000.0
    s = x[x > 20.0] - 20.0
    inc = prof[x > 20.0] - 1000.0
    b = np.polyfit(np.log(s[s > 1]), np.log(inc[s > 1]), 1)[0]
    assert 2.0 < b < 3.5  # a power law, not linear
    again = scenario.loads(scn.to_toml())  # the array replaces the file on writing
    np.testing.assert_allclose(again.params.strength_profile, prof)


def test_preset_runs_by_name_through_the_api(tmp_path):
    scn = scenario.load("insitu-arete-de-roc").replace(
        setup={"length": 10.0, "dx": 0.05, "duration": 0.02}, output={"plot": False}
    )
    out = runner.run(scn, tmp_path / "run")
    assert out.fault is None and (tmp_path / "run" / "summary.json").is_file()


def _write(tmp_path, strength: str) -> str:
    (tmp_path / "p.csv").write_text(GOOD)
    text = f'type = "pst"\nname = "s"\n[setup]\nlength = 100.0\ndx = 0.05\n{strength}'
    path = tmp_path / "s.toml"
    path.write_text(text)
    return str(path)


def test_scenario_strength_table(tmp_path):
    scn = scenario.load(_write(tmp_path, '[strength]\nfile = "p.csv"\n'))
    prof = np.asarray(scn.params.strength_profile)
    assert prof.size == 2001 and prof[0] == 1000.0 and prof[-1] == 13000.0


@pytest.mark.parametrize(
    "strength,needle",
    [
        ('[strength]\nfile = "nope.csv"\n', 'strength.file = "nope.csv": no such file'),
        ('[strength]\nfile = "p.csv"\nfit = "cubic"\n', 'strength.fit = "cubic": must be one of'),
        ('[strength]\nfile = "p.csv"\nfitt = "linear"\n', "strength.fitt: unknown key"),
        ('[strength]\nfit = "linear"\n', "strength.file: missing"),
        ('[strength]\nfile = "p.csv"\npoints = 1\n', "strength.points = 1: must be an integer"),
        (
            '[params]\nstrength_profile = [2000.0, 3000.0]\n[strength]\nfile = "p.csv"\n',
            "strength: give either",
        ),
    ],
)
def test_scenario_strength_table_errors(tmp_path, strength, needle):
    with pytest.raises(ValueError) as exc:
        scenario.load(_write(tmp_path, strength))
    assert any(needle in line for line in str(exc.value).splitlines()), str(exc.value)


def test_scenario_strength_csv_problem_is_one_line(tmp_path):
    path = _write(tmp_path, '[strength]\nfile = "bad.csv"\n')
    (tmp_path / "bad.csv").write_text("x_m,tau_peak_pa\n0,1000\n20,-1\n")
    with pytest.raises(ValueError) as exc:
        scenario.load(path)
    lines = str(exc.value).splitlines()
    assert len(lines) == 1 and "negative value -1" in lines[0], lines


def test_cli_run_reports_strength_problem(tmp_path, capsys):
    path = _write(tmp_path, '[strength]\nfile = "bad.csv"\n')
    (tmp_path / "bad.csv").write_text("x_m,tau_peak_pa\n0,1000\n0,1200\n")
    assert main(["run", path, "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "duplicate x_m 0" in err[0], err


def test_csv_with_a_byte_order_mark_reads_like_plain_utf8(tmp_path):
    """Excel's "CSV UTF-8" starts the file with a byte-order mark; the header is the same."""
    plain, bom = tmp_path / "plain.csv", tmp_path / "bom.csv"
    plain.write_text(GOOD, encoding="utf-8")
    bom.write_text(GOOD, encoding="utf-8-sig")
    assert bom.read_bytes().startswith(b"\xef\xbb\xbf")
    np.testing.assert_array_equal(
        fields.pst_strength_profile(bom, 100.0, 11), fields.pst_strength_profile(plain, 100.0, 11)
    )
