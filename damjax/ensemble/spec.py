"""The ensemble's definition: the ``[ensemble]`` table of a slope scenario (member count,
seeds, parameter distributions), checked with one line per problem naming its key, and
each member's scenario (its GRF seed and its drawn parameters)."""

from __future__ import annotations

import dataclasses
import difflib
import functools
import hashlib
import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from damjax.params import PSTParams
from damjax.scenario import parse, resolve
from damjax.scenario.schema import _fmt, _is_number, unknown_keys
from damjax.scenario.slope import PST_ONLY_PARAMS
from damjax.validation import param_problems

DISTRIBUTIONS = ("normal", "lognormal", "uniform")
# strength-table keys that [ensemble.strength] may draw, per strength kind
STRENGTH_DRAWS = {
    "grf": ("mean", "mean_at", "trend", "std", "length_scale", "angle_deg", "trend_deg"),
    "constant": ("tau_peak", "trend"),
    "map": (),
    "stability": ("mean", "cov", "length_scale", "angle_deg"),
    "coulomb": ("cohesion", "friction_coefficient", "std", "length_scale", "angle_deg"),
}
# strength kinds whose random field follows strength.seed (a member's seed); with
# strength.trigger = "random" the seed also places the trigger, whatever the kind
SEEDED_KINDS = ("grf", "stability", "coulomb")


def seeded(strength: dict[str, Any] | None) -> bool:
    """Whether members of a scenario with this [strength] table differ by their seed."""
    st = strength or {"kind": "constant"}
    if st["kind"] == "coulomb" and not st.get("std", 0.0):  # a constant cohesion
        return st.get("trigger") == "random"
    return st["kind"] in SEEDED_KINDS or st.get("trigger") == "random"


# --------------------------------------------------------------------------- distributions


@dataclasses.dataclass(frozen=True)
class Distribution:
    """A parameter distribution.

    Attributes:
        dist: "normal", "lognormal" or "uniform".
        mean, std: mean and standard deviation of the value (normal, lognormal) [its unit].
        low, high: the range of a uniform distribution [its unit].
        bounds: (low, high) truncation of a normal or lognormal distribution (None: none).
    """

    dist: str
    mean: float | None = None
    std: float | None = None
    low: float | None = None
    high: float | None = None
    bounds: tuple[float, float] | None = None

    def ppf(self, u: float) -> float:
        """The value at cumulative probability u in (0, 1) (inverse CDF; the truncated
        distribution when `bounds` is given)."""
        if self.dist == "uniform":
            assert self.low is not None and self.high is not None
            return float(self.low + u * (self.high - self.low))
        d, a, b = _frozen(self)
        return float(d.ppf(a + u * (b - a)))

    def to_dict(self) -> dict[str, Any]:
        """The ``[ensemble.params.NAME]`` table of this distribution (TOML-ready)."""
        out = {k: v for k, v in dataclasses.asdict(self).items() if v is not None}
        if self.bounds is not None:
            out["bounds"] = list(self.bounds)
        return out


@functools.lru_cache(maxsize=64)
def _frozen(dist: Distribution) -> tuple[Any, float, float]:
    """The scipy distribution of a normal or lognormal `Distribution` and its CDF at the
    bounds."""
    from scipy import stats

    assert dist.mean is not None and dist.std is not None
    if dist.dist == "normal":
        d = stats.norm(dist.mean, dist.std)
    else:  # mean and std of the value -> those of its logarithm
        s2 = math.log1p((dist.std / dist.mean) ** 2)
        d = stats.lognorm(s=math.sqrt(s2), scale=math.exp(math.log(dist.mean) - s2 / 2))
    lo, hi = dist.bounds if dist.bounds is not None else (-math.inf, math.inf)
    return d, float(d.cdf(lo)), float(d.cdf(hi))


def _is_int(v: Any, lo: int) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= lo


def _distribution(name: str, table: Any, problems: list[str]) -> Distribution | None:
    """A distribution table checked (one line per problem, keys named ``name.key``)."""
    if not isinstance(table, dict):
        problems.append(
            f"{name} = {_fmt(table)}: must be a table with dist = "
            '"normal" | "lognormal" | "uniform" and its numbers'
        )
        return None
    n0 = len(problems)
    dist = table.get("dist")
    if dist not in DISTRIBUTIONS:
        problems.append(
            f'{name}.dist = {_fmt(dist)}: must be one of {{"normal", "lognormal", "uniform"}}'
        )
        return None
    keys = ("low", "high") if dist == "uniform" else ("mean", "std", "bounds")
    for key in table:
        if key != "dist" and key not in keys:
            hit = difflib.get_close_matches(key, keys, n=1)
            more = f" (did you mean '{name}.{hit[0]}'?)" if hit else ""
            problems.append(
                f'{name}.{key}: unknown key for dist = "{dist}" (valid: '
                f"{', '.join(('dist', *keys))}){more}"
            )
    vals: dict[str, Any] = {}
    for key in keys:
        if key == "bounds":
            continue
        if key not in table:
            problems.append(f'{name}.{key}: missing (dist = "{dist}" needs {", ".join(keys[:2])})')
        elif not (_is_number(table[key]) and math.isfinite(table[key])):
            problems.append(f"{name}.{key} = {_fmt(table[key])}: must be a finite number")
        else:
            vals[key] = float(table[key])
    if len(problems) > n0:
        return None
    if dist == "uniform" and not vals["low"] < vals["high"]:
        problems.append(f"{name}.high = {vals['high']:g}: must be > {name}.low = {vals['low']:g}")
    if dist != "uniform":
        if not vals["std"] > 0:
            problems.append(f"{name}.std = {vals['std']:g}: must be in (0, inf)")
        if dist == "lognormal" and not vals["mean"] > 0:
            problems.append(f"{name}.mean = {vals['mean']:g}: must be in (0, inf) (lognormal)")
        if "bounds" in table:
            b = table["bounds"]
            ok = isinstance(b, list) and len(b) == 2
            ok = ok and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in b)
            if not ok or not float(b[0]) < float(b[1]):
                problems.append(f"{name}.bounds = {_fmt(b)}: must be [low, high] with low < high")
            else:
                vals["bounds"] = (float(b[0]), float(b[1]))
                lo_ok = dist == "normal" or vals["bounds"][1] > 0
                if not lo_ok:
                    problems.append(
                        f"{name}.bounds = {_fmt(b)}: a lognormal value is > 0: high must be > 0"
                    )
    if len(problems) > n0:
        return None
    return Distribution(dist=dist, **vals)


# --------------------------------------------------------------------------- the ensemble


@dataclasses.dataclass(frozen=True)
class Ensemble:
    """A slope scenario and how its members differ.

    Attributes:
        scenario: the validated slope scenario (member 0 before its draws).
        members: member count N.
        seeds: the GRF seed of each member (length >= N); None: ``strength.seed + i``.
        param_seed: seed of the parameter draws.
        params: distributions of `PSTParams` fields, by field name.
        strength: distributions of ``[strength]`` numbers, by key.
        slice_size: members per vmapped slice; None: chosen from memory.
    """

    scenario: Any
    members: int
    seeds: tuple[int, ...] | None = None
    param_seed: int = 0
    params: dict[str, Distribution] = dataclasses.field(default_factory=dict)
    strength: dict[str, Distribution] = dataclasses.field(default_factory=dict)
    slice_size: int | None = None

    def table(self) -> dict[str, Any]:
        """The ``[ensemble]`` table (TOML-ready values)."""
        out: dict[str, Any] = {"members": self.members, "param_seed": self.param_seed}
        if self.seeds is not None:
            out["seeds"] = list(self.seeds)
        if self.slice_size is not None:
            out["slice_size"] = self.slice_size
        for part in ("params", "strength"):
            d = getattr(self, part)
            if d:
                out[part] = {k: v.to_dict() for k, v in sorted(d.items())}
        return out


ENSEMBLE_KEYS = ("members", "seeds", "param_seed", "slice_size", "params", "strength")


def _scalar_param_fields() -> list[str]:
    return [
        f.name
        for f in dataclasses.fields(PSTParams)
        if f.name not in PST_ONLY_PARAMS and np.ndim(f.default) == 0 and f.default is not None
    ]


def check_table(table: Any, scn: Any, problems: list[str]) -> dict[str, Any]:
    """The keyword arguments of `Ensemble` from an ``[ensemble]`` table (problems appended,
    one line each, naming ``ensemble.KEY``)."""
    if not isinstance(table, dict):
        problems.append(f"ensemble = {_fmt(table)}: must be a table ([ensemble])")
        return {}
    out: dict[str, Any] = {}
    unknown_keys(table, ENSEMBLE_KEYS, "ensemble", problems)
    for key, value in table.items():
        if key not in ENSEMBLE_KEYS:
            continue
        if key in ("members", "slice_size"):
            if not _is_int(value, 1):
                problems.append(f"ensemble.{key} = {_fmt(value)}: must be an integer >= 1")
            else:
                out[key] = int(value)
        elif key == "param_seed":
            if not _is_int(value, 0):
                problems.append(f"ensemble.param_seed = {_fmt(value)}: must be an integer >= 0")
            else:
                out[key] = int(value)
        elif key == "seeds":
            if not isinstance(value, list) or not value or not all(_is_int(v, 0) for v in value):
                problems.append(f"ensemble.seeds = {_fmt(value)}: must be a list of integers >= 0")
            else:
                out["seeds"] = tuple(int(v) for v in value)
        else:
            if not isinstance(value, dict):
                problems.append(
                    f"ensemble.{key} = {_fmt(value)}: must be a table of "
                    f"distributions ([ensemble.{key}.NAME])"
                )
                continue
            kind = (scn.strength or {"kind": "constant"})["kind"] if scn is not None else "grf"
            valid = _scalar_param_fields() if key == "params" else list(STRENGTH_DRAWS[kind])
            dists = {}
            for name, sub in value.items():
                if name not in valid:
                    hit = difflib.get_close_matches(name, valid, n=1)
                    if key == "strength":
                        more = f' (strength.kind = "{kind}" draws: {", ".join(valid) or "none"})'
                    else:
                        more = f" (did you mean 'ensemble.params.{hit[0]}'?)" if hit else ""
                        more = more or " (a scalar field of [params])"
                    problems.append(f"ensemble.{key}.{name}: cannot be drawn{more}")
                    continue
                d = _distribution(f"ensemble.{key}.{name}", sub, problems)
                if d is not None:
                    dists[name] = d
            out[key] = dists
    return out


def from_scenario(
    scn: Any, table: dict[str, Any] | None = None, *, members: int | None = None
) -> Ensemble:
    """An `Ensemble` of a loaded slope scenario; ``table``: the ``[ensemble]`` table as
    TOML values (``{"params": {"softening": {"dist": "uniform", "low": 0.5, "high":
    1.5}}}``); ``members`` overrides its ``members``. ValueError (one line per problem)
    on bad input."""
    problems: list[str] = []
    if getattr(scn, "type", None) != "slope":
        raise ValueError(
            f"scenario {getattr(scn, 'name', scn)!r}: an ensemble needs a slope scenario "
            '(type = "slope"); for PSTs use damjax.sweep'
        )
    kw = check_table({} if table is None else table, scn, problems)
    if members is not None:
        if not _is_int(members, 1):
            problems.append(f"members = {members!r}: must be an integer >= 1")
        else:
            kw["members"] = int(members)
    if problems:
        raise ValueError("\n".join(problems))
    kw.setdefault("members", 1)
    ens = Ensemble(scenario=scn, **kw)
    problems += _member_problems(ens)
    if problems:
        raise ValueError("\n".join(problems))
    return ens


def load(name_or_path: str | Path, members: int | None = None, sets: Any = ()) -> Ensemble:
    """Read a slope scenario file (path or shipped name) with its optional ``[ensemble]``
    table; ``members`` overrides ``ensemble.members``, ``sets`` are ``"section.key=value"``
    overrides (`damjax.scenario.override`, ``ensemble.*`` keys too). ValueError on
    problems."""
    import tomllib

    path = resolve(name_or_path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: cannot read: {' '.join(str(exc).split())}") from None
    if sets:
        from damjax.scenario import override

        data = override(data, sets)
    table = data.pop("ensemble", {})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        scn = parse(data, base_dir=path.parent)
    if not isinstance(table, dict):
        raise ValueError(f"ensemble = {_fmt(table)}: must be a table ([ensemble])")
    return from_scenario(scn, table, members=members)


def member_seed(ens: Ensemble, i: int) -> int:
    """The GRF seed of member i."""
    if ens.seeds is not None:
        return int(ens.seeds[i])
    return int((ens.scenario.strength or {}).get("seed", 0)) + i


def member_draws(ens: Ensemble, i: int) -> tuple[dict[str, float], dict[str, float]]:
    """(params, strength) values drawn for member i: each from its own stream
    ``default_rng([param_seed, i])``, in sorted name order, so member i is the same in
    every ensemble size."""
    if not ens.params and not ens.strength:
        return {}, {}
    rng = np.random.default_rng([ens.param_seed, i])
    out: tuple[dict[str, float], dict[str, float]] = ({}, {})
    for part, d in ((0, ens.params), (1, ens.strength)):
        for name in sorted(d):
            out[part][name] = d[name].ppf(float(rng.random()))
    return out


def member_scenario(ens: Ensemble, i: int) -> Any:
    """The scenario of member i (its seed and draws), runnable on its own with
    `damjax.scenario.slope_fields.simulate`. With the "crack_band" slab the member's
    tensile-strength field is drawn too: its seed is ``setup.seed + i``."""
    scn = ens.scenario
    pdraw, sdraw = member_draws(ens, i)
    strength = dict(scn.strength or {"kind": "constant"})
    if seeded(strength):
        strength["seed"] = member_seed(ens, i)
    strength.update(sdraw)
    setup = scn.setup
    if setup.slab_fracture == "crack_band":
        setup = dataclasses.replace(setup, seed=setup.seed + i)
    return dataclasses.replace(
        scn, params=dataclasses.replace(scn.params, **pdraw), strength=strength, setup=setup
    )


def _member_problems(ens: Ensemble) -> list[str]:
    out = []
    kind = (ens.scenario.strength or {"kind": "constant"})["kind"]
    if (
        ens.members > 1
        and not seeded(ens.scenario.strength)
        and not ens.params
        and not ens.strength
    ):
        out.append(
            f'strength.kind = "{kind}": the members would be identical (give a "grf" or '
            '"stability" strength, whose seed differs per member, strength.trigger = '
            '"random", or [ensemble.params] distributions)'
        )
    if ens.seeds is not None and len(ens.seeds) < ens.members:
        out.append(
            f"ensemble.seeds: {len(ens.seeds)} seeds for {ens.members} members (give one per "
            "member, or leave seeds out: strength.seed + member)"
        )
    elif ens.seeds is not None:
        first: dict[int, int] = {}
        for i, seed in enumerate(ens.seeds[: ens.members]):
            if seed in first:  # the same strength field and trigger: a member counted twice
                out.append(
                    f"ensemble.seeds: members {first[seed]} and {i} share seed {seed}: their "
                    "strength fields and triggers would be the same (give each member its "
                    "own seed)"
                )
                break
            first[seed] = i
    if out or not (ens.params or ens.strength):
        return out
    for i in range(ens.members):
        pdraw, sdraw = member_draws(ens, i)
        params = dataclasses.replace(ens.scenario.params, **pdraw)
        for problem in param_problems(params, None):
            name = problem.field
            if name in pdraw:
                out.append(
                    f"ensemble.params.{name}: member {i} draws {pdraw[name]:.6g}: "
                    f"{problem.reason} (give ensemble.params.{name}.bounds)"
                )
        for name, v in sdraw.items():
            positive = name in ("mean", "tau_peak", "length_scale")
            if (positive and not v > 0) or (name == "std" and v < 0):
                out.append(
                    f"ensemble.strength.{name}: member {i} draws {v:.6g}: must be "
                    f"{'> 0' if positive else '>= 0'} (give ensemble.strength.{name}.bounds)"
                )
        if out:
            break
    return out


def key_of(ens: Ensemble) -> str:
    """Hash of what makes the members: the scenario (without [output]) and the
    [ensemble] table without members and slice_size."""
    d = ens.scenario.to_dict()
    d.pop("output", None)
    t = ens.table()
    t.pop("members", None)
    t.pop("slice_size", None)
    if ens.seeds is not None:  # only the seeds the members use may differ in length
        t["seeds"] = list(ens.seeds)
    text = json.dumps({"scenario": d, "ensemble": t}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
