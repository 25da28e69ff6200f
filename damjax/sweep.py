"""Batches of PSTs as one vmapped, jitted (and optionally sharded) computation.

    batch = damjax.PSTParams(strength_gradient=jnp.array([200., 500., 1000.]))
    results = damjax.sweep(batch, damjax.PSTSetup(length=60.0))

Every leaf of ``params_batch`` is either a scalar (shared by the batch) or an array with
a leading batch axis of length B (``strength_profile``: (B, m)). The batch shares one
layout and one time step (computed from the batch's largest wave speed), so a member
whose own dt would be larger runs with the batch's smaller dt.

Memory: ``batch_size`` runs the batch in slices of that size with `jax.lax.map`. Without
it the slice size comes from the compiled program's memory analysis, as an ensemble's
(`damjax.ensemble`): the whole batch vmapped when XLA's peak estimate fits in
``memory_fraction`` of the device's free memory, else the largest slice that fits (at
least one member); on a CPU slices of at most `CPU_SLICE` members, since a large vmapped
batch outgrows the caches. `damjax.last_sweep_plan()` returns that choice and the memory figures
of the last call (a `SweepPlan`).
Devices: the batch axis is sharded over every device with `jax.sharding`
(`NamedSharding` over a 1D mesh named "batch"), so the same call uses all GPUs of a
machine; on several hosts call `jax.distributed.initialize()` first and the mesh spans
all processes' devices.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from typing import Any

import jax
import numpy as np

from damjax import pst
from damjax._tracing import is_traced, under_staging
from damjax.core.loop import (
    MEMORY_FRACTION,
    RunInfo,
    cpu_compiler_options,
    free_memory_bytes,
    peak_bytes,
    run_chunk,
    temp_bytes,
)
from damjax.params import PROFILE_FIELDS, PSTParams, PSTSetup, specs
from damjax.validation import (
    InputError,
    Problem,
    _leaf_values,
    _members,
    dubious,
    expect_types,
    implausible,
    must_text,
    param_problems,
    raise_if,
    setup_problems,
    warn_notes,
)


def _member_suffix(index: list[int]) -> str:
    return f" (batch member{'s' if len(index) > 1 else ''} {_members(index)})"


def _leaf_problems(name: str, value: Any) -> list[Problem]:
    """A leaf's members that are not numbers, and members of different shapes (profiles
    of different lengths): checked before `broadcast_batch` converts the leaf to floats,
    which would take True as 1.0 and "500" as 500."""
    dtype = getattr(value, "dtype", None)
    if isinstance(value, jax.core.Tracer) or (dtype is not None and dtype.kind in "iuf"):
        return []  # a numeric array (sweep refuses traced leaves itself)
    profile = name in PROFILE_FIELDS
    spec = specs(PSTParams)[name]
    if isinstance(value, (list, tuple)):
        # a list of numbers is one profile; a list of sequences, a batch of them
        batched = not profile or any(_shape(v) != () for v in value)
        items = list(value) if batched else [value]
    elif dtype is not None and np.ndim(value) > (1 if profile else 0):
        items = [x.item() if isinstance(x, np.generic) else x for x in np.asarray(value)]
        batched = True
    else:
        batched, items = False, [value.item() if isinstance(value, np.generic) else value]
    bad = [i for i, v in enumerate(items) if _leaf_values(v) is None]
    if bad:
        first, suffix = items[bad[0]], _member_suffix(bad) if batched else ""
        if profile:
            reason = f"must be an array of >= 2 values [{spec.unit}]{suffix}"
            return [Problem(name, _shape(first), reason, form="shape")]
        return [Problem(name, first, must_text(f"{spec.valid_text} (a number)") + suffix)]
    by_shape: dict[Any, list[int]] = {}
    for i, v in enumerate(items):
        by_shape.setdefault(_shape(v), []).append(i)
    if len(by_shape) < 2:
        return []
    if profile and all(len(s) == 1 for s in by_shape):
        found = " and ".join(f"{s[0]} values{_member_suffix(i)}" for s, i in by_shape.items())
        reason = (
            f"${{{name}}}: profiles of different lengths in one batch, {found}: a batch of "
            "profiles is one (B, m) array; sample them on one grid (e.g. np.interp)"
        )
    else:
        found = " and ".join(f"shape {s}{_member_suffix(i)}" for s, i in by_shape.items())
        reason = f"${{{name}}}: members of different shapes in one batch, {found}"
    return [Problem(name, None, reason, form="line")]


def _shape(value: Any) -> Any:
    try:
        return np.shape(value)
    except ValueError:  # a ragged sequence
        return "ragged"


def batch_size_of(params: PSTParams) -> int:
    """Length B of the batch axis (1 if every leaf is a scalar); `InputError` where a
    member is not a number or the members' shapes differ."""
    raise_if(
        [
            p
            for f in dataclasses.fields(params)
            if getattr(params, f.name) is not None
            for p in _leaf_problems(f.name, getattr(params, f.name))
        ]
    )
    sizes: dict[int, list[str]] = {}
    for f in dataclasses.fields(params):
        v = getattr(params, f.name)
        if v is None:
            continue
        nd = np.ndim(v) - (1 if f.name in PROFILE_FIELDS else 0)
        if nd > 1:
            raise ValueError(
                f"params_batch.{f.name} has shape {np.shape(v)}: a batch is one leading "
                "axis (flatten a grid of parameters, e.g. with np.meshgrid(...).ravel())"
            )
        if nd == 1:
            if np.shape(v)[0] == 0:
                raise ValueError(f"params_batch.{f.name} is empty: a batch needs >= 1 member")
            sizes.setdefault(int(np.shape(v)[0]), []).append(f.name)
    if len(sizes) > 1:
        lengths = "; ".join(f"{', '.join(names)}: {n}" for n, names in sorted(sizes.items()))
        raise ValueError(
            f"params_batch: batched fields have different lengths ({lengths}); every "
            "batched field needs one value per member"
        )
    return next(iter(sizes)) if sizes else 1


def broadcast_batch(params: PSTParams, n: int) -> PSTParams:
    """Every leaf broadcast to a leading batch axis of length n (numpy arrays)."""
    kw = {}
    for f in dataclasses.fields(params):
        v = getattr(params, f.name)
        if v is None:
            kw[f.name] = None
            continue
        a = np.asarray(v, dtype=float)
        base_nd = 1 if f.name in PROFILE_FIELDS else 0
        if a.ndim == base_nd:
            a = np.broadcast_to(a, (n,) + a.shape)
        kw[f.name] = np.array(a)
    return PSTParams(**kw)


def member(params_batch: PSTParams, i: int) -> PSTParams:
    """The i-th member of a broadcast batch as scalar parameters."""
    kw = {}
    for f in dataclasses.fields(params_batch):
        v = getattr(params_batch, f.name)
        kw[f.name] = (
            None
            if v is None
            else (np.asarray(v)[i] if f.name in PROFILE_FIELDS else float(np.asarray(v)[i]))
        )
    return PSTParams(**kw)


def _given_members(params: PSTParams, n: int) -> list[PSTParams]:
    """The members as given: a shared leaf as it is, a batched one indexed in its own
    dtype, so that a member's lines show its values as written (float32 ones too)."""
    batched = {}
    for f in dataclasses.fields(params):
        v = getattr(params, f.name)
        if v is not None and np.ndim(v) > (1 if f.name in PROFILE_FIELDS else 0):
            batched[f.name] = np.asarray(v)
    return [dataclasses.replace(params, **{k: a[i] for k, a in batched.items()}) for i in range(n)]


def _member_notes(said: list[Problem], per_member: list[list[Problem]]) -> list[Problem]:
    """The members' own notes (a single run's warnings, which the batch's cannot give of
    batched values), one line per kind not said already: the first member's, naming
    every member that has it."""

    def kind(p: Problem) -> tuple[str, str | None, str]:
        return p.category, p.field, p.form

    known = {kind(p) for p in said}
    found: dict[tuple[str, str | None, str], tuple[Problem, list[int]]] = {}
    for i, notes in enumerate(per_member):
        for note in notes:
            if kind(note) not in known:
                found.setdefault(kind(note), (note, []))[1].append(i)
    return [
        dataclasses.replace(note, reason=note.reason + _member_suffix(index))
        for note, index in found.values()
    ]


_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _named(problems: list[Problem], members: list[PSTParams], setup: PSTSetup) -> list[Problem]:
    """The batch's problems naming the members that have them on their own, each as the
    first such member's (its own values: the batch checks the extremes across members);
    as they were where no member has one alone, or every member alike (a shared value)."""

    def key(p: Problem) -> tuple[Any, ...]:
        return p.field, p.form, p.what, _NUMBER.sub("#", p.reason)

    check_setup = None if setup_problems(setup) else setup
    own = [param_problems(m, check_setup) for m in members]
    out = []
    for p in problems:
        hits = [(i, q) for i, qs in enumerate(own) for q in qs if key(q) == key(p)]
        index = sorted({i for i, _ in hits})
        alike = len(index) == len(members) and len({q.text() for _, q in hits}) == 1
        if not hits or alike:
            out.append(p)
        else:
            first = hits[0][1]
            out.append(dataclasses.replace(first, reason=first.reason + _member_suffix(index)))
    return out


def _prepared(
    params_batch: PSTParams, batch: PSTParams, n: int, setup: PSTSetup, member_notes: bool
) -> pst.Prepared:
    """`pst.prepare` of the broadcast batch with its notes warned, and with
    ``member_notes`` each member's own; an invalid batch's problems name their members,
    and its members' notes on implausible values are warned (a unit mix-up is the likely
    cause), as a single run's (`pst._prepared_and_warned`)."""
    try:
        prep = pst.prepare(batch, setup, batch=True, caller="sweep")
    except InputError as exc:
        members = _given_members(params_batch, n)
        notes = list(exc.notes)
        if member_notes:
            notes += _member_notes(notes, [implausible(m) for m in members])
        warn_notes(notes, stacklevel=4)
        raise InputError(_named(exc.problems, members, setup), notes) from None
    notes = list(prep.notes)
    if member_notes:
        notes += _member_notes(notes, [dubious(m, setup) for m in _given_members(params_batch, n)])
    warn_notes(notes, stacklevel=4)
    return prep


@dataclasses.dataclass
class SweepPlan:
    """How `sweep` cut its batch (per device; `damjax.last_sweep_plan()` after a call).

    Attributes:
        members: batch members run (B).
        members_per_device: members each device runs, padding included.
        slice_size: members per `jax.lax.map` slice on a device (== members_per_device:
            the whole batch vmapped in one slice).
        chosen: "memory" (from XLA's estimate), "cpu" (`CPU_SLICE` members per slice on a
            CPU) or "given" (``batch_size``).
        peak_bytes_per_device: XLA's peak estimate of the compiled chunk that ran
            (None where the backend gives none).
        peak_bytes_whole_batch: the estimate for the whole batch vmapped (None when
            ``batch_size`` was given).
        budget_bytes_per_device: ``memory_fraction`` of the free memory, per device.
        devices: devices the batch is sharded over.
    """

    members: int
    members_per_device: int
    slice_size: int
    chosen: str
    peak_bytes_per_device: int | None
    peak_bytes_whole_batch: int | None
    budget_bytes_per_device: int
    devices: int

    @property
    def bytes_per_member(self) -> float | None:
        """Peak estimate per member on a device [bytes]: of the whole batch vmapped where
        that was compiled, else of the program that ran (every member's state and one
        slice's temporaries)."""
        peak = self.peak_bytes_whole_batch or self.peak_bytes_per_device
        return None if peak is None else peak / self.members_per_device


last_plan: SweepPlan | None = None
# members per slice on a CPU without ``batch_size``: 64 baseline PSTs (0.1 s) took
# 541 / 432 / 453 / 522 / 676 ms per member in slices of 4 / 8 / 16 / 32 / all 64, and in a
# second round 600 / 307 / 423 ms in slices of 4 / 8 / 16 (2-core AMD EPYC, 2026-11-26,
# `damjax.sweep(..., batch_size=...)`): a large vmapped batch outgrows the caches
CPU_SLICE = 8


def last_sweep_plan() -> SweepPlan | None:
    """How the last `damjax.sweep` call of this process cut its batch (None before one):
    the slice size, whether memory or ``batch_size`` chose it, and XLA's peak estimates."""
    return last_plan


def _slice_size(per_dev: int, peak: int | None, temp: int | None, budget: int) -> int:
    """The largest slice of a device's ``per_dev`` members whose estimate fits ``budget``:
    the arguments and outputs (every member's state) stay, the temporaries shrink in
    proportion to the slice."""
    if peak is None or peak <= budget or per_dev <= 1:
        return per_dev
    temp = peak if temp is None else temp
    fixed = peak - temp
    per_member = temp / per_dev
    if per_member <= 0:
        return per_dev
    return int(max(1, min(per_dev - 1, (budget - fixed) // per_member)))


def _mesh_sharding(n_devices: int) -> Any:
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    mesh = Mesh(np.array(jax.devices()[:n_devices]), ("batch",))
    return NamedSharding(mesh, PartitionSpec("batch"))


def sweep(
    params_batch: PSTParams,
    setup: PSTSetup | None = None,
    *,
    batch_size: int | None = None,
    shard: bool = True,
    progress: bool = False,
    memory_fraction: float = MEMORY_FRACTION,
) -> list[pst.PSTResult]:
    """Run a batch of PSTs; returns one `PSTResult` per member (same order).

    Args:
        params_batch: `PSTParams` with batched leaves (see the module doc).
        setup: shared numerics.
        batch_size: run in slices of this many members (`jax.lax.map`), bounding memory;
            default: from the compiled program's memory analysis (see the module doc).
        shard: shard the batch axis over all devices (a no-op on one device).
        progress: tqdm progress bar over the time chunks (off by default).
        memory_fraction: share of a device's free memory a slice may use, (0, 1] (only
            without ``batch_size``).
    """
    return _sweep(
        params_batch,
        setup,
        batch_size=batch_size,
        shard=shard,
        progress=progress,
        memory_fraction=memory_fraction,
    )


def _sweep(
    params_batch: PSTParams,
    setup: PSTSetup | None = None,
    *,
    batch_size: int | None = None,
    shard: bool = True,
    progress: bool = False,
    memory_fraction: float = MEMORY_FRACTION,
    member_notes: bool = True,
) -> list[pst.PSTResult]:
    """`sweep`; ``member_notes``: warn each member's own notes (`_prepared`), off where
    the caller made the batch itself (`damjax.gradient_check`'s window)."""
    global last_plan
    setup = PSTSetup() if setup is None else setup
    expect_types("sweep", params_batch=(params_batch, PSTParams), setup=(setup, PSTSetup))
    if batch_size is not None and (
        isinstance(batch_size, bool)
        or not isinstance(batch_size, (int, np.integer))
        or batch_size < 1
    ):
        raise ValueError(f"batch_size = {batch_size!r}: {must_text('[1, inf)', integer=True)}")
    if (
        isinstance(memory_fraction, bool)
        or not isinstance(memory_fraction, (int, float, np.floating))
        or not 0 < memory_fraction <= 1
    ):
        raise ValueError(f"memory_fraction = {memory_fraction!r}: {must_text('(0, 1]')}")
    if under_staging():
        raise TypeError(
            "sweep: called inside jax.jit (or another staging transform); it runs a batch "
            "on the host in compiled chunks. Inside jax.jit batch with jax.vmap(lambda p: "
            "damjax.simulate_pst(p, setup, layout=layout)), or call sweep outside the "
            "jitted function"
        )
    if is_traced(params_batch):
        raise TypeError(
            "sweep: called with traced parameters (inside jax.grad or jax.vmap); it runs a "
            "batch on the host in compiled chunks. Differentiate or batch "
            "damjax.simulate_pst instead, jax.grad(lambda p: damjax.simulate_pst(p, "
            "setup).arrest_position_smooth) or jax.vmap(lambda p: damjax.simulate_pst(p, "
            "setup, layout=layout)), or call sweep outside the transform"
        )
    n = batch_size_of(params_batch)
    batch = broadcast_batch(params_batch, n)
    prep = _prepared(params_batch, batch, n, setup, member_notes)
    layout = prep.layout

    n_dev = len(jax.devices()) if shard else 1
    pad = (-n) % n_dev
    leaves = jax.tree.map(
        lambda a: np.concatenate([a, np.repeat(a[-1:], pad, axis=0)]) if pad else a, batch
    )
    build = jax.vmap(lambda p: pst.build(p, setup, layout))  # layout.plastic: concrete batch
    models, states = jax.jit(build)(leaves)
    if n_dev > 1:
        sh = _mesh_sharding(n_dev)
        models, states = jax.device_put((models, states), sh)

    def one_chunk(model: Any, state: Any) -> tuple[Any, Any]:
        return run_chunk(model, state, layout.chunk_steps)

    def chunk_program(size: int | None) -> Any:
        """The jitted chunk over the batch, in `jax.lax.map` slices of ``size`` members
        per device (None: all of them vmapped)."""
        if size is None:
            body = jax.vmap(one_chunk)
        else:

            def body(models: Any, states: Any) -> tuple[Any, Any]:
                return jax.lax.map(lambda ms: one_chunk(*ms), (models, states), batch_size=size)

        if n_dev > 1:
            # each device runs its own members (shard_map): the transfers' batching rule
            # then scatters into the device's flat grid; under automatic partitioning the
            # flat (member x node) scatter would be gathered across devices (2 host
            # devices: 2.3x slower)
            from jax.sharding import PartitionSpec

            body = jax.shard_map(
                body,
                mesh=_mesh_sharding(n_dev).mesh,
                in_specs=PartitionSpec("batch"),
                out_specs=PartitionSpec("batch"),
            )
        # the states are donated: a chunk updates them in place (as a single run does)
        return jax.jit(body, donate_argnums=(1,), compiler_options=cpu_compiler_options())

    import time

    info = RunInfo()
    t0 = time.perf_counter()
    per_dev = (n + pad) // n_dev
    budget = int(memory_fraction * free_memory_bytes(jax.devices()[0]) / n_dev)
    whole = None
    if batch_size is not None:  # given: the old meaning, slices of batch_size members
        size = None if batch_size >= n + pad else int(batch_size)
        compiled = chunk_program(size).lower(models, states).compile()
        chosen, slice_size = "given", per_dev if size is None else min(size, per_dev)
    else:
        on_cpu = all(d.platform == "cpu" for d in jax.devices()[:n_dev])
        if on_cpu and per_dev > CPU_SLICE:
            # on a CPU a large vmapped batch outgrows the caches (see CPU_SLICE)
            slice_size, chosen = CPU_SLICE, "cpu"
            compiled = chunk_program(slice_size).lower(models, states).compile()
        else:
            slice_size, chosen = per_dev, "memory"
            compiled = chunk_program(None).lower(models, states).compile()
            whole = peak_bytes(compiled)
        for _ in range(3):  # the temporaries shrink about in proportion to the slice
            new = _slice_size(slice_size, peak_bytes(compiled), temp_bytes(compiled), budget)
            if new >= slice_size:
                break
            slice_size, chosen = new, "memory"
            compiled = chunk_program(slice_size).lower(models, states).compile()
        peak = peak_bytes(compiled)
        if peak is not None and peak > budget:
            warnings.warn(
                f"sweep: XLA's peak estimate {peak / 2**20:.0f} MiB per device (slices of "
                f"{slice_size}) exceeds memory_fraction x free memory = {budget / 2**20:.0f} "
                "MiB; the members' states alone may not fit: run fewer members per call",
                stacklevel=2,
            )
    last_plan = SweepPlan(
        members=n,
        members_per_device=per_dev,
        slice_size=slice_size,
        chosen=chosen,
        peak_bytes_per_device=peak_bytes(compiled),
        peak_bytes_whole_batch=whole,
        budget_bytes_per_device=budget,
        devices=n_dev,
    )
    info.compile_time_s = time.perf_counter() - t0
    bar = None
    if progress:
        from damjax._progress import progress_bar as tqdm

        bar = tqdm(total=layout.n_steps, unit="step", unit_scale=True, desc=f"sweep x{n}")
    tips, snaps = [], []
    t0 = time.perf_counter()
    for _ in range(layout.n_chunks):
        states, tip = compiled(models, states)
        tips.append(np.asarray(tip))
        snaps.append(jax.tree.map(np.asarray, jax.vmap(pst._snapshot)(models, states)))
        if bar is not None:
            bar.update(layout.chunk_steps)
    jax.block_until_ready(states)
    info.wall_time_s = time.perf_counter() - t0
    if bar is not None:
        bar.close()
    tips_all = np.concatenate(tips, axis=1)  # (B, n_steps)
    # members are sliced from host copies: indexing a sharded array is a cross-device
    # gather, one collective per leaf and member, and XLA:CPU's host devices could stall
    # in such a collective's rendezvous on a busy machine (2026-11-26, 4 host devices on
    # 2 cores beside other XLA processes)
    models, states = jax.device_get((models, states))
    results = []
    for i in range(n):
        take = lambda x, i=i: x[i]  # noqa: E731
        m_i = jax.tree.map(take, models)
        s_i = jax.tree.map(take, states)
        snaps_i = [jax.tree.map(take, s) for s in snaps]
        info_i = RunInfo()
        info_i.compile_time_s = info.compile_time_s
        info_i.wall_time_s = info.wall_time_s / n  # per simulation
        info_i.steps_done = layout.n_steps
        results.append(
            pst.finish(member(batch, i), setup, layout, m_i, s_i, tips_all[i], snaps_i, info_i)
        )
    return results


__all__ = ["sweep", "SweepPlan", "batch_size_of", "broadcast_batch", "member"]
