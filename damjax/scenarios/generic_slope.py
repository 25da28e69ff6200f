"""Deprecated since 2026-11-24: `damjax.slope.generic`."""

from damjax._deprecated import forward

__getattr__ = forward("damjax.scenarios.generic_slope", ["damjax.slope.generic"])
