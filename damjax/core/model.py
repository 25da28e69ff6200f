"""The one place where a run's static layout and its model are made from params + setup.

- PST (`damjax.pst`): `make_layout` (grid, padding, step count and slab law from concrete
  parameters), `build` (the `Model` constants and the initial `State`: the slab in
  equilibrium on the loaded weak layer), `check_layout` (a given layout fits the
  parameters), `time_step`.
- Slope (`damjax.slope`): `make_slope_layout`, `build_slope` (the same `Model` on a 2D
  release area, with slope, strength and fall-line fields at the cell centres).

Inputs are validated before they get here (`damjax.pst.prepare`,
`damjax.slope.simulation.prepare`, at the edge); the model is built once per run and then
only the core's step and loop act on it. The one check made here is at run time, on
traced values (inside `jax.jit` nothing is known before): each against its valid range
as `damjax.params` declares it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from damjax import theory
from damjax._tracing import is_traced
from damjax.constants import G_ACC
from damjax.core import transfer
from damjax.core.state import Grid, Model, Saw, State, zero_components
from damjax.materials import mcc, slab_fracture, weak_layer
from damjax.materials.slab import Slab
from damjax.materials.slab_fracture import Fracture
from damjax.materials.weak_layer import WeakLayer
from damjax.params import (
    PSTParams,
    PSTSetup,
    SlopeSetup,
    is_plastic,
    map_specs,
    specs,
)

SAW_LEAD = 0.5  # the saw stops once the crack leads it by this much [m]


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
    (at the steepest point of a slope profile; the largest of a batch)."""
    return float(np.max(_slide_accels(params)))


def _slide_accels(params: PSTParams, xp: Any = np) -> Any:
    """`_slide_accel` per member of a batch: numpy in float64 for concrete parameters,
    ``xp = jax.numpy`` for traced ones (the runtime guard, `_guarded_dt`)."""
    arr = (lambda v: np.asarray(v, dtype=float)) if xp is np else jnp.asarray  # noqa: E731
    if params.slope_profile is None:
        psi = xp.radians(arr(params.slope_deg))
    else:
        psi = xp.radians(xp.max(arr(params.slope_profile), axis=-1))
    phi = xp.radians(arr(params.friction_deg))
    return xp.maximum(G_ACC * (xp.sin(psi) - xp.cos(psi) * xp.tan(phi)), 0.0)


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
    """Grid and step counts; parameters enter only through concrete maxima (a batch's).
    The input is valid (checked at the edge: `damjax.make_layout`, `damjax.pst.prepare`),
    and the run's size is checked there too (`Layout.n_particles`, ``grid_shape``)."""
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
    if setup.dim == 1:
        return Layout(1, (nx,), (False,), pad, n_cells * ppc, n_chunks, chunk, plastic, setup)
    if setup.lateral == "constrained":
        ny = 3
        shape, periodic, n_y = (nx, ny), (False, True), ny
    else:
        n_y = max(1, int(round(setup.width / dx)))
        shape, periodic = (nx, n_y + 8), (False, False)
    n = n_cells * ppc * n_y * ppc
    return Layout(2, shape, periodic, pad, n, n_chunks, chunk, plastic, setup)


def traced_checks(
    values: dict[str, Any], table: dict[str, Any], every: str = ""
) -> list[tuple[Any, str]]:
    """(bad, message) per value that holds a JAX tracer: ``bad`` a JAX bool, true when any
    of its values is outside the valid range its declaration (``table``, `damjax.params`)
    gives (NaN included). Inside `jax.jit` no value is known when the run is traced, so
    these become runtime errors (`equinox.error_if`) instead of a silent NaN or a
    plausible number; concrete values are checked before tracing, at the edge.
    ``every``: "value" (a profile) or "cell" (a slope's map, named bare)."""
    out = []
    for name, value in values.items():
        if value is None or not is_traced(value):
            continue
        spec = table[name]
        bad = ~jnp.all(spec.valid.holds(jnp.asarray(value)))
        valid = spec.valid_text + (f" (every {every})" if every else "")
        message = (
            f"{spec.name if every == 'cell' else spec.label}: a value outside {valid}, found "
            "at run time (under jax.jit the values are not known when the run is traced)"
        )
        out.append((bad, message))
    return out


def _param_checks(params: PSTParams) -> list[tuple[Any, str]]:
    """`traced_checks` of every field of the parameters."""
    table = specs(PSTParams)
    checks = []
    for name in table:
        every = "value" if table[name].kind == "profile" else ""
        checks += traced_checks({name: getattr(params, name)}, table, every)
    return checks


def _checked(dt: Any, checks: list[tuple[Any, str]]) -> Any:
    """``dt`` with a runtime error per (bad, message) check (`eqx.error_if` on dt: always
    used, so never pruned)."""
    for bad, message in checks:
        dt = eqx.error_if(dt, bad, message)
    return dt


def _guarded_dt(params: PSTParams, setup: PSTSetup, dt: Any, elastic_guard: Any) -> Any:
    """dt, with runtime errors (`eqx.error_if`, on dt: always used, so never pruned) for
    traced parameters that the layout does not fit: a finite tensile strength on an
    elastic layout, or a slab so stiff that dt breaks the Courant limit (the run would
    blow up into NaN), and traced values outside their valid ranges
    (`traced_checks`: NaN, a negative strength gradient, ...). Concrete parameters are
    checked before tracing (at the edge, and `check_layout`)."""
    dt = _checked(dt, _param_checks(params))
    if elastic_guard is not None:
        dt = eqx.error_if(
            dt,
            elastic_guard,
            "tensile_strength is finite but the layout was made for an elastic slab "
            "(tensile_strength = inf): make the layout from these parameters",
        )
    if is_traced(params):
        # the concrete check's bound (`time_step`: cfl dx / (c_p + v_slide)), with room for
        # float32's rounding of the same parameters the layout was made from
        lateral = "constrained" if setup.dim == 2 else setup.lateral
        c = theory.longitudinal_wave_speed(params, lateral)
        dt_max = setup.cfl * setup.dx / (c + _slide_accels(params, jnp) * setup.duration)
        dt = eqx.error_if(
            dt,
            jnp.any(dt > dt_max * (1.0 + 1e-5)),
            "layout: its time step exceeds the stable cfl dx / (c_p + v_slide) of these "
            "parameters, found at run time (a stiffer or more steeply sliding slab than the "
            "layout was made for: it would break the Courant limit); make it with "
            "damjax.make_layout(params, setup) from the largest youngs_modulus and "
            "slope_deg you evaluate",
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
    # the slab fracture model: the particles' lattice (band openings, fracture count) for
    # every plastic slab; G_f and the tensile-strength field (`slab_fracture.strength_field`)
    # for "crack_band"
    lattice = (cx.size,) if layout.dim == 1 else (cx.size, cy.size)
    y_ref = None if layout.dim == 1 else (cell0[1] - y0 + frac0[1]) * dx
    extent = setup.length if layout.dim == 1 else (setup.length, cy.size * dx / ppc)
    fracture = _slab_fracture(params, setup, plastic, lattice, x_ref, y_ref, extent)

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
    g_t = jnp.zeros((layout.dim, n), dtype).at[0].set(-G_ACC * jnp.sin(psi))

    def preload(K: Any) -> tuple[Any, Any]:  # the loaded layer's slip: K u = -tau_g along x
        tau_g = f(params.density) * G_ACC * f(params.thickness) * jnp.sin(psi)
        u0 = jnp.zeros((layout.dim, n), dtype).at[0].set(-tau_g / K)
        return u0, jnp.abs(u0[0])

    return _model_and_state(
        params,
        setup,
        grid_shape=layout.grid_shape,
        periodic=layout.periodic,
        lateral=setup.lateral,
        saw_stops=not setup.controlled,
        cell0=cell0,
        frac0=frac0,
        saw_coord=x_ref_j,
        dt=_guarded_dt(params, setup, f(setup.duration / layout.n_steps), elastic_guard),
        area0=area0,
        slab_fracture=fracture,
        psi=psi,
        g_tangent=g_t,
        tau_peak=tau_p,
        preload=preload,
    )


def _model_and_state(
    params: PSTParams,
    setup: PSTSetup | SlopeSetup,
    *,
    grid_shape: tuple[int, ...],
    periodic: tuple[bool, ...],
    lateral: str,
    saw_stops: bool,
    cell0: np.ndarray,
    frac0: np.ndarray,
    saw_coord: Any,
    dt: Any,
    thickness: Any = None,
    area0: float,
    slab_fracture: _SlabFractureInputs,
    psi: Any,
    g_tangent: Any,
    tau_peak: Any,
    preload: Callable[[Any], tuple[Any, Any]],
    outflow: bool = False,
) -> tuple[Model, State]:
    """The `Model` and its initial `State` of a PST or a slope, from the fields at the
    particles (n of them) that `build` and `build_slope` make in their own ways.

    ``cell0``, ``frac0``: the particles' reference cells and offsets (dim, n);
    ``saw_coord``: the distance along the saw path [m]; ``dt``: the time step [s], with
    its runtime checks; ``thickness``: h0 [m], a scalar or (n,) per particle (None:
    ``params.thickness``); ``area0``: the reference column-base area per particle
    [m^2]; ``slab_fracture``: the slab law, sigma_t, G_f and the static fields of the
    slab fracture model (`_slab_fracture`); ``psi``: the slope angle [rad] (scalar or
    (n,)); ``g_tangent``: gravity along the slope (dim, n) [m/s^2]; ``tau_peak``: (n,)
    strength [Pa]; ``preload``: given the weak layer's stiffness K [Pa/m], the slip of
    the loaded weak layer in equilibrium with an unstressed slab, (dim, n), and its
    magnitude, (n,) [m]; ``outflow``: a
    particle that slides over the grid's edge leaves the run (`State.outflow`) instead
    of stopping it with a fault. Everything else comes from ``params`` and ``setup``: the
    weak layer's K = G_wl / D_wl, its residual slip u_res (n,) [m] and its friction
    angle.
    The derived constants (front width, w_c, the smallest mass) are derived once here,
    not every step (`Model.with_constants`).

    ``preload`` is called after the model is made: reverse mode sums the cotangents of a
    traced parameter (K, rho, psi) in the reverse order of its uses, so that order is
    part of the bits of a gradient.
    """
    dtype = jnp.dtype(setup.dtype)
    f = lambda v: jnp.asarray(v, dtype)  # noqa: E731
    n = saw_coord.shape[0]
    dim = len(grid_shape)
    # made in this order (the weak layer's K and u_res, grid, slab, fracture, gravity, weak
    # layer, saw): the order of the operations is the order of a traced parameter's uses,
    # part of a gradient's bits (`preload`)
    K = f(params.wl_shear_modulus) / f(params.wl_thickness)
    _, u_res = weak_layer.critical_displacements(tau_peak, K, f(params.softening))
    grid = Grid(
        grid_shape=grid_shape,
        dx=float(setup.dx),
        periodic=periodic,
        cell0=jnp.asarray(cell0, jnp.int32),
        frac0=jnp.asarray(frac0, dtype),
    )
    slab = Slab(
        density=f(params.density),
        thickness=f(params.thickness) if thickness is None else thickness,
        area0=f(area0),
        youngs_modulus=f(params.youngs_modulus),
        poisson=f(params.poisson),
        lateral=lateral,
    )
    fracture = Fracture(
        plastic=slab_fracture.plastic,
        p0_init=mcc.p0_from_tensile_strength(
            slab_fracture.tensile_strength,
            f(params.mcc_m),
            f(params.mcc_beta),
            setup.p0_rule,
            setup.mcc_invariants,
        ),
        mcc_m=f(params.mcc_m),
        mcc_beta=f(params.mcc_beta),
        mcc_xi=f(params.mcc_xi),
        fracture_energy=f(slab_fracture.fracture_energy),
        cell_width=float(setup.dx),
        mcc_invariants=setup.mcc_invariants,
        **slab_fracture.fields,
    )
    g_normal = jnp.broadcast_to(G_ACC * jnp.cos(psi), (n,))
    layer = WeakLayer(
        stiffness=K,
        tau_peak=tau_peak,
        softening=f(params.softening),
        u_res=u_res,
        friction=jnp.tan(jnp.deg2rad(f(params.friction_deg))),
    )
    saw = Saw(
        saw_coord=saw_coord,
        saw_speed=f(params.saw_speed),
        saw_lead=f(SAW_LEAD),
        saw_stops=saw_stops,
    )
    model = Model(
        grid=grid,
        slab=slab,
        fracture=fracture,
        weak_layer=layer,
        saw=saw,
        dt=dt,
        g_tangent=g_tangent,
        g_normal=g_normal,
        accumulation=transfer.resolve_accumulation(setup.accumulation),
    ).with_constants()
    u0, u_max = preload(K)
    state = State(
        u=u0,
        v=jnp.zeros((dim, n), dtype),
        C=jnp.zeros((dim, dim, n), dtype),
        eps=zero_components(n, dtype),
        sigma=zero_components(n, dtype),
        eps_p=zero_components(n, dtype),
        opening=jnp.zeros((n,), dtype),
        opening_y=jnp.zeros((n,), dtype),
        t_fracture=jnp.full((n,), jnp.inf, dtype),
        t_broken=jnp.full((n,), jnp.inf, dtype),
        u_max=u_max,
        time=f(0.0),
        saw_pos=f(0.0),
        saw_active=jnp.asarray(True),
        tip=f(0.0),
        fault=jnp.asarray(0, jnp.int32),
        fault_time=f(jnp.nan),
        outflow=jnp.zeros((n,), bool) if outflow else None,
    )
    return model, state


class _SlabFractureInputs(NamedTuple):
    """What `_slab_fracture` decides for `_model_and_state`: the slab law (``plastic``),
    sigma_t [Pa] (a scalar or per particle), G_f [J/m^2] and the static fields of the
    slab fracture model (`Fracture`'s lattice keywords)."""

    plastic: bool
    tensile_strength: Any
    fracture_energy: Any
    fields: dict[str, Any]


def _slab_fracture(
    params: PSTParams,
    setup: Any,
    plastic: bool,
    lattice: tuple[int, ...],
    x_ref: np.ndarray,
    y_ref: np.ndarray | None,
    extent: float | tuple[float, float],
    lattice_for_paper: bool = True,
    lattice_index: Any = None,
) -> _SlabFractureInputs:
    """The slab law ``plastic`` as given, the slab's tensile strength [Pa] (per particle
    for "crack_band"), its fracture energy G_f [J/m^2] and the static fields of the slab
    fracture model (`Fracture`) (`PSTSetup.slab_fracture`;
    `damjax.materials.slab_fracture`).

    Every plastic slab gets the particles' lattice (x-major, ``lattice`` particles per
    axis at spacing dx / ppc), so fractures are counted from band openings for every
    model. "crack_band" adds the seeded strength field (mean ``tensile_strength``, CoV
    ``slab_strength_cov``, correlation length ``slab_strength_length``, on a grid fixed in
    metres over ``extent``) and G_f (default `slab_fracture.DEFAULT_FRACTURE_ENERGY`).
    "paper" keeps sigma_t homogeneous and G_f as given (None: perfectly plastic). An
    elastic slab gets none of it (the same model as without fracture models), nor does a
    "paper" slab with ``lattice_for_paper`` False (the slope: fractures from strains).
    ``lattice_index``: each particle's flat site in the lattice where the particles do not
    fill it (a snow cover with gaps, `Fracture.lattice_index`); None: they do, in order.
    """
    dtype = jnp.dtype(setup.dtype)
    crack_band = plastic and setup.slab_fracture == "crack_band"
    g_f = params.slab_fracture_energy
    if g_f is None:
        g_f = slab_fracture.DEFAULT_FRACTURE_ENERGY if crack_band else math.inf
    tensile = jnp.asarray(params.tensile_strength, dtype)
    if not plastic or not (crack_band or lattice_for_paper):
        return _SlabFractureInputs(plastic, tensile, g_f, {})
    spacing = setup.dx / int(setup.particles_per_cell)
    kw = dict(
        lattice=tuple(int(s) for s in lattice),
        lattice_spacing=float(spacing),
        opening_window=slab_fracture.opening_window(spacing),
        crack_band=crack_band,
    )
    if lattice_index is not None:
        kw["lattice_index"] = jnp.asarray(lattice_index, jnp.int32)
    if crack_band:
        tensile = slab_fracture.strength_field(
            int(setup.seed),
            tensile,
            jnp.asarray(params.slab_strength_cov, dtype),
            jnp.asarray(params.slab_strength_length, dtype),
            jnp.asarray(x_ref, dtype),
            extent,
            None if y_ref is None else jnp.asarray(y_ref, dtype),
        )
    return _SlabFractureInputs(plastic, tensile, g_f, kw)


def check_layout(params: PSTParams, setup: PSTSetup, layout: Layout) -> None:
    """ValueError unless `layout` fits `setup` and (when concrete) `params`: made for this
    setup, stable time step, same slab law (the values themselves are valid: checked at
    the edge)."""
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
    if is_traced(params):
        return  # traced values: checked where the layout was made from concrete ones
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


# --------------------------------------------------------------------------- slope


@dataclasses.dataclass(frozen=True)
class SlopeLayout:
    """Static discretisation of a slope run (grid, padding, step counts)."""

    grid_shape: tuple[int, int]
    pad: tuple[int, int]  # cells below x = 0 and beside y = 0
    n_cells: tuple[int, int]
    n_chunks: int
    chunk_steps: int
    # the slab law, from the concrete parameters (read by build_slope when they are traced)
    plastic: bool = True

    @property
    def n_steps(self) -> int:
        return self.n_chunks * self.chunk_steps


def make_slope_layout(params: PSTParams, setup: SlopeSetup, max_slope_deg: float) -> SlopeLayout:
    """Grid and step counts of a slope run (concrete, valid parameters; the steepest angle
    [deg] of the terrain sets how far a released slab may slide). The run's size is
    checked at the edge (`damjax.slope.simulation.prepare`)."""
    dx = setup.dx
    nx, ny = int(round(setup.length / dx)), int(round(setup.width / dx))
    psi, phi = math.radians(max_slope_deg), math.radians(float(params.friction_deg))
    acc = max(G_ACC * (math.sin(psi) - math.cos(psi) * math.tan(phi)), 0.0)
    slide = 0.5 * acc * setup.duration**2
    pad_x = int(math.ceil((1.25 * slide + 1.0) / dx)) + 3
    pad_y = int(math.ceil(0.25 * slide / dx)) + 4
    c = float(theory.plane_stress_wave_speed(params)) + acc * setup.duration
    dt_max = setup.cfl * dx / c
    n_needed = max(1, int(math.ceil(setup.duration / dt_max)))
    chunk = min(int(setup.chunk_steps), n_needed)  # a longer chunk would shrink dt
    n_chunks = max(1, int(math.ceil(n_needed / chunk)))
    shape = (pad_x + nx + pad_y, 2 * pad_y + ny)
    plastic = is_plastic(params) is not False
    return SlopeLayout(shape, (pad_x, pad_y), (nx, ny), n_chunks, chunk, plastic)


def _bilinear(field: Any, xp: np.ndarray, yp: np.ndarray, dx: float) -> Any:
    """Field given at cell centres (nx, ny), interpolated at (xp, yp) [m] (differentiable
    in the field values: indices and weights are fixed numpy arrays)."""
    f = jnp.asarray(field)
    if f.ndim == 0:
        return jnp.broadcast_to(f, xp.shape)
    nx, ny = f.shape
    gx = np.clip(xp / dx - 0.5, 0, nx - 1)
    gy = np.clip(yp / dx - 0.5, 0, ny - 1)
    i0 = np.minimum(np.floor(gx).astype(int), nx - 2 if nx > 1 else 0)
    j0 = np.minimum(np.floor(gy).astype(int), ny - 2 if ny > 1 else 0)
    tx, ty = gx - i0, gy - j0
    i1, j1 = np.minimum(i0 + 1, nx - 1), np.minimum(j0 + 1, ny - 1)
    return (
        (1 - tx) * (1 - ty) * f[i0, j0]
        + tx * (1 - ty) * f[i1, j0]
        + (1 - tx) * ty * f[i0, j1]
        + tx * ty * f[i1, j1]
    )


def slope_particles(
    setup: SlopeSetup, pad: tuple[int, int] = (0, 0), cover: Any = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The particles of a slope run: (cell0 (2, n) grid cells, frac0 (2, n) offsets in
    them, xp, yp (n,) reference positions [m]), x-major, ``particles_per_cell`` per cell
    and axis; where ``cover`` ((nx, ny) bool, the snow-covered cells) is given, only in
    its cells (a cell without snow holds no particle and costs no particle work)."""
    dx, ppc = setup.dx, setup.particles_per_cell
    nx, ny = int(round(setup.length / dx)), int(round(setup.width / dx))
    sub = (np.arange(ppc) + 0.5) / ppc
    cx, fx = np.repeat(np.arange(nx), ppc), np.tile(sub, nx)
    cy, fy = np.repeat(np.arange(ny), ppc), np.tile(sub, ny)
    cell = np.stack([np.repeat(cx, cy.size), np.tile(cy, cx.size)])
    frac0 = np.stack([np.repeat(fx, fy.size), np.tile(fy, fx.size)])
    if cover is not None:
        keep = np.asarray(cover, bool)[cell[0], cell[1]]
        cell, frac0 = cell[:, keep], frac0[:, keep]
    xp = (cell[0] + frac0[0]) * dx
    yp = (cell[1] + frac0[1]) * dx
    cell0 = cell + np.asarray(pad, dtype=cell.dtype)[:, None]
    return cell0, frac0, xp, yp


def slope_particle_fields(
    params: PSTParams,
    setup: SlopeSetup,
    slope_deg: Any,
    tau_peak: Any,
    fall_deg: Any = 0.0,
    *,
    pad: tuple[int, int] = (0, 0),
    thickness: Any = None,
    cover: Any = None,
    stability: Any = None,
    wl_friction: Any = None,
) -> dict[str, Any]:
    """The particles of a slope run (`slope_particles` on ``cover`` and ``pad``:
    ``cell0``, ``frac0``, ``xp``, ``yp``) and the terrain, snow and weak-layer fields at
    their reference positions xp, yp [m] (maps at cell centres interpolated bilinearly;
    a map of one value is the scalar, `uniform_value`): ``psi`` and ``fall`` [rad],
    ``thickness`` h0 [m] (a scalar: ``params.thickness`` when ``thickness`` is None),
    ``tau_g`` = rho g h0 sin(psi), the gravitational shear the layer carries [Pa], and
    ``tau_peak`` [Pa]: the map ``tau_peak``; or S tau_g with ``stability`` S (a map of
    tau_p / tau_g: the layer's strength follows its own load); plus, with ``wl_friction``
    (a coefficient mu, scalar or map), mu rho g h0 cos(psi) (cohesion plus friction on the
    slab's normal stress; ``tau_peak`` is then the cohesion).
    """
    dtype = jnp.dtype(setup.dtype)
    f = lambda v: jnp.asarray(v, dtype)  # noqa: E731
    dx = setup.dx
    thickness = uniform_value(thickness)  # a uniform map is the scalar model
    cell0, frac0, xp, yp = slope_particles(setup, pad, cover)
    psi = jnp.deg2rad(_bilinear(jnp.asarray(slope_deg, dtype), xp, yp, dx).astype(dtype))
    fall = jnp.deg2rad(_bilinear(jnp.asarray(fall_deg, dtype), xp, yp, dx).astype(dtype))
    if thickness is None:
        h = f(params.thickness)
    elif jnp.ndim(thickness) == 0:  # a uniform slab: the scalar model
        h = f(thickness)
    else:
        h = _bilinear(jnp.asarray(thickness, dtype), xp, yp, dx).astype(dtype)
    rho_g_h = f(params.density) * G_ACC * h
    tau_g = rho_g_h * jnp.sin(psi)
    if stability is not None:
        tau_p = _bilinear(jnp.asarray(stability, dtype), xp, yp, dx).astype(dtype) * tau_g
    else:
        tau_p = _bilinear(jnp.asarray(tau_peak, dtype), xp, yp, dx).astype(dtype)
    if wl_friction is not None:
        mu = _bilinear(jnp.asarray(wl_friction, dtype), xp, yp, dx).astype(dtype)
        tau_p = tau_p + mu * rho_g_h * jnp.cos(psi)
    fields = {"psi": psi, "fall": fall, "thickness": h, "tau_g": tau_g, "tau_peak": tau_p}
    return dict(cell0=cell0, frac0=frac0, xp=xp, yp=yp, **fields)


def uniform_value(field: Any) -> Any:
    """A concrete map whose cells all hold one value as that value (a float: the scalar
    model, bitwise that of a scalar input); anything else as it is."""
    if field is None or is_traced(field) or np.ndim(field) == 0:
        return field
    a = np.asarray(field)
    flat = a.ravel()
    if flat.size and np.all(flat == flat[0]):
        return float(flat[0])
    return field


def _sites(xp: np.ndarray, yp: np.ndarray, spacing: float, lattice: tuple[int, int]) -> Any:
    """Each particle's flat site (x-major) in the lattice of ``spacing`` [m], from its
    reference position (x, y) [m] at the centre of its site."""
    i = np.rint(np.asarray(xp) / spacing - 0.5).astype(np.int64)
    j = np.rint(np.asarray(yp) / spacing - 0.5).astype(np.int64)
    return i * lattice[1] + j


def build_slope(
    params: PSTParams,
    setup: SlopeSetup,
    layout: SlopeLayout,
    slope_deg: Any,
    tau_peak: Any,
    fall_deg: Any = 0.0,
    *,
    thickness: Any = None,
    cover: Any = None,
    stability: Any = None,
    wl_friction: Any = None,
    outflow: bool = True,
) -> tuple[Model, State, np.ndarray, np.ndarray]:
    """Model, initial state and the particles' reference positions (x, y) [m].

    Snow and weak layer (`slope_particle_fields`): ``thickness`` (a map of h0 [m] at the
    cell centres, normal to the slope; None: the scalar ``params.thickness``, the model
    of a uniform slab), ``cover`` ((nx, ny) bool: particles only in these cells; None:
    every cell), ``stability`` (S = tau_p / tau_g: tau_p follows each particle's own load;
    None: ``tau_peak`` [Pa]) and ``wl_friction`` (a friction coefficient added to the
    strength: tau_p + mu rho g h0 cos psi). ``outflow``: a particle that slides over the
    grid's edge leaves the run (`State.outflow`) instead of stopping it with a fault.
    The inputs are valid (checked at the edge, `damjax.slope.simulation.prepare`: a cover
    with snow on some cell). A "crack_band" slab sums its band openings over the
    particles' lattice; on a cover with gaps, the sites without snow add no opening.
    """
    dtype = jnp.dtype(setup.dtype)
    f = lambda v: jnp.asarray(v, dtype)  # noqa: E731
    dx, ppc = setup.dx, setup.particles_per_cell
    nx, ny = layout.n_cells
    thickness = uniform_value(thickness)  # a uniform map is the scalar model
    pf = slope_particle_fields(
        params,
        setup,
        slope_deg,
        tau_peak,
        fall_deg,
        pad=layout.pad,
        thickness=thickness,
        cover=cover,
        stability=stability,
        wl_friction=wl_friction,
    )
    cell0, frac0, xp, yp = pf["cell0"], pf["frac0"], pf["xp"], pf["yp"]
    # "crack_band": lattice (nx ppc, ny ppc particles, x-major), G_f and strength field
    # over the release area; "paper": homogeneous, no lattice (as in earlier versions)
    plastic = is_plastic(params)  # None when traced: the layout's (concrete) slab law
    plastic = layout.plastic if plastic is None else plastic
    lattice = (nx * ppc, ny * ppc)
    fracture = _slab_fracture(
        params,
        setup,
        plastic,
        lattice,
        xp,
        yp,
        (setup.length, setup.width),
        lattice_for_paper=False,
        lattice_index=None
        if xp.size == lattice[0] * lattice[1]
        else _sites(xp, yp, dx / ppc, lattice),
    )
    psi, fall, tau_p, h0 = pf["psi"], pf["fall"], pf["tau_peak"], pf["thickness"]
    # traced values outside their ranges stop the run
    maps = dict(tau_peak=tau_peak, slope_deg=slope_deg, fall_deg=fall_deg)
    maps.update(thickness=thickness, stability=stability, wl_friction=wl_friction)
    checks = _param_checks(params) + traced_checks(maps, map_specs(), "cell")
    dt = _checked(f(setup.duration / layout.n_steps), checks)
    gs = G_ACC * jnp.sin(psi)
    g_t = jnp.stack([-gs * jnp.cos(fall), -gs * jnp.sin(fall)])  # down the local fall line
    x0, y0 = setup.start

    def preload(K: Any) -> tuple[Any, Any]:  # the loaded layer's slip: K u = -rho h g_t
        u0 = (f(params.density) * h0 / K) * g_t
        return u0, mcc._sqrt(jnp.sum(u0 * u0, axis=0))  # finite gradient on a flat cell

    model, state = _model_and_state(
        params,
        setup,
        grid_shape=layout.grid_shape,
        periodic=(False, False),
        lateral="free",
        saw_stops=True,
        cell0=cell0,
        frac0=frac0,
        saw_coord=jnp.asarray(np.hypot(xp - x0, yp - y0), dtype),
        dt=dt,
        thickness=h0,
        area0=(dx / ppc) ** 2,
        slab_fracture=fracture,
        psi=psi,
        g_tangent=g_t,
        tau_peak=tau_p,
        preload=preload,
        outflow=outflow,
    )
    return model, state, xp, yp
