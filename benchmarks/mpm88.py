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
* Taichi: the example's ``substep`` kernel verbatim (one ``@ti.kernel`` per substep whose four
  top-level loops -- grid reset, P2G, grid update, G2P -- Taichi offloads as four parallel
  tasks), launched once per substep from Python as the example does, on ``ti.cpu`` with
  ``cpu_max_num_threads`` equal to the cores JAX uses.

Both start from the same seeded particles: uniform in the example's box [0.2, 0.6]**2, J = 1,
C = 0 and zero velocity (the example starts at v = (0, -1); the brief asks for rest).
"""

from __future__ import annotations

import contextlib
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


def damjax_substep(state: tuple[Any, Any, Any, Any]) -> tuple[Any, Any, Any, Any]:
    """One mpm88 substep on damjax.core.transfer, written as damjax.core.step writes its
    P2G and G2P for the transfer API present (see `transfer_api`)."""
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
        if hasattr(transfer, "p2g_channels"):  # mass and momentum in complex pairs
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


def damjax_runner(n_steps: int, substep=None):
    """A jitted function advancing the state by n_steps substeps (one lax.scan)."""
    import jax

    substep = substep or damjax_substep

    def run(state):
        def body(s, _):
            return substep(s), None

        return jax.lax.scan(body, state, None, length=n_steps)[0]

    return jax.jit(run)


# --------------------------------------------------------------------------------------------
# Taichi
# --------------------------------------------------------------------------------------------


def taichi_init(threads: int):
    """Import and initialise Taichi on the CPU (None if it is not importable).

    Taichi's banner goes to stderr: stdout carries only the benchmark's JSON lines.
    """
    with contextlib.redirect_stdout(sys.stderr):
        try:
            import taichi as ti
        except Exception as e:  # any import failure means "skip the peer"
            sys.stderr.write(f"mpm88: taichi is not importable ({e!r}); peer skipped\n")
            return None
        ti.init(
            arch=ti.cpu,
            cpu_max_num_threads=threads,
            default_fp=ti.f32,
            offline_cache=False,  # measure the real JIT compile time
            random_seed=0,
            log_level=ti.WARN,
        )
    return ti


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


def run_case(
    n_particles: int,
    n_steps: int = 100,
    repeats: int = 5,
    seed: int = 0,
    ti=None,
    runner=None,
) -> dict:
    """Time damjax and (if ti is given) Taichi alternately; return one JSON row.

    ``runner(n_steps)`` builds the jitted damjax function (default ``damjax_runner``; the
    transfer experiments pass their variants).
    """
    import jax

    threads = n_threads()
    p0 = initial_particles(n_particles, seed)

    # damjax: AOT compile (timed), then warm runs
    s0 = to_soa(p0)
    jax.block_until_ready(s0)
    t0 = time.perf_counter()
    run = (runner or damjax_runner)(n_steps).lower(s0).compile()
    compile_time = time.perf_counter() - t0

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

    walls, peer_walls = [], []
    out = peer_out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(run(s0))
        walls.append(time.perf_counter() - t0)
        if sim is not None:
            sim.load(p0)
            ti.sync()
            t0 = time.perf_counter()
            for _ in range(n_steps):
                sim.substep()
            ti.sync()
            peer_walls.append(time.perf_counter() - t0)
            peer_out = sim.state()

    # the harder agreement check (untimed): same compiled function, other initial state
    active = active_particles(n_particles, seed + 1)
    active_out = jax.block_until_ready(run(to_soa(active)))
    active_peer = None
    if sim is not None:
        sim.load(active)
        for _ in range(n_steps):
            sim.substep()
        active_peer = sim.state()

    wall = statistics.median(walls)
    row: dict = dict(
        case="mpm88",
        n_particles=n_particles,
        n_steps=n_steps,
        dtype="float32",
        n_grid=N_GRID,
        compile_time_s=round(compile_time, 3),
        wall_time_s=round(wall, 4),
        wall_time_min_s=round(min(walls), 4),
        particle_steps_per_s=round(n_particles * n_steps / wall),
        repeats=repeats,
        threads=threads,
        transfer_api=transfer_api() if runner is None else "experiment",
    )
    x_dj = np.asarray(out[0]).T
    if not np.all(np.isfinite(x_dj)):
        raise RuntimeError("mpm88 (damjax): non-finite positions")
    if sim is None:
        row.update(
            peer=None,
            peer_particle_steps_per_s=None,
            peer_compile_time_s=None,
            ratio=None,
            state_max_abs_diff=None,
        )
        return row
    peer_wall = statistics.median(peer_walls)
    diff_x = float(np.max(np.abs(x_dj - peer_out["x"])))
    diff_v = float(np.max(np.abs(np.asarray(out[1]).T - peer_out["v"])))
    diff_J = float(np.max(np.abs(np.asarray(out[3]) - peer_out["J"])))
    moved = float(np.max(np.abs(peer_out["x"] - p0["x"])))
    act_x = float(np.max(np.abs(np.asarray(active_out[0]).T - active_peer["x"])))
    act_J = float(np.max(np.abs(np.asarray(active_out[3]) - active_peer["J"])))
    act_dJ = float(np.max(np.abs(active_peer["J"] - 1.0)))
    # 100 substeps from the same state: float32 rounding (and Taichi's unordered atomic adds)
    # keeps the two well within 1e-3 m (~0.13 cell) of each other; a wrong transfer or
    # boundary condition is off by far more (the particles fall ~ 2e-3 m in 100 substeps
    # and move up to 2e-2 m in the active check).
    for name, d in (("free fall", diff_x), ("active", act_x)):
        if not d < 1e-3:
            raise RuntimeError(
                f"mpm88: damjax and Taichi disagree after {n_steps} substeps ({name}): {d}"
            )
    row.update(
        peer="taichi-cpu",
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
    return row
