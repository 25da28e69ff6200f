"""Scenario files: a whole run (physics, numerics, outputs) in one TOML file.

A scenario is read with `tomllib` and validated here, at the edge, before anything is
traced or compiled. Every problem is one line naming the TOML key, the value and the
valid range (``params.poisson = 0.7: must be in (0, 0.5)``); `load` and `parse` raise
one `ValueError` carrying all of them, the CLI prints them and exits with status 2.
Physically dubious but valid choices raise a `ScenarioWarning` instead.

One module (~620 lines, a sixth of them this format description) on
purpose: the keys common to every scenario type, their checks and messages live together,
and the type-specific parts register themselves from `damjax.scenario.pst` and
`damjax.scenario.slope`.

Format (SI units throughout; angles in degrees)::

    type = "pst"                  # required: "pst", or "slope" (format: damjax.scenario.slope)
    name = "elastic-delta0"       # required: [A-Za-z0-9._-], names the output folder
    description = "one line"      # optional: shown by `damjax scenarios`

    [params]                      # optional: fields of damjax.PSTParams (defaults: paper)
    slope_deg = 35.0              # slope angle psi [deg], (0, 90)
    thickness = 0.5               # slab thickness h0 [m]
    density = 250.0               # slab density rho [kg/m^3]
    youngs_modulus = 4.0e6        # slab Young's modulus E [Pa]
    poisson = 0.3                 # slab Poisson ratio nu [-], (0, 0.5)
    friction_deg = 27.0           # residual friction angle phi of the broken layer [deg]
    wl_shear_modulus = 2.0e5      # weak-layer shear modulus G_wl [Pa]
    wl_thickness = 0.04           # weak-layer thickness D_wl [m]
    tau_peak = 1000.0             # weak-layer peak shear strength tau_p [Pa] (inf allowed)
    steady_length = 20.0          # length L_ss of constant strength [m]
    strength_gradient = 500.0     # strength gradient theta beyond L_ss [Pa/m]
    softening = 0.0               # softening coefficient delta [-]
    tensile_strength = inf        # slab tensile strength sigma_t [Pa]; inf: elastic slab
    slab_fracture_energy = 0.12   # G_f [J/m^2] (default: the slab model's, see PSTParams)
    slab_strength_cov = 0.2       # coefficient of variation of sigma_t, [0, 1]
    slab_strength_length = 1.0    # its correlation length [m], [0.2, 10]
    saw_speed = 6.0               # saw (or controlled cut) speed [m/s]
    # ... and any other PSTParams field (mcc_m, mcc_beta, ...; see its docstring)

    [setup]                       # optional: fields of damjax.PSTSetup
    length = 100.0                # PST length L [m]
    dx = 0.02                     # grid spacing [m] (at most Lambda/2)
    duration = 3.0                # simulated time [s]
    controlled = false            # true: unbreakable layer cut at saw_speed for the run
    lateral = "free"              # "free" (sigma_yy = 0) or "constrained" (eps_yy = 0)
    cfl = 0.5                     # Courant number, (0, 1)
    particles_per_cell = 2        # integer >= 1
    dtype = "float32"             # "float32" or "float64"
    chunk_steps = 1000            # integer >= 1: steps per jitted chunk (snapshots)
    dim = 1                       # 1 (strip) or 2 (2D step on a strip)
    width = 0.3                   # strip width for dim = 2 [m]
    p0_rule = "paper"             # "paper" or "uniaxial"
    slab_fracture = "paper"       # "paper" (perfectly plastic) or "crack_band" (G_f and a
                                  # random sigma_t field: params.slab_fracture_energy,
                                  # slab_strength_cov, slab_strength_length)
    seed = 0                      # integer, picks the sigma_t field ("crack_band")
    accumulation = "auto"         # P2G sums: "auto" ("float" on a CPU, "fixed" on a
                                  # GPU), "fixed" (deterministic fixed point) or "float"

    [strength]                    # optional: tau_p from a CSV (columns x_m, tau_peak_pa)
    file = "profile.csv"          # relative to the scenario file's folder
    fit = "none"                  # "none": the CSV is tau_p(x) along the PST (interpolated);
                                  # "linear" / "power_law": a measured transect, fitted,
                                  # shifted to params.tau_peak at params.steady_length and
                                  # extrapolated over the PST (paper Figs. 10-11)
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
import typing
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from damjax.constants import (
    DTYPES,
    LATERAL_CONDITIONS,
    MCC_INVARIANTS,
    P0_RULES,
    SLAB_FRACTURE_MODELS,
)
from damjax.params import PSTParams, PSTSetup
from damjax.validation import NO_CLI_FLAG, PARAM_RULES, SETUP_CHOICES, SETUP_RULES

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
)
STRENGTH_KEYS = ("file", "fit", "points")
PROFILE_KEYS = ("file", "weak_layer", "modulus", "vertical", "date", "use_strength")
SECTIONS = ("params", "setup", "output")
MAX_PARTICLES = 50_000_000  # beyond this a run cannot be allocated on one device
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


# scenario type -> (check, warn): check(data, base_dir, problems) -> (Scenario or None,
# dubious-value notes) appends one line per problem; warn(scn) gives the warnings of a
# valid scenario (under-resolved dx). Filled by damjax.scenario.pst / .slope on import.
_TYPES: dict[str, tuple[Callable[..., Any], Callable[..., None]]] = {}


def register(
    kind: str,
    check: Callable[[dict[str, Any], str | Path | None, list[str]], tuple[Any, list[str]]],
    warn: Callable[[Any], None],
) -> None:
    """Register the checker and the warnings of a scenario ``type`` (a module of
    `damjax.scenario` per type calls this when it is imported)."""
    _TYPES[kind] = (check, warn)


class ScenarioWarning(UserWarning):
    """A valid but physically dubious scenario value."""


@dataclasses.dataclass(frozen=True)
class Output:
    """The ``[output]`` table.

    Attributes:
        dir: output folder; None: ``damjax-out/<name>`` in the working directory.
        plot: write ``pst.png``.
        snapshots: store the per-chunk snapshots in ``results.nc``.
    """

    dir: str | None = None
    plot: bool = True
    snapshots: bool = True


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

    def to_dict(self) -> dict[str, Any]:
        """Every field resolved (defaults included), TOML-ready python values."""
        out: dict[str, Any] = {"type": self.type, "name": self.name}
        out["description"] = self.description
        params: dict[str, Any] = {}
        for f in dataclasses.fields(PSTParams):
            v = _plain(getattr(self.params, f.name))
            if v is not None:
                params[f.name] = v
        out["params"] = params
        out["setup"] = {
            f.name: _plain(getattr(self.setup, f.name))
            for f in dataclasses.fields(type(self.setup))
        }
        for table in ("terrain", "strength"):
            if getattr(self, table) is not None:
                out[table] = {k: _plain(v) for k, v in getattr(self, table).items()}
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
                section in ("terrain", "strength") and isinstance(data.get(section), dict)
            ):
                data[section] = {**data.get(section, {}), **values}
            else:
                data[section] = values
        return parse(data)


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
    hint = difflib.get_close_matches(str(name_or_path), list(lib), n=1)
    more = f" (did you mean '{hint[0]}'?)" if hint else f" (shipped: {', '.join(lib)})"
    raise ValueError(f"{name_or_path}: no such scenario file or shipped scenario{more}")


# --------------------------------------------------------------------------- reading


def load(name_or_path: str | Path, *, warn: bool = True) -> Scenario:
    """Read and validate a scenario file (path or shipped name); ValueError on problems."""
    path = resolve(name_or_path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read: {exc}") from None
    return loads(text, warn=warn, base_dir=path.parent)


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
    """One line per valid but physically dubious value (the warnings of `parse`)."""
    return _check(data)[2]


# --------------------------------------------------------------------------- checking


def _fmt(value: Any, limit: int = 60) -> str:
    """A value as it would read in TOML (shortened)."""
    try:
        text = _toml_value(value)
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
    cls = {"params": "PSTParams", "setup": "PSTSetup", "output": "[output]"}[section]
    return f" (not a field of {cls}; see the damjax.scenario.schema docstring)"


def _known_keys() -> dict[str, list[str]]:
    return {
        "params": [f.name for f in dataclasses.fields(PSTParams)],
        "setup": [f.name for f in dataclasses.fields(PSTSetup)],
        "output": [f.name for f in dataclasses.fields(Output)],
    }


def _kind_of(cls: type, f: dataclasses.Field) -> str:
    """Expected TOML kind of a field: bool, int, float, str, str?, or array."""
    try:
        hint = typing.get_type_hints(cls).get(f.name, Any)
    except Exception:  # pragma: no cover - unresolvable annotation
        hint = Any
    default = f.default if f.default is not dataclasses.MISSING else None
    if hint is bool or isinstance(default, bool):
        return "bool"
    if hint is int or (hint is Any and type(default) is int):
        return "int"
    if hint is float or (hint is Any and type(default) is float):
        return "float"
    if hint is str or isinstance(default, str):
        return "str"
    if hint == (str | None):
        return "str?"
    return "array"


_KIND_TEXT = {
    "bool": "true or false",
    "int": "an integer",
    "float": "a number",
    "str": "a string",
    "str?": "a string",
    "array": "a number or an array of numbers",
}

_CHOICES = {
    "lateral": LATERAL_CONDITIONS,
    "dtype": DTYPES,
    "p0_rule": P0_RULES,
    "mcc_invariants": MCC_INVARIANTS,
    "slab_fracture": SLAB_FRACTURE_MODELS,
    "accumulation": SETUP_CHOICES["accumulation"],
}


def _valid_text(section: str, name: str, kind: str) -> str:
    rules = PARAM_RULES if section == "params" else SETUP_RULES
    text = _KIND_TEXT[kind]
    if name in rules:
        valid = rules[name][1]
        if kind == "int" and valid.endswith(", integers"):
            return "must be an integer in " + valid[: -len(", integers")]
        return f"must be {text} in {valid}"
    if name in _CHOICES and section == "setup":
        return "must be one of {" + ", ".join(f'"{c}"' for c in _CHOICES[name]) + "}"
    return f"must be {text}"


def _is_number(v: Any) -> bool:
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
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key, value in table.items():
        if key not in fields:
            problems.append(f"{section}.{key}: unknown key{_suggest(section, key)}")
            continue
        kind = _kind_of(cls, fields[key])
        ok, v = _convert(kind, value)
        if not ok:
            reason = _valid_text(section, key, kind)
            if _is_number(value) and math.isnan(float(value)):
                reason += ", not nan"
            problems.append(f"{section}.{key} = {_fmt(value)}: {reason}")
            bad.add(key)
        else:
            values[key] = v
    return values, bad, set(table)


# 'poisson (--poisson) = ...', or a bare 'slope_profile = ...' (fields with no CLI flag)
_LINE_RE = re.compile(
    r"^(?:(?P<name>\w+) \(--[\w-]+\)|(?P<bare>" + "|".join(NO_CLI_FLAG) + r")(?= ))(?P<rest>.*)$"
)


def _retarget(lines: list[str], skip: set[str], given: dict[str, Any]) -> list[str]:
    """Config problem lines ('poisson (--poisson) = ...') renamed to TOML keys, with the
    value written as in TOML (``"sideways"``, not ``'sideways'``)."""
    known = _known_keys()
    out = []
    for line in lines:
        m = _LINE_RE.match(line)
        if not m:
            out.append(line)
            continue
        name, rest = m["name"] or m["bare"], m["rest"]
        section = "setup" if name in known["setup"] else "params"
        key = f"{section}.{name}"
        if key in skip:
            continue
        if key in given:
            value = given[key]
            for text in {repr(value), repr(_as_float_or(value))}:
                if rest.startswith(f" = {text}: "):
                    rest = f" = {_fmt(value)}" + rest[len(f" = {text}") :]
                    break
        out.append(key + rest)
    return out


def _as_float_or(value: Any) -> Any:
    try:
        return float(value)
    except (TypeError, ValueError):
        return value


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
    return (None, problems, []) if problems else (scn, [], notes)


# --------------------------------------------------------------------------- writing


def _plain(value: Any) -> Any:
    """A parameter value as plain python (floats, lists of floats, str, bool, int)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    arr = np.asarray(value)
    if arr.dtype == bool:
        return bool(arr) if arr.ndim == 0 else arr.tolist()
    if np.issubdtype(arr.dtype, np.integer):
        return int(arr) if arr.ndim == 0 else arr.tolist()
    arr = arr.astype(float)
    return float(arr) if arr.ndim == 0 else arr.tolist()


def _toml_str(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, np.ndarray) or np.isscalar(v):
        return _toml_value(_plain(v))
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def dumps(data: Any) -> str:
    """TOML text of a scenario dict (or of a `Scenario`: its ``to_toml()``): top-level
    keys first, then one table per section."""
    if hasattr(data, "to_toml") and not isinstance(data, dict):
        return data.to_toml()
    if not isinstance(data, dict):
        raise TypeError(f"dumps: a scenario dict or Scenario, got {type(data).__name__}")
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append("")
            lines.append(f"[{k}]")
            lines += [f"{kk} = {_toml_value(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"
