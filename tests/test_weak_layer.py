"""Unit tests of the quasi-brittle interface law (paper Fig. 1b)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


# --- failure without events: the failed fraction averaged over a step -------------------


def _numeric_average(u_max, slip, rate, u_b, w, dt, n=200_000):
    tau = (np.arange(n) + 0.5) / n
    path = np.maximum(u_max, slip + max(rate, 0.0) * dt * tau)
    return float(np.mean(np.clip((path - u_b) / w + 0.5, 0.0, 1.0)))


@given(
    u_max=st.floats(0.0, 3e-4),
    back=st.floats(0.0, 1.0),
    rate=st.floats(-0.5, 0.5),
    dt=st.floats(1e-5, 1e-3),
)
@settings(max_examples=200, deadline=None)
def test_failed_fraction_in_step_is_the_average_over_a_linear_slip_path(u_max, back, rate, dt):
    slip = u_max * back  # the slip never exceeds its history
    u_b, w = 2e-4, 1e-5
    got = float(wl.failed_fraction_in_step(u_max, slip, rate, u_b, w, dt))
    assert got == pytest.approx(_numeric_average(u_max, slip, rate, u_b, w, dt), abs=1e-4)


def test_failed_fraction_in_step_is_continuous_in_the_crossing_time():
    """A front that crosses the particle within one step: the average moves smoothly with
    the slip at the start of the step (no jump where the crossing moves to the next step)."""
    u_b, w, dt, rate = 2e-4, 1e-6, 1e-4, 0.1  # the front crosses in 1 % of a step
    slips = np.linspace(u_b - 2 * rate * dt, u_b + 0.5 * rate * dt, 2001)
    avg = np.array([float(wl.failed_fraction_in_step(s, s, rate, u_b, w, dt)) for s in slips])
    assert avg[0] == 0.0 and avg[-1] == 1.0
    # steps of 2.5 rate dt / 2000 in slip, slope at most 1 / (rate dt): no jump
    assert np.max(np.abs(np.diff(avg))) < 1.5e-3
    g = jax.grad(lambda s: wl.failed_fraction_in_step(s, s, rate, u_b, w, dt))
    mid = u_b - 0.5 * rate * dt  # crossing in the middle of the step
    assert float(g(mid)) == pytest.approx(1.0 / (rate * dt), rel=1e-3)


def test_failed_fraction_and_sawn_fraction_limits():
    inf = jnp.inf
    assert float(wl.failed_fraction(1.0, inf, 1e-6)) == 0.0  # unbreakable
    assert float(wl.failed_fraction_in_step(1.0, 1.0, 1.0, inf, 1e-6, 1e-4)) == 0.0
    assert float(wl.failed_fraction(2e-4, 2e-4, 1e-5)) == 0.5  # centre at u_r
    assert float(wl.sawn_fraction(1.0, 0.9, 1.3)) == pytest.approx(0.25)
    assert float(wl.sawn_fraction(0.5, 0.9, 1.3)) == 0.0  # behind the saw
    assert float(wl.sawn_fraction(2.0, 1.3, 1.3)) == 1.0  # saw stopped before it
    gs = jax.grad(wl.failed_fraction_in_step, argnums=(0, 1, 2, 3, 4))(
        1.0, 1.0, 1.0, inf, 1e-6, 1e-4
    )
    assert all(np.isfinite(float(v)) for v in gs)


# --------------------------------------------------------------------------- uniform load


def test_a_uniformly_loaded_brittle_layer_fails_where_its_segments_start_to():
    """A segment starts failing at a centre slip of u_r - w/2 (the gradient of a crack
    front across it); under a uniform load that is the stress K (u_r - w/2) =
    tau_p (1 + delta) (1 - spacing / (2 Lambda)) where below tau_p."""
    k, spacing, lam = 2e5 / 0.03, 0.025, 0.66
    for delta, want in ((0.0, 1000.0 * (1 - spacing / (2 * lam))), (1.0, 1000.0)):
        u_r = 1000.0 / k * (1 + delta)
        w = wl.front_width(u_r, spacing, lam)
        got = float(wl.uniform_failure_stress(1000.0, k, u_r, w))
        assert got == pytest.approx(want, rel=1e-6)  # float32 (jax.numpy)
    assert float(wl.uniform_failure_stress(jnp.inf, k, jnp.inf, 1.0)) == jnp.inf


def test_a_pst_whose_layer_would_fail_by_itself_is_refused_and_one_that_holds_stays():
    """The baseline slab (tau_g 703.3 Pa) on dx 0.05 m, two particles per cell: a brittle
    layer fails under the uniform load below tau_p = tau_g / (1 - 0.025 / (2 Lambda)) =
    716.9 Pa (measured: 716 failed everywhere at once, 718 held, 2026-11-28)."""
    import damjax
    from damjax import PSTParams, PSTSetup

    setup = PSTSetup(length=20.0, dx=0.05, duration=0.3)
    untriggered = dict(steady_length=10.0, strength_gradient=1000.0, saw_speed=1e-6)
    with pytest.raises(ValueError, match=r"tau_peak \(--tau-peak\) = 712.0: must exceed 716.9 Pa"):
        damjax.simulate_pst(PSTParams(tau_peak=712.0, **untriggered), setup)
    held = damjax.simulate_pst(PSTParams(tau_peak=718.0, **untriggered), setup)
    assert held.summary["crack_front"] == "sawn_only" and held.summary["final_tip_m"] == 0.0
    # a softening layer fails at tau_p: the same strength is accepted
    damjax.pst.prepare(PSTParams(tau_peak=712.0, softening=0.5, **untriggered), setup)


def test_a_slope_says_and_counts_a_layer_that_fails_by_itself():
    """On dx 0.2 m with two particles per cell, S = 1.06 fails under the slab's own
    weight (below 1 / (1 - 0.1 / (2 Lambda)) = 1.082), S = 1.10 holds."""
    import damjax
    from damjax.slope import simulation

    setup = damjax.SlopeSetup(length=10.0, width=6.0, dx=0.2, duration=0.05, start=(2.0, 3.0))
    p = damjax.PSTParams()
    tau_g = float(damjax.theory.gravity_shear(p))
    for s, fails in ((1.06, True), (1.10, False)):
        prep = simulation.prepare(p, setup, tau_peak=s * tau_g)
        said = [n.text() for n in prep.notes if n.category == "overloaded"]
        assert bool(said) == fails
        if fails:
            assert "starts failing under the slab's weight at once on 100 % of the area" in said[0]
            assert np.all(simulation.load_ratio(p, setup, 35.0, s * tau_g) <= 1.0)
            assert np.all(simulation.load_ratio(p, setup, 35.0, s * tau_g, uniform=False) > 1)
