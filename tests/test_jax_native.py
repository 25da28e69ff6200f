"""simulate_pst and simulate_slope as JAX functions: jax.grad, jax.vmap and jax.jit of a
function that calls them give the values of the layout-based API and of damjax.sweep
(float64, set with a JAX dtype); traced inputs get errors that say what to do instead."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import damjax
from damjax import PSTParams, PSTSetup, SlopeSetup
from damjax.core.model import make_slope_layout

PARAMS = PSTParams(steady_length=3.0, strength_gradient=3000.0, softening=1.0)
THETAS = (2000.0, 4000.0)


def _pst_setup() -> PSTSetup:
    return PSTSetup(length=8.0, dx=0.1, duration=0.4, chunk_steps=100, dtype=jnp.float64)


def _with_theta(theta):
    return eqx.tree_at(lambda p: p.strength_gradient, PARAMS, theta)


def test_setups_accept_numpy_and_jax_dtypes():
    for dt in (jnp.float64, np.float64, np.dtype("float64"), jnp.dtype("float64"), "float64"):
        assert PSTSetup(dtype=dt).dtype == "float64"
        assert SlopeSetup(dtype=dt).dtype == "float64"
    assert PSTSetup(dtype=jnp.float32) == PSTSetup()  # one setting, one compiled program
    with pytest.raises(ValueError, match=r"dtype \(--dtype\) = 'int32': must be in"):
        damjax.simulate_pst(PARAMS, PSTSetup(dtype=jnp.int32))


def test_pst_grad_vmap_jit_match_the_layout_api_and_sweep():
    with jax.enable_x64(True):
        setup = _pst_setup()
        layout = damjax.make_layout(PARAMS, setup)

        # jax.grad through simulate_pst == the layout-based API
        g = jax.grad(lambda th: damjax.simulate_pst(_with_theta(th), setup).arrest_position_smooth)(
            3000.0
        )
        g_ref = jax.grad(lambda th: damjax.arrest_position_smooth(_with_theta(th), setup, layout))(
            3000.0
        )
        assert float(g_ref) != 0.0
        assert float(g) == pytest.approx(float(g_ref), rel=1e-9)

        # jax.vmap: one batched PSTResult, members equal to damjax.sweep's
        thetas = jnp.array(THETAS)
        res = jax.vmap(lambda th: damjax.simulate_pst(_with_theta(th), setup))(thetas)
        assert isinstance(res, damjax.PSTResult)
        assert res.tip.shape[0] == len(THETAS) and res.sigma_xx.shape[0] == len(THETAS)
        swept = damjax.sweep(_with_theta(thetas), setup)
        for i, r in enumerate(swept):
            assert float(res.arrest_position_smooth[i]) == pytest.approx(
                r.arrest_position_smooth, rel=1e-9
            )
            np.testing.assert_allclose(
                np.asarray(res.sigma_xx[i]), r.sigma_xx, rtol=1e-9, atol=1e-6
            )

        # jax.jit with a layout == the concrete run
        jitted = jax.jit(lambda p: damjax.simulate_pst(p, setup, layout=layout))(PARAMS)
        concrete = damjax.simulate_pst(PARAMS, setup)
        assert float(jitted.arrest_position_smooth) == pytest.approx(
            concrete.arrest_position_smooth, rel=1e-9
        )
        assert float(jitted.summary["tip_m"]) == pytest.approx(concrete.summary["final_tip_m"])
        assert concrete.setup.dtype == "float64" and concrete.sigma_xx.dtype == np.float64


def test_pst_hessian_matches_finite_differences_of_the_gradient():
    """jax.hessian (forward over reverse through the scan and the transfers' batching
    rules, which JAX's derivative of a custom_vmap calls with nothing batched) equals a
    central difference of jax.grad (float64)."""
    with jax.enable_x64(True):
        setup = _pst_setup()

        def f(th):
            return damjax.simulate_pst(_with_theta(th), setup).arrest_position_smooth

        h = float(jax.hessian(f)(3000.0))
        g = jax.grad(f)
        fd = (float(g(3001.0)) - float(g(2999.0))) / 2.0
        assert h != 0.0
        assert h == pytest.approx(fd, rel=1e-5)


def test_traced_pst_errors_say_what_to_do():
    with jax.enable_x64(True):
        setup = _pst_setup()
        # inside jit the layout cannot be read from the values: the message says how
        with pytest.raises(TypeError, match=r"layout=layout"):
            jax.jit(lambda p: damjax.simulate_pst(p, setup).arrest_position_smooth)(PARAMS)
        # a traced out-of-range value is named with its value, not its tracer
        with pytest.raises(ValueError, match=r"poisson \(--poisson\) = 0\.7: must be in"):
            jax.grad(
                lambda nu: (
                    damjax.simulate_pst(
                        eqx.tree_at(lambda p: p.poisson, PARAMS, nu), setup
                    ).arrest_position_smooth
                )
            )(0.7)
        # event-based diagnostics need a concrete run
        res = jax.vmap(lambda th: damjax.simulate_pst(_with_theta(th), setup))(jnp.array(THETAS))
        with pytest.raises(ValueError, match="arrest_position_smooth"):
            res.arrest_position  # noqa: B018


def _slope_case(dtype=jnp.float64):
    setup = SlopeSetup(
        length=6.0,
        width=2.0,
        dx=0.25,
        duration=0.3,
        start=(1.0, 1.0),
        particles_per_cell=1,
        chunk_steps=50,
        dtype=dtype,
    )
    # tau_p 1200-1300 Pa: the crack still runs beyond the saw cut at the end of the run, so
    # the smooth release area (5.52 / 5.40 m^2) depends on tau_p; at 1100 Pa the whole
    # slope releases, at 1400 Pa only the cut (measured 2026-11-25)
    params = PSTParams(tau_peak=1250.0, softening=1.0, strength_gradient=300.0)
    return params, setup


def test_slope_grad_vmap_jit_match_the_layout_api_and_concrete_runs():
    with jax.enable_x64(True):
        params, setup = _slope_case()
        layout = make_slope_layout(params, setup, 35.0)

        def run(tau, **kw):
            p = eqx.tree_at(lambda q: q.tau_peak, params, tau)
            return damjax.simulate_slope(p, setup, slope_deg=35.0, **kw)

        def area(tau, **kw):
            return run(tau, **kw).summary["release_area_smooth_m2"]

        # jax.grad through simulate_slope == through the layout-based call, and == the
        # central difference of two concrete runs
        g = jax.grad(area)(1250.0)
        g_layout = jax.grad(lambda t: area(t, layout=layout))(1250.0)
        assert float(g) != 0.0
        assert float(g) == pytest.approx(float(g_layout), rel=1e-9)
        # h = 0.01 Pa: truncation and rounding both far below 1e-6 here (the difference
        # quotients for h = 0.03, 0.01, 0.001 agree to 1e-9, measured 2026-11-25)
        h = 0.01
        fd = (area(1250.0 + h) - area(1250.0 - h)) / (2 * h)
        assert float(g) == pytest.approx(fd, rel=1e-6)

        # jax.vmap: one batched SlopeResult, members equal to concrete runs
        taus = (1200.0, 1300.0)
        batched = jax.vmap(run)(jnp.array(taus))
        assert isinstance(batched, damjax.SlopeResult)
        assert batched.height.shape == (len(taus), *layout.n_cells)
        for i, t in enumerate(taus):
            r = run(t)
            assert float(batched.summary["release_area_smooth_m2"][i]) == pytest.approx(
                r.summary["release_area_smooth_m2"], rel=1e-9
            )
            # a sum of cell areas (multiples of dx^2): the batched run is another compiled
            # program, whose float64 sum may round in another order (~1e-16 relative)
            assert float(batched.summary["release_area_m2"][i]) == pytest.approx(
                r.summary["release_area_m2"], rel=1e-12
            )

        # jax.jit with a layout == the concrete run; the strength map does not fix the
        # layout, so jit needs none for it; a traced slope angle does: a message says how
        jitted = jax.jit(lambda t: area(t, layout=layout))(1250.0)
        assert float(jitted) == pytest.approx(area(1250.0), rel=1e-9)
        assert float(jax.jit(area)(1250.0)) == float(jitted)
        with pytest.raises(TypeError, match="slope_deg are unknown.*make_slope_layout"):
            jax.jit(lambda s: damjax.simulate_slope(params, setup, slope_deg=s))(35.0)


def test_out_of_range_values_under_jit_stop_the_run_with_the_field_named():
    """Inside jax.jit no value is known when the run is traced: a NaN or negative strength
    gradient, a NaN cell of a slope's strength map, stop the computation at run time with
    the field and its range instead of returning a plausible number (or NaN)."""
    setup = PSTSetup(length=8.0, dx=0.1, duration=0.2, chunk_steps=100)
    f = jax.jit(lambda th: damjax.simulate_pst(_with_theta(th), setup).arrest_position_smooth)
    assert np.isfinite(float(f(3000.0)))
    for bad in (float("nan"), -100.0):
        with pytest.raises(
            Exception,
            match=r"strength_gradient \(--strength-gradient\): a value outside \[0, inf\) Pa/m",
        ):  # noqa: E501
            jax.block_until_ready(f(bad))
    layout = damjax.make_layout(PARAMS, setup)
    g = jax.jit(
        lambda nu: damjax.arrest_position_smooth(
            eqx.tree_at(lambda p: p.poisson, PARAMS, nu), setup, layout
        )
    )
    with pytest.raises(Exception, match=r"poisson \(--poisson\): a value outside \(0, 0.5\)"):
        jax.block_until_ready(g(float("nan")))

    params, sset = _slope_case(jnp.float32)
    n = make_slope_layout(params, sset, 35.0).n_cells
    tau = np.full(n, 1250.0, np.float32)
    area = jax.jit(
        lambda t: damjax.simulate_slope(params, sset, tau_peak=t).summary["release_area_smooth_m2"]
    )
    assert np.isfinite(float(area(tau)))
    tau[1, 1] = np.nan
    with pytest.raises(Exception, match=r"tau_peak: a value outside \(0, inf\] Pa \(every cell\)"):
        jax.block_until_ready(area(tau))


def test_a_runtime_fault_stops_a_traced_smooth_summary():
    from damjax.core.state import FAULT_EDGE, raise_on_fault

    f = jax.jit(raise_on_fault)
    assert float(f(jnp.float32(2.5), jnp.int32(0))) == 2.5
    with pytest.raises(Exception, match="a particle reached the edge of the grid"):
        jax.block_until_ready(f(jnp.float32(2.5), jnp.int32(FAULT_EDGE)))


def test_concrete_runs_inside_a_jitted_function_keep_their_concrete_path():
    """Parameters captured by a jitted function (or static under equinox.filter_jit) are
    concrete: the run does not depend on what is traced, runs once while tracing, and
    gives the concrete run's value, where it stopped inside the AOT-compiled chunk
    ("Cannot apply JAX transformations to a function lowered and compiled ...") or on a
    tracer converted to numpy."""
    setup = PSTSetup(length=8.0, dx=0.1, duration=0.2, chunk_steps=100)
    concrete = damjax.simulate_pst(PARAMS, setup)
    f = jax.jit(lambda x: x * damjax.simulate_pst(PARAMS, setup).arrest_position_smooth)
    assert float(f(2.0)) == 2.0 * concrete.arrest_position_smooth
    g = eqx.filter_jit(lambda p: damjax.simulate_pst(p, setup).arrest_position_smooth)
    assert float(g(PARAMS)) == concrete.arrest_position_smooth
    # sweep runs its batch on the host: inside jax.jit a line says what to use instead
    batch = _with_theta(np.array(THETAS))
    with pytest.raises(TypeError, match="sweep: called inside jax.jit.*jax.vmap"):
        jax.jit(lambda x: x * damjax.sweep(batch, setup)[0].arrest_position_smooth)(2.0)

    params, sset = _slope_case(jnp.float32)
    area = damjax.simulate_slope(params, sset).summary["release_area_smooth_m2"]
    h = jax.jit(lambda x: x * damjax.simulate_slope(params, sset).summary["release_area_smooth_m2"])
    assert float(h(2.0)) == 2.0 * area


def test_shapes_under_jit_get_the_concrete_line():
    """Inside jax.jit only the shapes of traced inputs are known: a profile of one value or
    of two dimensions, a batched scalar and a slope map of the wrong shape stop the trace
    with the line a concrete value gets (they ran on silently: the (1,) profile gave an
    arrest of 20 m, a (5, 5) map the area of a uniform one, or failed inside numpy)."""
    setup = PSTSetup(length=8.0, dx=0.1, duration=0.2, chunk_steps=100)
    layout = damjax.make_layout(PARAMS, setup)

    def arrest(field, value):
        p = eqx.tree_at(lambda q: getattr(q, field), PARAMS, value, is_leaf=lambda x: x is None)
        return damjax.simulate_pst(p, setup, layout=layout).arrest_position_smooth

    cases = [
        ("strength_profile", np.full(1, 1000.0), r"has shape \(1,\): must be an array of >= 2"),
        ("strength_profile", np.full((3, 7), 1000.0), r"has shape \(3, 7\): must be a 1-D"),
        ("strength_gradient", np.full(3, 800.0), r"has shape \(3,\): must be a number"),
    ]
    for field, value, line in cases:
        with pytest.raises(damjax.validation.InputError, match=line):
            arrest(field, value)  # the concrete value's line
        with pytest.raises(damjax.validation.InputError, match=line):
            jax.jit(lambda v, field=field: arrest(field, v))(value)

    params, sset = _slope_case(jnp.float32)
    n = make_slope_layout(params, sset, 35.0).n_cells

    def area(t):
        return damjax.simulate_slope(params, sset, tau_peak=t).summary["release_area_smooth_m2"]

    for shape, line in [
        ((5, 5), rf"shape \(5, 5\) must be \(nx, ny\) = \({n[0]}, {n[1]}\)"),
        ((n[0],), r"must be a scalar or a 2D array"),
    ]:
        tau = np.full(shape, 1250.0, np.float32)
        with pytest.raises(damjax.validation.InputError, match=line):
            area(tau)
        with pytest.raises(damjax.validation.InputError, match=line):
            jax.jit(area)(tau)
