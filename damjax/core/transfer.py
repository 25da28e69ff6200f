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
several stencil offsets per index are 3-8x slower. A complex64 scatter costs what a real
one does, so `p2g_channels` scatters two float32 channels as the real and imaginary parts
of one complex row: the sums are the same float additions, done in half the scatters;
likewise `g2p_channels` gathers two float32 grid fields in one complex gather. Pairs are
formed on CPUs only and never of float64 data: XLA:GPU adds complex64 in a compare-and-swap
loop and scatters elements wider than 64 bits one update at a time (`_pairs`,
`_cpu_paired`). Under `jax.vmap` (sweeps),
the scatters and gathers run over all members' grids at once (a batching rule, below).

P2G sums are deterministic by default (``accumulation="fixed"``, `p2g_channels`): each
channel is quantised to integers on a power-of-two scale fixed by its largest magnitude,
and the integers are added exactly, so neither the order of the particles nor the order in
which a device applies the adds changes a bit of the result. ``"float"`` is the plain
float scatter-add (on a GPU: float atomics in a varying order).
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from damjax.constants import ACCUMULATIONS

# how P2G adds the particles' contributions (`p2g_channels`), `ACCUMULATIONS`: "fixed"
# (deterministic fixed point), "float" (plain float scatter-adds, order-dependent on a
# GPU) or "auto" (what `resolve_accumulation` picks for the backend: the setups' default)


def resolve_accumulation(accumulation: str, backend: str | None = None) -> str:
    """The accumulation a run uses: "fixed" or "float" as given; "auto" is "float" on a
    CPU and "fixed" on every other backend (``backend``: default `jax.default_backend()`).

    Both are deterministic where they are chosen: XLA:CPU adds a scatter's elements one
    after the other in the particles' order, so a CPU run repeats bitwise with float sums,
    which cost less there (their scatter moves half the bytes: mpm88 1.2-1.6 x faster,
    the Fig. 13a slope up to 1.1 x; docs/performance/transfers.md); a GPU applies float
    atomics in a varying order, and the fixed-point sums make its runs repeat. "fixed"
    everywhere also makes a run independent of the particles' order and gives CPU and GPU
    the same sums (not the same elementwise arithmetic)."""
    _check_accumulation(accumulation)
    if accumulation != "auto":
        return accumulation
    return "float" if (backend or jax.default_backend()) == "cpu" else "fixed"


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


def _plain_scatter(grid: Any, idx: Any, vals: Any) -> Any:
    return grid.at[idx].add(vals)


@functools.cache
def _flat_scatter(n_nodes: int) -> Any:
    """`grid.at[idx].add(vals)` whose batching rule is one flat scatter over the members'
    grids (no derivative rule: `_scatter_add` adds it; the fixed-point path has its own)."""
    flat = jax.custom_batching.custom_vmap(_plain_scatter)

    @flat.def_vmap
    def _rule(axis_size: int, in_batched: Any, grid: Any, idx: Any, vals: Any) -> Any:
        if not any(in_batched):  # see `_take`'s rule
            return _plain_scatter(grid, idx, vals), False
        # 64-bit carriers of the fixed-point sums (float64, int64) may reach
        # this rule outside the caller's x64 scope (a vmapped scan batches its body later)
        dt = np.dtype(vals.dtype)
        wide = (dt.itemsize // 2 if dt.kind == "c" else dt.itemsize) >= 8
        with jax.enable_x64(True) if wide else contextlib.nullcontext():
            grid, idx, vals = (
                _batched(x, b, axis_size)
                for x, b in zip((grid, idx, vals), in_batched, strict=True)
            )
            total = axis_size * n_nodes
            ok = (idx >= 0) & (idx < n_nodes)
            off = _member_offsets(axis_size, n_nodes, idx.ndim, idx.dtype)
            g = jnp.where(ok, idx + off, total)
            out = grid.reshape(-1).at[g.ravel()].add(vals.ravel(), mode="drop")
            return out.reshape(axis_size, n_nodes), True

    return flat


@functools.cache
def _scatter_add(n_nodes: int) -> Any:
    plain = _plain_scatter
    flat = _flat_scatter(n_nodes)

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
        # JAX's derivative of a custom_vmap calls its rule with nothing batched where
        # only the tangents are (forward over reverse under a scan: jax.hessian,
        # jax.jacfwd(jax.grad(f))): then the plain op, unbatched
        if not any(in_batched):
            return plain(grid, idx), False
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


def materialise(tree: Any, ok: Any) -> Any:
    """``tree`` (float arrays) if ``ok`` (a scalar bool) is true, else NaN in its shapes; on
    a CPU a conditional, whose operands XLA computes into buffers (elsewhere ``tree``).

    A fusion barrier for XLA:CPU, which otherwise recomputes a per-particle value's whole
    arithmetic in every fusion that reads it, at the vector width of that fusion's widest
    type: the 64-bit rows of the fixed-point P2G (`p2g_channels`) halve it. The step passes
    its particles' P2G factors with ``ok`` = a finite time step (with a non-finite dt they
    are NaN or inf anyway), with either accumulation: without it every fusion building a
    P2G row recomputed the weak layer's law (1D baseline step 204 -> 176 us with float
    sums). An ``ok`` that XLA can evaluate at compile time, or one batched
    by `jax.vmap`, turns the conditional into a select and the barrier goes (the values
    stay right). On other platforms ``tree`` as it is: XLA:GPU can read a conditional's
    predicate on the host, a round trip per step. Measured: docs/performance/transfers.md.
    """

    def barrier(t: Any) -> Any:
        nan = lambda t: jax.tree.map(lambda x: jnp.full_like(x, jnp.nan), t)  # noqa: E731
        return lax.cond(ok, lambda t: t, nan, t)

    return lax.platform_dependent(tree, cpu=barrier, default=lambda t: t)


@jax.custom_jvp
def tangent_barrier(tree: Any, ok: Any) -> Any:
    """``tree`` itself; its tangent passes through `materialise` (``ok`` as there), so the
    transpose of a P2G sum reads its grid cotangent from a buffer.

    Reverse mode transposes each P2G scatter into a gather of the grid's cotangent, and
    XLA:CPU fused the grid update's whole transposed arithmetic (about 60 operations per
    node) into each of those gathers, evaluating it once per gathered particle row instead
    of once per node. The conditional of `materialise` in the tangent becomes one in the
    transpose, computed into buffers before the gathers.
    """
    return tree


@tangent_barrier.defjvp
def _tangent_barrier_jvp(primals: Any, tangents: Any) -> Any:
    tree, ok = primals
    return tree, materialise(tangents[0], ok)


def _pairs(dtype: Any) -> bool:
    """Whether two real channels of ``dtype`` may travel as one complex array: only as
    complex64 (float32 parts). XLA:GPU cannot scatter elements wider than 64 bits
    atomically and rewrites such a scatter into a loop over its updates, one at a time
    (its GpuScatterExpander), so no complex128 array is ever scattered, nor gathered
    (reverse mode transposes a gather into a scatter). Even complex64 pairs are formed
    on CPUs only (`_cpu_paired`)."""
    return np.dtype(dtype) == np.dtype(np.float32)


def _cpu_paired(paired: Any, unpaired: Any, *args: Any) -> Any:
    """``paired(*args)`` when JAX's default backend is a CPU, else ``unpaired(*args)``
    (decided when the function is traced).

    On XLA:CPU a complex64 scatter or gather costs what a real one does, so pairs halve
    the transfers. XLA:GPU adds only float16/32/64 and integers with native atomics; a
    complex64 add becomes a compare-and-swap loop on 64-bit words, which retries as
    particles crowd a node (and reverse mode turns each paired gather into such a
    scatter-add), so other backends keep one real array per channel. Not
    `lax.platform_dependent`: under reverse mode its two branches' residuals are joined,
    and a GPU program would carry the CPU branch's complex buffers through every step."""
    return paired(*args) if jax.default_backend() == "cpu" else unpaired(*args)


def _check_accumulation(accumulation: str) -> None:
    if accumulation not in ACCUMULATIONS:
        raise ValueError(
            f"accumulation = {accumulation!r}: must be one of "
            + ", ".join(repr(a) for a in ACCUMULATIONS)
            + " (PSTSetup.accumulation / SlopeSetup.accumulation: 'fixed' adds the "
            "particle-to-grid sums in deterministic fixed point, 'float' in plain float "
            "scatter-adds, 'auto' picks 'float' on a CPU and 'fixed' elsewhere)"
        )


def p2g(st: Stencil, rows: Any, n_nodes: int, accumulation: str = "fixed") -> Any:
    """Scatter-add per-node contributions (S rows of (n,)) to a flat grid (n_nodes,).

    ``accumulation``: "fixed" (default, deterministic), "float" or "auto"
    (`resolve_accumulation`); see `p2g_channels`.
    """
    accumulation = resolve_accumulation(accumulation)
    if accumulation == "fixed":
        return _p2g_fixed(int(n_nodes))(tuple(st.idx), (tuple(rows),), (None,))[0]
    return _p2g_float(st, rows, n_nodes)


def _p2g_float(st: Stencil, rows: Any, n_nodes: int) -> Any:
    return _float_sums(st.idx, [rows], n_nodes, _scatter_add(int(n_nodes)))[0]


def p2g_channels(
    st: Stencil,
    channels: Any,
    n_nodes: int,
    accumulation: str = "fixed",
    bounds: Any = None,
) -> list[Any]:
    """`p2g` of several channels (each S rows of (n,)): a list of flat grids (n_nodes,).

    ``accumulation="fixed"`` (the default) is deterministic: the grids do not depend on the
    order of the particles, nor on the order in which a device applies the adds (GPU
    atomics), and under `jax.vmap` a member's grids equal its own run's. Per channel, with
    n particles and S rows (N = n S contributions, a bound on those of any node), every
    contribution v is quantised to the integer q = round(v 2^s), with s = B - L - E, 2^L >= N
    and 2^E > max|v| (E from the maximum's float exponent: a maximum over every row and
    particle, or over ``bounds``, is independent of the order; taken per member under vmap).
    Then |q| <= 2^(B - L), and no sum of a node's at most N integers exceeds 2^B: they add
    exactly, as integers, in any order, and are scaled back by 2^-s and rounded once to the
    data's float type. Float32 data: B = 52, the integers carried as float64 (exact below
    2^53); float64 data: B = 62, int64 (no overflow below 2^63); one 64-bit scatter per
    channel (a complex128 pair would be one scatter on a CPU, but XLA:GPU runs scatters of
    128-bit elements one update at a time: `_pairs`). Precision: the quantum 2^-s is
    below 4 N 2^-B max|v|, so each
    contribution moves by less than 2^(1-B) N of the largest: float32 data 4.4e-16 N
    (1.3e-11 for the 1D baseline PST, N = 30 000; 3e-10 for the 75 000-particle slope, N =
    675 000; float32's own rounding, 6e-8, is reached at N = 1.4e8), float64 data 4.3e-19 N;
    contributions above 2^(25-B) N of the largest (float32 data: 7.5e-9 N) are quantised
    exactly. A node's sum is then exact to (its contributions) x (that error), then rounded
    once; the float scatter rounds once per add, relative to the partial sums.
    Non-finite values: a non-finite maximum (of the rows or of ``bounds``) makes the
    channel's grid NaN; with float32 data and bounds, a non-finite contribution still
    propagates through the float64 sums to its nodes, as in the float path. Derivatives
    (forward and reverse) are those of the plain float scatter-add: the quantisation has
    zero derivative almost everywhere, so a custom JVP takes the float scatter's tangent.

    ``bounds`` (fixed only; used for float32 data): per channel None, or a value not below
    |v| for every row of the particle (a scalar, or an array over the particles): its
    maximum sets the scale instead of the maximum over all S rows, which XLA would compute
    by recomputing each row. A looser bound costs precision in proportion; one below the
    true maximum by less than 2x is harmless (the float64 sums stay exact below 2^53).
    Cost on XLA:CPU: docs/performance/transfers.md (see also `materialise`).

    ``accumulation="auto"``: "float" on a CPU, "fixed" elsewhere (`resolve_accumulation`).

    ``accumulation="float"``: plain float scatter-adds. Float32 channels go in pairs
    through one complex64 scatter-add each (real part the first, imaginary part the
    second; float64 channels one by one, `_pairs`): per element
    a complex scatter costs about what a real one does on XLA:CPU (micro-benchmark,
    10 000 particles, 3 channels x 3 rows: 82 -> 63 us per step; 2D slope step 43.7 -> 40.1
    ms; no gain in the 1D step, where building the complex rows costs what the saved
    scatters did; benchmarks/README.md), and each part is summed in its own precision, in
    the same order, so the grids equal `p2g`'s. An odd channel out uses `p2g`.
    """
    accumulation = resolve_accumulation(accumulation)
    if accumulation == "fixed":
        chans = tuple(tuple(c) for c in channels)
        bounds = (None,) * len(chans) if bounds is None else tuple(bounds)
        if len(bounds) != len(chans):
            raise ValueError(f"p2g_channels: {len(bounds)} bounds for {len(chans)} channels")
        return list(_p2g_fixed(int(n_nodes))(tuple(st.idx), chans, bounds))
    return _p2g_float_channels(st, channels, n_nodes)


def _p2g_float_channels(st: Stencil, channels: Any, n_nodes: int) -> list[Any]:
    return _float_sums(st.idx, channels, n_nodes, _scatter_add(int(n_nodes)))


def _float_sums(idx: Any, channels: Any, n_nodes: int, scatter: Any) -> list[Any]:
    """Float sums of channels (each S rows of (n,)) onto flat grids (n_nodes,) with
    ``scatter(grid, idx_k, row_k)``: float32 channels in complex64 pairs on a CPU
    (`_pairs`, `_cpu_paired`; an odd one out alone), others one by one. Used by the float
    path (`_scatter_add`) and by the fixed path's tangent (`_plain_scatter`)."""

    def one(rows: Any) -> Any:
        grid = jnp.zeros((n_nodes,), rows[0].dtype)
        for k in range(len(idx)):
            grid = scatter(grid, idx[k], rows[k])
        return grid

    def unpaired(channels: Any) -> list[Any]:
        return [one(c) for c in channels]

    def paired(channels: Any) -> list[Any]:
        out = []
        for c in range(0, len(channels) - 1, 2):
            a, b = channels[c], channels[c + 1]
            grid = one([lax.complex(a[k], b[k]) for k in range(len(idx))])
            out += [jnp.real(grid), jnp.imag(grid)]
        if len(channels) % 2:
            out.append(one(channels[-1]))
        return out

    channels = [list(c) for c in channels]
    if not _pairs(channels[0][0].dtype):  # float64 data: one real scatter per channel
        return unpaired(channels)
    return _cpu_paired(paired, unpaired, channels)


# --------------------------------------------------------------------------------------
# Fixed-point accumulation (see `p2g_channels`). Integers are added exactly, so the sums
# do not depend on the order of the adds. The 64-bit carriers (float64 holding integers,
# int64) live inside `jax.enable_x64(True)` scopes; the inputs
# and outputs keep the data's dtype, so a float32 program stays float32 around them.
# --------------------------------------------------------------------------------------

# per data dtype: (bits of the float, its exponent bias, mantissa bits, carrier, B)
_FIXED = {
    np.dtype(np.float32): (np.int32, 127, 23, "float64", 52),
    np.dtype(np.float64): (np.int64, 1023, 52, "int64", 62),
}


def _fixed_scale(values: list[Any], dtype: Any, n_bound: int) -> tuple[Any, Any]:
    """(2^s, 2^-s) as float64 scalars with max|v| 2^s n_bound <= 2^B, max|v| over the
    ``values`` (a channel's rows, or its bound: arrays over the particles, or scalars; per
    member under vmap); 2^-s is NaN when that maximum is not finite."""
    dtype = np.dtype(dtype)
    ibits, bias, mant, _, B = _FIXED[dtype]
    nbits = 8 * dtype.itemsize
    # the largest magnitude's bit pattern: an integer max (exact, order-free, and cheaper
    # on XLA:CPU than a NaN-propagating float max); NaN and inf sort above every finite
    absmask = ibits((1 << (nbits - 1)) - 1)
    mags = [lax.bitcast_convert_type(jnp.asarray(v, dtype), ibits) & absmask for v in values]
    top = functools.reduce(jnp.maximum, mags)
    top = jnp.max(top, axis=-1) if top.ndim else top
    with jax.enable_x64(True):
        top = top.astype(jnp.int64)
        biased = jnp.maximum(top >> mant, 1)  # |v| < 2^(biased - bias + 1) (zero: 2^(1 - bias))
        log2n = max(0, math.ceil(math.log2(n_bound)))
        s = B - log2n - (biased - bias + 1)
        s = jnp.clip(s, -1022, 1000)  # 2^s and 2^-s stay normal float64 numbers
        scale = lax.bitcast_convert_type((s + 1023) << 52, jnp.float64)
        inv = lax.bitcast_convert_type((1023 - s) << 52, jnp.float64)
        finite = top < (((1 << (nbits - 1 - mant)) - 1) << mant)  # exponent not all ones
        inv = jnp.where(finite, inv, jnp.nan)
    return scale, inv


def _quantise(row: Any, scale: Any, carrier: str) -> Any:
    with jax.enable_x64(True):
        q = jnp.round(row.astype(jnp.float64) * scale)
        return q.astype(jnp.int64) if carrier == "int64" else q


def _fixed_primal(
    n_nodes: int, idx: tuple[Any, ...], channels: tuple[Any, ...], bounds: tuple[Any, ...]
) -> tuple:
    dtype = np.dtype(channels[0][0].dtype)
    if dtype not in _FIXED:
        raise TypeError(f"fixed-point P2G: float32 or float64 contributions, not {dtype}")
    carrier = _FIXED[dtype][3]
    n_bound = len(idx) * int(idx[0].shape[-1])  # contributions a node can receive, at most
    # float32 data: a given bound sets the scale (a non-finite contribution still
    # propagates, through the float64 sums); float64 data: the rows' own maximum (an int64
    # sum would turn a NaN into 0)
    scales = [
        _fixed_scale([b] if b is not None and carrier == "float64" else list(c), dtype, n_bound)
        for c, b in zip(channels, bounds, strict=True)
    ]
    flat = _flat_scatter(n_nodes)
    out: list[Any] = []
    with jax.enable_x64(True):

        def add(rows: list[Any], gdtype: Any) -> Any:
            grid = jnp.zeros((n_nodes,), gdtype)
            for k in range(len(idx)):
                grid = flat(grid, idx[k], rows[k])
            return grid

        # one 64-bit scatter per channel: a complex128 pair would halve the scatters on a
        # CPU, but XLA:GPU runs a scatter of 128-bit elements one update at a time
        for ch, (sc, inv) in zip(channels, scales, strict=True):
            grid = add([_quantise(r, sc, carrier) for r in ch], carrier)
            out.append((grid.astype(jnp.float64) * inv).astype(dtype))
    return tuple(out)


@functools.cache
def _p2g_fixed(n_nodes: int) -> Any:
    @jax.custom_jvp
    def fixed(idx: tuple[Any, ...], channels: tuple[Any, ...], bounds: tuple[Any, ...]) -> tuple:
        return _fixed_primal(n_nodes, idx, channels, bounds)

    @fixed.defjvp
    def _jvp(primals: Any, tangents: Any) -> Any:
        idx, channels, bounds = primals

        # tangent: the plain float scatter-add of the tangent rows (linear, transposable)
        t_out = _float_sums(idx, tangents[1], n_nodes, _plain_scatter)
        return fixed(idx, channels, bounds), tuple(t_out)

    return fixed


def g2p(st: Stencil, grid: Any) -> tuple[Any, ...]:
    """Gather a flat grid field (n_nodes,) at the particles' stencils: S rows of (n,)."""
    take = _take(int(grid.shape[-1]))
    return tuple(take(grid, i) for i in st.idx)


def g2p_channels(st: Stencil, grids: Any) -> list[tuple[Any, ...]]:
    """`g2p` of several grid fields (n_nodes,): per field, S rows of (n,).

    Float32 fields go in pairs through one complex64 gather each (real part the first,
    imaginary part the second), half the gathers: the values are the same floats as
    `g2p`'s. An odd field out, and float64 fields, use `g2p` (`_pairs`). Measured on
    XLA:CPU (2-core Intel Xeon): 2D generic-slope step
    (300 000 particles) 37.2 -> 34.0 ms; mpm88 throughput +10-15 % at N = 32768 and
    131072 (benchmarks/README.md).
    """

    def unpaired(st: Stencil, grids: Any) -> list[tuple[Any, ...]]:
        return [g2p(st, g) for g in grids]

    def paired(st: Stencil, grids: Any) -> list[tuple[Any, ...]]:
        out = []
        for c in range(0, len(grids) - 1, 2):
            rows = g2p(st, jax.lax.complex(grids[c], grids[c + 1]))
            out += [tuple(jnp.real(r) for r in rows), tuple(jnp.imag(r) for r in rows)]
        if len(grids) % 2:
            out.append(g2p(st, grids[-1]))
        return out

    grids = list(grids)
    if not _pairs(grids[0].dtype):  # float64 fields: one real gather each
        return unpaired(st, grids)
    return _cpu_paired(paired, unpaired, st, grids)


def interpolate(st: Stencil, grid: Any) -> Any:
    """sum_k w_k grid[idx_k]: a grid field at the particles (n,)."""
    vals = g2p(st, grid)
    out = st.w[0] * vals[0]
    for k in range(1, len(vals)):
        out = out + st.w[k] * vals[k]
    return out
