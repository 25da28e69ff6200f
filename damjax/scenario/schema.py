"""Scenario files: a whole run (physics, numerics, outputs) in one TOML file.

A scenario is read with `tomllib` and validated here, at the edge, before anything is
traced or compiled. Every problem is one line naming the TOML key, the value and the
valid range (``params.poisson = 0.7: must be in (0, 0.5)``); `load` and `parse` raise
one `ValueError` carrying all of them, the CLI prints them and exits with status 2.
Physically dubious but valid choices raise a `ScenarioWarning` instead.

One module (~550 lines) on purpose: the keys common to every scenario type, how their
problems are worded and the format live together, and the type-specific parts register
themselves from `damjax.scenario.pst` and `damjax.scenario.slope`. The keys of [params]
and [setup] are the fields of `damjax.params`, whose declarations give each key's kind,
range and meaning; the values are checked once by the type's `prepare`, and the
scenario carries the result (`prepared`).

Format (SI units throughout; angles in degrees)::

    type = "pst"                  # required: "pst", or "slope" (format: damjax.scenario.slope)
    name = "elastic-delta0"       # required: [A-Za-z0-9._-], names the output folder
    description = "one line"      # optional: shown by `damjax scenarios`

    [params]                      # optional: fields of damjax.PSTParams (defaults: paper)
    slope_deg = 35.0              # e.g. the slope angle psi [deg], in (0, 90)
    tensile_strength = inf        # slab tensile strength sigma_t [Pa]; inf: elastic slab

    [setup]                       # optional: fields of damjax.PSTSetup
    length = 100.0                # e.g. the PST length L [m]
    dx = 0.02                     # grid spacing [m] (at most Lambda/2)

    # every field of [params] and [setup], with its unit, valid range, kind and default:
    # `damjax.params` (the reference page "Scenario-file keys" is generated from it)

    [strength]                    # optional: tau_p from a CSV (columns x_m, tau_peak_pa)
    file = "profile.csv"          # relative to the scenario file's folder
    fit = "none"                  # "none": the CSV is tau_p(x) along the PST (interpolated);
                                  # "linear" / "power_law": a measured transect, fitted,
                                  # shifted to params.tau_peak at params.steady_length and
                                  # extrapolated over the PST (paper Figs. 11-12)
    points = 5001                 # optional: samples over [0, L] (default L/dx + 1)

    [profile]                     # optional: the slab from a snow profile (type = "pst")
    file = "pit.caaml"            # CAAML 6 (.xml/.caaml) or SNOWPACK .pro, relative to the
                                  # scenario file's folder (damjax.snow_profiles)
    weak_layer = 4                # layer index, 0 = top (default: CAAML layer of concern)
    modulus = "scapozza"          # E(rho) relation: "scapozza", "gerling" or "bergfeld"
    vertical = false              # true: the profile's depths are vertical
    date = "2017-11-14T12:00"     # SNOWPACK time series: the profile at this time
    use_strength = true           # tau_peak from the weak layer's strength (SNOWPACK 0601)

    [output]                      # optional
    dir = "damjax-out/NAME"       # output folder (relative to the working directory)
    plot = true                   # write pst.png
    snapshots = true              # store the per-chunk snapshots in results.nc

Numbers: a TOML integer is accepted where a float is expected (``density = 250``), not
the reverse (``chunk_steps = 50.0`` is an error); ``inf`` is a valid TOML float where
the range allows it (strengths); ``nan`` never is. A parameter field that is not a
scalar in `PSTParams` (an array such as a strength profile) takes a number or a TOML
array of numbers. Unknown keys are errors, with a "did you mean" suggestion.

A ``[profile]`` table is resolved when the scenario is read: it sets params.thickness,
density, youngs_modulus, slope_deg (if the profile has one) and tau_peak (if it has the
weak layer's strength); a key written in ``[params]`` wins over the profile's value.

A ``[strength]`` table is resolved when the scenario is read: the result holds the
sampled ``params.strength_profile`` array (so `Scenario.to_toml` writes that array, and
no longer needs the file); it cannot be combined with ``params.strength_profile``.

Shipped scenarios live in ``damjax/scenario/library/*.toml``; `shipped()` lists them
and `load` accepts a file path or a shipped name (``damjax run quick``).
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib.resources
import math
import re
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from damjax import io
from damjax.params import PSTParams, PSTSetup, specs
from damjax.validation import Problem

try:
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

SCENARIO_TYPES = ("pst", "slope")
TOP_KEYS = (
    "type",
    "name",
    "description",
    "params",
    "setup",
    "output",
    "strength",
    "terrain",
    "profile",
    "snow",  # slope scenarios: the snow cover (damjax.scenario.slope; 2026-11-27)
)
STRENGTH_KEYS = ("file", "fit", "points")
PROFILE_KEYS = ("file", "weak_layer", "modulus", "vertical", "date", "use_strength")
SECTIONS = ("params", "setup", "output")
MAX_PARTICLES = 50_000_000  # beyond this a run cannot be allocated on one device
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


# scenario type -> (check, warn, prepare): check(data, base_dir, problems) -> (Scenario
# or None, dubious-value notes) appends one line per problem and attaches the checked run
# (`prepared`); warn(scn) gives the warnings of a valid scenario (under-resolved dx);
# prepare(scn) checks a scenario made otherwise (`dataclasses.replace`, by hand). Filled
# by damjax.scenario.pst / .slope on import.
_TYPES: dict[str, tuple[Callable[..., Any], Callable[..., None], Callable[..., Any]]] = {}


def register(
    kind: str,
    check: Callable[[dict[str, Any], str | Path | None, list[str]], tuple[Any, list[str]]],
    warn: Callable[[Any], None],
    prepare: Callable[[Any], Any],
) -> None:
    """Register the checker, the warnings and the preparation of a scenario ``type`` (a
    module of `damjax.scenario` per type calls this when it is imported)."""
    _TYPES[kind] = (check, warn, prepare)


class ScenarioWarning(UserWarning):
    """A valid but physically dubious scenario value."""


@dataclasses.dataclass(frozen=True)
class Output:
    """The ``[output]`` table (each key's TOML kind and meaning declared beside it)."""

    dir: str | None = dataclasses.field(
        default=None,
        metadata={
            "kind": "str?",
            "doc": "output folder; None: ``damjax-out/<name>`` in the working directory",
        },
    )
    plot: bool = dataclasses.field(
        default=True, metadata={"kind": "bool", "doc": "write ``pst.png``"}
    )
    snapshots: bool = dataclasses.field(
        default=True,
        metadata={"kind": "bool", "doc": "store the per-chunk snapshots in ``results.nc``"},
    )


Output.__doc__ += "\n\n    Attributes:\n" + "".join(
    f"        {f.name}: {f.metadata['doc']}.\n" for f in dataclasses.fields(Output)
)


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A validated scenario: a name, the physics, the numerics and the outputs."""

    name: str
    params: PSTParams
    setup: PSTSetup
    description: str = ""
    output: Output = Output()
    type: str = "pst"
    terrain: dict[str, Any] | None = None  # slope scenarios: the [terrain] table
    strength: dict[str, Any] | None = None  # slope scenarios: the [strength] table
    snow: dict[str, Any] | None = None  # slope scenarios: the [snow] table
    # the checked run the loader made (`prepared`); not copied by `dataclasses.replace`
    _prepared: Any = dataclasses.field(default=None, init=False, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """Every field resolved (defaults included), TOML-ready python values."""
        out: dict[str, Any] = {"type": self.type, "name": self.name}
        out["description"] = self.description
        out["params"] = io.plain_fields(self.params)
        out["setup"] = io.plain_fields(self.setup)
        for table in ("terrain", "strength", "snow"):
            if getattr(self, table) is not None:
                out[table] = {k: io.plain(v) for k, v in getattr(self, table).items()}
        out["output"] = {
            f.name: getattr(self.output, f.name)
            for f in dataclasses.fields(Output)
            if getattr(self.output, f.name) is not None
        }
        return out

    def to_toml(self) -> str:
        """Canonical TOML text of the full scenario (``parse(s.to_toml()) == s``)."""
        return dumps(self.to_dict())

    def replace(self, **sections: dict[str, Any]) -> Scenario:
        """A validated copy with some keys overridden, e.g. ``replace(setup={"dx": 0.05})``."""
        data = self.to_dict()
        for section, values in sections.items():
            if section in SECTIONS or (
                section in ("terrain", "strength", "snow") and isinstance(data.get(section), dict)
            ):
                data[section] = {**data.get(section, {}), **values}
            else:
                data[section] = values
        return parse(data)


def prepared(scn: Scenario) -> Any:
    """The checked run of a scenario (`damjax.pst.Prepared` or
    `damjax.slope.simulation.PreparedSlope`): the one its loader made, else made now (a
    scenario from `dataclasses.replace` or made by hand; ValueError on problems)."""
    if scn._prepared is None:
        object.__setattr__(scn, "_prepared", _TYPES[scn.type][2](scn))
    return scn._prepared


# --------------------------------------------------------------------------- shipped


def library_dir() -> Path:
    """Folder of the shipped scenario files."""
    return Path(str(importlib.resources.files("damjax.scenario"))) / "library"


def shipped() -> dict[str, Path]:
    """Shipped scenarios: name -> file (sorted by name)."""
    return {p.stem: p for p in sorted(library_dir().glob("*.toml"))}


def describe_shipped() -> list[tuple[str, str]]:
    """(name, one-line description) of every shipped scenario."""
    rows = []
    for name, path in shipped().items():
        with open(path, "rb") as fh:
            desc = str(tomllib.load(fh).get("description", ""))
        rows.append((name, desc.strip().splitlines()[0] if desc.strip() else ""))
    return rows


def resolve(name_or_path: str | Path) -> Path:
    """The file of a scenario given by path or by shipped name (ValueError if neither)."""
    p = Path(name_or_path)
    if p.is_file():
        return p
    lib = shipped()
    if str(name_or_path) in lib:
        return lib[str(name_or_path)]
    if p.is_dir():
        tomls = sorted(q.name for q in p.glob("*.toml"))[:5]
        holds = f" (it holds {', '.join(tomls)})" if tomls else ""
        raise ValueError(
            f"{name_or_path}: a folder; give a scenario file (a .toml){holds} or a shipped "
            "scenario's name (`damjax scenarios`)"
        )
    hint = difflib.get_close_matches(str(name_or_path), list(lib), n=1)
    more = f" (did you mean '{hint[0]}'?)" if hint else f" (shipped: {', '.join(lib)})"
    raise ValueError(f"{name_or_path}: no such scenario file or shipped scenario{more}")


# --------------------------------------------------------------------------- reading


def load(name_or_path: str | Path, *, warn: bool = True, sets: Iterable[str] = ()) -> Scenario:
    """Read and validate a scenario file (path or shipped name); ValueError on problems.

    ``sets``: ``"section.key=value"`` overrides (`override`), applied before the checks.
    """
    path = resolve(name_or_path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read: {exc}") from None
    if not sets:
        return loads(text, warn=warn, base_dir=path.parent)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError("invalid TOML: " + " ".join(str(exc).split())) from None
    return parse(override(data, sets), warn=warn, base_dir=path.parent)


def override(data: dict[str, Any], sets: Iterable[str]) -> dict[str, Any]:
    """``data`` (a scenario as `tomllib` reads it, changed in place and returned) with each
    ``"section.key=value"`` of ``sets`` applied (the command line's ``--set``): the value
    is read as a TOML value (``0.5``, ``true``, ``"grf"``, ``[1.0, 2.0]``), else as a string
    (``strength.kind=stability``); dotted keys reach nested tables
    (``ensemble.params.softening.dist=uniform``); nothing after ``=`` removes the key
    (``strength.tau_peak=``: a key of another kind). A relative path given to a file key
    (`SET_PATH_KEYS`: ``terrain.file``, ``snow.mask``, ...) is taken from the working
    directory, where the command runs, not from the scenario file's folder. The
    scenario's checks then name a key or value that is not valid. ValueError on a
    malformed assignment."""
    for item in sets:
        key, eq, text = str(item).partition("=")
        key, text = key.strip(), text.strip()
        parts = key.split(".")
        if not eq or not key or not all(re.fullmatch(r"[A-Za-z0-9_-]+", k) for k in parts):
            raise ValueError(
                f"--set {item}: must be KEY=VALUE with KEY a scenario key such as "
                "setup.duration or strength.seed (sections and keys joined by dots)"
            )
        remove = not text
        try:
            value = None if remove else tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            value = text  # a bare word: a string
        table = data
        for depth, k in enumerate(parts[:-1]):
            sub = table.setdefault(k, {})
            if not isinstance(sub, dict):
                where = ".".join(parts[: depth + 1])
                raise ValueError(f"--set {item}: {where} = {_fmt(sub)} is a value, not a table")
            table = sub
        if remove:
            table.pop(parts[-1], None)
        else:
            if parts[-1] in SET_PATH_KEYS and isinstance(value, str) and value:
                value = str(Path(value).expanduser().absolute())
            table[parts[-1]] = value
    return data


# keys whose values are file paths ([terrain] file and release, [strength] file, [snow]
# file and mask, [profile] file): relative to the scenario file when written in it
SET_PATH_KEYS = ("file", "release", "mask")


def loads(text: str, *, warn: bool = True, base_dir: str | Path | None = None) -> Scenario:
    """Parse and validate TOML text; ValueError (one line per problem) on problems.

    ``base_dir``: folder that relative ``[strength] file`` paths are taken from (default:
    the working directory; `load` passes the scenario file's folder).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError("invalid TOML: " + " ".join(str(exc).split())) from None
    return parse(data, warn=warn, base_dir=base_dir)


def parse(
    data: dict[str, Any], *, warn: bool = True, base_dir: str | Path | None = None
) -> Scenario:
    """Validate a scenario given as a dict (as read by `tomllib`); ValueError on problems.

    A ``[strength]`` table is resolved here into ``params.strength_profile`` (relative
    file paths from ``base_dir``, default the working directory).
    """
    scn, problems, notes = _check(data, base_dir)
    if problems:
        if warn:  # a unit mix-up first: it explains the lines that follow
            for note in notes:
                warnings.warn(note, ScenarioWarning, stacklevel=2)
        raise ValueError("\n".join(problems))
    assert scn is not None
    if warn:
        for note in notes:
            warnings.warn(note, ScenarioWarning, stacklevel=2)
        _TYPES[scn.type][1](scn)  # e.g. under-resolved dx (Lambda/5)
    return scn


def problems(data: dict[str, Any]) -> list[str]:
    """One line per problem of a scenario dict (empty when it is valid)."""
    return _check(data)[1]


def dubious(data: dict[str, Any]) -> list[str]:
    """One line per valid but physically dubious value (the warnings of `parse`); where
    the scenario has problems, the lines on implausible values (a unit hint)."""
    return _check(data)[2]


# --------------------------------------------------------------------------- checking


def _fmt(value: Any, limit: int = 60) -> str:
    """A value as it would read in TOML (shortened)."""
    try:
        text = io.toml_value(value)
    except TypeError:
        text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def unknown_keys(table: dict[str, Any], valid: Any, name: str, problems: list[str]) -> None:
    """One problem per key of the TOML table ``[name]`` that is not in ``valid``, with the
    closest valid key or the list of them."""
    valid = list(valid)
    for key in table:
        if key not in valid:
            hit = difflib.get_close_matches(key, valid, n=1)
            more = f" (did you mean '{name}.{hit[0]}'?)" if hit else f" (valid: {', '.join(valid)})"
            problems.append(f"{name}.{key}: unknown key{more}")


def _suggest(section: str | None, key: str) -> str:
    """' (did you mean 'setup.dx'?)' for a misplaced or misspelled key, else ''."""
    known = _known_keys()
    if section is None:
        if key in known["params"]:
            return f" (did you mean 'params.{key}'?)"
        if key in known["setup"]:
            return f" (did you mean 'setup.{key}'?)"
        hit = difflib.get_close_matches(key, TOP_KEYS, n=1)
        return f" (did you mean '{hit[0]}'?)" if hit else f" (valid: {', '.join(TOP_KEYS)})"
    for other in SECTIONS:
        if other != section and key in known[other]:
            return f" (did you mean '{other}.{key}'?)"
    hit = difflib.get_close_matches(key, known[section], n=1, cutoff=0.6)
    if hit:
        return f" (did you mean '{section}.{hit[0]}'?)"
    for other in SECTIONS:  # misspelled and misplaced: setup.poison -> params.poisson
        hit = difflib.get_close_matches(key, known[other], n=1, cutoff=0.8)
        if other != section and hit:
            return f" (did you mean '{other}.{hit[0]}'?)"
    cls = {"params": "PSTParams", "setup": "PSTSetup", "output": "[output]"}[section]
    return f" (not a field of {cls}; see damjax.params)"


def _known_keys() -> dict[str, list[str]]:
    return {
        "params": list(specs(PSTParams)),
        "setup": list(specs(PSTSetup)),
        "output": [f.name for f in dataclasses.fields(Output)],
    }


# TOML kind of each kind of declaration (`damjax.params.Spec.kind`), and of [output]
_TOML_KINDS = {
    "float": "float",
    "int": "int",
    "bool": "bool",
    "choice": "str",
    "profile": "array",
    "point": "array",
}
_KIND_TEXT = {
    "bool": "true or false",
    "int": "an integer",
    "float": "a number",
    "str": "a string",
    "str?": "a string",
    "array": "a number or an array of numbers",
}


def key_kind(cls: type, name: str) -> str:
    """Expected TOML kind of a key of [params], [setup] (``cls``: its class, whose
    declarations say) or [output]: bool, int, float, str, str? (a string, optional) or
    array (a number or an array of numbers)."""
    if cls is Output:
        return {f.name: f.metadata["kind"] for f in dataclasses.fields(Output)}[name]
    return _TOML_KINDS[specs(cls)[name].kind]


def key_doc(cls: type, name: str) -> str:
    """The meaning of a key of [params], [setup] or [output], as declared (with its unit
    and, where None is allowed, what None means)."""
    if cls is Output:
        return {f.name: f.metadata["doc"] for f in dataclasses.fields(Output)}[name]
    spec = specs(cls)[name]
    unit = f" [{spec.unit}]" if spec.unit else ""
    none = f"; None: {spec.optional}" if spec.optional else ""
    return f"{spec.doc}{unit}{none}"


def valid_words(cls: type, name: str) -> str:
    """What a key's value must be, in TOML words: ``must be a number in (0, inf) m``,
    ``must be an integer in [1, 64]``, ``must be one of {"free", "constrained"}``."""
    kind = key_kind(cls, name)
    spec = None if cls is Output else specs(cls)[name]
    if spec is not None and spec.kind == "point":
        return f"must be [x, y], two finite numbers [{spec.unit}]"
    if spec is None or spec.valid is None or kind == "bool":
        return f"must be {_KIND_TEXT[kind]}"
    if spec.kind == "choice":
        return "must be one of {" + ", ".join(f'"{c}"' for c in spec.valid) + "}"
    if kind == "int" and isinstance(spec.valid, tuple):
        return "must be one of {" + ", ".join(str(c) for c in spec.valid) + "}"
    if kind == "int":
        return f"must be an integer in {spec.valid_text}"
    return f"must be {_KIND_TEXT[kind]} in {spec.valid_text}"


def _is_number(v: Any) -> bool:
    """A TOML number: an int or a float, not a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _convert(kind: str, value: Any) -> tuple[bool, Any]:
    """(ok, converted value) for a TOML value against the expected kind."""
    if kind == "bool":
        return isinstance(value, bool), value
    if kind == "int":
        return (isinstance(value, int) and not isinstance(value, bool)), value
    if kind == "float":
        if not _is_number(value):
            return False, value
        try:
            v = float(value)
        except OverflowError:
            return False, value
        return not math.isnan(v), v
    if kind in ("str", "str?"):
        return isinstance(value, str), value
    # array: a number or a (nested, rectangular) array of numbers
    if _is_number(value):
        v = float(value)
        return not math.isnan(v), v
    if not isinstance(value, list) or not value:
        return False, value

    def numbers_only(x: Any) -> bool:
        return all(numbers_only(y) for y in x) if isinstance(x, list) else _is_number(x)

    if not numbers_only(value):
        return False, value
    try:
        arr = np.asarray(value, dtype=float)
    except (ValueError, OverflowError):
        return False, value
    return bool(np.all(~np.isnan(arr))), arr


def _check_section(
    section: str, table: Any, cls: type, problems: list[str]
) -> tuple[dict[str, Any], set[str], set[str]]:
    """Typed values of a section, the fields reported bad, and the keys given."""
    values: dict[str, Any] = {}
    bad: set[str] = set()
    if not isinstance(table, dict):
        problems.append(f"{section} = {_fmt(table)}: must be a table ([{section}])")
        return values, bad, set()
    fields = {f.name for f in dataclasses.fields(cls) if f.init}
    for key, value in table.items():
        if key not in fields:
            problems.append(f"{section}.{key}: unknown key{_suggest(section, key)}")
            continue
        ok, v = _convert(key_kind(cls, key), value)
        if not ok:
            reason = valid_words(cls, key)
            if _is_number(value) and math.isnan(float(value)):
                reason += ", not nan"
            problems.append(f"{section}.{key} = {_fmt(value)}: {reason}")
            bad.add(key)
        else:
            values[key] = v
    return values, bad, set(table)


def toml_name(field: str) -> str:
    """A field as a scenario file names it: ``params.poisson``, ``setup.dx``."""
    return ("params." if field in specs(PSTParams) else "setup.") + field


def _same(given: Any, value: Any) -> bool:
    """Whether a checked value is the whole value given in the file (not one element)."""
    if isinstance(given, (list, dict)) or isinstance(value, (list, tuple, np.ndarray)):
        return False
    try:
        return given == value or (math.isnan(float(given)) and math.isnan(float(value)))
    except (TypeError, ValueError):
        return False


def toml_lines(problems: Iterable[Problem], given: dict[str, Any]) -> list[str]:
    """Problems (`damjax.validation.Problem`) worded for a scenario file: keys as
    ``params.poisson``, values as written in the file (``given``: the file's values by
    field name, as read)."""

    def show(field: str, value: Any) -> str:
        written = given.get(field, value)
        return _fmt(written if _same(written, value) else value)

    return [p.text(toml_name, show) for p in problems]


def _check(
    data: Any, base_dir: str | Path | None = None
) -> tuple[Scenario | None, list[str], list[str]]:
    """(scenario or None, problems, dubious-value notes) of a scenario dict."""
    problems: list[str] = []
    if not isinstance(data, dict):
        return None, [f"scenario = {_fmt(data)}: must be a TOML document (a table)"], []
    for key in data:
        if key not in TOP_KEYS:
            problems.append(f"{key}: unknown key{_suggest(None, key)}")

    kind = data.get("type")
    if "type" not in data:
        choices = ", ".join(f'"{t}"' for t in SCENARIO_TYPES)
        problems.append(f"type: missing (must be one of {{{choices}}})")
    elif kind not in SCENARIO_TYPES:
        valid = "{" + ", ".join(f'"{t}"' for t in SCENARIO_TYPES) + "}"
        problems.append(f"type = {_fmt(kind)}: must be one of {valid}")
    name = data.get("name")
    if "name" not in data:
        problems.append("name: missing (must be a string of letters, digits, '.', '_', '-')")
    elif not isinstance(name, str) or not _NAME_RE.match(name):
        problems.append(
            f"name = {_fmt(name)}: must be a non-empty string of letters, digits, '.', '_', "
            "'-' (it names the output folder)"
        )
    desc = data.get("description", "")
    if not isinstance(desc, str):
        problems.append(f"description = {_fmt(desc)}: must be a string")

    if any(isinstance(data[k], dict) for k in data if k not in TOP_KEYS):
        # a misspelt table ([param]): its values were not read, and checking the others
        # against the defaults would report what follows from that (a default L_ss longer
        # than the PST) as problems of their own
        return None, problems, []
    check = _TYPES["slope"][0] if kind == "slope" else _TYPES["pst"][0]
    scn, notes = check(data, base_dir, problems)
    # with problems, the notes are those on implausible values (a unit hint), which
    # explain them
    return (None, problems, notes) if problems else (scn, [], notes)


# --------------------------------------------------------------------------- writing


def dumps(data: Any) -> str:
    """TOML text of a scenario dict (or of a `Scenario`: its ``to_toml()``): top-level
    keys first, then one table per section."""
    if hasattr(data, "to_toml") and not isinstance(data, dict):
        return data.to_toml()
    if not isinstance(data, dict):
        raise TypeError(f"dumps: a scenario dict or Scenario, got {type(data).__name__}")
    return io.toml_dumps(data)
