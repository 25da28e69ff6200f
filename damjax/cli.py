"""Command line: ``damjax pst|scenarios|run|resume|show|ensemble|export`` (``damjax CMD --help``).

``damjax pst [--flag value ...] [--json] [--plot FILE]`` runs a PST from flags (or from a
snow profile: ``--profile FILE --weak-layer N``). Scenario
files: ``damjax scenarios`` (list the shipped ones), ``damjax run SCENARIO
[--out DIR] [--json] [--quiet] [--checkpoint-every SECONDS]``, ``damjax resume DIR``,
``damjax show DIR``; ``damjax ensemble SCENARIO --members N [--out DIR] [--json] [--quiet]``
(`damjax.ensemble`); ``damjax export RUN_DIR --to gis|avaframe OUT`` (`damjax.export`).

Bad input exits with status 2 and one line per problem (flag or TOML key, value, valid
range); never a traceback. A runtime fault exits with status 3 after writing the results
up to it; an interrupt with status 130, SIGTERM (``kill``, a scheduler's time limit) with
143, both after writing a checkpoint where the run takes them.

One module (~650 lines) on purpose: one argparse parser, and per subcommand a thin
function that parses, calls the module doing the work and prints; splitting it would
spread one parser's flags over several files.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import signal
import sys
import threading
import warnings
from typing import Any, NoReturn

from damjax._commands import Parser as _Parser
from damjax._commands import add_set_flag as _add_set_flag
from damjax._commands import dispatch
from damjax.params import PSTParams, PSTSetup, Spec, specs

# the flags of `damjax pst`: the fields whose declarations say so (`damjax.params`); the
# strength profile's flag reads a CSV (`--strength-profile FILE.csv`)
_PARAM_FLAGS = [s for s in specs(PSTParams).values() if s.cli and s.kind != "profile"]
_SETUP_FLAGS = [s for s in specs(PSTSetup).values() if s.cli and s.kind != "bool"]


def _help(spec: Spec, default: Any) -> str:
    """A flag's help: its meaning, unit and valid range, and its default."""
    unit = f" [{spec.unit}]" if spec.unit else ""
    if spec.kind == "choice":
        valid = ""  # the metavar lists them
    elif isinstance(spec.valid, tuple):  # --dim
        valid = "one of " + ", ".join(str(v) for v in spec.valid)
    else:
        valid = ("an integer in " if spec.kind == "int" else "in ") + str(spec.valid)
    default = f"default: {spec.optional}" if spec.optional else f"default {default}"
    return f"{spec.doc}{unit}" + (f", {valid}" if valid else "") + f"; {default}"


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


class _StoreGiven(argparse.Action):
    """``store``, remembering that the flag was given (``ns.given``): a snow profile's
    values give way only to the parameter flags written on the command line."""

    def __call__(self, parser: Any, ns: argparse.Namespace, values: Any, opt: Any = None) -> None:
        setattr(ns, self.dest, values)
        given = set(getattr(ns, "given", ()) or ())
        ns.given = given | {self.dest}


def _weak_layer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a layer index (an integer)") from None


def _probability(text: str) -> float:
    """A release-probability threshold: in (0, 1] (0 would make every cell a zone)."""
    v = _number(text)
    if not 0.0 < v <= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be in (0, 1]")
    return v


def _positive(text: str) -> float:
    v = _number(text)
    if not (math.isfinite(v) and v > 0.0):
        raise argparse.ArgumentTypeError(f"{text!r}: must be a number > 0")
    return v


def _count(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: must be an integer >= 1")
    return v


def _enable_compilation_cache() -> None:
    """Persistent XLA cache: repeated CLI runs skip most of the compilation."""
    import jax

    path = os.environ.get(
        "DAMJAX_CACHE_DIR", os.path.join(os.path.expanduser("~"), ".cache", "damjax", "xla")
    )
    try:
        os.makedirs(path, exist_ok=True)
        jax.config.update("jax_compilation_cache_dir", path)
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    except Exception:  # pragma: no cover - cache is an optimisation only
        pass


def _add_pst_flags(p: argparse.ArgumentParser) -> None:
    defaults_p, defaults_s = PSTParams(), PSTSetup()
    g = p.add_argument_group("physical parameters (SI units; defaults: paper baseline)")
    for spec in _PARAM_FLAGS:
        default = getattr(defaults_p, spec.name)
        g.add_argument(
            spec.flag,
            dest=spec.name,
            type=_number,
            default=default,
            action=_StoreGiven,
            help=_help(spec, default),
        )
    g = p.add_argument_group(
        "snow profile (slab thickness, density, E(rho), slope and weak-layer strength from "
        "a CAAML 6 or SNOWPACK .pro file; parameter flags given here win)"
    )
    g.add_argument(
        "--profile",
        metavar="FILE",
        default=None,
        help="snow profile: CAAML 6 (.xml/.caaml, needs damjax[profiles]) or SNOWPACK .pro",
    )
    g.add_argument(
        "--weak-layer",
        dest="weak_layer",
        metavar="N",
        type=_weak_layer,
        default=None,
        help="index of the weak layer (0 = top layer; default: the CAAML layer of concern)",
    )
    g.add_argument(
        "--modulus",
        choices=("scapozza", "gerling", "bergfeld"),
        default="scapozza",
        help="E(rho) relation for the slab (default scapozza)",
    )
    g.add_argument(
        "--profile-date",
        metavar="ISO",
        default=None,
        help="the profile at this time (SNOWPACK .pro time series; default the last one)",
    )
    g = p.add_argument_group("strength profile along the PST")
    g.add_argument(
        "--strength-profile",
        dest="strength_profile",
        metavar="FILE.csv",
        default=None,
        help="weak-layer strength from a CSV (columns x_m, tau_peak_pa); replaces "
        "--tau-peak/--steady-length/--strength-gradient as tau_p(x) along the PST "
        "(see --strength-fit)",
    )
    g.add_argument(
        "--strength-fit",
        dest="strength_fit",
        choices=("none", "linear", "power_law"),
        default="none",
        help="none (default): the CSV is tau_p(x) along the PST; linear/power_law: the CSV "
        "is a measured transect, fitted, shifted to --tau-peak at --steady-length and "
        "extrapolated over the PST (paper Figs. 11-12)",
    )
    g = p.add_argument_group("numerics")
    for spec in _SETUP_FLAGS:
        default = getattr(defaults_s, spec.name)
        choice = spec.kind == "choice"
        g.add_argument(
            spec.flag,
            dest=spec.name,
            type=str if choice else _number,
            default=default,
            metavar="{" + ",".join(spec.valid) + "}" if choice else None,
            help=_help(spec, default),
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
    for spec in _SETUP_FLAGS:
        v = getattr(ns, spec.name)
        integer = spec.kind == "int"
        if integer and isinstance(v, float) and math.isfinite(v) and v.is_integer():
            v = int(v)
        kw[spec.name] = v
    return PSTSetup(controlled=ns.controlled, **kw)


def _print_summary(summary: dict[str, Any]) -> None:
    for k, v in summary.items():
        if isinstance(v, float):
            v = f"{v:.6g}"
        print(f"{k:34s} {v}")


def _strength_profile_reader(path: str, fit: str) -> Any:
    """``resolve(setup, params)`` for `damjax.pst.prepare`: ``params`` with
    ``strength_profile`` read from a CSV (`fields.pst_strength_profile`), on one point per
    grid node of the (valid) setup; ValueError (one line) on a bad file."""
    from damjax import fields

    def resolve(setup: PSTSetup, params: PSTParams) -> PSTParams:
        num = max(2, int(round(float(setup.length) / float(setup.dx))) + 1)
        try:
            prof = fields.pst_strength_profile(
                path,
                float(setup.length),
                num,
                fit=fit,
                steady_length=float(params.steady_length),
                tau_peak=float(params.tau_peak),
            )
        except FileNotFoundError:
            raise ValueError(f"--strength-profile {path}: no such file") from None
        except ValueError as exc:
            raise ValueError(f"--strength-profile {exc}") from None
        return dataclasses.replace(params, strength_profile=prof)

    return resolve


def _params_from_profile(ns: argparse.Namespace) -> PSTParams:
    """PSTParams from ``--profile`` (`snow_profiles.pst_params`), the parameter flags given
    on the command line winning; one note on stderr with what the profile set."""
    from damjax import snow_profiles

    given = {name: getattr(ns, name) for name in sorted(getattr(ns, "given", ()) or ())}
    try:
        params = snow_profiles.pst_params(
            ns.profile,
            ns.weak_layer,
            modulus=ns.modulus,
            date=ns.profile_date,
            **given,
        )
    except (FileNotFoundError, ImportError) as exc:
        raise ValueError(f"--profile {exc}") from None
    except ValueError as exc:
        msg = str(exc).replace("weak_layer = ", "--weak-layer ")
        raise ValueError(f"--profile {msg}" if "--weak-layer" not in msg else msg) from None
    units = {"thickness": "m", "density": "kg/m^3", "youngs_modulus": "Pa", "slope_deg": "deg"}
    set_ = [
        f"{k} = {float(getattr(params, k)):.4g} {units.get(k, 'Pa')}"
        for k in ("thickness", "density", "youngs_modulus", "slope_deg", "tau_peak")
        if k not in given and float(getattr(params, k)) != float(getattr(PSTParams(), k))
    ]
    sys.stderr.write(f"damjax: profile {ns.profile}: {', '.join(set_)}\n")
    return params


def cmd_pst(ns: argparse.Namespace) -> int:
    from damjax import io, pst
    from damjax.validation import InputError

    if ns.profile is None:
        for flag, v in (("--weak-layer", ns.weak_layer), ("--profile-date", ns.profile_date)):
            if v is not None:
                raise ValueError(f"{flag} {v}: needs --profile FILE")
        if ns.modulus != "scapozza":
            raise ValueError(f"--modulus {ns.modulus}: needs --profile FILE")
        params = PSTParams(**{spec.name: getattr(ns, spec.name) for spec in _PARAM_FLAGS})
    setup = _setup_from(ns)
    if ns.strength_fit != "none" and ns.strength_profile is None:
        raise ValueError(f"--strength-fit {ns.strength_fit}: needs --strength-profile FILE")
    if setup.width != PSTSetup().width and (setup.dim == 1 or setup.lateral == "constrained"):
        raise ValueError(
            f"--width {setup.width!r}: only a 2D strip with free edges has a width "
            "(--dim 2 --lateral free)"
        )
    if ns.plot:
        io.check_figure_path(ns.plot)
    _enable_compilation_cache()
    # the warnings as they come: those on the input before the run
    with _WarningPrinter():
        if ns.profile is not None:
            params = _params_from_profile(ns)
        resolve = None
        if ns.strength_profile is not None:
            resolve = _strength_profile_reader(ns.strength_profile, ns.strength_fit)
        try:
            prep = pst.prepare(params, setup, resolve=resolve, caller="damjax pst")
        except InputError as exc:
            for note in exc.notes:  # a unit mix-up may be the cause of the problems
                warnings.warn(note.text(), stacklevel=1)
            raise
        for note in prep.notes:
            warnings.warn(note.text(), stacklevel=1)
        result = pst.run(prep, progress=not ns.quiet)
    # the summary first: a figure that cannot be written after all (a full disk) does
    # not take the run's result with it
    if ns.json:
        print(json.dumps(result.summary))
    else:
        _print_summary(result.summary)
    if ns.plot:
        from damjax.plot import plot_pst

        try:
            io.save_figure(plot_pst(result), ns.plot)
        except OSError as e:
            raise ValueError(f"--plot {ns.plot}: not written ({e.strerror or e})") from None
        if not ns.json:
            print(f"{'plot':34s} {ns.plot}")
    if result.fault:
        sys.stderr.write(f"damjax: {result.fault}\n")
        return 3
    return 0


class _WarningPrinter:
    """Print each distinct UserWarning once as ``damjax: warning: ...`` (stderr)."""

    def __enter__(self) -> _WarningPrinter:
        self._ctx = warnings.catch_warnings()
        self._ctx.__enter__()
        warnings.simplefilter("always")
        self._seen: set[str] = set()
        warnings.showwarning = self._show  # type: ignore[assignment]
        return self

    def _show(self, message: Any, category: Any, *args: Any, **kwargs: Any) -> None:
        text = str(message)
        if issubclass(category, UserWarning) and text not in self._seen:
            self._seen.add(text)
            from tqdm import tqdm

            # above a running progress bar, which is drawn again below it
            tqdm.write(f"damjax: warning: {text}", file=sys.stderr)

    def __exit__(self, *exc: Any) -> None:
        self._ctx.__exit__(*exc)


def _run_flags(p: argparse.ArgumentParser, checkpoint_help: str) -> None:
    """--json, --quiet and --checkpoint-every, shared by `run` and `resume`."""
    p.add_argument(
        "--json",
        action="store_true",
        help="print the summary and the files written (key files) as one JSON object",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--checkpoint-every", metavar="SECONDS", type=_seconds, default=None, help=checkpoint_help
    )


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"{text!r}: must be in [0, inf) s")
    return v


def _report(outcome: Any, as_json: bool) -> int:
    from damjax import io

    if as_json:  # the summary, and the files the text lists after it
        files = {k: str(v) for k, v in outcome.files.items()}
        print(io.to_json({**outcome.summary, "files": files}))
    else:
        _print_summary({k: v for k, v in outcome.summary.items() if k != "out_dir"})
        for key, path in outcome.files.items():
            print(f"{key:34s} {path}")
    if outcome.fault:
        sys.stderr.write(f"damjax: {outcome.fault}\n")
        return 3
    return 0


def _interrupted(out: Any, every: float | None = None) -> int:
    """Exit status 130 after Ctrl-C, with what the folder holds now: the checkpoint to
    resume from, or why there is none (and whether an earlier run's results are kept)."""
    import shlex

    from damjax import runner

    if (out / runner.CHECKPOINT).is_file():
        sys.stderr.write(
            f"damjax: interrupted; continue with: damjax resume {shlex.quote(str(out))}\n"
        )
        return 130
    if every is not None:
        why = "it stopped before its first chunk ended (a checkpoint holds whole chunks)"
    else:
        why = "--checkpoint-every SECONDS keeps one to resume from"
    kept = ""
    if (out / runner.SUMMARY).is_file():  # written last: a whole run's files
        kept = f"; {out} keeps the earlier run's results"
    elif (out / runner.RESULTS).is_file():
        kept = f"; {out} holds part of this run's outputs (it stopped writing them): run it again"
    sys.stderr.write(f"damjax: interrupted (no checkpoint written: {why}){kept}\n")
    return 130


def cmd_scenarios(ns: argparse.Namespace) -> int:
    from damjax import scenario

    rows = scenario.describe_shipped()
    width = max((len(n) for n, _ in rows), default=0)
    for name, desc in rows:
        print(f"{name:{width}s}  {desc}")
    return 0


def _refuse_ensemble(path: Any, given: str) -> None:
    """A scenario with an [ensemble] table is many runs: say which command runs it."""
    import tomllib

    try:
        data = tomllib.loads(path.read_text())
    except (OSError, ValueError):
        return  # scenario.load reports unreadable files
    if isinstance(data, dict) and "ensemble" in data:
        raise ValueError(
            f"{path.name}: has an [ensemble] table, so it describes many runs: run it with "
            f"`damjax ensemble {given}`, or remove the table to run the scenario once"
        )


def cmd_run(ns: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from damjax import runner, scenario

    t0 = time.perf_counter()
    with _WarningPrinter():
        path = scenario.resolve(ns.scenario)
        _refuse_ensemble(path, ns.scenario)
        try:
            sets = getattr(ns, "set", None) or ()
            if getattr(ns, "release_area", None):
                scn = _load_with_release(path, ns.release_area, sets)
            else:
                scn = scenario.load(path, sets=sets)
        except ValueError as exc:
            raise ValueError(
                "\n".join(
                    line if line.startswith(str(path)) else f"{path.name}: {line}"
                    for line in str(exc).splitlines()
                )
            ) from None
        out = Path(ns.out) if ns.out else runner.default_out_dir(scn)
        _enable_compilation_cache()
        t1 = time.perf_counter()
        try:
            outcome = runner.run(
                scn, out, checkpoint_every=ns.checkpoint_every, progress=not ns.quiet
            )
        except KeyboardInterrupt:
            return _interrupted(out, ns.checkpoint_every)
    phases = outcome.summary.get("phases_s")
    if isinstance(phases, dict):  # the scenario's loading and checks come first
        outcome.summary["phases_s"] = {"scenario_s": round(t1 - t0, 4), **phases}
    return _report(outcome, ns.json)


def _load_with_release(path: Any, release: str, sets: Any = ()) -> Any:
    """``--release-area FILE``: a DEM slope scenario with terrain.release = FILE (the
    polygon then sets terrain.origin and setup.length / width, which are dropped), and
    the ``--set`` overrides."""
    import tomllib
    from pathlib import Path

    from damjax import scenario

    data = tomllib.loads(Path(path).read_text())
    ter = data.get("terrain")
    if data.get("type") != "slope" or not isinstance(ter, dict) or ter.get("kind") != "dem":
        raise ValueError(
            f"--release-area {release}: needs a slope scenario on a DEM "
            '([terrain] kind = "dem", file = ...)'
        )
    ter["release"] = str(Path(release).expanduser().resolve())
    ter.pop("origin", None)
    for key in ("length", "width"):
        data.get("setup", {}).pop(key, None)
    return scenario.parse(scenario.override(data, sets), base_dir=Path(path).parent)


def cmd_resume(ns: argparse.Namespace) -> int:
    from pathlib import Path

    from damjax import runner

    out = Path(ns.dir)
    every = -1.0 if ns.checkpoint_every is None else ns.checkpoint_every
    with _WarningPrinter():
        _enable_compilation_cache()
        try:
            outcome = runner.resume(out, checkpoint_every=every, progress=not ns.quiet)
        except KeyboardInterrupt:
            return _interrupted(out)
    return _report(outcome, ns.json)


def cmd_export(ns: argparse.Namespace) -> int:
    """``damjax export RUN_DIR --to gis|avaframe OUT``: `damjax.export.gis.export_gis` or
    `damjax.export.avaframe.export_avaframe` (needs the ``geo`` extra)."""
    from damjax import io

    kw: dict[str, Any] = dict(
        scenario=ns.scenario, crs=ns.crs, threshold=ns.threshold, min_cells=ns.min_cells
    )
    try:
        with _WarningPrinter():
            if ns.to == "gis":
                from damjax.export import gis

                files = gis.export_gis(
                    ns.run, ns.out, resolution=ns.resolution, formats=tuple(ns.formats), **kw
                )
            else:
                from damjax.export import avaframe

                files = avaframe.export_avaframe(
                    ns.run, ns.out, name=ns.name, thickness=ns.thickness, **kw
                )
    except (FileNotFoundError, ImportError) as exc:
        raise ValueError(f"{ns.run}: {exc}" if str(ns.run) not in str(exc) else str(exc)) from None
    if ns.json:
        print(io.to_json({k: str(v) for k, v in files.items()}))
    else:
        _print_summary({k: str(v) for k, v in files.items()})
    return 0


def cmd_show(ns: argparse.Namespace) -> int:
    from damjax import io, runner

    if ns.plot:
        io.check_figure_path(ns.plot)
    summary, plot = runner.show(ns.dir, ns.plot)
    if ns.json:
        print(io.to_json(summary))
    else:
        _print_summary({k: v for k, v in summary.items() if k != "out_dir"})
        print(f"{'plot':34s} {plot}")
    return 0


def cmd_ensemble(ns: argparse.Namespace) -> int:
    from damjax.ensemble import cli as ensemble_cli

    with _WarningPrinter():
        _enable_compilation_cache()
        try:
            return ensemble_cli.command(ns)
        except KeyboardInterrupt:
            sys.stderr.write("damjax: interrupted (finished members are kept; run it again)\n")
            return 130


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="damjax",
        description="damjax: snow slab avalanche release with a depth-averaged MPM. "
        "`damjax CMD --help` for each command.",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    p = sub.add_parser(
        "pst",
        help="run a propagation saw test",
        description="Run a propagation saw test from flags (the paper's elastic baseline "
        "where a flag is not given) or from a snow profile (--profile FILE --weak-layer "
        "N); print its summary, one key a line (--json: one JSON object), and with --plot "
        "write its figure.",
    )
    _add_pst_flags(p)
    p.set_defaults(func=cmd_pst)

    p = sub.add_parser(
        "scenarios",
        help="list the shipped scenario files",
        description="List the shipped scenario files, name and title (`damjax run "
        "NAME` runs one; copy its file to change it, or change a key with --set).",
    )
    p.set_defaults(func=cmd_scenarios)

    p = sub.add_parser(
        "run",
        help="run a scenario file (or a shipped scenario by name)",
        description="Run a scenario and write results.nc, summary.json, final_state.npz "
        "and pst.png into DIR (slope scenarios: results.nc, summary.json, final_state.npz, "
        "slope.png and release.gif).",
    )
    p.add_argument("scenario", help="TOML file or shipped name (see `damjax scenarios`)")
    p.add_argument(
        "--out",
        metavar="DIR",
        help="output folder (default ./damjax-out/<name>); a finished run's files there are "
        "replaced once this run writes its own (with a warning if it was another "
        "scenario's)",
    )
    _add_set_flag(p)
    p.add_argument(
        "--release-area",
        metavar="FILE",
        default=None,
        help="a release-area polygon (.shp, .geojson; the DEM's CRS) as the domain of a "
        "DEM slope scenario: sets terrain.release (replaces terrain.origin, setup.length, "
        "setup.width; the slab thickness from its 'thickness' attribute)",
    )
    _run_flags(p, "write DIR/checkpoint.npz every SECONDS of wall-clock time (0: every chunk)")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("resume", help="continue a checkpointed run in DIR")
    p.add_argument("dir", metavar="DIR", help="output folder holding checkpoint.npz")
    _run_flags(p, "checkpoint interval (default: that of the interrupted run)")
    p.set_defaults(func=cmd_resume)

    p = sub.add_parser(
        "export",
        help="export a slope run: GeoTIFFs and release polygons, or an AvaFrame directory",
        description="Write a slope run's (or ensemble's) GeoTIFFs and release-zone polygons "
        "in the DEM's CRS (--to gis OUT) or an AvaFrame avalanche directory with the release "
        "zones in Inputs/REL (--to avaframe AVADIR). Needs pip install 'damjax[geo]'.",
    )
    p.add_argument("run", metavar="RUN_DIR", help="run folder (results.nc) or ensemble folder")
    p.add_argument("out", metavar="OUT", help="output folder (AVADIR for --to avaframe)")
    p.add_argument("--to", choices=("gis", "avaframe"), required=True, help="what to write")
    p.add_argument("--scenario", metavar="FILE", default=None, help="the scenario file (ensembles)")
    p.add_argument(
        "--crs",
        default=None,
        help="the CRS of a DEM that states none, e.g. EPSG:2056 (a projected CRS; it labels "
        "the files, it does not reproject them, so a DEM's own CRS stays)",
    )
    p.add_argument(
        "--threshold",
        type=_probability,
        default=0.5,
        help="ensembles: zones where release probability >= this (default 0.5)",
    )
    p.add_argument(
        "--min-cells",
        dest="min_cells",
        type=_count,
        default=4,
        help="leave out zones of fewer cells (default 4)",
    )
    p.add_argument(
        "--formats",
        nargs="+",
        choices=("gpkg", "shp", "geojson"),
        default=["gpkg", "shp"],
        help="--to gis: polygon formats (default gpkg shp)",
    )
    p.add_argument(
        "--resolution",
        type=_positive,
        default=None,
        help="--to gis: GeoTIFF pixel size [m] (default dx times the smallest cos(psi) "
        "along the area's centre line: no cell is skipped)",
    )
    p.add_argument("--name", default=None, help="--to avaframe: release shapefile name")
    p.add_argument(
        "--thickness",
        type=_positive,
        default=None,
        help="--to avaframe: one release thickness [m] (default each zone's mean)",
    )
    p.add_argument("--json", action="store_true", help="print the files as one JSON object")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("show", help="print the summary and re-plot a finished run in DIR")
    p.add_argument("dir", metavar="DIR", help="output folder holding results.nc, or a results file")
    p.add_argument(
        "--plot",
        metavar="FILE",
        help="figure file (default DIR/pst.png or DIR/slope.png; for a file, the file's "
        "name with .png)",
    )
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_show)

    from damjax.ensemble import cli as ensemble_cli

    p = sub.add_parser(
        "ensemble",
        help="release-probability ensemble of a slope scenario",
        description="Run (or resume) N members of a slope scenario that differ in the GRF "
        "seed and the [ensemble] draws; write DIR/ensemble.nc (member dimension, released, "
        "release_probability), ensemble.png and ensemble_summary.json.",
    )
    ensemble_cli.add_arguments(p)
    p.set_defaults(func=cmd_ensemble)
    return parser


_SIGTERM = threading.Event()


def _on_sigterm(signum: int, frame: Any) -> None:
    """SIGTERM (``kill``, a batch scheduler's time limit) as Ctrl-C: a run with
    checkpoints writes one for its last completed chunk and names the resume command."""
    _SIGTERM.set()
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        ns = parser.parse_args(argv)
    except SystemExit as exc:  # usage error (status 2, one line) or --help (status 0)
        return exc.code if isinstance(exc.code, int) else 2
    previous = None
    if threading.current_thread() is threading.main_thread():
        _SIGTERM.clear()
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        rc = dispatch(ns.func, ns)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return 143 if rc == 130 and _SIGTERM.is_set() else rc  # 128 + SIGTERM, as a shell reports


def exit_fast(rc: int) -> NoReturn:
    """Flush stdout and stderr and end the process without the interpreter's teardown.

    Tearing down XLA's CPU client and the imported modules took 1.3-1.8 s after a
    `damjax run quick` on a 2-core VM (2026-11-25, `benchmarks.cli_startup`, ``exit_s``),
    longer than the run. Every output file is closed before `main` returns. Processes of
    a `jax.distributed` job exit normally (its shutdown runs at exit)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (BrokenPipeError, ValueError):  # reader gone / stream closed
            pass
    distributed = sys.modules.get("jax._src.distributed")
    state = getattr(distributed, "global_state", None)
    if getattr(state, "client", None) is not None:
        sys.exit(rc)
    os._exit(rc)


def entry() -> NoReturn:
    """The ``damjax`` console script: `main` on ``sys.argv``, then `exit_fast`."""
    exit_fast(main())


if __name__ == "__main__":
    entry()
