"""Values and gradients stay finite at the exact ties of the traced step (float32, CPU).

A compiled program on a GPU rounds differently (fused multiply-adds, subnormals flushed to
zero) and gave NaN gradients where a quantity sits exactly at, or a few ulps from, a tie:
a divisor that is zero or so small that its square underflows (reverse mode forms
divisor^-2, and 0 * inf = NaN even in a branch that a `jnp.where` or a `jnp.maximum`
discards), or a sqrt at zero. Each test puts one mechanism exactly at its tie and checks
the value and `jax.grad` there; each failed before the fix (NaN gradients).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from damjax import PSTParams, SlopeSetup
from damjax.core import step
from damjax.core.model import build_slope, make_slope_layout
from damjax.materials import mcc, slab_fracture, weak_layer
from damjax.pst import weak_layer_shear

F32 = jnp.float32
TINY = 1e-20  # a float32 whose square (1e-40) is subnormal, flushed to 0: x^-2 is inf


def _finite(tree) -> bool:
    return all(bool(jnp.all(jnp.isfinite(x))) for x in jax.tree.leaves(tree))


def test_division_by_a_tiny_divisor_has_a_finite_gradient():
    """mcc._div: the value x / y unchanged, the gradient exact while y^2 is normal, zero
    below; a discarded branch (where / maximum) no longer turns 0 * inf into NaN."""
    y = jnp.asarray(TINY, F32)
    assert float(mcc._div(F32(3.0), y)) == float(F32(3.0) / y)

    def stopped(x, y):  # maximum discards the branch
        return jnp.maximum(0.0, 1.0 - mcc._div(x, y))

    for x in (0.0, 1e-3):
        g = jax.grad(stopped, argnums=(0, 1))(F32(x), y)
        assert _finite(g), (x, g)
    # normal range: the exact derivative of x / y
    gx, gy = jax.grad(lambda x, y: mcc._div(x, y), argnums=(0, 1))(F32(2.0), F32(4.0))
    assert float(gx) == 0.25 and float(gy) == -0.125


def test_zero_slip_on_a_flat_slope_in_2d():
    """On a flat release area the pre-load slip is exactly zero: sqrt(|u|^2) at 0 in the
    initial u_max (build_slope), in the step's u_max and in the weak-layer shear made
    d / d wl_shear_modulus NaN."""
    setup = SlopeSetup(length=1.0, width=1.0, dx=0.25, duration=0.01, start=(0.5, 0.5))
    params = PSTParams()
    layout = make_slope_layout(params, setup, 0.0)

    def f(g_wl):
        p = PSTParams(wl_shear_modulus=g_wl)
        model, state, _, _ = build_slope(p, setup, layout, 0.0, 1000.0)
        after = step.step(model, state)
        return jnp.sum(after.u_max) + jnp.sum(weak_layer_shear(model, after))

    g_wl = jnp.asarray(2.0e5, F32)
    _, state, _, _ = build_slope(PSTParams(), setup, layout, 0.0, 1000.0)
    assert float(jnp.max(jnp.abs(state.u))) == 0.0  # the tie: no slip at all
    assert np.isfinite(float(f(g_wl)))
    g = jax.grad(f)(g_wl)
    assert _finite(g), g


def test_softening_return_map_where_the_clip_rounds_to_no_increment(monkeypatch):
    """A particle above its strength (tension) whose clipped stress, fused and rounded
    apart from the strength test, equals its trial stress: d_xx = 0 (on CPU in float64
    the reverse was seen, d_xx = 1e-54 below the strength). The map scaled d_yy by
    d / d_xx = inf, and 0 x inf made the value and the gradient NaN; d_yy is then d
    times the flow ratio, the value of the consistent rounding."""
    p0 = jnp.asarray(3000.0, F32)
    E = 1.0e6
    sig = 1.5 * mcc.uniaxial_strengths(p0, 0.3, 1.2)[0]
    args = (p0, p0, 100.0, 0.0, 0.3, 1.2, E)
    consistent = mcc.return_map_uniaxial_softening(sig, *args)
    exact = mcc.return_map_uniaxial

    def rounded_apart(sig_trial, *rest):
        s, _, _ = exact(sig_trial, *rest)
        return s, jnp.zeros_like(sig_trial), jnp.zeros_like(sig_trial)

    monkeypatch.setattr(mcc, "return_map_uniaxial", rounded_apart)

    def f(sig):
        return jnp.stack(mcc.return_map_uniaxial_softening(sig, *args))

    out = f(sig)
    assert _finite(out), out
    np.testing.assert_allclose(np.asarray(out), np.asarray(jnp.stack(consistent)), rtol=1e-6)
    assert _finite(jax.jacfwd(f)(sig)) and _finite(jax.grad(lambda s: jnp.sum(f(s)))(sig))


def test_plane_return_map_of_an_elastic_particle_at_a_round_off_strain():
    """An elastic particle with a round-off strain (1e-23) on a surface centred on p = 0
    (beta = 1): its discarded Newton steps divide by df ~ 1e-27, whose square flushes to
    zero, and 0 x inf made the gradient NaN. Elastic: sigma = C eps, d eps_p = 0."""
    args = (0.3, 1.0, 1.0e6, 0.3)
    p0 = jnp.asarray(3000.0, F32)
    e = (jnp.asarray(1e-23, F32), jnp.asarray(0.0, F32), jnp.asarray(0.0, F32))

    def f(e):
        sigma, d = mcc.return_map_plane(e, p0, *args)
        return sigma[0] + 1e6 * d[0]

    assert np.isfinite(float(f(e)))
    g = jax.grad(f)(e)
    assert _finite(g), g
    c = 1.0e6 / (1.0 - 0.3**2)  # d sigma_xx / d eps of plane stress
    np.testing.assert_allclose([float(x) for x in g], [c, 0.3 * c, 0.0], rtol=1e-6)


def test_cohesive_factor_with_a_softening_below_float_resolution():
    """delta = 1e-9 rounds 1 + delta to 1 in float32: u_r = u_c, a zero softening span
    (0 / 0 in the discarded branch of a broken particle) at u_max = u_c."""
    K, tau_p, tau_r = F32(5.0e6), F32(1000.0), F32(500.0)
    u_c = tau_p / K

    def f(u_max, tau_p, delta):
        u_c, u_r = weak_layer.critical_displacements(tau_p, K, delta)
        broken = u_max >= u_r
        return weak_layer.cohesive_factor(u_max, tau_p, tau_r, K, delta, broken)

    for u in (u_c, 0.5 * u_c):
        assert np.isfinite(float(f(u, tau_p, F32(1e-9))))
        g = jax.grad(f, argnums=(0, 1, 2))(u, tau_p, F32(1e-9))
        assert _finite(g), (u, g)


def test_strength_field_gradient_at_zero_coefficient_of_variation():
    """s = sqrt(log1p(cov^2)) at cov = 0: d s / d cov was 0 x inf = NaN; it is the
    one-sided limit 1, so d sigma_t(x) / d cov = mean z(x)."""
    x = jnp.linspace(0.0, 5.0, 11, dtype=F32)

    def field(cov):
        return slab_fracture.strength_field(0, F32(4000.0), cov, F32(1.0), x, 5.0)

    cov0 = jnp.asarray(0.0, F32)
    assert np.allclose(np.asarray(field(cov0)), 4000.0)
    jac = jax.jacfwd(field)(cov0)
    grad = jax.grad(lambda c: jnp.sum(field(c)))(cov0)
    assert _finite((jac, grad)), (jac, grad)
    # the one-sided limit: (field(h) - field(0)) / h for a small h > 0
    h = 1e-3
    fd = (np.asarray(field(jnp.asarray(h, F32)), float) - 4000.0) / h
    assert np.allclose(np.asarray(jac), fd, rtol=0.02, atol=20.0)
