"""The model's parts (`damjax.core.state.Model`): flat names in `with_fields`, derived
constants derived again, and static fields that stay out of the traced leaves."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from damjax import PSTParams, PSTSetup, pst
from damjax.core.model import build
from damjax.core.state import DERIVED, PART_OF, PARTS, Model
from damjax.core.step import step


@pytest.fixture(scope="module")
def model_and_state():
    p = PSTParams(steady_length=2.0, strength_gradient=3000.0, tensile_strength=3000.0)
    s = PSTSetup(length=4.0, dx=0.1, duration=0.05, slab_fracture="crack_band")
    return build(p, s, pst.make_layout(p, s))


def test_every_field_has_one_part():
    names = [f.name for cls in PARTS.values() for f in dataclasses.fields(cls)]
    assert len(names) == len(set(names)) == len(PART_OF)
    top = {f.name for f in dataclasses.fields(Model)}
    assert set(PARTS) <= top and not (set(PART_OF) & top)
    assert set(DERIVED) <= set(PART_OF)


def test_with_fields_takes_flat_names_and_derives_again(model_and_state):
    model, _ = model_and_state
    u_res = 2.0 * model.weak_layer.u_res
    p0 = 0.5 * model.fracture.p0_init
    new = model.with_fields(u_res=u_res, p0_init=p0, dt=0.5 * model.dt)
    assert new.weak_layer.u_res is u_res and new.fracture.p0_init is p0
    assert float(new.dt) == 0.5 * float(model.dt)
    # the derived constants follow the new fields: the same as a model built with them
    fresh = dataclasses.replace(
        model,
        weak_layer=dataclasses.replace(model.weak_layer, u_res=u_res, front_width=None),
        fracture=dataclasses.replace(model.fracture, p0_init=p0, band_w_c=None),
    ).with_constants()
    np.testing.assert_array_equal(new.weak_layer.front_width, fresh.weak_layer.front_width)
    np.testing.assert_array_equal(new.fracture.band_w_c, fresh.fracture.band_w_c)
    assert not np.array_equal(new.weak_layer.front_width, model.weak_layer.front_width)
    # the other parts hold the model's own arrays
    for part in ("grid", "slab", "saw"):
        a, b = jax.tree.leaves(getattr(new, part)), jax.tree.leaves(getattr(model, part))
        assert all(x is y for x, y in zip(a, b, strict=True)), part


def test_with_fields_refuses_derived_and_unknown_names(model_and_state):
    model, _ = model_and_state
    with pytest.raises(ValueError, match="front_width"):
        model.with_fields(front_width=1.0)
    with pytest.raises(TypeError, match="u_r"):
        model.with_fields(u_r=1.0)


def test_with_fields_is_traceable(model_and_state):
    model, state = model_and_state

    def tip_after_a_step(scale):
        m = model.with_fields(u_res=scale * model.weak_layer.u_res)
        return jnp.sum(step(m, state).u_max)

    g = jax.grad(tip_after_a_step)(1.0)
    assert np.isfinite(float(g))


def test_static_fields_stay_static(model_and_state):
    # every traced leaf is an array: strings, flags and shapes are static, so a new value
    # of a traced field reuses the compiled step
    model, state = model_and_state
    assert all(isinstance(x, jax.Array) for x in jax.tree.leaves(model))
    traces = []

    @jax.jit
    def f(m, s):
        traces.append(1)
        return step(m, s)

    f(model, state)
    f(model.with_fields(softening=model.weak_layer.softening + 1.0), state)
    assert len(traces) == 1
    f(model.with_fields(lattice=(), lattice_spacing=0.0, opening_window=0), state)
    assert len(traces) == 2
