"""Deterministic particle-to-grid sums (`PSTSetup.accumulation`, `damjax.core.transfer`).

The "fixed" accumulation adds integers, so a run does not depend on the order in which its
particles are stored (nor, on a GPU, on the order of the atomic adds); "float" is the
plain float scatter-add; "auto", the setups' default, is "float" on a CPU and "fixed"
elsewhere. Small runs: a 10 m plastic strip and a 6 m x 6 m slope.
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from damjax import PSTParams, PSTSetup, SlopeSetup, scenario, simulate_pst, simulate_slope
from damjax.core import loop, transfer
from damjax.core.model import build, build_slope, make_layout, make_slope_layout
from damjax.pst import arrest_position_smooth, run_pure
from damjax.validation import setup_problems, slope_problems

# a plastic ("paper") slab with a low tensile strength, so the return map yields
PLASTIC = PSTParams(steady_length=3.0, strength_gradient=1500.0, tensile_strength=2500.0)
SLOPE = PSTParams(tau_peak=600.0, tensile_strength=4000.0)


def pst_setup(accumulation: str = "fixed", **kw) -> PSTSetup:
    base = dict(length=10.0, dx=0.05, duration=0.5, chunk_steps=500, slab_fracture="paper")
    return PSTSetup(**{**base, **kw}, accumulation=accumulation)


def slope_setup(accumulation: str = "fixed") -> SlopeSetup:
    return SlopeSetup(
        length=6.0,
        width=6.0,
        dx=0.2,
        duration=0.4,
        start=(3.0, 3.0),
        particles_per_cell=1,
        chunk_steps=500,
        accumulation=accumulation,
    )


def pst_model(accumulation: str):
    setup = pst_setup(accumulation)
    model, state = build(PLASTIC, setup, make_layout(PLASTIC, setup))
    # without the particle lattice (the openings are then strains x dx, as on slopes): the
    # lattice's window sums follow the particles' storage order by design
    model = model.with_fields(lattice=(), lattice_spacing=0.0, opening_window=0)
    return model, state


def slope_model(accumulation: str):
    setup = slope_setup(accumulation)
    layout = make_slope_layout(SLOPE, setup, 38.0)
    model, state, _, _ = build_slope(SLOPE, setup, layout, 38.0, 600.0)
    assert not model.fracture.lattice
    return model, state


def permuted(tree, perm: np.ndarray, n: int):
    """Every per-particle array (last axis n) of a Model or State in the order ``perm``."""
    return jax.tree.map(lambda x: x[..., perm] if jnp.ndim(x) and x.shape[-1] == n else x, tree)


def run(model, state, n_steps: int):
    return jax.block_until_ready(jax.jit(loop.run_chunk, static_argnums=2)(model, state, n_steps))


@pytest.mark.parametrize("make", [pst_model, slope_model], ids=["pst_1d_plastic", "slope_2d"])
def test_fixed_accumulation_does_not_depend_on_the_particle_order(make):
    """The same run with its particles stored in another order gives, bitwise, the same
    final state (reordered). "float" may differ in the last bits: not asserted."""
    model, state = make("fixed")
    n = state.u.shape[-1]
    perm = np.random.default_rng(0).permutation(n)
    n_steps = 600
    final, tips = run(model, state, n_steps)
    final_p, tips_p = run(permuted(model, perm, n), permuted(state, perm, n), n_steps)
    assert float(final.tip) > 0.5  # the crack ran
    if make is pst_model:
        assert np.any(np.asarray(final.eps_p[0]) != 0.0)  # the return map acted
    np.testing.assert_array_equal(np.asarray(tips), np.asarray(tips_p))
    for a, b in zip(
        jax.tree.leaves(permuted(final, perm, n)), jax.tree.leaves(final_p), strict=True
    ):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # the float scatter runs too (its last bits may depend on the order)
    model_f, state_f = make("float")
    final_f, _ = run(model_f, state_f, n_steps)
    assert np.allclose(np.asarray(final_f.u), np.asarray(final.u), rtol=1e-3, atol=1e-5)


def test_fixed_and_float_agree_on_the_diagnostics():
    """Fixed-point and float sums differ by float32 round-off: the same arrest and crack
    speed of a PST, the same release area of a slope."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = {
            a: simulate_pst(PLASTIC, pst_setup(a, length=15.0, duration=1.0))
            for a in ("fixed", "float")
        }
        s = {a: simulate_slope(SLOPE, slope_setup(a)) for a in ("fixed", "float")}
    fx, fl = r["fixed"].summary, r["float"].summary
    assert fx["arrested"] and fl["arrested"]
    assert fx["arrest_position_m"] == pytest.approx(fl["arrest_position_m"], abs=0.05 / 2)
    assert fx["max_crack_speed_over_cs"] == pytest.approx(fl["max_crack_speed_over_cs"], rel=1e-3)
    np.testing.assert_allclose(
        np.asarray(r["fixed"].slip), np.asarray(r["float"].slip), rtol=1e-3, atol=1e-6
    )
    area = {a: s[a].summary["release_area_m2"] for a in s}
    assert area["fixed"] > 1.0
    assert area["fixed"] == pytest.approx(area["float"], abs=2 * 0.2**2)


def test_gradients_through_the_fixed_path_equal_the_float_path():
    """The custom JVP takes the float scatter's tangent: the gradient of a small PST's
    smooth arrest position through the fixed path equals the float path's to round-off."""
    params = dataclasses.replace(PLASTIC, steady_length=2.0)
    out = {}
    for acc in ("fixed", "float"):
        setup = pst_setup(acc, length=8.0)
        layout = make_layout(params, setup)
        f = lambda p, s=setup, lay=layout: arrest_position_smooth(p, s, lay)  # noqa: E731
        out[acc] = jax.value_and_grad(f)(params)
    assert float(out["fixed"][0]) == pytest.approx(float(out["float"][0]), rel=1e-5)
    for name in ("strength_gradient", "tensile_strength", "youngs_modulus", "tau_peak"):
        g, h = float(getattr(out["fixed"][1], name)), float(getattr(out["float"][1], name))
        assert np.isfinite(g) and g != 0.0, name
        assert g == pytest.approx(h, rel=1e-3), name


def test_sweep_members_equal_single_runs_bitwise():
    """Under jax.vmap over parameters a member's fixed-point sums use its own scale: each
    member's final state equals its own run's, bitwise."""
    setup = pst_setup(duration=0.3)
    thetas = jnp.asarray([800.0, 1500.0, 3000.0], jnp.float32)
    layout = make_layout(PLASTIC, setup)

    def final(theta):
        return run_pure(dataclasses.replace(PLASTIC, strength_gradient=theta), setup, layout)[1]

    batched = jax.vmap(final)(thetas)
    for i, theta in enumerate(thetas):
        single = final(theta)
        for a, b in zip(jax.tree.leaves(batched), jax.tree.leaves(single), strict=True):
            np.testing.assert_array_equal(np.asarray(a)[i], np.asarray(b))


def test_p2g_is_exact_and_order_free_and_pairs_equal_single_channels():
    """Unit level: the fixed-point grids are the exact sums (float64 reference) to the
    quantum and one float32 rounding, equal under any order of the particles, equal whether
    two channels share a complex scatter or not, and per member under vmap."""
    rng = np.random.default_rng(3)
    shape, n = (12, 9), 400
    nn = int(np.prod(shape))
    cell0 = jnp.asarray(rng.integers(2, 7, size=(2, n)), jnp.int32)
    frac0 = jnp.asarray(rng.random((2, n)), jnp.float32)
    u = jnp.asarray(rng.normal(0, 0.05, (2, n)), jnp.float32)
    vals = [jnp.asarray(rng.normal(size=n) * 10.0**e, jnp.float32) for e in (-3, 0, 4)]

    def grids(c, f, uu, vv):
        st = transfer.stencil(c, f, uu, 0.1, shape)
        return st, transfer.p2g_channels(st, [[w * v for w in st.w] for v in vv], nn)

    st, out = grids(cell0, frac0, u, vals)
    for v, g in zip(vals, out, strict=True):
        rows = [st.w[k] * v for k in range(len(st.idx))]
        ref = np.zeros(nn)
        for k, r in enumerate(rows):
            np.add.at(ref, np.asarray(st.idx[k]), np.asarray(r, np.float64))
        # each contribution is rounded to 2^-s <= 2 N 2^-52 max|v| (N = 9 n), then the sum
        # once to float32: within that of the exact sum, and closer than the float scatter
        top = max(float(jnp.max(jnp.abs(r))) for r in rows)
        quantum = 2 * 9 * n * 2.0**-52 * top
        err = np.abs(np.asarray(g, np.float64) - ref)
        assert np.all(err <= np.abs(ref) * 2.0**-24 + 40 * quantum)
        flt = transfer.p2g_channels(st, [rows], nn, "float")[0]
        assert err.max() <= np.abs(np.asarray(flt, np.float64) - ref).max()
        single = transfer.p2g(st, rows, nn)
        np.testing.assert_array_equal(np.asarray(single), np.asarray(g))
    perm = rng.permutation(n)
    _, out_p = grids(cell0[:, perm], frac0[:, perm], u[:, perm], [v[perm] for v in vals])
    for a, b in zip(out, out_p, strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    scales = jnp.asarray([1.0, 1e-20, 3e20], jnp.float32)
    batched = jax.vmap(lambda s: grids(cell0, frac0, u, [v * s for v in vals])[1])(scales)
    for i, s in enumerate(scales):
        single = grids(cell0, frac0, u, [v * s for v in vals])[1]
        for a, b in zip(batched, single, strict=True):
            np.testing.assert_array_equal(np.asarray(a)[i], np.asarray(b))
    # a non-finite contribution: NaN grids, as the float path's nodes
    bad = [vals[0].at[5].set(jnp.nan)]
    assert np.isnan(np.asarray(grids(cell0, frac0, u, bad)[1][0])).any()


def test_invalid_accumulation_is_a_clear_error():
    problems = [str(p) for p in setup_problems(pst_setup("fixedpoint"))]
    assert problems == ["accumulation = 'fixedpoint': must be in {auto, fixed, float}"]
    problems = [str(p) for p in slope_problems(SLOPE, slope_setup("atomic"), 38.0, 600.0)]
    assert problems == ["accumulation = 'atomic': must be in {auto, fixed, float}"]
    with pytest.raises(
        ValueError, match=r"accumulation = 'atomic': must be in \{auto, fixed, float\}"
    ):
        simulate_pst(PLASTIC, pst_setup("atomic"))
    for kind, valid in (
        ("pst", "in {auto, fixed, float}"),
        ("slope", 'one of {"auto", "fixed", "float"}'),
    ):
        with pytest.raises(
            ValueError, match=re.escape(f'setup.accumulation = "bogus": must be {valid}')
        ):
            scenario.parse(
                {"type": kind, "name": "t", "setup": {"accumulation": "bogus", "length": 30.0}},
                warn=False,
            )
    st = transfer.stencil(jnp.zeros((1, 3), jnp.int32) + 2, jnp.full((1, 3), 0.5), 0.0, 0.1, (8,))
    with pytest.raises(ValueError, match="accumulation = 'det'"):
        transfer.p2g_channels(st, [list(st.w)], 8, "det")


def test_auto_accumulation_is_float_on_a_cpu_and_fixed_elsewhere():
    assert transfer.resolve_accumulation("auto", "cpu") == "float"
    for backend in ("gpu", "cuda", "rocm", "tpu"):
        assert transfer.resolve_accumulation("auto", backend) == "fixed"
    for acc in ("fixed", "float"):
        assert transfer.resolve_accumulation(acc, "cpu") == acc
        assert transfer.resolve_accumulation(acc, "gpu") == acc
    with pytest.raises(ValueError, match="accumulation = 'atomic'"):
        transfer.resolve_accumulation("atomic")
    # the setups default to "auto"; the model holds what it resolves to on this backend
    assert PSTSetup().accumulation == SlopeSetup().accumulation == "auto"
    want = transfer.resolve_accumulation("auto")
    assert pst_model("auto")[0].accumulation == want
    assert slope_model("auto")[0].accumulation == want


def test_transfers_pair_channels_on_a_cpu_only_and_never_in_128_bits(monkeypatch):
    """XLA:GPU rewrites a scatter of elements wider than 64 bits (complex128) into a loop
    over its updates, one at a time, and adds complex64 through a compare-and-swap loop.
    Traced for a GPU (the default backend patched to "gpu") and exported for CUDA
    (`jax.export`, no GPU needed), the transfers and a whole 1D step, with their
    gradients, hold no complex array at all; on the CPU float32 channels go in complex64
    pairs and nothing in complex128, with float32 or float64 data."""
    from jax import export

    rng = np.random.default_rng(0)
    n, shape = 50, (12,)
    nn = int(np.prod(shape))

    def module(dtype, accumulation: str, platform: str) -> str:
        cell0 = jnp.asarray(rng.integers(3, 8, size=(1, n)), jnp.int32)
        frac0 = jnp.asarray(rng.random((1, n)), dtype)
        vals = [jnp.asarray(rng.normal(size=n), dtype) for _ in range(3)]

        def f(u, vals):
            st = transfer.stencil(cell0, frac0, u, 0.1, shape)
            chans = [[w * v for w in st.w] for v in vals]
            grids = transfer.p2g_channels(st, chans, nn, accumulation)
            rows = transfer.g2p_channels(st, grids[:2])
            return sum(jnp.sum(r) for rs in rows for r in rs) + jnp.sum(grids[2])

        u = jnp.zeros((1, n), dtype)
        fn = jax.jit(jax.grad(f, argnums=(0, 1)))
        return export.export(fn, platforms=[platform])(u, vals).mlir_module()

    def step_module(accumulation: str) -> str:
        model, state = pst_model(accumulation)

        def loss(u):
            out = loop.run_chunk(model, dataclasses.replace(state, u=u), 3)[0]
            return jnp.sum(out.u) + jnp.sum(out.sigma[0])

        fn = jax.jit(jax.grad(loss))
        return export.export(fn, platforms=["cuda"])(state.u).mlir_module()

    for acc in ("fixed", "float"):
        cpu = module(jnp.float32, acc, "cpu")
        assert "scatter" in cpu and "complex<f32>" in cpu, acc  # the CPU's pairs
        assert "complex<f64>" not in cpu, acc
        with jax.enable_x64(True):
            assert "complex" not in module(jnp.float64, acc, "cpu"), acc
    monkeypatch.setattr(jax, "default_backend", lambda: "gpu")
    for acc in ("fixed", "float"):
        cuda = module(jnp.float32, acc, "cuda")
        assert "scatter" in cuda and "complex" not in cuda, acc
        with jax.enable_x64(True):
            assert "complex" not in module(jnp.float64, acc, "cuda"), acc
        text = step_module(acc)
        assert "scatter" in text and "complex" not in text, acc
