"""Slope ensembles (`damjax.ensemble`) and multi-process runs (`damjax.distributed`).

One tiny slope (8 m x 4 m, dx 0.2 m, 0.3 s, a GRF weak layer with a start window) is run
as a 3-member ensemble in slices of 2: its members equal the same seeds run one by one,
a run killed after its first slice and resumed writes the same ``ensemble.nc``, and two
processes (`jax.distributed` on localhost, CPU) give the same ensemble as one; in the
same two-process job the PST sweep (`distributed.sweep`) equals the one-process sweep.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from damjax import distributed, ensemble, io

TINY = """
type = "slope"
name = "ens-tiny"
[params]
slope_deg = 35.0
[setup]
length = 8.0
width = 4.0
dx = 0.2
duration = 0.3
particles_per_cell = 1
chunk_steps = 50
[terrain]
kind = "plane"
[strength]
kind = "grf"
mean = 1000.0
trend = 150.0
std = 150.0
length_scale = 2.0
seed = 0
start_window = [1.5, 3.0]
[output]
plot = false
[ensemble]
members = 3
slice_size = 2
"""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("ens") / "tiny.toml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def full_run(tiny, tmp_path_factory):
    out = tmp_path_factory.mktemp("ens-full")
    ens = ensemble.load(tiny)
    ds = ensemble.run(ens, out, plot=True)
    return ens, out, ds


def _doc(extra: str) -> str:
    return TINY.replace("[ensemble]\nmembers = 3\nslice_size = 2\n", extra)


# --------------------------------------------------------------------------- the table


@pytest.mark.parametrize(
    ("table", "needle"),
    [
        (
            "[ensemble]\nmembrs = 3\n",
            "ensemble.membrs: unknown key (did you mean 'ensemble.members'?)",
        ),
        ("[ensemble]\nmembers = 0\n", "ensemble.members = 0: must be an integer >= 1"),
        ("[ensemble]\nseeds = [1, -2]\n", "ensemble.seeds = [1, -2]: must be a list of integers"),
        (
            '[ensemble.params.softening]\ndist = "beta"\n',
            'ensemble.params.softening.dist = "beta": must be one of',
        ),
        (
            '[ensemble.params.softening]\ndist = "normal"\nmean = 1.0\n',
            "ensemble.params.softening.std: missing",
        ),
        (
            '[ensemble.params.softening]\ndist = "uniform"\nlow = 2.0\nhigh = 1.0\n',
            "ensemble.params.softening.high = 1: must be > ensemble.params.softening.low = 2",
        ),
        (
            '[ensemble.params.softening]\ndist = "normal"\nmean = 1.0\nstd = 0.1\n'
            "bounds = [2.0, 1.0]\n",
            "ensemble.params.softening.bounds = [2.0, 1.0]: must be [low, high] with low < high",
        ),
        (
            '[ensemble]\nmembers = 50\n[ensemble.params.poisson]\ndist = "normal"\n'
            "mean = 0.3\nstd = 0.3\n",
            "ensemble.params.poisson: member 1 draws 0.667542: must be in (0, 0.5) (give",
        ),
        (
            '[ensemble.params.steady_length]\ndist = "uniform"\nlow = 1.0\nhigh = 2.0\n',
            "ensemble.params.steady_length: cannot be drawn",
        ),
        (
            '[ensemble.strength.seed]\ndist = "uniform"\nlow = 1.0\nhigh = 2.0\n',
            'ensemble.strength.seed: cannot be drawn (strength.kind = "grf" draws: mean',
        ),
        ("[ensemble]\nseeds = [1, 2]\nmembers = 3\n", "ensemble.seeds: 2 seeds for 3 members"),
        (
            "[ensemble]\nseeds = [4, 7, 4, 9]\nmembers = 3\n",
            "ensemble.seeds: members 0 and 2 share seed 4: their strength fields",
        ),
    ],
)
def test_bad_ensemble_tables_give_one_line_errors(tmp_path, table, needle):
    path = tmp_path / "bad.toml"
    path.write_text(_doc(table))
    with pytest.raises(ValueError) as exc:
        ensemble.load(path)
    assert needle in str(exc.value)
    assert "Traceback" not in str(exc.value)


def test_identical_members_are_an_error(tmp_path):
    doc = _doc("[ensemble]\nmembers = 2\n").replace('kind = "grf"', 'kind = "constant"')
    for key in ("mean", "std", "length_scale", "seed"):
        doc = "\n".join(line for line in doc.splitlines() if not line.startswith(key + " "))
    path = tmp_path / "const.toml"
    path.write_text(doc.replace("trend = 150.0", "trend = 150.0\ntau_peak = 1000.0"))
    with pytest.raises(ValueError, match="the members would be identical"):
        ensemble.load(path)


def test_member_draws_are_per_member_and_follow_their_distributions(tiny):
    scn = ensemble.load(tiny).scenario
    table = {
        "params": {
            "softening": {"dist": "uniform", "low": 0.5, "high": 1.5},
            "tensile_strength": {
                "dist": "lognormal",
                "mean": 4000.0,
                "std": 800.0,
                "bounds": [3000.0, 6000.0],
            },
        },
        "strength": {"trend": {"dist": "normal", "mean": 150.0, "std": 10.0}},
    }
    small = ensemble.from_scenario(scn, table, members=4)
    big = ensemble.from_scenario(scn, table, members=200)
    for i in range(4):  # member i does not depend on N
        assert ensemble.member_draws(small, i) == ensemble.member_draws(big, i)
    p = np.array([ensemble.member_draws(big, i)[0]["tensile_strength"] for i in range(200)])
    s = np.array([ensemble.member_draws(big, i)[0]["softening"] for i in range(200)])
    t = np.array([ensemble.member_draws(big, i)[1]["trend"] for i in range(200)])
    assert p.min() >= 3000.0 and p.max() <= 6000.0
    assert 0.5 <= s.min() and s.max() <= 1.5 and abs(s.mean() - 1.0) < 0.05
    assert abs(t.mean() - 150.0) < 2.0 and abs(t.std() - 10.0) < 1.5
    m = ensemble.member_scenario(big, 7)
    assert m.strength["seed"] == 7 and m.strength["trend"] == t[7]
    assert m.params.softening == s[7]
    # an unbounded lognormal has the stated mean and std
    d = ensemble.Distribution("lognormal", mean=4000.0, std=800.0)
    u = (np.arange(20000) + 0.5) / 20000
    v = np.array([d.ppf(x) for x in u])
    assert abs(v.mean() / 4000.0 - 1) < 2e-3 and abs(v.std() / 800.0 - 1) < 2e-2


def test_crack_band_members_draw_their_own_slab_strength_field(tiny):
    import dataclasses

    scn = ensemble.load(tiny).scenario
    paper = ensemble.from_scenario(scn, {}, members=3)
    assert {ensemble.member_scenario(paper, i).setup.seed for i in range(3)} == {scn.setup.seed}
    setup = dataclasses.replace(scn.setup, slab_fracture="crack_band")
    band = dataclasses.replace(scn, setup=setup)
    ens = ensemble.from_scenario(band, {}, members=3)
    seeds = [ensemble.member_scenario(ens, i).setup.seed for i in range(3)]
    assert seeds == [scn.setup.seed + i for i in range(3)]


# --------------------------------------------------------------------------- runs


def test_members_equal_the_same_seeds_run_one_by_one(full_run):
    from damjax.scenario import slope_fields

    ens, out, ds = full_run
    assert ds.sizes["member"] == 3
    assert list(ds["seed"].values) == [0, 1, 2]
    for i in range(3):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = slope_fields.simulate(ensemble.member_scenario(ens, i))
        at = np.where(np.isfinite(r.arrival_time), r.arrival_time, np.nan)
        np.testing.assert_allclose(ds["arrival_time"].values[i], at, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(ds["released"].values[i], np.isfinite(r.arrival_time))
        np.testing.assert_allclose(ds["height"].values[i], r.height, rtol=1e-6)
        for key in ("release_area_m2", "upslope_extent_m", "crossslope_extent_m"):
            assert float(ds[key].values[i]) == pytest.approx(r.summary[key], rel=1e-6), key
        for key in ("upslope_front", "crossslope_front"):
            assert str(ds[key].values[i]) == r.summary[key], key
        arrest = r.summary["upslope_arrest_distance_m"]
        got = float(ds["upslope_arrest_distance_m"].values[i])
        assert (np.isnan(got) and arrest is None) or got == pytest.approx(arrest), arrest
        assert [float(ds["start_x"][i]), float(ds["start_y"][i])] == r.summary["start_m"]
        # the terrain's maps, once for all members
        np.testing.assert_array_equal(ds["snow"].values, r.snow)
        np.testing.assert_allclose(ds["slope_angle"].values, r.slope_deg, rtol=1e-6)
    # the products
    prob = ds["released"].values.mean(axis=0)
    np.testing.assert_allclose(ds["release_probability"].values, prob, rtol=1e-6)
    assert 0 < prob.max() <= 1 and prob.min() == 0
    q = np.quantile(ds["release_area_m2"].values, ensemble.QUANTILES)
    np.testing.assert_allclose(ds["release_area_m2_quantiles"].values, q)
    assert (out / ensemble.FIGURE).is_file() and (out / ensemble.SUMMARY_FILE).is_file()
    assert sorted(p.name for p in (out / ensemble.SLICE_DIR).iterdir()) == [
        "members_00000-00002.nc",
        "members_00002-00003.nc",
    ]


def test_killed_ensemble_resumes_to_the_same_file(full_run, tmp_path):
    ens, out, _ = full_run
    cut = tmp_path / "cut"

    def kill(a: int, b: int) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        ensemble.run(ens, cut, plot=False, on_slice=kill)
    assert not (cut / ensemble.ENSEMBLE_FILE).exists()
    lines: list[str] = []
    ensemble.run(ens, cut, plot=False, log=lines.append)
    assert any("resuming: 2 of 3 members done, 1 to run" in line for line in lines)
    a = io.open_dataset(out / ensemble.ENSEMBLE_FILE)
    b = io.open_dataset(cut / ensemble.ENSEMBLE_FILE)
    assert a.identical(b)
    # the folder belongs to its ensemble
    other = ensemble.from_scenario(
        ens.scenario.replace(strength={"std": 120.0}), {"slice_size": 2}, members=3
    )
    with pytest.raises(ValueError, match="holds an ensemble of another scenario"):
        ensemble.run(other, cut, plot=False)


def test_a_grown_ensemble_runs_only_its_new_members(full_run, tmp_path):
    """3 members in slices of 2, then 4: the new plan's slice 2-3 holds a finished member
    (2); only member 3 runs, and every member is in the file once."""
    import shutil

    ens, out, ds = full_run
    grown = tmp_path / "grown"
    shutil.copytree(out, grown)
    bigger = ensemble.from_scenario(ens.scenario, {"slice_size": 2}, members=4)
    lines: list[str] = []
    ds4 = ensemble.run(bigger, grown, plot=False, log=lines.append)
    assert any("resuming: 3 of 4 members done, 1 to run" in line for line in lines), lines
    assert ds4["member"].values.tolist() == [0, 1, 2, 3]
    np.testing.assert_array_equal(ds4["released"].values[:3], ds["released"].values)
    assert "members_00003-00004.nc" in {p.name for p in (grown / ensemble.SLICE_DIR).iterdir()}


@pytest.mark.min_versions
def test_ensembles_repeat_bit_for_bit_on_two_host_devices(tiny, tmp_path):
    """The same ensemble run twice by separate processes on a CPU host split into 2
    devices writes the same ensemble.nc, bit for bit, and each member is its single run
    (the strength fields were drawn with XLA's FFT, which on such a host rounded
    differently while other work ran: tau_peak differed by a float32 step in 2 runs of 2,
    2026-11-27)."""
    code = textwrap.dedent(
        f"""
        import sys
        from damjax.ensemble import main
        sys.exit(main([{str(tiny)!r}, "--out", sys.argv[1], "--quiet", "--json"]))
        """
    )
    env = {
        **os.environ,
        "XLA_FLAGS": "--xla_force_host_platform_device_count=2",
        "JAX_PLATFORMS": "cpu",
    }
    for name in ("a", "b"):
        done = subprocess.run(
            [sys.executable, "-c", code, str(tmp_path / name)],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert done.returncode == 0, done.stderr[-2000:]
    a = io.open_dataset(tmp_path / "a" / ensemble.ENSEMBLE_FILE)
    b = io.open_dataset(tmp_path / "b" / ensemble.ENSEMBLE_FILE)
    assert json.loads(a.attrs["layout"]) == json.loads(b.attrs["layout"])
    assert a.identical(b)
    from damjax.scenario import slope_fields

    ens = ensemble.load(tiny)
    for i in range(ens.members):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = slope_fields.simulate(ensemble.member_scenario(ens, i))
        # the member's input is the single run's, bit for bit; its results come from
        # another compiled program (vmapped, sharded): equal bit for bit with jax 0.10.2,
        # within 2 float32 steps in a few cells with jax 0.8.0 (2026-11-27)
        np.testing.assert_array_equal(a["tau_peak"].values[i], r.tau_peak.astype(np.float32))
        at = np.where(np.isfinite(r.arrival_time), r.arrival_time, np.nan).astype(np.float32)
        np.testing.assert_array_max_ulp(a["arrival_time"].values[i], at, maxulp=4)
        np.testing.assert_array_max_ulp(a["height"].values[i], r.height.astype(np.float32), 4)


def test_a_second_run_into_a_folder_in_use_is_refused(tiny, tmp_path):
    """A run holds the folder's lock file: a second run into it stops at once, naming the
    holder; a lock file left by a process that is gone is taken over."""
    from damjax.ensemble import batch

    out = tmp_path / "busy"
    out.mkdir()
    held, left = io.lock_folder(out, batch.LOCK_FILE, "damjax ensemble")
    assert left is None
    try:
        text = (out / batch.LOCK_FILE).read_text()
        assert f"pid {os.getpid()} on " in text
        # another process (the lock is per open file: a second open in this process
        # would not conflict with flock, so ask a child)
        code = textwrap.dedent(
            f"""
            import sys
            from damjax.ensemble import main
            sys.exit(main([{str(tiny)!r}, "--out", {str(out)!r}, "--quiet"]))
            """
        )
        done = subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, timeout=300
        )
        assert done.returncode == 2, done.stderr
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1, lines
        assert lines[0].startswith(f"damjax: error: {out}: in use by another damjax ensemble")
        assert f"pid {os.getpid()} on " in lines[0] and "give another --out" in lines[0]
        assert not (out / "plan.json").exists()  # it touched nothing
    finally:
        io.unlock_folder(out, batch.LOCK_FILE, held)
    assert not (out / batch.LOCK_FILE).exists()
    # a killed run's lock file: its process is gone, so the next run takes it over
    (out / batch.LOCK_FILE).write_text("pid 999999 on elsewhere, started 2026-11-27 00:00:00\n")
    lines: list[str] = []
    ds = ensemble.run(ensemble.load(tiny), out, plot=False, log=lines.append)
    assert ds.sizes["member"] == 3
    assert any("took over the lock" in ln and "pid 999999" in ln for ln in lines), lines
    assert not (out / batch.LOCK_FILE).exists()


def _port() -> int:
    """A free TCP port on localhost (skip where the loopback cannot be bound)."""
    try:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            return int(s.getsockname()[1])
    except OSError as exc:  # pragma: no cover - sandboxes without a loopback
        pytest.skip(f"cannot bind a localhost port for the coordinator: {exc}")


def _launch(code: str, folder: Path, n: int = 2, timeout: float = 300) -> list[str]:
    """Run ``python -c CODE`` as n processes (DAMJAX_TEST_PORT: a free port for the
    coordinator, DAMJAX_TEST_PID: the process id, with the parent's damjax and JAX
    platform); their
    stdout (each must exit 0). Output goes to files: a process blocked on a full pipe
    would hold the others at a barrier. When one process fails, or the time is up, the
    others are killed at once."""
    import jax

    import damjax

    port = _port()
    root = str(Path(damjax.__file__).parent.parent)  # the damjax this test imported
    path = os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])])
    # the device's platform ("cpu", "cuda", "rocm"): jax.default_backend() says "gpu" on
    # both GPU kinds, and JAX_PLATFORMS=gpu makes JAX look for ROCm beside CUDA
    platform = jax.devices()[0].platform
    env = {
        **os.environ,
        "DAMJAX_TEST_PORT": str(port),
        "JAX_PLATFORMS": platform,
        "PYTHONPATH": path,
    }
    if platform != "cpu":
        # n processes on one accelerator: none may take 75 % of its memory up front
        env["XLA_PYTHON_CLIENT_PREALLOCATE"] = "false"
    procs, files = [], []
    for i in range(n):
        out = open(folder / f"proc{i}.out", "w+")  # noqa: SIM115
        err = open(folder / f"proc{i}.err", "w+")  # noqa: SIM115
        procs.append(
            subprocess.Popen(
                [sys.executable, "-c", code],
                stdout=out,
                stderr=err,
                env={**env, "DAMJAX_TEST_PID": str(i)},
                cwd=folder,
            )
        )
        files.append((out, err))
    try:
        deadline = time.monotonic() + timeout
        while any(p.poll() is None for p in procs):
            failed = [i for i, p in enumerate(procs) if p.poll() not in (None, 0)]
            if failed or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        outs = []
        for i, (p, (out, err)) in enumerate(zip(procs, files, strict=True)):
            out.seek(0)
            err.seek(0)
            text = err.read()[-3000:]
            assert p.poll() is not None, f"process {i} still running after {timeout} s: {text}"
            assert p.returncode == 0, f"process {i} exited {p.returncode}: {text}"
            outs.append(out.read())
    finally:
        for p, (out, err) in zip(procs, files, strict=True):
            if p.poll() is None:
                p.kill()
                p.wait()
            out.close()
            err.close()
    return outs


PST_BATCH = {"strength_gradient": [400.0, 600.0, 800.0], "steady_length": 3.0}
PST_SETUP = {"length": 8.0, "dx": 0.04, "duration": 0.5, "chunk_steps": 500}


def test_two_processes_give_the_one_process_results(full_run, tiny, tmp_path):
    """One two-process job (jax.distributed on localhost, on the test's device): the slope
    ensemble through the command line (``--coordinator``) and then a PST sweep
    (`distributed.sweep`). The processes meet through the coordinator only: JAX's device
    collectives are switched off in them (NCCL refuses two processes on one GPU)."""
    import damjax

    _, out, _ = full_run
    two = tmp_path / "two"
    code = textwrap.dedent(
        f"""
        import json, os, sys
        import numpy as np
        import damjax
        from damjax import distributed
        from damjax.ensemble import main
        from jax.experimental import multihost_utils

        def no_device_collectives(*args, **kwargs):
            raise RuntimeError("a device collective was called")

        multihost_utils.process_allgather = no_device_collectives
        multihost_utils.sync_global_devices = no_device_collectives
        rc = main([{str(tiny)!r}, "--out", {str(two)!r}, "--json", "--quiet",
                   "--coordinator", "127.0.0.1:" + os.environ["DAMJAX_TEST_PORT"],
                   "--num-processes", "2", "--process-id", os.environ["DAMJAX_TEST_PID"]])
        if rc:
            sys.exit(rc)
        batch = damjax.PSTParams(strength_gradient=np.array({PST_BATCH["strength_gradient"]}),
                                 steady_length={PST_BATCH["steady_length"]})
        res = distributed.sweep(batch, damjax.PSTSetup(**{PST_SETUP!r}))
        print("PST " + json.dumps([r.tip.tolist() for r in res]))
        """
    )
    outs = _launch(code, tmp_path)
    # the ensemble: the same file as one process; the summary line from process 0 only
    line = [ln for ln in outs[0].splitlines() if ln.startswith("{")]
    assert len(line) == 1
    summary = json.loads(line[0])
    assert summary["members"] == 3
    assert set(summary["release_area_m2_quantiles"]) == {"q05", "q50", "q95"}
    assert set(summary["upslope_arrest_distance_m_quantiles"]) == {"q05", "q50", "q95"}
    assert set(summary["upslope_extent_m_quantiles"]) == {"q05", "q50", "q95"}
    assert 0 <= summary["upslope_arrested_members"] <= 3
    assert summary["wall_time_s"] > 0
    assert not [ln for ln in outs[1].splitlines() if ln.startswith("{")]
    a = io.open_dataset(out / ensemble.ENSEMBLE_FILE)
    b = io.open_dataset(two / ensemble.ENSEMBLE_FILE)
    assert a.identical(b)
    runs = json.loads((two / ensemble.SUMMARY_FILE).read_text())
    assert runs["processes"] == 2 and runs["members_run_here"] == 2  # slice 0 of 2
    # the PST sweep: every process returns the whole batch, equal to one process's sweep
    batch = damjax.PSTParams(
        strength_gradient=np.array(PST_BATCH["strength_gradient"]),
        steady_length=PST_BATCH["steady_length"],
    )
    setup = damjax.PSTSetup(**PST_SETUP)
    one = damjax.sweep(batch, setup)
    # each process runs its share as a smaller batch: another compiled program, which a GPU
    # may round differently (fusion, FMA contraction). The tip is the saw coordinate of the
    # furthest broken particle: a round-off difference can at most move one particle's
    # failure by a step, and so a tip sample by one particle spacing
    spacing = setup.dx / setup.particles_per_cell
    for text in outs:
        tips = json.loads([ln for ln in text.splitlines() if ln.startswith("PST ")][-1][4:])
        assert len(tips) == 3
        for t, r in zip(tips, one, strict=True):
            np.testing.assert_allclose(np.asarray(t, np.float32), r.tip, rtol=0, atol=spacing)
    assert one[0].tip[-1] > one[2].tip[-1]  # steeper strength gradient: shorter crack


def test_share_is_round_robin():
    assert distributed.share(range(7), 1, 3) == [1, 4]
    assert distributed.share(range(2), 2, 3) == []
    with pytest.raises(ValueError, match="process_id = 2: must be an integer in"):
        distributed.initialize("127.0.0.1:1", 2, 2)
    with pytest.raises(ValueError, match="give all three"):
        distributed.initialize("127.0.0.1:1")


def test_cli_errors_are_one_line(tiny, capsys):
    import jax

    jax.devices()  # backends started: the command line leaves this process's devices as they are
    assert ensemble.main([str(tiny), "--members", "0"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "damjax: error: --members = 0: must be an integer >= 1"
    assert ensemble.main(["slope-quick", "--members", "2"]) == 2
    assert "the members would be identical" in capsys.readouterr().err
    assert ensemble.main(["quick", "--members", "2"]) == 2
    assert "needs a slope scenario" in capsys.readouterr().err
    # the same command as ``damjax ensemble``
    from damjax import cli

    assert cli.main(["ensemble", str(tiny), "--members", "0", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "damjax: error: --members = 0: must be an integer >= 1"


def test_an_unwritable_output_folder_is_one_line_from_both_commands(tiny, tmp_path, capsys):
    """``python -m damjax.ensemble`` ends as ``damjax ensemble`` does: an output folder
    that cannot be made is one error line and exit code 1, not a traceback."""
    from damjax import cli

    blocker = tmp_path / "a-file"
    blocker.write_text("")
    out = str(blocker / "ens")
    args = [str(tiny), "--members", "2", "--out", out, "--quiet"]
    for main, argv in ((ensemble.main, args), (cli.main, ["ensemble", *args])):
        rc = main(argv)
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 1 and len(err) == 1, err
        assert err[0].startswith("damjax: error: ") and "a-file" in err[0]


def test_every_drawable_setting_has_cf_units():
    """The drawn values in ensemble.nc carry units: every scalar parameter and strength
    setting an [ensemble] table may draw."""
    from damjax.ensemble import products
    from damjax.ensemble.spec import STRENGTH_DRAWS, _scalar_param_fields

    for name in _scalar_param_fields():
        assert products._param_units(name), name
    assert products._param_units("tensile_strength") == "Pa"
    assert products._param_units("strength_gradient") == "Pa m-1"
    for names in STRENGTH_DRAWS.values():
        for name in names:
            assert products._STRENGTH_UNITS.get(name), name


def test_string_states_of_later_slices_keep_their_length(tmp_path):
    """The front states of an ensemble file: a slice read first with shorter strings
    ("moving") must not cut the longer ones of the next ("reached_edge") when the
    concatenation is written."""
    import xarray as xr

    from damjax import io
    from damjax.ensemble.products import drop_string_widths

    parts = []
    for i, state in enumerate(("moving", "reached_edge")):
        io.write_dataset(tmp_path / f"{i}.nc", xr.Dataset({"front": ("member", [state])}))
        parts.append(io.open_dataset(tmp_path / f"{i}.nc"))
    both = drop_string_widths(xr.concat(parts, dim="member"))
    io.write_dataset(tmp_path / "both.nc", both)
    back = io.open_dataset(tmp_path / "both.nc")["front"].values.astype(str).tolist()
    assert back == ["moving", "reached_edge"]


def test_members_warnings_are_said_once_per_kind():
    from damjax.ensemble.batch import _warn_grouped
    from damjax.slope.simulation import SlopeRunWarning

    edge = "simulate_slope: {} % of the released area's boundary lies on the domain's edge"
    rows = [(0, edge.format(50)), (1, edge.format(72.7)), (3, "the crack never ran ahead")]
    with pytest.warns(SlopeRunWarning) as caught:
        _warn_grouped(rows)
    assert [str(w.message) for w in caught] == [
        "2 members (0, 1); member 0: " + edge.format(50),
        "1 member (3); member 3: the crack never ran ahead",
    ]


def test_a_damaged_plan_is_one_line_saying_what_to_do(tiny, tmp_path, capsys):
    """plan.json cut short (a full disk): the file and the remedy, not a bare JSON error."""
    out = tmp_path / "ens"
    out.mkdir()
    (out / "plan.json").write_text('{"slice_')
    assert ensemble.main([str(tiny), "--members", "2", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"damjax: error: {out / 'plan.json'}: unreadable")
    assert "delete it and run again" in err[0]


def test_run_and_ensemble_files_never_share_a_folder(tiny, tmp_path, capsys):
    from damjax import runner, scenario

    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "results.nc").write_bytes(b"")
    assert ensemble.main([str(tiny), "--members", "2", "--out", str(run_dir), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "holds a single run's files (results.nc), not an ensemble's" in err
    assert not (run_dir / "slices").exists()
    ens_dir = tmp_path / "ens"
    (ens_dir / "slices").mkdir(parents=True)
    with pytest.raises(ValueError, match="holds an ensemble's files .* give another --out"):
        runner.run(scenario.load("quick"), ens_dir)
