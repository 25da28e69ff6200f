"""PST scenarios (``type = "pst"``): the ``[params]``, ``[setup]`` and ``[strength]``
tables of a PST run, read as `damjax.PSTParams` / `damjax.PSTSetup` (their declarations
give each key's kind) and checked once by `damjax.pst.prepare`, its problems worded with
the file's keys (the format: `damjax.scenario.schema`).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from damjax import fields, pst
from damjax.params import PSTParams, PSTSetup
from damjax.scenario.schema import (
    MAX_PARTICLES,
    PROFILE_KEYS,
    STRENGTH_KEYS,
    Output,
    Scenario,
    _check_section,
    _fmt,
    prepared,
    register,
    toml_lines,
    unknown_keys,
)
from damjax.validation import InputError


def check(
    data: dict[str, Any], base_dir: str | Path | None, problems: list[str]
) -> tuple[Scenario | None, list[str]]:
    """The Scenario of a PST document (None with problems appended) and its dubious-value
    notes. Top-level keys, type and name are checked by the caller (`schema.parse`); the
    values by `damjax.pst.prepare`, whose result the Scenario carries (`prepared`)."""
    for table in ("terrain", "snow"):
        if table in data:
            problems.append(f'{table}: only for type = "slope" scenarios')
    pvals, pbad, pgiven = _check_section("params", data.get("params", {}), PSTParams, problems)
    svals, sbad, _ = _check_section("setup", data.get("setup", {}), PSTSetup, problems)
    ovals, _, _ = _check_section("output", data.get("output", {}), Output, problems)
    if not all(isinstance(data.get(t, {}), dict) for t in ("params", "setup", "output")):
        return None, []  # a section that is no table: the rest would check its defaults

    profile_notes: list[str] = []
    if "profile" in data:
        pvals, profile_notes = _profile_values(data["profile"], pvals, base_dir, problems)
    strength_notes: list[str] = []
    resolve = None
    if "strength" in data:
        table = _strength_table(data["strength"], "strength_profile" in pvals, problems)
        if table is not None:

            def resolve(setup: PSTSetup, params: PSTParams) -> PSTParams:
                prof, notes = _strength_profile(table, params, setup, base_dir, problems)
                strength_notes.extend(notes)
                return (
                    params if prof is None else dataclasses.replace(params, strength_profile=prof)
                )

    given = {**pvals, **svals}
    try:
        prep = pst.prepare(
            PSTParams(**pvals),
            PSTSetup(**svals),
            given=pgiven,
            resolve=resolve,
            max_particles=MAX_PARTICLES,
            caller="scenario",
        )
    except InputError as exc:
        bad = pbad | sbad  # their kind was reported: the checks saw the default
        problems += toml_lines([p for p in exc.problems if p.field not in bad], given)
        # a unit mix-up (E = 4 Pa: did you mean 4 MPa?) explains the problems it causes
        return None, toml_lines(exc.notes, given)
    if problems:
        return None, []
    scn = Scenario(
        name=data.get("name"),
        params=prep.params,
        setup=prep.setup,
        description=data.get("description", ""),
        output=Output(**ovals),
        type="pst",
    )
    object.__setattr__(scn, "_prepared", prep)
    notes = [n for n in prep.notes if n.category != "resolution"]
    return scn, profile_notes + strength_notes + toml_lines(notes, given)


def warn_resolution(scn: Scenario) -> None:
    """The warnings of `damjax.pst.prepare` that are not dubious values (dx > Lambda/5)."""
    for note in prepared(scn).notes:
        if note.category == "resolution":
            warnings.warn(note.text(), stacklevel=3)


def prepare(scn: Scenario) -> pst.Prepared:
    """`damjax.pst.prepare` of a scenario's parameters and setup."""
    return pst.prepare(scn.params, scn.setup, caller="scenario")


def _profile_values(
    table: Any, pvals: dict[str, Any], base_dir: str | Path | None, problems: list[str]
) -> tuple[dict[str, Any], list[str]]:
    """``pvals`` with the ``[profile]`` table's slab (`damjax.snow_profiles.pst_params`:
    thickness, density, youngs_modulus, slope_deg, tau_peak) under the keys written in
    ``[params]``, and the reader's warnings as notes; ``pvals`` unchanged on problems."""
    from damjax import snow_profiles

    if not isinstance(table, dict):
        problems.append(f"profile = {_fmt(table)}: must be a table ([profile])")
        return pvals, []
    n0 = len(problems)
    unknown_keys(table, PROFILE_KEYS, "profile", problems)
    file = table.get("file")
    if "file" not in table:
        problems.append("profile.file: missing (a CAAML 6 .xml/.caaml or SNOWPACK .pro file)")
    elif not isinstance(file, str) or not file:
        problems.append(f"profile.file = {_fmt(file)}: must be a path (a string)")
    wl = table.get("weak_layer")
    if wl is not None and (not isinstance(wl, int) or isinstance(wl, bool) or wl < 1):
        problems.append(
            f"profile.weak_layer = {_fmt(wl)}: must be an integer >= 1 (a layer index, 0 = "
            "the top layer, which has no slab above it)"
        )
    modulus = table.get("modulus", "scapozza")
    if modulus not in snow_profiles.MODULUS_RELATIONS:
        valid = "{" + ", ".join(f'"{c}"' for c in snow_profiles.MODULUS_RELATIONS) + "}"
        problems.append(f"profile.modulus = {_fmt(modulus)}: must be one of {valid}")
    for key in ("vertical", "use_strength"):
        if key in table and not isinstance(table[key], bool):
            problems.append(f"profile.{key} = {_fmt(table[key])}: must be true or false")
    date = table.get("date")
    if date is not None and not isinstance(date, str):
        problems.append(f'profile.date = {_fmt(date)}: must be ISO text ("2017-11-14T12:00")')
    if len(problems) > n0:
        return pvals, []
    path = Path(file)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    given = {k: v for k, v in pvals.items() if k != "strength_profile"}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            params = snow_profiles.pst_params(
                path,
                wl,
                modulus=modulus,
                vertical=table.get("vertical", False),
                use_strength=table.get("use_strength", True),
                date=date,
                **given,
            )
        except (FileNotFoundError, ImportError) as exc:
            problems.append(f"profile.file = {_fmt(file)}: {exc}")
            return pvals, []
        except ValueError as exc:
            msg = str(exc)
            if "weak_layer = " in msg:
                msg = "profile." + msg[msg.index("weak_layer = ") :]
            else:
                msg = f"profile.file = {_fmt(file)}: {msg}"
            problems.append(msg)
            return pvals, []
    out = dict(pvals)
    for name in ("thickness", "density", "youngs_modulus", "slope_deg", "tau_peak"):
        out[name] = float(getattr(params, name))
    notes = [f"profile.file = {_fmt(file)}: {w.message}" for w in caught]
    return out, notes


def _strength_table(table: Any, has_profile: bool, problems: list[str]) -> dict | None:
    """The ``[strength]`` table's keys checked (None on problems): ``file`` (CSV with
    columns x_m, tau_peak_pa), ``fit`` ("none": the CSV is tau_p along the PST;
    "linear"/"power_law": a measured transect fitted, shifted to params.tau_peak at
    params.steady_length and extrapolated, see `damjax.fields.pst_strength_profile`),
    ``points`` (samples over [0, L]; default one per grid node)."""
    if not isinstance(table, dict):
        problems.append(f"strength = {_fmt(table)}: must be a table ([strength])")
        return None
    n0 = len(problems)
    unknown_keys(table, STRENGTH_KEYS, "strength", problems)
    if has_profile:
        problems.append("strength: give either [strength] or params.strength_profile, not both")
    file = table.get("file")
    if "file" not in table:
        problems.append("strength.file: missing (a CSV with columns x_m, tau_peak_pa)")
    elif not isinstance(file, str) or not file:
        problems.append(f"strength.file = {_fmt(file)}: must be a path (a string)")
    fit = table.get("fit", "none")
    if fit not in fields.PROFILE_FITS:
        valid = "{" + ", ".join(f'"{c}"' for c in fields.PROFILE_FITS) + "}"
        problems.append(f"strength.fit = {_fmt(fit)}: must be one of {valid}")
    points = table.get("points")
    if points is not None and (
        not isinstance(points, int) or isinstance(points, bool) or points < 2
    ):
        problems.append(f"strength.points = {_fmt(points)}: must be an integer >= 2")
    return None if len(problems) > n0 else table


def _strength_profile(
    table: dict,
    params: PSTParams,
    setup: PSTSetup,
    base_dir: str | Path | None,
    problems: list[str],
) -> tuple[np.ndarray | None, list[str]]:
    """The checked ``[strength]`` table as a ``strength_profile`` array sampled on the
    (valid) setup's grid (None on problems, appended), and the reader's warnings."""
    for name in ("tau_peak", "steady_length"):
        v = getattr(params, name)
        if np.ndim(v) != 0 or math.isnan(float(v)):
            return None, []  # reported by the params checks
    file, fit, points = table["file"], table.get("fit", "none"), table.get("points")
    path = Path(file)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    num = points if points is not None else max(2, int(round(setup.length / setup.dx)) + 1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            prof = fields.pst_strength_profile(
                path,
                setup.length,
                num,
                fit=fit,
                steady_length=float(params.steady_length),
                tau_peak=float(params.tau_peak),
            )
        except FileNotFoundError:
            problems.append(f"strength.file = {_fmt(file)}: no such file ({path})")
            return None, []
        except (OSError, UnicodeDecodeError) as exc:
            problems.append(f"strength.file = {_fmt(file)}: cannot read: {exc}")
            return None, []
        except ValueError as exc:
            problems.append(f"strength.file = {_fmt(file)}: {exc}")
            return None, []
    notes = [f"strength.file = {_fmt(file)}: {w.message}" for w in caught]
    return prof, notes


register("pst", check, warn_resolution, prepare)
