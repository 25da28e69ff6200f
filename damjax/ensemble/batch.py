"""Running an ensemble: the shared layout, the slice size chosen from the compiled step's
memory, the vmapped (and device-sharded) slices, and resume from the slice files of the
output folder (`run`)."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax import distributed, io
from damjax.core.loop import (
    MEMORY_FRACTION,
    cpu_compiler_options,
    free_memory_bytes,
    peak_bytes,
    run_chunk,
)
from damjax.core.model import make_slope_layout
from damjax.ensemble.plot import plot_ensemble
from damjax.ensemble.products import (
    ENSEMBLE_FILE,
    FIGURE,
    SLICE_DIR,
    SUMMARY_FILE,
    assemble,
    done_slices,
    quantile_summary,
    slice_dataset,
    slice_name,
)
from damjax.ensemble.spec import Ensemble, _is_int, key_of, member_draws, member_scenario
from damjax.scenario import prepared
from damjax.scenario.slope_fields import resolve_inputs, simulate
from damjax.slope.simulation import SlopeRunWarning, steepest_covered
from damjax.validation import ensure_x64

PLAN_FILE = "plan.json"
LOCK_FILE = ".damjax-ensemble.lock"  # held by the run writing into the folder
MAX_PER_DEVICE = 8  # members per device and slice (resume granularity)
# On a CPU device a vmapped slice of slope members ran slower per member than the members
# one at a time (Fig. 13a slope, 0.3 s, 2 cores, 2026-11-25: 14 s per member vmapped by 2,
# 10 s sequential); CPU members run one per device, a host split into one device per core
# (`damjax ensemble --cpu-devices`), the devices running their members side by side.


# --------------------------------------------------------------------------- planning


def _resolve(scn: Any, member: int | None = None) -> Any:
    try:
        return resolve_inputs(scn)
    except ValueError as exc:  # a plain one-line ValueError, naming the member
        seed = (scn.strength or {}).get("seed")
        who = "" if member is None else f"member {member}"
        if who and seed is not None:
            who += f" (strength.seed = {seed})"
        raise ValueError(f"{who}: {exc}" if who else str(exc)) from None


def shared_layout(ens: Ensemble, members: range | None = None) -> Any:
    """One layout for every member: the largest grid padding and the smallest time step
    any member needs (`damjax.core.model.make_slope_layout`)."""
    scn = ens.scenario
    prep = prepared(scn)  # read and checked when the scenario was
    max_slope = steepest_covered(prep.slope_deg, prep.cover)
    members = range(ens.members) if members is None else members
    layouts = []
    for i in members if (ens.params or ens.strength) else [0]:
        params = dataclasses.replace(scn.params, **member_draws(ens, i)[0])
        layouts.append(make_slope_layout(params, scn.setup, max_slope))
    fine = max(layouts, key=lambda lay: (lay.n_steps, -lay.chunk_steps))
    px = max(lay.pad[0] for lay in layouts)
    py = max(lay.pad[1] for lay in layouts)
    nx, ny = fine.n_cells
    return dataclasses.replace(fine, grid_shape=(px + nx + py, 2 * py + ny), pad=(px, py))


_free_memory_bytes = free_memory_bytes  # the names this module had (shared with sweep)
_peak_bytes = peak_bytes


# --------------------------------------------------------------------------- the run


def _stack(trees: list[Any]) -> Any:
    return jax.tree.map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *trees)


def _build_members(ens: Ensemble, idx: list[int], layout: Any) -> tuple[Any, Any, list[Any]]:
    """Stacked (models, states) of members idx and their member scenarios with the
    resolved start."""
    models, states, scns = [], [], []
    for i in idx:
        scn = member_scenario(ens, i)
        inp = _resolve(scn, i)
        ensure_x64(scn.setup.dtype)
        m, s = inp.build(scn, layout)
        models.append(m)
        states.append(s)
        scns.append(scn)
    return _stack(models), _stack(states), scns


_COMPILED: dict[Any, Any] = {}


class _Runner:
    """The compiled slice step: a vmapped chunk of `run_chunk` over a slice, sharded over
    the local devices; members that had faulted keep their state."""

    def __init__(self, layout: Any, devices: list[Any]) -> None:
        self.layout, self.devices = layout, devices
        n = layout.chunk_steps

        def body(models: Any, states: Any) -> Any:
            new, _ = jax.vmap(lambda m, s: run_chunk(m, s, n))(models, states)
            keep = states.fault != 0

            def sel(a: Any, b: Any) -> Any:
                return jnp.where(keep.reshape(keep.shape + (1,) * (a.ndim - 1)), a, b)

            return jax.tree.map(sel, states, new)

        self.sharding = None
        if len(devices) > 1:
            from jax.sharding import Mesh, NamedSharding, PartitionSpec

            mesh = Mesh(np.array(devices), ("member",))
            self.sharding = NamedSharding(mesh, PartitionSpec("member"))
            body = jax.shard_map(
                body,
                mesh=mesh,
                in_specs=PartitionSpec("member"),
                out_specs=PartitionSpec("member"),
            )
        self.fn = jax.jit(body, donate_argnums=1, compiler_options=cpu_compiler_options())
        self.compiled: Any = None
        self.compile_time_s = 0.0

    def put(self, tree: Any) -> Any:
        if self.sharding is not None:
            return jax.device_put(tree, self.sharding)
        return jax.device_put(tree, self.devices[0])

    def compile(self, models: Any, states: Any) -> Any:
        """The compiled slice step for these shapes (kept for the process: a resumed or
        repeated ensemble of the same layout compiles nothing)."""
        leaves, treedef = jax.tree.flatten((models, states))
        key = (
            treedef,
            tuple((np.shape(x), str(x.dtype)) for x in leaves),
            self.layout.chunk_steps,
            tuple(d.id for d in self.devices),
        )
        if key not in _COMPILED:
            t0 = time.perf_counter()
            _COMPILED[key] = self.fn.lower(models, states).compile()
            self.compile_time_s += time.perf_counter() - t0
        self.compiled = _COMPILED[key]
        return self.compiled

    def run(self, models: Any, states: Any, progress: Any = None) -> Any:
        for _ in range(self.layout.n_chunks):
            states = self.compiled(models, states)
            if progress is not None:
                # a call returns once the chunk is queued: count it when it is done (the
                # bar reached 100 % while the members were still running)
                states = jax.block_until_ready(states)
                progress(self.layout.chunk_steps)
        return jax.block_until_ready(states)


def _pad(tree: Any, n: int) -> Any:
    def one(a: np.ndarray) -> np.ndarray:
        k = n - a.shape[0]
        return np.concatenate([a, np.repeat(a[-1:], k, axis=0)]) if k > 0 else a

    return jax.tree.map(one, tree)


def _finish_member(scn: Any, state: Any, layout: Any) -> Any:
    """The `SlopeResult` of a finished member: `damjax.scenario.slope_fields.simulate`
    resumed at the last chunk with the member's final state (no step is run: the same
    maps and summary as a single run)."""
    return simulate(scn, state=state, start_chunk=layout.n_chunks)


# how a plan's slice size was chosen, as the log says it
CHOSEN_TEXT = {
    "memory": "from XLA's memory estimate",
    "cpu": "one member per CPU device",
    "given": "given",
    "stored": "stored with the ensemble",
}


@dataclasses.dataclass
class Plan:
    """How an ensemble is cut: the slice size, the shared layout, the memory figures."""

    key: str
    slice_size: int
    layout: dict[str, Any]
    peak_bytes_per_device: int | None
    budget_bytes_per_device: int
    devices_per_process: int
    chosen: str  # a key of CHOSEN_TEXT

    def slices(self, members: int) -> list[tuple[int, int]]:
        """Member ranges ``(start, stop)`` of ``slice_size`` members covering ``members``."""
        s = self.slice_size
        return [(a, min(a + s, members)) for a in range(0, members, s)]


def _layout_dict(layout: Any) -> dict[str, Any]:
    return {
        "grid_shape": list(layout.grid_shape),
        "pad": list(layout.pad),
        "n_cells": list(layout.n_cells),
        "n_chunks": layout.n_chunks,
        "chunk_steps": layout.chunk_steps,
    }


def run(
    ens: Ensemble,
    out_dir: str | os.PathLike[str],
    *,
    slice_size: int | None = None,
    memory_fraction: float = MEMORY_FRACTION,
    devices: list[Any] | None = None,
    plot: bool = True,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
    on_slice: Callable[[int, int], None] | None = None,
) -> Any:
    """Run (or resume) an ensemble into ``out_dir``; returns the ``ensemble.nc`` dataset.

    Args:
        ens: the ensemble (`load`, `from_scenario`).
        out_dir: output folder (see the module doc for its files).
        slice_size: members per slice (overrides ``ensemble.slice_size``; default: from
            memory). A folder keeps the slice size it was started with.
        memory_fraction: share of the free memory a slice may use, (0, 1].
        devices: this process's devices (default `jax.local_devices()`).
        plot: write ``ensemble.png``.
        progress: tqdm progress bar over the members' steps.
        log: called with one line per event (slice done, resumed slices, ...).
        on_slice: called as ``on_slice(a, b)`` once members a..b-1 are on disk.
    """
    if slice_size is not None and not _is_int(slice_size, 1):
        raise ValueError(f"slice_size = {slice_size!r}: must be an integer >= 1")
    if not (isinstance(memory_fraction, (int, float)) and 0 < memory_fraction <= 1):
        raise ValueError(f"memory_fraction = {memory_fraction!r}: must be in (0, 1]")
    say = log or (lambda _msg: None)
    t_start = time.perf_counter()
    out = Path(out_dir)
    from damjax import runner

    held_by_run = [
        n for n in (runner.RESULTS, runner.SUMMARY, runner.CHECKPOINT) if (out / n).exists()
    ]
    if held_by_run:  # two kinds of output never mix
        raise ValueError(
            f"{out}: holds a single run's files ({', '.join(held_by_run)}), not an "
            "ensemble's; give another --out"
        )
    slices_dir = out / SLICE_DIR
    slices_dir.mkdir(parents=True, exist_ok=True)
    # one run per folder: process 0 holds the lock for its job, and every process of the
    # job hears whether it got it (before anything in the folder is touched)
    held, problem = None, None
    if distributed.process_index() == 0:
        try:
            held, left = io.lock_folder(out, LOCK_FILE, "damjax ensemble")
            if left:
                say(f"took over the lock a finished or killed run left ({left})")
        except ValueError as exc:
            problem = str(exc)
    problem = distributed.allgather_objects(problem)[0]
    if problem:
        raise ValueError(problem)
    try:
        return _run_locked(
            ens, out, slice_size, memory_fraction, devices, plot, progress, say, on_slice, t_start
        )
    finally:
        io.unlock_folder(out, LOCK_FILE, held)


def _run_locked(
    ens: Ensemble,
    out: Path,
    slice_size: int | None,
    memory_fraction: float,
    devices: list[Any] | None,
    plot: bool,
    progress: bool,
    say: Callable[[str], None],
    on_slice: Callable[[int, int], None] | None,
    t_start: float,
) -> Any:
    """`run` once the folder is this run's."""
    slices_dir = out / SLICE_DIR
    io.remove_stale_temporaries(slices_dir)
    io.remove_stale_temporaries(out)
    devices = list(jax.local_devices()) if devices is None else list(devices)
    n_dev = len(devices)
    proc, n_proc = distributed.process_index(), distributed.process_count()
    key = key_of(ens)
    layout = shared_layout(ens)
    given = slice_size if slice_size is not None else ens.slice_size

    # the plan: stored, or made by process 0 (it compiles the first slice to measure it)
    plan_path = out / PLAN_FILE
    plan: Plan | None = None
    if plan_path.is_file():
        try:
            plan = Plan(**json.loads(plan_path.read_text()))
        except (ValueError, TypeError) as exc:  # truncated by a full disk, or edited
            raise ValueError(
                f"{plan_path}: unreadable ({' '.join(str(exc).split())}); delete it and run "
                "again (the finished members are kept: the plan is made again from them)"
            ) from None
        _check_plan(plan, key, layout, out)
        plan.chosen = "stored"
    runner = _Runner(layout, devices)
    peak = None
    if plan is None and proc == 0:
        budget = int(memory_fraction * _free_memory_bytes(devices[0]) / max(1, n_dev))
        per_dev_cap = max(1, math.ceil(ens.members / (n_dev * n_proc)))
        if given is not None:
            if given > ens.members:  # a larger slice would only run padding members
                say(f"slice size {given} > {ens.members} members: slices of {ens.members}")
                given = ens.members
            per_dev, chosen = max(1, math.ceil(given / n_dev)), "given"
        elif all(d.platform == "cpu" for d in devices):
            per_dev, chosen = 1, "cpu"  # on CPU: see MAX_PER_DEVICE
        else:
            per_dev, chosen = min(MAX_PER_DEVICE, per_dev_cap), "memory"
        while True:
            k = per_dev * n_dev
            m, s, _ = _build_members(ens, [0], layout)
            m, s = _pad(m, k), _pad(s, k)
            runner.compile(*runner.put((m, s)))
            peak = _peak_bytes(runner.compiled)
            if chosen == "given" or peak is None or peak <= budget or per_dev == 1:
                break
            per_dev = max(1, int(per_dev * budget / peak))
        plan = Plan(
            key=key,
            slice_size=given if chosen == "given" else per_dev * n_dev,
            layout=_layout_dict(layout),
            peak_bytes_per_device=peak,
            budget_bytes_per_device=budget,
            devices_per_process=n_dev,
            chosen=chosen,
        )
        if peak is not None and peak > budget:
            say(
                f"slice of {plan.slice_size}: XLA's peak estimate {peak / 2**20:.0f} MiB per "
                f"device exceeds the budget {budget / 2**20:.0f} MiB"
            )
        io.write_json(plan_path, dataclasses.asdict(plan))
    distributed.barrier("damjax-ensemble-plan")
    if plan is None:
        plan = Plan(**json.loads(plan_path.read_text()))
        _check_plan(plan, key, layout, out)
    size = plan.slice_size
    k_pad = math.ceil(size / n_dev) * n_dev
    say(
        f"ensemble of {ens.members} members, slices of {size} "
        f"({CHOSEN_TEXT.get(plan.chosen, plan.chosen)}; peak "
        f"{_mib(plan.peak_bytes_per_device)} per device, budget "
        f"{_mib(plan.budget_bytes_per_device)}), {n_dev} device(s) x {n_proc} process(es)"
    )

    # what is left: the scan is done by every process before any writes again
    all_slices = plan.slices(ens.members)
    done = done_slices(out)
    for p in done.values():  # a damaged slice stops the run now, not after the others
        try:
            io.dataset_attrs(p)
        except Exception as exc:
            raise ValueError(
                f"{p}: not a readable slice ({type(exc).__name__}); delete it and run "
                "again: its members are run anew"
            ) from None
    distributed.barrier("damjax-ensemble-scan")
    # by member, not by slice: a grown ensemble's plan may cut its slices elsewhere than
    # the earlier run did (3 members in slices of 2, then 4: members 2-3 of the new plan,
    # of which 2 is done), and no member is run twice
    covered = {m for a, b in done for m in range(a, b)}
    todo = [r for a, b in all_slices for r in _missing_runs(a, b, covered)]
    mine = [s for j, s in enumerate(todo) if j % n_proc == proc]
    skipped = sum(all(m in covered for m in range(a, b)) for a, b in all_slices)
    left = sum(b - a for a, b in todo)
    if left < ens.members:
        say(f"resuming: {ens.members - left} of {ens.members} members done, {left} to run")

    bar = None
    if progress and mine:
        from damjax._progress import progress_bar as tqdm

        here = sum(b - a for a, b in mine)  # members this process runs now
        bar = tqdm(
            total=here * layout.n_steps,
            unit="step",
            unit_scale=True,
            desc=f"ensemble x{here}" + (f" of {ens.members}" if here < ens.members else ""),
        )
    run_time = 0.0
    run_members = 0
    member_warnings: list[tuple[int, str]] = []
    for a, b in mine:
        idx = list(range(a, b))
        models, states, scns = _build_members(ens, idx, layout)
        models, states = runner.put((_pad(models, k_pad), _pad(states, k_pad)))
        if runner.compiled is None:
            runner.compile(models, states)
        t0 = time.perf_counter()
        per_member = None
        if bar is not None:
            n_idx = len(idx)
            per_member = lambda steps, k=n_idx: bar.update(steps * k)  # noqa: E731
        final = runner.run(models, states, per_member)
        run_time += time.perf_counter() - t0
        run_members += len(idx)
        final_h = jax.tree.map(np.asarray, final)
        results = []
        for j in range(len(idx)):
            take = lambda x, j=j: jnp.asarray(x[j])  # noqa: E731
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("ignore", UserWarning)
                warnings.simplefilter("always", SlopeRunWarning)
                results.append(_finish_member(scns[j], jax.tree.map(take, final_h), layout))
            member_warnings += [(idx[j], str(w.message)) for w in caught]
        ds = slice_dataset(ens, idx, results)
        io.write_dataset(slices_dir / slice_name(a, b), ds)
        say(f"members {a}-{b - 1} done ({time.perf_counter() - t0:.1f} s)")
        if on_slice is not None:
            on_slice(a, b)
    if bar is not None:
        bar.close()
    _warn_grouped(member_warnings)
    distributed.barrier("damjax-ensemble-done")
    summary = None
    if proc == 0:
        ds = assemble(out, ens.members, key)
        ds.attrs["scenario"] = ens.scenario.to_toml()
        ds.attrs["ensemble"] = json.dumps(ens.table(), sort_keys=True)
        ds.attrs["layout"] = json.dumps(plan.layout)
        io.write_dataset(out / ENSEMBLE_FILE, ds)
        summary = {
            **quantile_summary(ds),
            "wall_time_s": time.perf_counter() - t_start,
            "run_time_s": run_time,
            "compile_time_s": runner.compile_time_s,
            "members_run_here": run_members,
            "slices_resumed": skipped,
            "slice_size": size,
            "slice_size_chosen_by": plan.chosen,
            "peak_bytes_per_device": plan.peak_bytes_per_device,
            "budget_bytes_per_device": plan.budget_bytes_per_device,
            "devices_per_process": n_dev,
            "processes": n_proc,
            "n_steps": layout.n_steps,
        }
        io.write_json(out / SUMMARY_FILE, summary)
        if plot:
            plot_ensemble(ds, out / FIGURE)
    distributed.barrier("damjax-ensemble-written")
    ds = io.open_dataset(out / ENSEMBLE_FILE)
    if summary is not None:
        ds.attrs["run_summary"] = json.dumps(summary)
    return ds


def _warn_grouped(member_warnings: list[tuple[int, str]]) -> None:
    """One `SlopeRunWarning` per kind of the members' warnings (their text with the
    numbers left out), naming the members and giving the first member's text: an
    ensemble of 16 says "bounded by the domain" once, not 16 times."""
    groups: dict[str, list[tuple[int, str]]] = {}
    for i, text in member_warnings:
        groups.setdefault(re.sub(r"-?\d+(\.\d+)?(e[-+]?\d+)?", "#", text), []).append((i, text))
    for rows in groups.values():
        members = sorted({i for i, _ in rows})
        named = ", ".join(map(str, members[:8])) + (", ..." if len(members) > 8 else "")
        warnings.warn(
            f"{len(members)} member{'s' if len(members) > 1 else ''} ({named}); member "
            f"{rows[0][0]}: {rows[0][1]}",
            SlopeRunWarning,
            stacklevel=3,
        )


def _mib(b: int | None) -> str:
    return "n/a" if b is None else f"{b / 2**20:.0f} MiB"


def _check_plan(plan: Plan, key: str, layout: Any, out: Path) -> None:
    if plan.key != key:
        raise ValueError(
            f"{out}: holds an ensemble of another scenario or [ensemble] table (key "
            f"{plan.key}, this one {key}); give another --out"
        )
    if plan.layout != _layout_dict(layout):
        raise ValueError(
            f"{out}: its members ran with another layout ({plan.layout}); the drawn "
            "parameters of the new members need a smaller time step: give another --out"
        )


def _missing_runs(a: int, b: int, covered: set[int]) -> list[tuple[int, int]]:
    """The contiguous runs (first, end) of members a..b-1 not in ``covered``."""
    runs: list[tuple[int, int]] = []
    for m in range(a, b):
        if m in covered:
            continue
        if runs and runs[-1][1] == m:
            runs[-1] = (runs[-1][0], m + 1)
        else:
            runs.append((m, m + 1))
    return runs
