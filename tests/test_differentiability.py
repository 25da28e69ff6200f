"""Gradients of the smooth arrest position, sweeps and sharding."""

import dataclasses
import json
import math
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import damjax
from damjax import PSTParams, PSTSetup, pst

SETUP = PSTSetup(length=10.0, dx=0.05, duration=0.5, chunk_steps=250)
PARAMS = PSTParams(steady_length=4.0, strength_gradient=800.0, softening=1.0)


@pytest.fixture(scope="module")
def smooth_fn():
    layout = pst.make_layout(PARAMS, SETUP)
    f = jax.jit(lambda q: pst.arrest_position_smooth(q, SETUP, layout))
    g = jax.jit(jax.grad(lambda q: pst.arrest_position_smooth(q, SETUP, layout)))
    return f, g


def test_smooth_arrest_position_tracks_the_event_based_tip(smooth_fn):
    f, _ = smooth_fn
    r = damjax.simulate_pst(PARAMS, SETUP)
    assert abs(float(f(PARAMS)) - r.summary["final_tip_m"]) < 0.2
    assert r.arrest_position_smooth == pytest.approx(float(f(PARAMS)), abs=1e-4)


@pytest.mark.min_versions
@pytest.mark.parametrize(
    "name",
    ["strength_gradient", "softening", "youngs_modulus", "wl_shear_modulus", "steady_length"],
)
def test_gradient_brackets_central_differences_at_two_steps(smooth_fn, name):
    """The surrogate is continuous and piecewise smooth: it has kinks where a weak-layer
    segment enters or leaves its partly failed range (measured on this PST: the slope in
    theta doubles over theta 798.4-800.9 while two segments are partly failed). So the
    difference quotient over [x, x + h] must lie between the AD derivatives at its two
    ends (a jump, which AD cannot see, would put it far outside), within 5 %."""
    f, g = smooth_fn
    x0 = float(getattr(PARAMS, name))
    h = 2.5e-3 * abs(x0)
    xs = [x0 - h, x0, x0 + h]
    qs = [dataclasses.replace(PARAMS, **{name: x}) for x in xs]
    vals = [float(f(q)) for q in qs]
    ads = [float(getattr(g(q), name)) for q in qs]
    assert all(a != 0.0 for a in ads), (name, ads)
    for i in range(2):
        fd = (vals[i + 1] - vals[i]) / h
        lo, hi = sorted(ads[i : i + 2])
        tol = 0.05 * max(abs(lo), abs(hi))
        assert lo - tol <= fd <= hi + tol, (name, xs[i], ads[i : i + 2], fd)


def test_tensile_strength_gradient_matches_central_differences():
    """sigma_t where the slab yields (MCC) but does not fracture: the arrest moves smoothly.

    The plastic slab caps the tension ahead of the tip, so the layer there stays below
    0.9 u_r and the default 10 % damage ramp holds no particle: the surrogate is a
    multiple of the particle spacing with a zero gradient (measured: 5.025 m at
    sigma_t = 4200 Pa). The ramp over the whole softening branch, w = delta / (1 + delta)
    = 0.5 (the documented choice for plastic slabs), keeps particles in it. That
    surrogate is piecewise smooth (kinks where a particle enters the plastic branch or
    the ramp), so central differences are compared at a point with no kink within the
    steps: measured AD 3.956e-4 vs FD 3.986e-4 / 3.979e-4 / 3.964e-4 m/Pa (steps 0.1, 0.25,
    0.5 %) at 4500 Pa, f32 and f64 alike.
    """
    q = dataclasses.replace(PARAMS, tensile_strength=4500.0)
    # the paper's perfectly plastic slab: the crack-band slab's reverse-mode gradient
    # misses how its fractures move (calibrate_slope(gradient="fd") is for that one)
    setup = dataclasses.replace(SETUP, slab_fracture="paper")
    layout = pst.make_layout(q, setup)
    f = jax.jit(lambda q: pst.arrest_position_smooth(q, setup, layout, width=0.5))
    g = jax.jit(jax.grad(lambda q: pst.arrest_position_smooth(q, setup, layout, width=0.5)))
    r = damjax.simulate_pst(q, setup)
    assert r.fractures == []  # no slab fracture ...
    assert float(np.max(r.opening)) > 0.0  # ... but the slab has yielded
    ad = float(g(q).tensile_strength)
    assert ad > 0.0  # a stronger slab carries more tension: the crack runs further
    for rel in (2.5e-3, 5e-3):
        h = rel * 4500.0
        fd = (
            float(f(dataclasses.replace(q, tensile_strength=4500.0 + h)))
            - float(f(dataclasses.replace(q, tensile_strength=4500.0 - h)))
        ) / (2 * h)
        assert abs(fd / ad - 1) <= 0.05, (rel, ad, fd)


def test_gradient_is_finite_for_every_finite_field_with_an_infinite_one(smooth_fn):
    _, g = smooth_fn
    assert math.isinf(PARAMS.tensile_strength)
    grads = g(PARAMS)
    for f in dataclasses.fields(PARAMS):
        v = getattr(grads, f.name)
        if v is None or not math.isfinite(float(getattr(PARAMS, f.name))):
            continue
        assert np.isfinite(float(v)), f.name
    # a finite slab strength that is never reached: zero, finite gradient
    q = dataclasses.replace(PARAMS, tensile_strength=1e5)
    layout = pst.make_layout(q, SETUP)
    gs = jax.grad(lambda p: pst.arrest_position_smooth(p, SETUP, layout))(q)
    assert float(gs.tensile_strength) == 0.0


def test_elastic_layout_rejects_a_traced_finite_tensile_strength(smooth_fn):
    """The slab law is static: a layout made at sigma_t = inf skips the return map, so a
    finite traced sigma_t on it is an error, not a silently elastic slab."""
    _, g = smooth_fn
    with pytest.raises(Exception, match="layout was made for an elastic slab"):
        # blocked on: under asynchronous dispatch the runtime error surfaces when the
        # result is read, which may otherwise be after this block has closed
        jax.block_until_ready(g(dataclasses.replace(PARAMS, tensile_strength=4500.0)))


@pytest.mark.min_versions
def test_sweep_equals_a_loop_of_simulate_pst():
    batch = PSTParams(
        steady_length=4.0,
        strength_gradient=jnp.array([1000.0, 3000.0]),
        softening=jnp.array([0.0, 2.0]),
    )
    results = damjax.sweep(batch, SETUP)
    sliced = damjax.sweep(batch, SETUP, batch_size=1)
    for i, (theta, delta) in enumerate([(1000.0, 0.0), (3000.0, 2.0)]):
        ref = damjax.simulate_pst(
            PSTParams(steady_length=4.0, strength_gradient=theta, softening=delta), SETUP
        )
        for r in (results[i], sliced[i]):
            # a vmapped batch and a single run are two compiled programs: on a GPU their
            # fusions may round differently, so the tip may differ by one particle
            spacing = SETUP.dx / SETUP.particles_per_cell
            assert r.summary["final_tip_m"] == pytest.approx(
                ref.summary["final_tip_m"], abs=spacing * 1.001
            )
            np.testing.assert_allclose(r.sigma_xx, ref.sigma_xx, rtol=1e-4, atol=0.05)
            assert r.arrest_position_smooth == pytest.approx(ref.arrest_position_smooth, abs=1e-4)


@pytest.mark.min_versions
def test_sweep_sharded_over_four_host_devices_equals_unsharded():
    code = textwrap.dedent("""
        import os, json
        # four CPU host devices, also on a machine with a GPU (the question is the sharding)
        os.environ["JAX_PLATFORMS"] = "cpu"
        # four devices on a CI machine with two busy cores: an all-reduce may wait for a
        # device's thread for longer than XLA's default 40 s before it aborts the process
        os.environ["XLA_FLAGS"] = ("--xla_force_host_platform_device_count=4 "
                                   "--xla_cpu_collective_call_terminate_timeout_seconds=600")
        import jax, jax.numpy as jnp, damjax
        from damjax import PSTParams, PSTSetup
        assert len(jax.devices()) == 4
        s = PSTSetup(length=8.0, dx=0.05, duration=0.3, chunk_steps=100)
        b = PSTParams(steady_length=3.0, strength_gradient=jnp.array([800., 1500., 3000.]))
        a = damjax.sweep(b, s, shard=True)
        u = damjax.sweep(b, s, shard=False)
        print(json.dumps([[r.summary["final_tip_m"], float(r.sigma_xx.max())] for r in a]
                         + [[r.summary["final_tip_m"], float(r.sigma_xx.max())] for r in u]))
    """)
    # 5-10 s, also beside busy processes. Until 2026-11-26 the sweep sliced its members
    # from the sharded arrays, one cross-device gather (an all-reduce) per leaf and member,
    # and under load the host devices' collective rendezvous stalled past 600 s
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    rows = json.loads(out.stdout.strip().splitlines()[-1])
    sharded, unsharded = rows[:3], rows[3:]
    np.testing.assert_allclose(sharded, unsharded, rtol=1e-5)


def test_sweep_rejects_inconsistent_batches():
    with pytest.raises(
        ValueError, match=r"different lengths \(strength_gradient: 2; softening: 3\)"
    ):
        damjax.sweep(PSTParams(strength_gradient=jnp.ones(2), softening=jnp.ones(3)), SETUP)
    with pytest.raises(ValueError, match="poisson"):
        damjax.sweep(PSTParams(poisson=jnp.array([0.3, 0.7])), SETUP)


def test_grad_without_a_layout_is_a_clear_error():
    with pytest.raises(TypeError, match="make_layout"):
        jax.grad(damjax.arrest_position_smooth)(PARAMS, SETUP)
    layout = damjax.make_layout(PARAMS, SETUP)  # the documented way (README)
    g = jax.grad(lambda p: damjax.arrest_position_smooth(p, SETUP, layout))(PARAMS)
    assert float(g.strength_gradient) < 0.0  # a steeper strength rise stops the crack sooner


def test_jit_without_a_layout_over_fields_that_do_not_fix_it():
    """Inside jax.jit the layout is made from the fields that are not traced: a traced
    strength gradient (elastic slab) or tensile strength (plastic slab) needs no layout
    and gives the layout path's values; a traced field that fixes the grid or the step
    count is a clear error naming it (and so is a traced one in arrest_position_smooth)."""

    def smooth(p, **kw):
        return damjax.simulate_pst(p, SETUP, **kw).arrest_position_smooth

    elastic = PARAMS
    plastic = dataclasses.replace(PARAMS, tensile_strength=4500.0)
    for params, name, value in (
        (elastic, "strength_gradient", 700.0),
        (plastic, "tensile_strength", 4000.0),
    ):
        layout = damjax.make_layout(dataclasses.replace(params, **{name: value}), SETUP)

        def with_value(v, params=params, name=name):
            return dataclasses.replace(params, **{name: v})

        free = jax.jit(lambda v: smooth(with_value(v)))(value)
        given = jax.jit(lambda v, layout=layout: smooth(with_value(v), layout=layout))(value)
        assert float(free) == float(given), name
        assert np.isfinite(float(free))
    # arrest_position_smooth: jax.grad over a field that does not fix the layout
    th = PARAMS.strength_gradient
    layout = damjax.make_layout(PARAMS, SETUP)
    g = jax.grad(
        lambda t: damjax.arrest_position_smooth(
            dataclasses.replace(PARAMS, strength_gradient=t), SETUP
        )
    )(th)
    g_layout = jax.grad(
        lambda t: damjax.arrest_position_smooth(
            dataclasses.replace(PARAMS, strength_gradient=t), SETUP, layout
        )
    )(th)
    assert float(g) == float(g_layout) and float(g) < 0.0
    for name in ("wl_shear_modulus", "youngs_modulus", "softening"):
        with pytest.raises(TypeError, match=f"{name} are unknown.*make_layout"):
            jax.jit(lambda v, name=name: smooth(dataclasses.replace(PARAMS, **{name: v})))(1.0)
    with pytest.raises(TypeError, match="wl_shear_modulus traced.*make_layout"):
        jax.grad(
            lambda g: damjax.arrest_position_smooth(
                dataclasses.replace(PARAMS, wl_shear_modulus=g), SETUP
            )
        )(2.0e5)


def _checkpointed_value_and_grad(params: PSTParams, setup: PSTSetup, mode: object):
    from damjax.core.loop import integrate_pure
    from damjax.diagnostics import smooth_arrest_position

    layout = pst.make_layout(params, setup)

    def f(q):
        model, state = pst.build(q, setup, layout)
        final, _ = integrate_pure(model, state, layout.n_chunks, layout.chunk_steps, mode)
        # the plastic slab's surrogate needs the wide ramp (see the sigma_t test above)
        return smooth_arrest_position(model, final, 0.5 if layout.plastic else None)

    return jax.jit(jax.value_and_grad(f))(params)


@pytest.mark.parametrize("tensile_strength", [math.inf, 4500.0])
def test_checkpoint_schemes_give_the_same_gradient(tensile_strength):
    """Per-step rematerialisation (default) == blocks == no remat, elastic and MCC slab.

    In float64, where the three schemes must agree to rounding. (In float32 the plastic
    slab's gradient moves by up to ~1 % between compilations of the same maths: the return
    mapping switches on the sign of a yield function that rounding can flip. The float32
    accuracy of the default scheme is checked against float64 below.)
    """
    params = dataclasses.replace(PARAMS, tensile_strength=tensile_strength)
    names = ["strength_gradient", "softening", "youngs_modulus"]
    if math.isfinite(tensile_strength):
        names.append("tensile_strength")
    with jax.enable_x64(True):
        setup = dataclasses.replace(SETUP, dtype="float64")
        modes = ("steps", "blocks", False)
        out = {m: _checkpointed_value_and_grad(params, setup, m) for m in modes}
        v0, g0 = out[False]
        for m in ("steps", "blocks"):
            v, g = out[m]
            assert float(v) == pytest.approx(float(v0), rel=1e-12)
            for name in names:
                a, b = float(getattr(g, name)), float(getattr(g0, name))
                assert b != 0.0, name
                assert a == pytest.approx(b, rel=1e-9), (m, name, a, b)
        with pytest.raises(ValueError, match="checkpoint"):
            _checkpointed_value_and_grad(params, setup, "sometimes")


def test_float32_gradient_of_the_plastic_slab_matches_float64():
    """The default scheme's single-precision gradients on an MCC slab, against float64.

    The crack length is piecewise smooth: its derivative changes where a weak-layer
    segment enters or leaves its partly failed range, which happens densely in the
    parameters (measured in float64: d L / d delta is -0.6940, -0.6964, -0.6923, -0.6929,
    -0.6890 at delta = 1 - 1e-4, 1 - 3e-5, 1, 1 + 3e-5, 1 + 1e-4). Float32 rounding moves
    the run by about that much, so its gradient must be the float64 gradient of a nearby
    run: inside the range of the float64 gradients over delta x (1 +- 1e-4), within 0.5 %.
    """
    params = dataclasses.replace(PARAMS, tensile_strength=4500.0)
    v32, g32 = _checkpointed_value_and_grad(params, SETUP, "steps")
    names = ["strength_gradient", "softening", "youngs_modulus", "tensile_strength"]
    g64s = []
    with jax.enable_x64(True):
        for rel in (-1e-4, -3e-5, 0.0, 3e-5, 1e-4):
            p = dataclasses.replace(params, softening=params.softening * (1.0 + rel))
            v, g = _checkpointed_value_and_grad(
                p, dataclasses.replace(SETUP, dtype="float64"), "steps"
            )
            g64s.append(g)
            if rel == 0.0:
                v64 = v
    assert float(v32) == pytest.approx(float(v64), abs=1e-3)
    for name in names:
        a = float(getattr(g32, name))
        b = [float(getattr(g, name)) for g in g64s]
        tol = 5e-3 * max(abs(x) for x in b)
        assert min(b) - tol <= a <= max(b) + tol, (name, a, b)
