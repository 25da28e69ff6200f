"""Benchmark cases of two commits, alternated in one run.

    python -m benchmarks.alternate --old f14d8a0 --cases pst_f32 slope --rounds 3

Each round runs every case once with the old commit's code and once with this working
tree's (the order flips every round, so a drift of the machine's load hits both alike),
each in its own process: ``python -m benchmarks CASE`` with ``PYTHONPATH`` pointing at
the tree. The old commit is checked out with ``git worktree`` into a temporary folder
(removed afterwards). One JSON row per run, then one summary row per case: the median
``wall_time_s`` (the time loop; the case's own field) and the child's CPU time
(user + system) of each side, and new / old ratios of both. On a machine shared with
other jobs the CPU-time ratio is the steadier figure.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_case(tree: Path, case: str, env: dict[str, str]) -> dict[str, Any]:
    """One ``python -m benchmarks CASE`` in ``tree``: its last JSON row with the run's
    wall and CPU time [s] of the whole process added."""
    env = {**env, "PYTHONPATH": str(tree)}
    cpu0, t0 = _child_cpu(), time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "benchmarks", case],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
    )
    wall, cpu = time.perf_counter() - t0, _child_cpu() - cpu0
    rows = [json.loads(x) for x in proc.stdout.splitlines() if x.startswith("{")]
    if proc.returncode != 0 or not rows:
        raise RuntimeError(
            f"{case} in {tree} failed (exit {proc.returncode}):\n{proc.stderr[-2000:]}"
        )
    row = rows[-1]
    row.update(process_wall_s=round(wall, 2), process_cpu_s=round(cpu, 2))
    return row


def _short(rev: str, cwd: Path) -> str:
    return subprocess.run(
        ["git", "rev-parse", "--short", rev], cwd=cwd, capture_output=True, text=True, check=True
    ).stdout.strip()


@contextlib.contextmanager
def worktree(commit: str, prefix: str = "damjax-alternate-") -> Iterator[Path]:
    """A temporary ``git worktree`` of ``commit`` (removed afterwards); CalledProcessError
    when git cannot make one (no repository, unknown commit)."""
    tmp = Path(tempfile.mkdtemp(prefix=prefix))
    tree = tmp / "tree"
    try:
        subprocess.run(
            ["git", "worktree", "add", "--detach", str(tree), commit],
            cwd=ROOT,
            check=True,
            capture_output=True,
            text=True,
        )
        yield tree
    finally:
        subprocess.run(
            ["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT, capture_output=True
        )
        shutil.rmtree(tmp, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    from benchmarks.cases import CASES, at_least

    ap = argparse.ArgumentParser(
        prog="python -m benchmarks alternate", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--old", required=True, help="the commit to compare with (any git revision)")
    ap.add_argument("--cases", nargs="+", default=["pst_f32"], help="benchmark cases")
    ap.add_argument("--rounds", type=at_least(int, 1), default=3, help="alternations (>= 1)")
    args = ap.parse_args(argv)
    unknown = [c for c in args.cases if c not in CASES]
    if unknown:
        ap.error(f"--cases: unknown case(s) {unknown}; choose from {list(CASES)}")
    try:
        old = _short(args.old, ROOT)
    except subprocess.CalledProcessError:
        ap.error(f"--old {args.old}: not a revision of this repository (git rev-parse)")
    new = _short("HEAD", ROOT)
    dirty = bool(
        subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=ROOT,
            capture_output=True,
            text=True,
        ).stdout.strip()
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    results: dict[tuple[str, str], list[dict[str, Any]]] = {}
    with worktree(old) as old_tree:
        sides = {"old": old_tree, "new": ROOT}
        for r in range(args.rounds):
            order = ("old", "new") if r % 2 == 0 else ("new", "old")
            for case in args.cases:
                for side in order:
                    row = run_case(sides[side], case, env)
                    row.update(side=side, commit=old if side == "old" else new, round=r)
                    if side == "new":
                        row["dirty"] = dirty
                    print(json.dumps(row), flush=True)
                    results.setdefault((case, side), []).append(row)
    for case in args.cases:
        summ: dict[str, Any] = dict(
            case=f"alternate_{case}", old=old, new=new, dirty=dirty, rounds=args.rounds
        )
        for key in ("wall_time_s", "process_cpu_s"):
            med = {}
            for side in ("old", "new"):
                vals = [row[key] for row in results[(case, side)] if row.get(key) is not None]
                med[side] = statistics.median(vals) if vals else None
                summ[f"{side}_{key}"] = None if med[side] is None else round(med[side], 3)
            if med["old"] and med["new"] is not None:
                summ[f"new_over_old_{key}"] = round(med["new"] / med["old"], 3)
        print(json.dumps(summ), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
