"""``damjax ensemble SCENARIO --members N [--out DIR] [--json] [--quiet]`` (and ``python
-m damjax.ensemble``): flags, the run, the printed summary."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import jax

from damjax import distributed, io
from damjax._commands import add_set_flag, dispatch
from damjax.ensemble.batch import run
from damjax.ensemble.products import ENSEMBLE_FILE, FIGURE, QUANTILE_KEYS, SUMMARY_FILE
from damjax.ensemble.spec import load

DESCRIPTION = "Release-probability ensemble of a slope scenario (damjax.ensemble)."


def add_arguments(p: Any) -> None:
    """The flags of ``damjax ensemble`` on an argparse parser."""
    p.add_argument("scenario", help="slope scenario: TOML file or shipped name")
    add_set_flag(p)
    p.add_argument(
        "--members",
        type=int,
        default=None,
        metavar="N",
        help="member count (default: ensemble.members of the file)",
    )
    p.add_argument(
        "--out", metavar="DIR", help="output folder (default ./damjax-out/<name>-ensemble)"
    )
    p.add_argument("--json", action="store_true", help="print the summary as one JSON line")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no log lines")
    p.add_argument(
        "--slice-size",
        type=int,
        default=None,
        metavar="K",
        help="members per slice (default: on CPU one per device; otherwise the most that "
        "fit half the free memory, measured on the compiled step, at most 8 per device)",
    )
    p.add_argument("--no-plot", action="store_true", help="do not write ensemble.png")
    p.add_argument(
        "--cpu-devices",
        type=int,
        default=None,
        metavar="D",
        help="on CPU: split the host into D devices, each running its own members "
        "(default: one per core this process may use; 1 with several processes)",
    )
    g = p.add_argument_group("several processes (jax.distributed)")
    g.add_argument(
        "--distributed",
        action="store_true",
        help="join a detected cluster job (SLURM, Open MPI): one process per task",
    )
    g.add_argument("--coordinator", metavar="HOST:PORT", help="process 0's address (manual)")
    g.add_argument("--num-processes", type=int, metavar="P", help="process count (manual)")
    g.add_argument("--process-id", type=int, metavar="I", help="this process, 0..P-1 (manual)")


def _set_cpu_devices(n: int | None) -> None:
    """Split the CPU into ``n`` devices (None: one per core this process may use) if JAX
    has not started its backends yet; afterwards the devices stay as they are. Only the
    CPU backend is affected (a GPU run keeps its GPUs)."""
    if n is None:
        n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    try:
        from jax._src import xla_bridge

        if xla_bridge.backends_are_initialized():
            return
    except (ImportError, AttributeError):  # pragma: no cover - another JAX layout
        pass
    try:
        jax.config.update("jax_num_cpu_devices", max(1, int(n or 1)))
    except Exception:  # noqa: BLE001 - backends already started: keep their devices
        pass


def command(ns: Any) -> int:
    """Run ``damjax ensemble`` from parsed flags; returns the exit status (ValueError on
    bad input, one line per problem)."""
    import sys

    if ns.members is not None and ns.members < 1:
        raise ValueError(f"--members = {ns.members}: must be an integer >= 1")
    if ns.slice_size is not None and ns.slice_size < 1:
        raise ValueError(f"--slice-size = {ns.slice_size}: must be an integer >= 1")
    if ns.cpu_devices is not None and ns.cpu_devices < 1:
        raise ValueError(f"--cpu-devices = {ns.cpu_devices}: must be an integer >= 1")
    manual = (ns.coordinator, ns.num_processes, ns.process_id)
    several = ns.distributed or any(v is not None for v in manual)
    _set_cpu_devices(ns.cpu_devices if ns.cpu_devices is not None else 1 if several else None)
    if any(v is not None for v in manual):
        if ns.distributed:
            raise ValueError("--distributed: detects the cluster; leave out --coordinator etc.")
        if any(v is None for v in manual):
            raise ValueError("--coordinator, --num-processes and --process-id: give all three")
        distributed.initialize(ns.coordinator, ns.num_processes, ns.process_id)
    elif ns.distributed:
        distributed.initialize()
    ens = load(ns.scenario, members=ns.members, sets=getattr(ns, "set", None) or ())
    out = Path(ns.out) if ns.out else Path("damjax-out") / f"{ens.scenario.name}-ensemble"
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a folder")
    log = None if ns.quiet else (lambda msg: print(f"damjax: {msg}", file=sys.stderr))
    ds = run(
        ens, out, slice_size=ns.slice_size, plot=not ns.no_plot, progress=not ns.quiet, log=log
    )
    if distributed.process_index() != 0:
        return 0
    summary = json.loads(ds.attrs["run_summary"])
    quantiles = [f"{name}_quantiles" for name in QUANTILE_KEYS]
    if ns.json:
        keys = ("members", "upslope_arrested_members", *quantiles, "wall_time_s")
        print(io.to_json({**{k: summary[k] for k in keys}, "out_dir": str(out)}))
    else:
        for name in quantiles:
            q = summary[name]
            print(
                f"{name:38s} "
                + "  ".join(f"{k} {'n/a' if v is None else format(v, '.4g')}" for k, v in q.items())
            )
        print(f"{'members':38s} {summary['members']}")
        print(f"{'upslope_arrested_members':38s} {summary['upslope_arrested_members']}")
        print(f"{'wall_time_s':38s} {summary['wall_time_s']:.1f}")
        for f in (ENSEMBLE_FILE, FIGURE, SUMMARY_FILE):
            if (out / f).is_file():
                print(f"{f:38s} {out / f}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m damjax.ensemble`` (the same as ``damjax ensemble``)."""
    from damjax._commands import Parser

    p = Parser(prog="damjax ensemble", description=DESCRIPTION)
    add_arguments(p)
    try:
        ns = p.parse_args(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2
    return dispatch(
        command, ns, "damjax: interrupted (finished slices are kept; run again to resume)"
    )
