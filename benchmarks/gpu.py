"""One prepared command for a GPU (or any device): the GPU-relevant tests and figures.

    python -m benchmarks gpu                    # every part (about 15 min on one H100/H200)
    python -m benchmarks gpu --dry-run          # every part at toy size (CI; any device)
    python -m benchmarks gpu --no-tests         # the figures only
    python -m benchmarks gpu --parts pst_f32,repeat --timeout 300
    python -m benchmarks gpu --parts acceptance # the throughput figures (about 4 min)
    python -m benchmarks gpu --parts checks     # the rest: tests, determinism, gradients
    python -m benchmarks.gpu --prepare DIR      # the old tree and wheels for a bare machine

Every part runs in its own process (a crash, an out-of-memory or a hang of one part is
reported and the rest still run) and prints JSON lines on stdout, each with ``part``,
``device``, ``platform``, ``jax``, ``jaxlib``, ``date`` and ``commit``; a part that fails
prints one line with ``error``. The parts:

- ``environment``: the device, versions, XLA flags, and whether the setups have the
  ``accumulation`` option (deterministic fixed-point particle-to-grid sums);
- ``pst_f32``: the full baseline PST (100 m, dx 0.02 m, 3 s, float32), `cases._pst_row`;
- ``slope``: the paper's Fig. 13a slope (75 000 particles, 2 s), `cases.slope_row`;
- ``slope_1m``: the same slope at dx 0.05 m (1.2 M particles): cost per particle-step;
- ``repeat``: two baseline PSTs in one process: bitwise equal? max |slip difference|;
- ``pst_grad``: gradient / forward time of the baseline PST (`cases.pst_grad`);
- ``gradient_check``: `damjax.gradient_check` of the 20 m PST (softening 0 and 0.3) for
  four fields: all AD values finite, and AD within 10 % of the event-based slope;
- ``accumulation``: "fixed" against "float" on pst_f32 and the slope (time ratio), where
  the option exists;
- ``ensemble16``: 16 Fig. 13a members as one ensemble against 16 sequential runs
  (`benchmarks.ensemble16`'s parts);
- ``pst_f32_old``: the baseline PST of this checkout against the code of an older commit
  (``OLD_COMMIT``, the code of the 2026-11-26 H200 figures), alternated, each run in its
  own process: the old tree from ``DAMJAX_OLD_TREE`` (an export made with ``--prepare``)
  or else a ``git worktree``;
- ``sweep256``: `benchmarks.throughput`'s 256 baseline PSTs through `damjax.sweep`
  against one PST at a time;
- ``slope_large``: `benchmarks.throughput`'s 200 m x 200 m slope (4 M particles), one run
  and a 16-member ensemble, each timed over a window of steps and extrapolated to the
  14 100 steps (``DAMJAX_SLOPE_WINDOW``; ``python -m benchmarks slope_large`` alone runs
  every step on a GPU);
- ``real_path``: one member of the shipped scenario ``real-path-avakot`` (AvaFrame's
  documented avaKot release on its DEM, 1.9e5 particles, 3 s), every step timed: built from
  the scenario (needs the ``geo`` extra) or loaded from the member that ``--prepare`` built
  (``DIR/real_path_avakot.pkl.gz``, for a machine without the GIS packages);
- ``mpm88``: `benchmarks.mpm88`'s rows (3 to 200 particles per cell and the 2 x 2
  lattice) with Taichi on the same backend as the peer where taichi is importable;
- ``tests``: pytest on the GPU-relevant test files (every test, ``-v -rfE``, several
  workers with ``XLA_PYTHON_CLIENT_PREALLOCATE=false``; ``--log DIR`` keeps the output).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime
import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tarfile
import tempfile
import time
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

TEST_FILES = tuple(
    f"tests/test_{name}.py"
    for name in (
        "pst_physics",
        "slope",
        "jax_native",
        "runner",
        "ensemble",
        "differentiability",
        "sensitivity",
        "weak_layer",
        "slab_length_scale",
        "slab_fracture",
        "mcc",
    )
)
# --dry-run: a few fast tests of the same files (seconds on 2 CPU cores)
DRY_TESTS = (
    "tests/test_pst_physics.py::test_paired_complex_transfers_equal_the_real_ones",
    "tests/test_mcc.py::test_infinite_tensile_strength_is_exactly_elastic",
    "tests/test_ensemble.py::test_share_is_round_robin",
)
GRADIENT_FIELDS = ("strength_gradient", "youngs_modulus", "wl_shear_modulus", "tau_peak")


# ------------------------------------------------------------------ sizes


# the --dry-run PST, as keywords that older commits' PSTSetup / PSTParams also take (the
# baseline's L_ss of 20 m needs more than the toy's 8 m)
TOY_PST_SETUP = dict(length=8.0, dx=0.1, duration=0.05, chunk_steps=50)
TOY_PST_PARAMS = dict(steady_length=3.0)


@dataclasses.dataclass(frozen=True)
class Sizes:
    """What each part runs: the full figures, or toy sizes for --dry-run."""

    dry: bool

    def pst(self):  # noqa: ANN201 - damjax.PSTSetup
        from damjax import PSTSetup

        # 100 m, dx 0.02 m, 3 s: 40 000 steps
        return PSTSetup(**TOY_PST_SETUP) if self.dry else PSTSetup()

    def pst_params(self):  # noqa: ANN201 - damjax.PSTParams
        from damjax import PSTParams

        return PSTParams(**TOY_PST_PARAMS) if self.dry else PSTParams()

    def slope(self, dx: float | None = None):  # noqa: ANN201 - GenericSlopeCase
        from damjax.slope.generic import GenericSlopeCase

        if self.dry:
            return GenericSlopeCase(
                length=8.0,
                width=6.0,
                dx=0.3,
                duration=0.05,
                toe_length=2.0,
                roll_length=2.0,
                grf_length=2.0,
                start_window=(1.0, 3.0),
                particles_per_cell=1,
                chunk_steps=25,
            )
        if dx is None:
            # the timing case of `cases.slope`: 75 000 particles, 2 s (2 800 steps)
            return GenericSlopeCase(particles_per_cell=1, duration=2.0)
        # 1.2 M particles at dx 0.05 m; 0.5 s is enough for a steady cost per step
        return GenericSlopeCase(particles_per_cell=1, dx=dx, duration=0.5)

    def grad_duration(self) -> float:
        return 0.01 if self.dry else 3.0

    def gradient_case(self) -> tuple:
        """The 20 m PST of tests/test_sensitivity and the GPU NaN probe."""
        from damjax import PSTParams, PSTSetup

        if self.dry:
            # arrests in all three runs of the +-10 % window at softening 0 and 0.3
            setup = PSTSetup(length=10.0, dx=0.1, duration=0.8)
            return setup, PSTParams(steady_length=3.0, strength_gradient=3000.0), 3
        setup = PSTSetup(length=20.0, dx=0.05, duration=0.8)
        return setup, PSTParams(steady_length=5.0, strength_gradient=600.0), 11

    def ensemble(self) -> tuple[int, float]:
        return (2, 0.01) if self.dry else (16, 2.0)


# ------------------------------------------------------------------ parts (child side)


def _emit(**row: object) -> None:
    from benchmarks.cases import emit

    emit(**row)


def _accumulation_field() -> bool:
    """Whether this checkout's setups have the deterministic ``accumulation`` option."""
    from damjax import PSTSetup

    return "accumulation" in {f.name for f in dataclasses.fields(PSTSetup)}


@contextlib.contextmanager
def _slope_accumulation(mode: str | None) -> Iterator[None]:
    """Runs of `run_generic_slope` with ``SlopeSetup.accumulation = mode`` (None: default).
    `GenericSlopeCase` does not carry the option, so its `setup_of` is wrapped."""
    if mode is None:
        yield
        return
    from damjax.slope import generic

    original = generic.setup_of

    def setup_of(case, start):  # noqa: ANN001, ANN202 - the wrapped signature
        return dataclasses.replace(original(case, start), accumulation=mode)

    generic.setup_of = setup_of
    try:
        yield
    finally:
        generic.setup_of = original


def part_environment(sizes: Sizes) -> None:
    import jax

    dev = jax.devices()[0]
    _emit(
        case="environment",
        devices=[str(d) for d in jax.devices()],
        device_kind=getattr(dev, "device_kind", None),
        n_devices=len(jax.devices()),
        default_backend=jax.default_backend(),
        xla_flags=os.environ.get("XLA_FLAGS", ""),
        preallocate=os.environ.get("XLA_PYTHON_CLIENT_PREALLOCATE"),
        python=sys.version.split()[0],
        accumulation_option=_accumulation_field(),
        dry_run=sizes.dry,
    )


def part_pst_f32(sizes: Sizes) -> None:
    from benchmarks.cases import _pst_row

    row = _pst_row("pst_f32", sizes.pst_params(), sizes.pst())
    row["us_per_step"] = round(1e6 * row["wall_time_s"] / row["n_steps"], 2)
    _emit(**row)


def _slope_row(name: str, case, mode: str | None = None) -> dict:  # noqa: ANN001
    from benchmarks.cases import slope_row

    with _slope_accumulation(mode):
        row = slope_row(name, case)
    row["ns_per_particle_step"] = round(1e9 / row["particle_steps_per_s"], 3)
    return row


def part_slope(sizes: Sizes) -> None:
    _emit(**_slope_row("slope", sizes.slope()))


def part_slope_1m(sizes: Sizes) -> None:
    _emit(**_slope_row("slope_1m", sizes.slope(dx=0.05)))


def part_repeat(sizes: Sizes) -> None:
    import numpy as np

    from damjax import simulate_pst

    setup, params = sizes.pst(), sizes.pst_params()
    a, b = simulate_pst(params, setup), simulate_pst(params, setup)
    diffs = {
        k: float(np.max(np.abs(np.asarray(getattr(a, k)) - np.asarray(getattr(b, k)))))
        for k in ("slip", "sigma_xx", "tip")
    }
    _emit(
        case="repeat",
        n_particles=a.summary["n_particles"],
        n_steps=a.summary["n_steps"],
        dtype=setup.dtype,
        accumulation=getattr(setup, "accumulation", None),
        bitwise_equal=all(
            np.array_equal(np.asarray(getattr(a, k)), np.asarray(getattr(b, k)))
            for k in ("slip", "sigma_xx", "tip")
        ),
        max_abs_diff=diffs,
        arrest_position_m=[a.summary["arrest_position_m"], b.summary["arrest_position_m"]],
        wall_time_s=[a.summary["wall_time_s"], b.summary["wall_time_s"]],
    )


def part_pst_grad(sizes: Sizes) -> None:
    from benchmarks import cases

    os.environ["DAMJAX_BENCH_DURATION"] = str(sizes.grad_duration())
    cases.pst_grad()


def part_gradient_check(sizes: Sizes) -> None:
    import math

    from damjax import gradient_check

    setup, base, n_runs = sizes.gradient_case()
    for softening in (0.0, 0.3):
        params = dataclasses.replace(base, softening=softening)
        t0 = time.perf_counter()
        checks = gradient_check(params, setup, list(GRADIENT_FIELDS), tolerance=0.10, n_runs=n_runs)
        wall = time.perf_counter() - t0
        for c in checks:
            ad = [float(v) for v in c.ad_values]
            _emit(
                case="gradient_check",
                field=c.field,
                softening=softening,
                length=setup.length,
                dx=setup.dx,
                duration=setup.duration,
                n_runs=len(ad),
                all_finite=all(math.isfinite(v) for v in ad),
                n_nonfinite=sum(not math.isfinite(v) for v in ad),
                ad_mean=c.ad_mean,
                event_slope=c.event_slope,
                relative_error=c.relative_error,
                within_10_percent=bool(c.ok),
                ad_values=ad,
                arrests_m=[float(v) for v in c.arrests],
                wall_time_s_all_fields=round(wall, 2),
            )


def part_accumulation(sizes: Sizes) -> None:
    import jax

    from benchmarks.cases import _pst_row

    if not _accumulation_field():
        _emit(case="accumulation", skipped="PSTSetup has no 'accumulation' option here")
        return
    for name in ("pst_f32", "slope"):
        rows = {}
        for mode in ("fixed", "float"):
            if name == "pst_f32":
                setup = dataclasses.replace(sizes.pst(), accumulation=mode)
                rows[mode] = _pst_row(name, sizes.pst_params(), setup)
            else:
                rows[mode] = _slope_row(name, sizes.slope(), mode)
            jax.clear_caches()
        fixed, flt = rows["fixed"], rows["float"]
        _emit(
            case=f"accumulation_{name}",
            n_particles=fixed["n_particles"],
            n_steps=fixed["n_steps"],
            wall_time_s={"fixed": fixed["wall_time_s"], "float": flt["wall_time_s"]},
            compile_time_s={"fixed": fixed["compile_time_s"], "float": flt["compile_time_s"]},
            fixed_over_float=round(fixed["wall_time_s"] / flt["wall_time_s"], 3),
        )


def toy_ensemble(members: int, duration: float):  # noqa: ANN201 - damjax.ensemble.Ensemble
    """`benchmarks.ensemble16._ensemble` on an 8 m x 6 m piece of its slope (--dry-run)."""
    import warnings

    from benchmarks import ensemble16
    from damjax import ensemble, scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scn = scenario.load(ensemble16.SCENARIO).replace(
            setup={"duration": duration, "length": 8.0, "width": 6.0, "dx": 0.3},
            terrain={"toe_length": 2.0, "roll_length": 2.0},
            strength={"length_scale": 2.0, "mean_at": 1.0, "start_window": [1.0, 3.0]},
            output={"plot": False, "snapshots": False},
        )
    return ensemble.from_scenario(scn, {"seeds": list(range(members))}, members=members)


def part_ensemble16(sizes: Sizes) -> None:
    """`benchmarks.ensemble16`'s sequential and ensemble parts (the two-process part is a
    CPU question), each in its own process as there; the ratio as `ensemble16.rows`."""
    members, duration = sizes.ensemble()
    # --dry-run: the same parts on a small strip of the slope
    code = "import sys, benchmarks.ensemble16 as e; "
    if sizes.dry:
        code += "import benchmarks.gpu as g; e._ensemble = g.toy_ensemble; "
    code += "sys.exit(e.main(sys.argv[1:]))"
    out = []
    with tempfile.TemporaryDirectory(prefix="ensemble16-") as tmp:
        for part in ("sequential", "ensemble"):
            args = ["--part", part, "--members", str(members), "--duration", str(duration)]
            cmd = [sys.executable, "-c", code, *args, "--dir", tmp]
            res = subprocess.run(cmd, stdout=subprocess.PIPE, check=True, cwd=ROOT)
            out.append(json.loads(res.stdout.decode().strip().splitlines()[-1]))
    seq, ens = out
    ens["peer"] = f"{members} sequential simulate_slope"
    ens["peer_wall_time_s"] = seq["wall_time_s"]
    # (a toy run can round to 0 s)
    ens["ratio"] = round(seq["wall_time_s"] / ens["wall_time_s"], 3) if ens["wall_time_s"] else None
    ens["ratio_end_to_end"] = round(seq["end_to_end_s"] / ens["end_to_end_s"], 3)
    for row in out:
        _emit(**row)


# the code of the H200 figures of 2026-11-26 (baseline PST 1.23 s): `pst_f32_old`'s default
OLD_COMMIT = "f14d8a0"
OLD_ROUNDS = 2
# one baseline PST in the tree on PYTHONPATH: `benchmarks.cases._pst_row`, which both trees
# have; the sizes as JSON (null: the tree's own defaults, the baseline)
_OLD_CHILD = """
import json, sys
from benchmarks.cases import _pst_row
from damjax import PSTParams, PSTSetup
p, s = json.loads(sys.argv[1])
print(json.dumps(_pst_row("pst_f32", PSTParams(**(p or {})), PSTSetup(**(s or {})))))
"""


@contextlib.contextmanager
def _old_tree(dry: bool) -> Iterator[tuple[Path, str]]:
    """The older code's checkout and its commit: ``DAMJAX_OLD_TREE`` (its commit in the
    tree's ``COMMIT`` file, else ``DAMJAX_OLD_COMMIT``), else, on a --dry-run, this checkout
    (the mechanics only), else a temporary ``git worktree`` of ``DAMJAX_OLD_COMMIT``
    (default `OLD_COMMIT`)."""
    commit = os.environ.get("DAMJAX_OLD_COMMIT", OLD_COMMIT)
    given = os.environ.get("DAMJAX_OLD_TREE")
    if given:
        tree = Path(given).resolve()
        if not (tree / "damjax").is_dir() or not (tree / "benchmarks").is_dir():
            raise RuntimeError(
                f"DAMJAX_OLD_TREE = {given!r} has no damjax/ and benchmarks/ "
                "(make one with: python -m benchmarks.gpu --prepare DIR)"
            )
        stamp = tree / "COMMIT"
        yield tree, (stamp.read_text().strip() if stamp.is_file() else commit)
        return
    if dry:
        yield ROOT, "this checkout (dry run)"
        return
    from benchmarks.alternate import worktree

    try:
        with worktree(commit, prefix="damjax-old-") as tree:
            yield tree, commit
    except subprocess.CalledProcessError as e:
        raise RuntimeError(
            f"no checkout of {commit}: git worktree failed ({(e.stderr or '').strip()[-300:]}); "
            "set DAMJAX_OLD_TREE to an export (python -m benchmarks.gpu --prepare DIR)"
        ) from None


def _pst_in_tree(tree: Path, spec: str) -> dict:
    # the tree first; the rest of PYTHONPATH stays (a bare machine's wheels in /tmp/site)
    path = [str(tree), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = {**_child_env(False), "PYTHONPATH": os.pathsep.join(path)}
    res = subprocess.run(
        [sys.executable, "-c", _OLD_CHILD, spec], cwd=tree, env=env, capture_output=True, text=True
    )
    if res.returncode != 0:
        raise RuntimeError(f"the PST in {tree} failed: {res.stderr[-1500:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def part_pst_f32_old(sizes: Sizes) -> None:
    """The baseline PST of this checkout and of the older code, alternated (the order
    flips every round), each in its own process; a row per run and a summary row with the
    median times and ``new_over_old``."""
    import statistics

    spec = json.dumps([TOY_PST_PARAMS, TOY_PST_SETUP] if sizes.dry else [None, None])
    walls: dict[str, list[float]] = {"new": [], "old": []}
    with _old_tree(sizes.dry) as (old_tree, old_commit):
        trees = {"new": ROOT, "old": old_tree}
        rounds = 1 if sizes.dry else OLD_ROUNDS
        for r in range(rounds):
            for side in ("old", "new") if r % 2 == 0 else ("new", "old"):
                row = _pst_in_tree(trees[side], spec)
                walls[side].append(row["wall_time_s"])
                _emit(
                    **{**row, "case": "pst_f32_old_new_run"},
                    side=side,
                    code=old_commit if side == "old" else "this checkout",
                    round=r,
                )
    med = {k: statistics.median(v) for k, v in walls.items()}
    _emit(
        case="pst_f32_old_new",
        old_commit=old_commit,
        rounds=rounds,
        wall_time_s=med["new"],
        old_wall_time_s=med["old"],
        new_over_old=round(med["new"] / med["old"], 3) if med["old"] else None,
    )


def _throughput_env(sizes: Sizes, **values: str) -> None:
    """`benchmarks.throughput`'s settings: its toy sizes on a --dry-run, else ``values``
    where the environment does not set them."""
    if sizes.dry:
        os.environ["DAMJAX_BENCH_DRY_RUN"] = "1"
        return
    for k, v in values.items():
        os.environ.setdefault(k, v)


def part_sweep256(sizes: Sizes) -> None:
    from benchmarks import throughput

    _throughput_env(sizes)
    for row in throughput.sweep256_rows():
        _emit(**row)


def part_slope_large(sizes: Sizes) -> None:
    from benchmarks import throughput

    # a window of 800 steps of the 14 100 on a GPU: one run ~2 s on an H200, a slice of 8
    # members ~15 s (from 0.59 ns per particle-step), against ~35 s and ~5 min for every step
    # the ensemble of 16 members: two slices of up to 8 on one GPU
    _throughput_env(
        sizes,
        DAMJAX_SLOPE_EXTRAPOLATE="1",
        DAMJAX_SLOPE_WINDOW="4x200",
        DAMJAX_SLOPE_MEMBERS="16",
    )
    for row in throughput.slope_large_rows():
        _emit(**row)


REAL_PATH = "avaKot"
REAL_PATH_FILE = "real_path_avakot.pkl.gz"  # in the --prepare folder


def real_path_member(dry: bool = False) -> dict:
    """Member 0 of the shipped scenario of `REAL_PATH` (``dry``: `verification.real_path`'s
    toy version), built on this machine with ``accumulation = "fixed"`` (what "auto" picks
    on a GPU; "auto" would resolve to this machine's backend when the model is built): the
    model and state as NumPy trees, the chunk layout, and the build time [s]."""
    import warnings

    import jax
    import numpy as np

    from damjax import scenario
    from damjax.ensemble import batch as eb
    from damjax.ensemble.spec import from_scenario
    from verification import real_path

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if dry:
            scn = real_path.toy_scenario(REAL_PATH, Path(tempfile.mkdtemp(prefix="toy-path-")))
        else:
            scn = scenario.load(real_path.scenario_name(REAL_PATH))
        scn = dataclasses.replace(scn, setup=dataclasses.replace(scn.setup, accumulation="fixed"))
        ens = from_scenario(scn, members=1)
        layout = eb.shared_layout(ens)
        models, states, _ = eb._build_members(ens, [0], layout)
    model, state = jax.tree.map(lambda a: np.asarray(a[0]), (models, states))
    return dict(
        scenario=scn.name,
        dx=scn.setup.dx,
        duration_s=scn.setup.duration,
        chunk_steps=layout.chunk_steps,
        n_chunks=layout.n_chunks,
        n_steps=layout.n_steps,
        model=model,
        state=state,
        build_time_s=round(time.perf_counter() - t0, 3),
    )


def part_real_path(sizes: Sizes) -> None:
    """One member of the real path, every chunk timed after an ahead-of-time compile."""
    import gzip
    import pickle

    import jax
    import numpy as np

    from damjax.core.loop import compile_chunk, peak_bytes

    # DAMJAX_REAL_PATH_MEMBER: a member file of --prepare's (also on a --dry-run)
    given = os.environ.get("DAMJAX_REAL_PATH_MEMBER")
    carried = Path(given or ROOT / ".gpu-carry" / REAL_PATH_FILE)
    if given and not carried.is_file():
        raise FileNotFoundError(f"DAMJAX_REAL_PATH_MEMBER = {given!r}: no such file")
    if carried.is_file() and (given or not sizes.dry):
        with gzip.open(carried, "rb") as fh:
            member = pickle.load(fh)
        source = f"built by --prepare ({Path(carried).name})"
    else:
        member = real_path_member(sizes.dry)
        source = "built here"
    model, state = jax.tree.map(jax.numpy.asarray, (member["model"], member["state"]))
    n_particles = int(np.shape(state.opening)[-1])
    exe, compile_s = compile_chunk(model, state, member["chunk_steps"])
    t0 = time.perf_counter()
    for _ in range(member["n_chunks"]):
        out = exe(model, state)
        state = out[0] if isinstance(out, tuple) else out
    jax.block_until_ready(state)
    wall = time.perf_counter() - t0
    broken = np.isfinite(np.asarray(state.t_broken))
    _emit(
        case="real_path_member",
        path=REAL_PATH,
        scenario=member["scenario"],
        member_source=source,
        accumulation="fixed",
        dx=member["dx"],
        duration_s=member["duration_s"],
        n_particles=n_particles,
        n_steps=member["n_steps"],
        build_time_s=member["build_time_s"],
        compile_time_s=round(compile_s, 3),
        wall_time_s=round(wall, 3),
        us_per_step=round(1e6 * wall / member["n_steps"], 2),
        particle_steps_per_s=round(n_particles * member["n_steps"] / wall),
        peak_mib=None if peak_bytes(exe) is None else round(peak_bytes(exe) / 2**20, 1),
        released_area_m2=round(float(broken.sum()) * member["dx"] ** 2, 1),
        fault=int(np.asarray(state.fault)),
        time_s=float(np.asarray(state.time)),
    )


def part_mpm88(sizes: Sizes) -> None:
    from benchmarks import mpm88

    ti = mpm88.taichi_init(mpm88.n_threads())
    steps = 10 if sizes.dry else 100
    for n, repeats, layout in [(1024, 1, "random")] if sizes.dry else mpm88.CASE_ROWS:
        _emit(**mpm88.run_case(n, n_steps=steps, repeats=repeats, ti=ti, layout=layout))


PARTS: dict[str, Callable[[Sizes], None]] = {
    "environment": part_environment,
    "pst_f32": part_pst_f32,
    "slope": part_slope,
    "repeat": part_repeat,
    "pst_grad": part_pst_grad,
    "gradient_check": part_gradient_check,
    "accumulation": part_accumulation,
    "ensemble16": part_ensemble16,
    "slope_1m": part_slope_1m,
    "pst_f32_old": part_pst_f32_old,
    "sweep256": part_sweep256,
    "slope_large": part_slope_large,
    "real_path": part_real_path,
    "mpm88": part_mpm88,
    "tests": None,  # type: ignore[dict-item] # runs pytest from the parent (see _run_tests)
}
# --parts takes these names for their lists: the throughput and transfer figures, and the
# correctness checks; each fits one 10-minute command on one H100/H200
GROUPS: dict[str, tuple[str, ...]] = {
    "acceptance": (
        "environment",
        "pst_f32_old",
        "pst_grad",
        "sweep256",
        "slope_large",
        "mpm88",
    ),
    "checks": (
        "environment",
        "pst_f32",
        "slope",
        "repeat",
        "gradient_check",
        "accumulation",
        "ensemble16",
        "slope_1m",
        "real_path",
        "tests",
    ),
}
# the longest a part may take in the full run [s] (the tests get what is left)
PART_TIMEOUT = {
    "pst_grad": 150.0,  # two rounds of forward + gradient of 40 000 steps, two compilations
    "gradient_check": 150.0,
    "accumulation": 180.0,  # four runs, four compilations
    "ensemble16": 150.0,
    "slope_1m": 120.0,
    "pst_f32_old": 180.0,  # four baseline PSTs in their own processes, four compilations
    "sweep256": 240.0,  # 256 PSTs of 40 000 steps: a few seconds at 50 x, 5 min at 1 x
    "real_path": 90.0,  # one build (if not carried), one compilation, 2 200 steps
    "slope_large": 150.0,  # builds of 4 M-particle members, two compilations, two windows
    "mpm88": 150.0,  # five sizes, damjax twice and Taichi each
}


# ------------------------------------------------------------------ parent side


def _meta_fallback() -> dict:
    """What is known without starting JAX (for the error line of a failed part)."""
    from importlib import metadata

    def version(name: str) -> str | None:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return None

    return dict(device=None, platform=None, jax=version("jax"), jaxlib=version("jaxlib"))


def _git_commit() -> str | None:
    from benchmarks.cases import git_commit

    return git_commit()


def _child_meta() -> dict:
    import jax
    import jaxlib

    dev = jax.devices()[0]
    return dict(
        device=str(dev),
        platform=dev.platform,
        jax=jax.__version__,
        jaxlib=jaxlib.__version__,
    )


def _child(name: str, dry: bool) -> int:
    """Run one part in this process; its JSON rows on stdout, the metadata first."""
    print("GPU-META " + json.dumps(_child_meta()), flush=True)
    PARTS[name](Sizes(dry=dry))
    return 0


def _child_env(dry: bool) -> dict:
    env = dict(os.environ)
    path = [str(ROOT), *filter(None, [env.get("PYTHONPATH")])]
    env["PYTHONPATH"] = os.pathsep.join(path)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


def _run_group(cmd: list[str], env: dict, timeout: float) -> tuple[str, str, int | None]:
    """stdout, stderr and exit status of ``cmd`` (None: killed at ``timeout``, with every
    process it started: pytest workers, the parts' own subprocesses)."""
    proc = subprocess.Popen(
        cmd,
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        out, err = proc.communicate(timeout=timeout)
        return out, err, proc.returncode
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        return out, err, None


def _run_child(name: str, dry: bool, timeout: float) -> tuple[list[dict], dict, str | None]:
    """The rows a part printed, its metadata, and an error (None: it succeeded)."""
    cmd = [sys.executable, "-m", "benchmarks.gpu", "--run-part", name]
    if dry:
        cmd.append("--dry-run")
    stdout, stderr, rc = _run_group(cmd, _child_env(dry), timeout)
    rows, meta = [], {}
    for line in stdout.splitlines():
        if line.startswith("GPU-META "):
            meta = json.loads(line[len("GPU-META ") :])
            continue
        try:
            row = json.loads(line)
        except ValueError:
            sys.stderr.write(line + "\n")
            continue
        if isinstance(row, dict):
            rows.append(row)
    if rc is None:
        return rows, meta, f"timed out after {timeout:.0f} s; stderr: {stderr[-1500:]}"
    if rc != 0:
        return rows, meta, f"exit status {rc}; stderr: {stderr[-1500:]}"
    return rows, meta, None


def _run_tests(dry: bool, workers: int, timeout: float, log_dir: Path | None = None) -> dict:
    """pytest on the GPU-relevant files (several workers share one GPU: no preallocation).

    Every test runs (no ``-x``: one run names every failure); ``-v`` names a failure as it
    happens, so a run cut at ``timeout`` still says which failed, and ``-rfE`` puts each
    failure's message in the summary. pytest-benchmark (on some GPU images) is switched
    off: under xdist it warns once per worker and buries the summary. ``log_dir``: the
    whole output goes to ``log_dir/pytest.log``."""
    cmd = [sys.executable, "-m", "pytest", "-v", "-rfE", "--tb=short", "--durations=15"]
    cmd += ["-p", "no:cacheprovider", "-p", "no:benchmark"]
    if dry:
        cmd += ["-p", "no:xdist", *DRY_TESTS]
    else:
        if workers > 1:
            cmd += ["-n", str(workers)]
        cmd += list(TEST_FILES)
    env = _child_env(dry)
    env["XLA_PYTHON_CLIENT_PREALLOCATE"] = "false"
    t0 = time.perf_counter()
    stdout, stderr, rc = _run_group(cmd, env, timeout)
    out = stdout + stderr
    wall = time.perf_counter() - t0
    # the counts of pytest's last summary line ("3 failed, 170 passed, 6 skipped in 250s")
    if log_dir is not None:
        log_dir.mkdir(parents=True, exist_ok=True)
        (log_dir / "pytest.log").write_text(out)
    summary = [ln for ln in out.splitlines() if re.search(r"\d+ (passed|failed|error)", ln)]
    counts = {
        k: int(n)
        for n, k in re.findall(
            r"(\d+) (passed|failed|skipped|errors?|xfailed)", summary[-1] if summary else ""
        )
    }
    row = dict(
        case="tests",
        command=" ".join(cmd[1:]),
        returncode=rc,
        passed=counts.get("passed", 0),
        failed=counts.get("failed", 0),
        skipped=counts.get("skipped", 0),
        errors=counts.get("error", 0) + counts.get("errors", 0),
        wall_time_s=round(wall, 1),
    )
    if rc != 0:
        # "[gw3] [ 69%] FAILED tests/...::name" as it happens, "FAILED tests/...::name -
        # message" in the summary
        failed = re.findall(r"(?:^|\] )(?:FAILED|ERROR) (tests/\S+)", out, flags=re.M)
        row["failed_tests"] = list(dict.fromkeys(failed))
        row["failure_messages"] = re.findall(r"^(?:FAILED|ERROR) tests/\S+ - .*$", out, flags=re.M)
        row["output_tail"] = out[-3000:]
        if rc is None:
            row["error"] = f"timed out after {timeout:.0f} s"
        else:
            row["error"] = f"pytest exit status {rc}"
    return row


def _default_workers() -> int:
    try:
        import xdist  # noqa: F401
    except ImportError:
        return 0
    # the tests are compile-bound: 15 workers on 16 cores ran them in ~220 s on an H100
    return max(1, min(15, (os.cpu_count() or 2) - 1))


def run(
    parts: list[str],
    *,
    dry: bool,
    timeout: float,
    workers: int,
    jobs: int = 1,
    print_row: Callable[[dict], None] | None = None,
    log_dir: Path | None = None,
) -> list[dict]:
    """Run the parts within ``timeout`` seconds in all, ``jobs`` at a time; one or more
    rows each. ``log_dir``: where the tests part writes pytest's whole output."""
    print_row = print_row or (lambda r: print(json.dumps(r), flush=True))
    common = dict(
        date=datetime.date.today().isoformat(),
        commit=_git_commit(),
        dry_run=dry,
    )
    meta = _meta_fallback()
    deadline = time.monotonic() + timeout
    rows: list[dict] = []
    with contextlib.ExitStack() as stack:
        if dry and "JAX_COMPILATION_CACHE_DIR" not in os.environ:
            # toy sizes are compile-bound: the parts share the programs they have in common
            # (pst_f32 / repeat / accumulation, slope / slope_1m) through a private cache
            cache = stack.enter_context(tempfile.TemporaryDirectory(prefix="damjax-xla-"))
            stack.enter_context(
                _environ(
                    JAX_COMPILATION_CACHE_DIR=cache, JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0"
                )
            )
        if jobs <= 1:
            for name in parts:
                rows += _run_part(
                    name, dry, timeout, deadline, workers, meta, common, print_row, log_dir
                )
            return rows
        # parts side by side on one accelerator: none may take 75 % of its memory up front
        # (a part that did made the tests beside it fail on an H100, 2026-11-27)
        stack.enter_context(_environ(XLA_PYTHON_CLIENT_PREALLOCATE="false"))
        # several parts at once (--dry-run: toy sizes are compile-bound, one part per core);
        # rows are printed in the order of the parts
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = [
                pool.submit(
                    _run_part,
                    name,
                    dry,
                    timeout,
                    deadline,
                    workers,
                    meta,
                    common,
                    lambda r: None,
                    log_dir,
                )
                for name in parts
            ]
            for fut in futures:
                for row in fut.result():
                    rows.append(row)
                    print_row(row)
    return rows


@contextlib.contextmanager
def _environ(**values: str) -> Iterator[None]:
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run_part(
    name: str,
    dry: bool,
    timeout: float,
    deadline: float,
    workers: int,
    meta: dict,
    common: dict,
    print_row: Callable[[dict], None],
    log_dir: Path | None = None,
) -> list[dict]:
    """One part's rows (its error as a row); ``meta`` is updated from the child."""
    rows: list[dict] = []
    left = deadline - time.monotonic()
    t0 = time.perf_counter()
    if left < 5.0:
        got = [dict(case=name, error=f"not run: the --timeout of {timeout:.0f} s is spent")]
    elif name == "tests":
        got = [_run_tests(dry, workers, left, log_dir)]
    else:
        limit = left if dry else min(left, PART_TIMEOUT.get(name, 90.0))
        got, child_meta, error = _run_child(name, dry, limit)
        meta.update(child_meta)
        if error is not None:
            got.append(dict(case=name, error=error))
    elapsed = round(time.perf_counter() - t0, 1)
    for row in got:
        row = {"part": name, **row, **meta, **common, "part_time_s": elapsed}
        rows.append(row)
        print_row(row)
    return rows


# wheels a bare GPU machine lacks (its Python: 3.12): the mpm88 peer and its one missing
# dependency, and NetCDF output for the tests
WHEELS = ("taichi==1.7.4", "dill", "h5netcdf")
WHEEL_PLATFORMS = ("manylinux_2_27_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64")


def prepare(folder: Path, commit: str | None = None, python_version: str = "3.12") -> int:
    """Write ``folder/old`` (damjax/, benchmarks/ and pyproject.toml of the older commit,
    with a ``COMMIT`` file), ``folder/whl`` (`WHEELS` for ``python_version``) and
    ``folder/real_path_avakot.pkl.gz`` (`real_path_member`, needs the ``geo`` extra), then print
    the commands that run the figures on a machine whose checkout has ``folder`` in it."""
    commit = commit or os.environ.get("DAMJAX_OLD_COMMIT", OLD_COMMIT)
    old, whl = folder / "old", folder / "whl"
    if old.exists():
        shutil.rmtree(old)
    old.mkdir(parents=True)
    archive = subprocess.run(
        ["git", "archive", "--format=tar", commit, "damjax", "benchmarks", "pyproject.toml"],
        cwd=ROOT,
        capture_output=True,
    )
    if archive.returncode != 0:
        sys.stderr.write(f"git archive {commit} failed: {archive.stderr.decode()[-500:]}\n")
        return 1
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(old, filter="data")
    (old / "COMMIT").write_text(commit + "\n")
    cmd = [sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--only-binary=:all:"]
    cmd += ["--python-version", python_version, "--implementation", "cp", "-d", str(whl)]
    for plat in WHEEL_PLATFORMS:
        cmd += ["--platform", plat]
    if subprocess.run([*cmd, *WHEELS]).returncode != 0:
        sys.stderr.write("pip download failed; the older code is in place, the wheels are not\n")
        return 1
    # the real-path member, built here: the GPU machine may lack the GIS packages that read
    # its DEM and polygon
    import gzip
    import pickle

    member = real_path_member()
    with gzip.open(folder / REAL_PATH_FILE, "wb", compresslevel=6) as fh:
        pickle.dump(member, fh, protocol=pickle.HIGHEST_PROTOCOL)
    rel = os.path.relpath(folder.resolve(), ROOT)
    if rel.startswith(".."):
        sys.stderr.write(
            f"{folder} is outside the checkout {ROOT}: a machine that is sent the checkout "
            "does not get it (.gpu-carry/ in the checkout is ignored by git)\n"
        )
    size = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file()) / 2**20
    print(f"wrote {folder} ({size:.1f} MiB): {old} ({commit}), {whl}")
    print("on the GPU machine, in this checkout:")
    print(
        f"  python3 -m pip install -q --no-index --no-deps --target /tmp/site {rel}/whl/*.whl && "
        f"export PYTHONPATH=/tmp/site:$PWD DAMJAX_OLD_TREE=$PWD/{rel}/old "
        f"DAMJAX_COMMIT={_git_commit()}"
    )
    print("  python3 -m benchmarks gpu --parts acceptance --timeout 540   # then --parts checks")
    return 0


def _at_least_one(text: str) -> int:
    """An argparse type: an integer >= 1."""
    from benchmarks.cases import at_least

    return at_least(int, 1)(text)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks gpu", description=__doc__.split("\n")[0])
    p.add_argument("--dry-run", action="store_true", help="every part at toy size (CI)")
    p.add_argument("--no-tests", action="store_true", help="leave out the pytest part")
    p.add_argument(
        "--parts",
        default=None,
        help=f"comma-separated subset of {list(PARTS)}, or a group: {list(GROUPS)}",
    )
    p.add_argument(
        "--prepare",
        metavar="DIR",
        default=None,
        help="write what a bare GPU machine needs into DIR (old/: the older code; whl/: "
        "taichi, h5netcdf and dill wheels for Python 3.12; real_path_avakot.pkl.gz: the "
        "real-path member) and print the command to run there",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=None,
        help="seconds for all parts (default 480; --dry-run 300); parts beyond it are "
        "reported as not run",
    )
    p.add_argument("--workers", type=_at_least_one, default=None, help="pytest-xdist workers")
    p.add_argument(
        "--log",
        metavar="DIR",
        default=None,
        help="write pytest's whole output (the tests part) to DIR/pytest.log",
    )
    p.add_argument(
        "--jobs",
        type=_at_least_one,
        default=None,
        help="parts run at once (default 1; --dry-run: 2). Timings of parts that ran "
        "side by side are not figures",
    )
    p.add_argument("--run-part", default=None, help=argparse.SUPPRESS)
    ns = p.parse_args(argv)
    if ns.run_part is not None:
        return _child(ns.run_part, ns.dry_run)
    if ns.prepare is not None:
        return prepare(Path(ns.prepare))
    parts = list(PARTS) if ns.parts is None else []
    for name in [] if ns.parts is None else [s for s in ns.parts.split(",") if s]:
        parts += [n for n in GROUPS.get(name, (name,)) if n not in parts]
    unknown = [n for n in parts if n not in PARTS]
    if unknown:
        p.error(f"unknown part(s) {unknown}; choose from {list(PARTS)} or {list(GROUPS)}")
    if not parts:
        p.error(f"--parts names no part; choose from {list(PARTS)} or {list(GROUPS)}")
    if ns.timeout is not None and not ns.timeout > 0:
        p.error(f"--timeout = {ns.timeout}: must be a number of seconds > 0")
    if ns.no_tests:
        parts = [n for n in parts if n != "tests"]
    timeout = ns.timeout if ns.timeout is not None else (300.0 if ns.dry_run else 480.0)
    workers = _default_workers() if ns.workers is None else ns.workers
    jobs = ns.jobs if ns.jobs is not None else (2 if ns.dry_run else 1)
    log_dir = None if ns.log is None else Path(ns.log)
    rows = run(parts, dry=ns.dry_run, timeout=timeout, workers=workers, jobs=jobs, log_dir=log_dir)
    return 1 if any("error" in r for r in rows) else 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except Exception:  # a child part: the traceback on stderr for the parent's error line
        traceback.print_exc()
        sys.exit(1)
