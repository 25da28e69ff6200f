"""Several processes (hosts) on one job, with `jax.distributed`.

Every process runs the same program. `initialize` connects it to the others through a
coordinator (process 0's address); each process then drives only its own devices
(`jax.local_devices()`) and takes its share of the work items (`share`: item ``i`` goes
to process ``i % process_count``). Results meet either on a shared file system (the
ensemble's slice files, `damjax.ensemble`) or through `allgather_objects`, and `barrier`
lines the processes up. Both go through the coordinator's key-value store and barriers
(host memory and TCP), not through device collectives: NCCL refuses two ranks on one GPU,
so device collectives would fail for several processes sharing one GPU, and a host-side
exchange of pickled results gains nothing from them.

Start the processes

- under SLURM: ``srun -N 2 --ntasks-per-node=1 damjax ensemble SCN --members 64
  --distributed`` (or ``jax.distributed.initialize()`` with no arguments in Python):
  JAX reads the coordinator, the process count and the process id from SLURM's
  variables (one process per task; each task sees the GPUs SLURM gives it);
- by hand, on any machines that reach each other: pick a free port on the first one and
  start process ``i`` of ``n`` with ``--coordinator HOST:PORT --num-processes n
  --process-id i`` (``damjax.distributed.initialize("HOST:PORT", n, i)`` in Python).

Why `jax.distributed` (and not Dask or Ray): the work is SPMD over identical members,
every process already holds JAX devices, and it needs no extra service or dependency.
Failure recovery is by restart: when a process dies, the coordinator's heartbeat stops
the others (within a minute) and the job is started again; what finished is on disk
(one file per finished slice of members) and is not run again. Dask or Ray would
re-queue a dead worker's slice without stopping the rest, which saves at most one slice
of work per failure, at the cost of a scheduler to run next to the devices and of
re-compiling the step in every fresh worker (the compile is 10-20 % of a slice).
"""

from __future__ import annotations

import dataclasses
import pickle
from collections.abc import Sequence
from typing import Any

import jax
import numpy as np

_STATE = {"initialized": False}


def initialize(
    coordinator_address: str | None = None,
    num_processes: int | None = None,
    process_id: int | None = None,
) -> None:
    """Join a multi-process job (`jax.distributed.initialize`); call it before any
    computation. No arguments: the cluster is detected (SLURM, Open MPI, ...). A second
    call is a no-op. On CPU the processes exchange data with gloo."""
    if _STATE["initialized"]:
        return
    given = [coordinator_address is None, num_processes is None, process_id is None]
    if any(given) and not all(given):
        raise ValueError(
            "coordinator_address, num_processes and process_id: give all three (a manual "
            "start) or none (a detected cluster such as SLURM)"
        )
    if num_processes is not None:
        if (
            isinstance(num_processes, bool)
            or not isinstance(num_processes, int)
            or num_processes < 1
        ):
            raise ValueError(f"num_processes = {num_processes!r}: must be an integer >= 1")
        if (
            isinstance(process_id, bool)
            or not isinstance(process_id, int)
            or not 0 <= process_id < num_processes
        ):
            raise ValueError(
                f"process_id = {process_id!r}: must be an integer in [0, {num_processes - 1}]"
            )
    try:
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
    except (AttributeError, ValueError):  # pragma: no cover - older JAX
        pass
    jax.distributed.initialize(
        coordinator_address=coordinator_address,
        num_processes=num_processes,
        process_id=process_id,
    )
    _STATE["initialized"] = True


def process_index() -> int:
    """This process's index (0 on a single process)."""
    return int(jax.process_index())


def process_count() -> int:
    """Number of processes in the job (1 on a single process)."""
    return int(jax.process_count())


def share(items: Sequence[Any], index: int | None = None, count: int | None = None) -> list[Any]:
    """This process's items: every ``count``-th one from ``index`` (round robin, so the
    shares differ by at most one item)."""
    index = process_index() if index is None else index
    count = process_count() if count is None else count
    return list(items)[index::count]


# how long a process waits for the others at a barrier or a gather [ms]: the work between
# two meetings (a slice of members, a process's share of a sweep) may take hours; a
# process that dies stops the others through the coordinator's heartbeat well before
TIMEOUT_MS = 24 * 3600 * 1000
# every process makes the same calls in the same order (SPMD), so a counter per kind of
# call gives the keys and barrier ids that the processes share, each used once
_CALLS = {"barrier": 0, "gather": 0}


def _client() -> Any:
    """The coordination-service client of `jax.distributed` (None before `initialize`)."""
    from jax._src import distributed as jax_distributed

    return jax_distributed.global_state.client


def _next(kind: str) -> int:
    _CALLS[kind] += 1
    return _CALLS[kind]


def barrier(name: str) -> None:
    """Wait until every process reaches the barrier of this name (no-op on one)."""
    if process_count() == 1:
        return
    client = _client()
    if client is None:  # pragma: no cover - several processes without jax.distributed
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)
        return
    client.wait_at_barrier(f"damjax/{name}/{_next('barrier')}", TIMEOUT_MS)


def allgather_objects(obj: Any) -> list[Any]:
    """Every process's ``obj`` (picklable), in process order, on every process.

    Each process puts its pickled ``obj`` in the coordinator's key-value store and reads
    the others'; a barrier then lets each delete its own entry."""
    count = process_count()
    if count == 1:
        return [obj]
    client = _client()
    if client is None:  # pragma: no cover - several processes without jax.distributed
        from jax.experimental import multihost_utils

        data = np.frombuffer(pickle.dumps(obj), dtype=np.uint8)
        sizes = np.asarray(multihost_utils.process_allgather(np.array([data.size], np.int64)))
        buf = np.zeros(int(sizes.max()), np.uint8)
        buf[: data.size] = data
        allbuf = np.asarray(multihost_utils.process_allgather(buf))
        return [pickle.loads(allbuf[i, : int(sizes[i, 0])].tobytes()) for i in range(count)]
    call = _next("gather")
    key = f"damjax/allgather/{call}/"
    me = process_index()
    client.key_value_set_bytes(key + str(me), pickle.dumps(obj))
    out = [
        obj
        if i == me
        else pickle.loads(client.blocking_key_value_get_bytes(key + str(i), TIMEOUT_MS))
        for i in range(count)
    ]
    client.wait_at_barrier(f"damjax/allgather-read/{call}", TIMEOUT_MS)
    client.key_value_delete(key + str(me))
    return out


def sweep(params_batch: Any, setup: Any = None, **kwargs: Any) -> list[Any]:
    """`damjax.sweep` over the processes of a job: member ``i`` runs on process
    ``i % process_count()`` (on that process's devices), and every process returns the
    whole batch's results in member order (`allgather_objects`). ``kwargs``: those of
    `damjax.sweep` (batch_size, shard, progress). On one process it is `damjax.sweep`."""
    import importlib

    sweep_fn = importlib.import_module("damjax.sweep").sweep
    if process_count() == 1:
        return sweep_fn(params_batch, setup, **kwargs)
    from damjax.sweep import batch_size_of, broadcast_batch

    n = batch_size_of(params_batch)
    batch = broadcast_batch(params_batch, n)
    mine = share(range(n))
    results: list[Any] = []
    if mine:
        sub = dataclasses.replace(
            batch,
            **{
                f.name: (None if getattr(batch, f.name) is None else getattr(batch, f.name)[mine])
                for f in dataclasses.fields(batch)
            },
        )
        # damjax.sweep shards over jax.devices(), which spans every process
        kwargs = {**kwargs, "shard": False}
        results = sweep_fn(sub, setup, **kwargs)
    gathered = allgather_objects(list(zip(mine, results, strict=True)))
    out: list[Any] = [None] * n
    for part in gathered:
        for i, r in part:
            out[i] = r
    return out


__all__ = [
    "allgather_objects",
    "barrier",
    "initialize",
    "process_count",
    "process_index",
    "share",
    "sweep",
]
