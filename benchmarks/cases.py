"""Benchmark cases. Timings are warm: compilation is measured and reported separately."""

from __future__ import annotations

import json
import resource
import sys
import time
from collections.abc import Callable

import numpy as np

CASES: dict[str, Callable[[], None]] = {}


def case(fn: Callable[[], None]) -> Callable[[], None]:
    CASES[fn.__name__] = fn
    return fn


def peak_rss_mb() -> float:
    """Peak resident memory of this process [MB] (Linux ru_maxrss is in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def emit(**row: object) -> None:
    row.setdefault("peak_rss_mb", round(peak_rss_mb(), 1))
    print(json.dumps(row), flush=True)


def _pst_row(case_name: str, params, setup) -> dict:
    from damjax import simulate_pst

    r = simulate_pst(params, setup)
    s = r.summary
    return dict(
        case=case_name,
        n_particles=s["n_particles"],
        n_steps=s["n_steps"],
        dtype=setup.dtype,
        dx=setup.dx,
        lateral=setup.lateral,
        compile_time_s=round(s["compile_time_s"], 3),
        wall_time_s=round(s["wall_time_s"], 3),
        particle_steps_per_s=round(s["particle_steps_per_s"]),
        arrest_position_m=s["arrest_position_m"],
        max_crack_speed_over_cs=s["max_crack_speed_over_cs"],
    )


@case
def pst_f32() -> None:
    """Full baseline PST (100 m, dx 0.02 m, 3 s), float32."""
    from damjax import PSTParams, PSTSetup

    emit(**_pst_row("pst_f32", PSTParams(), PSTSetup()))


@case
def pst_f64() -> None:
    """Full baseline PST (100 m, dx 0.02 m, 3 s), float64."""
    from damjax import PSTParams, PSTSetup

    emit(**_pst_row("pst_f64", PSTParams(), PSTSetup(dtype="float64")))


@case
def pst_scaling() -> None:
    """Cost growth: baseline PST at dx 0.04, 0.02, 0.01 m; fitted exponent of wall time."""
    from damjax import PSTParams, PSTSetup

    rows = []
    for dx in (0.04, 0.02, 0.01):
        row = _pst_row(f"pst_dx{dx}", PSTParams(), PSTSetup(dx=dx))
        emit(**row)
        rows.append(row)
    work = np.log([r["n_particles"] * r["n_steps"] for r in rows])
    wall = np.log([r["wall_time_s"] for r in rows])
    slope = float(np.polyfit(work, wall, 1)[0])
    emit(
        case="pst_scaling",
        exponent_wall_vs_particle_steps=round(slope, 3),
        n_particles=[r["n_particles"] for r in rows],
        n_steps=[r["n_steps"] for r in rows],
        dtype="float32",
        compile_time_s=None,
        wall_time_s=[r["wall_time_s"] for r in rows],
        particle_steps_per_s=[r["particle_steps_per_s"] for r in rows],
    )


@case
def kx_controlled() -> None:
    """Controlled sawing at adot/c_s = 0.2, 0.8, 1.4: k_x against Appendix A (full size)."""
    from damjax import PSTParams, PSTSetup, simulate_pst, theory

    cs = float(theory.shear_wave_speed(PSTParams()))
    for lateral in ("free", "constrained"):
        for ratio in (0.2, 0.8, 1.4):
            adot = ratio * cs
            setup = PSTSetup(controlled=True, lateral=lateral, duration=min(3.0, 80.0 / adot))
            r = simulate_pst(PSTParams(saw_speed=adot), setup)
            s = r.summary
            kx, kth = s["tension_gradient_pa_per_m"], s["tension_gradient_theory_pa_per_m"]
            emit(
                case="kx_controlled",
                lateral=lateral,
                adot_over_cs=ratio,
                k_x=kx,
                k_x_theory=kth,
                rel_error=kx / kth - 1,
                n_particles=s["n_particles"],
                n_steps=s["n_steps"],
                dtype="float32",
                compile_time_s=s["compile_time_s"],
                wall_time_s=s["wall_time_s"],
                particle_steps_per_s=s["particle_steps_per_s"],
            )


@case
def pst_elastic_targets() -> None:
    """Self-propagating elastic PSTs (theta 500, L_ss 20): arrest and crack speed targets."""
    from damjax import PSTParams, PSTSetup

    for lateral in ("free", "constrained"):
        for delta in (0.0, 2.0):
            row = _pst_row("pst_elastic", PSTParams(softening=delta), PSTSetup(lateral=lateral))
            r = dict(row, softening=delta, youngs_modulus=4e6)
            emit(**r)
        for E in (2e6, 6e6):
            row = _pst_row("pst_elastic", PSTParams(youngs_modulus=E), PSTSetup(lateral=lateral))
            emit(**dict(row, softening=0.0, youngs_modulus=E))


@case
def pst_grad() -> None:
    """Gradient of the smooth arrest position vs the forward run, full baseline PST.

    ``DAMJAX_BENCH_DURATION`` (s, default 3) lengthens the run: 4.5 s is 60 000 steps.
    """
    import os

    import jax

    from damjax import PSTParams, PSTSetup, pst
    from damjax.core.loop import cpu_compiler_options

    duration = float(os.environ.get("DAMJAX_BENCH_DURATION", "3.0"))
    params, setup = PSTParams(), PSTSetup(duration=duration)
    layout = pst.make_layout(params, setup)
    # both with the options damjax compiles its own loop with (as a user would pass them)
    opts = cpu_compiler_options()
    fwd = jax.jit(lambda q: pst.arrest_position_smooth(q, setup, layout), compiler_options=opts)
    grad = jax.jit(
        jax.value_and_grad(lambda q: pst.arrest_position_smooth(q, setup, layout)),
        compiler_options=opts,
    )
    t0 = time.perf_counter()
    fwd_c = fwd.lower(params).compile()
    t_cf = time.perf_counter() - t0
    t0 = time.perf_counter()
    grad_c = grad.lower(params).compile()
    t_cg = time.perf_counter() - t0
    # forward and gradient alternate (two rounds; minima reported) so that one slow
    # round of a noisy machine does not make the ratio
    t_fs, t_gs = [], []
    for _ in range(2):
        t0 = time.perf_counter()
        value = float(fwd_c(params))
        t_fs.append(time.perf_counter() - t0)
        if not t_gs:
            rss_f = peak_rss_mb()
        t0 = time.perf_counter()
        v, g = grad_c(params)
        jax.block_until_ready(g)
        t_gs.append(time.perf_counter() - t0)
    t_f, t_g = min(t_fs), min(t_gs)
    rss_g = peak_rss_mb()  # the process peak: forward and gradient runs
    emit(
        case="pst_grad",
        n_particles=layout.n_particles,
        n_steps=layout.n_steps,
        dtype=setup.dtype,
        compile_time_s=round(t_cf, 2),
        grad_compile_time_s=round(t_cg, 2),
        wall_time_s=round(t_f, 3),
        grad_wall_time_s=round(t_g, 3),
        grad_over_forward=round(t_g / t_f, 2),
        forward_runs_s=[round(t, 3) for t in t_fs],
        grad_runs_s=[round(t, 3) for t in t_gs],
        particle_steps_per_s=round(layout.n_particles * layout.n_steps / t_f),
        forward_peak_rss_mb=round(rss_f, 1),
        grad_peak_rss_mb=round(rss_g, 1),
        arrest_position_smooth_m=value,
        d_arrest_d_theta=float(g.strength_gradient),
        d_arrest_d_delta=float(g.softening),
    )


@case
def batch16() -> None:
    """A vmapped batch of 16 PSTs (50 m, dx 0.02 m, 2 s; theta 500-2000 Pa/m) vs 16 sequential."""
    import jax.numpy as jnp

    from damjax import PSTParams, PSTSetup, simulate_pst, sweep

    setup = PSTSetup(length=50.0, duration=2.0)
    thetas = np.linspace(500.0, 2000.0, 16)
    seq_wall, seq_compile, seq_arrest = 0.0, 0.0, []
    for th in thetas:
        s = simulate_pst(PSTParams(strength_gradient=float(th)), setup).summary
        seq_wall += s["wall_time_s"]
        seq_compile += s["compile_time_s"]
        seq_arrest.append(s["arrest_position_m"])
    n_p, n_s = s["n_particles"], s["n_steps"]
    emit(
        case="batch16_sequential",
        n_particles=n_p,
        n_steps=n_s,
        dtype=setup.dtype,
        n_sims=16,
        compile_time_s=round(seq_compile, 2),
        wall_time_s=round(seq_wall, 3),
        particle_steps_per_s=round(16 * n_p * n_s / seq_wall),
    )
    for batch_size in (None, 4):
        res = sweep(
            PSTParams(strength_gradient=jnp.asarray(thetas, jnp.float32)),
            setup,
            batch_size=batch_size,
        )
        wall = sum(r.summary["wall_time_s"] for r in res)  # per-member shares of the batch
        pairs = zip([r.summary["arrest_position_m"] for r in res], seq_arrest, strict=True)
        diff = max((abs(b - a) for b, a in pairs if a is not None and b is not None), default=0.0)
        emit(
            case="batch16_vmapped" if batch_size is None else "batch16_lax_map4",
            n_particles=n_p,
            n_steps=n_s,
            dtype=setup.dtype,
            n_sims=16,
            compile_time_s=round(res[0].summary["compile_time_s"], 2),
            wall_time_s=round(wall, 3),
            particle_steps_per_s=round(16 * n_p * n_s / wall),
            peer="sequential simulate_pst",
            peer_particle_steps_per_s=round(16 * n_p * n_s / seq_wall),
            ratio=round(seq_wall / wall, 3),
            max_arrest_diff_vs_sequential_m=diff,
        )


@case
def pst_grad_fd() -> None:
    """Full-size gradients of the smooth arrest position vs central differences (2 steps)."""
    import os

    import jax

    from damjax import PSTParams, PSTSetup, pst

    dtype = os.environ.get("DAMJAX_BENCH_DTYPE", "float64")
    if dtype == "float64":
        jax.config.update("jax_enable_x64", True)
    setup = PSTSetup(dtype=dtype)
    for base in (PSTParams(softening=1.0), PSTParams()):
        layout = pst.make_layout(base, setup)  # fixed step count for every perturbation
        fwd = jax.jit(lambda q, lay=layout: pst.arrest_position_smooth(q, setup, lay))
        grad = jax.jit(jax.grad(lambda q, lay=layout: pst.arrest_position_smooth(q, setup, lay)))
        g = grad(base)
        for name in ("strength_gradient", "softening"):
            x0 = float(getattr(base, name))
            if x0 == 0.0:
                continue  # delta = 0 is the edge of the valid range: no central difference
            ad = float(getattr(g, name))
            for rel in (0.005, 0.01):
                h = rel * x0
                up = float(fwd(eqx_replace(base, name, x0 + h)))
                dn = float(fwd(eqx_replace(base, name, x0 - h)))
                fd = (up - dn) / (2 * h)
                emit(
                    case="pst_grad_fd",
                    dtype=dtype,
                    field=name,
                    at=x0,
                    softening=float(base.softening),
                    rel_step=rel,
                    ad=ad,
                    fd=fd,
                    rel_error=abs(ad - fd) / max(abs(fd), 1e-12),
                    arrest_position_smooth_m=float(fwd(base)),
                    n_particles=layout.n_particles,
                    n_steps=layout.n_steps,
                )


def _gradient_rows(case_name: str, params, setup, fields, batch_size=None) -> None:
    from damjax import gradient_check

    t0 = time.perf_counter()
    checks = gradient_check(params, setup, list(fields), batch_size=batch_size)
    wall = time.perf_counter() - t0
    for c in checks:
        emit(
            case=case_name,
            field=c.field,
            at=c.at,
            softening=float(params.softening),
            steady_length=float(params.steady_length),
            length=setup.length,
            dx=setup.dx,
            duration=setup.duration,
            dtype=setup.dtype,
            window=[c.values[0], c.values[-1]],
            n_runs=len(c.values),
            ad_mean=c.ad_mean,
            ad_center=c.ad,
            event_slope=c.event_slope,
            length_slope=c.length_slope,
            relative_error=round(c.relative_error, 4),
            ok=c.ok,
            arrests_m=list(c.arrests),
            ad_values=list(c.ad_values),
            wall_time_s_all_fields=round(wall, 1),
        )


@case
def gradient_events() -> None:
    """AD of the crack length vs the event-based arrest's slope (+-10 %, 11 runs): theta,
    E, G_wl, tau_peak at softening 0 and 0.3 (40 m PST, L_ss 10, theta 800, dx 0.04, f64)."""
    import jax

    from damjax import PSTParams, PSTSetup

    jax.config.update("jax_enable_x64", True)
    setup = PSTSetup(length=40.0, dx=0.04, duration=1.0, dtype="float64")
    fields = ("strength_gradient", "youngs_modulus", "wl_shear_modulus", "tau_peak")
    for delta in (0.0, 0.3):
        params = PSTParams(steady_length=10.0, strength_gradient=800.0, softening=delta)
        _gradient_rows("gradient_events", params, setup, fields)


@case
def gradient_full() -> None:
    """The same check on the paper's brittle baseline (theta 500, L_ss 20, softening 0,
    100 m, dx 0.02 m, 3 s, float32), for theta."""
    from damjax import PSTParams, PSTSetup

    # one member at a time: the memory of one gradient of the full baseline
    _gradient_rows("gradient_full", PSTParams(), PSTSetup(), ("strength_gradient",), 1)


@case
def inversion_brittle() -> None:
    """Gradient inversion through the solver at softening 0: theta from event-based
    arrests observed on a twice finer grid with noise (30 m PST, dx 0.05 m model; long
    enough that the crack arrests inside it from both starts, theta 400 and 900 Pa/m)."""
    import dataclasses

    from damjax import PSTParams, PSTSetup, calibrate, simulate_pst

    truth = PSTParams(steady_length=5.0, strength_gradient=600.0, softening=0.0)
    model_setup = PSTSetup(length=30.0, dx=0.05, duration=1.2)
    obs_setup = dataclasses.replace(model_setup, dx=0.025)
    rng = np.random.default_rng(0)
    noise = 0.1  # [m]
    observations = []
    for lss in (4.0, 5.0, 6.0):  # three PSTs of one snowpack: the steady length varies
        r = simulate_pst(dataclasses.replace(truth, steady_length=lss), obs_setup)
        observed = r.arrest_position + float(rng.normal(0.0, noise))
        observations.append(({"steady_length": lss}, observed))
        emit(
            case="inversion_brittle_observation",
            steady_length=lss,
            arrest_position_m=r.arrest_position,
            observed_m=observed,
            dx=obs_setup.dx,
        )
    for start in (400.0, 900.0):
        t0 = time.perf_counter()
        inv = calibrate.invert(
            observations,
            dataclasses.replace(truth, strength_gradient=start),
            model_setup,
            ["strength_gradient"],
            noise_std=noise,
            steps=30,
            learning_rate=0.05,
        )
        est = inv.estimates["strength_gradient"]
        emit(
            case="inversion_brittle",
            truth=600.0,
            start=start,
            estimate=est,
            relative_error=abs(est / 600.0 - 1.0),
            std_error=inv.std_errors["strength_gradient"],
            loss=inv.loss,
            loss_history=[round(v, 3) for v in inv.history],
            dx_model=model_setup.dx,
            dx_observed=obs_setup.dx,
            noise_m=noise,
            wall_time_s=round(time.perf_counter() - t0, 1),
        )


def eqx_replace(params, name: str, value: float):
    """`params` with one field replaced (keeps the leaf dtype)."""
    import dataclasses

    return dataclasses.replace(params, **{name: value})


@case
def surrogate_table() -> None:
    """Smooth arrest surrogate vs event-based L_ca, elastic baseline, theta 200-5000 Pa/m."""
    import jax.numpy as jnp

    from damjax import PSTParams, PSTSetup, sweep

    # low gradients run far: below theory.runaway_gradient (303 Pa/m) an elastic brittle
    # slab never arrests (theta 300 runs through a 400 m strip in 12 s), so theta 200 and
    # 300 have no L_ca; they run on a 300 m strip for 6 s with theta 400 (112.6 m)
    for thetas, setup in (
        ([200.0, 300.0, 400.0], PSTSetup(length=300.0, duration=6.0)),
        ([500.0, 1000.0, 2000.0, 5000.0], PSTSetup()),
    ):
        res = sweep(PSTParams(strength_gradient=jnp.asarray(thetas, jnp.float32)), setup)
        _surrogate_rows(thetas, res, setup)


def _surrogate_rows(thetas, res, setup) -> None:
    for th, r in zip(thetas, res, strict=True):
        s = r.summary
        a, sm = s["arrest_position_m"], s["arrest_position_smooth_m"]
        emit(
            case="surrogate_table",
            theta=th,
            arrested=s["arrested"],
            arrest_position_m=a,
            arrest_position_smooth_m=sm,
            difference_m=None if a is None else sm - a,
            n_particles=s["n_particles"],
            n_steps=s["n_steps"],
            dtype=setup.dtype,
        )


_SLOPE_KEYS = (
    "upslope_front",
    "crossslope_front",
    "upslope_extent_m",
    "upslope_arrest_distance_m",
    "upslope_arrest_position_m",
    "arrested_before_top",
    "crossslope_extent_m",
    "crossslope_arrest_distance_m",
    "upslope_crack_speed_over_cs",
    "crossslope_crack_speed_over_cs",
    "upslope_crack_speed_mean_over_cs",
    "crossslope_crack_speed_mean_over_cs",
    "release_area_m2",
    "crown_area_m2",
    "stauchwall_area_m2",
    "slab_fracture_area_m2",
    "critical_cut_radius_m",
    "last_failure_time_s",
    "last_upslope_failure_time_s",
    "front_quiet_at_end",
    "start_m",
    "fault",
)


def slope_row(case_name: str, case, params=None) -> dict:
    """One JSON row of a generic-slope run (`damjax.slope.generic`); `params`
    defaults to the paper's Fig. 12 slab (`fig12_params`)."""
    from damjax.slope.generic import run_generic_slope

    s = run_generic_slope(case, params).summary
    return dict(
        case=case_name,
        n_particles=s["n_particles"],
        n_steps=s["n_steps"],
        dtype=case.dtype,
        dx=case.dx,
        particles_per_cell=case.particles_per_cell,
        compile_time_s=round(s["compile_time_s"], 3),
        wall_time_s=round(s["wall_time_s"], 3),
        particle_steps_per_s=round(s["particle_steps_per_s"]),
        **{k: s.get(k) for k in _SLOPE_KEYS},
    )


@case
def slope() -> None:
    """Paper Fig. 12a: 50 m x 60 m generic slope, GRF 20 Pa/m, dx 0.2 m, 2 s (seed 0)."""
    import os

    from damjax.slope.generic import GenericSlopeCase

    ppc = int(os.environ.get("DAMJAX_BENCH_PPC", "1"))
    # the timing case: 2 s simulated (the arrest itself needs up to ~2.8 s, see
    # benchmarks/slope_acceptance.py)
    emit(**slope_row("slope", GenericSlopeCase(particles_per_cell=ppc, duration=2.0)))


@case
def ensemble16() -> None:
    """16 Fig. 12a slope members (dx 0.2 m, 2 s): ensemble vs 16 sequential; 2 processes vs 1."""
    from benchmarks import ensemble16 as e

    for row in e.rows():
        emit(**row)


@case
def mpm88() -> None:
    """Taichi's mpm88 (2D fluid, 128^2 grid, f32) on damjax transfers (fixed and float
    P2G sums) vs Taichi on the same backend; 3-200 particles per cell."""
    from benchmarks import mpm88 as m

    ti = m.taichi_init(m.n_threads())  # None (peer skipped) if taichi is not importable
    # the particles-per-cell sweep and the 2 x 2 per cell row; damjax "fixed" and "float"
    for n, repeats, layout in m.CASE_ROWS:
        emit(**m.run_case(n, n_steps=100, repeats=repeats, ti=ti, layout=layout))


@case
def figures() -> None:
    """The documentation's figures (docs/images/*.png), about 5 min: benchmarks/figures.py."""
    from benchmarks import figures as f

    f.main([])


@case
def real_path() -> None:
    """AvaFrame's avaAlr / avaKot paths: damjax release ensemble vs documented polygon, com1DFA
    runout vs reference (hours on 2 cores; DAMJAX_REAL_PATH_MEMBERS, default 16)."""
    import os

    from benchmarks import real_path as rp

    rp.main(["--members", os.environ.get("DAMJAX_REAL_PATH_MEMBERS", "16")])


@case
def sweep256() -> None:
    """256 baseline PSTs (100 m, dx 0.02 m, 3 s, theta 250-1000) in memory-sized batches
    vs one at a time (--dry-run: a toy batch; benchmarks/throughput.py)."""
    from benchmarks import throughput as t

    for row in t.sweep256_rows():
        emit(**row)


@case
def slope_large() -> None:
    """200 m x 200 m slope, dx 0.1 m, 5 s: one run and a 32-member ensemble (off a GPU a
    window of steps, extrapolated; --dry-run: a 24 m x 16 m patch; benchmarks/throughput.py)."""
    from benchmarks import throughput as t

    for row in t.slope_large_rows():
        emit(**row)


def _run(name: str) -> None:
    t0 = time.perf_counter()
    CASES[name]()
    sys.stderr.write(f"[{name}: {time.perf_counter() - t0:.1f} s]\n")


if __name__ == "__main__":
    for n in sys.argv[1:]:
        _run(n)
