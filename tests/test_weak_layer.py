"""Unit tests of the quasi-brittle interface law (paper Fig. 1b)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from damjax.materials import weak_layer as wl

K, TAU_P, TAU_R = 5e6, 1000.0, 512.0


def traction(u, u_max, delta, tau_p=TAU_P, broken=False):
    k = wl.cohesive_factor(
        jnp.asarray(u_max), jnp.asarray(tau_p), TAU_R, K, jnp.asarray(delta), jnp.asarray(broken)
    )
    return float(k * u)


def test_elastic_branch_and_peak():
    uc = TAU_P / K
    assert traction(0.5 * uc, 0.5 * uc, 1.0) == pytest.approx(0.5 * TAU_P)
    assert traction(uc * (1 - 1e-6), uc * (1 - 1e-6), 1.0) == pytest.approx(TAU_P, rel=1e-5)


def test_linear_softening_to_residual():
    uc = TAU_P / K
    delta = 2.0
    ur = uc * (1 + delta)
    mid = 0.5 * (uc + ur)
    assert traction(mid, mid, delta) == pytest.approx(0.5 * (TAU_P + TAU_R), rel=1e-5)
    assert traction(ur * 0.999999, ur * 0.999999, delta) == pytest.approx(TAU_R, rel=1e-4)
    u_c, u_r = wl.critical_displacements(TAU_P, K, delta)
    assert bool(wl.is_broken(jnp.asarray(u_r), u_r, jnp.asarray(False)))
    assert not bool(wl.is_broken(jnp.asarray(0.99 * u_r), u_r, jnp.asarray(False)))


def test_damage_is_irreversible_secant_unloading():
    uc = TAU_P / K
    delta = 1.0
    u_hist = 1.5 * uc  # reached in the softening zone
    env = TAU_P - (TAU_P - TAU_R) * 0.5
    # unloading to half the displacement follows the secant, not the elastic slope
    assert traction(0.75 * uc, u_hist, delta) == pytest.approx(env / 2, rel=1e-5)
    assert traction(0.75 * uc, 0.75 * uc, delta) == pytest.approx(0.75 * TAU_P, rel=1e-5)


def test_brittle_and_broken_have_no_cohesion():
    uc = TAU_P / K
    assert traction(uc, uc, 0.0, broken=True) == 0.0
    assert traction(0.1 * uc, 0.1 * uc, 0.0, broken=True) == 0.0  # sawn


def test_infinite_strength_is_nan_free_in_values_and_gradients():
    def f(u, tau_p, delta):
        k = wl.cohesive_factor(jnp.abs(u), tau_p, TAU_R, K, delta, jnp.asarray(False))
        return k * u

    for tau_p in (jnp.inf, 1000.0):
        for delta in (0.0, 1.0):
            for u in (0.0, 1e-4, 3e-4, 1.0):
                val = f(jnp.asarray(u), jnp.asarray(tau_p), jnp.asarray(delta))
                grads = jax.grad(f, argnums=(0, 1, 2))(
                    jnp.asarray(u), jnp.asarray(tau_p), jnp.asarray(delta)
                )
                assert np.isfinite(float(val))
                assert all(np.isfinite(float(g)) for g in grads)


def test_strength_profile():
    x = jnp.asarray([0.0, 10.0, 20.0, 30.0])
    tp = wl.strength_profile(x, 1000.0, 20.0, 150.0)
    np.testing.assert_allclose(np.asarray(tp), [1000, 1000, 1000, 2500])
