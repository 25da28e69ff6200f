"""Check a gradient of the crack length on your own case.

A brittle weak layer makes the event-based arrest position a staircase in every
parameter, so a finite difference smaller than one particle step says nothing. What a
calibration needs is the trend: `gradient_check` compares the reverse-mode gradient of
the continuous crack length (`damjax.arrest_position_smooth`) with the least-squares
slope of the event-based arrest over a window of the parameter::

    check = damjax.gradient_check(params, setup, "strength_gradient")
    print(check)   # AD vs event-based slope, the window, the verdict

The window runs as one vmapped `damjax.sweep` and one vmapped gradient (about four
forward runs per member). The verdict compares the window mean of the AD derivative with
the slope (`damjax.diagnostics.GradientCheck` says why); the derivative at the centre is
reported too. Measured on a 40 m PST (L_ss 10 m, theta 800 Pa/m, dx 0.04 m, softening 0,
float64, theta 720-880 Pa/m, 2026-11-25): AD mean -0.01716, at the centre -0.01647,
event-based slope -0.01723 m/(Pa/m); the derivative runs from about -0.021 to -0.012
across the window as L_ca flattens with theta.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax import pst
from damjax.core.model import make_layout
from damjax.diagnostics import GradientCheck, compare_gradient
from damjax.params import PROFILE_FIELDS, PSTParams, PSTSetup
from damjax.sweep import _sweep
from damjax.validation import as_number, check_width, param_problems, shown, warn_notes


def _window_problems(
    params: PSTParams,
    setup: PSTSetup,
    field: str,
    window: np.ndarray,
    rel_window: float,
    dtype: Any,
) -> list[str]:
    """Lines for a window whose ends leave the valid values: each end checked as the run
    gets it (in the setup's dtype), but shown as given, not as float32 rounds it; a
    window is the user's argument, not a batch of theirs, so no member is named."""
    lo, hi = float(window[0]), float(window[-1])
    head = (
        f"{field} window [{lo:.10g}, {hi:.10g}] (rel_window = {rel_window!r} around "
        f"{field} = {getattr(params, field)!r})"
    )
    out = []
    for end, which in ((lo, "lower"), (hi, "upper")):

        def show(name: str, v: Any, end: float = end) -> str:
            return f"{end:.10g}" if name == field else shown(v)

        value = float(np.asarray(end, dtype))
        for p in param_problems(dataclasses.replace(params, **{field: value}), setup):
            if p.field == field and p.valid:
                line = f"its {which} end leaves the valid range {p.valid}"
            else:
                line = f"at its {which} end, {p.text(show=show)}"
            out.append(f"{head}: {line}; narrow the window (rel_window)")
    return out


def gradient_check(
    params: PSTParams,
    setup: PSTSetup,
    field: str | Sequence[str],
    *,
    rel_window: float = 0.1,
    n_runs: int = 11,
    tolerance: float = 0.1,
    batch_size: int | None = None,
    width: float | None = None,
) -> GradientCheck | list[GradientCheck]:
    """AD of the continuous crack length [m] with respect to ``field`` over the window
    field x (1 - rel_window .. 1 + rel_window) (``n_runs`` runs, centred on ``params``)
    against the least-squares slope of the event-based arrest over the same runs.

    Several fields (a sequence) run as one batch: one compiled sweep and one compiled
    gradient for all their windows; the result is then a list, in the order given.

    Args:
        params: the case (concrete values); each field must be a finite, nonzero scalar.
        setup: numerics; the windows and the gradients share one layout (the time step of
            the stiffest member).
        field: a scalar field of `PSTParams`, e.g. "strength_gradient", or a sequence.
        rel_window: half-width of the window relative to the value, in (0, 0.5].
        n_runs: runs in each window, odd, in [3, 1001].
        tolerance: relative error accepted for the verdict, > 0.
        batch_size: run the forward runs and gradients in slices of this many members
            (`jax.lax.map`), bounding memory: a gradient holds about twice a forward run's
            memory per member. Default: the forward runs sliced as `damjax.sweep` slices
            them (from memory), the gradients one at a time.
        width: the damage ramp of the continuous length (`damjax.arrest_position_smooth`'s
            ``width``): None (default) for the failed fraction, or a relative width in
            (0, 1], 0.5 where slab fractures stop the crack. The reported lengths are
            those of the differentiated length.
    """
    fields = [field] if isinstance(field, str) else list(field)
    names = [f.name for f in dataclasses.fields(PSTParams)]
    scalars = [n for n in names if n not in PROFILE_FIELDS]
    problems = [
        f"field = {f!r}: must be a scalar field of PSTParams ({scalars})"
        for f in fields
        if f not in scalars
    ]
    if not fields:
        problems.append("field: empty; name at least one PSTParams field")
    if as_number(rel_window) is None or not 0.0 < rel_window <= 0.5:
        problems.append(f"rel_window = {rel_window!r}: must be in (0, 0.5]")
    if (
        isinstance(n_runs, bool)
        or not isinstance(n_runs, int)
        or not 3 <= n_runs <= 1001
        or n_runs % 2 == 0
    ):
        problems.append(f"n_runs = {n_runs!r}: must be an odd integer in [3, 1001]")
    if as_number(tolerance) is None or not tolerance > 0.0:
        problems.append(f"tolerance = {tolerance!r}: must be in (0, inf)")
    for f in fields:
        if not problems:
            x0 = getattr(params, f)
            if x0 is None or np.ndim(x0) != 0 or not np.isfinite(float(x0)) or float(x0) == 0.0:
                problems.append(f"{f} = {x0!r}: the check needs a finite, nonzero scalar value")
    try:
        check_width(width)
    except ValueError as e:
        problems.append(str(e))
    if problems:
        raise ValueError("\n".join(problems))
    warn_notes(pst.prepare(params, setup, caller="gradient_check").notes, stacklevel=2)
    dtype = jnp.float64 if setup.dtype == "float64" else jnp.float32
    x0 = np.array([float(getattr(params, f)) for f in fields])
    windows = [np.linspace(x * (1 - rel_window), x * (1 + rel_window), n_runs) for x in x0]
    lines = [
        line
        for j, f in enumerate(fields)
        for line in _window_problems(params, setup, f, windows[j], rel_window, dtype)
    ]
    if lines:
        raise ValueError("\n".join(lines))
    # member (j, i): field j at its i-th window value, every other field at params
    points = np.repeat(x0[None, :], len(fields) * n_runs, axis=0)
    for j, xs in enumerate(windows):
        points[j * n_runs : (j + 1) * n_runs, j] = xs
    pts = jnp.asarray(points, dtype)
    batch = dataclasses.replace(params, **{f: pts[:, j] for j, f in enumerate(fields)})
    # the window's members are not the user's batch: the centre's notes were warned
    results = _sweep(batch, setup, batch_size=batch_size, member_notes=False)
    arrests = np.array(
        [
            np.nan if r.summary["arrest_position_m"] is None else r.summary["arrest_position_m"]
            for r in results
        ]
    )
    layout = make_layout(batch, setup)  # the windows' time step (checked by sweep)

    def length(v: jax.Array) -> jax.Array:
        values = {f: v[j] for j, f in enumerate(fields)}
        p = dataclasses.replace(params, **values)
        return pst.arrest_position_smooth(p, setup, layout, width=width)

    # the lengths come with their gradients: the same surrogate, ``width`` included
    grad = jax.value_and_grad(length)
    lengths, ads = jax.jit(lambda v: jax.lax.map(grad, v, batch_size=batch_size))(pts)
    lengths, ads = np.asarray(lengths, float), np.asarray(ads, float)
    checks = [
        compare_gradient(
            f,
            windows[j],
            ads[j * n_runs : (j + 1) * n_runs, j],
            arrests[j * n_runs : (j + 1) * n_runs],
            tolerance,
            lengths[j * n_runs : (j + 1) * n_runs],
            resolution=setup.dx / int(setup.particles_per_cell),
        )
        for j, f in enumerate(fields)
    ]
    return checks[0] if isinstance(field, str) else checks


__all__ = ["gradient_check"]
