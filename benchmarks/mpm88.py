"""Taichi's "mpm88" (MLS-MPM in 88 lines) in damjax's transfer kernels, against Taichi itself.

The problem is the example shipped with Taichi (``taichi/examples/simulation/mpm88.py``):
2D, 128 x 128 grid on the unit square, quadratic B-splines, APIC, a weakly compressible
fluid (p_vol = (dx/2)**2, rho = 1, E = 400, stress = -dt 4 E p_vol (J - 1) / dx**2, J updated
by 1 + dt tr(C)), gravity 9.8 downward, velocity clamped into the walls within ``bound = 3``
nodes of the boundary, dt = 2e-4, float32.

* damjax: one substep assembled from ``damjax.core.transfer`` (``stencil``, ``p2g``,
  ``g2p``; structure of arrays, particle index last, flat node arrays), advanced by a jitted
  ``jax.lax.scan``. Absolute positions in metres go in as the displacement ``u`` from
  ``cell0 = 0, frac0 = 0``; dx = 1/128 is a power of two, so ``u * (1/dx)`` is exact and equal to
  Taichi's ``x / dx``.
  Both P2G accumulations run (``accumulation="fixed"``, deterministic fixed-point sums;
  ``"float"``, plain float scatter-adds), so the price of determinism shows; the row's
  headline (``wall_time_s``, ``ratio``) is the one damjax's default ``"auto"`` picks on the
  backend (``"float"`` on a CPU, ``"fixed"`` on a GPU).
* Taichi: the example's ``substep`` kernel verbatim (one ``@ti.kernel`` per substep whose four
  top-level loops -- grid reset, P2G, grid update, G2P -- Taichi offloads as four parallel
  tasks), launched once per substep from Python as the example does, on the backend JAX
  uses: ``ti.cuda`` when ``jax.default_backend()`` is "gpu", else ``ti.cpu`` with
  ``cpu_max_num_threads`` equal to the cores JAX uses. Without taichi the peer is skipped.

Both start from the same seeded particles at rest (J = 1, C = 0; the example starts at
v = (0, -1)): uniform in the example's box [0.2, 0.6]**2 (``layout="random"``, 2621.44 cells,
so N / 2621.44 particles per cell), or 2 x 2 per cell on a lattice over 51 x 51 cells
(``layout="lattice"``, N = 10404). Each row reports the particles per cell
(``particles_per_cell``); a sweep over N on the fixed 128 x 128 grid shows how contention
for shared nodes (more particles per cell) changes the throughput.

    python -m benchmarks mpm88                      # the case: the rows of `CASE_ROWS`
    python -m benchmarks.mpm88 --n 8192 131072      # chosen sizes (--lattice: the 2 x 2 row)
    python -m benchmarks.mpm88 --step               # the damjax time step: fixed vs float
    python -m benchmarks.mpm88 --runs               # whole pst_f32 and slope runs: the same
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import statistics
import sys
import time
from typing import Any

import numpy as np

N_GRID = 128
DX = 1.0 / N_GRID
INV_DX = float(N_GRID)
DT = 2e-4
P_RHO = 1.0
P_VOL = (DX * 0.5) ** 2
P_MASS = P_VOL * P_RHO
GRAVITY = 9.8
BOUND = 3
E = 400.0
BOX_CELLS = (0.4 * N_GRID) ** 2  # cells of the random layout's box [0.2, 0.6]^2
LATTICE = (26, 51)  # lattice layout: first cell and cells per side (2 x 2 particles each)
ACCUMULATIONS = ("fixed", "float")


def default_accumulations() -> tuple[str, ...]:
    """Both accumulations, the one damjax's default ``"auto"`` picks on this backend first
    (`damjax.core.transfer.resolve_accumulation`)."""
    from damjax.core.transfer import resolve_accumulation

    first = resolve_accumulation("auto")
    return (first, *(a for a in ACCUMULATIONS if a != first))


# (N, repeats, layout) of `python -m benchmarks mpm88`: the particles-per-cell sweep on the
# fixed 128 x 128 grid (3.1, 12.5, 50, 200 per cell) and the 2 x 2 per cell lattice
CASE_ROWS = (
    (8192, 5, "random"),
    (32768, 5, "random"),
    (131072, 3, "random"),
    (524288, 3, "random"),
    (4 * LATTICE[1] ** 2, 5, "lattice"),
)


def n_threads() -> int:
    """CPU cores this process may use (the size of XLA:CPU's intra-op thread pool)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def initial_particles(n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Seeded particles in the example's box, at rest, J = 1 (array-of-structs shapes)."""
    rng = np.random.default_rng(seed)
    return dict(
        x=(rng.random((n, 2)) * 0.4 + 0.2).astype(np.float32),
        v=np.zeros((n, 2), np.float32),
        C=np.zeros((n, 2, 2), np.float32),
        J=np.ones((n,), np.float32),
    )


def lattice_particles(n: int | None = None, seed: int = 0) -> dict[str, np.ndarray]:
    """2 x 2 particles per cell at the quarter points of 51 x 51 cells (N = 10404), at rest
    (``n`` must be that N; the order is shuffled with ``seed``)."""
    c0, m = LATTICE
    if n is not None and n != 4 * m * m:
        raise ValueError(f"the lattice layout has {4 * m * m} particles, not {n}")
    sub = (np.arange(2) + 0.5) / 2
    g = (np.repeat(np.arange(c0, c0 + m), 2) + np.tile(sub, m)) * DX
    x = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    x = x[np.random.default_rng(seed).permutation(len(x))]
    p = initial_particles(len(x), seed)
    p["x"] = x.astype(np.float32)
    return p


def particles_per_cell(n: int, layout: str = "random") -> float:
    """Initial particles per occupied cell."""
    return 4.0 if layout == "lattice" else n / BOX_CELLS


def active_particles(n: int, seed: int = 1) -> dict[str, np.ndarray]:
    """A harder agreement check than the free fall from rest: a block resting against the left
    and bottom walls (inside their ``bound`` layers) with random velocities in [-1, 1] m/s,
    so stress, J, C and the wall clamps all act within the first 100 substeps."""
    rng = np.random.default_rng(seed)
    p = initial_particles(n, seed)
    p["x"] = (rng.random((n, 2)) * 0.4 + 0.02).astype(np.float32)
    p["v"] = (rng.random((n, 2)) * 2.0 - 1.0).astype(np.float32)
    return p


# --------------------------------------------------------------------------------------------
# damjax
# --------------------------------------------------------------------------------------------


def to_soa(p: dict[str, np.ndarray]) -> tuple[Any, Any, Any, Any]:
    """(x (2, n), v (2, n), C (2, 2, n), J (n,)) jax arrays, particle index last."""
    import jax.numpy as jnp

    return (
        jnp.asarray(p["x"].T.copy()),
        jnp.asarray(p["v"].T.copy()),
        jnp.asarray(np.transpose(p["C"], (1, 2, 0)).copy()),
        jnp.asarray(p["J"]),
    )


def transfer_api() -> str:
    """Which damjax.core.transfer this process sees: "rows" (the stencil as S separate (n,)
    rows, p2g/g2p over S rows) or "stacked" (the stencil as (S, n) arrays, commit 7eb5e82)."""
    import jax.numpy as jnp

    from damjax.core import transfer

    st = transfer.stencil(0, 0.0, jnp.full((2, 1), 0.5, jnp.float32), DX, (N_GRID, N_GRID))
    return "rows" if isinstance(st.w, (tuple, list)) else "stacked"


def _grid_update(grid_m: Any, grid_px: Any, grid_py: Any) -> tuple[Any, Any]:
    """mpm88's grid step: v = p / m where m > 0, gravity, walls within BOUND nodes."""
    import jax.numpy as jnp

    node = jnp.arange(N_GRID * N_GRID, dtype=jnp.int32)
    i, j = node // N_GRID, node % N_GRID
    m = jnp.where(grid_m > 0, grid_m, 1.0)  # an empty node keeps v = p (= 0)
    # the division comes last, as in damjax.core.step: XLA:CPU otherwise fuses this cheap
    # update (node coordinates, walls) into every G2P gather and re-evaluates it per
    # gathered element (N = 131072: 9 gathers of ~590 us). The walls test the sign of
    # the momentum, which is the velocity's (m > 0); gravity is added as a momentum.
    px = grid_px
    py = grid_py - (DT * GRAVITY) * m
    px = jnp.where(((i < BOUND) & (px < 0)) | ((i > N_GRID - BOUND) & (px > 0)), 0.0, px)
    py = jnp.where(((j < BOUND) & (py < 0)) | ((j > N_GRID - BOUND) & (py > 0)), 0.0, py)
    return px / m, py / m


def damjax_substep(
    state: tuple[Any, Any, Any, Any], accumulation: str | None = None
) -> tuple[Any, Any, Any, Any]:
    """One mpm88 substep on damjax.core.transfer, written as damjax.core.step writes its
    P2G and G2P for the transfer API present (see `transfer_api`); ``accumulation``:
    "fixed" or "float" (None: the transfer's default)."""
    import jax.numpy as jnp

    from damjax.core import transfer

    x, v, C, J = state
    n_nodes = N_GRID * N_GRID
    st = transfer.stencil(0, 0.0, x, DX, (N_GRID, N_GRID))  # cell0 = 0, frac0 = 0, u = x
    # affine = stress I + m C; momentum w (m v + affine @ dpos); mass w m
    stress = (-DT * 4 * E * P_VOL) * (J - 1.0) / DX**2
    aff = [
        [P_MASS * C[0, 0] + stress, P_MASS * C[0, 1]],
        [P_MASS * C[1, 0], P_MASS * C[1, 1] + stress],
    ]
    k_c = 4.0 * INV_DX**2

    if isinstance(st.w, (tuple, list)):  # rows API: S separate (n,) rows
        S = len(st.w)
        channels = [[st.w[k] * P_MASS for k in range(S)]] + [
            [
                st.w[k] * (P_MASS * v[a] + aff[a][0] * st.dpos[k][0] + aff[a][1] * st.dpos[k][1])
                for k in range(S)
            ]
            for a in range(2)
        ]
        if accumulation is not None:  # deterministic fixed point or float scatter-adds
            grid_m, *grid_p = transfer.p2g_channels(st, channels, n_nodes, accumulation)
        elif hasattr(transfer, "p2g_channels"):  # mass and momentum in complex pairs
            grid_m, *grid_p = transfer.p2g_channels(st, channels, n_nodes)
        else:
            grid_m, *grid_p = [transfer.p2g(st, c, n_nodes) for c in channels]
        gx, gy = _grid_update(grid_m, *grid_p)
        if hasattr(transfer, "g2p_channels"):  # vx and vy in one complex gather per row
            vs = transfer.g2p_channels(st, [gx, gy])  # 2 x S x (n,)
        else:
            vs = [transfer.g2p(st, gx), transfer.g2p(st, gy)]
        v_rows, C_rows = [], []
        for a in range(2):
            wv = [st.w[k] * vs[a][k] for k in range(S)]
            v_rows.append(sum(wv[1:], wv[0]))
            C_rows.append(
                [
                    k_c * sum((wv[k] * st.dpos[k][b] for k in range(1, S)), wv[0] * st.dpos[0][b])
                    for b in range(2)
                ]
            )
        new_v = jnp.stack(v_rows)
        new_C = jnp.stack([jnp.stack(r) for r in C_rows])
    else:  # stacked API: (S, n) arrays, reductions over the stencil axis with jnp.sum
        grid_m = transfer.p2g(st, st.w * P_MASS, n_nodes)
        grid_p = [
            transfer.p2g(
                st,
                st.w
                * (
                    P_MASS * v[a][None]
                    + aff[a][0][None] * st.dpos[0]
                    + aff[a][1][None] * st.dpos[1]
                ),
                n_nodes,
            )
            for a in range(2)
        ]
        gx, gy = _grid_update(grid_m, *grid_p)
        vx, vy = transfer.g2p(st, gx), transfer.g2p(st, gy)  # (S, n)
        new_v = jnp.stack([jnp.sum(st.w * vx, axis=0), jnp.sum(st.w * vy, axis=0)])
        new_C = jnp.stack(
            [
                jnp.stack([k_c * jnp.sum(st.w * g * st.dpos[b], axis=0) for b in range(2)])
                for g in (vx, vy)
            ]
        )
    x = x + DT * new_v
    J = J * (1.0 + DT * (new_C[0, 0] + new_C[1, 1]))
    return x, new_v, new_C, J


def damjax_runner(n_steps: int, substep=None, accumulation: str | None = None):
    """A jitted function advancing the state by n_steps substeps (one lax.scan);
    ``accumulation`` picks the P2G sums of the default substep."""
    import jax

    substep = substep or functools.partial(damjax_substep, accumulation=accumulation)

    def run(state):
        def body(s, _):
            return substep(s), None

        return jax.lax.scan(body, state, None, length=n_steps)[0]

    return jax.jit(run)


# --------------------------------------------------------------------------------------------
# Taichi
# --------------------------------------------------------------------------------------------


def jax_backend() -> str:
    """JAX's default backend ("cpu", "gpu", ...)."""
    import jax

    return jax.default_backend()


def taichi_init(threads: int, backend: str | None = None):
    """Import and initialise Taichi on the backend JAX uses: ``ti.cuda`` for "gpu", else
    ``ti.cpu`` with ``threads`` threads (None if taichi is not importable, or has no such
    backend here).

    Taichi's banner goes to stderr: stdout carries only the benchmark's JSON lines.
    """
    backend = backend or jax_backend()
    with contextlib.redirect_stdout(sys.stderr):
        try:
            import taichi as ti
        except Exception as e:  # any import failure means "skip the peer"
            sys.stderr.write(f"mpm88: taichi is not importable ({e!r}); peer skipped\n")
            return None
        kw = dict(arch=ti.cpu, cpu_max_num_threads=threads)
        if backend == "gpu":
            kw = dict(arch=ti.cuda)
        ti.init(
            **kw,
            default_fp=ti.f32,
            offline_cache=False,  # measure the real JIT compile time
            random_seed=0,
            log_level=ti.WARN,
        )
        arch = ti.lang.impl.current_cfg().arch
        if backend == "gpu" and arch != ti.cuda:  # Taichi fell back to the CPU
            sys.stderr.write("mpm88: taichi has no CUDA backend here; peer skipped\n")
            return None
    return ti


def taichi_arch_name(ti) -> str:
    """ "taichi-cuda" or "taichi-cpu", for the row's ``peer``."""
    return "taichi-cuda" if ti.lang.impl.current_cfg().arch == ti.cuda else "taichi-cpu"


def make_taichi_mpm88(ti, n_particles: int):
    """The example's fields and substep kernel for n_particles (a ti.data_oriented object)."""
    n_grid, dx, dt = N_GRID, DX, DT
    p_vol, p_mass, gravity, bound, E_ = P_VOL, P_MASS, GRAVITY, BOUND, E

    @ti.data_oriented
    class MPM88:
        def __init__(self):
            self.x = ti.Vector.field(2, float, n_particles)
            self.v = ti.Vector.field(2, float, n_particles)
            self.C = ti.Matrix.field(2, 2, float, n_particles)
            self.J = ti.field(float, n_particles)
            self.grid_v = ti.Vector.field(2, float, (n_grid, n_grid))
            self.grid_m = ti.field(float, (n_grid, n_grid))

        def load(self, p: dict[str, np.ndarray]) -> None:
            self.x.from_numpy(p["x"])
            self.v.from_numpy(p["v"])
            self.C.from_numpy(p["C"])
            self.J.from_numpy(p["J"])

        def state(self) -> dict[str, np.ndarray]:
            return dict(
                x=self.x.to_numpy(), v=self.v.to_numpy(), C=self.C.to_numpy(), J=self.J.to_numpy()
            )

        @ti.kernel
        def substep(self):
            # verbatim from taichi/examples/simulation/mpm88.py (fields on self)
            for i, j in self.grid_m:
                self.grid_v[i, j] = [0, 0]
                self.grid_m[i, j] = 0
            for p in self.x:
                Xp = self.x[p] / dx
                base = int(Xp - 0.5)
                fx = Xp - base
                w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1) ** 2, 0.5 * (fx - 0.5) ** 2]
                stress = -dt * 4 * E_ * p_vol * (self.J[p] - 1) / dx**2
                affine = ti.Matrix([[stress, 0], [0, stress]]) + p_mass * self.C[p]
                for i, j in ti.static(ti.ndrange(3, 3)):
                    offset = ti.Vector([i, j])
                    dpos = (offset - fx) * dx
                    weight = w[i].x * w[j].y
                    self.grid_v[base + offset] += weight * (p_mass * self.v[p] + affine @ dpos)
                    self.grid_m[base + offset] += weight * p_mass
            for i, j in self.grid_m:
                if self.grid_m[i, j] > 0:
                    self.grid_v[i, j] /= self.grid_m[i, j]
                self.grid_v[i, j].y -= dt * gravity
                if i < bound and self.grid_v[i, j].x < 0:
                    self.grid_v[i, j].x = 0
                if i > n_grid - bound and self.grid_v[i, j].x > 0:
                    self.grid_v[i, j].x = 0
                if j < bound and self.grid_v[i, j].y < 0:
                    self.grid_v[i, j].y = 0
                if j > n_grid - bound and self.grid_v[i, j].y > 0:
                    self.grid_v[i, j].y = 0
            for p in self.x:
                Xp = self.x[p] / dx
                base = int(Xp - 0.5)
                fx = Xp - base
                w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1) ** 2, 0.5 * (fx - 0.5) ** 2]
                new_v = ti.Vector.zero(float, 2)
                new_C = ti.Matrix.zero(float, 2, 2)
                for i, j in ti.static(ti.ndrange(3, 3)):
                    offset = ti.Vector([i, j])
                    dpos = (offset - fx) * dx
                    weight = w[i].x * w[j].y
                    g_v = self.grid_v[base + offset]
                    new_v += weight * g_v
                    new_C += 4 * weight * g_v.outer_product(dpos) / dx**2
                self.v[p] = new_v
                self.x[p] += dt * self.v[p]
                self.J[p] *= 1 + dt * new_C.trace()
                self.C[p] = new_C

    return MPM88()


# --------------------------------------------------------------------------------------------
# the benchmark
# --------------------------------------------------------------------------------------------


def _median(x: list[float]) -> float:
    return statistics.median(x)


def run_case(
    n_particles: int,
    n_steps: int = 100,
    repeats: int = 5,
    seed: int = 0,
    ti=None,
    runner=None,
    accumulations: tuple[str, ...] | None = None,
    layout: str = "random",
) -> dict:
    """Time damjax (each of ``accumulations``) and, if ti is given, Taichi, alternately;
    return one JSON row. The first accumulation is the row's headline (``wall_time_s``,
    ``ratio``; default: `default_accumulations`, the backend's default first); every one
    has its ``damjax_<acc>_*`` fields, and ``fixed_over_float`` compares the two.

    ``runner(n_steps)`` builds the jitted damjax function instead (the transfer
    experiments pass their variants; ``accumulations`` is then ignored).
    """
    import jax

    if accumulations is None:
        accumulations = default_accumulations()
    threads = n_threads()
    p0 = (
        lattice_particles(n_particles, seed)
        if layout == "lattice"
        else initial_particles(n_particles, seed)
    )
    n_particles = len(p0["x"])

    # damjax: AOT compile (timed), then warm runs
    s0 = to_soa(p0)
    jax.block_until_ready(s0)
    variants = (
        {"experiment": runner}
        if runner is not None
        else {a: functools.partial(damjax_runner, accumulation=a) for a in accumulations}
    )
    runs, compile_times = {}, {}
    for name, make in variants.items():
        t0 = time.perf_counter()
        runs[name] = make(n_steps).lower(s0).compile()
        compile_times[name] = time.perf_counter() - t0

    sim = None
    peer_compile = None
    if ti is not None:
        sim = make_taichi_mpm88(ti, n_particles)
        sim.load(p0)
        ti.sync()
        t0 = time.perf_counter()
        sim.substep()  # first launch JIT-compiles the kernel
        ti.sync()
        peer_compile = time.perf_counter() - t0

    walls: dict[str, list[float]] = {name: [] for name in runs}
    peer_walls: list[float] = []
    outs: dict[str, Any] = {}
    peer_out = None
    for r in range(repeats):
        order = list(runs) if r % 2 == 0 else list(runs)[::-1]  # alternate who goes first
        for name in order:
            t0 = time.perf_counter()
            outs[name] = jax.block_until_ready(runs[name](s0))
            walls[name].append(time.perf_counter() - t0)
        if sim is not None:
            sim.load(p0)
            ti.sync()
            t0 = time.perf_counter()
            for _ in range(n_steps):
                sim.substep()
            ti.sync()
            peer_walls.append(time.perf_counter() - t0)
            peer_out = sim.state()

    head = next(iter(runs))
    out = outs[head]
    wall = _median(walls[head])
    row: dict = dict(
        case="mpm88",
        n_particles=n_particles,
        particles_per_cell=round(particles_per_cell(n_particles, layout), 3),
        layout=layout,
        n_steps=n_steps,
        dtype="float32",
        n_grid=N_GRID,
        backend=jax_backend(),
        accumulation=None if runner is not None else head,
        compile_time_s=round(compile_times[head], 3),
        wall_time_s=round(wall, 4),
        wall_time_min_s=round(min(walls[head]), 4),
        particle_steps_per_s=round(n_particles * n_steps / wall),
        repeats=repeats,
        threads=threads,
        transfer_api=transfer_api() if runner is None else "experiment",
    )
    for name in runs:
        if name == "experiment":
            continue
        w = _median(walls[name])
        row[f"damjax_{name}_wall_time_s"] = round(w, 4)
        row[f"damjax_{name}_wall_time_min_s"] = round(min(walls[name]), 4)
        row[f"damjax_{name}_particle_steps_per_s"] = round(n_particles * n_steps / w)
        row[f"damjax_{name}_compile_time_s"] = round(compile_times[name], 3)
    x_dj = np.asarray(out[0]).T
    if not np.all(np.isfinite(x_dj)):
        raise RuntimeError("mpm88 (damjax): non-finite positions")
    if "fixed" in runs and "float" in runs:
        row["fixed_over_float"] = round(_median(walls["fixed"]) / _median(walls["float"]), 3)
        row["fixed_float_max_abs_diff"] = float(
            np.max(np.abs(np.asarray(outs["fixed"][0]) - np.asarray(outs["float"][0])))
        )
    if "fixed" in runs:
        # determinism, untimed: the particles stored in reverse order give the same bits
        rev = jax.block_until_ready(runs["fixed"](to_soa({k: v[::-1] for k, v in p0.items()})))
        row["fixed_reordered_bitwise_equal"] = bool(
            all(
                np.array_equal(np.asarray(a)[..., ::-1], np.asarray(b))
                for a, b in zip(outs["fixed"], rev, strict=True)
            )
        )

    # the harder agreement check (untimed): same compiled functions, other initial state
    active = active_particles(n_particles, seed + 1)
    active_outs = {name: jax.block_until_ready(f(to_soa(active))) for name, f in runs.items()}
    active_peer = None
    if sim is not None:
        sim.load(active)
        for _ in range(n_steps):
            sim.substep()
        active_peer = sim.state()

    if sim is None:
        row.update(
            peer=None,
            peer_particle_steps_per_s=None,
            peer_compile_time_s=None,
            ratio=None,
            state_max_abs_diff=None,
        )
        return row
    peer_wall = _median(peer_walls)
    diff_x = float(np.max(np.abs(x_dj - peer_out["x"])))
    diff_v = float(np.max(np.abs(np.asarray(out[1]).T - peer_out["v"])))
    diff_J = float(np.max(np.abs(np.asarray(out[3]) - peer_out["J"])))
    moved = float(np.max(np.abs(peer_out["x"] - p0["x"])))
    act_x = max(
        float(np.max(np.abs(np.asarray(a[0]).T - active_peer["x"]))) for a in active_outs.values()
    )
    act_J = float(np.max(np.abs(np.asarray(active_outs[head][3]) - active_peer["J"])))
    act_dJ = float(np.max(np.abs(active_peer["J"] - 1.0)))
    # 100 substeps from the same state: float32 rounding (and Taichi's unordered atomic adds)
    # keeps the two well within 1e-3 m (~0.13 cell) of each other; a wrong transfer or
    # boundary condition is off by far more (the particles fall ~ 2e-3 m in 100 substeps
    # and move up to 2e-2 m in the active check). Every accumulation is checked.
    for name, d in (("free fall", diff_x), ("active", act_x)):
        if not d < 1e-3:
            raise RuntimeError(
                f"mpm88: damjax and Taichi disagree after {n_steps} substeps ({name}): {d}"
            )
    row.update(
        peer=taichi_arch_name(ti),
        peer_version=".".join(map(str, ti.__version__)),
        peer_wall_time_s=round(peer_wall, 4),
        peer_wall_time_min_s=round(min(peer_walls), 4),
        peer_particle_steps_per_s=round(n_particles * n_steps / peer_wall),
        peer_compile_time_s=round(peer_compile, 3),
        ratio=round(peer_wall / wall, 3),
        state_max_abs_diff=diff_x,
        state_max_abs_diff_v=diff_v,
        state_max_abs_diff_J=diff_J,
        max_displacement=moved,
        active_state_max_abs_diff=act_x,
        active_state_max_abs_diff_J=act_J,
        active_max_abs_J_minus_1=act_dJ,
    )
    for name in runs:
        if name != "experiment":
            row[f"ratio_{name}"] = round(peer_wall / _median(walls[name]), 3)
    return row


# --------------------------------------------------------------------------------------------
# the damjax time step: fixed against float accumulation
# --------------------------------------------------------------------------------------------


def _fig12a_slope() -> tuple[Any, Any, Any, Any, Any]:
    """The Fig. 13a slope of ``python -m benchmarks slope`` (2 s, one particle per cell):
    (case, params, slope field, strength field, start)."""
    from damjax.slope import generic

    case = generic.GenericSlopeCase(duration=2.0, particles_per_cell=1)
    psi, tau = generic.slope_field(case), generic.strength_field(case)
    start = case.start if case.start is not None else generic.weak_spot(case, tau)
    return case, generic.fig12_params(), psi, tau, start


def step_rows(cases: tuple[str, ...] = ("pst", "slope"), rounds: int = 7) -> list[dict]:
    """The damjax time step (`damjax.core.loop.run_chunk`) with ``accumulation`` "fixed"
    and "float", compiled once each and timed alternately (``rounds`` rounds of a
    500-step chunk for the 1D baseline PST, 50 steps for the Fig. 13a slope): wall and
    process CPU time per step, medians and minima, and the fixed / float ratio."""
    import dataclasses

    import jax

    from damjax import PSTParams, PSTSetup
    from damjax.core import loop
    from damjax.core.model import build, build_slope, make_layout, make_slope_layout
    from damjax.slope import generic

    def pst(acc: str):
        p, s = PSTParams(), PSTSetup(accumulation=acc)
        return (*build(p, s, make_layout(p, s)), 500)

    def slope(acc: str):
        case, params, psi, tau, start = _fig12a_slope()
        setup = dataclasses.replace(generic.setup_of(case, start), accumulation=acc)
        layout = make_slope_layout(params, setup, float(np.max(psi)))
        return (*build_slope(params, setup, layout, psi, tau)[:2], 50)

    rows = []
    for name in cases:
        exes = {}
        for acc in ACCUMULATIONS:
            model, state, n = {"pst": pst, "slope": slope}[name](acc)
            exe = loop.compile_chunk(model, state, n)[0]
            jax.block_until_ready(exe(model, jax.tree.map(jax.numpy.copy, state)))
            exes[acc] = (exe, model, state, n)
        wall: dict[str, list[float]] = {a: [] for a in exes}
        cpu: dict[str, list[float]] = {a: [] for a in exes}
        for r in range(rounds):
            for acc in list(exes) if r % 2 == 0 else list(exes)[::-1]:
                exe, model, state, n = exes[acc]
                s = jax.block_until_ready(jax.tree.map(jax.numpy.copy, state))
                t0, c0 = time.perf_counter(), time.process_time()
                jax.block_until_ready(exe(model, s))  # the chunk donates its state
                wall[acc].append((time.perf_counter() - t0) / n * 1e6)
                cpu[acc].append((time.process_time() - c0) / n * 1e6)
        n_particles = int(exes["fixed"][2].u.shape[-1])
        row = dict(case=f"mpm88_step_{name}", n_particles=n_particles, rounds=rounds)
        for acc in exes:
            row[f"{acc}_us_per_step"] = round(_median(wall[acc]), 1)
            row[f"{acc}_us_per_step_min"] = round(min(wall[acc]), 1)
            row[f"{acc}_cpu_us_per_step"] = round(_median(cpu[acc]), 1)
        row["fixed_over_float"] = round(_median(wall["fixed"]) / _median(wall["float"]), 3)
        row["fixed_over_float_min"] = round(min(wall["fixed"]) / min(wall["float"]), 3)
        row["fixed_over_float_cpu"] = round(_median(cpu["fixed"]) / _median(cpu["float"]), 3)
        rows.append(row)
    return rows


def run_rows(rounds: int = 4, cases: tuple[str, ...] = ("pst_f32", "slope")) -> list[dict]:
    """Whole runs, "fixed" and "float" alternated in one process (the order flips every
    round), after one warm-up run each (compilation): the baseline PST of ``python -m
    benchmarks pst_f32`` and the Fig. 13a slope of ``python -m benchmarks slope``; wall
    times from the runs' summaries (time loop only), medians, minima and the ratio."""
    import dataclasses

    from damjax import PSTParams, PSTSetup, simulate_pst, simulate_slope
    from damjax.slope import generic

    def pst(acc: str) -> dict:
        s = simulate_pst(PSTParams(), PSTSetup(accumulation=acc)).summary
        return dict(
            wall=s["wall_time_s"],
            n=s["n_particles"],
            steps=s["n_steps"],
            arrest_position_m=s["arrest_position_m"],
            max_crack_speed_over_cs=s["max_crack_speed_over_cs"],
        )

    case, params, psi, tau, start = _fig12a_slope()

    def slope(acc: str) -> dict:
        setup = dataclasses.replace(generic.setup_of(case, start), accumulation=acc)
        s = simulate_slope(params, setup, slope_deg=psi, tau_peak=tau).summary
        return dict(
            wall=s["wall_time_s"],
            n=s["n_particles"],
            steps=s["n_steps"],
            release_area_m2=s["release_area_m2"],
            upslope_arrest_distance_m=s["upslope_arrest_distance_m"],
        )

    rows = []
    for name in cases:
        fn = {"pst_f32": pst, "slope": slope}[name]
        first = {acc: fn(acc) for acc in ACCUMULATIONS}  # compile + warm
        walls: dict[str, list[float]] = {acc: [] for acc in ACCUMULATIONS}
        cpus: dict[str, list[float]] = {acc: [] for acc in ACCUMULATIONS}
        for r in range(rounds):
            for acc in ACCUMULATIONS if r % 2 == 0 else ACCUMULATIONS[::-1]:
                c0 = time.process_time()
                walls[acc].append(fn(acc)["wall"])
                cpus[acc].append(time.process_time() - c0)  # the whole call, both threads
        row = dict(
            case=f"accumulation_{name}",
            n_particles=first["fixed"]["n"],
            n_steps=first["fixed"]["steps"],
            rounds=rounds,
        )
        for acc in ACCUMULATIONS:
            row[f"{acc}_wall_time_s"] = [round(w, 3) for w in walls[acc]]
            row[f"{acc}_median_s"] = round(_median(walls[acc]), 3)
            row[f"{acc}_diagnostics"] = {
                k: v for k, v in first[acc].items() if k not in ("wall", "n", "steps")
            }
        row["fixed_over_float"] = round(_median(walls["fixed"]) / _median(walls["float"]), 3)
        row["fixed_over_float_min"] = round(min(walls["fixed"]) / min(walls["float"]), 3)
        for acc in ACCUMULATIONS:
            row[f"{acc}_cpu_time_s"] = [round(c, 2) for c in cpus[acc]]
        row["fixed_over_float_cpu"] = round(_median(cpus["fixed"]) / _median(cpus["float"]), 3)
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)  # progress
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks mpm88", description=__doc__.split("\n")[0]
    )
    from benchmarks.cases import at_least, emit

    ap.add_argument("--n", type=at_least(int, 1), nargs="*", help="particle counts (random layout)")
    ap.add_argument("--lattice", action="store_true", help="the 2 x 2 particles per cell row")
    ap.add_argument(
        "--repeats",
        type=at_least(int, 1),
        default=None,
        help="timed repeats (default 5, 3 above 32768)",
    )
    ap.add_argument("--no-peer", action="store_true", help="skip Taichi")
    ap.add_argument("--step", action="store_true", help="damjax's own time step, fixed vs float")
    ap.add_argument(
        "--runs", action="store_true", help="whole pst_f32 and slope runs, fixed vs float"
    )
    ap.add_argument(
        "--rounds", type=at_least(int, 1), default=None, help="rounds of --step / --runs"
    )
    ap.add_argument("--cases", nargs="*", default=None, help="--step / --runs: pst and/or slope")
    args = ap.parse_args(argv)
    if args.step or args.runs:
        names = args.cases or ["pst", "slope"]
        rows = step_rows(tuple(names), rounds=args.rounds or 7) if args.step else []
        runs = tuple("pst_f32" if c == "pst" else c for c in names)
        rows += run_rows(rounds=args.rounds or 4, cases=runs) if args.runs else []
        for row in rows:
            emit(**row)
        return 0
    ti = None if args.no_peer else taichi_init(n_threads())
    rows = [(n, args.repeats or (5 if n <= 32768 else 3), "random") for n in (args.n or [])]
    if args.lattice:
        rows.append((4 * LATTICE[1] ** 2, args.repeats or 5, "lattice"))
    for n, repeats, layout in rows or CASE_ROWS:
        emit(**run_case(n, n_steps=100, repeats=repeats, ti=ti, layout=layout))
    return 0


if __name__ == "__main__":
    sys.exit(main())
