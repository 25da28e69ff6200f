"""`damjax.sweep` without ``batch_size``: slices from XLA's memory estimate of the compiled
chunk (`damjax.last_sweep_plan()`), the same results as the whole batch vmapped."""

import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import damjax
from damjax import PSTParams, PSTSetup

SETUP = PSTSetup(length=10.0, dx=0.05, duration=0.5, chunk_steps=250)


def test_sweep_slices_the_batch_from_the_memory_estimate():
    batch = PSTParams(steady_length=4.0, strength_gradient=jnp.array([1000.0, 2000.0, 3000.0]))
    whole = damjax.sweep(batch, SETUP)
    plan = damjax.last_sweep_plan()
    assert plan.chosen == "memory" and plan.members == 3
    assert plan.peak_bytes_whole_batch is None or plan.bytes_per_member > 0
    # a budget below one member's temporaries: one member per slice
    with pytest.warns(UserWarning, match="exceeds memory_fraction"):
        sliced = damjax.sweep(batch, SETUP, memory_fraction=1e-12)
    small = damjax.last_sweep_plan()
    if plan.peak_bytes_whole_batch is not None:  # the backend estimates memory
        assert plan.slice_size == plan.members_per_device  # the host has room for 3
        assert small.slice_size == 1 and small.chosen == "memory"
    damjax.sweep(batch, SETUP, batch_size=2)
    assert damjax.last_sweep_plan().chosen == "given" and damjax.last_sweep_plan().slice_size == 2
    for a, b in zip(whole, sliced, strict=True):
        assert a.summary["final_tip_m"] == b.summary["final_tip_m"]
        np.testing.assert_allclose(a.sigma_xx, b.sigma_xx, rtol=1e-5, atol=0.05)
    with pytest.raises(ValueError, match=r"memory_fraction = 0: must be in \(0, 1\]"):
        damjax.sweep(batch, SETUP, memory_fraction=0)


def test_on_a_cpu_a_large_batch_runs_in_slices_of_cpu_slice(monkeypatch):
    """On a CPU a vmapped batch larger than `CPU_SLICE` outgrows the caches: it runs in
    slices of `CPU_SLICE` members (here lowered to 2), with the results of `batch_size`."""
    sweep_module = sys.modules["damjax.sweep"]  # the module (damjax.sweep is the function)
    if jax.devices()[0].platform != "cpu":
        pytest.skip("the CPU rule")
    monkeypatch.setattr(sweep_module, "CPU_SLICE", 2)
    batch = PSTParams(steady_length=4.0, strength_gradient=jnp.array([1000.0, 2000.0, 3000.0]))
    auto = damjax.sweep(batch, SETUP)
    plan = damjax.last_sweep_plan()
    assert (plan.chosen, plan.slice_size, plan.peak_bytes_whole_batch) == ("cpu", 2, None)
    given = damjax.sweep(batch, SETUP, batch_size=2)
    for a, b in zip(auto, given, strict=True):
        assert a.summary["final_tip_m"] == b.summary["final_tip_m"]


def test_an_invalid_batch_member_is_named():
    batch = PSTParams(steady_length=4.0, strength_gradient=jnp.array([1000.0, np.nan, -1.0]))
    with pytest.raises(ValueError, match=r"strength_gradient .* \(batch members 1, 2\)"):
        damjax.sweep(batch, SETUP)
