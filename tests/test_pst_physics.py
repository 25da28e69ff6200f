"""Physics of the DA-MPM core on small PSTs: analytic targets, conservation, agreement."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from damjax import PSTParams, PSTSetup, simulate_pst, theory
from damjax.constants import G_ACC
from damjax.core import transfer


@pytest.mark.parametrize("lateral", ["free", "constrained"])
def test_controlled_sawing_tension_gradient_matches_appendix_a(lateral):
    p = PSTParams()
    adot = 0.8 * float(theory.shear_wave_speed(p))
    s = PSTSetup(
        length=20.0,
        dx=0.05,
        duration=16.0 / adot,
        controlled=True,
        lateral=lateral,
        chunk_steps=200,
    )
    r = simulate_pst(PSTParams(saw_speed=adot), s)
    kx, kth = r.summary["tension_gradient_pa_per_m"], r.summary["tension_gradient_theory_pa_per_m"]
    assert kth == pytest.approx(float(theory.dynamic_gradient(p, adot, lateral)))
    assert abs(kx / kth - 1) <= 0.03, (kx, kth)
    assert r.summary["slab_yielded"] is False


def test_controlled_sawing_reports_no_elastic_ramp_once_the_slab_yields():
    """sigma_t = 4 kPa: the paper's slab yields at 0.534 sigma_t (2.1 kPa), inside the
    fitted window of a 10 m cut (k_x ~ 380 Pa/m): no elastic k_x is reported for it."""
    p = PSTParams(tensile_strength=4000.0)
    adot = 0.2 * float(theory.shear_wave_speed(p))
    s = PSTSetup(length=12.0, dx=0.1, duration=10.0 / adot, controlled=True, chunk_steps=200)
    r = simulate_pst(PSTParams(saw_speed=adot, tensile_strength=4000.0), s)
    assert r.summary["slab_yielded"] is True
    assert r.summary["tension_gradient_pa_per_m"] is None
    assert r.summary["tension_gradient_theory_pa_per_m"] > 0
    # the same slab far from its strength (sigma_t = 100 kPa against ~4 kPa of tension):
    # the return mapping's round-off (plastic strain ~1e-8) is no yield, and k_x is the
    # elastic ramp's
    strong = PSTParams(saw_speed=adot, tensile_strength=1e5)
    r = simulate_pst(strong, s)
    assert float(np.max(r.opening)) < 1e-6
    assert r.summary["slab_yielded"] is False
    kx, kth = r.summary["tension_gradient_pa_per_m"], r.summary["tension_gradient_theory_pa_per_m"]
    assert abs(kx / kth - 1) <= 0.03, (kx, kth)


@pytest.mark.parametrize("factor, arrests", [(0.9, False), (1.1, True)])
def test_elastic_brittle_crack_arrests_only_above_the_runaway_gradient(factor, arrests):
    """theta_run = (tau_g - tau_r) / lambda (303 Pa/m): below it the tip stress grows faster
    with crack length than the strength and the crack runs through (measured at 0.9 theta_run
    over 40 m); just above it the crack stops (1.1 theta_run: 18.0 m)."""
    p = PSTParams(steady_length=2.0)
    theta = factor * float(theory.runaway_gradient(p))
    r = simulate_pst(
        PSTParams(steady_length=2.0, strength_gradient=theta),
        PSTSetup(length=40.0, dx=0.05, duration=2.5),
    )
    assert r.arrested is arrests, r.summary["final_tip_m"]
    assert r.summary["crack_front"] == ("arrested" if arrests else "reached_end")
    assert r.summary["runaway_gradient_pa_per_m"] == pytest.approx(theta / factor)
    if not arrests:
        assert r.summary["final_tip_m"] > 39.0


@pytest.mark.min_versions
def test_self_propagating_crack_reaches_strip_wave_speed():
    r = simulate_pst(
        PSTParams(strength_gradient=0.0),
        PSTSetup(length=25.0, dx=0.05, duration=0.6, chunk_steps=200),
    )
    ratio = r.summary["max_crack_speed_over_cs"] / r.summary["wave_speed_over_cs"]
    assert 0.93 <= ratio <= 1.03, ratio
    assert r.summary["critical_cut_length_m"] is not None
    # dynamic sawing overshoots the quasi-static estimate a little, never by a factor
    ac, ac_th = r.summary["critical_cut_length_m"], r.summary["critical_cut_length_theory_m"]
    assert 0.8 * ac_th < ac < 1.6 * ac_th


def _slide_run(friction_deg, duration):
    p = PSTParams(friction_deg=friction_deg, saw_speed=1e5)  # the whole layer cut at once
    s = PSTSetup(length=5.0, dx=0.05, duration=duration, controlled=True, chunk_steps=100)
    return p, simulate_pst(p, s)


def test_released_slab_slides_with_coulomb_acceleration():
    p, r = _slide_run(27.0, 1.0)
    psi, phi = math.radians(35.0), math.radians(27.0)
    a = G_ACC * (math.sin(psi) - math.cos(psi) * math.tan(phi))
    u0 = -float(theory.gravity_shear(p)) / float(theory.wl_stiffness(p))
    t = r.time[-1]
    assert np.mean(r.slip) == pytest.approx(u0 - 0.5 * a * t**2, rel=0.01)
    assert r.fault is None


def test_friction_cap_holds_a_released_slab_at_rest():
    p, r = _slide_run(40.0, 0.3)
    u0 = -float(theory.gravity_shear(p)) / float(theory.wl_stiffness(p))
    np.testing.assert_allclose(r.slip, u0, rtol=1e-6)


def test_no_particle_leaves_the_grid_on_a_long_slide():
    from damjax import pst

    p = PSTParams(friction_deg=5.0, saw_speed=1e5)
    s = PSTSetup(length=3.0, dx=0.05, duration=2.0, controlled=True, chunk_steps=100)
    r = simulate_pst(p, s)
    assert r.fault is None
    lay = pst.make_layout(p, s)
    slide = -np.min(r.slip)
    assert slide > 9.0  # the slab really slid (0.5 a t^2 = 9.8 m)
    assert slide < lay.pad_cells * s.dx


def test_transfers_conserve_mass_in_1d_and_2d():
    rng = np.random.default_rng(0)
    for shape in [(40,), (20, 16)]:
        dim = len(shape)
        n = 300
        cell0 = jnp.asarray(rng.integers(3, 12, size=(dim, n)), jnp.int32)
        frac0 = jnp.asarray(rng.random((dim, n)), jnp.float32)
        u = jnp.asarray(rng.normal(0, 0.03, (dim, n)), jnp.float32)
        st = transfer.stencil(cell0, frac0, u, 0.1, shape)
        m = jnp.asarray(rng.random(n) + 0.5, jnp.float32)
        grid = transfer.p2g(st, [w * m for w in st.w], int(np.prod(shape)))
        assert float(grid.sum()) == pytest.approx(float(m.sum()), rel=1e-5)
        np.testing.assert_allclose(np.asarray(sum(st.w)), 1.0, rtol=1e-6)
        # linear completeness: sum_i w_ip dpos_ip = 0
        for d in range(dim):
            first = sum(w * dp[d] for w, dp in zip(st.w, st.dpos, strict=True))
            np.testing.assert_allclose(np.asarray(first), 0.0, atol=1e-6)
        # interpolating a linear field is exact
        nodes = np.indices(shape).reshape(dim, -1).astype(np.float32)
        lin = jnp.asarray(nodes[0] * 0.1 + 2.0)
        xp = (np.asarray(cell0[0]) + np.asarray(frac0[0])) * 0.1 + np.asarray(u[0])
        np.testing.assert_allclose(np.asarray(transfer.interpolate(st, lin)), xp + 2.0, rtol=1e-5)


def test_paired_complex_transfers_equal_the_real_ones():
    """p2g_channels / g2p_channels (two real channels per complex scatter or gather) give
    exactly the floats of one real p2g / g2p per channel, an odd channel included."""
    rng = np.random.default_rng(1)
    shape = (20, 16)
    n = 400
    cell0 = jnp.asarray(rng.integers(3, 12, size=(2, n)), jnp.int32)
    frac0 = jnp.asarray(rng.random((2, n)), jnp.float32)
    u = jnp.asarray(rng.normal(0, 0.03, (2, n)), jnp.float32)
    st = transfer.stencil(cell0, frac0, u, 0.1, shape)
    vals = [jnp.asarray(rng.normal(size=n), jnp.float32) for _ in range(3)]
    channels = [[w * v for w in st.w] for v in vals]
    nn = int(np.prod(shape))
    # bit for bit on any device: with the default fixed-point accumulation both are exact
    # integer sums (no dependence on the order of the adds), and the gathers do no arithmetic
    paired = transfer.p2g_channels(st, channels, nn)
    for c in range(3):
        np.testing.assert_array_equal(
            np.asarray(paired[c]), np.asarray(transfer.p2g(st, channels[c], nn))
        )
    grids = [jnp.asarray(rng.normal(size=nn), jnp.float32) for _ in range(3)]
    rows = transfer.g2p_channels(st, grids)
    assert len(rows) == 3
    for c in range(3):
        for a, b in zip(rows[c], transfer.g2p(st, grids[c]), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_batched_transfers_equal_per_member_ones():
    """Under vmap, p2g and g2p run as one flat scatter (gather) over the members' grids.
    The result equals member-by-member calls, an out-of-range index is dropped (clamped)
    within its own member, and forward- and reverse-mode derivatives agree."""
    rng = np.random.default_rng(2)
    shape, n, B = (30,), 50, 4
    nn = shape[0]
    cell0 = jnp.asarray(rng.integers(2, 26, size=(B, 1, n)), jnp.int32)
    frac0 = jnp.asarray(rng.random((B, 1, n)), jnp.float32)
    u = jnp.asarray(rng.normal(0, 0.05, (B, 1, n)), jnp.float32)
    u = u.at[1, 0, 0].set(-10.0).at[2, 0, 1].set(10.0)  # outside the grid: dropped / clamped
    vals = jnp.asarray(rng.normal(size=(B, n)), jnp.float32)
    grid_in = jnp.asarray(rng.normal(size=(B, nn)), jnp.float32)

    def one(c, f, uu, v, g):
        st = transfer.stencil(c, f, uu, 0.1, shape)
        grid = transfer.p2g(st, [w * v for w in st.w], nn)
        return grid, transfer.interpolate(st, g * grid)

    batched = jax.vmap(one)(cell0, frac0, u, vals, grid_in)
    for b in range(B):
        single = one(cell0[b], frac0[b], u[b], vals[b], grid_in[b])
        for x, y in zip(batched, single, strict=True):
            np.testing.assert_allclose(np.asarray(x[b]), np.asarray(y), rtol=1e-6, atol=1e-6)

    def loss(v):
        return jnp.sum(jax.vmap(one)(cell0, frac0, u, v, grid_in)[1] ** 2)

    rev = jax.grad(loss)(vals)
    fwd = jax.jacfwd(loss)(vals)
    np.testing.assert_allclose(np.asarray(rev), np.asarray(fwd), rtol=1e-4, atol=1e-5)


def test_column_volume_h_times_area_is_conserved(small_setup, arresting_params):
    from damjax import pst
    from damjax.core.step import column_height
    from damjax.materials.slab import area_ratio

    lay = pst.make_layout(arresting_params, small_setup)
    model, state = pst.build(arresting_params, small_setup, lay)
    final, _ = jax.jit(lambda m, s: pst.integrate_pure(m, s, 1, 400))(model, state)
    h = column_height(model, final)
    area = model.slab.area0 * area_ratio(final.eps)
    vol = float(jnp.sum(h * area))
    assert vol == pytest.approx(float(model.slab.thickness * model.slab.area0) * h.size, rel=1e-6)
    assert float(jnp.max(jnp.abs(final.eps[0]))) > 1e-5  # the slab did deform


def test_float32_and_float64_agree_on_arrest(small_setup, arresting_params):
    import dataclasses

    r32 = simulate_pst(arresting_params, small_setup)
    r64 = simulate_pst(arresting_params, dataclasses.replace(small_setup, dtype="float64"))
    assert r32.arrested and r64.arrested
    assert abs(r32.arrest_position - r64.arrest_position) <= 0.1
    assert r64.sigma_xx.dtype == np.float64


@pytest.mark.parametrize("lateral", ["constrained", "free"])
def test_1d_and_2d_paths_agree(lateral, arresting_params):
    import dataclasses

    s1 = PSTSetup(length=12.0, dx=0.05, duration=0.8, lateral=lateral, chunk_steps=200)
    r1 = simulate_pst(arresting_params, s1)
    r2 = simulate_pst(arresting_params, dataclasses.replace(s1, dim=2, width=0.3))
    assert r1.arrested and r2.arrested
    assert r2.arrest_position == pytest.approx(r1.arrest_position, rel=0.03)
    v1, v2 = r1.summary["max_crack_speed_over_cs"], r2.summary["max_crack_speed_over_cs"]
    assert v2 == pytest.approx(v1, rel=0.03)
    # the 2D strip's fields are width averages on its x, snapshots included
    for f in (r2.sigma_xx, r2.height, r2.slip, r2.u_max, r2.tau_peak, r2.opening):
        assert f.shape == r2.x.shape
    assert r2.snapshots["slip"].shape[1:] == r2.x.shape
    assert np.mean(r2.u_max) == pytest.approx(np.mean(r1.u_max), rel=0.05)


def test_no_arrest_without_a_self_propagating_crack():
    """A saw too slow to start a crack in the run leaves the tip still: not an arrest."""
    r = simulate_pst(
        PSTParams(saw_speed=1e-4, steady_length=2.0), PSTSetup(length=4.0, dx=0.1, duration=0.4)
    )
    assert not r.summary["arrested"] and r.summary["arrest_position_m"] is None
    assert r.summary["critical_cut_length_m"] is None
    assert r.summary["crack_front"] == "sawn_only"


@pytest.mark.min_versions
@pytest.mark.parametrize("theta", [150.0, 250.0, 400.0])
def test_critical_cut_length_beyond_the_steady_length(theta):
    """L_ss 0.3 m, below the uniform layer's a_c (0.98 m): the cut meets the rising
    strength beyond L_ss, and above theta_run (303 Pa/m) it never does. Measured
    2026-11-27 (8 m, dx 0.05 m, 1 s): cuts of 1.97 / 5.18 m against 1.65 / 4.19 m from
    the bar model (the uniform one says 0.98 m for both), and at 400 Pa/m the saw cut the
    whole PST with no crack ahead of it."""
    p = PSTParams(steady_length=0.3, strength_gradient=theta)
    a_uniform = float(theory.critical_cut_length(p))
    assert a_uniform > 0.3
    a_th = float(theory.pst_critical_cut_length(p))
    r = simulate_pst(p, PSTSetup(length=8.0, dx=0.05, duration=1.0, chunk_steps=200))
    s = r.summary
    if theta < float(theory.runaway_gradient(p)):
        assert s["critical_cut_length_theory_m"] == pytest.approx(a_th)
        # the same dynamic overshoot as on the uniform layer (1.14 there), not a factor
        assert 1.0 < s["critical_cut_length_m"] / a_th < 1.4
        assert s["critical_cut_length_m"] > 1.6 * a_uniform
        assert s["crack_front"] == "reached_end" and not s["arrested"]
    else:
        assert math.isinf(a_th)
        assert s["critical_cut_length_theory_m"] is None
        assert s["crack_front"] == "sawn_only" and s["critical_cut_length_m"] is None
        assert not s["arrested"]


def test_pst_critical_cut_length_is_the_uniform_one_within_the_steady_length():
    p = PSTParams()  # a_c 0.98 m < L_ss 20 m
    assert float(theory.pst_critical_cut_length(p)) == float(theory.critical_cut_length(p))
    # continuous where a_c crosses L_ss (below theta_run; above it no cut beyond L_ss does)
    a = float(theory.critical_cut_length(p))
    below, above = (
        float(theory.pst_critical_cut_length(PSTParams(steady_length=lss, strength_gradient=150.0)))
        for lss in (a + 1e-9, a - 1e-9)
    )
    assert below == pytest.approx(above, abs=1e-6)
    assert math.isinf(float(theory.pst_critical_cut_length(PSTParams(steady_length=a - 1e-3))))


def test_a_strength_profile_has_no_steady_length_in_the_summary():
    """A measured profile replaces tau_p, L_ss and theta: no L_ca - L_ss, no closed forms."""
    xs = np.linspace(0.0, 12.0, 241)
    prof = 1000.0 + 3000.0 * np.maximum(xs - 5.0, 0.0)
    r = simulate_pst(PSTParams(strength_profile=prof), PSTSetup(length=12.0, dx=0.1, duration=0.8))
    assert r.summary["arrested"] and 5.0 < r.summary["arrest_position_m"] < 10.0
    for key in ("arrest_length_m", "critical_cut_length_theory_m", "runaway_gradient_pa_per_m"):
        assert r.summary[key] is None, key


def test_crack_speed_of_a_record_shorter_than_its_window():
    """A run shorter than the 0.02 s speed window (a smoke test of a few steps) gets a
    speed from the shorter one-sided windows instead of failing."""
    from damjax.diagnostics import SPEED_WINDOW, crack_speed

    for n in (3, 20, 150, 400):  # dt = 1e-4 s: 2k = 200 samples span the window
        t = np.arange(n) * 1e-4
        assert n * 1e-4 < SPEED_WINDOW or n == 400
        np.testing.assert_allclose(crack_speed(t, 2.5 + 7.0 * t), 7.0, rtol=1e-9)
    r = simulate_pst(PSTParams(steady_length=2.0), PSTSetup(length=4.0, dx=0.1, duration=0.005))
    assert np.all(np.isfinite(crack_speed(r.time, r.tip)))
    # the tip only followed the saw: no crack speed in the summary
    assert r.summary["crack_front"] == "sawn_only"
    assert r.summary["max_crack_speed_over_cs"] is None
