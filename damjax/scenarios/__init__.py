"""Deprecated since 2026-11-24: the simulations are `damjax.pst` and `damjax.slope`
(``damjax.simulate_pst``, ``damjax.simulate_slope``); the shipped scenario files are in
``damjax/scenario/library``."""

from damjax._deprecated import forward

__getattr__ = forward("damjax.scenarios", ["damjax.pst", "damjax.slope"])
