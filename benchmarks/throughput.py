"""Throughput cases: many PSTs in as few batches as fit (``sweep256``) and a release area
of real size (``slope_large``), each as JSON rows.

    python -m benchmarks sweep256 [--dry-run]
    python -m benchmarks slope_large [--dry-run]

``--dry-run`` (or ``DAMJAX_BENCH_DRY_RUN=1``) runs toy versions of the same code in
seconds; their rows carry ``"dry_run": true``.

- ``sweep256``: 256 baseline PSTs (100 m, dx 0.02 m, 3 s, theta from 250 to 1000 Pa/m)
  through `damjax.sweep`, whose slices come from XLA's memory estimate of the compiled
  chunk, against one PST at a time (`damjax.simulate_pst`) on the same device.
  ``DAMJAX_SWEEP_MEMBERS`` (default 256), ``DAMJAX_BENCH_DURATION`` (s, default 3) and
  ``DAMJAX_SWEEP_SEQUENTIAL`` (PSTs timed one at a time, default 4) shrink it.
- ``slope_large``: the shipped scenario ``slope-large-200x200`` (4 million particles,
  5 s): one run and a 32-member ensemble (`damjax.ensemble`'s slices: one member per
  device on a CPU, up to 8 from memory elsewhere). Off a GPU the steps of a short window
  (``DAMJAX_SLOPE_WINDOW`` = "chunks x steps", default "3x20", after one warm-up chunk)
  are timed and the full run extrapolated from them (``"extrapolated": true``);
  ``DAMJAX_SLOPE_FULL=1`` runs every step, ``DAMJAX_SLOPE_EXTRAPOLATE=1`` times the window
  on a GPU too. The ensemble times one slice (``slices_timed``) and multiplies by the
  slices.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def dry_run() -> bool:
    return os.environ.get("DAMJAX_BENCH_DRY_RUN", "") not in ("", "0")


def _env_number(name: str, default: str, kind: type = int) -> Any:
    """A positive number from the environment variable ``name``, with a clear error."""
    text = os.environ.get(name, default)
    try:
        value = kind(text)
        if not value > 0:
            raise ValueError
    except ValueError:
        what = "an integer" if kind is int else "a number"
        raise ValueError(f"{name} = {text!r}: must be {what} > 0") from None
    return value


def meta() -> dict[str, Any]:
    """Where and when a row was measured."""
    import jax

    from benchmarks.cases import stamp

    dev = jax.devices()[0]
    return dict(
        device=getattr(dev, "device_kind", str(dev)),
        platform=dev.platform,
        n_devices=len(jax.devices()),
        **stamp(),
        dry_run=dry_run(),
    )


def _mib(b: float | None) -> float | None:
    return None if b is None else round(b / 2**20, 2)


# --------------------------------------------------------------------------- sweep256


def sweep256_rows() -> list[dict[str, Any]]:
    """One row for the PSTs one at a time, one for the batch (with the ratio)."""
    import jax.numpy as jnp

    from damjax import PSTParams, PSTSetup, last_sweep_plan, simulate_pst, sweep

    dry = dry_run()
    members = _env_number("DAMJAX_SWEEP_MEMBERS", "8" if dry else "256")
    n_seq = _env_number("DAMJAX_SWEEP_SEQUENTIAL", "2" if dry else "4")
    if dry:
        setup = PSTSetup(length=10.0, dx=0.05, duration=0.1, chunk_steps=100)
        base = dict(steady_length=4.0)
    else:
        setup = PSTSetup(duration=_env_number("DAMJAX_BENCH_DURATION", "3", float))
        base = {}
    thetas = np.linspace(250.0, 1000.0, members)
    m = meta()

    # one at a time: evenly spread members, the first compile not timed (summary)
    picks = np.unique(np.linspace(0, members - 1, min(n_seq, members)).round().astype(int))
    seq_wall, seq_work, seq_compile = 0.0, 0, 0.0
    for i in picks:
        r = simulate_pst(PSTParams(**base, strength_gradient=float(thetas[i])), setup)
        s = r.summary
        seq_wall += s["wall_time_s"]
        seq_work += s["n_particles"] * s["n_steps"]
        seq_compile += s["compile_time_s"]
    seq_rate = seq_work / seq_wall
    seq_row = dict(
        case="sweep256_sequential",
        **m,
        members_timed=len(picks),
        n_particles=s["n_particles"],
        duration_s=setup.duration,
        dx=setup.dx,
        compile_time_s=round(seq_compile, 3),
        wall_time_s=round(seq_wall, 3),
        wall_time_per_member_s=round(seq_wall / len(picks), 3),
        particle_steps_per_s=round(seq_rate),
    )
    rows = [seq_row]

    batch = PSTParams(**base, strength_gradient=jnp.asarray(thetas, jnp.float32))
    t0 = time.perf_counter()
    res = sweep(batch, setup)
    end_to_end = time.perf_counter() - t0
    plan = last_sweep_plan()
    s0 = res[0].summary
    loop = s0["wall_time_s"] * members  # the sweep reports its loop time per member
    work = members * s0["n_particles"] * s0["n_steps"]
    rate = work / loop
    slices_per_device = math.ceil(plan.members_per_device / plan.slice_size)
    rows.append(
        dict(
            case="sweep256_batch",
            **m,
            members=members,
            theta_range=[float(thetas[0]), float(thetas[-1])],
            n_particles=s0["n_particles"],
            n_steps=s0["n_steps"],
            duration_s=setup.duration,
            dx=setup.dx,
            slice_size=plan.slice_size,
            slices_per_device=slices_per_device,
            slice_size_chosen_by=plan.chosen,
            peak_mib_per_device=_mib(plan.peak_bytes_per_device),
            mib_per_member=_mib(plan.bytes_per_member),
            budget_mib_per_device=_mib(plan.budget_bytes_per_device),
            compile_time_s=round(s0["compile_time_s"], 3),
            wall_time_s=round(loop, 3),
            end_to_end_s=round(end_to_end, 3),
            particle_steps_per_s=round(rate),
            ratio_over_sequential=round(rate / seq_rate, 3),
            arrest_position_m=[r.summary["arrest_position_m"] for r in (res[0], res[-1])],
        )
    )
    return rows


# --------------------------------------------------------------------------- slope_large


def _window() -> tuple[int, int]:
    text = os.environ.get("DAMJAX_SLOPE_WINDOW", "2x10" if dry_run() else "3x20")
    try:
        chunks, steps = (int(v) for v in text.lower().split("x"))
        if chunks < 1 or steps < 1:
            raise ValueError
    except ValueError:
        raise ValueError(
            f"DAMJAX_SLOPE_WINDOW = {text!r}: must be 'CHUNKSxSTEPS', integers >= 1"
        ) from None
    return chunks, steps


def _large_scenario() -> Any:
    from damjax import scenario

    scn = scenario.load("slope-large-200x200")
    if dry_run():  # the same physics on a 24 m x 16 m patch at dx 0.2 m
        setup = dataclasses.replace(scn.setup, length=24.0, width=16.0, dx=0.2, duration=0.5)
        scn = dataclasses.replace(scn, setup=setup)
    return scn


def _timed_chunks(exe: Any, models: Any, states: Any, chunks: int) -> tuple[float, Any]:
    """One warm-up chunk, then ``chunks`` timed ones; the seconds of the timed ones."""
    import jax

    out = exe(models, states)
    states = out[0] if isinstance(out, tuple) else out
    jax.block_until_ready(states)
    t0 = time.perf_counter()
    for _ in range(chunks):
        out = exe(models, states)
        states = out[0] if isinstance(out, tuple) else out
    jax.block_until_ready(states)
    return time.perf_counter() - t0, states


def slope_large_rows() -> list[dict[str, Any]]:
    """One row for a single run, one for the 32-member ensemble."""
    import jax

    from damjax.core.loop import compile_chunk, free_memory_bytes, peak_bytes
    from damjax.ensemble import batch as eb
    from damjax.ensemble.spec import from_scenario

    dry = dry_run()
    members = _env_number("DAMJAX_SLOPE_MEMBERS", "32")
    full = os.environ.get("DAMJAX_SLOPE_FULL", "") not in ("", "0")
    window_anywhere = os.environ.get("DAMJAX_SLOPE_EXTRAPOLATE", "") not in ("", "0")
    on_cpu = jax.devices()[0].platform == "cpu"
    extrapolate = not full and (on_cpu or dry or window_anywhere)
    chunks, steps = _window()
    scn = _large_scenario()
    ens = from_scenario(scn, members=members)
    layout = eb.shared_layout(ens)
    n_steps = layout.n_steps
    if extrapolate:
        run_layout = dataclasses.replace(layout, chunk_steps=steps, n_chunks=chunks)
    else:
        run_layout = layout
        chunks, steps = layout.n_chunks - 1, layout.chunk_steps  # the first is the warm-up
    timed_steps = chunks * steps
    window = dict(chunks=chunks, chunk_steps=steps, warmup_chunks=1, steps=timed_steps)
    m = meta()

    # one run: the single-run path (damjax.core.loop.compile_chunk)
    t0 = time.perf_counter()
    models, states, _ = eb._build_members(ens, [0], layout)
    build_s = time.perf_counter() - t0
    one = jax.tree.map(lambda a: jax.numpy.asarray(a[0]), (models, states))
    n_particles = int(np.shape(one[1].opening)[-1])
    exe, compile_s = compile_chunk(one[0], one[1], run_layout.chunk_steps)
    peak_one = peak_bytes(exe)
    wall, _ = _timed_chunks(exe, one[0], one[1], chunks)
    per_step = wall / timed_steps
    one_wall = per_step * n_steps if extrapolate else wall
    rows = [
        dict(
            case="slope_large_single",
            **m,
            scenario=scn.name,
            length_m=scn.setup.length,
            width_m=scn.setup.width,
            dx=scn.setup.dx,
            duration_s=scn.setup.duration,
            n_particles=n_particles,
            n_steps=n_steps,
            extrapolated=extrapolate,
            window=window,
            build_time_s=round(build_s, 3),
            compile_time_s=round(compile_s, 3),
            window_time_s=round(wall, 3),
            s_per_step=round(per_step, 6),
            wall_time_s=round(one_wall, 3),
            particle_steps_per_s=round(n_particles * timed_steps / wall),
            peak_mib=_mib(peak_one),
        )
    ]
    del one, exe

    # the ensemble: damjax.ensemble's slices and compiled slice step
    devices = list(jax.local_devices())
    n_dev = len(devices)
    budget = int(eb.MEMORY_FRACTION * free_memory_bytes(devices[0]) / n_dev)
    per_dev = 1 if on_cpu else min(eb.MAX_PER_DEVICE, math.ceil(members / n_dev))
    runner = eb._Runner(run_layout, devices)
    while True:
        k = per_dev * n_dev
        mm, ss = eb._pad(models, k), eb._pad(states, k)
        runner.compile(*runner.put((mm, ss)))
        peak = peak_bytes(runner.compiled)
        if peak is None or peak <= budget or per_dev == 1:
            break
        per_dev = max(1, int(per_dev * budget / peak))
    k = per_dev * n_dev
    idx = list(range(min(k, members)))
    t0 = time.perf_counter()
    models, states, _ = eb._build_members(ens, idx, layout)
    build_s = time.perf_counter() - t0
    mm, ss = runner.put((eb._pad(models, k), eb._pad(states, k)))
    wall, _ = _timed_chunks(runner.compiled, mm, ss, chunks)
    n_slices = math.ceil(members / k)
    slice_wall = wall / timed_steps * n_steps if extrapolate else wall
    ens_wall = n_slices * slice_wall
    rows.append(
        dict(
            case="slope_large_ensemble",
            **m,
            scenario=scn.name,
            members=members,
            n_particles=n_particles,
            n_steps=n_steps,
            extrapolated=extrapolate,
            window=window,
            slice_size=k,
            slices=n_slices,
            slices_timed=1,
            slice_build_time_s=round(build_s, 3),
            compile_time_s=round(runner.compile_time_s, 3),
            window_time_s=round(wall, 3),
            wall_time_s=round(ens_wall, 3),
            particle_steps_per_s=round(k * n_particles * timed_steps / wall),
            ratio_over_single=round((k * per_step * timed_steps) / wall, 3),
            peak_mib_per_device=_mib(peak),
            mib_per_member=_mib(None if peak is None else peak / per_dev),
            budget_mib_per_device=_mib(budget),
        )
    )
    return rows
