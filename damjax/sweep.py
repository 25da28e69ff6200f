"""Batches of PSTs as one vmapped, jitted (and optionally sharded) computation.

    batch = damjax.PSTParams(strength_gradient=jnp.array([200., 500., 1000.]))
    results = damjax.sweep(batch, damjax.PSTSetup(length=60.0))

Every leaf of ``params_batch`` is either a scalar (shared by the batch) or an array with
a leading batch axis of length B (``strength_profile``: (B, m)). The batch shares one
layout and one time step (computed from the batch's largest wave speed), so a member
whose own dt would be larger runs with the batch's smaller dt.

Memory: ``batch_size`` runs the batch in slices of that size with `jax.lax.map`.
Devices: the batch axis is sharded over every device with `jax.sharding`
(`NamedSharding` over a 1D mesh named "batch"), so the same call uses all GPUs of a
machine; on several hosts call `jax.distributed.initialize()` first and the mesh spans
all processes' devices.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import numpy as np

from damjax import pst
from damjax.core.loop import RunInfo, cpu_compiler_options, run_chunk
from damjax.params import PROFILE_FIELDS, PSTParams, PSTSetup
from damjax.validation import ensure_x64, must_text, validate


def batch_size_of(params: PSTParams) -> int:
    """Length B of the batch axis (1 if every leaf is a scalar)."""
    sizes = set()
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
            sizes.add(int(np.shape(v)[0]))
    if len(sizes) > 1:
        raise ValueError(f"params_batch: batched fields have different lengths {sorted(sizes)}")
    return sizes.pop() if sizes else 1


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
) -> list[pst.PSTResult]:
    """Run a batch of PSTs; returns one `PSTResult` per member (same order).

    Args:
        params_batch: `PSTParams` with batched leaves (see the module doc).
        setup: shared numerics.
        batch_size: run in slices of this many members (`jax.lax.map`), bounding memory.
        shard: shard the batch axis over all devices (a no-op on one device).
        progress: tqdm progress bar over the time chunks (off by default).
    """
    setup = PSTSetup() if setup is None else setup
    if batch_size is not None and (
        isinstance(batch_size, bool)
        or not isinstance(batch_size, (int, np.integer))
        or batch_size < 1
    ):
        raise ValueError(f"batch_size = {batch_size!r}: {must_text('[1, inf), integers')}")
    n = batch_size_of(params_batch)
    batch = broadcast_batch(params_batch, n)
    validate(batch, setup, batch=True)
    ensure_x64(setup.dtype)
    layout = pst.make_layout(batch, setup)

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

    if batch_size is None or batch_size >= n + pad:
        body = jax.vmap(one_chunk)
    else:

        def body(models: Any, states: Any) -> tuple[Any, Any]:
            return jax.lax.map(lambda ms: one_chunk(*ms), (models, states), batch_size=batch_size)

    if n_dev > 1:
        # each device runs its own members (shard_map): the transfers' batching rule then
        # scatters into the device's flat grid; under automatic partitioning the flat
        # (member x node) scatter would be gathered across devices (2 host devices: 2.3x
        # slower)
        from jax.sharding import PartitionSpec

        body = jax.shard_map(
            body,
            mesh=_mesh_sharding(n_dev).mesh,
            in_specs=PartitionSpec("batch"),
            out_specs=PartitionSpec("batch"),
        )
    chunk_fn = jax.jit(body, compiler_options=cpu_compiler_options())

    import time

    info = RunInfo()
    t0 = time.perf_counter()
    compiled = chunk_fn.lower(models, states).compile()
    info.compile_time_s = time.perf_counter() - t0
    bar = None
    if progress:
        from tqdm.auto import tqdm

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


__all__ = ["sweep", "batch_size_of", "broadcast_batch", "member"]
