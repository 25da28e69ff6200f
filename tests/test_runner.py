"""`damjax run` / `resume` / `show`: outputs, checkpoints, restarts, runtime faults.

A run interrupted at any moment (SIGKILL, SIGINT, an exception between chunks) and
resumed from its checkpoint must give the results of an uninterrupted run: an identical
results.nc (`xarray.Dataset.identical`) and a bitwise-equal final state.
"""

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import damjax
from damjax import io, runner, scenario
from damjax.cli import main

# 10 m, dx 0.05 m, 3 s in chunks of 100 steps: ~160 chunks, about a second of stepping
RESTART_TOML = """
type = "pst"
name = "restart"
description = "small PST for the restart tests"

[params]
steady_length = 4.0
strength_gradient = 3000.0

[setup]
length = 10.0
dx = 0.05
duration = 3.0
chunk_steps = 100

[output]
plot = false
"""


@pytest.fixture(scope="module")
def scn_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("scn") / "restart.toml"
    path.write_text(RESTART_TOML)
    return path


# the signal tests' run: about 5 s of stepping on a 2-core CPU (the short one above steps
# its 3 s in 0.7 s, within the random delay after a checkpoint: the signal could come after
# the run had finished)
LONG_TOML = RESTART_TOML.replace("duration = 3.0", "duration = 20.0").replace(
    "chunk_steps = 100", "chunk_steps = 1000"
)


@pytest.fixture(scope="module")
def long_scn_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("scn") / "restart-long.toml"
    path.write_text(LONG_TOML)
    return path


@pytest.fixture(scope="module")
def env(tmp_path_factory) -> dict:
    """Subprocess environment: a private persistent compilation cache; no preallocation of
    an accelerator's memory (two runs at once share one GPU; no effect on a CPU)."""
    cache = tmp_path_factory.mktemp("xla-cache")
    return {
        **os.environ,
        "DAMJAX_CACHE_DIR": str(cache),
        "PYTHONUNBUFFERED": "1",
        "XLA_PYTHON_CLIENT_PREALLOCATE": "false",
    }


def assert_same_run(ref: Path, other: Path) -> None:
    a = io.open_dataset(ref / runner.RESULTS)
    b = io.open_dataset(other / runner.RESULTS)
    assert a.identical(b)
    sa, sb = io.read_npz(ref / runner.FINAL_STATE), io.read_npz(other / runner.FINAL_STATE)
    assert list(sa) == list(sb)
    for key in sa:
        assert sa[key].dtype == sb[key].dtype, key
        assert sa[key].tobytes() == sb[key].tobytes(), key  # bitwise
    assert not (other / runner.CHECKPOINT).exists()


def cli(*args: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "damjax", *args], capture_output=True, text=True, env=env
    )


# --------------------------------------------------------------------------- outputs


@pytest.mark.min_versions
def test_run_writes_outputs_and_show_replots(tmp_path, scn_file, capsys):
    text = RESTART_TOML.replace("duration = 3.0", "duration = 0.5").replace(
        "plot = false", "plot = true"
    )
    path = tmp_path / "s.toml"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["scenario"] == "restart" and summary["fault"] is None
    assert summary["out_dir"] == str(out) and "wall_time_s" in summary
    assert summary["files"]["results"] == str(out / runner.RESULTS)  # as the text lists them
    for name in (runner.RESULTS, runner.SUMMARY, runner.PLOT, runner.FINAL_STATE):
        assert (out / name).is_file(), name
    assert not (out / runner.CHECKPOINT).exists()

    ds = io.open_dataset(out / runner.RESULTS)
    assert ds.attrs["damjax_version"] == damjax.__version__
    scn = scenario.loads(ds.attrs["scenario"], warn=False)
    assert scn.to_toml() == scenario.loads(text).to_toml()  # the full scenario
    stored = json.loads(ds.attrs["summary"])
    assert not set(runner.TIMING_KEYS) & set(stored)  # no wall-clock in the NetCDF
    for name in ("crack_tip", "crack_speed"):
        assert ds[name].dims == ("time",)
    for name in ("sigma_xx", "height", "slip", "u_max", "tau_peak"):
        assert ds[name].dims == ("x",)
    assert ds["snapshot_sigma_xx"].dims == ("chunk", "x")
    for name, var in ds.variables.items():
        assert var.attrs["units"] and var.attrs["long_name"], name
    assert ds["x"].attrs["units"] == "m" and ds["sigma_xx"].attrs["units"] == "Pa"

    png = tmp_path / "again.png"
    assert main(["show", str(out), "--plot", str(png)]) == 0
    shown = capsys.readouterr().out
    assert "arrest_position_m" in shown and str(png) in shown
    assert png.stat().st_size > 10_000
    assert main(["show", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["scenario"] == "restart"

    assert main(["show", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nothing: no such folder" in err[0]
    (tmp_path / "empty").mkdir()
    assert main(["show", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no results.nc" in err[0]
    assert main(["resume", str(out)]) == 2  # finished: nothing to resume
    assert "no checkpoint.npz" in capsys.readouterr().err


def test_run_by_shipped_name_and_bad_arguments(tmp_path, capsys):
    assert main(["run", "quik", "--out", str(tmp_path)]) == 2
    assert "did you mean 'quick'" in capsys.readouterr().err
    (tmp_path / "scenarios").mkdir()
    (tmp_path / "scenarios" / "mine.toml").write_text('type = "pst"\n')
    assert main(["run", str(tmp_path / "scenarios")]) == 2  # a folder: which file
    assert "a folder; give a scenario file (a .toml) (it holds mine.toml)" in (
        capsys.readouterr().err
    )
    assert main(["run", "quick", "--checkpoint-every", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--checkpoint-every" in err and len(err.strip().splitlines()) == 1
    for every in (-1.0, "x", float("nan")):  # the API checks what the CLI's flag does
        with pytest.raises(ValueError, match="checkpoint_every = .*: must be None"):
            runner.run("quick", tmp_path / "q", checkpoint_every=every)
    with pytest.raises(ValueError, match="no such folder"):
        runner.resume(tmp_path / "never-ran")
    ens = tmp_path / "ens.toml"  # an ensemble scenario: one line naming the command to use
    ens.write_text('type = "slope"\nname = "e"\n[ensemble]\nmembers = 3\n')
    assert main(["run", str(ens), "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "damjax ensemble" in err[0] and "[ensemble]" in err[0]


# --------------------------------------------------------------------------- restart


@pytest.mark.min_versions
def test_interrupted_in_process_and_resumed(tmp_path, scn_file):
    scn = scenario.load(scn_file)
    ref = runner.run(scn, tmp_path / "ref")

    def stop_after(k):
        def hook(chunk):
            if chunk == k:
                raise KeyboardInterrupt

        return hook

    # no checkpointing asked: an interrupt leaves nothing to resume
    with pytest.raises(KeyboardInterrupt):
        runner.run(scn, tmp_path / "none", on_chunk=stop_after(5))
    assert not (tmp_path / "none" / runner.CHECKPOINT).exists()

    # a long interval: only the interrupt writes the checkpoint (after chunk 40)
    out = tmp_path / "int"
    with pytest.raises(KeyboardInterrupt):
        runner.run(scn, out, checkpoint_every=1e9, on_chunk=stop_after(40))
    ck = io.read_npz(out / runner.CHECKPOINT)
    assert int(ck["chunk"]) == 41 and ck["tips"].shape == (41, 100)
    assert str(ck["scenario"]) == scn.to_toml()
    assert not (out / runner.RESULTS).exists()
    # a new run into that folder would delete the checkpoint: refused, resume named
    with pytest.raises(
        ValueError, match="holds an unfinished run's checkpoint.npz; `damjax resume"
    ):
        runner.run(scn, out)
    assert (out / runner.CHECKPOINT).exists()
    # ... and the scenario edited since: said, since `resume` would run the old one
    edited = scenario.loads(scn.to_toml().replace("duration = 3.0", "duration = 2.0"))
    with pytest.raises(ValueError, match="holds an unfinished run of another scenario"):
        runner.run(edited, out)
    # resume of a file or of a folder that never held a checkpoint: what to do instead
    with pytest.raises(ValueError, match="a file; give the folder of the run"):
        runner.resume(ref.out_dir / runner.RESULTS)
    with pytest.raises(ValueError, match="only with --checkpoint-every"):
        runner.resume(tmp_path / "none")
    # a finished run of another scenario in the folder: replaced, with a warning
    other = tmp_path / "other"
    other.mkdir()
    (other / runner.RESULTS).write_bytes((ref.out_dir / runner.RESULTS).read_bytes())
    with pytest.warns(UserWarning, match="held a finished run of scenario 'restart' with other"):
        runner.run(edited, other)
    # ... but kept when the new run stops before writing its own (Ctrl-C while it
    # compiled, in its first chunks without checkpoints): the folder lost a finished run
    names = [n for n in runner.OUTPUTS if (ref.out_dir / n).exists()]
    finished = {n: (ref.out_dir / n).read_bytes() for n in names}
    kept = tmp_path / "kept"
    kept.mkdir()
    for n, data in finished.items():
        (kept / n).write_bytes(data)
    with pytest.warns(UserWarning, match="once it writes its own"):
        with pytest.raises(KeyboardInterrupt):
            runner.run(edited, kept, on_chunk=stop_after(2))
    assert {n: (kept / n).read_bytes() for n in names} == finished and len(names) >= 3
    assert not (kept / runner.REPLACED).exists()

    # resume, interrupt again (every chunk checkpointed now), resume to the end
    with pytest.raises(KeyboardInterrupt):
        runner.resume(out, checkpoint_every=0, on_chunk=stop_after(77))
    assert int(io.read_npz(out / runner.CHECKPOINT)["chunk"]) == 78
    done = runner.resume(out)
    assert done.resumed_from_chunk == 78
    assert done.summary["resumed_from_chunk"] == 78
    # the throughput counts the steps timed: those after the restart
    s = done.summary
    timed = s["n_steps"] - 78 * 100
    assert s["particle_steps_per_s"] == pytest.approx(
        s["n_particles"] * timed / s["wall_time_s"], rel=1e-6
    )
    assert_same_run(ref.out_dir, out)
    final = runner.load_final_state(out)
    assert float(final.time) == pytest.approx(scn.setup.duration, rel=1e-3)  # float32 sum
    # a state saved before State.opening_y existed loads with it zero
    arrays = io.read_npz(out / runner.FINAL_STATE)
    del arrays["state.opening_y"]
    io.write_npz(out / runner.FINAL_STATE, arrays)
    old = runner.load_final_state(out)
    assert np.all(np.asarray(old.opening_y) == 0.0)
    np.testing.assert_array_equal(np.asarray(old.opening), np.asarray(final.opening))


def _start(env: dict, *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "damjax", *args, "--quiet"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        # a pytest-xdist worker ignores SIGINT and a child inherits that: give the run
        # Python's own Ctrl-C back, as a shell would
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def _signal_after_checkpoint(proc: subprocess.Popen, ck: Path, sig: int) -> tuple[int, str]:
    """Wait for a new checkpoint, then send ``sig`` at a random moment (the run still has
    seconds of stepping left then); returns (exit status, stderr)."""
    before = ck.stat().st_mtime_ns if ck.exists() else None
    deadline = time.monotonic() + 120
    while not ck.exists() or ck.stat().st_mtime_ns == before:
        if proc.poll() is not None:
            break
        assert time.monotonic() < deadline, "no checkpoint written"
        time.sleep(0.01)
    time.sleep(random.uniform(0.0, 0.6))
    if proc.poll() is None:
        proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err


def test_killed_runs_resume_identically(tmp_path, long_scn_file, env):
    """SIGINT a run, SIGKILL its resumption, resume again: identical to an uninterrupted
    run (computed at the same time in another process)."""
    ref, out = tmp_path / "ref", tmp_path / "run"
    ref_proc = _start(env, "run", str(long_scn_file), "--out", str(ref))
    ck = out / runner.CHECKPOINT
    proc = _start(env, "run", str(long_scn_file), "--out", str(out), "--checkpoint-every", "0")
    rc, err = _signal_after_checkpoint(proc, ck, signal.SIGINT)
    assert rc == 130 and f"damjax resume {out}" in err and "Traceback" not in err, err
    chunk = int(io.read_npz(ck)["chunk"])
    assert chunk >= 1

    proc = _start(env, "resume", str(out), "--checkpoint-every", "0")
    rc, err = _signal_after_checkpoint(proc, ck, signal.SIGKILL)
    assert rc == -signal.SIGKILL, err
    assert int(io.read_npz(ck)["chunk"]) > chunk  # the resumed run had moved on

    res = cli("resume", str(out), "--quiet", "--json", env=env)
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["resumed_from_chunk"] > chunk
    assert ref_proc.wait(timeout=120) == 0, ref_proc.stderr.read()
    assert_same_run(ref, out)


def test_sigterm_writes_the_checkpoint_and_exits_143(tmp_path, long_scn_file, env):
    """`kill` (a batch scheduler's time limit) is an interrupt: the checkpoint of the last
    completed chunk is written and the resume command named; status 128 + 15."""
    out = tmp_path / "run"
    ck = out / runner.CHECKPOINT
    proc = _start(env, "run", str(long_scn_file), "--out", str(out), "--checkpoint-every", "0")
    rc, err = _signal_after_checkpoint(proc, ck, signal.SIGTERM)
    assert rc == 143 and f"damjax resume {out}" in err and "Traceback" not in err, err
    assert int(io.read_npz(ck)["chunk"]) >= 1


# --------------------------------------------------------------------------- faults


def test_fault_is_reported_with_time_and_results_are_kept(tmp_path, scn_file, monkeypatch, capsys):
    """A NaN velocity injected into a checkpoint: the resumed run faults mid-run."""
    scn = scenario.load(scn_file)
    out = tmp_path / "run"

    def stop(chunk):
        if chunk == 9:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        runner.run(scn, out, checkpoint_every=1e9, on_chunk=stop)
    ck = io.read_npz(out / runner.CHECKPOINT)
    ck["state.v"] = np.full_like(ck["state.v"], np.nan)
    io.write_npz(out / runner.CHECKPOINT, ck)

    rc = main(["resume", str(out), "--quiet", "--json"])
    captured = capsys.readouterr()
    assert rc == 3
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in captured.err
    assert err[0].startswith("damjax: run stopped at t = ") and "non-finite velocity" in err[0]
    t_fault = float(err[0].split("t = ")[1].split()[0])
    summary = json.loads(captured.out)
    assert summary["fault"] == err[0][len("damjax: ") :]
    ds = io.open_dataset(out / runner.RESULTS)
    assert ds.attrs["fault"].startswith("run stopped at t = ")
    assert ds.sizes["time"] == 10 * 100  # the history up to the fault
    assert float(ds["time"][-1]) < t_fault
    assert np.all(np.isfinite(ds["crack_tip"].values))
    assert not (out / runner.CHECKPOINT).exists()


def test_run_cli_fault_exits_nonzero(tmp_path, scn_file, monkeypatch, capsys):
    """`damjax run` of a state that is broken from the start: exit 3, results written."""
    from damjax import pst

    build = pst.build

    def broken_build(*args, **kwargs):
        model, state = build(*args, **kwargs)
        return model, eqx.tree_at(lambda s: s.v, state, state.v + jnp.nan)

    monkeypatch.setattr(pst, "build", broken_build)
    out = tmp_path / "out"
    rc = main(["run", str(scn_file), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 3
    assert "damjax: run stopped at t = " in err and "Traceback" not in err
    assert (out / runner.RESULTS).is_file() and (out / runner.SUMMARY).is_file()
    assert json.loads((out / runner.SUMMARY).read_text())["fault"].startswith("run stopped")


def test_damaged_or_unfinished_folders_give_one_line_errors(tmp_path, capsys):
    """A truncated or foreign checkpoint, an empty or foreign results.nc and a folder of
    an unfinished run: one line naming the file (status 2), no traceback."""
    import numpy as np

    d = tmp_path / "d"
    d.mkdir()
    np.savez(tmp_path / "full.npz", a=np.zeros(100_000))
    cases = [
        ("checkpoint.npz", b"hello", ["resume"], "checkpoint.npz: not an .npz archive"),
        (
            "checkpoint.npz",
            (tmp_path / "full.npz").read_bytes()[:1000],
            ["resume"],
            "checkpoint.npz: damaged .npz archive",
        ),
        ("results.nc", b"", ["show"], "results.nc: not a readable NetCDF file"),
        ("results.nc", b"text\n", ["show"], "results.nc: not a readable NetCDF file"),
    ]
    for name, data, cmd, needle in cases:
        for f in d.iterdir():
            f.unlink()
        (d / name).write_bytes(data)
        assert main([*cmd, str(d)]) == 2, (name, data[:10])
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err
    for f in d.iterdir():
        f.unlink()
    (d / "checkpoint.npz").write_bytes(b"PK")  # an unfinished run's folder
    assert main(["show", str(d)]) == 2
    assert "an unfinished run" in capsys.readouterr().err


def test_a_resume_refuses_inputs_that_changed_or_went(tmp_path):
    """A checkpoint keeps the sha256 of each file its scenario reads (a DEM, a polygon
    with its sidecar files, rasters): a resume after one changed would mix two terrains."""

    class Scn:  # the part of a Scenario that input_files reads
        def __init__(self, d):
            self.d = d

        def to_dict(self):
            return self.d

    dem, shp, dbf = tmp_path / "dem.asc", tmp_path / "rel.shp", tmp_path / "rel.dbf"
    for f in (dem, shp, dbf):
        f.write_text(f.name)
    scn = Scn({"terrain": {"kind": "dem", "file": str(dem), "release": str(shp)}, "x": "dem.asc"})
    assert runner.input_files(scn) == sorted([dem, shp, dbf])  # relative strings: not files
    ck = {"inputs": np.array(json.dumps(runner.input_digests(scn)))}
    path = tmp_path / runner.CHECKPOINT
    runner._check_inputs(path, ck)  # unchanged: nothing to say
    dbf.write_text("thickness 2 m")
    with pytest.raises(ValueError, match=r"rel\.dbf: changed since the run was checkpointed"):
        runner._check_inputs(path, ck)
    dbf.write_text("rel.dbf")
    dem.unlink()
    with pytest.raises(ValueError, match=r"dem\.asc: read by the checkpointed run, no longer"):
        runner._check_inputs(path, ck)
    runner._check_inputs(path, {})  # a checkpoint written before the digests: not checked


def test_a_folder_in_use_by_a_run_is_refused_naming_the_holder(tmp_path, scn_file):
    """`run` and `resume` hold the folder's lock file (as ensembles do): a second one into
    the same folder stops at once, naming the holder, and writes nothing."""
    out = tmp_path / "busy"
    out.mkdir()
    (out / runner.CHECKPOINT).write_bytes(b"PK")  # the running one's checkpoint
    held, _ = io.lock_folder(out, runner.LOCK_FILE, "damjax run")  # another open file
    try:
        for call in (lambda: runner.run(scenario.load(scn_file), out), lambda: runner.resume(out)):
            with pytest.raises(ValueError, match=r"in use by another damjax run \(pid "):
                call()
    finally:
        io.unlock_folder(out, runner.LOCK_FILE, held)
    assert [p.name for p in out.iterdir()] == [runner.CHECKPOINT]


def test_an_interrupt_while_writing_the_outputs_keeps_the_earlier_run(
    tmp_path, scn_file, monkeypatch, capsys
):
    """Ctrl-C after results.nc but before summary.json (written last): the earlier run's
    files come back whole, not mixed with a part of this run's, and the CLI says which;
    without an earlier run the line says the folder holds a part of this one."""
    out = tmp_path / "run"
    assert main(["run", str(scn_file), "--out", str(out), "--quiet"]) == 0
    before = {n: (out / n).read_bytes() for n in runner.OUTPUTS if (out / n).exists()}
    assert runner.SUMMARY in before

    def interrupted(*_a, **_k):
        raise KeyboardInterrupt

    monkeypatch.setattr(io, "write_json", interrupted)
    edited = scn_file.parent / "edited.toml"
    edited.write_text(scn_file.read_text().replace("duration = 3.0", "duration = 2.0"))
    capsys.readouterr()
    assert main(["run", str(edited), "--out", str(out), "--quiet"]) == 130
    assert "keeps the earlier run's results" in capsys.readouterr().err
    assert {n: (out / n).read_bytes() for n in before} == before  # whole, and the same
    assert not (out / runner.REPLACED).exists()
    fresh = tmp_path / "fresh run"
    assert main(["run", str(edited), "--out", str(fresh), "--quiet"]) == 130
    err = capsys.readouterr().err
    assert "holds part of this run's outputs (it stopped writing them): run it again" in err


def test_a_full_disk_is_one_line_naming_the_file(tmp_path, scn_file, monkeypatch, capsys):
    """No space for results.nc: one line naming the file, exit 1, no temporary file or
    lock left (the NetCDF is made in memory, so HDF5 never closes a half-written file)."""
    import errno

    def full(self, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Path, "write_bytes", full)
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["run", str(scn_file), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"damjax: error: cannot write {out / runner.RESULTS}: No space left")
    assert "[Errno" not in err and len(err.splitlines()) == 1
    assert sorted(p.name for p in out.iterdir()) == []


def test_the_resume_hint_is_quoted_for_the_shell(tmp_path, capsys):
    from damjax import cli

    out = tmp_path / "out int"
    out.mkdir()
    (out / runner.CHECKPOINT).write_bytes(b"")
    assert cli._interrupted(out) == 130
    assert f"damjax resume '{out}'" in capsys.readouterr().err
