"""Modified Cam Clay slab: surface, return mapping, p0 rules, robustness, fracture bands."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from damjax import diagnostics
from damjax.materials import mcc

M, BETA, E, NU = 0.3, 1.2, 4e6, 0.3


@pytest.mark.parametrize(
    "rule,inv,expected",
    [
        ("uniaxial", "3d", 6000.0),
        ("paper", "3d", 3206.1),
        ("uniaxial", "plane", 6000.0),
        ("paper", "plane", 3704.6),
    ],
)
def test_uniaxial_tension_yields_where_the_p0_rule_puts_it(rule, inv, expected):
    p0 = mcc.p0_from_tensile_strength(6000.0, M, BETA, rule, inv)
    st_, sc_ = mcc.uniaxial_strengths(p0, M, BETA, inv)
    assert float(st_) == pytest.approx(expected, rel=1e-3)
    # the yield function, in this choice's invariants, vanishes at uniaxial tension and
    # compression
    for sig in (float(st_), -float(sc_)):
        p, q = mcc.invariants(jnp.asarray([sig, 0.0, 0.0]), inv)
        assert abs(float(mcc.yield_function(p, q, p0, M, BETA))) < 1e-5 * float(p0) ** 2
    # a uniaxial return mapping caps the stress there
    sig, dxx, dyy = mcc.return_map_uniaxial(jnp.asarray([2e4, -2e4, 100.0]), p0, M, BETA, E, inv)
    np.testing.assert_allclose(np.asarray(sig), [float(st_), -float(sc_), 100.0], rtol=1e-5)
    assert float(dxx[2]) == 0.0 and float(dyy[2]) == 0.0
    # associative flow at uniaxial tension: in-plane isochoric for the plane invariants,
    # 3D-isochoric (d eps_yy = d eps_zz = -d eps_xx / 2) for the 3d ones, up to the small
    # pressure term
    ratio = {"plane": -1.0, "3d": -0.5}[inv]
    assert float(dyy[0] / dxx[0]) == pytest.approx(ratio, abs=0.03)


def test_3d_invariants_of_plane_stress():
    sig = jnp.asarray([3000.0, -1000.0, 500.0])
    p, q = mcc.invariants(sig, "3d")
    full = np.array([[3000.0, 500.0, 0.0], [500.0, -1000.0, 0.0], [0.0, 0.0, 0.0]])
    dev = full - np.trace(full) / 3 * np.eye(3)
    assert float(p) == pytest.approx(-np.trace(full) / 3)
    assert float(q) == pytest.approx(np.sqrt(1.5 * np.sum(dev * dev)), rel=1e-6)


@pytest.mark.parametrize("inv", ["3d", "plane"])
def test_compression_strength_from_p0_and_beta(inv):
    p0 = 20000.0
    _, sc = mcc.uniaxial_strengths(p0, M, BETA, inv)
    # solve y(p, q) = 0 for uniaxial compression by bisection
    lo, hi = 0.0, 1e6
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        # uniaxial compression sigma = -mid: (p, q) = (mid/3, mid) or (mid/2, sqrt(3)/2 mid)
        p, q = (mid / 3, mid) if inv == "3d" else (mid / 2, np.sqrt(3) / 2 * mid)
        y = float(mcc.yield_function(p, q, p0, M, BETA))
        lo, hi = (mid, hi) if y < 0 else (lo, mid)
    assert float(sc) == pytest.approx(lo, rel=1e-6)


def _plane_stress(eps):
    c = E / (1 - NU**2)
    return np.stack([c * (eps[0] + NU * eps[1]), c * (eps[1] + NU * eps[0]), c * (1 - NU) * eps[2]])


@pytest.mark.parametrize("inv", ["3d", "plane"])
def test_states_inside_are_untouched_and_returned_states_lie_on_the_surface(inv):
    rng = np.random.default_rng(1)
    p0 = float(mcc.p0_from_tensile_strength(6000.0, M, BETA, "uniaxial", inv))
    eps = rng.normal(0.0, 2e-3, (3, 4000))
    sigma, dep = mcc.return_map_plane(jnp.asarray(eps), p0, M, BETA, E, NU, inv)
    sigma, dep = np.asarray(sigma), np.asarray(dep)
    from damjax.materials.slab import plane_stress

    trial = np.asarray(plane_stress(jnp.asarray(eps), E, NU))
    p_tr, q_tr = mcc.invariants(jnp.asarray(trial), inv)
    inside = np.asarray(mcc.yield_function(p_tr, q_tr, p0, M, BETA)) <= 0
    assert inside.sum() > 100 and (~inside).sum() > 100
    np.testing.assert_array_equal(sigma[:, inside], trial[:, inside])
    np.testing.assert_array_equal(dep[:, inside], 0.0)
    p, q = mcc.invariants(jnp.asarray(sigma[:, ~inside]), inv)
    y = np.asarray(mcc.yield_function(p, q, p0, M, BETA))
    assert np.max(np.abs(y)) < 1e-6 * p0**2
    # stress = elastic law of the remaining elastic strain
    np.testing.assert_allclose(
        _plane_stress(eps - dep)[:, ~inside], sigma[:, ~inside], rtol=1e-5, atol=1e-5 * p0
    )


def test_infinite_tensile_strength_is_exactly_elastic():
    rng = np.random.default_rng(2)
    eps = jnp.asarray(rng.normal(0.0, 1e-2, (3, 500)))
    p0 = mcc.p0_from_tensile_strength(jnp.inf, M, BETA, "paper")
    sigma, dep = mcc.return_map_plane(eps, p0, M, BETA, E, NU)
    np.testing.assert_array_equal(np.asarray(dep), 0.0)
    np.testing.assert_allclose(np.asarray(sigma), _plane_stress(np.asarray(eps)), rtol=1e-12)
    sig, dxx, _ = mcc.return_map_uniaxial(eps[0] * E, p0, M, BETA, E)
    np.testing.assert_array_equal(np.asarray(sig), np.asarray(eps[0] * E))


def test_pst_with_infinite_tensile_strength_reproduces_the_elastic_slab():

    from damjax import PSTParams, PSTSetup, pst

    # float64: the two paths round differently, and in float32 that alone moves kPa stresses
    # by a few ulp (1e-3 Pa) over the run; in float64 they must agree to round-off
    p = PSTParams(steady_length=5.0, strength_gradient=3000.0)
    s = PSTSetup(length=10.0, dx=0.05, duration=0.3, chunk_steps=100, dtype="float64")
    with jax.enable_x64(True):
        lay = pst.make_layout(p, s)
        m_el, st0 = pst.build(p, s, lay)
        m_pl = m_el.with_fields(plastic=True)  # the return mapping with p0 = inf
        run = jax.jit(lambda m, x: pst.integrate_pure(m, x, lay.n_chunks, lay.chunk_steps))
        f_el, tips_el = run(m_el, st0)
        f_pl, tips_pl = run(m_pl, st0)
        # two compiled programs (equal on XLA:CPU): the tip, the saw coordinate of the
        # furthest broken particle, can move by one particle spacing where round-off moves
        # a failure by a step
        spacing = s.dx / s.particles_per_cell
        np.testing.assert_allclose(np.asarray(tips_el), np.asarray(tips_pl), rtol=0, atol=spacing)
        sig_el, sig_pl = np.asarray(f_el.sigma), np.asarray(f_pl.sigma)
    assert sig_el.dtype == np.float64
    np.testing.assert_allclose(sig_el, sig_pl, rtol=1e-9, atol=1e-6)


finite = st.floats(-0.5, 0.5, allow_nan=False)


@functools.cache
def _nan_probe(rule: str, inv: str):
    """Jitted value and gradient of every return mapping (compiled once per choice)."""

    def f(sigma_t_, eps_):
        p0 = mcc.p0_from_tensile_strength(sigma_t_, M, BETA, rule, inv)
        sig, dep = mcc.return_map_plane(eps_, p0, M, BETA, E, NU, inv)
        sx, _, _ = mcc.return_map_uniaxial(E * eps_[0], p0, M, BETA, E, inv)
        return sum(jnp.sum(c) for c in (*sig, *dep)) + jnp.sum(sx)

    return jax.jit(jax.value_and_grad(f, argnums=(0, 1)))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(finite, min_size=3, max_size=3),
    st.sampled_from([2000.0, 6000.0, np.inf]),
    st.sampled_from(["paper", "uniaxial"]),
    st.sampled_from(["3d", "plane"]),
)
def test_return_mapping_never_produces_nan(e, sigma_t, rule, inv):
    eps = jnp.asarray(e, jnp.float32)[:, None] * jnp.asarray([1.0, 0.3, 1e-3])[None, :]
    val, (g_st, g_eps) = _nan_probe(rule, inv)(jnp.float32(sigma_t), eps)
    assert np.isfinite(float(val))
    assert np.isfinite(float(g_st)) and np.all(np.isfinite(np.asarray(g_eps)))


def test_gradient_is_finite_at_the_elastic_plastic_switch():
    p0 = mcc.p0_from_tensile_strength(6000.0, M, BETA, "uniaxial")
    st_, _ = mcc.uniaxial_strengths(p0, M, BETA)

    def f(s_t, sig):
        p0_ = mcc.p0_from_tensile_strength(s_t, M, BETA, "uniaxial")
        return mcc.return_map_uniaxial(sig, p0_, M, BETA, E)[0]

    g = jax.grad(f, argnums=(0, 1))(6000.0, st_)
    assert all(np.isfinite(float(x)) for x in g)


def test_one_band_is_one_fracture():
    x = np.linspace(0, 50, 5001)
    opening = np.zeros_like(x)
    opening[(x > 20) & (x < 20.3)] = 0.05  # one localised band, several particles wide
    opening[(x > 20.5) & (x < 20.6)] = 0.02  # a neighbouring sliver of the same band
    opening[(x > 35) & (x < 35.1)] = 0.5
    t = np.where(opening > 0, 0.4, np.inf)
    t[x > 30] = 0.7
    fr = diagnostics.slab_fractures(x, opening, t, threshold=0.01, gap=1.0)
    assert [round(f["x_m"]) for f in fr] == [20, 35]
    assert [f["t_s"] for f in fr] == [0.4, 0.7]


@pytest.mark.parametrize("inv", ["3d", "plane"])
def test_crack_band_dissipates_the_fracture_energy_on_any_band_width(inv):
    # a band of width dx pulled in uniaxial tension until it is stress-free, with p0
    # softened explicitly from the previous increment's opening (as in the step): the
    # plastic work per unit crack area, dx * int sigma d eps_p, is G_f whatever dx is,
    # while the perfectly plastic band's grows with dx
    p0_init = mcc.p0_from_tensile_strength(4000.0, M, BETA, "paper", inv)
    sigma_y = float(mcc.uniaxial_strengths(p0_init, M, BETA, inv)[0])
    g_f = 0.3
    w_c = mcc.crack_band_opening(p0_init, g_f, M, BETA, inv)
    assert float(w_c) == pytest.approx(g_f / sigma_y, rel=1e-6)

    def dissipation(dx, w_c, n=4000, eps_end=None):
        if eps_end is None:  # twelve w_c of opening: the band is stress-free
            eps_end = 12.0 * g_f / sigma_y / dx + 2.0 * sigma_y / E
        eps_p = opening = work = 0.0
        for eps in np.linspace(0.0, eps_end, n)[1:]:
            p0 = p0_init * mcc.crack_band_factor(opening, dx, w_c)
            sig, dxx, _ = mcc.return_map_uniaxial(E * (eps - eps_p), p0, M, BETA, E, inv)
            sig, dxx = float(sig), float(dxx)
            eps_p += dxx
            opening += max(dxx, 0.0)
            work += sig * dxx
        return work * dx, sig

    for dx in (0.02, 0.2):
        g, sig_end = dissipation(dx, w_c)
        assert g == pytest.approx(g_f, rel=0.02), dx
        assert abs(sig_end) < 0.01 * sigma_y  # the band is stress-free at the end
    # no softening (G_f = inf): the factor is 1, the band keeps its strength and, pulled
    # to the same strain, dissipates in proportion to its width
    w_inf = mcc.crack_band_opening(p0_init, jnp.inf, M, BETA, inv)
    assert float(mcc.crack_band_factor(0.5, 0.1, w_inf)) == 1.0
    g1, s1 = dissipation(0.02, w_inf, 400, eps_end=0.05)
    g2, _ = dissipation(0.2, w_inf, 400, eps_end=0.05)
    assert s1 == pytest.approx(sigma_y, rel=1e-4)
    assert g2 == pytest.approx(10.0 * g1, rel=1e-3)


def test_crack_band_gradient_is_finite_without_softening():
    # d/dG_f at G_f = inf, and d/dp0 with the softening on, are finite
    def f(g_f, p0):
        w_c = mcc.crack_band_opening(p0, g_f, M, BETA)
        return p0 * mcc.crack_band_factor(0.01, 0.1, w_c)

    for g_f in (jnp.inf, 0.3):
        grads = jax.grad(f, argnums=(0, 1))(jnp.asarray(g_f), jnp.asarray(2000.0))
        assert all(np.isfinite(float(g)) for g in grads)


@settings(max_examples=10, deadline=None)
@given(steps=st.integers(3, 200), width=st.sampled_from([0.005, 0.02, 0.08]))
def test_energy_consistent_band_dissipates_the_fracture_energy_on_any_time_step(steps, width):
    # one band of width `width` pulled apart in `steps` strain increments, as few as three:
    # each step's work is the softening curve's integral over the step's opening, so the
    # sum is G_f (1 - exp(-w / w_c)) to round-off, however coarse the steps (the explicit
    # strength of the step's start overcounts by ~ 1 + h / 2 for an opening h w_c per step)
    p0_init = mcc.p0_from_tensile_strength(4000.0, M, BETA, "paper", "3d")
    sigma_y = float(mcc.uniaxial_strengths(p0_init, M, BETA, "3d")[0])
    g_f = 0.12
    w_c = float(mcc.crack_band_opening(p0_init, g_f, M, BETA, "3d"))
    rate = width / w_c
    eps_end = 8.0 * w_c / width + sigma_y / E
    eps_p = opening = work = 0.0
    for eps in np.linspace(0.0, eps_end, steps + 1)[1:]:
        p0 = p0_init * np.exp(-opening * width / w_c)
        sig, dxx, _ = mcc.return_map_uniaxial_softening(
            jnp.asarray(E * (eps - eps_p)), p0, p0, rate, 0.0, M, BETA, E, "3d"
        )
        sig, dxx = float(sig), float(dxx)
        eps_p += dxx
        opening += max(dxx, 0.0)
        work += sig * dxx * width
    expected = g_f * (1.0 - np.exp(-opening * width / w_c))
    assert work == pytest.approx(expected, rel=1e-4)
    assert opening * width > 7.0 * w_c  # the band opened through its softening
