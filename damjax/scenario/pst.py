"""PST scenarios (``type = "pst"``): the ``[params]``, ``[setup]`` and ``[strength]``
tables of a PST run checked against `damjax.PSTParams` / `damjax.PSTSetup` and the rules
of `damjax.validation` (the format: `damjax.scenario.schema`).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from damjax import fields
from damjax.params import PSTParams, PSTSetup
from damjax.scenario.schema import (
    MAX_PARTICLES,
    PROFILE_KEYS,
    STRENGTH_KEYS,
    Output,
    Scenario,
    _check_section,
    _fmt,
    _retarget,
    register,
    unknown_keys,
)
from damjax.validation import dubious, param_problems, setup_problems, validate


def check(
    data: dict[str, Any], base_dir: str | Path | None, problems: list[str]
) -> tuple[Scenario | None, list[str]]:
    """The Scenario of a PST document (None with problems appended) and its dubious-value
    notes. Top-level keys, type and name are checked by the caller (`schema.parse`)."""
    for table in ("terrain", "snow"):
        if table in data:
            problems.append(f'{table}: only for type = "slope" scenarios')
    pvals, pbad, pgiven = _check_section("params", data.get("params", {}), PSTParams, problems)
    svals, sbad, sgiven = _check_section("setup", data.get("setup", {}), PSTSetup, problems)
    ovals, _, _ = _check_section("output", data.get("output", {}), Output, problems)

    reported = {f"params.{k}" for k in pbad} | {f"setup.{k}" for k in sbad}
    profile_notes: list[str] = []
    if "profile" in data:
        pvals, profile_notes = _profile_values(data["profile"], pvals, base_dir, problems)
    params = PSTParams(**pvals)
    setup = PSTSetup(**svals)
    strength_notes: list[str] = []
    if "strength" in data:
        prof, strength_notes = _strength_profile(
            data["strength"], params, setup, "strength_profile" in pvals, base_dir, problems
        )
        if prof is not None:
            params = dataclasses.replace(params, strength_profile=prof)
    # field ranges and consistency (damjax.validation's rules), as validate() orders them
    sprob = setup_problems(setup)
    if sprob:
        lines = sprob + param_problems(params, None)
    else:
        lines = param_problems(params, setup)
        if not lines and not reported:
            lines = _size_problems(params, setup)
    given = {f"params.{k}": v for k, v in pvals.items()}
    given.update({f"setup.{k}": v for k, v in svals.items()})
    problems += _retarget(lines, reported, given)
    if problems:
        return None, []
    scn = Scenario(
        name=data.get("name"),
        params=params,
        setup=setup,
        description=data.get("description", ""),
        output=Output(**ovals),
        type="pst",
    )
    notes = profile_notes + strength_notes
    return scn, notes + dubious(params, setup, pgiven, style="toml")


def warn_resolution(scn: Scenario) -> None:
    """`damjax.validation.validate`'s warnings that are not dubious values (dx > Lambda/5)."""
    validate(scn.params, scn.setup, warn_dubious=False)


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
    if wl is not None and (not isinstance(wl, int) or isinstance(wl, bool) or wl < 0):
        problems.append(f"profile.weak_layer = {_fmt(wl)}: must be an integer >= 0 (0 = top)")
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


def _strength_profile(
    table: Any,
    params: PSTParams,
    setup: PSTSetup,
    has_profile: bool,
    base_dir: str | Path | None,
    problems: list[str],
) -> tuple[np.ndarray | None, list[str]]:
    """The ``[strength]`` table as a ``strength_profile`` array (None on problems).

    Keys: ``file`` (CSV with columns x_m, tau_peak_pa; relative to ``base_dir``), ``fit``
    ("none": the CSV is tau_p along the PST; "linear"/"power_law": a measured transect
    fitted, shifted to params.tau_peak at params.steady_length and extrapolated, see
    `damjax.fields.pst_strength_profile`), ``points`` (samples over [0, L]; default one
    per grid node).
    """
    if not isinstance(table, dict):
        problems.append(f"strength = {_fmt(table)}: must be a table ([strength])")
        return None, []
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
    if len(problems) > n0 or setup_problems(setup):
        return None, []
    for name in ("tau_peak", "steady_length"):
        v = getattr(params, name)
        if np.ndim(v) != 0 or math.isnan(float(v)):
            return None, []  # reported by the params checks
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


def _size_problems(params: PSTParams, setup: PSTSetup) -> list[str]:
    """Runs too large to allocate (a clean error instead of a MemoryError)."""
    ppc = int(setup.particles_per_cell)
    n = max(1.0, setup.length / setup.dx) * ppc
    if setup.dim == 2:
        n *= (3 if setup.lateral == "constrained" else max(1.0, setup.width / setup.dx)) * ppc
    if n > MAX_PARTICLES:
        return [
            f"setup.length = {setup.length!r}: with setup.dx = {setup.dx!r} and "
            f"setup.particles_per_cell = {ppc} the run has {n:.3g} particles: must be at "
            f"most {MAX_PARTICLES:.0e}"
        ]
    return []


register("pst", check, warn_resolution)
