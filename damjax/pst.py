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
import os
from collections.abc import Callable, Iterable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from damjax import diagnostics, io, theory
from damjax._tracing import concrete_tree, concrete_value, eager_if_concrete, is_traced
from damjax.core import model as core_model
from damjax.core.loop import integrate, integrate_pure
from damjax.core.model import (  # noqa: F401  (Layout, SAW_LEAD, time_step: public here too)
    SAW_LEAD,
    Layout,
    build,
    check_layout,
    time_step,
)
from damjax.core.state import FAULT_MESSAGES, Model, State, raise_on_fault
from damjax.core.step import broken_mask, column_height, residual_shear
from damjax.materials import mcc, weak_layer
from damjax.materials.slab_fracture import band_opening, fracture_strain
from damjax.params import PSTParams, PSTSetup
from damjax.validation import (
    InputError,
    Problem,
    check_width,
    concrete_only,
    dubious,
    ensure_x64,
    expect_types,
    implausible,
    param_problems,
    raise_if,
    require_x64,
    resolution_note,
    setup_problems,
    shape_problems,
    single_run_problems,
    size_problem,
    warn_notes,
)


def weak_layer_shear(model: Model, state: State) -> Any:
    """Weak-layer shear stress magnitude [Pa]: cohesive traction where intact or
    softening, the friction cap tau_r where broken (an upper bound when at rest)."""
    broken = broken_mask(model, state)
    tau_r = residual_shear(model, state)
    wl = model.weak_layer
    k = weak_layer.cohesive_factor(
        state.u_max, wl.tau_peak, tau_r, wl.stiffness, wl.softening, broken
    )
    slip = mcc._sqrt(jnp.sum(state.u * state.u, axis=0))  # finite gradient at zero slip
    return jnp.where(broken, tau_r, k * slip)


def _snapshot(model: Model, state: State) -> dict[str, Any]:
    return {
        "time": state.time,
        "sigma_xx": state.sigma[0],
        "height": column_height(model, state),
        "slip": state.u[0],
        "tip": state.tip,
    }


def one_run_only(what: str) -> str:
    """The message for a result that is not one run of concrete parameters."""
    return (
        f"{what} takes the result of one run of concrete parameters; this one holds JAX "
        "arrays from inside jax.grad, jax.jit or jax.vmap (a batch has a leading member "
        "axis): run the member you want on its own, damjax.simulate_pst(params, setup)"
    )


@dataclasses.dataclass
class PSTResult:
    """Outcome of a PST run (SI units); a pytree, so `jax.vmap` of `simulate_pst` returns
    one batched result.

    From concrete parameters the fields are numpy arrays and ``summary`` holds every
    diagnostic; in a 2D strip (``dim=2``) every (n,) field and snapshot is the average
    across the width at each ``x``. Event-based diagnostics (crack tip, arrest,
    fractures) are computed on the host from the tip history; they are discrete and not
    differentiable (see `damjax.diagnostics`). From traced parameters (inside
    `jax.grad`, `jax.vmap`, `jax.jit`) the fields are JAX arrays per particle (a 2D strip
    is not width-averaged), ``snapshots`` and ``fractures`` are empty, and ``summary``
    holds only JAX scalars:
    ``arrest_position_smooth_m`` (differentiable), ``saw_position_m``, ``tip_m`` (the
    crack tip at the end) and ``fault_code`` (0: no runtime fault; bits of
    `damjax.core.state.FAULT_MESSAGES`).

    Attributes:
        params: the `PSTParams` that were run.
        setup: the `PSTSetup` that was run.
        x: (n,) particle reference position along the PST [m].
        time: (n_steps,) time after each step [s].
        tip: (n_steps,) crack tip position after each step [m].
        sigma_xx: (n,) final slab tension sigma_xx [Pa].
        height: (n,) final column height h [m].
        slip: (n,) final slope-parallel displacement [m].
        u_max: (n,) maximum slip reached [m].
        tau_peak: (n,) weak-layer peak shear strength tau_p [Pa].
        opening: (n,) accumulated tensile plastic strain of the slab [-].
        wl_shear: (n,) final weak-layer shear stress magnitude [Pa].
        snapshots: fields at the end of every chunk (``time`` [s], ``sigma_xx`` [Pa], ...).
        summary: diagnostics by name, units in the key (``arrest_position_m``,
            ``max_crack_speed_over_cs``, ``wall_time_s``, ...).
        fault: runtime fault (one line), None if the run was clean.
        fractures: slab fractures, each ``{"x_m": position [m], ...}``.
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

    def _event(self, key: str) -> Any:
        if key not in self.summary:
            raise ValueError(
                f"PSTResult.{key}: event-based diagnostics need concrete parameters (this "
                "result comes from traced ones, inside jax.grad/jit/vmap); use "
                "arrest_position_smooth, or run simulate_pst outside the transform"
            )
        return self.summary[key]

    @property
    def arrested(self) -> bool:
        """Whether the crack stopped inside the PST (event-based; concrete runs only)."""
        return bool(self._event("arrested"))

    @property
    def arrest_position(self) -> float:
        """Event-based L_ca [m]; NaN when the crack did not arrest (not differentiable)."""
        v = self._event("arrest_position_m")
        return math.nan if v is None else float(v)

    @property
    def arrest_position_smooth(self) -> Any:
        """Smooth surrogate of L_ca [m] (`damjax.diagnostics.smooth_arrest_position`): a
        float from concrete parameters, a JAX scalar (differentiable) or a batch of them
        from traced ones (`jax.grad`, `jax.vmap`)."""
        v = self.summary["arrest_position_smooth_m"]
        return v if is_traced(v) or np.ndim(v) > 0 else float(v)

    def to_dataset(self, snapshots: bool = True) -> Any:
        """The result as an `xarray.Dataset`, as `damjax run` writes ``results.nc``: the
        crack tip and speed per step, the final fields on ``x``, the per-chunk snapshots
        (``snapshots``), CF ``units`` and ``long_name``; global attributes
        ``damjax_version``, ``summary`` (JSON, without the timings) and ``scenario`` (the
        TOML of these parameters and setup: `damjax.scenario.loads` reads it back).
        Results of concrete parameters only (not from inside `jax.grad`/`jit`/`vmap`)."""
        if is_traced(self.tip) or not isinstance(self.tip, np.ndarray):
            raise TypeError(one_run_only("PSTResult.to_dataset"))
        from damjax._version import __version__

        stable = {k: v for k, v in self.summary.items() if k not in io.TIMING_KEYS}
        # a scenario file of these parameters and setup (`damjax.scenario` reads it)
        scenario = {
            "type": "pst",
            "name": "simulate_pst",
            "description": "",
            "params": io.plain_fields(self.params),
            "setup": io.plain_fields(self.setup),
        }
        attrs = {
            "Conventions": "CF-1.10",
            "title": "damjax PST (simulate_pst)",
            "source": f"damjax {__version__}",
            "damjax_version": __version__,
            "scenario": io.toml_dumps(scenario),
            "summary": io.to_json(stable),
            "fault": self.fault,
        }
        return io.result_dataset(
            self,
            crack_speed=diagnostics.crack_speed(self.time, self.tip),
            attrs=attrs,
            snapshots=snapshots,
        )

    def to_netcdf(self, path: str | os.PathLike[str], snapshots: bool = True) -> None:
        """Write `to_dataset` to ``path`` (NetCDF4 with h5netcdf, else NetCDF3; atomically:
        a temporary file, then a rename). Read it with `damjax.io.open_dataset`."""
        io.write_dataset(path, self.to_dataset(snapshots))


jax.tree_util.register_dataclass(
    PSTResult,
    data_fields=[
        "params",
        "x",
        "time",
        "tip",
        "sigma_xx",
        "height",
        "slip",
        "u_max",
        "tau_peak",
        "opening",
        "wl_shear",
        "snapshots",
        "summary",
        "fractures",
    ],
    meta_fields=["setup", "fault"],
)


def simulate_pst(
    params: PSTParams | None = None,
    setup: PSTSetup | None = None,
    progress: bool = False,
    *,
    layout: Layout | None = None,
    state: State | None = None,
    start_chunk: int = 0,
    history: tuple[list[np.ndarray], list[Any]] | None = None,
    callback: Any = None,
) -> PSTResult:
    """Run a PST and return its diagnostics (see `PSTResult`, `damjax.diagnostics`).

    Works on concrete parameters (validated, run chunk by chunk with progress, snapshots
    and every diagnostic) and on traced ones, like any JAX function::

        jax.grad(lambda p: damjax.simulate_pst(p, setup).arrest_position_smooth)(params)
        jax.vmap(lambda th: damjax.simulate_pst(
            eqx.tree_at(lambda p: p.strength_gradient, params, th), setup))(thetas)
        jax.jit(lambda p: damjax.simulate_pst(p, setup, layout=layout))(params)

    The static layout (grid, step count, elastic or plastic slab) is made from the
    concrete values JAX holds behind the tracers under `jax.grad` and `jax.vmap` (the
    whole batch, as `damjax.sweep` does); inside `jax.jit` from the fields that are not
    traced. Only `layout_fields` fix it (the slab's wave speed, the slope and friction,
    the weak layer's largest cohesive slip): a traced strength_gradient, tensile_strength
    (a plastic layout), steady_length, ... needs no layout, and a traced field that fixes
    it is a TypeError naming it; then pass ``layout=damjax.make_layout(params, setup)``
    made from concrete parameters (the stiffest and most sliding you will evaluate).
    Traced runs keep the runtime guards
    (`equinox.error_if`: a slab too stiff for the layout's time step, a finite tensile
    strength on an elastic layout).

    Args:
        params: physical parameters (default: the paper's elastic baseline).
        setup: numerics (default: 100 m, dx = 0.02 m, 3 s, free lateral condition).
        progress: show a tqdm progress bar (concrete parameters only).
        layout: static layout (`make_layout`); default: made from the parameters.
        state: resume from this saved state (with ``start_chunk`` and ``history``).
        start_chunk: number of chunks run before ``state``.
        history: the per-chunk tip arrays and snapshots recorded before ``state``.
        callback: ``callback(chunk, state, tips, snaps)`` after every chunk
            (checkpointing; see `damjax.core.loop.integrate`).
    """
    params = PSTParams() if params is None else params
    resume = dict(state=state, start_chunk=start_chunk, history=history, callback=callback)
    concrete_only("simulate_pst", is_traced(params), progress, resume)
    with eager_if_concrete(params):
        prep = _prepared_and_warned(params, setup, layout, stacklevel=3)
        if is_traced(params):
            return _simulate_traced(prep)
        return run(prep, progress=progress, **resume)


@dataclasses.dataclass(frozen=True)
class Prepared:
    """A PST checked once, at the edge (`prepare`): what `run` integrates.

    Attributes:
        params: the parameters (traced ones stay traced; a scenario's [strength] table
            sampled into ``strength_profile``).
        setup: the setup.
        layout: the static layout (grid, step count, slab law) the run uses.
        notes: the warnings of the input, not yet warned (`damjax.validation.Problem`s:
            dubious and implausible values, an under-resolved dx), for the caller to word.
    """

    params: PSTParams
    setup: PSTSetup
    layout: Layout
    notes: tuple[Problem, ...] = ()


def prepare(
    params: PSTParams | None = None,
    setup: PSTSetup | None = None,
    layout: Layout | None = None,
    *,
    batch: bool = False,
    given: Iterable[str] | None = None,
    resolve: Callable[[PSTSetup, PSTParams], PSTParams] | None = None,
    max_particles: int | None = None,
    jitted: bool = False,
    from_known: bool = False,
    caller: str = "simulate_pst",
) -> Prepared:
    """Check a PST's input once and make its layout: the types, every value (those JAX
    holds behind tracers under `jax.grad` and `jax.vmap` too; inside `jax.jit` only the
    setup's), the 64-bit switch, the layout (made, or checked against the parameters)
    and the run's size. `damjax.validation.InputError` (a ValueError, one line per problem) on
    invalid input, carrying the notes on implausible values in ``notes``.

    Args:
        params: physical parameters (default: the paper's elastic baseline).
        setup: numerics (default: `PSTSetup()`).
        layout: static layout (`make_layout`), checked against the parameters; default:
            made from them.
        batch: batched fields allowed (`damjax.sweep`).
        given: the parameters set explicitly (the dubious-value notes report only those
            as ignored by a controlled run); None: all.
        resolve: ``resolve(setup, params) -> params``, run once the setup is valid (a
            scenario's [strength] table, sampled on the grid).
        max_particles: the most particles a run may have (scenario files).
        jitted: the run is traced even with concrete parameters (`run_pure`): float64
            needs 64-bit mode on beforehand.
        from_known: for traced parameters, the layout from the fields that are not
            traced (`layout_from_known`), not from the values JAX holds behind them.
        caller: the function named in type errors.
    """
    params = PSTParams() if params is None else params
    setup = PSTSetup() if setup is None else setup
    expect_types(
        caller,
        params=(params, PSTParams),
        setup=(setup, PSTSetup),
        layout=(layout, (Layout, type(None))),
    )
    traced = is_traced(params)
    if traced or jitted:  # 64-bit mode cannot be switched on inside a trace
        require_x64(setup.dtype)
    values = concrete_tree(params) if traced else params
    notes: list[Problem] = []
    if values is None:  # inside jax.jit: the setup and the parameters' shapes are known
        raise_if(shape_problems(params, batch) + setup_problems(setup))
    else:
        problems = [] if batch or traced else single_run_problems(values)
        if not problems:
            problems = setup_problems(setup)
            if not problems and resolve is not None and not traced:
                params = values = resolve(setup, values)
            problems += param_problems(values, None if problems else setup)
        if problems:
            raise InputError(problems, notes=implausible(values))
        notes = dubious(values, setup, given)
        lam = float(np.min(np.asarray(theory.elastic_length(values), dtype=float)))
        notes += [n for n in [resolution_note(setup.dx, lam)] if n is not None]
    if not (traced or jitted):
        ensure_x64(setup.dtype)
    if layout is not None:
        check_layout(params if traced else values, setup, layout)
    elif values is None or (traced and from_known):
        layout = layout_from_known(params, setup, caller)
    else:
        layout = _layout(values, setup, max_particles)
    return Prepared(params, setup, layout, tuple(notes))


def _prepared_and_warned(
    params: PSTParams, setup: PSTSetup | None, layout: Layout | None, **kw: Any
) -> Prepared:
    """`prepare` for the API: its notes warned in the API's words (those on implausible
    values also when the input is invalid: a unit mix-up is the likely cause)."""
    stacklevel = kw.pop("stacklevel", 3)
    try:
        prep = prepare(params, setup, layout, **kw)
    except InputError as exc:
        warn_notes(exc.notes, stacklevel=stacklevel)
        raise
    warn_notes(prep.notes, stacklevel=stacklevel)
    return prep


def _layout(params: PSTParams, setup: PSTSetup, max_particles: int | None = None) -> Layout:
    """`damjax.core.model.make_layout` of valid values, and the run's size checked: at
    most ``max_particles``, and within this machine's memory."""
    layout = core_model.make_layout(params, setup)
    if max_particles is not None and layout.n_particles > max_particles:
        raise InputError(
            [
                Problem(
                    "length",
                    setup.length,
                    f"with ${{dx}} = {setup.dx!r} and ${{particles_per_cell}} = "
                    f"{int(setup.particles_per_cell)} the run has {layout.n_particles:.3g} "
                    f"particles: must be at most {max_particles:.0e}",
                )
            ]
        )
    fields = ("length", "dx", "duration", "particles_per_cell")
    problem = size_problem(
        layout.n_particles,
        math.prod(layout.grid_shape),
        layout.n_chunks,
        np.dtype(setup.dtype).itemsize,
        fields + (("width",) if layout.dim == 2 else ()),
    )
    raise_if([problem] if problem is not None else [])
    return layout


def make_layout(params: PSTParams, setup: PSTSetup) -> Layout:
    """Grid and step counts of a PST (`Layout`), from concrete parameters (a batch's
    maxima: the stiffest and most sliding values you will evaluate), for use under
    `jax.grad` / `jax.jit` / `jax.vmap` (``simulate_pst(..., layout=layout)``). The values
    are checked (ValueError naming the field), not how they fit the setup: a layout may
    serve parameters that `simulate_pst` would refuse for this setup alone
    (steady_length, say)."""
    expect_types("make_layout", params=(params, PSTParams), setup=(setup, PSTSetup))
    raise_if(setup_problems(setup) or param_problems(params, None))
    return _layout(params, setup)


def run(
    prep: Prepared,
    *,
    progress: bool = False,
    state: State | None = None,
    start_chunk: int = 0,
    history: tuple[list[np.ndarray], list[Any]] | None = None,
    callback: Any = None,
) -> PSTResult:
    """Integrate a prepared PST of concrete parameters (`prepare`): the model built once,
    the run chunk by chunk, every diagnostic (`finish`). The arguments are
    `simulate_pst`'s."""
    model, state0 = build(prep.params, prep.setup, prep.layout)
    final, tips, snaps, info = integrate(
        model,
        state0 if state is None else state,
        prep.layout.n_chunks,
        prep.layout.chunk_steps,
        snapshot=_snapshot,
        progress=progress,
        callback=callback,
        start_chunk=start_chunk,
        history=history,
    )
    return finish(prep.params, prep.setup, prep.layout, model, final, tips, snaps, info)


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
    # the coordinates in float64 whatever the run's precision, from the layout: the
    # particles sit at odd multiples of dx / (2 ppc), step k ends at k duration / n_steps;
    # float32 and float64 runs of one setup then share them (their files line up)
    half = setup.dx / (2 * int(setup.particles_per_cell))
    x_ref = np.round(np.asarray(model.saw.saw_coord, np.float64) / half) * half
    tau_p = np.asarray(model.weak_layer.tau_peak)
    times = (setup.duration / layout.n_steps) * np.arange(1, tips.size + 1)
    fault = None
    if int(final.fault) != 0:
        msgs = [m for bit, m in FAULT_MESSAGES.items() if int(final.fault) & bit]
        fault = f"run stopped at t = {float(final.fault_time):.4f} s: " + "; ".join(msgs)
        # keep the history up to the fault
        keep = times < float(final.fault_time)
        times, tips = times[keep], tips[keep]
    snapshots = {k: np.stack([s[k] for s in snaps]) for k in snaps[0]} if snaps else {}
    sigma_xx = np.asarray(final.sigma[0])
    height, wl_shear, smooth = (np.asarray(v) for v in _host_diagnostics(model, final))
    opening = np.asarray(final.opening)
    if model.fracture.plastic and not model.fracture.crack_band:
        fractures = _crack_fractures(params, setup, x_ref, final, times, tips)
    else:
        fractures = slab_fractures(model, final)
    slip, u_max = np.asarray(final.u[0]), np.asarray(final.u_max)
    if layout.dim == 2:  # report the strip's average per x, the snapshots' too
        x_all = x_ref
        x_ref, sigma_xx, height, opening, wl_shear, slip, u_max, tau_p = _width_average(
            x_all, sigma_xx, height, opening, wl_shear, slip, u_max, tau_p
        )
        snapshots = {
            k: (
                np.stack([_width_average(x_all, row)[1] for row in v])
                if v.ndim == 2 and v.shape[-1] == x_all.size
                else v
            )
            for k, v in snapshots.items()
        }
    result = PSTResult(
        params=params,
        setup=setup,
        x=x_ref,
        time=times,
        tip=tips,
        sigma_xx=sigma_xx,
        height=height,
        slip=slip,
        u_max=u_max,
        tau_peak=tau_p,
        opening=opening,
        wl_shear=wl_shear,
        snapshots=snapshots,
        summary={},
        fault=fault,
        fractures=fractures,
    )
    smooth = float(smooth)
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
    result.summary["slab_fracture_speed_changes"] = diagnostics.fracture_speed_changes(
        times, tips, fractures
    )
    return result


@eqx.filter_jit
def _host_diagnostics(model: Model, final: State) -> tuple[Any, Any, Any]:
    """Column height, weak-layer shear and the smooth arrest position of a final state as
    one compiled program (cached on disk by the CLI): op by op they were ~40 small
    programs, 0.6 s of a 3 s `damjax run quick` (2026-11-25); the values are the same."""
    return (
        column_height(model, final),
        weak_layer_shear(model, final),
        diagnostics.smooth_arrest_position(model, final),
    )


def slab_fractures(model: Model, state: State) -> list[dict[str, float]]:
    """Band fractures of a final state, ``{x_m, t_s, opening_m}`` sorted by time: bands
    whose opening [m] reached `damjax.materials.slab_fracture.fracture_opening`, bands closer
    than `damjax.diagnostics.FRACTURE_GAP` merged (`damjax.diagnostics.band_fractures`).
    `simulate_pst` reports these for the "crack_band" slab, whose bands have a width of
    their own; the perfectly plastic "paper" slab's fractures are counted by what they do
    to the crack (`damjax.diagnostics.crack_fractures`), which needs the tip
    history. Models without a particle lattice use the opening strain
    (`damjax.diagnostics.slab_fractures`)."""
    x_ref = np.asarray(model.saw.saw_coord)
    if model.fracture.lattice:
        w = np.asarray(band_opening(model.fracture, state.opening, opening_y=state.opening_y))
        return diagnostics.band_fractures(x_ref, w, np.asarray(state.t_fracture))
    return diagnostics.slab_fractures(
        x_ref,
        np.asarray(state.opening),
        np.asarray(state.t_fracture),
        float(np.min(np.asarray(fracture_strain(model.fracture)))),
        diagnostics.FRACTURE_GAP,
    )


def _crack_fractures(
    params: PSTParams,
    setup: PSTSetup,
    x_ref: np.ndarray,
    final: State,
    times: np.ndarray,
    tips: np.ndarray,
) -> list[dict[str, float]]:
    """Fractures of the perfectly plastic slab by what they do to the crack
    (`damjax.diagnostics.crack_fractures`: speed drops and the crown)."""
    arrested, l_ca, t_stop = diagnostics.arrest(times, tips, setup.length, setup.dx)
    if setup.controlled or not arrested:
        l_ca, t_stop = None, None
    return diagnostics.crack_fractures(
        times,
        tips,
        x_ref,
        np.asarray(final.u[0]),
        float(theory.shear_wave_speed(params)),
        l_ca,
        t_stop,
        float(theory.longitudinal_wave_speed(params, setup.lateral)),
    )


def layout_fields(params: PSTParams) -> tuple[str, ...]:
    """The fields of `PSTParams` that `make_layout` reads, hence that fix the layout: the
    time step (the slab's wave speed from youngs_modulus, density and poisson; the slide
    of a released slab from the slope and friction_deg) and the grid's padding (that
    slide and the largest cohesive slip tau_p (1 + softening) D_wl / G_wl). The slab law
    (tensile_strength) is not among them: unknown, the layout is plastic, which runs
    any tensile strength (an infinite one through the same return map)."""
    slope = "slope_profile" if params.slope_profile is not None else "slope_deg"
    strength = "strength_profile" if params.strength_profile is not None else "tau_peak"
    return (
        "youngs_modulus",
        "density",
        "poisson",
        slope,
        "friction_deg",
        strength,
        "softening",
        "wl_shear_modulus",
        "wl_thickness",
    )


def unknown_fields(params: PSTParams) -> list[str]:
    """Fields with a leaf whose value JAX does not hold (traced inside jax.jit)."""
    return [
        f.name
        for f in dataclasses.fields(params)
        if any(concrete_value(x) is None for x in jax.tree.leaves(getattr(params, f.name)))
    ]


def layout_from_known(params: PSTParams, setup: PSTSetup, caller: str) -> Layout:
    """`make_layout` inside `jax.jit`, from the fields whose values are known: those that
    fix the layout (`layout_fields`) must be, the others (strength_gradient,
    steady_length, tensile_strength, saw_speed, the MCC constants, ...) may be traced.
    A traced tensile strength gives a plastic layout. TypeError naming the traced fields
    that fix the layout otherwise."""
    unknown = unknown_fields(params)
    fixing = [f for f in layout_fields(params) if f in unknown]
    if fixing:
        raise TypeError(
            f"{caller}: inside jax.jit the values of {', '.join(fixing)} are unknown, and "
            "they fix the layout (the grid and the step count); make the layout from "
            "concrete parameters and pass it: layout = damjax.make_layout(params, setup); "
            f"jax.jit(lambda p: damjax.{caller}(p, setup, layout=layout)). Traced fields "
            "that do not fix it need no layout"
        )
    return _layout(known_params(params, unknown), setup)


def known_params(params: PSTParams, unknown: list[str]) -> PSTParams:
    """``params`` with concrete values only, for a layout: the ``unknown`` fields (which
    the layout must not read) get stand-ins, the defaults, and a traced tensile strength a
    finite one, so that the layout is plastic. No tracer may reach `make_layout`, where
    theory's formulas would turn traced too."""
    defaults = PSTParams()
    values = {
        f.name: (
            (1.0 if f.name == "tensile_strength" else getattr(defaults, f.name))
            if f.name in unknown
            else jax.tree.map(concrete_value, getattr(params, f.name))
        )
        for f in dataclasses.fields(params)
    }
    return dataclasses.replace(params, **values)


def _simulate_traced(prep: Prepared) -> PSTResult:
    """`simulate_pst` on traced parameters: the pure run (`run_pure`), JAX fields."""
    params, setup, layout = prep.params, prep.setup, prep.layout
    model, final, tips = run_pure(params, setup, layout)
    summary = {
        "arrest_position_smooth_m": raise_on_fault(diagnostics_smooth(model, final), final.fault),
        "saw_position_m": final.saw_pos,
        "tip_m": final.tip,
        "fault_code": final.fault,
    }
    return PSTResult(
        params=params,
        setup=setup,
        x=model.saw.saw_coord,
        time=model.dt * jnp.arange(1, layout.n_steps + 1, dtype=model.saw.saw_coord.dtype),
        tip=tips,
        sigma_xx=final.sigma[0],
        height=column_height(model, final),
        slip=final.u[0],
        u_max=final.u_max,
        tau_peak=model.weak_layer.tau_peak,
        opening=final.opening,
        wl_shear=weak_layer_shear(model, final),
        snapshots={},
        summary=summary,
        fault=None,
        fractures=[],
    )


def _width_average(x: np.ndarray, *fields: np.ndarray) -> tuple[np.ndarray, ...]:
    xs, inv = np.unique(np.round(x, 9), return_inverse=True)
    out = [xs]
    for fld in fields:
        out.append(np.bincount(inv, weights=fld) / np.bincount(inv))
    return tuple(out)


def run_pure(params: PSTParams, setup: PSTSetup, layout: Layout) -> tuple[Model, State, Any]:
    """Traceable full run (for grad / vmap): model, final state and tip per step.

    Reverse mode is checkpointed per segment and per step (`damjax.core.loop.integrate_pure`).
    Compiled once per setup, layout and set of traced fields (`equinox.filter_jit`), so a
    repeated `jax.grad` or `jax.vmap` of a function that calls it does not recompile.
    """
    return _run_pure_jit(params, setup, layout)


@eqx.filter_jit
def _run_pure_jit(params: PSTParams, setup: PSTSetup, layout: Layout) -> tuple[Model, State, Any]:
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

    The layout (grid, step count, elastic or plastic slab) comes from concrete
    parameters: without one it is made from the fields that are not traced (`jax.grad`,
    `jax.jit`, `jax.vmap` of, e.g., strength_gradient or tensile_strength alone), and a
    traced field that fixes it (`layout_fields`) is a TypeError that names it; pass the
    layout then, as above.
    It is the event-based crack tip made continuous (each particle's segment of weak
    layer counts by a C1 ramp of its maximum slip about the failure slip; see
    `damjax.diagnostics`), within one particle spacing of the event-based tip.
    ``width``: optional relative width of a damage ramp over u_max / u_r that replaces
    the failed fraction (0.5 where slab fractures stop the crack; see
    `damjax.diagnostics.smooth_arrest_position`).
    """
    check_width(width)
    if layout is None and is_traced(params):
        fixing = [f for f in layout_fields(params) if is_traced(getattr(params, f))]
        if fixing:
            raise TypeError(
                f"arrest_position_smooth: {', '.join(fixing)} traced (jax.grad/jit/vmap) "
                "and no layout was given; they fix the layout (the grid and the step "
                "count): make it from concrete parameters first: layout = "
                "damjax.make_layout(params, setup), then "
                "jax.grad(lambda p: damjax.arrest_position_smooth(p, setup, layout))(params)"
            )
    prep = _prepared_and_warned(
        params, setup, layout, jitted=True, from_known=True, caller="arrest_position_smooth"
    )
    model, final, _ = run_pure(prep.params, prep.setup, prep.layout)
    return raise_on_fault(diagnostics_smooth(model, final, width), final.fault)


def diagnostics_smooth(model: Model, final: State, width: float | None = None) -> Any:
    """`damjax.diagnostics.smooth_arrest_position` of a final state."""
    return diagnostics.smooth_arrest_position(model, final, width)
