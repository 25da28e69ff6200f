"""Quadratic B-spline particle-grid transfers, written once for any dimension.

A particle's position is kept as an integer reference cell ``cell0``, a reference offset
``frac0`` in [0, 1) (both in cell units) and a displacement ``u`` [m] from the reference
position. The stencil is computed from ``frac0 + u / dx`` only, never from an absolute
coordinate, so float32 resolves weak-layer displacements of 1e-5 m anywhere on a 100 m
(or 1 km) domain.

Layout (chosen by measurement, see benchmarks/README.md): structure of arrays with the
particle index last; every grid quantity is a flat 1D array over the nodes; a transfer is
S scalar scatter-adds (P2G) or gathers (G2P) of n elements per channel, S = 3**dim.
On XLA:CPU a scalar scatter costs ~1 ns per element, while scatters of row vectors or
several stencil offsets per index are 3-8x slower. A complex scatter costs what a real one
does, so `p2g_channels` scatters two real channels as the real and imaginary parts of one
complex row: the sums are the same float additions, done in half the scatters; likewise
`g2p_channels` gathers two grid fields in one complex gather. Under `jax.vmap` (sweeps),
the scatters and gathers run over all members' grids at once (a batching rule, below).
"""

from __future__ import annotations

import functools
import itertools
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp


def offsets(dim: int) -> list[tuple[int, ...]]:
    """The 3**dim node offsets of the quadratic stencil, relative to the base node."""
    return list(itertools.product(range(3), repeat=dim))


def strides(grid_shape: tuple[int, ...]) -> tuple[int, ...]:
    """Row-major strides of the flat node index."""
    out = []
    acc = 1
    for n in reversed(grid_shape):
        out.append(acc)
        acc *= n
    return tuple(reversed(out))


class Stencil(NamedTuple):
    """Stencil of every particle: S = 3**dim nodes each, kept as S separate rows.

    Rows are tuples of (n,) arrays, never stacked: on XLA:CPU a reduction over a
    stacked (S, n) axis costs ~100x more than S-1 elementwise adds (measured:
    2.2 ms vs 16 us for S = 9, n = 20000), and per-row gathers fuse into their consumers.
    """

    idx: tuple[Any, ...]  # S x (n,) int32 flat node indices
    w: tuple[Any, ...]  # S x (n,) weights
    dpos: tuple[tuple[Any, ...], ...]  # S x dim x (n,) node minus particle position [m]
    base: Any  # (dim, n) int32 base node per dimension


def stencil(
    cell0: Any,
    frac0: Any,
    u: Any,
    dx: float,
    grid_shape: tuple[int, ...],
    periodic: tuple[bool, ...] | None = None,
) -> Stencil:
    """Quadratic B-spline weights of particles at cell0 + frac0 + u/dx (cell units).

    Axes flagged in ``periodic`` wrap around (a strip that is periodic across its width).
    """
    dim = len(grid_shape)
    s = frac0 + u * (1.0 / dx)
    fl = jnp.floor(s - 0.5)
    fx = s - fl  # in [0.5, 1.5): distance from the base node [cells]
    base = cell0 + fl.astype(jnp.int32)
    w1 = [
        (0.5 * (1.5 - fx[d]) ** 2, 0.75 - (fx[d] - 1.0) ** 2, 0.5 * (fx[d] - 0.5) ** 2)
        for d in range(dim)
    ]
    d1 = [tuple((o - fx[d]) * dx for o in range(3)) for d in range(dim)]
    st = strides(grid_shape)
    periodic = periodic or (False,) * dim
    idx, w, dpos = [], [], []
    for o in offsets(dim):
        wk = w1[0][o[0]]
        for d in range(1, dim):
            wk = wk * w1[d][o[d]]
        w.append(wk)
        node = [
            (base[d] + o[d]) % grid_shape[d] if periodic[d] else base[d] + o[d] for d in range(dim)
        ]
        idx.append(sum(node[d] * st[d] for d in range(dim)))
        dpos.append(tuple(d1[d][o[d]] for d in range(dim)))
    return Stencil(idx=tuple(idx), w=tuple(w), dpos=tuple(dpos), base=base)


# --------------------------------------------------------------------------------------
# Scatter and gather with a batching rule. Under `jax.vmap` (a sweep), XLA's batched
# scatter builds (member, node) index pairs and copies, and costs 1.6-2 ns per element
# against 0.9 unbatched (benchmarks/README.md). A batch of B members is instead one flat
# scalar scatter (gather) on a (B * n_nodes,) grid, member b's nodes offset by b * n_nodes.
# Indices outside [0, n_nodes) are dropped (scatter) or clamped (gather) per member, as
# unbatched, so a member never writes into its neighbour. Derivatives: a custom JVP whose
# tangent is the plain (transposable) scatter or gather, so forward and reverse mode work.
# --------------------------------------------------------------------------------------


def _batched(x: Any, is_batched: bool, axis_size: int) -> Any:
    """x with a leading member axis (broadcast when vmap left it unbatched)."""
    return x if is_batched else jnp.broadcast_to(x, (axis_size, *x.shape))


def _member_offsets(axis_size: int, n_nodes: int, ndim: int, dtype: Any) -> Any:
    off = jnp.arange(axis_size, dtype=dtype) * n_nodes
    return jnp.reshape(off, (axis_size,) + (1,) * (ndim - 1))


@functools.cache
def _scatter_add(n_nodes: int) -> Any:
    def plain(grid: Any, idx: Any, vals: Any) -> Any:
        return grid.at[idx].add(vals)

    flat = jax.custom_batching.custom_vmap(plain)

    @flat.def_vmap
    def _rule(axis_size: int, in_batched: Any, grid: Any, idx: Any, vals: Any) -> Any:
        grid, idx, vals = (
            _batched(x, b, axis_size) for x, b in zip((grid, idx, vals), in_batched, strict=True)
        )
        total = axis_size * n_nodes
        ok = (idx >= 0) & (idx < n_nodes)
        g = jnp.where(ok, idx + _member_offsets(axis_size, n_nodes, idx.ndim, idx.dtype), total)
        out = grid.reshape(-1).at[g.ravel()].add(vals.ravel(), mode="drop")
        return out.reshape(axis_size, n_nodes), True

    @jax.custom_jvp
    def scatter(grid: Any, idx: Any, vals: Any) -> Any:
        return flat(grid, idx, vals)

    @scatter.defjvp
    def _jvp(primals: Any, tangents: Any) -> Any:
        grid, idx, vals = primals
        return scatter(grid, idx, vals), plain(tangents[0], idx, tangents[2])

    return scatter


@functools.cache
def _take(n_nodes: int) -> Any:
    def plain(grid: Any, idx: Any) -> Any:
        return jnp.take(grid, idx, mode="clip")

    flat = jax.custom_batching.custom_vmap(plain)

    @flat.def_vmap
    def _rule(axis_size: int, in_batched: Any, grid: Any, idx: Any) -> Any:
        grid, idx = (
            _batched(grid, in_batched[0], axis_size),
            _batched(idx, in_batched[1], axis_size),
        )
        g = jnp.clip(idx, 0, n_nodes - 1) + _member_offsets(axis_size, n_nodes, idx.ndim, idx.dtype)
        return jnp.take(grid.reshape(-1), g, mode="clip"), True

    @jax.custom_jvp
    def take(grid: Any, idx: Any) -> Any:
        return flat(grid, idx)

    @take.defjvp
    def _jvp(primals: Any, tangents: Any) -> Any:
        grid, idx = primals
        return take(grid, idx), plain(tangents[0], idx)

    return take


def p2g(st: Stencil, rows: Any, n_nodes: int) -> Any:
    """Scatter-add per-node contributions (S rows of (n,)) to a flat grid (n_nodes,)."""
    scatter = _scatter_add(int(n_nodes))
    grid = jnp.zeros((n_nodes,), rows[0].dtype)
    for k in range(len(st.idx)):
        grid = scatter(grid, st.idx[k], rows[k])
    return grid


def p2g_channels(st: Stencil, channels: Any, n_nodes: int) -> list[Any]:
    """`p2g` of several channels (each S rows of (n,)): a list of flat grids (n_nodes,).

    Channels go in pairs through one complex scatter-add each (real part the first,
    imaginary part the second): per element a complex scatter costs about what a real one
    does on XLA:CPU (micro-benchmark, 10 000 particles, 3 channels x 3 rows: 82 -> 63 us
    per step; 2D slope step 43.7 -> 40.1 ms; no gain in the 1D step, where building the
    complex rows costs what the saved scatters did; benchmarks/README.md), and each part is
    summed in its own precision, in the same order, so the grids equal `p2g`'s. An odd
    channel out uses `p2g`.
    """
    out = []
    for c in range(0, len(channels) - 1, 2):
        a, b = channels[c], channels[c + 1]
        rows = [jax.lax.complex(a[k], b[k]) for k in range(len(st.idx))]
        grid = p2g(st, rows, n_nodes)
        out += [jnp.real(grid), jnp.imag(grid)]
    if len(channels) % 2:
        out.append(p2g(st, channels[-1], n_nodes))
    return out


def g2p(st: Stencil, grid: Any) -> tuple[Any, ...]:
    """Gather a flat grid field (n_nodes,) at the particles' stencils: S rows of (n,)."""
    take = _take(int(grid.shape[-1]))
    return tuple(take(grid, i) for i in st.idx)


def g2p_channels(st: Stencil, grids: Any) -> list[tuple[Any, ...]]:
    """`g2p` of several grid fields (n_nodes,): per field, S rows of (n,).

    Fields go in pairs through one complex gather each (real part the first, imaginary
    part the second), half the gathers: the values are the same floats as `g2p`'s. An odd
    field out uses `g2p`. Measured on XLA:CPU (2-core Intel Xeon): 2D generic-slope step
    (300 000 particles) 37.2 -> 34.0 ms; mpm88 throughput +10-15 % at N = 32768 and
    131072 (benchmarks/README.md).
    """
    out = []
    for c in range(0, len(grids) - 1, 2):
        rows = g2p(st, jax.lax.complex(grids[c], grids[c + 1]))
        out += [tuple(jnp.real(r) for r in rows), tuple(jnp.imag(r) for r in rows)]
    if len(grids) % 2:
        out.append(g2p(st, grids[-1]))
    return out


def interpolate(st: Stencil, grid: Any) -> Any:
    """sum_k w_k grid[idx_k]: a grid field at the particles (n,)."""
    vals = g2p(st, grid)
    out = st.w[0] * vals[0]
    for k in range(1, len(vals)):
        out = out + st.w[k] * vals[k]
    return out
