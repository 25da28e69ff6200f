"""Transfer-layout experiments on the mpm88 problem (XLA:CPU).

    python -m benchmarks.experiments_transfer reduce          # stencil-axis reductions
    python -m benchmarks.experiments_transfer scatter         # P2G scatter formulations
    python -m benchmarks.experiments_transfer substep [N ...] # whole mpm88 substeps
    python -m benchmarks.experiments_transfer taichi [N ...]  # best variant vs Taichi
    python -m benchmarks.experiments_transfer shard [N ...]   # 2 host devices, shard_map
    python -m benchmarks.experiments_transfer breakdown [N ...] # cumulative cost of C's pieces
    python -m benchmarks.experiments_transfer pst [DIM ...]   # damjax's PST step, 3 versions

Every experiment alternates its variants round-robin in one process and prints the median
(and minimum) over the rounds, one JSON line per (experiment, N, variant). Results and
conclusions: benchmarks/README.md, "mpm88 and transfer-layout experiments".

The substep variants all compute the mpm88 substep of ``benchmarks/mpm88.py``; each checks
its final state against variant 0 (``max_abs_diff_x``).
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

# `shard` needs two host devices; the flag must be set before jax is imported.
if len(sys.argv) > 1 and sys.argv[1] == "shard":
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2"
    )

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from benchmarks import mpm88  # noqa: E402
from benchmarks.mpm88 import BOUND, DT, DX, GRAVITY, INV_DX, N_GRID, P_MASS, P_VOL, E  # noqa: E402

NN = N_GRID * N_GRID
OFF = np.array([(i, j) for i in range(3) for j in range(3)], np.int32)  # transfer.offsets(2)
OFF_FLAT = OFF[:, 0] * N_GRID + OFF[:, 1]


def timeit_rounds(fns: dict[str, tuple[Callable, tuple]], rounds: int) -> dict[str, list[float]]:
    """Warm every function, then time them round-robin; seconds per call."""
    for f, a in fns.values():
        jax.block_until_ready(f(*a))
    ts: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(rounds):
        for k, (f, a) in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(*a))
            ts[k].append(time.perf_counter() - t0)
    return ts


def emit(**row: Any) -> None:
    print(json.dumps(row), flush=True)


# --------------------------------------------------------------------------------------------
# building blocks
# --------------------------------------------------------------------------------------------


def rsum(a: Any) -> Any:
    """Sum over the leading (stencil) axis as an unrolled chain of elementwise adds."""
    out = a[0]
    for k in range(1, a.shape[0]):
        out = out + a[k]
    return out


def stencil_bcast(x: Any) -> tuple[Any, Any, Any, Any]:
    """transfer.stencil's (idx, w, dpos) built by broadcasting instead of stacking 9 pieces.

    Returns (flat base node (n,), idx (9, n), w (9, n), dpos (2, 9, n)).
    """
    s = x * INV_DX
    fl = jnp.floor(s - 0.5)
    fx = s - fl
    b = fl.astype(jnp.int32)
    w1 = jnp.stack([0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2])
    n = x.shape[-1]
    w = (w1[:, None, 0, :] * w1[None, :, 1, :]).reshape(9, n)
    flat = b[0] * N_GRID + b[1]
    idx = flat[None] + jnp.asarray(OFF_FLAT)[:, None]
    dpos = (jnp.asarray(OFF.T, x.dtype)[:, :, None] - fx[:, None, :]) * DX
    return flat, idx, w, dpos


def stencil_stacked(x: Any) -> tuple[Any, Any, Any, Any]:
    """damjax.core.transfer.stencil as committed in b66a697 (stacked (S, n) arrays, each
    built by stacking S pieces), specialised to cell0 = 0, frac0 = 0, 2D, non-periodic.

    Returns (flat base node (n,), idx (9, n), w (9, n), dpos (2, 9, n)).
    """
    s = x * INV_DX
    fl = jnp.floor(s - 0.5)
    fx = s - fl
    base = fl.astype(jnp.int32)
    w1 = (0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2)
    idx, w, dpos = [], [], []
    for o in OFF:
        w.append(w1[o[0]][0] * w1[o[1]][1])
        idx.append((base[0] + int(o[0])) * N_GRID + (base[1] + int(o[1])))
        dpos.append(jnp.stack([(int(o[d]) - fx[d]) * DX for d in range(2)]))
    flat = base[0] * N_GRID + base[1]
    return flat, jnp.stack(idx), jnp.stack(w), jnp.stack(dpos, axis=1)


def p2g_values(state: tuple, w: Any, dpos: Any) -> Any:
    """(3, 9, n): mass, x- and y-momentum contributions of every stencil node."""
    x, v, C, J = state
    stress = (-DT * 4 * E * P_VOL) * (J - 1.0) / DX**2
    a00 = stress + P_MASS * C[0, 0]
    a11 = stress + P_MASS * C[1, 1]
    a01, a10 = P_MASS * C[0, 1], P_MASS * C[1, 0]
    qx = P_MASS * v[0][None] + a00[None] * dpos[0] + a01[None] * dpos[1]
    qy = P_MASS * v[1][None] + a10[None] * dpos[0] + a11[None] * dpos[1]
    return jnp.stack([w * P_MASS, w * qx, w * qy])


def grid_update(grid: Any) -> tuple[Any, Any]:
    """mpm88's grid step on (3, NN) [mass, px, py]: velocities with gravity and wall clamps."""
    node = jnp.arange(NN, dtype=jnp.int32)
    i, j = node // N_GRID, node % N_GRID
    m = grid[0]
    has_m = m > 0
    inv_m = 1.0 / jnp.where(has_m, m, 1.0)
    gx = jnp.where(has_m, grid[1] * inv_m, grid[1])
    gy = jnp.where(has_m, grid[2] * inv_m, grid[2]) - DT * GRAVITY
    gx = jnp.where(((i < BOUND) & (gx < 0)) | ((i > N_GRID - BOUND) & (gx > 0)), 0.0, gx)
    gy = jnp.where(((j < BOUND) & (gy < 0)) | ((j > N_GRID - BOUND) & (gy > 0)), 0.0, gy)
    return gx, gy


def g2p_finish(state: tuple, w: Any, dpos: Any, vx: Any, vy: Any, reduce=rsum) -> tuple:
    """New (x, v, C, J) from the gathered stencil velocities vx, vy (9, n)."""
    x, _, _, J = state
    k = 4.0 * INV_DX**2
    new_v = jnp.stack([reduce(w * vx), reduce(w * vy)])
    new_C = jnp.stack(
        [jnp.stack([k * reduce(w * g * dpos[b]) for b in range(2)]) for g in (vx, vy)]
    )
    x = x + DT * new_v
    J = J * (1.0 + DT * (new_C[0, 0] + new_C[1, 1]))
    return x, new_v, new_C, J


def sum0(a: Any) -> Any:
    return jnp.sum(a, axis=0)


# P2G formulations: (flat, idx, vals (3, 9, n)) -> grid (3, NN)


def p2g_scalar3(flat, idx, vals):
    """damjax today: one scalar scatter-add of 9n elements per channel."""
    i = idx.ravel()
    return jnp.stack([jnp.zeros((NN,), vals.dtype).at[i].add(vals[c].ravel()) for c in range(3)])


def p2g_one27(flat, idx, vals):
    """One scalar scatter of 27n elements into a (3 NN,) grid (channel folded into the index)."""
    i = (idx[None] + NN * jnp.arange(3, dtype=jnp.int32)[:, None, None]).ravel()
    return jnp.zeros((3 * NN,), vals.dtype).at[i].add(vals.ravel()).reshape(3, NN)


def p2g_rows3(flat, idx, vals):
    """One scatter of 9n rows of 3 channels into (NN, 3)."""
    upd = jnp.moveaxis(vals, 0, -1).reshape(-1, 3)
    return jnp.zeros((NN, 3), vals.dtype).at[idx.ravel()].add(upd).T


def p2g_segment_sorted(flat, idx, vals):
    """Per offset and channel a segment_sum of n values with indices_are_sorted=True (valid
    when the particles are sorted by base cell)."""
    return jnp.stack(
        [
            sum(
                jax.ops.segment_sum(vals[c, k], idx[k], NN, indices_are_sorted=True)
                for k in range(9)
            )
            for c in range(3)
        ]
    )


def _shift_sum(cell: Any) -> Any:
    """(NN, 3, 9) per-base-cell sums -> (3, NN) node sums by 9 dense shifted adds."""
    cell = cell.reshape(N_GRID, N_GRID, 3, 9)
    out = jnp.zeros((3, N_GRID + 2, N_GRID + 2), cell.dtype)
    for k, (i, j) in enumerate(OFF):
        out = out.at[:, i : i + N_GRID, j : j + N_GRID].add(jnp.moveaxis(cell[..., k], -1, 0))
    return out[:, :N_GRID, :N_GRID].reshape(3, NN)


def p2g_cellrows(flat, idx, vals):
    """One scatter of n rows of 27 values by base cell, then 9 dense shifted adds."""
    upd = jnp.moveaxis(vals.reshape(27, -1), 0, -1)  # (n, 27)
    cell = jnp.zeros((NN, 27), vals.dtype).at[flat].add(upd)
    return _shift_sum(cell)


# G2P formulations: (flat, idx, gx, gy) -> (vx, vy) (9, n)


def g2p_scalar(flat, idx, gx, gy):
    """damjax today: one scalar gather per channel."""
    return jnp.take(gx, idx, mode="clip"), jnp.take(gy, idx, mode="clip")


def g2p_rows(flat, idx, gx, gy):
    """One gather of rows (vx, vy) from an interleaved (NN, 2) grid."""
    g = jnp.take(jnp.stack([gx, gy], axis=-1), idx, axis=0, mode="clip")  # (9, n, 2)
    return g[..., 0], g[..., 1]


def g2p_patch(flat, idx, gx, gy):
    """One gather of n rows of 18 from (NN, 18) 3x3 neighbourhoods built by dense shifts."""
    g = jnp.pad(jnp.stack([gx, gy]).reshape(2, N_GRID, N_GRID), ((0, 0), (0, 2), (0, 2)))
    patches = jnp.stack(
        [g[:, i : i + N_GRID, j : j + N_GRID].reshape(2, NN) for i, j in OFF], axis=-1
    )  # (2, NN, 9)
    patches = jnp.moveaxis(patches, 0, -1).reshape(NN, 18)  # [k, c] minor
    rows = jnp.take(patches, flat, axis=0, mode="clip").reshape(-1, 9, 2)  # (n, 9, 2)
    rows = jnp.moveaxis(rows, 0, -1)  # (9, 2, n)
    return rows[:, 0], rows[:, 1]


def make_substep(p2g, g2p, reduce=rsum, stencil="bcast", grid_hook=None):
    def substep(state):
        x = state[0]
        if stencil.startswith("bcast"):
            flat, idx, w, dpos = stencil_bcast(x)
            if stencil == "bcast-barrier":
                flat, idx, w, dpos = jax.lax.optimization_barrier((flat, idx, w, dpos))
        else:
            flat, idx, w, dpos = stencil_stacked(x)
        grid = p2g(flat, idx, p2g_values(state, w, dpos))
        if grid_hook is not None:
            grid = grid_hook(grid)
        gx, gy = grid_update(grid)
        vx, vy = g2p(flat, idx, gx, gy)
        return g2p_finish(state, w, dpos, vx, vy, reduce)

    return substep


def make_substep_per_offset(p2g_mode: str):
    """The stencil loop unrolled over its 9 offsets on (n,) arrays, as Taichi's kernel is
    written: no (9, n) intermediates; G2P is one fusion of 18 gathers and the sums.

    p2g_mode: "scalar27" (27 scalar scatters of n), "rows9" (9 scatters of n rows of 3) or
    "rows1" (one scatter of 9n rows of 3 built by concatenation)."""

    def substep(state):
        x, v, C, J = state
        s = x * INV_DX
        fl = jnp.floor(s - 0.5)
        fx = s - fl
        b = fl.astype(jnp.int32)
        flat = b[0] * N_GRID + b[1]
        w1 = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
        stress = (-DT * 4 * E * P_VOL) * (J - 1.0) / DX**2
        a00, a11 = stress + P_MASS * C[0, 0], stress + P_MASS * C[1, 1]
        a01, a10 = P_MASS * C[0, 1], P_MASS * C[1, 0]
        mv0, mv1 = P_MASS * v[0], P_MASS * v[1]
        idx, w, d0, d1, rows = [], [], [], [], []
        for i, j in OFF:
            wk = w1[i][0] * w1[j][1]
            dp0, dp1 = (i - fx[0]) * DX, (j - fx[1]) * DX
            idx.append(flat + (int(i) * N_GRID + int(j)))
            w.append(wk)
            d0.append(dp0)
            d1.append(dp1)
            rows.append(
                (
                    wk * P_MASS,
                    wk * (mv0 + a00 * dp0 + a01 * dp1),
                    wk * (mv1 + a10 * dp0 + a11 * dp1),
                )
            )
        if p2g_mode == "scalar27":
            grid = jnp.stack(
                [
                    sum(jnp.zeros((NN,), x.dtype).at[idx[k]].add(rows[k][c]) for k in range(9))
                    for c in range(3)
                ]
            )
        elif p2g_mode == "rows9":
            grid = sum(
                jnp.zeros((NN, 3), x.dtype).at[idx[k]].add(jnp.stack(rows[k], axis=-1))
                for k in range(9)
            ).T
        else:
            upd = jnp.concatenate([jnp.stack(r, axis=-1) for r in rows])
            grid = jnp.zeros((NN, 3), x.dtype).at[jnp.concatenate(idx)].add(upd).T
        gx, gy = grid_update(grid)
        kk = 4.0 * INV_DX**2
        nv0 = nv1 = c00 = c01 = c10 = c11 = 0.0
        for k in range(9):
            gvx = jnp.take(gx, idx[k], mode="clip")
            gvy = jnp.take(gy, idx[k], mode="clip")
            wx, wy = w[k] * gvx, w[k] * gvy
            nv0, nv1 = nv0 + wx, nv1 + wy
            c00, c01 = c00 + wx * d0[k], c01 + wx * d1[k]
            c10, c11 = c10 + wy * d0[k], c11 + wy * d1[k]
        new_v = jnp.stack([nv0, nv1])
        new_C = kk * jnp.stack([jnp.stack([c00, c01]), jnp.stack([c10, c11])])
        return x + DT * new_v, new_v, new_C, J * (1.0 + DT * (new_C[0, 0] + new_C[1, 1]))

    return substep


SUBSTEPS: dict[str, Callable] = {
    # damjax b66a697's pattern: stacked (S, n) stencil, jnp.sum over the stencil axis
    "0: stacked (S,n) + jnp.sum(axis=0) [b66a697]": make_substep(
        p2g_scalar3, g2p_scalar, reduce=sum0, stencil="stacked"
    ),
    # the benchmark case on whatever damjax.core.transfer this checkout has
    "W: mpm88 case (this checkout's transfer)": mpm88.damjax_substep,
    "A: 0 with unrolled stencil sums": make_substep(p2g_scalar3, g2p_scalar, stencil="stacked"),
    "B: A + one 27n scalar scatter": make_substep(p2g_one27, g2p_scalar, stencil="stacked"),
    "C: A + (9n,3) row scatter": make_substep(p2g_rows3, g2p_scalar, stencil="stacked"),
    "D: C + (9n,2) row gather": make_substep(p2g_rows3, g2p_rows, stencil="stacked"),
    "E: A + cell rows (n,27) + 9 shifts": make_substep(p2g_cellrows, g2p_scalar, stencil="stacked"),
    "F: E + patch gather (n,18)": make_substep(p2g_cellrows, g2p_patch, stencil="stacked"),
    "J1: per-offset (n,) rows, 27 scalar scatters": make_substep_per_offset("scalar27"),
    "J2: per-offset (n,) rows, 9 scatters of (n,3) rows": make_substep_per_offset("rows9"),
    "J3: per-offset (n,) rows, 1 scatter of (9n,3) rows": make_substep_per_offset("rows1"),
    "G: A with a broadcast-built stencil": make_substep(p2g_scalar3, g2p_scalar, stencil="bcast"),
    "G2: G, stencil behind an optimization_barrier": make_substep(
        p2g_scalar3, g2p_scalar, stencil="bcast-barrier"
    ),
}


def sorted_runner(substep: Callable, every: int) -> Callable[[int], Any]:
    """Runner that re-sorts the particles by base cell every ``every`` substeps.

    The particles' original order is carried along and restored at the end, so the final
    state is comparable with the unsorted variants.
    """

    def runner(n_steps: int):
        assert n_steps % every == 0

        def run(state):
            n = state[0].shape[-1]

            def chunk(carry, _):
                s, ids = carry
                x = s[0]
                b = jnp.floor(x * INV_DX - 0.5).astype(jnp.int32)
                order = jnp.argsort(b[0] * N_GRID + b[1])
                s = jax.tree.map(lambda a: jnp.take(a, order, axis=-1), s)
                ids = ids[order]
                s = jax.lax.scan(lambda c, _: (substep(c), None), s, None, length=every)[0]
                return (s, ids), None

            ids0 = jnp.arange(n, dtype=jnp.int32)
            (s, ids), _ = jax.lax.scan(chunk, (state, ids0), None, length=n_steps // every)
            inv = jnp.zeros_like(ids).at[ids].set(ids0)
            return jax.tree.map(lambda a: jnp.take(a, inv, axis=-1), s)

        return jax.jit(run)

    return runner


# --------------------------------------------------------------------------------------------
# experiments
# --------------------------------------------------------------------------------------------


def exp_reduce(rounds: int = 9) -> None:
    """Sum over the stencil axis of an (S, n) array: jnp.sum(axis=0) vs alternatives."""
    rng = np.random.default_rng(0)
    for n in (8192, 32768, 131072):
        for S in (3, 9):
            a = jnp.asarray(rng.random((S, n)).astype(np.float32))
            fns = {
                "jnp.sum(axis=0)": (jax.jit(sum0), (a,)),
                "unrolled adds": (jax.jit(rsum), (a,)),
                "ones @ a": (jax.jit(lambda a: jnp.ones((a.shape[0],), a.dtype) @ a), (a,)),
                "jnp.sum(a.T, axis=1)": (jax.jit(lambda a: jnp.sum(a.T, axis=1)), (a,)),
            }
            for k, t in timeit_rounds(fns, rounds).items():
                emit(
                    experiment="reduce",
                    n=n,
                    S=S,
                    variant=k,
                    median_us=round(statistics.median(t) * 1e6, 1),
                    min_us=round(min(t) * 1e6, 1),
                    ns_per_element=round(statistics.median(t) * 1e9 / (S * n), 2),
                )


def exp_scatter(rounds: int = 9) -> None:
    """P2G scatter formulations alone (random and cell-sorted particles), 3 channels."""
    rng = np.random.default_rng(0)
    for n in (8192, 32768, 131072):
        x = (rng.random((2, n)) * 0.4 + 0.2).astype(np.float32)
        for order_name in ("random", "sorted"):
            xs = x
            if order_name == "sorted":
                b = np.floor(x * INV_DX - 0.5).astype(np.int32)
                xs = x[:, np.argsort(b[0] * N_GRID + b[1], kind="stable")]
            xj = jnp.asarray(xs)
            vals = jnp.asarray(rng.random((3, 9, n)).astype(np.float32))

            def make(p2g):
                def f(xx, vv):
                    flat, idx, _, _ = stencil_bcast(xx)
                    return p2g(flat, idx, vv)

                return jax.jit(f)

            fns = {
                "3 scalar scatters of 9n (damjax)": (make(p2g_scalar3), (xj, vals)),
                "1 scalar scatter of 27n": (make(p2g_one27), (xj, vals)),
                "1 scatter of 9n rows of 3": (make(p2g_rows3), (xj, vals)),
                "1 scatter of n rows of 27 + 9 shifts": (make(p2g_cellrows), (xj, vals)),
            }
            if order_name == "sorted":  # per offset the indices are sorted: segment_sum
                fns["27 segment_sums of n (indices_are_sorted)"] = (
                    make(p2g_segment_sorted),
                    (xj, vals),
                )
            ref = np.asarray(fns["3 scalar scatters of 9n (damjax)"][0](xj, vals))
            for k, t in timeit_rounds(fns, rounds).items():
                err = float(np.max(np.abs(np.asarray(fns[k][0](xj, vals)) - ref)))
                emit(
                    experiment="scatter",
                    n=n,
                    particles=order_name,
                    variant=k,
                    median_us=round(statistics.median(t) * 1e6, 1),
                    min_us=round(min(t) * 1e6, 1),
                    ns_per_element=round(statistics.median(t) * 1e9 / (27 * n), 2),
                    max_abs_diff=err,
                )


def _substep_variants(sort_every: int) -> dict[str, Callable[[int], Any]]:
    runners = {k: (lambda n, f=f: mpm88.damjax_runner(n, f)) for k, f in SUBSTEPS.items()}
    runners[f"H: A + sort by cell every {sort_every}"] = sorted_runner(
        SUBSTEPS["A: 0 with unrolled stencil sums"], sort_every
    )
    runners[f"I: E + sort by cell every {sort_every}"] = sorted_runner(
        SUBSTEPS["E: A + cell rows (n,27) + 9 shifts"], sort_every
    )
    return runners


def exp_substep(ns: list[int], n_steps: int = 20, rounds: int = 7, sort_every: int = 10) -> None:
    """Whole mpm88 substeps (lax.scan of n_steps), every variant, round-robin."""
    for n in ns:
        s0 = mpm88.to_soa(mpm88.active_particles(n))
        runners = _substep_variants(sort_every)
        fns, compile_s = {}, {}
        for k, r in runners.items():
            t0 = time.perf_counter()
            fns[k] = (r(n_steps).lower(s0).compile(), (s0,))
            compile_s[k] = time.perf_counter() - t0
        ref = np.asarray(fns["0: stacked (S,n) + jnp.sum(axis=0) [b66a697]"][0](s0)[0])
        for k, t in timeit_rounds(fns, rounds).items():
            med = statistics.median(t)
            err = float(np.max(np.abs(np.asarray(fns[k][0](s0)[0]) - ref)))
            emit(
                experiment="substep",
                n=n,
                n_steps=n_steps,
                variant=k,
                ms_per_substep=round(med * 1e3 / n_steps, 3),
                min_ms_per_substep=round(min(t) * 1e3 / n_steps, 3),
                particle_steps_per_s=round(n * n_steps / med),
                compile_time_s=round(compile_s[k], 3),
                max_abs_diff_x=err,
            )


def exp_taichi(ns: list[int], repeats: int = 5) -> None:
    """The mpm88 case (100 substeps, alternating with Taichi) with the fastest variant."""
    ti = mpm88.taichi_init(mpm88.n_threads())
    for name in ("A: 0 with unrolled stencil sums", "C: A + (9n,3) row scatter"):
        best = SUBSTEPS[name]
        for n in ns:
            row = mpm88.run_case(
                n, repeats=repeats, ti=ti, runner=lambda k, f=best: mpm88.damjax_runner(k, f)
            )
            emit(experiment="taichi", variant=name, **row)


def exp_shard(ns: list[int], n_steps: int = 20, rounds: int = 5) -> None:
    """Particles split over 2 host devices (shard_map), grid psum: parallel scatters."""
    from jax.sharding import Mesh
    from jax.sharding import PartitionSpec as P

    devs = jax.devices()
    if len(devs) < 2:
        raise SystemExit("shard: needs 2 host devices")
    mesh = Mesh(np.array(devs[:2]), ("p",))
    specs = (P(None, "p"), P(None, "p"), P(None, None, "p"), P("p"))

    substep = make_substep(
        p2g_rows3, g2p_scalar, stencil="stacked", grid_hook=lambda g: jax.lax.psum(g, "p")
    )

    def sharded(n_steps):
        def run(state):
            return jax.lax.scan(lambda c, _: (substep(c), None), state, None, length=n_steps)[0]

        return jax.jit(jax.shard_map(run, mesh=mesh, in_specs=(specs,), out_specs=specs))

    single = SUBSTEPS["C: A + (9n,3) row scatter"]
    for n in ns:
        s0 = mpm88.to_soa(mpm88.active_particles(n))
        fns = {
            "1 device": (mpm88.damjax_runner(n_steps, single).lower(s0).compile(), (s0,)),
            "2 devices (shard_map, psum grid)": (sharded(n_steps).lower(s0).compile(), (s0,)),
        }
        ref = np.asarray(fns["1 device"][0](s0)[0])
        for k, t in timeit_rounds(fns, rounds).items():
            med = statistics.median(t)
            err = float(np.max(np.abs(np.asarray(fns[k][0](s0)[0]) - ref)))
            emit(
                experiment="shard",
                n=n,
                n_steps=n_steps,
                variant=k,
                ms_per_substep=round(med * 1e3 / n_steps, 3),
                min_ms_per_substep=round(min(t) * 1e3 / n_steps, 3),
                particle_steps_per_s=round(n * n_steps / med),
                max_abs_diff_x=err,
            )


class _UnrolledStencilSums:
    """Stand-in for ``jax.numpy`` in a step module: ``sum(a, axis=0)`` over a short leading
    (stencil or component) axis becomes an unrolled chain of adds."""

    def __getattr__(self, name: str) -> Any:
        return getattr(jnp, name)

    @staticmethod
    def sum(a: Any, axis: Any = None, **kw: Any) -> Any:
        if axis == 0 and not kw and getattr(a, "ndim", 0) == 2 and a.shape[0] <= 9:
            return rsum(a)
        return jnp.sum(a, axis=axis, **kw)


COMMITTED = "b66a697708f6b0da02f1414f1669643dce780d16"  # stacked (S, n) transfer and step


def committed_step(unrolled: bool = False):
    """damjax.core.step and .transfer as committed in COMMITTED, loaded from git into
    private modules (the rest of damjax from this checkout); ``unrolled`` swaps the step's
    ``jnp`` for `_UnrolledStencilSums`."""
    import subprocess
    import types

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

    def load(path: str, name: str, env: dict) -> types.ModuleType:
        src = subprocess.run(
            ["git", "show", f"{COMMITTED}:{path}"],
            cwd=root,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
        # the committed step must use the committed transfer (injected through env)
        src = src.replace("from damjax.core import transfer\n", "")
        mod = types.ModuleType(name)
        mod.__dict__.update(env)
        exec(compile(src, f"{COMMITTED[:7]}:{path}", "exec"), mod.__dict__)
        return mod

    transfer = load("damjax/core/transfer.py", "transfer_committed", {})
    step = load("damjax/core/step.py", "step_committed", {"transfer": transfer})
    if unrolled:
        step.jnp = _UnrolledStencilSums()
    return step


def _pst_setup(dim: int):
    from damjax import PSTSetup

    if dim == 1:  # the baseline PST: 100 m, dx 0.02 m, 10 000 particles, S = 3
        return PSTSetup()
    # 2D free strip, 30 m x 0.3 m, dx 0.02 m: 90 000 particles, S = 9
    return PSTSetup(dim=2, length=30.0)


def exp_pst(dims: list[int], rounds: int = 5) -> None:
    """damjax's own PST step, scanned: the committed (stacked, jnp.sum) step, the same with its
    sums unrolled, and this checkout's damjax.core.step; alternating in one process."""
    from damjax import PSTParams
    from damjax.core import step as step_here
    from damjax.core.model import build, make_layout

    steps = {
        f"{COMMITTED[:7]} step.py (stacked, jnp.sum)": committed_step(False).step,
        f"{COMMITTED[:7]} step.py, sums unrolled": committed_step(True).step,
        "this checkout's step.py": step_here.step,
    }
    for dim in dims:
        n_steps = 1000 if dim == 1 else 20
        params, setup = PSTParams(), _pst_setup(dim)
        model, state0 = build(params, setup, make_layout(params, setup))
        fns, compile_s = {}, {}
        for name, fstep in steps.items():

            def run(m, s, fstep=fstep, k=n_steps):
                return jax.lax.scan(lambda c, _: (fstep(m, c), None), s, None, length=k)[0]

            t0 = time.perf_counter()
            fns[name] = (jax.jit(run).lower(model, state0).compile(), (model, state0))
            compile_s[name] = time.perf_counter() - t0
        first = next(iter(fns))
        ref = np.asarray(fns[first][0](model, state0).u)
        for k, t in timeit_rounds(fns, rounds).items():
            med = statistics.median(t)
            u = np.asarray(fns[k][0](model, state0).u)
            n = state0.u.shape[-1]
            emit(
                experiment="pst",
                dim=dim,
                variant=k,
                n_particles=n,
                n_steps=n_steps,
                ms_per_step=round(med * 1e3 / n_steps, 3),
                min_ms_per_step=round(min(t) * 1e3 / n_steps, 3),
                particle_steps_per_s=round(n * n_steps / med),
                compile_time_s=round(compile_s[k], 3),
                max_abs_diff_u=float(np.max(np.abs(u - ref))),
            )


def exp_breakdown(ns: list[int], rounds: int = 7) -> None:
    """Cumulative cost of variant C's substep pieces (each a jitted prefix of the step)."""

    def stencil(state):
        return stencil_stacked(state[0])[1:]

    def p2g(state):
        idx, w, dpos = stencil(state)
        return p2g_rows3(None, idx, p2g_values(state, w, dpos)), idx, w, dpos

    def grid(state):
        g, idx, w, dpos = p2g(state)
        return grid_update(g), idx, w, dpos

    def gather(state):
        (gx, gy), idx, w, dpos = grid(state)
        return g2p_scalar(None, idx, gx, gy), w, dpos

    pieces = {
        "1 stacked stencil (b66a697 transfer.stencil)": stencil,
        "2 + P2G values and (9n,3) row scatter": p2g,
        "3 + grid update": grid,
        "4 + G2P gathers": gather,
        "5 + G2P unrolled sums, particle update (= C)": SUBSTEPS["C: A + (9n,3) row scatter"],
    }
    for n in ns:
        s0 = mpm88.to_soa(mpm88.active_particles(n))
        fns = {k: (jax.jit(f), (s0,)) for k, f in pieces.items()}
        for k, t in timeit_rounds(fns, rounds).items():
            emit(
                experiment="breakdown",
                n=n,
                piece=k,
                cumulative_ms=round(statistics.median(t) * 1e3, 3),
                min_ms=round(min(t) * 1e3, 3),
            )


def main(argv: list[str]) -> None:
    what = argv[0] if argv else "substep"
    ns = [int(a) for a in argv[1:]] or [8192, 32768, 131072]
    if what == "reduce":
        exp_reduce()
    elif what == "scatter":
        exp_scatter()
    elif what == "substep":
        exp_substep(ns)
    elif what == "taichi":
        exp_taichi(ns)
    elif what == "shard":
        exp_shard(ns)
    elif what == "breakdown":
        exp_breakdown(ns)
    elif what == "pst":
        exp_pst([int(a) for a in argv[1:]] or [1, 2])
    else:
        raise SystemExit(f"unknown experiment {what!r}")


if __name__ == "__main__":
    main(sys.argv[1:])
