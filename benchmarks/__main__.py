"""Run benchmark cases, each in its own process (clean peak-RSS figures).

    python -m benchmarks                 # every case
    python -m benchmarks pst_f32 mpm88   # some cases
    python -m benchmarks --list
    python -m benchmarks gpu [--dry-run] # the prepared GPU check (benchmarks/gpu.py)
    python -m benchmarks sweep256 slope_large --dry-run  # toy sizes of these cases
    python -m benchmarks --dry-run       # every case that has toy sizes (DRY_RUN_CASES)

Each case prints one JSON object per line on stdout.
"""

from __future__ import annotations

import os
import subprocess
import sys

from benchmarks.cases import CASES

# commands with options of their own (not cases): name -> module run as ``python -m``
COMMANDS = {"gpu": "benchmarks.gpu"}
# cases with toy sizes under --dry-run (they read DAMJAX_BENCH_DRY_RUN); the others would
# run at full size, so --dry-run refuses them
DRY_RUN_CASES = ("sweep256", "slope_large")


def main(argv: list[str]) -> int:
    if argv and argv[0] in COMMANDS:
        return subprocess.run([sys.executable, "-m", COMMANDS[argv[0]], *argv[1:]]).returncode
    if "-h" in argv or "--help" in argv:
        print(__doc__.strip())
        print(f"\ncases: {', '.join(CASES)}; commands: {', '.join(COMMANDS)}")
        return 0
    if "--list" in argv:
        for name, fn in CASES.items():
            print(f"{name:16s} {(fn.__doc__ or '').strip().splitlines()[0]}")
        print(f"{'gpu':16s} GPU tests and figures in one command (python -m benchmarks gpu -h)")
        return 0
    env = None
    if "--dry-run" in argv:  # toy sizes, for cases that read DAMJAX_BENCH_DRY_RUN
        argv = [a for a in argv if a != "--dry-run"]
        env = {**os.environ, "DAMJAX_BENCH_DRY_RUN": "1"}
    names = argv or list(DRY_RUN_CASES if env else CASES)
    unknown = [n for n in names if n not in CASES]
    if unknown:
        sys.stderr.write(f"unknown case(s) {unknown}; choose from {list(CASES)}\n")
        return 2
    full_size = [n for n in names if env and n not in DRY_RUN_CASES]
    if full_size:
        sys.stderr.write(
            f"--dry-run: {full_size} have no toy sizes (they would run at full size); "
            f"cases with a dry run: {list(DRY_RUN_CASES)}, and `gpu --dry-run`\n"
        )
        return 2
    rc = 0
    for name in names:
        proc = subprocess.run([sys.executable, "-m", "benchmarks.cases", name], env=env)
        rc = rc or proc.returncode
    return rc


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
