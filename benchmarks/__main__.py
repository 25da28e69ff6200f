"""Timing cases of damjax, each run in its own process (clean peak-memory figures).

    python -m benchmarks                 # the list of cases and commands (runs nothing)
    python -m benchmarks pst_f32 mpm88   # some cases, one JSON row per line on stdout
    python -m benchmarks sweep256 slope_large --dry-run  # toy sizes of these cases
    python -m benchmarks gpu [--dry-run] # a command with options of its own (-h for them)
    python -m benchmarks mpm88 --n 4096  # a case with options of its own (mpm88, ensemble16)

Nothing runs unless named. The verification scripts, which feed the documentation's
verification pages and figures, are in verification/ (``python -m verification``).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys

from benchmarks.cases import CASES

# commands with options of their own (not cases): name -> module run as ``python -m``
COMMANDS = {
    "gpu": "benchmarks.gpu",
    "alternate": "benchmarks.alternate",
    "cli_startup": "benchmarks.cli_startup",
    "slab_fracture_timing": "benchmarks.slab_fracture_timing",
}
# cases that take options of their own: ``python -m benchmarks mpm88 --n 4096`` (or -h)
# runs the module with them
CASE_OPTIONS = {"mpm88": "benchmarks.mpm88", "ensemble16": "benchmarks.ensemble16"}
# cases with toy sizes under --dry-run (they read DAMJAX_BENCH_DRY_RUN); the others would
# run at full size, so --dry-run refuses them
DRY_RUN_CASES = ("sweep256", "slope_large", "real_path_member")


def _first_line(doc: str | None) -> str:
    return " ".join((doc or "").strip().split("\n\n")[0].split())


def listing() -> str:
    """One line per case, then one per command."""
    lines = ["cases (python -m benchmarks CASE ...):"]
    lines += [f"  {name:21s} {_first_line(fn.__doc__)}" for name, fn in CASES.items()]
    lines.append("commands (python -m benchmarks COMMAND -h for their options):")
    for name, module in COMMANDS.items():  # the docstring, without importing the module
        path = os.path.join(os.path.dirname(__file__), module.split(".")[-1] + ".py")
        with open(path, encoding="utf-8") as fh:
            doc = ast.get_docstring(ast.parse(fh.read()))
        lines.append(f"  {name:21s} {_first_line(doc)}")
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if argv and argv[0] in COMMANDS:
        return subprocess.run([sys.executable, "-m", COMMANDS[argv[0]], *argv[1:]]).returncode
    if argv and argv[0] in CASE_OPTIONS and any(a.startswith("-") for a in argv[1:]):
        module = CASE_OPTIONS[argv[0]]
        return subprocess.run([sys.executable, "-m", module, *argv[1:]]).returncode
    if "-h" in argv or "--help" in argv:
        print((__doc__ or "").strip() + "\n")
    if not argv or {"--list", "-h", "--help"} & set(argv):
        print(listing())
        return 0
    env = None
    if "--dry-run" in argv:  # toy sizes, for cases that read DAMJAX_BENCH_DRY_RUN
        argv = [a for a in argv if a != "--dry-run"]
        env = {**os.environ, "DAMJAX_BENCH_DRY_RUN": "1"}
    if not argv:  # nothing runs unless named
        sys.stderr.write(
            f"--dry-run: name the cases to run at toy size (of {list(DRY_RUN_CASES)}), e.g. "
            "python -m benchmarks sweep256 --dry-run\n"
        )
        return 2
    names = argv
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
