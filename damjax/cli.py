"""Command line: ``damjax pst [--flag value ...] [--json] [--plot FILE]``.

Bad input exits with status 2 and one line per problem (flag, value, valid range);
never a traceback.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import warnings
from typing import Any

from damjax.config import PSTParams, PSTSetup

_PARAM_FIELDS = [f.name for f in dataclasses.fields(PSTParams)]
_SETUP_FIELDS = [
    "length",
    "dx",
    "duration",
    "lateral",
    "cfl",
    "particles_per_cell",
    "dtype",
    "chunk_steps",
    "dim",
    "width",
]
_INT_FIELDS = {"particles_per_cell", "chunk_steps", "dim"}
_STR_FIELDS = {"lateral", "dtype"}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2, no usage dump
        sys.stderr.write(f"damjax: error: {message}\n")
        sys.exit(2)


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _enable_compilation_cache() -> None:
    """Persistent XLA cache: repeated CLI runs skip most of the compilation."""
    import jax

    path = os.environ.get(
        "DAMJAX_CACHE_DIR", os.path.join(os.path.expanduser("~"), ".cache", "damjax", "xla")
    )
    try:
        os.makedirs(path, exist_ok=True)
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    except Exception:  # pragma: no cover - cache is an optimisation only
        pass


def _add_pst_flags(p: argparse.ArgumentParser) -> None:
    defaults_p, defaults_s = PSTParams(), PSTSetup()
    g = p.add_argument_group("physical parameters (SI units; defaults: paper baseline)")
    for name in _PARAM_FIELDS:
        g.add_argument(
            "--" + name.replace("_", "-"),
            dest=name,
            type=_number,
            default=getattr(defaults_p, name),
            help=f"default {getattr(defaults_p, name)}",
        )
    g = p.add_argument_group("numerics")
    for name in _SETUP_FIELDS:
        typ = str if name in _STR_FIELDS else _number
        g.add_argument(
            "--" + name.replace("_", "-"),
            dest=name,
            type=typ,
            default=getattr(defaults_s, name),
            help=f"default {getattr(defaults_s, name)}",
        )
    g.add_argument(
        "--controlled",
        action="store_true",
        help="unbreakable weak layer cut at --saw-speed for the whole run",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="FILE", help="write the PST figure (PNG/PDF)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _setup_from(ns: argparse.Namespace) -> PSTSetup:
    kw: dict[str, Any] = {}
    for name in _SETUP_FIELDS:
        v = getattr(ns, name)
        if name in _INT_FIELDS and isinstance(v, float) and math.isfinite(v) and v.is_integer():
            v = int(v)
        kw[name] = v
    return PSTSetup(controlled=ns.controlled, **kw)


def _print_summary(summary: dict[str, Any]) -> None:
    for k, v in summary.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        print(f"{k:34s} {v}")


def cmd_pst(ns: argparse.Namespace) -> int:
    from damjax.scenarios.pst import simulate_pst

    params = PSTParams(**{name: getattr(ns, name) for name in _PARAM_FIELDS})
    setup = _setup_from(ns)
    _enable_compilation_cache()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = simulate_pst(params, setup, progress=not ns.quiet)
    for w in caught:
        if issubclass(w.category, UserWarning):
            sys.stderr.write(f"damjax: warning: {w.message}\n")
    if ns.plot:
        from damjax.plot import plot_pst

        plot_pst(result, ns.plot)
    if ns.json:
        print(json.dumps(result.summary))
    else:
        _print_summary(result.summary)
        if ns.plot:
            print(f"{'plot':34s} {ns.plot}")
    if result.fault:
        sys.stderr.write(f"damjax: {result.fault}\n")
        return 3
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="damjax", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    p = sub.add_parser("pst", help="run a propagation saw test")
    _add_pst_flags(p)
    p.set_defaults(func=cmd_pst)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    ns = parser.parse_args(argv)
    try:
        return ns.func(ns)
    except ValueError as exc:  # validation: one line per problem
        for line in str(exc).splitlines():
            sys.stderr.write(f"damjax: error: {line}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("damjax: interrupted\n")
        return 130


if __name__ == "__main__":
    sys.exit(main())
