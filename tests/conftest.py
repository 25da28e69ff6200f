"""Shared fixtures: small PST setups that run in seconds on 2 CPU cores."""

import pytest

from damjax import PSTParams, PSTSetup


@pytest.fixture
def small_setup() -> PSTSetup:
    """A 15 m PST at dx = 0.05 m (Lambda/13), 1 s."""
    return PSTSetup(length=15.0, dx=0.05, duration=1.0, chunk_steps=250)


@pytest.fixture
def arresting_params() -> PSTParams:
    """Strong gradient so that the crack arrests within a 15 m PST."""
    return PSTParams(steady_length=5.0, strength_gradient=3000.0)
