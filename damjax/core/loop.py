"""The time loop: `lax.scan` over fixed-shape state, in chunks.

Two drivers share one chunk function:

- `integrate`: a host loop over jitted chunks (progress bar, early stop on a runtime
  fault, compile time measured separately). What the CLI and `simulate_pst` use.
- `integrate_pure`: one traceable function (outer scan over chunks, inner scan over
  steps, `jax.checkpoint` around each chunk) for `jax.grad`, `jax.vmap` and sharding.
  Reverse mode stores one state per chunk and recomputes a chunk's steps in the
  backward pass, so memory is O(n_chunks + chunk_steps) states, not O(n_steps).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax.core.state import Model, State
from damjax.core.step import step

Snapshot = Callable[[Model, State], Any]


def run_chunk(model: Model, state: State, n_steps: int) -> tuple[State, Any]:
    """Advance ``n_steps`` steps; returns the final state and the crack tip per step."""

    def body(s: State, _: Any) -> tuple[State, Any]:
        s = step(model, s)
        return s, s.tip

    return jax.lax.scan(body, state, None, length=n_steps)


_run_chunk_jit = jax.jit(run_chunk, static_argnums=2, donate_argnums=1)
_compiled: dict[Any, Any] = {}


def _signature(tree: Any) -> Any:
    leaves, treedef = jax.tree.flatten(tree)
    return treedef, tuple((np.shape(x), str(getattr(x, "dtype", type(x)))) for x in leaves)


def cpu_compiler_options() -> dict[str, Any]:
    """XLA:CPU options damjax compiles its own executables with (time loop, sweeps,
    calibration gradients): 512-bit vectors where the CPU has AVX-512 (LLVM's default
    prefers 256; measured on a 2-core Xeon: 1D baseline step 180 -> 169 us). Pass them to
    your own ``jax.jit(..., compiler_options=cpu_compiler_options())`` of a damjax run
    (e.g. a gradient through `integrate_pure`). Empty on other CPUs and backends."""
    if not _HAS_AVX512 or jax.default_backend() != "cpu":
        return {}
    return {"xla_cpu_prefer_vector_width": 512}


def _avx512() -> bool:
    try:
        with open("/proc/cpuinfo") as f:
            return any(line.startswith("flags") and " avx512f" in line for line in f)
    except OSError:  # not Linux: leave XLA's default
        return False


_HAS_AVX512 = _avx512()


def compile_chunk(model: Model, state: State, n_steps: int) -> tuple[Any, float]:
    """Ahead-of-time compiled chunk and the compile time [s] (0 when cached)."""
    key = (_signature((model, state)), n_steps)
    if key in _compiled:
        return _compiled[key], 0.0
    t0 = _time.perf_counter()
    exe = _run_chunk_jit.lower(model, state, n_steps).compile(
        compiler_options=cpu_compiler_options()
    )
    dt = _time.perf_counter() - t0
    _compiled[key] = exe
    return exe, dt


MEMORY_FRACTION = 0.5  # of the free memory a batch slice (sweep, ensemble) may use


def free_memory_bytes(device: Any) -> int:
    """Free memory of ``device`` [bytes]: the allocator's limit less what is in use where
    the backend reports it (GPUs), else the host's available memory (``MemAvailable``),
    else 4 GiB."""
    stats = None
    try:
        stats = device.memory_stats()
    except Exception:  # noqa: BLE001 - backends without stats
        stats = None
    if stats and "bytes_limit" in stats:
        return int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0))
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 4 << 30


def peak_bytes(compiled: Any) -> int | None:
    """XLA's estimate of a compiled program's peak memory per device [bytes]: arguments,
    outputs and temporaries less the donated (aliased) buffers; None where the backend
    gives no memory analysis."""
    m = _memory_analysis(compiled)
    if m is None:
        return None
    return int(
        m.argument_size_in_bytes
        + m.output_size_in_bytes
        + m.temp_size_in_bytes
        - m.alias_size_in_bytes
    )


def temp_bytes(compiled: Any) -> int | None:
    """The temporaries of `peak_bytes` alone (what a smaller batch slice shrinks)."""
    m = _memory_analysis(compiled)
    return None if m is None else int(m.temp_size_in_bytes)


def _memory_analysis(compiled: Any) -> Any:
    try:
        return compiled.memory_analysis()
    except Exception:  # noqa: BLE001
        return None


def compile_snapshot(snapshot: Snapshot, model: Model, state: State) -> tuple[Any, float]:
    """`snapshot` compiled ahead of time for these shapes, and the compile time [s] (0 when
    cached). Run eagerly, each of its ops compiled on first use inside the timed loop
    (0.1-0.2 s of a 7 s baseline PST, every process)."""
    key = (snapshot, _signature((model, state)))
    if key in _compiled:
        return _compiled[key], 0.0
    t0 = _time.perf_counter()
    exe = jax.jit(snapshot).lower(model, state).compile()
    dt = _time.perf_counter() - t0
    _compiled[key] = exe
    return exe, dt


class RunInfo:
    """Timings and bookkeeping of a host-driven integration."""

    def __init__(self) -> None:
        self.compile_time_s = 0.0
        self.wall_time_s = 0.0
        self.steps_done = 0
        self.stopped_early = False


def integrate(
    model: Model,
    state: State,
    n_chunks: int,
    chunk_steps: int,
    snapshot: Snapshot | None = None,
    progress: bool = False,
    callback: Callable[[int, State, list[Any], list[Any]], None] | None = None,
    start_chunk: int = 0,
    history: tuple[list[Any], list[Any]] | None = None,
) -> tuple[State, np.ndarray, list[Any], RunInfo]:
    """Run chunks ``start_chunk .. n_chunks-1`` on the host; stop at the first fault.

    Returns the final state, the crack tip after every step done (numpy), the snapshots
    taken at the end of every chunk, and timings. ``callback(chunk, state, tips, snaps)``
    runs after each chunk with the per-chunk tip arrays and snapshots so far
    (checkpointing). ``history``: the per-chunk tips and snapshots of the chunks before
    ``start_chunk`` (a resumed run); they lead every list passed on and returned.
    """
    info = RunInfo()
    exe = None
    if start_chunk < n_chunks:  # a finished run resumed at its end compiles nothing
        exe, info.compile_time_s = compile_chunk(model, state, chunk_steps)
        if snapshot is not None:
            snapshot, t_snap = compile_snapshot(snapshot, model, state)
            info.compile_time_s += t_snap
    tips: list[np.ndarray] = list(history[0]) if history is not None else []
    snaps: list[Any] = list(history[1]) if history is not None else []
    bar = None
    if progress:
        from damjax._progress import progress_bar as tqdm

        bar = tqdm(
            total=n_chunks * chunk_steps,
            initial=start_chunk * chunk_steps,
            unit="step",
            unit_scale=True,
            desc="damjax",
        )
    t0 = _time.perf_counter()
    try:
        for c in range(start_chunk, n_chunks):
            assert exe is not None
            state, tip = exe(model, state)
            tips.append(np.asarray(tip))
            info.steps_done += chunk_steps
            if snapshot is not None:
                snaps.append(jax.tree.map(np.asarray, snapshot(model, state)))
            if bar is not None:
                bar.update(chunk_steps)
            if callback is not None:
                callback(c, state, tips, snaps)
            if int(state.fault) != 0:
                info.stopped_early = True
                break
        jax.block_until_ready(state)
    finally:
        if bar is not None:
            bar.close()
    info.wall_time_s = _time.perf_counter() - t0
    tip_all = np.concatenate(tips) if tips else np.zeros((0,))
    return state, tip_all, snaps, info


def _block(n: int, target: int = 50) -> int:
    """Largest divisor of n that is at most target."""
    return max(d for d in range(1, min(n, target) + 1) if n % d == 0)


def integrate_pure(
    model: Model,
    state: State,
    n_chunks: int,
    chunk_steps: int,
    checkpoint: bool | str = True,
) -> tuple[State, Any]:
    """Traceable integration: returns the final state and the tip per step (n_steps,).

    Reverse mode (``checkpoint``):

    - ``True`` / ``"steps"`` (default): segments of K ~ sqrt(n_steps) steps (a divisor
      of ``chunk_steps``) are checkpointed, and so is every step inside them. The
      backward pass stores one state per segment, then, segment by segment, one state
      per step plus its P2G grid arrays (named ``"p2g"`` in `damjax.core.step.step`),
      and recomputes each step's particle work, without the scatters, right before its
      transpose: no per-step residual stacks (a step has ~70 particle-sized residuals;
      writing and reading them cost more than a forward step). Memory O(n_steps / K +
      K) states. Baseline PST gradient: 4.9 x the forward run, against 6.9 x for
      ``"blocks"`` (benchmarks/README.md).
    - ``"blocks"``: the earlier two-level scheme, one state per chunk and one per block of
      <= 50 steps, with the residuals of a block stored.
    - ``False``: no rematerialisation (memory O(n_steps) residuals; small runs only).
    """
    if checkpoint is True:
        checkpoint = "steps"
    n_steps = n_chunks * chunk_steps
    if checkpoint == "steps":
        seg = _block(chunk_steps, max(1, round(n_steps**0.5)))

        def step_b(model: Model, s: State) -> State:
            # measured 6 % faster gradients: the recomputed step reads the stored state
            # once instead of slicing the per-step stack inside many fusions
            return step(model, jax.lax.optimization_barrier(s))

        step_ck = jax.checkpoint(
            step_b, prevent_cse=False, policy=jax.checkpoint_policies.save_only_these_names("p2g")
        )

        def one(s: State, _: Any) -> tuple[State, Any]:
            s = step_ck(model, s)
            return s, s.tip

        def segment(s: State, _: Any) -> tuple[State, Any]:
            return jax.lax.scan(one, s, None, length=seg)

        final, tips = jax.lax.scan(
            jax.checkpoint(segment, prevent_cse=False), state, None, length=n_steps // seg
        )
        return final, jnp.reshape(tips, (-1,))
    if checkpoint not in ("blocks", False):
        raise ValueError(f"checkpoint must be True, 'steps', 'blocks' or False, got {checkpoint!r}")
    ck = checkpoint == "blocks"
    block = _block(chunk_steps)

    def run_block(s: State, _: Any) -> tuple[State, Any]:
        return run_chunk(model, s, block)

    def chunk(s: State, _: Any) -> tuple[State, Any]:
        body = jax.checkpoint(run_block, prevent_cse=False) if ck else run_block
        s, tips = jax.lax.scan(body, s, None, length=chunk_steps // block)
        return s, jnp.reshape(tips, (-1,))

    if ck:
        chunk = jax.checkpoint(chunk, prevent_cse=False)
    final, tips = jax.lax.scan(chunk, state, None, length=n_chunks)
    return final, jnp.reshape(tips, (-1,))
