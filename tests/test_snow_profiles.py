"""Snow profiles in: a SnowPilot CAAML pit and a SNOWPACK .pro file -> slab parameters."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from damjax import snow_profiles as sp
from damjax import theory

DATA = Path(__file__).parent / "data" / "profiles"
CAAML = DATA / "snowpilot-21449.caaml.xml"
PRO = DATA / "sarp-example.pro"

# the pit's density samples (depth of the 4 cm cutter's top [cm], rho [kg/m^3]), as in
# the file (checked by eye against its <caaml:densityProfile>)
PIT_DENSITY = [
    (0, 164), (10, 184), (20, 200), (30, 204), (40, 216), (50, 268), (60, 280), (70, 276),
    (80, 292), (90, 304), (100, 324), (110, 308), (120, 328), (130, 312), (140, 336),
    (150, 324),
]  # fmt: skip


def test_modulus_relations_at_250():
    """E(250 kg/m^3) of each relation against its formula evaluated by hand."""
    assert sp.youngs_modulus(250.0, "scapozza") == pytest.approx(6.448e6, rel=1e-3)
    assert sp.youngs_modulus(250.0, "gerling") == pytest.approx(64.37e6, rel=1e-3)
    assert sp.youngs_modulus(250.0, "bergfeld") == pytest.approx(21.38e6, rel=1e-3)
    with pytest.raises(ValueError, match="relation = 'x'"):
        sp.youngs_modulus(250.0, "x")
    with pytest.raises(ValueError, match="density = "):
        sp.youngs_modulus(-1.0)
    with pytest.warns(UserWarning, match="extrapolated"):
        sp.youngs_modulus(60.0)


def test_modulus_relations_match_weac():
    tools = pytest.importorskip("weac.tools")
    rho = np.array([150.0, 250.0, 350.0])
    np.testing.assert_allclose(
        sp.youngs_modulus(rho, "scapozza"), tools.scapozza(rho) * 1e6, rtol=1e-12
    )
    np.testing.assert_allclose(sp.youngs_modulus(rho, "gerling"), tools.gerling(rho) * 1e6)
    np.testing.assert_allclose(sp.youngs_modulus(rho, "bergfeld"), tools.bergfeld(rho) * 1e6)


@pytest.mark.parametrize(
    ("code", "index"),
    [("F", 1.0), ("4F+", 2 + 1 / 3), ("1F-", 3 - 1 / 3), ("K", 5.0), ("1F-P", 3.5)],
)
def test_hardness_index(code, index):
    assert sp.hardness_index(code) == pytest.approx(index)
    assert math.isnan(sp.hardness_index("Q"))


def test_caaml_pit_reads_layers_density_and_tests():
    pytest.importorskip("snowpylot")
    prof = sp.read_profile(CAAML)
    assert len(prof.layers) == 9
    assert prof.concern == 4  # the observer's layer of concern (FC, 90-115 cm)
    assert prof.slope_deg == 33.0
    assert prof.layers[4].top == pytest.approx(0.90)
    assert prof.layers[4].grain == "FC" and prof.layers[4].hardness == "4F"
    assert prof.density_samples.shape == (16, 3)
    assert prof.pst[0]["cut_length_m"] == pytest.approx(0.35)
    assert "layer of concern" in prof.table()


def test_caaml_slab_above_the_layer_of_concern():
    pytest.importorskip("snowpylot")
    prof = sp.read_profile(CAAML)
    slab = prof.slab()
    assert slab.weak_layer == 4 and slab.thickness == pytest.approx(0.90)
    # exact mean of the piecewise-linear density through the samples' mid-depths (2, 12,
    # ... cm; constant above the first) over 0-90 cm
    mids = np.array([d + 2.0 for d, _ in PIT_DENSITY]) / 100
    rho = np.array([r for _, r in PIT_DENSITY], dtype=float)
    z = np.concatenate([[0.0], mids[mids < 0.9], [0.9]])
    r = np.interp(z, mids, rho)
    exact = float(np.sum(0.5 * (r[1:] + r[:-1]) * np.diff(z)) / 0.9)
    assert slab.density == pytest.approx(exact, rel=1e-4)
    # E is the mean of E(rho(z)), above E(mean rho) (E is convex in rho)
    assert slab.youngs_modulus > sp.youngs_modulus(slab.density)
    params = sp.pst_params(CAAML)
    assert float(params.thickness) == pytest.approx(0.90)
    assert float(params.slope_deg) == 33.0
    assert float(params.density) == pytest.approx(slab.density)
    assert float(params.youngs_modulus) == pytest.approx(slab.youngs_modulus)
    vert = sp.pst_params(CAAML, vertical=True, tau_peak=1500.0)
    assert float(vert.thickness) == pytest.approx(0.90 * math.cos(math.radians(33.0)))
    assert float(vert.tau_peak) == 1500.0


@pytest.mark.parametrize("bad", [0, 9, -1, 2.5, "4", True])
def test_weak_layer_out_of_range_is_a_one_line_error(bad):
    pytest.importorskip("snowpylot")
    with pytest.raises(ValueError, match=r"weak_layer = .*: must be an integer in \[1, 8\]"):
        sp.pst_params(CAAML, weak_layer=bad)


def test_pro_last_profile_and_slab():
    prof = sp.read_profile(PRO)
    assert prof.date.isoformat() == "2017-11-14T12:00:00"
    assert len(prof.layers) == 18
    assert prof.layers[-1].bottom == pytest.approx(0.2161)  # HS = 21.61 cm
    crust = prof.layers[6]  # the 722 (MF) element at 16.16-16.92 cm height
    assert crust.grain == "MF" and crust.hardness_index == 5.0
    assert crust.top == pytest.approx(0.2161 - 0.1692) and crust.density == 206.6
    # weak layer: the new-snow element below the crust (15.59-16.16 cm height)
    slab = prof.slab(7)
    heights = np.array([16.16, 16.92, 18.91, 19.49, 19.99, 20.49, 21.03, 21.61]) / 100
    rho = np.array([206.6, 80.9, 79.9, 82.5, 82.5, 83.6, 85.1])
    assert slab.thickness == pytest.approx(0.2161 - 0.1616)
    assert slab.density == pytest.approx(np.sum(rho * np.diff(heights)) / 0.0545, rel=1e-9)
    assert slab.wl_shear_strength == pytest.approx(250.0)  # 0601: 0.25 kPa
    assert slab.wl_critical_cut_length == pytest.approx(3.0)  # 0606 (SNOWPACK's value)
    with pytest.warns(UserWarning, match="extrapolated"):
        params = sp.pst_params(PRO, weak_layer=7, slope_deg=38.0)
    assert float(params.tau_peak) == pytest.approx(250.0)
    assert float(params.slope_deg) == 38.0


def test_pro_date_selection_and_errors(tmp_path):
    assert len(sp.read_profile(PRO, date="2017-11-13T18:00").layers) == 12
    with pytest.raises(ValueError, match="before the first profile"):
        sp.read_profile(PRO, date="2017-01-01")
    with pytest.raises(FileNotFoundError, match="no such file"):
        sp.read_profile(tmp_path / "none.pro")
    bad = tmp_path / "bad.pro"
    bad.write_text("[STATION_PARAMETERS]\nStationName= x\n")
    with pytest.raises(ValueError, match="not a SNOWPACK .pro file"):
        sp.read_profile(bad)
    with pytest.raises(ValueError, match="unknown profile format"):
        sp.read_profile(tmp_path / "x.txt")
    prof = sp.read_profile(PRO)
    with pytest.raises(ValueError, match=r"no layer of concern.*\[1, 17\]"):
        prof.slab()


GOOD_PRO = """[STATION_PARAMETERS]
StationName= t
SlopeAngle= 38

[HEADER]
0500,Date

[DATA]
0500,10.02.2024 12:00:00
0501,5,20,40,50,60,80
0502,5,300,280,150,220,120
0513,6,440,440,550,330,220,0
0534,5,-3,-3,-1,-2,-1
0601,5,2.0,1.8,0.9,1.2,0.5
"""


@pytest.mark.parametrize(
    "line, bad, match",
    [
        (
            "0501,5,20,40,50,60,80",
            "0501,5,20,40,60,80",
            "code 0501: its count says 5 values, the line holds 4",
        ),
        (
            "0502,5,300,280,150,220,120",
            "0502,5,300,280,150,220",
            "code 0502: its count says 5 values, the line holds 4",
        ),
        (
            "0502,5,300,280,150,220,120",
            "0502,4,300,280,150,220",
            r"code 0502: 4 values for 5 elements \(0501\), 5 of them snow",
        ),
        (
            "0501,5,20,40,50,60,80",
            "0501,5,20,50,40,60,80",
            "heights must rise from the ground up; element 3 \\(40 cm\\) is not above element 2",
        ),
    ],
)
def test_pro_lines_that_do_not_fit_are_errors(tmp_path, line, bad, match):
    """A data line whose values do not match its count or the elements shifted every
    value to another layer (a 4-value density line: the top layer read 220 kg/m^3, not
    120), and unsorted heights gave a layer of negative thickness; both ran on."""
    path = tmp_path / "p.pro"
    path.write_text(GOOD_PRO)
    assert len(sp.read_profile(path).layers) == 5
    path.write_text(GOOD_PRO.replace(line, bad))
    with pytest.raises(ValueError, match=match):
        sp.read_profile(path)


def test_a_profile_s_bad_density_and_a_caaml_date_are_one_line(tmp_path):
    path = tmp_path / "p.pro"
    path.write_text(GOOD_PRO.replace("300,280,150,220,120", "300,280,150,-220,120"))
    with pytest.raises(ValueError, match=r"layer 1 \(20.0-30.0 cm\) has density -220 kg/m\^3"):
        sp.read_profile(path).slab(2)
    with pytest.raises(ValueError, match="a CAAML file holds one profile: leave the date out"):
        sp.read_profile(CAAML, date="2020-01-28")


SNOWPAT_DUMP = """
import json, sys
import snowpat.snowpackreader as spr
reader = spr.readPRO(sys.argv[1])
out = []
for when, pack in zip(reader.get_all_dates(), reader.get_all_profiles()):
    out.append({"date": when.isoformat(),
                **{c: pack.get_param(c).tolist() for c in ("0501", "0502", "0601")}})
print(json.dumps(out))
"""


def _snowpat_profiles() -> list[dict]:
    """snowpat's SnowpackReader on the example file: here if snowpat imports, else in the
    environment of DAMJAX_AVAFRAME_PYTHON (snowpat pins numpy < 2, which jax cannot use)."""
    try:
        import snowpat.snowpackreader  # noqa: F401

        exe = sys.executable
    except ImportError:
        exe = os.environ.get("DAMJAX_AVAFRAME_PYTHON")
        if not exe or not shutil.which(exe):
            pytest.skip("snowpat not importable (set DAMJAX_AVAFRAME_PYTHON to a python with it)")
    proc = subprocess.run([exe, "-c", SNOWPAT_DUMP, str(PRO)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_pro_reader_matches_snowpat():
    """The built-in reader against snowpat's SnowpackReader on every profile of the file."""
    packs = _snowpat_profiles()
    assert len(packs) == 3
    for pack in packs:
        ours = sp.read_pro(PRO, date=pack["date"])
        assert ours.date.isoformat() == pack["date"]
        b = np.asarray(pack["0501"])
        assert len(ours.layers) == b.size - 1
        tops = np.array([ly.top for ly in ours.layers])[::-1]
        np.testing.assert_allclose(tops, (b[-1] - b[1:]) / 100, atol=1e-12)
        dens = np.array([ly.density for ly in ours.layers])[::-1]
        np.testing.assert_allclose(dens, pack["0502"])
        st = np.array([ly.shear_strength for ly in ours.layers])[::-1]
        np.testing.assert_allclose(st, np.asarray(pack["0601"]) * 1e3)


# --------------------------------------------------------------------------- CLI, scenarios

# one small PST for every run below (one compilation): 2 m, dx 1 cm (the .pro slab's
# Lambda is 6.5 cm), 0.2 s
RUN_FLAGS = ["--length", "2", "--dx", "0.01", "--duration", "0.2", "--steady-length", "1"]


def _cli(capsys, *argv: str) -> tuple[int, str, str]:
    from damjax import cli

    rc = cli.main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def _same_cut_length(summary, params):
    """The summary's a_c is the bar model's for these params: None where it says no cut
    starts a crack (these slabs, with L_ss 1 m and theta 500 Pa/m above theta_run)."""
    a_c = float(theory.pst_critical_cut_length(params))
    if math.isinf(a_c):
        assert summary["critical_cut_length_theory_m"] is None
        assert float(theory.critical_cut_length(params)) > float(params.steady_length)
        assert float(params.strength_gradient) >= float(theory.runaway_gradient(params))
    else:
        assert summary["critical_cut_length_theory_m"] == pytest.approx(a_c, rel=1e-6)


@pytest.mark.parametrize(
    ("path", "extra", "expect"),
    [
        # the CAAML pit has no strength: tau_peak from the command line (tau_g 1136 Pa)
        (CAAML, ["--tau-peak", "2000"], {"thickness": 0.9, "slope_deg": 33.0}),
        # the .pro slab above element 7; its 0601 strength; --slope-deg given wins
        (PRO, ["--weak-layer", "7", "--slope-deg", "38"], {"tau_peak": 250.0, "slope_deg": 38}),
    ],
    ids=["caaml", "pro"],
)
def test_cli_pst_runs_a_profile(capsys, path, extra, expect):
    if path == CAAML:
        pytest.importorskip("snowpylot")
    rc, out, err = _cli(capsys, "pst", "--profile", str(path), *extra, *RUN_FLAGS, "--json")
    assert rc == 0, err
    summary = json.loads(out)
    kw = {"slope_deg": 38.0} if path == PRO else {"tau_peak": 2000.0}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the .pro slab's densities: checked in err below
        params = sp.pst_params(path, 7 if path == PRO else None, steady_length=1.0, **kw)
    for name, value in expect.items():
        assert float(getattr(params, name)) == pytest.approx(value)
    # the run used the profile's slab: its wave speed, runaway gradient and theoretical
    # a_c are those of params (thickness, density, E, slope and tau_peak all enter them)
    assert summary["shear_wave_speed_m_per_s"] == pytest.approx(
        float(theory.shear_wave_speed(params)), rel=1e-6
    )
    assert summary["runaway_gradient_pa_per_m"] == pytest.approx(
        float(theory.runaway_gradient(params)), rel=1e-6
    )
    _same_cut_length(summary, params)
    assert summary["n_steps"] > 0 and summary["fault"] is None
    assert f"damjax: profile {path}: thickness = " in err
    if path == PRO:
        assert "slope_deg" not in err.splitlines()[0]  # given on the command line
        assert "extrapolated" in err


def test_cli_profile_errors_are_one_line(capsys, tmp_path):
    rc, _, err = _cli(capsys, "pst", "--weak-layer", "3")
    assert rc == 2 and err.strip() == "damjax: error: --weak-layer 3: needs --profile FILE"
    rc, _, err = _cli(capsys, "pst", "--profile", str(PRO), "--weak-layer", "40")
    assert rc == 2 and "--weak-layer 40: must be an integer in [1, 17]" in err
    assert len(err.strip().splitlines()) == 1
    rc, _, err = _cli(capsys, "pst", "--profile", str(tmp_path / "none.pro"))
    assert rc == 2 and "--profile" in err and "no such file" in err
    rc, _, err = _cli(capsys, "pst", "--profile", str(PRO), "--weak-layer", "x")
    assert rc == 2 and "'x' is not a layer index" in err


SCENARIO = """
type = "pst"
name = "profile-test"

[params]
steady_length = 1.0
slope_deg = 38.0

[setup]
length = 2.0
dx = 0.01
duration = 0.2

[profile]
file = "{file}"
weak_layer = 7
date = "2017-11-14T12:00"

[output]
plot = false
snapshots = false
"""


def test_scenario_profile_table(tmp_path, capsys):
    from damjax import scenario

    shutil.copy(PRO, tmp_path / "station.pro")
    path = tmp_path / "scn.toml"
    path.write_text(SCENARIO.format(file="station.pro"))  # relative to the scenario file
    with pytest.warns(scenario.ScenarioWarning, match="profile.file = .*extrapolated"):
        scn = scenario.load(path)
    with pytest.warns(UserWarning):
        want = sp.pst_params(PRO, 7, slope_deg=38.0, steady_length=1.0)
    for name in ("thickness", "density", "youngs_modulus", "tau_peak"):
        assert float(getattr(scn.params, name)) == pytest.approx(float(getattr(want, name)))
    assert float(scn.params.slope_deg) == 38.0  # [params] wins over the profile
    # the resolved scenario is self-contained: its TOML has the values, not the table
    again = scenario.loads(scn.to_toml())
    assert float(again.params.thickness) == pytest.approx(float(want.thickness))
    # bad tables: one line per key, naming it
    bad = SCENARIO.format(file="station.pro").replace("weak_layer = 7", "weak_layer = 99")
    bad = bad.replace('date = "2017-11-14T12:00"', 'modulus = "x"\nvertikal = true')
    with pytest.raises(ValueError) as exc:
        scenario.loads(bad, base_dir=tmp_path)
    msg = str(exc.value)
    assert "profile.modulus = 'x'" in msg or 'profile.modulus = "x"' in msg
    assert "profile.vertikal: unknown key (did you mean 'profile.vertical'?)" in msg
    bad = SCENARIO.format(file="station.pro").replace("weak_layer = 7", "weak_layer = 99")
    with pytest.raises(ValueError, match=r"profile.weak_layer = 99: must be an integer in \[1, "):
        scenario.loads(bad, base_dir=tmp_path)
    with pytest.raises(ValueError, match="profile.file = .*no such file"):
        scenario.loads(SCENARIO.format(file="none.pro"), base_dir=tmp_path)
    slope = 'type = "slope"\nname = "s"\n[profile]\nfile = "x.pro"\n'
    with pytest.raises(ValueError, match='profile: only for type = "pst"'):
        scenario.loads(slope)
    # and it runs from the CLI
    rc, out, err = _cli(capsys, "run", str(path), "--out", str(tmp_path / "run"), "--json")
    assert rc == 0, err
    _same_cut_length(json.loads(out), scn.params)


def test_caaml_layers_with_a_gap_an_overlap_or_below_hs_are_warned():
    """Layers that do not tile the column (a typo in a depth, a thickness in m among cm)
    were read silently; the slab above a weak layer absorbs them."""
    sp._warn_layer_gaps("p", [(0.0, 0.27), (0.27, 0.5)], 0.5)  # tiles the column: quiet
    cases = [
        (
            [(0.0, 0.27), (0.28, 0.5)],
            0.5,
            "layer 0 ends at 27 cm depth, layer 1 starts at 28 cm (a gap)",
        ),
        ([(0.0, 0.27), (0.2, 0.5)], 0.5, "layer 1 starts at 20 cm (an overlap)"),
        ([(0.0, 0.27), (0.27, 27.0)], 0.5, "reach 2700 cm depth, below the snow height hs = 50 cm"),
    ]
    for spans, hs, match in cases:
        with pytest.warns(UserWarning, match=re.escape(match)):
            sp._warn_layer_gaps("p", spans, hs)
