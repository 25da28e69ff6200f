"""The propagation saw test (PST) on the DA-MPM core.

Geometry: x runs up-slope along the PST, the slab occupies [0, L]; the saw cuts the weak
layer from x = 0 upwards. Self-propagating runs saw at `saw_speed` until the crack leads
the saw by 0.5 m (the saw position then is the critical cut length); controlled runs
(`PSTSetup.controlled`) make the layer unbreakable and cut it at `saw_speed` for the
whole run. Both slab ends are free. The grid is padded down-slope by the distance a fully
released slab can slide in the run, so no particle ever leaves it.

The 1D path (``dim=1``) is the width-uniform strip with the lateral condition of the
setup; ``dim=2`` runs the same step on a 2D strip (periodic across the width for
"constrained", free edges of width `width` for "free").
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from damjax import config, theory
from damjax.config import G_ACC, PSTParams, PSTSetup, check_problem_size, is_plastic, validate
from damjax.core.loop import integrate, integrate_pure
from damjax.core.state import FAULT_MESSAGES, Model, State, zero_components
from damjax.core.step import column_height, fracture_strain
from damjax.materials import mcc, weak_layer

SAW_LEAD = 0.5  # the saw stops once the crack leads it by this much [m]
FRACTURE_GAP = 1.0  # tensile bands closer than this are one fracture [m]


@dataclasses.dataclass(frozen=True)
class Layout:
    """Static discretisation derived from the setup (and a padding estimate)."""

    dim: int
    grid_shape: tuple[int, ...]
    periodic: tuple[bool, ...]
    pad_cells: int  # grid cells below x = 0
    n_particles: int
    n_chunks: int
    chunk_steps: int
    # the slab law, from the concrete parameters: the MCC return map runs only where some
    # tensile strength is finite (an elastic slab skips it: 1.4x cheaper per step)
    plastic: bool = True
    # the setup it was made for (a layout fixes dt = duration / n_steps and the grid)
    setup: PSTSetup | None = None

    @property
    def n_steps(self) -> int:
        return self.n_chunks * self.chunk_steps


def _concrete_max(x: Any) -> float:
    return float(np.max(np.asarray(x, dtype=float)))


def time_step(params: PSTParams, setup: PSTSetup) -> float:
    """Largest stable dt [s] = cfl dx / (c_p + v_slide) for the (batched) parameters."""
    lateral = "constrained" if setup.dim == 2 else setup.lateral
    c = _concrete_max(theory.longitudinal_wave_speed(params, lateral))
    return setup.cfl * setup.dx / (c + _slide_accel(params) * setup.duration)


def _slide_accel(params: PSTParams) -> float:
    """Acceleration of a fully released slab, g (sin psi - cos psi tan phi) >= 0 [m/s^2]
    (at the steepest point of a slope profile)."""
    if params.slope_profile is None:
        psi = np.radians(np.asarray(params.slope_deg, dtype=float))
    else:
        psi = np.radians(np.max(np.asarray(params.slope_profile, dtype=float), axis=-1))
    phi = np.radians(np.asarray(params.friction_deg, dtype=float))
    return float(np.max(np.maximum(G_ACC * (np.sin(psi) - np.cos(psi) * np.tan(phi)), 0.0)))


def _max_cohesive_slip(params: PSTParams) -> float:
    """Largest slip the intact or softening layer allows, u_r = tau_p (1 + delta) / K [m]
    (finite strengths; a soft layer with a strong peak slides that far before it breaks)."""
    tau = params.strength_profile if params.strength_profile is not None else params.tau_peak
    tau = np.asarray(tau, dtype=float)
    tau = np.max(np.where(np.isfinite(tau), tau, 0.0))
    k = np.asarray(params.wl_shear_modulus, dtype=float) / np.asarray(
        params.wl_thickness, dtype=float
    )
    return float(np.max(tau * (1.0 + np.asarray(params.softening, dtype=float)) / k))


def make_layout(params: PSTParams, setup: PSTSetup) -> Layout:
    """Grid and step counts; parameters enter only through concrete maxima (a batch's)."""
    dx, ppc = setup.dx, int(setup.particles_per_cell)
    n_cells = max(1, int(round(setup.length / dx)))
    slide = 0.5 * _slide_accel(params) * setup.duration**2 + _max_cohesive_slip(params)
    pad = int(math.ceil((1.25 * slide + 1.0) / dx)) + 3
    pad_top = int(math.ceil(1.0 / dx)) + 3
    nx = pad + n_cells + pad_top
    dt_max = time_step(params, setup)
    n_needed = max(1, int(math.ceil(setup.duration / dt_max)))
    # a chunk longer than the run would shrink dt below the cfl's (and cost as much more)
    chunk = min(int(setup.chunk_steps), n_needed)
    n_chunks = max(1, int(math.ceil(n_needed / chunk)))
    plastic = is_plastic(params) is not False
    itemsize = np.dtype(setup.dtype).itemsize
    if setup.dim == 1:
        check_problem_size(n_cells * ppc, nx, n_chunks, itemsize, _SIZE_FIELDS)
        return Layout(1, (nx,), (False,), pad, n_cells * ppc, n_chunks, chunk, plastic, setup)
    if setup.lateral == "constrained":
        ny = 3
        shape, periodic, n_y = (nx, ny), (False, True), ny
    else:
        n_y = max(1, int(round(setup.width / dx)))
        shape, periodic = (nx, n_y + 8), (False, False)
    n = n_cells * ppc * n_y * ppc
    check_problem_size(n, shape[0] * shape[1], n_chunks, itemsize, _SIZE_FIELDS + ", width")
    return Layout(2, shape, periodic, pad, n, n_chunks, chunk, plastic, setup)


_SIZE_FIELDS = "length (--length), dx (--dx), duration (--duration), particles_per_cell"


def _traced(params: PSTParams) -> bool:
    """Whether any parameter is a JAX tracer (inside jax.grad/jit/vmap)."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(params))


def _guarded_dt(params: PSTParams, setup: PSTSetup, dt: Any, elastic_guard: Any) -> Any:
    """dt, with runtime errors (`eqx.error_if`, on dt: always used, so never pruned) for
    traced parameters that the layout does not fit: a finite tensile strength on an
    elastic layout, or a slab so stiff that dt breaks the Courant limit (the run would
    blow up into NaN). Concrete parameters are checked before tracing (`check_layout`)."""
    if elastic_guard is not None:
        dt = eqx.error_if(
            dt,
            elastic_guard,
            "tensile_strength is finite but the layout was made for an elastic slab "
            "(tensile_strength = inf): make the layout from these parameters",
        )
    if _traced(params):
        lateral = "constrained" if setup.dim == 2 else setup.lateral
        c = theory.longitudinal_wave_speed(params, lateral)
        dt = eqx.error_if(
            dt,
            jnp.any(dt * c > setup.dx),
            "youngs_modulus / density: the slab's wave speed breaks the Courant limit of "
            "the layout's time step (a stiffer slab than the layout was made from); make "
            "the layout from the stiffest parameters you evaluate",
        )
    return dt


def build(params: PSTParams, setup: PSTSetup, layout: Layout) -> tuple[Model, State]:
    """Model constants and the initial state (slab in equilibrium on the loaded layer).

    The slab law is elastic when every tensile strength is infinite: decided from
    ``params`` when they are concrete, else from ``layout.plastic`` (`make_layout` on
    the concrete values). Traced parameters with a finite sigma_t on an elastic layout
    stop with an error (make the layout from the parameters you evaluate).
    """
    dtype = jnp.dtype(setup.dtype)
    f = lambda x: jnp.asarray(x, dtype)  # noqa: E731
    dx, ppc = setup.dx, int(setup.particles_per_cell)
    plastic = is_plastic(params)
    elastic_guard = None
    if plastic is None:
        plastic = layout.plastic
        if not plastic:
            elastic_guard = jnp.any(jnp.isfinite(params.tensile_strength))
    n_cells = max(1, int(round(setup.length / dx)))
    sub = (np.arange(ppc) + 0.5) / ppc
    # reference positions along x (cell index + offset), slab cells start at pad_cells
    cx = np.repeat(np.arange(n_cells), ppc)
    fx = np.tile(sub, n_cells)
    if layout.dim == 1:
        cell0 = (cx + layout.pad_cells)[None]
        frac0 = fx[None]
        area0 = dx / ppc
    else:
        n_y = 3 if setup.lateral == "constrained" else layout.grid_shape[1] - 8
        y0 = 0 if setup.lateral == "constrained" else 4
        cy = np.repeat(np.arange(n_y), ppc)
        fy = np.tile(sub, n_y)
        cell0 = np.stack([np.repeat(cx, cy.size) + layout.pad_cells, np.tile(cy, cx.size) + y0])
        frac0 = np.stack([np.repeat(fx, fy.size), np.tile(fy, fx.size)])
        area0 = (dx / ppc) ** 2
    x_ref = (cell0[0] - layout.pad_cells + frac0[0]) * dx  # [m] along the PST
    n = x_ref.size

    phi = jnp.deg2rad(f(params.friction_deg))
    K = f(params.wl_shear_modulus) / f(params.wl_thickness)
    x_ref_j = jnp.asarray(x_ref, dtype)
    if params.slope_profile is not None:  # psi(x) at the particles' reference positions
        sprof = jnp.asarray(params.slope_profile, dtype)
        xs_psi = jnp.linspace(0.0, setup.length, sprof.shape[-1], dtype=dtype)
        psi = jnp.deg2rad(jnp.interp(x_ref_j, xs_psi, sprof))
    else:
        psi = jnp.deg2rad(f(params.slope_deg))
    if setup.controlled:
        tau_p = jnp.full((n,), jnp.inf, dtype)
    elif params.strength_profile is not None:
        prof = jnp.asarray(params.strength_profile, dtype)
        xs = jnp.linspace(0.0, setup.length, prof.shape[-1], dtype=dtype)
        tau_p = jnp.interp(x_ref_j, xs, prof)
    else:
        tau_p = weak_layer.strength_profile(
            x_ref_j, f(params.tau_peak), f(params.steady_length), f(params.strength_gradient)
        )
    _, u_res = weak_layer.critical_displacements(tau_p, K, f(params.softening))
    g_t = jnp.zeros((layout.dim, n), dtype).at[0].set(-G_ACC * jnp.sin(psi))
    n_steps = layout.n_steps
    model = Model(
        grid_shape=layout.grid_shape,
        dx=float(dx),
        periodic=layout.periodic,
        lateral=setup.lateral,
        saw_stops=not setup.controlled,
        cell0=jnp.asarray(cell0, jnp.int32),
        frac0=jnp.asarray(frac0, dtype),
        saw_coord=x_ref_j,
        dt=_guarded_dt(params, setup, f(setup.duration / n_steps), elastic_guard),
        density=f(params.density),
        thickness=f(params.thickness),
        area0=f(area0),
        youngs_modulus=f(params.youngs_modulus),
        poisson=f(params.poisson),
        plastic=plastic,
        p0_init=mcc.p0_from_tensile_strength(
            f(params.tensile_strength),
            f(params.mcc_m),
            f(params.mcc_beta),
            setup.p0_rule,
            setup.mcc_invariants,
        ),
        mcc_m=f(params.mcc_m),
        mcc_beta=f(params.mcc_beta),
        mcc_xi=f(params.mcc_xi),
        fracture_energy=f(params.slab_fracture_energy),
        g_tangent=g_t,
        g_normal=jnp.full((n,), 1.0, dtype) * (G_ACC * jnp.cos(psi)),
        stiffness=K,
        tau_peak=tau_p,
        softening=f(params.softening),
        u_res=u_res,
        friction=jnp.tan(phi),
        saw_speed=f(params.saw_speed),
        saw_lead=f(SAW_LEAD),
        mcc_invariants=setup.mcc_invariants,
    )
    tau_g = f(params.density) * G_ACC * f(params.thickness) * jnp.sin(psi)
    u0 = jnp.zeros((layout.dim, n), dtype).at[0].set(-tau_g / K)  # pre-loaded layer
    state = State(
        u=u0,
        v=jnp.zeros((layout.dim, n), dtype),
        C=jnp.zeros((layout.dim, layout.dim, n), dtype),
        eps=zero_components(n, dtype),
        sigma=zero_components(n, dtype),
        eps_p=zero_components(n, dtype),
        opening=jnp.zeros((n,), dtype),
        t_fracture=jnp.full((n,), jnp.inf, dtype),
        t_broken=jnp.full((n,), jnp.inf, dtype),
        u_max=jnp.abs(u0[0]),
        time=f(0.0),
        saw_pos=f(0.0),
        saw_active=jnp.asarray(True),
        tip=f(0.0),
        fault=jnp.asarray(0, jnp.int32),
        fault_time=f(jnp.nan),
    )
    return model, state


def weak_layer_shear(model: Model, state: State) -> Any:
    """Weak-layer shear stress magnitude [Pa]: cohesive traction where intact or
    softening, the friction cap tau_r where broken (an upper bound when at rest)."""
    from damjax.core.step import broken_mask, residual_shear

    broken = broken_mask(model, state)
    tau_r = residual_shear(model, state)
    k = weak_layer.cohesive_factor(
        state.u_max, model.tau_peak, tau_r, model.stiffness, model.softening, broken
    )
    slip = jnp.sqrt(jnp.sum(state.u * state.u, axis=0))
    return jnp.where(broken, tau_r, k * slip)


def _snapshot(model: Model, state: State) -> dict[str, Any]:
    return {
        "time": state.time,
        "sigma_xx": state.sigma[0],
        "height": column_height(model, state),
        "slip": state.u[0],
        "tip": state.tip,
    }


@dataclasses.dataclass
class PSTResult:
    """Outcome of a PST run (numpy arrays, SI units).

    Event-based diagnostics (crack tip, arrest) are computed on the host from the tip
    history; they are discrete and not differentiable (see `damjax.diagnostics`).
    """

    params: PSTParams
    setup: PSTSetup
    x: np.ndarray  # (n,) particle reference position along the PST [m]
    time: np.ndarray  # (n_steps,) time after each step [s]
    tip: np.ndarray  # (n_steps,) crack tip position [m]
    sigma_xx: np.ndarray  # (n,) final slab tension [Pa]
    height: np.ndarray  # (n,) final column height [m]
    slip: np.ndarray  # (n,) final slope-parallel displacement [m]
    u_max: np.ndarray  # (n,) maximum slip reached [m]
    tau_peak: np.ndarray  # (n,) weak-layer strength [Pa]
    opening: np.ndarray  # (n,) accumulated tensile plastic strain [-]
    wl_shear: np.ndarray  # (n,) final weak-layer shear stress magnitude [Pa]
    snapshots: dict[str, np.ndarray]  # fields at the end of every chunk
    summary: dict[str, Any]
    fault: str | None = None
    fractures: list[dict[str, float]] = dataclasses.field(default_factory=list)

    @property
    def arrested(self) -> bool:
        return bool(self.summary["arrested"])

    @property
    def arrest_position(self) -> float:
        """Event-based L_ca [m]; NaN when the crack did not arrest (not differentiable)."""
        v = self.summary["arrest_position_m"]
        return math.nan if v is None else float(v)

    @property
    def arrest_position_smooth(self) -> float:
        """Smooth surrogate of L_ca [m] (`damjax.diagnostics.smooth_arrest_position`);
        `damjax.arrest_position_smooth` is its differentiable JAX counterpart."""
        return float(self.summary["arrest_position_smooth_m"])


def simulate_pst(
    params: PSTParams | None = None,
    setup: PSTSetup | None = None,
    progress: bool = False,
    *,
    state: State | None = None,
    start_chunk: int = 0,
    history: tuple[list[np.ndarray], list[Any]] | None = None,
    callback: Any = None,
) -> PSTResult:
    """Run a PST and return its diagnostics (see `PSTResult`, `damjax.diagnostics`).

    Args:
        params: physical parameters (default: the paper's elastic baseline).
        setup: numerics (default: 100 m, dx = 0.02 m, 3 s, free lateral condition).
        progress: show a tqdm progress bar.
        state, start_chunk, history: resume from a saved state after ``start_chunk``
            chunks, with the per-chunk tip arrays and snapshots recorded before it.
        callback: ``callback(chunk, state, tips, snaps)`` after every chunk
            (checkpointing; see `damjax.core.loop.integrate`).
    """
    params = PSTParams() if params is None else params
    setup = PSTSetup() if setup is None else setup
    validate(params, setup)
    config.ensure_x64(setup.dtype)
    layout = make_layout(params, setup)
    model, state0 = build(params, setup, layout)
    final, tips, snaps, info = integrate(
        model,
        state0 if state is None else state,
        layout.n_chunks,
        layout.chunk_steps,
        snapshot=_snapshot,
        progress=progress,
        callback=callback,
        start_chunk=start_chunk,
        history=history,
    )
    return finish(params, setup, layout, model, final, tips, snaps, info)


def finish(
    params: PSTParams,
    setup: PSTSetup,
    layout: Layout,
    model: Model,
    final: State,
    tips: np.ndarray,
    snaps: list[Any],
    info: Any,
) -> PSTResult:
    """Assemble a `PSTResult` from a finished (or faulted) run."""
    from damjax import diagnostics

    x_ref = np.asarray(model.saw_coord)
    tau_p = np.asarray(model.tau_peak)
    dt = float(model.dt)
    times = dt * np.arange(1, tips.size + 1)
    fault = None
    if int(final.fault) != 0:
        msgs = [m for bit, m in FAULT_MESSAGES.items() if int(final.fault) & bit]
        fault = f"run stopped at t = {float(final.fault_time):.4f} s: " + "; ".join(msgs)
        # keep the history up to the fault
        keep = times < float(final.fault_time)
        times, tips = times[keep], tips[keep]
    snapshots = {k: np.stack([s[k] for s in snaps]) for k in snaps[0]} if snaps else {}
    sigma_xx = np.asarray(final.sigma[0])
    height = np.asarray(column_height(model, final))
    opening = np.asarray(final.opening)
    wl_shear = np.asarray(weak_layer_shear(model, final))
    fractures = diagnostics.slab_fractures(
        x_ref, opening, np.asarray(final.t_fracture), float(fracture_strain(model)), FRACTURE_GAP
    )
    if layout.dim == 2:  # report the strip's average per x
        x_all = x_ref
        x_ref, sigma_xx, height, opening, wl_shear = _width_average(
            x_all, sigma_xx, height, opening, wl_shear
        )
        tau_p = _width_average(x_all, tau_p)[1]
    result = PSTResult(
        params=params,
        setup=setup,
        x=x_ref,
        time=times,
        tip=tips,
        sigma_xx=sigma_xx,
        height=height,
        slip=np.asarray(final.u[0]),
        u_max=np.asarray(final.u_max),
        tau_peak=tau_p,
        opening=opening,
        wl_shear=wl_shear,
        snapshots=snapshots,
        summary={},
        fault=fault,
        fractures=fractures,
    )
    smooth = float(diagnostics.smooth_arrest_position(model, final))
    result.summary = diagnostics.summarize(
        result,
        saw_position=float(final.saw_pos),
        saw_stopped=not bool(final.saw_active),
        n_particles=layout.n_particles,
        n_steps=int(times.size),
        compile_time_s=info.compile_time_s,
        wall_time_s=info.wall_time_s,
        timed_steps=info.steps_done,
    )
    result.summary["arrest_position_smooth_m"] = smooth
    return result


def _width_average(x: np.ndarray, *fields: np.ndarray) -> tuple[np.ndarray, ...]:
    xs, inv = np.unique(np.round(x, 9), return_inverse=True)
    out = [xs]
    for fld in fields:
        out.append(np.bincount(inv, weights=fld) / np.bincount(inv))
    return tuple(out)


def run_pure(params: PSTParams, setup: PSTSetup, layout: Layout) -> tuple[Model, State, Any]:
    """Traceable full run (for grad / vmap): model, final state and tip per step.

    Reverse mode is checkpointed per segment and per step (`damjax.core.loop.integrate_pure`).
    """
    model, state = build(params, setup, layout)
    final, tips = integrate_pure(model, state, layout.n_chunks, layout.chunk_steps)
    return model, final, tips


def arrest_position_smooth(
    params: PSTParams, setup: PSTSetup, layout: Layout | None = None, *, width: float | None = None
) -> Any:
    """Differentiable smooth arrest position [m] of a PST (a JAX scalar).

    Its gradient with respect to every field of `PSTParams`::

        layout = damjax.make_layout(params, setup)   # grid and step count, concrete values
        grads = jax.grad(lambda p: damjax.arrest_position_smooth(p, setup, layout))(params)

    The layout (grid, step count, elastic or plastic slab) must come from concrete
    parameters, so pass it whenever the parameters are traced (`jax.grad`, `jax.jit`,
    `jax.vmap`); without it traced parameters are an error that says so.
    ``width``: relative width of the damage ramp (default
    `damjax.diagnostics.SMOOTH_WIDTH`; see `damjax.diagnostics.smooth_arrest_position`).
    """
    config.require_x64(setup.dtype)
    if layout is None:
        if _traced(params):
            raise TypeError(
                "arrest_position_smooth: the parameters are traced (jax.grad/jit/vmap) and no "
                "layout was given; make it from concrete parameters first: layout = "
                "damjax.make_layout(params, setup), then "
                "jax.grad(lambda p: damjax.arrest_position_smooth(p, setup, layout))(params)"
            )
        validate(params, setup)
        layout = make_layout(params, setup)
    else:
        check_layout(params, setup, layout)
    model, final, _ = run_pure(params, setup, layout)
    return diagnostics_smooth(model, final, width)


def check_layout(params: PSTParams, setup: PSTSetup, layout: Layout) -> None:
    """ValueError unless `layout` fits `setup` and (when concrete) `params`: made for this
    setup, stable time step, same slab law. Concrete parameters are validated too."""
    if layout.setup is not None and layout.setup != setup:
        diff = [
            f"{f.name} {getattr(layout.setup, f.name)!r} vs {getattr(setup, f.name)!r}"
            for f in dataclasses.fields(setup)
            if getattr(layout.setup, f.name) != getattr(setup, f.name)
        ]
        raise ValueError(
            "layout: made for another setup (" + ", ".join(diff) + "); make it with "
            "damjax.make_layout(params, setup) for the setup you run"
        )
    if _traced(params):
        return  # traced values: checked where the layout was made from concrete ones
    validate(params, setup)
    dt = setup.duration / layout.n_steps
    dt_max = time_step(params, setup)
    if dt > dt_max * (1 + 1e-9):
        raise ValueError(
            f"layout: its time step {dt:.4g} s exceeds the stable {dt_max:.4g} s of these "
            "parameters (a stiffer slab than the layout was made for?); make it with "
            "damjax.make_layout(params, setup) from the largest youngs_modulus you evaluate"
        )
    if is_plastic(params) and not layout.plastic:
        raise ValueError(
            "layout: made for an elastic slab (tensile_strength = inf) but these parameters "
            "have a finite tensile_strength; make it with damjax.make_layout(params, setup)"
        )


def diagnostics_smooth(model: Model, final: State, width: float | None = None) -> Any:
    from damjax.diagnostics import SMOOTH_WIDTH, smooth_arrest_position

    return smooth_arrest_position(model, final, SMOOTH_WIDTH if width is None else width)
