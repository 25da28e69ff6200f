"""Start-up cost of the command line: `damjax run quick` against `python -c "import jax"`.

    python -m benchmarks.cli_startup                 # 5 rounds
    python -m benchmarks.cli_startup --rounds 3 --scenario quick

Everything runs as child processes of this one, on one machine, so the two figures are
comparable: a bare ``python -c "import jax"``; ``damjax run SCENARIO`` once with an empty
persistent compilation cache (``DAMJAX_CACHE_DIR`` set to a fresh folder: the cold run
fills it), then ``--rounds`` times with that cache warm, alternating with
``import jax`` so that a change in the machine's load hits both. Each run writes into its
own fresh output folder (results.nc, summary.json, the figure, as a user's run does).

Prints JSON lines: one per timed process (``what``: ``import_jax``, ``run_cold``,
``run_warm``), then a summary line with the medians, the difference warm run - import jax
(``over_import_jax_s``, the 2 s line: ``target_met``) and the warm run's phases
(medians over the rounds): ``python_and_imports_s`` (interpreter start, ``import
damjax.cli`` and what it imports, from the child's own clock at process start),
the phases the CLI records in ``summary.json`` (``phases_s``: ``scenario_s`` loading and
checking the file, ``layout_s``, ``simulate_s`` = ``compile_time_s`` (compilation or
cache load of the time loop) + ``wall_time_s`` (the loop) + ``build_and_host_s``
(validation, building the model, host diagnostics), ``results_file_s`` (results.nc,
final state), ``figure_s``), ``exit_s`` (from the end of the CLI's main to the process's
exit as the parent sees it: the console script skips the interpreter's teardown, see
`damjax.cli.exit_fast`) and the machine's 1-minute load average (other work on it
inflates every figure).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

_PROBE = (
    "import os, time, json, sys\n"
    "t_main = time.time()\n"
    "from damjax import cli\n"
    "t_imported = time.time()\n"
    "rc = cli.main(sys.argv[1:])\n"
    "t_done = time.time()\n"
    "with open(os.environ['DAMJAX_STARTUP_PROBE'], 'w') as f:\n"
    "    json.dump({'main': t_main, 'imported': t_imported, 'done': t_done}, f)\n"
    "cli.exit_fast(rc)\n"  # as the damjax console script ends
)


def _timed(cmd: list[str], env: dict[str, str]) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    return wall, proc


def _emit(**row: Any) -> None:
    from benchmarks.cases import emit

    emit(**row)


def _run_damjax(
    scenario: str, out: Path, env: dict[str, str], probe: Path
) -> tuple[float, dict[str, Any]]:
    """One `damjax run` in a child process: wall time seen from here, and its phases."""
    env = dict(env, DAMJAX_STARTUP_PROBE=str(probe))
    cmd = [sys.executable, "-c", _PROBE, "run", scenario, "--out", str(out), "--quiet", "--json"]
    t_launch = time.time()
    wall, proc = _timed(cmd, env)
    t_end = t_launch + wall
    marks = json.loads(probe.read_text())
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    phases = dict(summary.get("phases_s") or {})
    if "simulate_s" in phases and summary.get("compile_time_s") is not None:
        phases["build_and_host_s"] = (
            phases["simulate_s"] - summary["compile_time_s"] - summary["wall_time_s"]
        )
    row = {
        "wall_s": round(wall, 3),
        "python_and_imports_s": round(marks["imported"] - t_launch, 3),
        "import_damjax_cli_s": round(marks["imported"] - marks["main"], 3),
        "cli_main_s": round(marks["done"] - marks["imported"], 3),
        "exit_s": round(t_end - marks["done"], 3),
        "phases_s": {k: round(float(v), 3) for k, v in phases.items()},
        "compile_time_s": summary.get("compile_time_s"),
        "wall_time_s": summary.get("wall_time_s"),
    }
    return wall, row


def main(argv: list[str] | None = None) -> int:
    from benchmarks.cases import at_least

    ap = argparse.ArgumentParser(
        prog="python -m benchmarks cli_startup",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--rounds", type=at_least(int, 1), default=5, help="warm rounds (default 5)")
    ap.add_argument("--scenario", default="quick", help="scenario to run (default quick)")
    args = ap.parse_args(argv)
    from damjax import scenario

    if args.scenario not in scenario.shipped() and not Path(args.scenario).is_file():
        ap.error(
            f"--scenario {args.scenario}: no shipped scenario or file of that name "
            f"(shipped: {', '.join(scenario.shipped())})"
        )

    tmp = Path(tempfile.mkdtemp(prefix="damjax-startup-"))
    env = dict(os.environ, DAMJAX_CACHE_DIR=str(tmp / "cache"), PYTHONUNBUFFERED="1")
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    try:
        jax_cmd = [sys.executable, "-c", "import jax"]
        _timed(jax_cmd, env)  # page cache warm for both
        wall, row = _run_damjax(args.scenario, tmp / "cold", env, tmp / "probe.json")
        _emit(case="cli_startup", what="run_cold", scenario=args.scenario, **row)
        imports, warms, rows = [], [], []
        for i in range(args.rounds):
            t, _ = _timed(jax_cmd, env)
            imports.append(t)
            _emit(case="cli_startup", what="import_jax", round=i, wall_s=round(t, 3))
            wall, row = _run_damjax(args.scenario, tmp / f"warm{i}", env, tmp / "probe.json")
            warms.append(wall)
            rows.append(row)
            _emit(case="cli_startup", what="run_warm", scenario=args.scenario, round=i, **row)

        def med(key: str) -> float:
            return round(statistics.median(r[key] for r in rows), 3)

        names = sorted({k for r in rows for k in r["phases_s"]})
        phases = {
            k: round(statistics.median(r["phases_s"].get(k, 0.0) for r in rows), 3) for k in names
        }
        over = statistics.median(warms) - statistics.median(imports)
        _emit(
            case="cli_startup",
            what="summary",
            scenario=args.scenario,
            rounds=args.rounds,
            import_jax_s=round(statistics.median(imports), 3),
            run_warm_s=round(statistics.median(warms), 3),
            over_import_jax_s=round(over, 3),
            target_s=2.0,
            target_met=bool(over <= 2.0),
            python_and_imports_s=med("python_and_imports_s"),
            import_damjax_cli_s=med("import_damjax_cli_s"),
            cli_main_s=med("cli_main_s"),
            exit_s=med("exit_s"),
            phases_s=phases,
            python=sys.version.split()[0],
            cpus=os.cpu_count(),
            load_average_1min=round(os.getloadavg()[0], 2),  # other work on the machine
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
