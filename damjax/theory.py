"""Closed forms of the paper (Meloche et al.), usable on floats, numpy or JAX arrays.

All functions take a `PSTParams`-like object (anything with the fields) and the lateral
condition of the strip where the slab modulus matters:

- ``"constrained"`` (eps_yy = 0): modulus E' = E / (1 - nu^2) (paper Eq. 8, App. A);
- ``"free"`` (sigma_yy = 0): bar modulus E.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as _np

from damjax.constants import G_ACC

try:  # theory works on JAX tracers too
    import jax.numpy as _jnp
except ImportError:  # pragma: no cover
    _jnp = _np


def _xp(p: Any) -> Any:
    """jax.numpy if any field of the parameters is a JAX array or tracer, else numpy: one
    traced field (``jax.grad`` with respect to the thickness alone) makes the result a
    JAX value."""
    try:
        import jax

        leaves = jax.tree.leaves(p)
    except ImportError:  # pragma: no cover
        return _np
    fields = [getattr(p, f) for f in getattr(p, "__dataclass_fields__", {})] or leaves
    for x in [*leaves, *fields]:
        if isinstance(x, jax.Array) or type(x).__module__.startswith("jax"):
            return _jnp
    return _np


def _checked(fn: Callable[..., Any]) -> Callable[..., Any]:
    """The closed form ``fn`` of a `PSTParams` (or an object with its fields), its
    concrete fields checked first against their declarations (`damjax.params`): a density
    of -250 gives one line naming the field and its range, not a NaN; traced fields
    (under `jax.grad`, `jax.jit`) pass unchecked."""

    @functools.wraps(fn)
    def wrapper(p: Any, *args: Any, **kwargs: Any) -> Any:
        _check_params(fn.__name__, p)
        try:
            return fn(p, *args, **kwargs)
        except AttributeError as exc:  # not a PSTParams: say which field it lacks
            if exc.obj is not p:
                raise
            raise TypeError(
                f"theory.{fn.__name__}: takes a damjax.PSTParams (or an object with its "
                f"fields); {type(p).__name__} has no field {exc.name!r}"
            ) from None

    return wrapper


def _check_params(name: str, p: Any) -> None:
    """ValueError naming the first concrete number field of ``p`` (every member of a
    batch) outside the range its declaration gives (the ``damjax`` metadata of a
    `PSTParams` field, `damjax.params.Spec`); profiles and choices are the run's to
    check, objects without declarations are not checked."""
    for field in getattr(p, "__dataclass_fields__", {}).values():
        spec = field.metadata.get("damjax")
        value = getattr(p, field.name)
        if spec is None or value is None or spec.kind != "float" or not _concrete(value):
            continue
        try:
            values = _np.asarray(value, dtype=float).ravel()
        except (TypeError, ValueError):
            values = _np.array([_np.nan])
        if isinstance(value, (str, bytes, bool)):
            values = _np.array([_np.nan])
        bad = [v for v in values if not spec.valid.holds(float(v))]
        if bad:
            shown = value if values.size == 1 or isinstance(value, (str, bytes)) else bad[0]
            label = f"{field.name} (--{field.name.replace('_', '-')})" if spec.cli else field.name
            raise ValueError(
                f"theory.{name}: {label} = {shown!r}: must be in {spec.valid} {spec.unit}".rstrip()
            )


def _concrete(value: Any) -> bool:
    import jax

    return not any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(value))


def _rad(deg: Any) -> Any:
    return deg * (_np.pi / 180.0)


@_checked
def strip_modulus(p: Any, lateral: str = "free") -> Any:
    """Longitudinal modulus of a width-uniform strip [Pa]: E (free) or E/(1-nu^2)."""
    if lateral == "free":
        return p.youngs_modulus
    if lateral == "constrained":
        return p.youngs_modulus / (1.0 - p.poisson**2)
    raise ValueError(f"lateral = {lateral!r}: must be in {{free, constrained}}")


@_checked
def shear_wave_speed(p: Any) -> Any:
    """c_s = sqrt(G / rho), G = E / (2 (1 + nu)) [m/s]."""
    xp = _xp(p)
    return xp.sqrt(p.youngs_modulus / (2.0 * (1.0 + p.poisson)) / p.density)


@_checked
def longitudinal_wave_speed(p: Any, lateral: str = "free") -> Any:
    """c_p = sqrt(E_strip / rho) [m/s] (1.61 c_s free, 1.69 c_s constrained at nu=0.3)."""
    xp = _xp(p)
    return xp.sqrt(strip_modulus(p, lateral) / p.density)


@_checked
def plane_stress_wave_speed(p: Any) -> Any:
    """Fastest wave of the 2D plane-stress slab, sqrt(E/((1-nu^2) rho)) [m/s]."""
    return longitudinal_wave_speed(p, "constrained")


@_checked
def gravity_shear(p: Any) -> Any:
    """tau_g = rho g h sin(psi): weak-layer shear stress at rest [Pa] (703 Pa baseline)."""
    xp = _xp(p)
    return p.density * G_ACC * p.thickness * xp.sin(_rad(p.slope_deg))


@_checked
def residual_shear(p: Any) -> Any:
    """tau_r = rho g h cos(psi) tan(phi): residual friction [Pa] (512 Pa baseline)."""
    xp = _xp(p)
    return (
        p.density * G_ACC * p.thickness * xp.cos(_rad(p.slope_deg)) * xp.tan(_rad(p.friction_deg))
    )


@_checked
def quasi_static_gradient(p: Any) -> Any:
    """k_f = rho g sin(psi) (1 - tan(phi)/tan(psi)) [Pa/m] (paper Eq. 7; 383 Pa/m)."""
    xp = _xp(p)
    psi, phi = _rad(p.slope_deg), _rad(p.friction_deg)
    return p.density * G_ACC * xp.sin(psi) * (1.0 - xp.tan(phi) / xp.tan(psi))


@_checked
def dynamic_gradient(p: Any, crack_speed: Any, lateral: str = "free") -> Any:
    """k_x = c_p^2 k_f / (c_p^2 + adot^2): slab tension gradient behind a crack running at
    ``crack_speed`` [m/s] (paper Eq. 8, App. A), with c_p of the lateral condition [Pa/m]."""
    if _concrete(crack_speed):
        try:
            speeds = _np.asarray(crack_speed, dtype=float)
        except (TypeError, ValueError):
            speeds = _np.array(_np.nan)
        if isinstance(crack_speed, (str, bytes)) or not _np.all(speeds >= 0):
            raise ValueError(
                f"theory.dynamic_gradient: crack_speed = {crack_speed!r}; must be a number "
                ">= 0 m/s (or an array of them)"
            )
    cp2 = strip_modulus(p, lateral) / p.density
    return cp2 * quasi_static_gradient(p) / (cp2 + crack_speed**2)


@_checked
def wl_stiffness(p: Any) -> Any:
    """K_wl = G_wl / D_wl [Pa/m]."""
    return p.wl_shear_modulus / p.wl_thickness


@_checked
def elastic_length(p: Any) -> Any:
    """Lambda = sqrt(E h D_wl / ((1 - nu^2) G_wl)) [m] (0.66 m baseline)."""
    xp = _xp(p)
    return xp.sqrt(
        p.youngs_modulus
        * p.thickness
        * p.wl_thickness
        / ((1.0 - p.poisson**2) * p.wl_shear_modulus)
    )


@_checked
def tensile_length(p: Any) -> Any:
    """L_t = sigma_t / k_f [m] (15.7 m at 6 kPa)."""
    return p.tensile_strength / quasi_static_gradient(p)


@_checked
def elastic_number(p: Any) -> Any:
    """Elastic scaling number tau_g / (theta Lambda sqrt(1 + delta)) [-] (paper Eq. 9)."""
    xp = _xp(p)
    return gravity_shear(p) / (p.strength_gradient * elastic_length(p) * xp.sqrt(1.0 + p.softening))


@_checked
def plastic_number(p: Any) -> Any:
    """Elasto-plastic number tau_g/(theta Lambda sqrt(1+delta)) sqrt(sigma_t/tau_g) (Eq. 10)."""
    xp = _xp(p)
    return elastic_number(p) * xp.sqrt(p.tensile_strength / gravity_shear(p))


@_checked
def bar_length(p: Any, lateral: str = "free") -> Any:
    """lambda = sqrt(E_s h / K_wl): decay length of a slab bar on the elastic weak layer,
    E_s the strip modulus of the lateral condition [m] (0.63 m baseline, free strip)."""
    xp = _xp(p)
    return xp.sqrt(strip_modulus(p, lateral) * p.thickness / wl_stiffness(p))


@_checked
def runaway_gradient(p: Any, lateral: str = "free") -> Any:
    """theta_run = (tau_g - tau_r) / lambda: below this strength gradient an elastic,
    brittle (delta = 0) slab never arrests a crack [Pa/m] (303 Pa/m baseline, free strip).

    The same bar model as `critical_cut_length`: with a cut of length a the shear stress at
    the tip is tau_g + (tau_g - tau_r) a / lambda, growing by (tau_g - tau_r) / lambda per
    metre of crack, while the strength grows by theta. If theta is smaller the tip stress
    outruns the strength for ever (only a finite tensile strength or the terrain stops
    the crack). Measured: theta 300 runs through a 400 m strip (12 s), theta 400 arrests at
    112.6 m.
    """
    return (gravity_shear(p) - residual_shear(p)) / bar_length(p, lateral)


@_checked
def critical_cut_length(p: Any, lateral: str = "free") -> Any:
    """Quasi-static critical cut length a_c of a brittle (delta = 0) weak layer [m].

    Beam on an elastic foundation with a cut of length a carrying the residual friction:
    the cut slab transmits the force (tau_g - tau_r) a to the intact part, whose shear
    stress at the tip then is tau_g + (tau_g - tau_r) a / lambda (lambda = sqrt(E_s h / K),
    E_s the strip modulus; semi-infinite bar under an end load). Failure when that reaches
    tau_p:  a_c = lambda (tau_p - tau_g) / (tau_g - tau_r).
    """
    tg, tr = gravity_shear(p), residual_shear(p)
    return bar_length(p, lateral) * (p.tau_peak - tg) / (tg - tr)


@_checked
def pst_critical_cut_length(p: Any, lateral: str = "free") -> Any:
    """Critical cut length of a PST's brittle weak layer whose strength is tau_p up to
    L_ss and rises by theta beyond [m]; inf where no cut starts a crack.

    The bar model of `critical_cut_length`: the tip stress tau_g + (tau_g - tau_r) a /
    lambda meets the strength at a_c = lambda (tau_p - tau_g) / (tau_g - tau_r) when
    a_c <= L_ss. Beyond L_ss the strength grows by theta per metre and the tip stress by
    theta_run (`runaway_gradient`): the cut meets it at
    a = (tau_p - tau_g - theta L_ss) / (theta_run - theta) where theta < theta_run, and
    never where theta >= theta_run (the saw then cuts on and the crack never runs by
    itself). Measured (SNOWPACK example profile, weak layer 7, L_ss 2 m, theta 500 Pa/m,
    2026-11-27): a_c = 3.30 m on the uniform layer, theta_run 66.6 Pa/m, and the saw cut
    the whole 5 m PST without a crack running ahead of it.
    """
    xp = _xp(p)
    a_c = critical_cut_length(p, lateral)
    theta, lss = p.strength_gradient, p.steady_length
    theta_run = runaway_gradient(p, lateral)
    gap = theta_run - theta
    beyond = (p.tau_peak - gravity_shear(p) - theta * lss) / xp.where(gap > 0, gap, 1.0)
    return xp.where(a_c <= lss, a_c, xp.where(gap > 0, beyond, xp.inf))
