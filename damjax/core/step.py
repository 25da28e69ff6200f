"""The one explicit DA-MPM time step shared by every scenario (1D strip and 2D slope).

`step` is a short driver over the step's phases (MLS-MPM with APIC momentum, symplectic
Euler), each a function below whose body runs under ``jax.named_scope`` of its name, so
that a profile or the lowered program (``jax.jit(step).lower(model, state)``) reads by
phase:

1. ``weak_layer`` (`weak_layer_forces`): per particle, the cohesive traction
   tau = k_sec(u_max) u on the intact part of its segment of weak layer, and the
   acceleration from gravity and cohesion;
2. ``p2g`` (`particles_to_grid`): mass, momentum including dt times every particle force
   (gravity, cohesion and the internal force -V0 sigma grad w folded into the affine
   term), and the friction cap;
3. ``grid_update`` (`grid_update`): v* = p / m, then Coulomb friction as an impulse cap:
   |v| shrinks by dt F_cap / m, never past zero (a slab at rest stays at rest);
4. ``g2p`` (`grid_to_particles`): v, C and displacement (a particle whose stencil would
   leave the grid stops there and leaves the run, where the run has outflow);
5. ``slab_law`` (`slab_law`): strain increment, stress, plastic strain and openings;
6. ``crack_and_saw`` (`crack_and_saw`): damage history, crack tip and saw;
7. ``guards`` (`guards`): runtime fault flags.

Phases pass what the next ones need as small named tuples; the ones named after `State`
fields are the step's new state. The floating-point operations are those of the step
written as one function, in the same order (the program JAX lowers is the same).

Depth averaging: momentum per unit area is rho h dv/dt = div(h sigma) - tau_b + rho h g.
With h A = h0 A0 (mass conservation of the column) the internal force on node i is
-sum_p h0 A0 sigma_p grad w_ip, gravity is m_p g, the cohesive traction acts on the
current base area A0 J and the friction cap is m_p g_n tan(phi).
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.ad_checkpoint import checkpoint_name

from damjax.core import transfer
from damjax.core.state import FAULT_EDGE, FAULT_NAN, FAULT_THICKNESS, Model, State
from damjax.materials import mcc, slab, slab_fracture, weak_layer


def stress_tensor(sigma: Any, dim: int) -> list[list[Any]]:
    """In-plane stress tensor as dim x dim nested lists of (n,) rows, from (xx, yy, xy)."""
    if dim == 1:
        return [[sigma[0]]]
    return [[sigma[0], sigma[2]], [sigma[2], sigma[1]]]


def strain_increment(C: Any, dt: Any, dim: int) -> tuple[Any, Any, Any]:
    """(xx, yy, xy) small-strain increment dt sym(C); the 1D yy part is set by the lateral law."""
    if dim == 1:
        z = jnp.zeros_like(C[0, 0])
        return dt * C[0, 0], z, z
    return dt * C[0, 0], dt * C[1, 1], 0.5 * dt * (C[0, 1] + C[1, 0])


def slip_and_rate(u: Any, v: Any, dim: int) -> tuple[Any, Any]:
    """Slip |u| [m] and its rate d|u|/dt = u.v / |u| [m/s] per particle, rows (n,)."""
    if dim == 1:
        return jnp.abs(u[0]), jnp.sign(u[0]) * v[0]
    u2 = u[0] * u[0] + u[1] * u[1]
    pos = u2 > 0.0
    slip = jnp.sqrt(jnp.where(pos, u2, 1.0))
    rate = jnp.where(pos, (u[0] * v[0] + u[1] * v[1]) / slip, 0.0)
    return jnp.where(pos, slip, 0.0), rate


def front_width(model: Model) -> Any:
    """Slip range [m] across a particle's segment of weak layer near a crack front
    (`damjax.materials.weak_layer.front_width`), from the particle spacing and the
    elastic length Lambda = sqrt(E h / ((1 - nu^2) K_wl)); derived once when the model is
    built (`WeakLayer.front_width`)."""
    if model.weak_layer.front_width is not None:
        return model.weak_layer.front_width
    return model.with_constants().weak_layer.front_width  # built without its constants


def broken_mask(model: Model, state: State) -> Any:
    """Where the weak layer has lost all cohesion (sawn or fully softened)."""
    cut = model.saw.saw_coord < state.saw_pos
    return weak_layer.is_broken(state.u_max, model.weak_layer.u_res, cut)


def constitutive(
    model: Model, state: State, eps: Any, start: slab_fracture.StepStart | None = None
) -> tuple[Any, Any, Any, Any, Any]:
    """Slab law on the trial total strain: (eps, sigma, eps_p, d_opening, d_opening_y),
    rows (n,); d_opening_y (2D; None in 1D) is the part of d_opening along y, the opening
    increment times n_y^2 for the direction n of the largest principal plastic strain.
    ``start``: `damjax.materials.slab_fracture.step_start` of the state (plastic slabs;
    made here when not given), whose return maps do the plastic update.

    1D strips get eps_yy from the lateral condition: "constrained" keeps eps_yy = 0,
    "free" keeps sigma_yy = 0 (uniaxial stress, exact uniaxial return mapping).

    Rows that stay zero in 1D (free: eps_xy, sigma_yy, sigma_xy; constrained: eps_yy) are
    the state's own rows, passed through (zero from the initial state): a fresh zero row
    is a new buffer that the time loop copies into its carry every step (1D baseline:
    a broadcast and two copies, 9 of ~215 us per step).
    """
    E, nu = model.slab.youngs_modulus, model.slab.poisson
    eps_p = tuple(state.eps_p)
    zero = jnp.zeros_like(eps[0])
    if model.fracture.plastic and start is None:
        start = slab_fracture.step_start(model.slab, model.fracture, state)
    if model.dim == 1 and model.slab.lateral == "free":
        sig_tr = E * (eps[0] - eps_p[0])
        if model.fracture.plastic:
            sxx, dxx, dyy = slab_fracture.return_map_uniaxial(
                model.slab, model.fracture, sig_tr, start
            )
            eps_p = (eps_p[0] + dxx, eps_p[1] + dyy, eps_p[2])
            d_open = jnp.maximum(dxx, 0.0)
        else:
            sxx, d_open = sig_tr, zero
        eps = (eps[0], -nu * sxx / E + eps_p[1], state.eps[2])
        return eps, (sxx, state.sigma[1], state.sigma[2]), eps_p, d_open, None
    if model.dim == 1:  # constrained: eps_yy = 0
        eps = (eps[0], state.eps[1], eps[2])
    eps_e = tuple(a - b for a, b in zip(eps, eps_p, strict=True))
    if not model.fracture.plastic:
        return eps, slab.plane_stress(eps_e, E, nu), eps_p, zero, None
    sigma, d_eps_p, d_open, d_open_y = slab_fracture.return_map_plane(
        model.slab, model.fracture, state, eps_e, start
    )
    eps_p = tuple(a + b for a, b in zip(eps_p, d_eps_p, strict=True))
    return eps, sigma, eps_p, d_open, (None if model.dim == 1 else d_open_y)


def _inv_d(dx: float) -> float:
    """MLS-MPM inverse inertia of the quadratic B-spline, 4 / dx^2 [1/m^2] (a constant)."""
    return 4.0 / dx**2


class WeakLayerForces(NamedTuple):
    """What the weak layer does in a step (`weak_layer_forces`)."""

    time: Any  # time at the end of the step [s]
    saw_pos: Any  # saw position along saw_coord at the end of the step [m]
    intact: Any  # (n,) intact fraction of each particle's segment of weak layer [-]
    acc: Any  # (dim, n) acceleration from gravity and cohesion [m/s^2]


class GridSums(NamedTuple):
    """The particles' sums on the grid (`particles_to_grid`)."""

    stencil: transfer.Stencil  # the particles' B-spline stencil (weights, offsets, cells)
    active: Any  # (n,) bool: the particles still on the grid (None: all; `State.outflow`)
    mass: Any  # (n_nodes,) node mass [kg]
    momentum: Any  # dim rows (n_nodes,) of node momentum after the particle forces [kg m/s]
    cap: Any  # (n_nodes,) friction cap: the Coulomb force the nodes can resist [N]


class GridVelocity(NamedTuple):
    """Node velocities after the friction cap (`grid_update`)."""

    velocity: Any  # dim rows (n_nodes,) [m/s]
    speed2: Any  # (n_nodes,) squared speed before the cap [m^2/s^2] (the NaN guard's)


class Motion(NamedTuple):
    """The particles' new kinematics (`grid_to_particles`), `State` fields."""

    u: Any  # (dim, n) displacement [m]
    v: Any  # (dim, n) velocity [m/s]
    C: Any  # (dim, dim, n) affine velocity [1/s]
    outflow: Any  # (n,) bool: the particles that slid over the grid's edge (None: no outflow)


class SlabUpdate(NamedTuple):
    """The slab's new strains, stresses and openings (`slab_law`), `State` fields."""

    eps: Any  # (xx, yy, xy) rows of the total strain [-]
    sigma: Any  # (xx, yy, xy) rows of the stress [Pa]
    eps_p: Any  # (xx, yy, xy) rows of the plastic strain [-]
    opening: Any  # (n,) accumulated tensile plastic strain [-]
    opening_y: Any  # (n,) its part along y [-]
    t_fracture: Any  # (n,) time the band opening reached the fracture opening [s]


class CrackUpdate(NamedTuple):
    """Damage history, crack tip and saw (`crack_and_saw`), `State` fields."""

    u_max: Any  # (n,) maximum slip reached [m]
    t_broken: Any  # (n,) time the weak layer under the particle lost all cohesion [s]
    tip: Any  # furthest saw_coord where the layer has lost all cohesion [m]
    saw_active: Any  # bool: the saw still cuts


class Faults(NamedTuple):
    """Runtime fault flags (`guards`), `State` fields."""

    fault: Any  # int32 bit flags, FAULT_*
    fault_time: Any  # simulated time of the first fault [s] (nan if none)


def step(model: Model, state: State) -> State:
    """Advance the state by one time step dt = model.dt: the phases in order."""
    mass = model.mass  # particle mass [kg] (P2G and the grid's empty-node threshold)
    wl = weak_layer_forces(model, state)
    sums = particles_to_grid(model, state, wl, mass)
    grid = grid_update(model, sums, mass)
    motion = grid_to_particles(model, state, sums.stencil, grid.velocity, sums.active)
    slab_new = slab_law(model, state, motion.C)
    crack = crack_and_saw(model, state, motion.u, wl.time, wl.saw_pos)
    faults = guards(model, state, sums.stencil, grid.speed2, slab_new.eps, wl.time)
    return dataclasses.replace(
        state,
        time=wl.time,
        saw_pos=wl.saw_pos,
        **motion._asdict(),
        **slab_new._asdict(),
        **crack._asdict(),
        **faults._asdict(),
    )


def weak_layer_forces(model: Model, state: State) -> WeakLayerForces:
    """Phase 1, the weak layer (cohesion only; friction is a grid-level cap, `grid_update`):
    the time and saw position at the end of the step [s, m], the intact fraction of each
    particle's segment of weak layer [-] and the acceleration from gravity and cohesion
    [m/s^2]."""
    with jax.named_scope("weak_layer"):
        dt = model.dt
        cut = model.saw.saw_coord < state.saw_pos
        k_sec = weak_layer.cohesive_factor(
            state.u_max,
            model.weak_layer.tau_peak,
            residual_shear(model, state),
            model.weak_layer.stiffness,
            model.weak_layer.softening,
            cut,
        )
        # Failure without events: a particle's segment of weak layer fails progressively as
        # the crack front crosses it, and cohesion acts on its intact part for the part of
        # the step before the saw reaches it; friction acts on the rest. Averaged over the
        # step, both make the impulse and the state after a failure continuous in its time
        # (`damjax.materials.weak_layer`), so reverse mode carries the shift of every
        # failure.
        time = state.time + dt
        saw_pos = jnp.where(state.saw_active, model.saw.saw_speed * time, state.saw_pos)
        slip, slip_rate = slip_and_rate(state.u, state.v, model.dim)
        failed = weak_layer.failed_fraction_in_step(
            state.u_max, slip, slip_rate, model.weak_layer.u_res, front_width(model), dt
        )
        unsawn = weak_layer.sawn_fraction(model.saw.saw_coord, state.saw_pos, saw_pos)
        intact = jnp.where(cut, 0.0, jnp.minimum(1.0 - failed, unsawn))
        J = slab.area_ratio(state.eps)
        # acceleration from gravity and cohesion; area0 / m = 1 / (rho h0)
        acc = (
            model.g_tangent
            - (J * k_sec * intact / (model.slab.density * model.slab.thickness)) * state.u
        )
        return WeakLayerForces(time, saw_pos, intact, acc)


def particles_to_grid(model: Model, state: State, wl: WeakLayerForces, mass: Any) -> GridSums:
    """Phase 2, P2G: node mass [kg], momentum after dt times every particle force
    [kg m/s] (gravity and cohesion, ``wl.acc``; the internal force folded into the affine
    term) and the friction cap of the failed weak layer [N], on the particles' stencil;
    particles that left the grid (`State.outflow`) add nothing. ``mass``: the particle
    mass [kg] (`Model.mass`)."""
    with jax.named_scope("p2g"):
        dim, dx, dt = model.dim, model.grid.dx, model.dt
        m, inv_d = mass, _inv_d(dx)
        # outflow (slopes): particles that slid over the grid's edge add nothing to the grid
        active = None if state.outflow is None else ~state.outflow
        sig = stress_tensor(state.sigma, dim)
        c_sig = dt * inv_d * model.slab.thickness * model.slab.area0
        affine = [[m * state.C[a, b] - c_sig * sig[a][b] for b in range(dim)] for a in range(dim)]
        v_star = state.v + dt * wl.acc
        fcap = (1.0 - wl.intact) * (m * model.weak_layer.friction * model.g_normal)
        # the particles' P2G factors computed once, into buffers: XLA:CPU would recompute
        # their arithmetic (the weak layer's law included) in every fusion that builds a
        # P2G row, and slower still in the 64-bit rows of fixed-point sums
        # (`transfer.materialise`; 1D baseline step 204 -> 176 us with float sums)
        finite_dt = jnp.isfinite(dt)  # the barriers' runtime predicate (`transfer.materialise`)
        v_star, affine, fcap, u_p2g = transfer.materialise(
            (v_star, affine, fcap, state.u), finite_dt
        )
        grid = model.grid
        st = transfer.stencil(grid.cell0, grid.frac0, u_p2g, dx, grid.grid_shape, grid.periodic)
        n_nodes = model.n_nodes
        S = len(st.w)
        w_p2g = st.w
        if active is not None:  # times exactly 1 or 0: a run without outflow is unchanged
            w_p2g = tuple(w * active.astype(w.dtype) for w in st.w)
        mass_rows = [w_p2g[k] * m for k in range(S)]
        mom_rows = []
        for a in range(dim):
            mv = m * v_star[a]
            rows = []
            for k in range(S):
                q = mv
                for b in range(dim):
                    q = q + affine[a][b] * st.dpos[k][b]
                rows.append(w_p2g[k] * q)
            mom_rows.append(rows)
        cap_rows = [w_p2g[k] * fcap for k in range(S)]
        # mass, momentum and cap (on a CPU in complex pairs: half the scatters); fixed-point
        # sums take their scales from per-particle bounds of the rows (w <= 1, |dpos| <=
        # 1.5 dx), cheaper than the maxima of the rows themselves
        bounds = None
        if model.accumulation == "fixed":
            bounds = [
                m,
                *(
                    jnp.abs(m * v_star[a]) + (1.5 * dx) * sum(jnp.abs(x) for x in affine[a])
                    for a in range(dim)
                ),
                fcap,
            ]
        grids = transfer.p2g_channels(
            st, [mass_rows, *mom_rows, cap_rows], n_nodes, model.accumulation, bounds=bounds
        )
        # reverse mode gathers each grid's cotangent once per stencil row: computed into
        # buffers first, not re-evaluated per gathered particle (`transfer.tangent_barrier`)
        grids = transfer.tangent_barrier(grids, finite_dt)
        grid_mass, grid_mom, grid_cap = grids[0], grids[1 : 1 + dim], grids[1 + dim]

        # named for the reverse pass: `integrate_pure` keeps these small grid arrays per
        # step and so does not redo the P2G scatters when it recomputes a step
        grid_mass, grid_mom, grid_cap = checkpoint_name((grid_mass, grid_mom, grid_cap), "p2g")
        return GridSums(st, active, grid_mass, grid_mom, grid_cap)


def grid_update(model: Model, sums: GridSums, mass: Any) -> GridVelocity:
    """Phase 3, the grid: node velocities p / m [m/s] with the Coulomb friction cap as an
    impulse (|v| shrinks by dt F_cap / m, never past zero). ``mass``: the particle mass
    [kg] (`Model.mass`), the scale of the empty-node threshold (`Model.mass_ref` where the
    thickness is per particle)."""
    with jax.named_scope("grid_update"):
        dt = model.dt
        # nodes holding less than 1e-6 of a particle's mass count as empty: their velocity
        # p / m is ill-conditioned, and in 2D reverse mode the 1/m^2 of a node touched only
        # by a B-spline tail (weight ~1e-12) overflows float32 (0 * inf = NaN gradients)
        has_mass = sums.mass > 1e-6 * (mass if model.slab.mass_ref is None else model.slab.mass_ref)
        m_safe = jnp.where(has_mass, sums.mass, 1.0)
        inv_m = jnp.where(has_mass, 1.0 / m_safe, 0.0)
        vg = [p * inv_m for p in sums.momentum]
        speed2 = sum(c * c for c in vg)
        moving = speed2 > 0.0
        speed = jnp.sqrt(jnp.where(moving, speed2, 1.0))
        scale = jnp.where(moving, jnp.maximum(0.0, 1.0 - dt * sums.cap * inv_m / speed), 0.0)
        # a division last: XLA:CPU fuses a cheap grid update into every G2P gather and
        # re-evaluates it per gathered element (1D baseline: 3 x 23 us per step); a divide
        # counts as expensive, so the grid velocity is evaluated once per node
        vg = [(p * scale) / m_safe for p in sums.momentum]
        return GridVelocity(vg, speed2)


def grid_to_particles(
    model: Model, state: State, st: transfer.Stencil, velocity: Any, active: Any = None
) -> Motion:
    """Phase 4, G2P: the particles' velocity [m/s] and affine velocity [1/s] from the node
    velocities ``velocity`` on their stencil ``st``, and the displacement [m] they move
    (rows kept separate: sums over the stencil are elementwise adds). With outflow
    (``active``: the particles still on the grid, `GridSums.active`), a particle whose
    stencil would leave the grid stops there and leaves the run."""
    with jax.named_scope("g2p"):
        dim, inv_d = model.dim, _inv_d(model.grid.dx)
        S = len(st.w)
        vs = transfer.g2p_channels(st, velocity)  # dim x S x (n,)
        v_rows, C_rows = [], []
        for a in range(dim):
            wv = [st.w[k] * vs[a][k] for k in range(S)]
            v_rows.append(sum(wv[1:], wv[0]))
            C_rows.append(
                [
                    inv_d * sum((wv[k] * st.dpos[k][b] for k in range(1, S)), wv[0] * st.dpos[0][b])
                    for b in range(dim)
                ]
            )
        v_new = jnp.stack(v_rows)
        C_new = jnp.stack([jnp.stack(r) for r in C_rows])
        u_new = state.u + model.dt * v_new
        outflow = state.outflow
        if active is not None:
            # a particle whose stencil would leave the grid in this step stays where it was
            # and leaves the run (outflow); one that left earlier is at rest and unstrained
            leaving = _off_grid(model, u_new) & active
            outflow = state.outflow | leaving
            moving_p = active & ~leaving
            v_new = jnp.where(moving_p, v_new, 0.0)
            C_new = jnp.where(active, C_new, 0.0)
            u_new = jnp.where(moving_p, u_new, state.u)
        return Motion(u_new, v_new, C_new, outflow)


def slab_law(model: Model, state: State, C: Any) -> SlabUpdate:
    """Phase 5, the slab law on the strain increment dt sym(C) of the new affine velocity
    ``C`` [1/s]: total and plastic strains [-], stress [Pa], the accumulated openings [-]
    and the fracture times [s] (`constitutive`)."""
    with jax.named_scope("slab_law"):
        d_eps = strain_increment(C, model.dt, model.dim)
        # the fracture law's view of the step's start: band openings, strengths, fracture
        # times
        start, t_fracture = None, state.t_fracture
        if model.fracture.plastic:  # an elastic slab never fractures
            start = slab_fracture.step_start(model.slab, model.fracture, state)
            t_fracture = start.t_fracture
        eps, sigma, eps_p, d_open, d_open_y = constitutive(
            model, state, tuple(a + b for a, b in zip(state.eps, d_eps, strict=True)), start
        )
        opening = state.opening + d_open
        opening_y = state.opening_y if d_open_y is None else state.opening_y + d_open_y
        return SlabUpdate(eps, sigma, eps_p, opening, opening_y, t_fracture)


def crack_and_saw(model: Model, state: State, u: Any, time: Any, saw_pos: Any) -> CrackUpdate:
    """Phase 6, crack and saw: the maximum slip [m] at the new displacement ``u``, the time
    each particle's weak layer broke [s], the crack tip [m] and whether the saw still
    cuts (it stops once the crack leads it by `Saw.saw_lead` where `Saw.saw_stops`).
    ``time``, ``saw_pos``: at the end of the step [s, m]."""
    with jax.named_scope("crack_and_saw"):
        # rows added elementwise: XLA:CPU reduces over a short leading axis in a slow loop
        # (jnp.sum(u * u, axis=0) was 4.2 of 40 ms per 2D slope step, 300 000 particles)
        # sqrt with a finite gradient at zero slip (a 2D particle at rest on a flat cell)
        slip = mcc._sqrt(u[0] * u[0] + u[1] * u[1]) if model.dim > 1 else jnp.abs(u[0])
        u_max = jnp.maximum(state.u_max, slip)
        broken_new = weak_layer.is_broken(
            u_max, model.weak_layer.u_res, model.saw.saw_coord < saw_pos
        )
        t_broken = jnp.where(broken_new & jnp.isinf(state.t_broken), time, state.t_broken)
        tip = jnp.max(jnp.where(broken_new, model.saw.saw_coord, -jnp.inf))
        tip = jnp.maximum(tip, state.tip)
        saw_active = state.saw_active
        if model.saw.saw_stops:
            saw_active = saw_active & (tip < saw_pos + model.saw.saw_lead)
        return CrackUpdate(u_max, t_broken, tip, saw_active)


def guards(
    model: Model, state: State, st: transfer.Stencil, speed2: Any, eps: Any, time: Any
) -> Faults:
    """Phase 7, runtime guards (cheap reductions; the caller stops at the first fault):
    a non-finite grid speed (``speed2``, `grid_update`), a particle's stencil ``st`` at
    the grid's edge, a column height h <= 0 (the new strain ``eps``); the fault's time
    ``time`` [s]."""
    with jax.named_scope("guards"):
        # The edge test is one any() of per-particle flags: min and max of the base cells
        # were two int reductions, 25 of ~200 us per 1D baseline step on XLA:CPU.
        # J = exp(tr eps) reaches 0 only by underflow: test tr eps, not min(exp(.)), which
        # XLA:CPU evaluates in a slow reduction fusion (30 us of a 230 us baseline PST step)
        log_tiny = float(np.log(np.finfo(eps[0].dtype).tiny))
        edge = _beyond_edge(model.grid, st.base)
        fault = (
            jnp.where(~jnp.all(jnp.isfinite(speed2)), FAULT_NAN, 0)
            | jnp.where(jnp.any(edge), FAULT_EDGE, 0)
            | jnp.where(jnp.any(eps[0] + eps[1] < log_tiny), FAULT_THICKNESS, 0)
        )
        fault = state.fault | fault
        fault_time = jnp.where((state.fault == 0) & (fault != 0), time, state.fault_time)
        return Faults(fault, fault_time)


def _beyond_edge(grid: Any, base: Any) -> Any:
    """(n,) bool: particles whose stencil, from base cells ``base`` (dim rows, (n,) each),
    reaches past the grid's non-periodic edges (`guards`, `_off_grid`)."""
    edge = jnp.zeros(base[0].shape, bool)
    for d in range(len(grid.grid_shape)):
        if not grid.periodic[d]:
            edge = edge | (base[d] < 0) | (base[d] > grid.grid_shape[d] - 3)
    return edge


def _off_grid(model: Model, u: Any) -> Any:
    """(n,) bool: particles whose stencil at displacement ``u`` would reach past the
    grid's non-periodic edges (the runtime guard's test, `guards`)."""
    g = model.grid
    base = [
        g.cell0[d] + jnp.floor(g.frac0[d] + u[d] * (1.0 / g.dx) - 0.5).astype(jnp.int32)
        for d in range(model.dim)
    ]
    return _beyond_edge(g, base)


def residual_shear(model: Model, state: State) -> Any:
    """tau_r = rho g_n h tan(phi) per particle with the current column height [Pa]."""
    h = model.slab.thickness / slab.area_ratio(state.eps)
    return model.slab.density * model.g_normal * h * model.weak_layer.friction


def column_height(model: Model, state: State) -> Any:
    """Current slab column height h = h0 / J [m]."""
    return model.slab.thickness / slab.area_ratio(state.eps)
