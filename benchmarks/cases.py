"""Benchmark cases. Timings are warm: compilation is measured and reported separately."""

from __future__ import annotations

import argparse
import datetime
import functools
import json
import math
import os
import resource
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CASES: dict[str, Callable[[], None]] = {}


def case(fn: Callable[[], None]) -> Callable[[], None]:
    CASES[fn.__name__] = fn
    return fn


def peak_rss_mb() -> float:
    """Peak resident memory of this process [MB] (Linux ru_maxrss is in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def git_commit() -> str | None:
    """The code that runs: ``DAMJAX_COMMIT`` where given (a copy whose git directory may
    not match its files), else ``git rev-parse --short HEAD``, with ``+`` where damjax/
    differs from that commit."""
    if os.environ.get("DAMJAX_COMMIT"):
        return os.environ["DAMJAX_COMMIT"]

    def git(*args: str) -> str:
        res = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=10)
        return res.stdout.strip()

    try:
        commit = git("rev-parse", "--short", "HEAD")
        return (commit + "+" if git("status", "--porcelain", "--", "damjax") else commit) or None
    except (OSError, subprocess.SubprocessError):
        return None


@functools.cache
def stamp() -> dict:
    """When, on what code and on what machine a row is measured."""
    model = ""
    try:
        with open("/proc/cpuinfo") as fh:
            model = next((ln.split(":", 1)[1].strip() for ln in fh if "model name" in ln), "")
    except OSError:
        pass
    machine = f"{os.cpu_count()}-core {model}".strip()
    return dict(date=datetime.date.today().isoformat(), commit=git_commit(), machine=machine)


def at_least(kind: type, low: float, strict: bool = False) -> Callable[[str], Any]:
    """An argparse type: a ``kind`` (int or float) >= ``low`` (> with ``strict``), finite;
    argparse prints one usage line naming the option otherwise."""

    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r}: not {'an integer' if kind is int else 'a number'}"
            ) from None
        if not math.isfinite(value) or not (value > low if strict else value >= low):
            raise argparse.ArgumentTypeError(f"{text}: must be {'>' if strict else '>='} {low:g}")
        return value

    return parse


def emit(**row: object) -> None:
    """Print one JSON row, with the process's peak memory and `stamp`."""
    row.setdefault("peak_rss_mb", round(peak_rss_mb(), 1))
    for k, v in stamp().items():
        row.setdefault(k, v)
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
    """The paper's baseline PST (100 m, dx 0.02 m, 3 s: 10 000 particles), float32."""
    from damjax import PSTParams, PSTSetup

    emit(**_pst_row("pst_f32", PSTParams(), PSTSetup()))


@case
def pst_f64() -> None:
    """The same in float64."""
    from damjax import PSTParams, PSTSetup

    emit(**_pst_row("pst_f64", PSTParams(), PSTSetup(dtype="float64")))


@case
def pst_scaling() -> None:
    """The baseline PST at dx 0.04, 0.02, 0.01 m: exponent of wall time vs particle-steps."""
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
def pst_grad() -> None:
    """value_and_grad of the baseline PST's smooth arrest position against its forward run.

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
    """A vmapped batch of 16 PSTs (50 m, 2 s, theta 500-2000 Pa/m) vs 16 sequential."""
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
    defaults to the paper's Fig. 13 slab (`fig12_params`)."""
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
    """The paper's Fig. 13a slope (50 m x 60 m, dx 0.2 m, 75 000 particles, 2 s, seed 0)."""
    import os

    from damjax.slope.generic import GenericSlopeCase

    ppc = int(os.environ.get("DAMJAX_BENCH_PPC", "1"))
    # the timing case: 2 s simulated (the arrest itself needs up to ~2.8 s, see
    # verification/slope_acceptance.py)
    emit(**slope_row("slope", GenericSlopeCase(particles_per_cell=ppc, duration=2.0)))


@case
def ensemble16() -> None:
    """16 Fig. 13a members: one ensemble vs 16 runs; 2 processes vs 1 (~20 min on 2 cores)."""
    from benchmarks import ensemble16 as e

    for row in e.rows():
        emit(**row)


@case
def mpm88() -> None:
    """Taichi's mpm88 on damjax's transfer kernels against Taichi, 3-200 particles per cell.

    2D fluid, 128^2 grid, float32; damjax with the fixed and the float P2G sums, Taichi on
    JAX's backend (skipped without taichi). Chosen sizes and the step comparisons:
    ``python -m benchmarks.mpm88 -h``."""
    from benchmarks import mpm88 as m

    ti = m.taichi_init(m.n_threads())  # None (peer skipped) if taichi is not importable
    # the particles-per-cell sweep and the 2 x 2 per cell row; damjax "fixed" and "float"
    for n, repeats, layout in m.CASE_ROWS:
        emit(**m.run_case(n, n_steps=100, repeats=repeats, ti=ti, layout=layout))


@case
def sweep256() -> None:
    """256 baseline PSTs through damjax.sweep against one at a time (~40 min on 2 cores).

    100 m, dx 0.02 m, 3 s, theta 250-1000 Pa/m, slices sized from XLA's memory estimate
    (--dry-run: a toy batch; benchmarks/throughput.py)."""
    from benchmarks import throughput as t

    for row in t.sweep256_rows():
        emit(**row)


@case
def slope_large() -> None:
    """The 200 m x 200 m slope (4 M particles): one run and a 32-member ensemble.

    dx 0.1 m, 5 s; off a GPU a window of steps, extrapolated (--dry-run: a 24 m x 16 m
    patch; benchmarks/throughput.py)."""
    from benchmarks import throughput as t

    for row in t.slope_large_rows():
        emit(**row)


@case
def real_path_member() -> None:
    """A real-path member end to end against the Fig. 13a slope (avaAlr: ~10 min on 2 cores).

    One member of a shipped real path (avaAlr, or DAMJAX_REAL_PATH=avaKot), with the Fig.
    12a slope and that slope widened to the path's particle count, in one process.

    Rows: ``slope_fig12a`` (75 000 particles, 2 s) and ``slope_fig12a_wide`` (the same
    profile and dx, as wide as gives the path's particle count, the first 0.2 s): cost per
    particle-step [ns]; then the member: the wall time of `scenario.slope_fields.simulate`
    (terrain, snow cover and fields, build, compile, every step, the maps and summary), its
    particles and steps, and its cost per particle-step against both slopes'. Then
    ``real_path_member_alternated``: chunks of 100 steps of the three taken in turn for 5
    rounds (`alternated_ns_per_particle_step`), the medians and their ratios. Toy sizes
    under --dry-run: the real-path toy polygon, 0.1 s."""
    import dataclasses
    import tempfile
    import warnings

    from damjax import scenario
    from damjax.scenario import slope_fields
    from damjax.slope.generic import GenericSlopeCase
    from verification import real_path

    dry = os.environ.get("DAMJAX_BENCH_DRY_RUN", "") not in ("", "0")
    path = os.environ.get("DAMJAX_REAL_PATH", "avaAlr")
    if dry:
        scn = real_path.toy_scenario(path, Path(tempfile.mkdtemp(prefix="toy-path-")))
    else:
        scn = scenario.load(real_path.scenario_name(path))
    slopes = {}
    fig12a = GenericSlopeCase(particles_per_cell=1, duration=0.1 if dry else 2.0)
    slopes["slope_fig12a"] = slope_row("slope_fig12a", fig12a)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the run's notes (the domain's edge) are in its row
        res = slope_fields.simulate(scn)
    wall = time.perf_counter() - t0
    s = res.summary
    n_p, n_s = int(s["n_particles"]), int(s["n_steps"])
    # the Fig. 13a slope as wide as gives the path's particle count (same dx and profile):
    # what the size alone costs
    width = max(fig12a.width, round(n_p * fig12a.dx**2 / fig12a.length / 10.0) * 10.0)
    wide = dataclasses.replace(fig12a, width=width, duration=0.02 if dry else 0.2)
    slopes["slope_fig12a_wide"] = slope_row("slope_fig12a_wide", wide)
    ns = {k: 1e9 / r["particle_steps_per_s"] for k, r in slopes.items()}
    for k, r in slopes.items():
        emit(**r, ns_per_particle_step=round(ns[k], 1), dry_run=dry)
    ns_member = 1e9 / s["particle_steps_per_s"]
    emit(
        case="real_path_member",
        path=path,
        scenario=scn.name,
        dx=scn.setup.dx,
        duration_s=scn.setup.duration,
        n_particles=n_p,
        n_steps=n_s,
        wall_time_s=round(wall, 1),
        compile_time_s=round(s["compile_time_s"], 1),
        run_time_s=round(s["wall_time_s"], 1),
        ns_per_particle_step=round(ns_member, 1),
        vs_fig12a=round(ns_member / ns["slope_fig12a"], 2),
        vs_fig12a_wide=round(ns_member / ns["slope_fig12a_wide"], 2),
        release_area_m2=s.get("release_area_m2"),
        domain_edge_fraction=s.get("domain_edge_fraction"),
        dry_run=dry,
    )
    # the same steps of the three, alternated in rounds: a shared machine's speed drifts
    # over a 10-minute run, and a 2 s slope, a 0.2 s one and a 4 s member run at different
    # times; medians of alternated chunks compare like with like
    from damjax.scenario import prepared
    from damjax.slope import simulation

    models = {
        "slope_fig12a": _slope_model(fig12a),
        "slope_fig12a_wide": _slope_model(wide),
        "member": simulation.build(prepared(scn))[:2],
    }
    ns_alt = alternated_ns_per_particle_step(models, 5 if dry else 100, 2 if dry else 5)
    emit(
        case="real_path_member_alternated",
        path=path,
        steps_per_chunk=5 if dry else 100,
        **{f"{k}_n_particles": int(np.shape(m[1].u)[-1]) for k, m in models.items()},
        **{f"{k}_ns_per_particle_step": round(v, 1) for k, v in ns_alt.items()},
        member_vs_fig12a=round(ns_alt["member"] / ns_alt["slope_fig12a"], 2),
        member_vs_fig12a_wide=round(ns_alt["member"] / ns_alt["slope_fig12a_wide"], 2),
        wide_vs_fig12a=round(ns_alt["slope_fig12a_wide"] / ns_alt["slope_fig12a"], 2),
        dry_run=dry,
    )


def _slope_model(case) -> tuple:
    """Model and initial state of a generic slope (`damjax.slope.generic`, the Fig. 13 slab)."""
    from damjax.slope import generic, simulation

    psi, tau = generic.slope_field(case), generic.strength_field(case)
    start = case.start if case.start is not None else generic.weak_spot(case, tau)
    prep = simulation.prepare(
        generic.fig12_params(), generic.setup_of(case, start), slope_deg=psi, tau_peak=tau
    )
    return simulation.build(prep)[:2]


def alternated_ns_per_particle_step(models: dict, n_steps: int, rounds: int) -> dict:
    """Median cost per particle-step [ns] of chunks of ``n_steps`` steps of each (model,
    state) in ``models``, alternated for ``rounds`` rounds (the order flips every round);
    each run goes on from where its last chunk ended, so the chunks see the run's own
    release. The smallest gets as many chunks a round as give it about the largest's
    particle-steps."""
    import statistics

    import jax

    from damjax.core import loop

    n_p = {k: int(np.shape(st.u)[-1]) for k, (_, st) in models.items()}
    reps = {k: max(1, round(max(n_p.values()) / v)) for k, v in n_p.items()}
    exes, states = {}, {}
    for k, (model, state) in models.items():
        exes[k] = loop.compile_chunk(model, state, n_steps)[0]
        states[k] = jax.block_until_ready(exes[k](model, state)[0])  # warm; donates its state
    ns: dict = {k: [] for k in models}
    for r in range(rounds):
        for k in list(models) if r % 2 == 0 else list(models)[::-1]:
            t0 = time.perf_counter()
            for _ in range(reps[k]):
                states[k] = exes[k](models[k][0], states[k])[0]
            jax.block_until_ready(states[k])
            ns[k].append((time.perf_counter() - t0) / (reps[k] * n_steps * n_p[k]) * 1e9)
    return {k: statistics.median(v) for k, v in ns.items()}


def _run(name: str) -> None:
    t0 = time.perf_counter()
    CASES[name]()
    sys.stderr.write(f"[{name}: {time.perf_counter() - t0:.1f} s]\n")


if __name__ == "__main__":
    for n in sys.argv[1:]:
        _run(n)
