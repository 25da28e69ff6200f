"""Parameter inversion through the solver: `invert` recovers `PSTParams` fields from
observed arrest positions [m] by gradient descent on the smooth arrest position
(`damjax.arrest_position_smooth`), with the Gauss-Newton Hessian of the misfit at the
optimum as identifiability diagnostic.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import warnings
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from damjax import pst
from damjax.core.loop import cpu_compiler_options
from damjax.core.model import check_layout
from damjax.params import PSTParams, PSTSetup
from damjax.validation import InputError, as_number, check_width, expect_types, param_problems


@dataclasses.dataclass
class Inversion:
    """Result of `invert`.

    Attributes:
        estimates: the fitted fields at the best iterate (lowest loss), by name.
        loss: the misfit sum ((L_smooth - L_obs) / noise_std)^2 [-] at the estimates:
            ``history[best_step]``, the smallest entry of ``history``.
        history: the misfit at every iterate, the start included: ``steps + 1`` values
            (``history[0]`` at ``params0``, ``history[k]`` after k Adam updates).
        best_step: the index in ``history`` of the estimates.
        stop_reason: "steps" (every Adam update ran), "zero_gradient" (the misfit does
            not change with the fitted fields at an iterate: no fit, warned) or
            "invalid_iterate" (an iterate left the valid range, warned).
        path: the fitted fields' values at every iterate of ``history``, by name.
        hessian: Gauss-Newton Hessian of the misfit in log-parameter space at the
            estimates.
        condition_number: of ``hessian`` (inf where singular: the fields are not
            identifiable from these observations).
        std_errors: one-sigma errors of the estimates from ``hessian`` and the assumed
            noise, by name, in the fields' units. A local, linearised measure: it holds
            at a minimum (``history`` flat at its end); after a few steps, or along a
            valley of the misfit (a large ``condition_number``), it can exceed the
            estimate itself.
    """

    estimates: dict[str, float]
    loss: float
    history: list[float]
    hessian: np.ndarray  # Gauss-Newton Hessian of the misfit in log-parameter space
    condition_number: float
    std_errors: dict[str, float]  # from the Hessian and the assumed noise
    best_step: int = 0
    stop_reason: str = "steps"
    path: dict[str, list[float]] = dataclasses.field(default_factory=dict)


def _positive_scalar(value: Any) -> bool:
    """A finite scalar number > 0 (None, arrays and strings are not)."""
    try:
        return np.ndim(value) == 0 and math.isfinite(float(value)) and float(value) > 0
    except (TypeError, ValueError):
        return False


def _stopped_early(who: str, k: int, exc: Exception) -> None:
    """Warn that a fit stopped at iterate ``k`` whose parameters left their valid range."""
    first = next((ln for ln in str(exc).splitlines() if ln.strip()), str(exc))
    warnings.warn(
        f"{who}: stopped at iterate {k}, whose parameters left their valid range "
        f"({first.strip()[:300]}); the best iterate before it is returned (a smaller "
        "learning_rate, or observations the model can reach)",
        stacklevel=3,
    )


def _zero_gradient(who: str, k: int, g: Any, values: dict[str, float]) -> bool:
    """Warn and say True when the gradient is exactly zero at iterate ``k``: the loss
    does not change with the fitted fields there (every run ends the same way: e.g. no
    crack left the saw cut, or all stopped at the same place), so the iterations cannot
    move towards the observations and the result is no fit."""
    if not bool(np.all(np.asarray(g) == 0.0)):
        return False
    at = ", ".join(f"{f} = {v:.6g}" for f, v in values.items() if f != "loss")
    warnings.warn(
        f"{who}: the loss's gradient is exactly zero at iterate {k} ({at}): the runs end "
        "the same way for nearby values (a crack that never leaves the saw cut, or that "
        "stops at the same place in every run), so no step can improve the fit; stopped "
        "(stop_reason 'zero_gradient'). Start from other values, or check that the model "
        "can reach the observations",
        stacklevel=3,
    )
    return True


def optimizer_problems(steps: Any, learning_rate: Any, tol: Any = None) -> list[str]:
    """The problems of an optimiser's arguments (`invert`, `calibrate_slope`): ``steps``
    an integer >= 1, ``learning_rate`` a number in (0, inf), ``tol`` (where given) a
    number in [0, inf)."""
    out = []
    if isinstance(steps, bool) or not isinstance(steps, numbers.Integral) or steps < 1:
        out.append(f"steps = {steps!r}: must be an integer >= 1 (optimiser iterations)")
    if isinstance(learning_rate, bool) or not _positive_scalar(learning_rate):
        out.append(f"learning_rate = {learning_rate!r}: must be a number in (0, inf)")
    if tol is not None:
        ok = not isinstance(tol, bool) and np.ndim(tol) == 0
        try:
            ok = ok and math.isfinite(float(tol)) and float(tol) >= 0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            out.append(f"tol = {tol!r}: must be a number in [0, inf)")
    return out


def _observation_pairs(observations: Any) -> list[tuple[dict[str, float], float]]:
    """``observations`` as a list of (overrides, L_observed) pairs; ValueError naming the
    form when it is not one (a plain array of arrest positions has no overrides)."""
    form = (
        "observations: must be a list of (overrides, L_observed) pairs, e.g. "
        '[({"strength_gradient": 500.0}, 6.9), ...]: each PST its overrides of params0 '
        "(a dict, {} for none) and its observed arrest position [m]"
    )
    try:
        pairs = list(observations)
    except TypeError:
        raise ValueError(form) from None
    for p in pairs:
        if isinstance(p, (str, bytes)) or not hasattr(p, "__len__") or len(p) != 2:
            raise ValueError(form)
        if not isinstance(p[0], dict):
            raise ValueError(form)
    return [(dict(p[0]), p[1]) for p in pairs]


def invert(
    observations: Sequence[tuple[dict[str, float], float]],
    params0: Any,
    setup: Any,
    fields: Sequence[str],
    *,
    noise_std: float = 1.0,
    steps: int = 60,
    learning_rate: float = 0.05,
    progress: bool = False,
    smooth_width: float | None = None,
    layout: Any = None,
) -> Inversion:
    """Recover ``fields`` of `PSTParams` from observed arrest positions [m].

    ``observations`` is a list of (overrides, L_observed): each PST is ``params0`` with
    the overrides (e.g. ``{"strength_gradient": 300.0}``) and was observed to arrest at
    L_observed. Minimises sum (L_smooth - L_obs)^2 / noise_std^2 with optax Adam over
    the logarithms of the fields (positivity), gradients through the full solver
    (`damjax.arrest_position_smooth`). One observation cannot identify two fields: the
    returned Gauss-Newton Hessian then is singular (condition number inf).
    ``smooth_width``: None (default) differentiates the continuous crack length; a
    damage-ramp width (0.5) where slab fractures stop the crack
    (`damjax.diagnostics.smooth_arrest_position`). ``layout``: the runs' layout
    (`damjax.make_layout`), default made from ``params0``; where a fitted field or an
    override fixes it (youngs_modulus, density, ...: a stiffer slab needs a shorter time
    step), make it from the stiffest parameters the fit may reach.
    The estimates are the best iterate (lowest loss) of the Adam run, the last one
    included, not the last: Adam's iterates oscillate around the minimum. ``steps`` Adam
    updates evaluate ``steps + 1`` iterates (`Inversion.history`).
    """
    if isinstance(fields, str):  # one name, not its letters
        fields = (fields,)
    setup = PSTSetup() if setup is None else setup
    expect_types("invert", params0=(params0, PSTParams), setup=(setup, PSTSetup))
    observations = _observation_pairs(observations)
    known = {f.name for f in dataclasses.fields(params0)}
    problems = [f"fields: {f!r} is not a PSTParams field" for f in fields if f not in known]
    if not problems:
        problems = [
            f"params0.{f} = {getattr(params0, f)!r}: a fitted field must be in (0, inf) "
            "(the fit runs on its logarithm); start from a positive value"
            for f in fields
            if not _positive_scalar(getattr(params0, f))
        ]
    if not fields:
        problems.append("fields: empty; name at least one PSTParams field to fit")
    dup = sorted({f for f in fields if list(fields).count(f) > 1})
    if dup:
        problems.append(f"fields: {dup} named more than once")
    if isinstance(noise_std, bool) or not _positive_scalar(noise_std):
        problems.append(f"noise_std = {noise_std!r}: must be a number in (0, inf) [m]")
    try:
        check_width(smooth_width)
    except ValueError as e:
        problems.append(f"smooth_{e}")
    for i, (over_i, _) in enumerate(observations):
        bad = sorted(k for k in over_i if k not in known)
        if bad:
            problems.append(f"observations[{i}]: overrides {bad} are not PSTParams fields")
        fitted = sorted(k for k in over_i if k in fields)
        if fitted:
            problems.append(
                f"observations[{i}]: overrides {fitted}, fitted fields: the fit sets them in "
                "every run (leave them out of the overrides, or fit other fields)"
            )
        problems += [
            f"observations[{i}]: override {k} = {v!r}: must be a number"
            for k, v in over_i.items()
            if k in known and k not in fields and as_number(v) is None
        ]
    if not observations:
        problems.append("observations: empty; give at least one (overrides, L_observed) pair")
    for i, (_, observed) in enumerate(observations):
        if as_number(observed) is None or not math.isfinite(float(observed)):
            problems.append(
                f"observations[{i}]: L_observed = {observed!r}: must be a finite arrest "
                "position [m] (a run that did not arrest has none: NaN)"
            )
        elif not 0.0 < float(observed) <= float(setup.length):
            problems.append(
                f"observations[{i}]: L_observed = {observed!r}: must be in (0, "
                f"{float(setup.length):g}] m, an arrest inside the PST (setup.length)"
            )
    problems += optimizer_problems(steps, learning_rate)
    if not problems:  # the runs at the start, as given (not after a float32 round trip)
        lines = [
            [
                e.text(lambda f: f)
                for e in param_problems(
                    dataclasses.replace(params0, **{k: float(v) for k, v in o.items()}), setup
                )
            ]
            for o, _ in observations
        ]
        common = [ln for ln in lines[0] if all(ln in other for other in lines)]
        problems += [f"params0: {ln}" for ln in common]  # once, not per observation
        problems += [
            f"observations[{i}]: {ln}"
            for i, own in enumerate(lines)
            for ln in own
            if ln not in common
        ]
    if problems:
        raise ValueError("\n".join(problems))
    if layout is not None:
        from damjax.core.model import Layout

        expect_types("invert", layout=(layout, Layout))
    layout = pst.make_layout(params0, setup) if layout is None else layout
    x0 = jnp.asarray([math.log(float(getattr(params0, f))) for f in fields])
    over = [{k: float(v) for k, v in o.items()} for o, _ in observations]
    obs = jnp.asarray([float(L) for _, L in observations])

    def predict(x: Any) -> Any:
        fitted = {f: jnp.exp(x[i]) for i, f in enumerate(fields)}
        return jnp.stack(
            [
                pst.arrest_position_smooth(
                    dataclasses.replace(params0, **{**o, **fitted}),
                    setup,
                    layout,
                    width=smooth_width,
                )
                for o in over
            ]
        )

    def loss(x: Any) -> Any:
        return jnp.sum(((predict(x) - obs) / noise_std) ** 2)

    vg = jax.jit(jax.value_and_grad(loss), compiler_options=cpu_compiler_options())
    import optax  # deferred: importing damjax stays light

    opt = optax.adam(learning_rate)
    x, st = x0, opt.init(x0)
    hist = []
    it: Any = range(steps)
    if progress:
        from damjax._progress import progress_bar as tqdm

        it = tqdm(it, desc="invert")
    best_x, best, best_step = x, math.inf, 0
    reason = "steps"
    path: dict[str, list[float]] = {f: [] for f in fields}

    def check_iterate(x: Any) -> None:
        # the jitted gradient sees tracers: the concrete iterate is checked here, every
        # field, how they fit together (a tau_peak below tau_g: a failed layer) and the
        # layout's time step (a stiffer slab needs a shorter one)
        fitted = {f: float(jnp.exp(x[i])) for i, f in enumerate(fields)}
        for o in over:
            p = dataclasses.replace(params0, **{**o, **fitted})
            problems = param_problems(p, setup)
            if problems:
                raise InputError(problems)
            check_layout(p, setup, layout)

    for k in it:
        try:
            check_iterate(x)
            val, g = vg(x)
        except (ValueError, RuntimeError) as exc:  # an iterate outside the valid range
            if not hist:
                raise
            _stopped_early("invert", k, exc)
            reason = "invalid_iterate"
            x = best_x
            break
        hist.append(float(val))
        values = {f: float(jnp.exp(x[i])) for i, f in enumerate(fields)}
        for f in fields:
            path[f].append(values[f])
        if float(val) < best:  # Adam's iterates oscillate: keep the best one seen
            best_x, best, best_step = x, float(val), k
        if _zero_gradient("invert", k, g, values):
            reason = "zero_gradient"
            break
        upd, st = opt.update(g, st)
        x = optax.apply_updates(x, upd)
    else:  # the iterate after the last update is one of them too
        try:
            check_iterate(x)
            hist.append(float(loss(x)))
            for i, f in enumerate(fields):
                path[f].append(float(jnp.exp(x[i])))
        except (ValueError, RuntimeError) as exc:
            _stopped_early("invert", len(hist), exc)
            reason = "invalid_iterate"
        else:
            if hist[-1] < best:
                best_x, best, best_step = x, hist[-1], len(hist) - 1
    x = best_x
    J = np.asarray(jax.jit(jax.jacfwd(predict))(x)) / noise_std  # (n_obs, n_fields)
    H = 2.0 * J.T @ J
    eig = np.linalg.eigvalsh(H)
    cond = float(eig[-1] / eig[0]) if eig[0] > 1e-12 * max(eig[-1], 1e-300) else math.inf
    est = {f: float(jnp.exp(x[i])) for i, f in enumerate(fields)}
    if math.isfinite(cond):
        cov = np.linalg.inv(0.5 * H)
        se = {f: est[f] * math.sqrt(max(cov[i, i], 0.0)) for i, f in enumerate(fields)}
    else:
        se = {f: math.inf for f in fields}
    return Inversion(est, best, hist, H, cond, se, best_step, reason, path)
