"""The time step (`damjax.core.step`): a driver over named phases, bit for bit.

- the step is its phases called in order: a driver written out here gives the same bits
  on any backend (one program);
- the phases' names (``jax.named_scope``) are in the lowered program, so a profile reads
  by phase;
- on XLA:CPU, a few steps of small 1D and 2D models from a perturbed state (the slab
  yields and fractures, the weak layer breaks, the saw cuts) give the bits recorded
  before the step was split into phases (the single-function step of commit 00f49bb).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from damjax import PSTParams, PSTSetup, SlopeSetup, pst
from damjax.core import step as step_module
from damjax.core.model import build, build_slope, make_slope_layout
from damjax.core.step import step

PHASES = ("weak_layer", "p2g", "grid_update", "g2p", "slab_law", "crack_and_saw", "guards")
N_STEPS = 8


def _perturbed(model, state):
    """``state`` with random velocities, affine velocities and damage: within a few steps
    the slab yields and fractures and the weak layer breaks (every branch of the step)."""
    rng = np.random.default_rng(0)
    dt = state.v.dtype
    return dataclasses.replace(
        state,
        v=np.asarray(rng.normal(0.0, 0.5, state.v.shape), dt),
        C=np.asarray(rng.normal(0.0, 30.0, state.C.shape), dt),
        u_max=np.asarray(model.weak_layer.u_res * rng.uniform(0.9, 1.0, state.u_max.shape), dt),
    )


def _case(name):
    p = PSTParams(
        steady_length=2.0, strength_gradient=3000.0, tensile_strength=3000.0, softening=1.0
    )
    if name == "pst_1d":  # crack-band slab on a lattice, free strip
        s = PSTSetup(length=4.0, dx=0.05, duration=0.05, slab_fracture="crack_band", seed=1)
        model, state = build(p, s, pst.make_layout(p, s))
    elif name == "pst_2d":  # the 2D step on a strip periodic in y
        s = PSTSetup(length=3.0, dx=0.1, duration=0.05, dim=2, lateral="constrained")
        model, state = build(p, s, pst.make_layout(p, s))
    else:  # a slope with a crack-band slab and a fall line off the x axis
        q = PSTParams(tau_peak=800.0, softening=1.0, tensile_strength=3000.0)
        s = SlopeSetup(
            length=4.0,
            width=2.0,
            dx=0.25,
            duration=0.2,
            start=(1.0, 1.0),
            particles_per_cell=2,
            slab_fracture="crack_band",
            seed=2,
        )
        layout = make_slope_layout(q, s, 38.0)
        model, state, _, _ = build_slope(q, s, layout, 38.0, 800.0, 10.0)
    return model, _perturbed(model, state)


CASES = ("pst_1d", "pst_2d", "slope_2d")


def _phases_in_order(model, state):
    """The step written out from its phases (`damjax.core.step`)."""
    sp = step_module
    mass = model.mass
    wl = sp.weak_layer_forces(model, state)
    sums = sp.particles_to_grid(model, state, wl, mass)
    grid = sp.grid_update(model, sums, mass)
    motion = sp.grid_to_particles(model, state, sums.stencil, grid.velocity, sums.active)
    slab = sp.slab_law(model, state, motion.C)
    crack = sp.crack_and_saw(model, state, motion.u, wl.time, wl.saw_pos)
    faults = sp.guards(model, state, sums.stencil, grid.speed2, slab.eps, wl.time)
    return dataclasses.replace(
        state,
        u=motion.u,
        v=motion.v,
        C=motion.C,
        outflow=motion.outflow,
        eps=slab.eps,
        sigma=slab.sigma,
        eps_p=slab.eps_p,
        opening=slab.opening,
        opening_y=slab.opening_y,
        t_fracture=slab.t_fracture,
        u_max=crack.u_max,
        t_broken=crack.t_broken,
        tip=crack.tip,
        saw_active=crack.saw_active,
        time=wl.time,
        saw_pos=wl.saw_pos,
        fault=faults.fault,
        fault_time=faults.fault_time,
    )


def _run(f, model, state):
    for _ in range(N_STEPS):
        state = f(model, state)
    return state


@pytest.mark.parametrize("name", CASES)
def test_step_is_its_phases_in_order_bit_for_bit(name):
    model, state = _case(name)
    a = _run(jax.jit(step), model, state)
    b = _run(jax.jit(_phases_in_order), model, state)
    assert int(a.fault) == 0
    # the steps did what they are here for: plastic flow, fractures, broken weak layer
    assert np.max(a.opening) > 0.0
    assert np.any(np.isfinite(a.t_fracture)) and np.any(np.isfinite(a.t_broken))
    assert jax.tree.structure(a) == jax.tree.structure(b)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_the_lowered_step_names_its_phases():
    model, state = _case("pst_1d")
    text = jax.jit(step).lower(model, state).as_text(debug_info=True)
    for phase in PHASES:
        assert f"/{phase}/" in text, phase


# sha256 (first 16 hex digits) of the state's leaves after N_STEPS steps of `_case`:
# recorded with the single-function step of commit 00f49bb (jax 0.10.2, XLA:CPU; the
# 1D and 2D PSTs' bits are also those of commit 7097dab, before slopes had outflow)
PINNED = {
    "pst_1d": "375faea6d5d2834b",
    "pst_2d": "2e831db90e883813",
    "slope_2d": "8e92e1bde2d6eb00",
}


@pytest.mark.skipif(
    jax.default_backend() != "cpu" or jax.__version__ != "0.10.2",
    reason="bits recorded on XLA:CPU of jax 0.10.2; another compiler may round otherwise "
    "(the phase test above holds everywhere)",
)
def test_step_gives_the_bits_of_the_single_function_step():
    # in a fresh interpreter: the bits are those of a process in its default state, not
    # of whatever jax configuration the tests run before this one in a worker left
    code = (
        "import importlib.util, json, sys; "
        f"spec = importlib.util.spec_from_file_location('ts', {str(Path(__file__))!r}); "
        "ts = importlib.util.module_from_spec(spec); spec.loader.exec_module(ts); "
        "print(json.dumps({n: ts._state_hash(n) for n in ts.CASES}))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=False
    )
    assert out.returncode == 0, out.stderr[-3000:]
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {n: PINNED[n] for n in CASES}


def _state_hash(name: str) -> str:
    """sha256 (first 16 hex digits) of the state's leaves after N_STEPS steps of a case."""
    model, state = _case(name)
    final = _run(jax.jit(step), model, state)
    h = hashlib.sha256()
    for leaf in jax.tree.leaves(final):
        h.update(np.asarray(leaf).tobytes())
    return h.hexdigest()[:16]
