"""Run a scenario into a folder, checkpoint it on a wall-clock interval, resume it.

A run writes into its output folder (every file atomically, see `damjax.io`):

- ``results.nc``: time series, final fields and snapshots (`damjax.io.result_dataset`),
  with the full scenario (TOML text) and the damjax version as global attributes; no
  wall-clock timings, so an interrupted-and-resumed run gives an identical file;
- ``final_state.npz``: every leaf of the final `State` (``state.u``, ``state.v``, ...);
- ``summary.json``: the diagnostics of `PSTResult.summary` (timings included);
- ``pst.png``: `damjax.plot.plot_pst` (unless ``[output] plot = false``);
- ``checkpoint.npz`` while running with ``checkpoint_every``: all State leaves, the
  per-chunk crack tips and snapshots so far, the number of chunks done and the scenario.
  It is removed once the outputs are written.

Slope scenarios write ``results.nc``, ``summary.json``, ``final_state.npz``,
``slope.png`` and ``release.gif`` instead (`damjax.scenario.slope`), and checkpoint the
same way.

`resume` continues a checkpoint with `simulate_pst(state=..., start_chunk=...,
history=...)`; chunks are the unit of work, so a resumed run repeats at most the chunks
done since the last checkpoint and its results are bitwise those of an uninterrupted run.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import tempfile
import time as _time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from damjax import io, scenario
from damjax.scenario import Scenario

CHECKPOINT = "checkpoint.npz"
RESULTS = "results.nc"
SUMMARY = "summary.json"
PLOT = "pst.png"
FINAL_STATE = "final_state.npz"
OUTPUTS = (RESULTS, SUMMARY, PLOT, FINAL_STATE)
SLOPE_PLOT = "slope.png"  # slope scenarios: maps (h, crown, stauchwall, arrival, speed)
SLOPE_ANIMATION = "release.gif"  # slope scenarios: animation of the release
SLOPE_OUTPUTS = (SLOPE_PLOT, SLOPE_ANIMATION)
CHECKPOINT_FORMAT = "damjax-checkpoint/1"
LOCK_FILE = ".damjax-run.lock"  # held by the run or resume writing into the folder
TIMING_KEYS = io.TIMING_KEYS  # kept out of results.nc (summary.json has them)


@dataclasses.dataclass
class RunOutcome:
    """What a run produced: the scenario, the `PSTResult` and the files written."""

    scenario: Scenario
    result: Any  # PSTResult
    out_dir: Path
    files: dict[str, Path]
    summary: dict[str, Any]
    resumed_from_chunk: int | None = None

    @property
    def fault(self) -> str | None:
        """The runtime fault of the run (one line), None if it ran clean."""
        return getattr(self.result, "fault", None) or self.summary.get("fault")


def _file_attrs(scn: Any, summary: dict[str, Any]) -> dict[str, str]:
    """results.nc's global attributes: CF conventions, the scenario and the summary
    without its timings (a file that does not change between equal runs)."""
    stable = {k: v for k, v in summary.items() if k not in TIMING_KEYS}
    return {
        "Conventions": "CF-1.10",
        "title": f"damjax {scn.type} scenario {scn.name}",
        "source": f"damjax {_version()}",
        "damjax_version": _version(),
        "scenario": scn.to_toml(),
        "summary": io.to_json(stable),
    }


def _read(reader: Any, path: Path, what: str) -> Any:
    """``reader(path)``, a failure to read as one line naming the file (the CLI's error)."""
    try:
        return reader(path)
    except ValueError as exc:  # the reader names the file
        raise ValueError(f"unreadable {what}: {exc}") from None
    except OSError as exc:
        raise ValueError(f"{path}: unreadable {what} ({exc})") from None


def default_out_dir(scn: Scenario) -> Path:
    """``[output] dir`` or ``damjax-out/<name>`` in the working directory."""
    return Path(scn.output.dir) if scn.output.dir else Path("damjax-out") / scn.name


# --------------------------------------------------------------------------- checkpoints


@dataclasses.dataclass
class _Record:
    chunk: int  # chunks done
    fault: int
    state: dict[str, np.ndarray]
    tips: list[np.ndarray]
    snaps: list[dict[str, np.ndarray]]


class _Recorder:
    """The `simulate_pst` callback: keeps a copy of the latest state (the next chunk
    donates its buffers) and writes a checkpoint every ``every`` wall-clock seconds."""

    def __init__(
        self,
        out_dir: Path,
        scn: Scenario,
        n_chunks: int,
        every: float | None,
        on_chunk: Callable[[int], None] | None,
    ) -> None:
        self.out_dir, self.scn, self.n_chunks = out_dir, scn, n_chunks
        self.every, self.on_chunk = every, on_chunk
        self.last: _Record | None = None
        self.inputs: str | None = None  # JSON of input_digests, made at the first save
        self.saved_chunk = -1
        self.t_saved = _time.monotonic()

    def __call__(self, c: int, state: Any, tips: list[Any], snaps: list[Any]) -> None:
        self.last = _Record(
            chunk=c + 1,
            fault=int(state.fault),
            state=io.tree_to_arrays(state, "state"),
            tips=list(tips),
            snaps=list(snaps),
        )
        if self.every is not None and _time.monotonic() - self.t_saved >= self.every:
            self.save()
        if self.on_chunk is not None:
            self.on_chunk(c)

    def save(self) -> bool:
        """Write the latest record if it can be resumed (not faulted, not the end)."""
        rec = self.last
        if rec is None or rec.fault or rec.chunk >= self.n_chunks or rec.chunk == self.saved_chunk:
            return False
        arrays: dict[str, Any] = {
            "format": np.array(CHECKPOINT_FORMAT),
            "damjax_version": np.array(_version()),
            "scenario": np.array(self.scn.to_toml()),
            "chunk": np.array(rec.chunk, np.int64),
            "n_chunks": np.array(self.n_chunks, np.int64),
            "checkpoint_every": np.array(np.nan if self.every is None else self.every),
            "tips": np.stack(rec.tips),
        }
        if self.inputs is None:
            self.inputs = json.dumps(input_digests(self.scn))
        arrays["inputs"] = np.array(self.inputs)
        arrays.update(rec.state)
        if rec.snaps:
            for key in rec.snaps[0]:
                arrays[f"snap.{key}"] = np.stack([np.asarray(s[key]) for s in rec.snaps])
        io.write_npz(self.out_dir / CHECKPOINT, arrays)
        self.saved_chunk = rec.chunk
        self.t_saved = _time.monotonic()
        return True


# a shapefile's attributes, index and projection live beside its .shp
_SIDECARS = {".shp": (".dbf", ".shx", ".prj", ".cpg")}


def input_files(scn: Scenario) -> list[Path]:
    """The files a scenario reads (a DEM, a release polygon with its sidecar files,
    snow rasters, masks, tables): each string of it that is the absolute path of a file
    (a loaded scenario holds its files' paths resolved)."""
    found: list[Path] = []

    def walk(v: Any) -> None:
        if isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, (list, tuple)):
            for x in v:
                walk(x)
        elif isinstance(v, str) and 0 < len(v) < 4096 and os.path.isabs(v):
            p = Path(v)
            if p.is_file():
                found.append(p)
                for ext in _SIDECARS.get(p.suffix.lower(), ()):
                    for side in (p.with_suffix(ext), p.with_suffix(ext.upper())):
                        if side.is_file():  # FOREST.SHP's FOREST.DBF too
                            found.append(side)

    walk(scn.to_dict())
    return sorted(set(found))


def input_digests(scn: Scenario) -> dict[str, str]:
    """``{path: sha256}`` of `input_files`: a checkpoint keeps them, so that a resume
    notices a file that changed (the run would mix two terrains)."""
    return _digests(input_files(scn))


def _check_inputs(path: Path, ck: dict[str, np.ndarray]) -> None:
    """ValueError if a file the checkpointed run read is gone or has changed."""
    if "inputs" not in ck:  # a checkpoint of an earlier version
        return
    recorded = json.loads(str(ck["inputs"]))
    problems = []
    for name, digest in recorded.items():
        f = Path(name)
        if not f.is_file():
            problems.append(f"{name}: read by the checkpointed run, no longer there")
            continue
        now = _digests([f])[name]
        if now != digest:
            problems.append(f"{name}: changed since the run was checkpointed")
    if problems:
        raise ValueError(
            "\n".join(problems)
            + f"\n{path}: a resumed run would mix the old inputs with the new; restore "
            f"them, or start afresh (delete {path} and run the scenario again)"
        )


def _digests(paths: list[Path]) -> dict[str, str]:
    import hashlib

    out = {}
    for p in paths:
        h = hashlib.sha256()
        with open(p, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        out[str(p)] = h.hexdigest()
    return out


def _version() -> str:
    from damjax._version import __version__

    return __version__


def _template(scn: Scenario) -> tuple[Any, Any]:
    """The layout and the initial state of a scenario's checked run (the state's
    structure, to read a saved one back)."""
    prep = scenario.prepared(scn)
    if scn.type == "slope":
        from damjax.slope.simulation import build

        return prep.layout, build(prep)[1]
    from damjax.core.model import build

    return prep.layout, build(prep.params, prep.setup, prep.layout)[1]


# --------------------------------------------------------------------------- running


def run(
    scn: Scenario | str | os.PathLike[str],
    out_dir: str | os.PathLike[str] | None = None,
    *,
    checkpoint_every: float | None = None,
    progress: bool = False,
    on_chunk: Callable[[int], None] | None = None,
) -> RunOutcome:
    """Run a scenario (object, file path or shipped name) and write its outputs.

    Args:
        scn: the scenario; a path or shipped name is loaded with `damjax.scenario.load`.
        out_dir: output folder (default `default_out_dir`); our files in it are replaced.
        checkpoint_every: write ``checkpoint.npz`` when this many wall-clock seconds have
            passed since the last one (0: after every chunk; None: never). An interrupt
            (KeyboardInterrupt) also writes one for the last completed chunk.
        progress: tqdm progress bar (stderr).
        on_chunk: ``on_chunk(chunk_index)`` after each chunk (and its checkpoint); an
            exception raised there aborts the run.

    Returns the `RunOutcome`; a runtime fault is reported in ``outcome.fault`` and the
    outputs hold the run up to it. Invalid scenarios raise ValueError before compiling,
    and so does a folder holding an unfinished run's ``checkpoint.npz`` (`resume`
    continues it; delete the file to start afresh).
    """
    _check_every(checkpoint_every)
    if not isinstance(scn, Scenario):
        scn = scenario.load(scn)
    out = Path(out_dir) if out_dir is not None else default_out_dir(scn)
    _make_out(out)
    with io.folder_lock(out, LOCK_FILE, "damjax run"):
        return _run_locked(scn, out, checkpoint_every, progress, on_chunk)


def _run_locked(
    scn: Scenario,
    out: Path,
    checkpoint_every: float | None,
    progress: bool,
    on_chunk: Callable[[int], None] | None,
) -> RunOutcome:
    from damjax.ensemble.products import ENSEMBLE_FILE, SLICE_DIR

    if (out / ENSEMBLE_FILE).exists() or (out / SLICE_DIR).is_dir():
        raise ValueError(
            f"{out}: holds an ensemble's files ({ENSEMBLE_FILE}, {SLICE_DIR}/), not a single "
            "run's; give another --out"
        )
    if (out / CHECKPOINT).exists():
        other = _checkpointed_scenario(out / CHECKPOINT)
        which = (
            "an unfinished run's"
            if other is None or other == scn.to_toml()
            else "an unfinished run of another scenario (or of this one edited since) in its"
        )
        raise ValueError(
            f"{out}: holds {which} {CHECKPOINT}; `damjax resume {out}` continues that run "
            f"(give another --out, or delete {out / CHECKPOINT} to start this one afresh there)"
        )
    _settle_replaced(out)
    _note_replaced(out, scn)
    io.remove_stale_temporaries(out)
    # never mix the files of two runs: the earlier run's are set aside, deleted once this
    # run has written its own (a checkpoint or its results), and put back if it stops
    # before that (Ctrl-C while compiling, an error), so a finished run is not lost
    _set_aside(out)
    try:
        t0 = _time.perf_counter()
        n_chunks = scenario.prepared(scn).layout.n_chunks  # checked once, when it was read
        rec = _Recorder(out, scn, n_chunks, checkpoint_every, on_chunk)
        if scn.type == "slope":
            outcome = _run_slope(scn, out, rec, progress, None)
        else:
            t1 = _time.perf_counter()
            result = _simulate(scn, rec, progress)
            phases = {"layout_s": t1 - t0, "simulate_s": _time.perf_counter() - t1}
            outcome = _finish(scn, out, result, rec, None, phases)
    finally:
        _settle_replaced(out)
    return outcome


REPLACED = ".damjax-replaced"  # the earlier run's files while a new run replaces them


def _set_aside(out: Path) -> None:
    """Move the earlier run's files of ``out`` into its `REPLACED` folder."""
    names = [n for n in (CHECKPOINT, *OUTPUTS, *SLOPE_OUTPUTS) if (out / n).exists()]
    if not names:
        return
    aside = out / REPLACED
    aside.mkdir(exist_ok=True)
    for name in names:
        os.replace(out / name, aside / name)


def _settle_replaced(out: Path) -> None:
    """The files set aside (`_set_aside`): deleted where a run has written its own into
    ``out`` (a checkpoint, or all its outputs: the summary is written last), else moved
    back over what the run wrote of its outputs (it stopped before that, or was killed
    while writing them: the earlier run's files are what the folder holds)."""
    aside = out / REPLACED
    if not aside.is_dir():
        return
    if not any((out / n).exists() for n in (CHECKPOINT, SUMMARY)):
        for name in (*OUTPUTS, *SLOPE_OUTPUTS):  # a part of this run's: not mixed in
            (out / name).unlink(missing_ok=True)
        for p in aside.iterdir():
            os.replace(p, out / p.name)
    shutil.rmtree(aside, ignore_errors=True)


def _checkpointed_scenario(path: Path) -> str | None:
    """The scenario (TOML text) a checkpoint holds; None if it cannot be read."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return str(data["scenario"])
    except Exception:  # a damaged checkpoint: `resume` names what is wrong with it
        return None


def _note_replaced(out: Path, scn: Scenario) -> None:
    """Warn when ``out`` holds the finished run of another scenario: its files are
    replaced (a mistyped --out would otherwise lose a long run without a word)."""
    if not (out / RESULTS).is_file():
        return
    try:
        attrs = io.dataset_attrs(out / RESULTS)
    except Exception:  # not ours or damaged: replaced as before
        attrs = {}
    old = str(attrs.get("scenario", ""))
    if old and old != scn.to_toml():
        name = str(attrs.get("title", "")).rsplit(" ", 1)[-1] or "?"
        warnings.warn(
            f"{out}: held a finished run of scenario '{name}' with other settings than "
            "this one's; its files are replaced by this run's once it writes its own (a "
            "checkpoint or its results)",
            stacklevel=3,
        )


def _check_every(every: Any, allow_keep: bool = False) -> None:
    """ValueError unless ``every`` is None or seconds in [0, inf) (-1 too where
    ``allow_keep``: `resume` keeps the interrupted run's interval)."""
    if every is None or (allow_keep and every == -1):
        return
    ok = isinstance(every, (int, float, np.integer, np.floating)) and not isinstance(every, bool)
    if not ok or not (math.isfinite(float(every)) and every >= 0):
        keep = ", or -1 to keep the interrupted run's" if allow_keep else ""
        raise ValueError(
            f"checkpoint_every = {every!r}: must be None (no checkpoints) or seconds in "
            f"[0, inf){keep}"
        )


def _make_out(out: Path) -> None:
    """The output folder, made if missing; ValueError naming it if it cannot be."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: exists and is not a folder (--out, out_dir)")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as e:
        raise ValueError(f"{out}: cannot write there ({e.strerror or e}; --out, out_dir)") from None


def resume(
    out_dir: str | os.PathLike[str],
    *,
    checkpoint_every: float | None = -1.0,
    progress: bool = False,
    on_chunk: Callable[[int], None] | None = None,
) -> RunOutcome:
    """Continue the run checkpointed in ``out_dir`` and write the same outputs.

    ``checkpoint_every`` defaults to the interval of the interrupted run (-1: keep it).
    ValueError if there is no usable checkpoint.
    """
    _check_every(checkpoint_every, allow_keep=True)
    out = Path(out_dir)
    path = out / CHECKPOINT
    if out.is_file():
        raise ValueError(f"{out}: a file; give the folder of the run to resume (its --out)")
    if not out.is_dir():
        raise ValueError(f"{out}: no such folder (the --out of the run to resume)")
    if not path.is_file():
        from damjax.ensemble.products import ENSEMBLE_FILE, SLICE_DIR

        if (out / SUMMARY).is_file():
            why = "the run there finished"
        elif (out / ENSEMBLE_FILE).is_file() or (out / SLICE_DIR).is_dir():
            why = (
                "an ensemble's folder: `damjax ensemble SCENARIO --out "
                f"{out}` runs its missing members"
            )
        else:
            why = (
                "no run there wrote one: an interrupted run leaves a checkpoint only with "
                "--checkpoint-every (checkpoint_every)"
            )
        raise ValueError(f"{out}: no {CHECKPOINT} to resume from ({why})")
    _make_out(out)  # an unwritable folder, in run's words
    with io.folder_lock(out, LOCK_FILE, "damjax run"):
        _settle_replaced(out)  # a killed run's earlier files, superseded by its checkpoint
        try:
            ck = _read(io.read_npz, path, "checkpoint")
        except ValueError as exc:
            raise ValueError(
                f"{exc}; delete it and run the scenario again (`damjax run SCENARIO --out "
                f"{out}`) to start afresh"
            ) from None
        if str(ck.get("format", "")) != CHECKPOINT_FORMAT:
            raise ValueError(f"{path}: not a {CHECKPOINT_FORMAT} file")
        _check_inputs(path, ck)
        try:
            scn, chunk, state, tips, snaps = _read_checkpoint(path, ck)
        except (KeyError, IndexError, TypeError) as exc:
            raise ValueError(f"{path}: incomplete checkpoint (no {exc})") from None
        except ValueError as exc:  # a scenario or state that does not fit: name the file
            if str(path) in str(exc):
                raise
            raise ValueError(f"{path}: {exc}") from None
        if checkpoint_every is not None and checkpoint_every < 0:
            saved = float(ck.get("checkpoint_every", np.nan))
            checkpoint_every = None if np.isnan(saved) else saved
        io.remove_stale_temporaries(out)
        rec = _Recorder(out, scn, int(ck["n_chunks"]), checkpoint_every, on_chunk)
        rec.saved_chunk = chunk
        resume_args = dict(state=state, start_chunk=chunk, history=(tips, snaps))
        if scn.type == "slope":
            return _run_slope(scn, out, rec, progress, chunk, **resume_args)
        result = _simulate(scn, rec, progress, **resume_args)
        return _finish(scn, out, result, rec, chunk)


def _read_checkpoint(path: Path, ck: dict[str, np.ndarray]) -> tuple[Any, ...]:
    """Scenario, chunks done, State, per-chunk tips and snapshots of a checkpoint."""
    scn = scenario.loads(str(ck["scenario"]), warn=False)
    if str(ck.get("damjax_version", "")) != _version():
        warnings.warn(
            f"{path} was written by damjax {ck.get('damjax_version')}, this is "
            f"{_version()}: the resumed run may differ from an uninterrupted one",
            stacklevel=3,
        )
    layout, template = _template(scn)
    chunk = int(ck["chunk"])
    if not 0 < chunk < layout.n_chunks or int(ck["n_chunks"]) != layout.n_chunks:
        raise ValueError(
            f"{path}: chunk {chunk} of {int(ck['n_chunks'])} does not fit this run's "
            f"{layout.n_chunks} chunks"
        )
    state = io.arrays_to_tree(_with_opening_y(ck), template, "state")
    tips = [np.asarray(t) for t in ck["tips"]]
    if len(tips) != chunk:
        raise ValueError(f"{path}: {len(tips)} chunks of crack tips for {chunk} chunks done")
    keys = [k[len("snap.") :] for k in ck if k.startswith("snap.")]
    snaps = [{k: ck[f"snap.{k}"][i] for k in keys} for i in range(chunk)] if keys else []
    return scn, chunk, state, tips, snaps


def _simulate(scn: Scenario, rec: _Recorder, progress: bool, **resume: Any) -> Any:
    from damjax import pst

    try:
        # checked (and warned, naming the file's keys) when the scenario was read
        return pst.run(scenario.prepared(scn), progress=progress, callback=rec, **resume)
    except KeyboardInterrupt:
        if rec.every is not None:
            rec.save()
        raise


def _finish(
    scn: Scenario,
    out: Path,
    result: Any,
    rec: _Recorder,
    resumed_from: int | None,
    phases: dict[str, float] | None = None,
) -> RunOutcome:
    """Write a PST's outputs; ``phases``: wall-clock seconds of the run's phases so far
    (recorded in the summary as ``phases_s``, with those of writing the outputs)."""
    from damjax import diagnostics

    phases = dict(phases or {})
    t0 = _time.perf_counter()
    summary = dict(result.summary)
    attrs = {**_file_attrs(scn, summary), "fault": result.fault}
    ds = io.result_dataset(
        result,
        crack_speed=diagnostics.crack_speed(result.time, result.tip),
        attrs=attrs,
        snapshots=scn.output.snapshots,
    )
    files = {"results": out / RESULTS}
    io.write_dataset(files["results"], ds)
    if rec.last is not None:
        files["final_state"] = out / FINAL_STATE
        io.write_npz(files["final_state"], rec.last.state)
    t1 = _time.perf_counter()
    phases["results_file_s"] = t1 - t0
    if scn.output.plot:
        from damjax.plot import plot_pst

        files["plot"] = out / PLOT
        io.save_figure(plot_pst(result), files["plot"])
        phases["figure_s"] = _time.perf_counter() - t1
    files["summary"] = out / SUMMARY
    full = {
        "scenario": scn.name,
        "damjax_version": _version(),
        **summary,
        "phases_s": {k: round(v, 4) for k, v in phases.items()},
        "resumed_from_chunk": resumed_from,
        "out_dir": str(out),
    }
    io.write_json(files["summary"], full)
    (out / CHECKPOINT).unlink(missing_ok=True)
    return RunOutcome(scn, result, out, files, full, resumed_from)


def _run_slope(
    scn: Scenario,
    out: Path,
    rec: _Recorder,
    progress: bool,
    resumed_from: int | None,
    **resume: Any,
) -> RunOutcome:
    """A slope scenario: results.nc (maps and snapshots), summary.json, slope.png and
    release.gif; checkpoints through ``rec`` as for PSTs (``resume``: state, start_chunk,
    history)."""
    from damjax.scenario.slope_fields import simulate
    from damjax.slope.results import result_dataset

    try:
        result = simulate(scn, progress=progress, callback=rec, **resume)
    except KeyboardInterrupt:
        if rec.every is not None:
            rec.save()
        raise
    summary = dict(result.summary)
    ds = result_dataset(result, snapshots=scn.output.snapshots)
    ds.attrs.update(_file_attrs(scn, summary))
    if summary.get("fault"):
        ds.attrs["fault"] = summary["fault"]
    files = {"results": out / RESULTS}
    io.write_dataset(files["results"], ds)
    if scn.output.plot:
        from damjax.plot import animate_slope, plot_slope

        files["plot"] = out / SLOPE_PLOT
        io.save_figure(plot_slope(result), files["plot"])
        if result.snapshots:
            files["animation"] = out / SLOPE_ANIMATION
            tmp = out / f".{SLOPE_ANIMATION}.partial.gif"  # the writer needs a .gif name
            try:
                animate_slope(result, str(tmp))
                os.replace(tmp, files["animation"])
            finally:
                tmp.unlink(missing_ok=True)
    files["summary"] = out / SUMMARY
    full = {
        "scenario": scn.name,
        "damjax_version": _version(),
        **summary,
        "resumed_from_chunk": resumed_from,
        "out_dir": str(out),
    }
    if rec.last is not None:
        files["final_state"] = out / FINAL_STATE
        io.write_npz(files["final_state"], rec.last.state)
    io.write_json(files["summary"], full)
    (out / CHECKPOINT).unlink(missing_ok=True)
    return RunOutcome(scn, result, out, files, full, resumed_from)


# --------------------------------------------------------------------------- reading back


def load_result(out_dir: str | os.PathLike[str]) -> tuple[Scenario, Any]:
    """The scenario and the result rebuilt from a run folder's ``results.nc`` alone (or
    from such a file, or one of `PSTResult.to_netcdf`, given itself): a `PSTResult`, or
    for a slope run a `damjax.slope.simulation.SlopeResult`
    (`damjax.slope.results.load_result`; its scenario read again with its files)."""
    from damjax.pst import PSTResult

    path = Path(out_dir) if Path(out_dir).is_file() else Path(out_dir) / RESULTS
    if not path.is_file():
        if (Path(out_dir) / CHECKPOINT).is_file():
            raise ValueError(
                f"{out_dir}: an unfinished run (no {RESULTS} yet); `damjax resume {out_dir}` "
                "continues it"
            )
        if (Path(out_dir) / "ensemble.nc").is_file():
            raise ValueError(
                f"{out_dir}: an ensemble folder (ensemble.nc, ensemble.png, "
                "ensemble_summary.json); `damjax show` re-plots single runs"
            )
        if not Path(out_dir).exists():
            raise ValueError(f"{out_dir}: no such folder (a run's output folder, --out DIR)")
        raise ValueError(f"{out_dir}: no {RESULTS} (not a damjax output folder?)")
    ds = _read(io.open_dataset, path, "results")
    if "scenario" not in ds.attrs or "summary" not in ds.attrs:
        raise ValueError(f"{path}: not written by damjax (no scenario/summary attributes)")
    try:
        scn = scenario.loads(ds.attrs["scenario"], warn=False)
    except ValueError as exc:
        alone = ""
        if 'type = "slope"' in str(ds.attrs["scenario"]):  # its files moved, say
            alone = f"; the slope result alone: damjax.slope.results.load_result({str(path)!r})"
        raise ValueError(
            f"{path}: its 'scenario' attribute is not a valid scenario ({exc}){alone}"
        ) from None
    if scn.type == "slope":
        from damjax.slope import results as slope_results

        return scn, slope_results.load_result(path)
    try:
        summary = json.loads(ds.attrs["summary"])
    except ValueError as exc:
        raise ValueError(f"{path}: its 'summary' attribute is not JSON ({exc})") from None
    try:
        fields = io.dataset_fields(ds)
    except KeyError as exc:
        raise ValueError(f"{path}: not a damjax PST results file (no variable {exc})") from None
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(PSTResult):
        if f.name in fields:
            kwargs[f.name] = fields[f.name]
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            # a field this file predates: NaN on x (plots draw nothing)
            kwargs[f.name] = np.full(fields["x"].shape, np.nan, np.float32)
    kwargs.update(
        params=scn.params,
        setup=scn.setup,
        summary=summary,
        fault=ds.attrs.get("fault"),
        fractures=summary.get("slab_fractures", []),
    )
    result = PSTResult(**kwargs)
    return scn, result


def load_final_state(out_dir: str | os.PathLike[str]) -> Any:
    """The final `State` of a finished run (``final_state.npz``; PST or slope)."""
    path = Path(out_dir) / RESULTS
    text = str(io.dataset_attrs(path).get("scenario", "")) if path.is_file() else ""
    if 'type = "slope"' in text:
        scn = scenario.loads(text, warn=False)
    else:
        scn, _ = load_result(out_dir)
    _, template = _template(scn)
    arrays = _with_opening_y(io.read_npz(Path(out_dir) / FINAL_STATE))
    return io.arrays_to_tree(arrays, template, "state")


def _with_opening_y(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Saved states from before `State.opening_y` (2026-11-25): zero, which is what every
    1D run has; a 2D run's earlier openings then all count along x."""
    if "state.opening" in arrays and "state.opening_y" not in arrays:
        arrays = {**arrays, "state.opening_y": np.zeros_like(arrays["state.opening"])}
    return arrays


def show(
    out_dir: str | os.PathLike[str], plot: str | os.PathLike[str] | None = None
) -> tuple[dict[str, Any], Path]:
    """Re-plot a finished run from its files; returns (summary, plot path).

    ``out_dir``: the run's folder, or a results file (its figure goes beside it, named
    after it, unless ``plot`` is given). The summary is ``summary.json`` when present,
    else the one stored in ``results.nc``.
    """
    from damjax.plot import plot_pst, plot_slope

    given = Path(out_dir)
    path = given if given.is_file() else given / RESULTS
    if given.is_file():  # the folder's names (pst.png, summary.json) are not its own
        out_dir = given.parent
        if plot is None:
            plot = given.with_suffix(".png")
    slope = None
    if path.is_file():
        from damjax.slope.results import load_result as load_slope_result

        try:
            slope = load_slope_result(path)
        except (OSError, ValueError, KeyError):
            slope = None
    if slope is not None:
        result = slope
        target = Path(plot) if plot is not None else Path(out_dir) / SLOPE_PLOT
        io.save_figure(plot_slope(result), target)
    else:
        _, result = load_result(path if given.is_file() else out_dir)
        target = Path(plot) if plot is not None else Path(out_dir) / PLOT
        io.save_figure(plot_pst(result), target)
    summary = result.summary
    sfile = Path(out_dir) / SUMMARY
    if sfile.is_file() and not given.is_file():
        try:
            summary = json.loads(sfile.read_text(encoding="utf-8"))
        except ValueError:
            pass
    return summary, target
