import math

import numpy as np
import pytest

from damjax import PSTParams, theory


def test_baseline_numbers_match_physics_notes():
    p = PSTParams()
    assert theory.gravity_shear(p) == pytest.approx(703, abs=1)
    assert theory.residual_shear(p) == pytest.approx(512, abs=1)
    assert theory.quasi_static_gradient(p) == pytest.approx(383, abs=1)
    assert theory.elastic_length(p) == pytest.approx(0.66, abs=0.01)
    assert theory.tensile_length(PSTParams(tensile_strength=6000.0)) == pytest.approx(15.7, abs=0.1)
    # runaway gradient = k_f h / lambda (k_f h = tau_g - tau_r), lambda = sqrt(E h D / G)
    lam = math.sqrt(4e6 * 0.5 * 0.04 / 2.0e5)  # free strip: E' = E
    assert theory.runaway_gradient(p) == pytest.approx(383.4 * 0.5 / lam, rel=2e-3)
    assert theory.runaway_gradient(p) == pytest.approx(303, abs=1)
    cs = theory.shear_wave_speed(p)
    assert theory.longitudinal_wave_speed(p, "constrained") / cs == pytest.approx(1.69, abs=0.01)
    assert theory.longitudinal_wave_speed(p, "free") / cs == pytest.approx(1.61, abs=0.01)


def test_dynamic_gradient_limits():
    p = PSTParams()
    kf = theory.quasi_static_gradient(p)
    assert theory.dynamic_gradient(p, 0.0) == pytest.approx(kf)
    for lateral in ("free", "constrained"):
        cp = theory.longitudinal_wave_speed(p, lateral)
        assert theory.dynamic_gradient(p, cp, lateral) == pytest.approx(kf / 2)
    # the two lateral conditions differ by ~4.5 % at 1.6 c_s (physics notes)
    a = 1.6 * theory.shear_wave_speed(p)
    ratio = theory.dynamic_gradient(p, a, "constrained") / theory.dynamic_gradient(p, a, "free")
    assert 1.03 < ratio < 1.06


def test_dimensionless_numbers_and_jax_inputs():
    import jax.numpy as jnp

    p = PSTParams(strength_gradient=500.0, softening=1.0, tensile_strength=6000.0)
    pi1 = theory.elastic_number(p)
    assert pi1 == pytest.approx(703.0 / (500 * 0.663 * math.sqrt(2)), rel=0.01)
    assert theory.plastic_number(p) == pytest.approx(pi1 * math.sqrt(6000 / 703.0), rel=0.01)
    pj = PSTParams(youngs_modulus=jnp.asarray([2e6, 4e6]))
    assert np.asarray(theory.elastic_length(pj)).shape == (2,)


def test_unknown_lateral_condition_is_an_error():
    with pytest.raises(ValueError, match="lateral"):
        theory.strip_modulus(PSTParams(), "sideways")


@pytest.mark.parametrize(
    "fn",
    [
        "critical_cut_length",
        "runaway_gradient",
        "bar_length",
        "shear_wave_speed",
        "tensile_length",
        "plastic_number",
        "residual_shear",
    ],
)
def test_theory_is_differentiable_in_every_field(fn):
    """Each field alone may be the traced one (a single jax.grad argument): the functions
    must switch to jax.numpy whenever any field is a JAX value."""
    import dataclasses

    import jax

    base = PSTParams(tensile_strength=6000.0, strength_gradient=100.0)
    f = getattr(theory, fn)
    for field in dataclasses.fields(PSTParams):
        x0 = getattr(base, field.name)
        if not isinstance(x0, float) or not math.isfinite(x0):
            continue
        h = 1e-6 * max(abs(x0), 1.0)
        g = jax.grad(lambda t, n=field.name: f(dataclasses.replace(base, **{n: t})))(x0)
        up = f(dataclasses.replace(base, **{field.name: x0 + h}))
        try:
            dn = f(dataclasses.replace(base, **{field.name: x0 - h}))
            fd = (up - dn) / (2 * h)
        except ValueError:  # x0 on its range's lower end (softening 0): one-sided
            fd = (up - f(base)) / h
        assert float(g) == pytest.approx(float(fd), rel=2e-2, abs=1e-5 * (1 + abs(float(up)))), (
            field.name
        )


def test_bad_parameters_and_arguments_get_one_line():
    """The closed forms check their concrete parameters as a run does: a NaN or a number
    outside the field's range is one line naming it, not a NaN or a wrong value."""
    for fn, p, needle in (
        (theory.shear_wave_speed, PSTParams(density=-250.0), "density (--density) = -250.0"),
        (theory.elastic_length, PSTParams(wl_thickness=0.0), "wl_thickness (--wl-thickness)"),
        (theory.gravity_shear, PSTParams(slope_deg=-10.0), "slope_deg (--slope-deg) = -10.0"),
        (theory.pst_critical_cut_length, PSTParams(thickness=0.0), "must be in (0, inf) m"),
    ):
        with pytest.raises(ValueError, match=f"theory.{fn.__name__}: .*") as exc:
            fn(p)
        assert needle in str(exc.value)
    for speed in (-100.0, float("nan"), "100"):
        with pytest.raises(ValueError, match="crack_speed = .*must be a number >= 0 m/s"):
            theory.dynamic_gradient(PSTParams(), speed)
    with pytest.raises(TypeError, match="takes a damjax.PSTParams .*dict has no field"):
        theory.shear_wave_speed({"density": 250.0})
    # batches and traced values pass
    np.testing.assert_allclose(
        theory.elastic_length(PSTParams(thickness=PSTParams().thickness * np.array([1.0, 4.0]))),
        theory.elastic_length(PSTParams()) * np.array([1.0, 2.0]),
    )
