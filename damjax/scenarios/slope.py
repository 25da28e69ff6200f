"""Deprecated since 2026-11-24: `damjax.slope` (``damjax.simulate_slope``), with the
layout and model in `damjax.core.model` and the input checks in `damjax.validation`."""

from damjax._deprecated import forward

__getattr__ = forward(
    "damjax.scenarios.slope",
    ["damjax.slope.simulation", "damjax.params", "damjax.core.model"],
    {
        "make_layout": "damjax.core.model:make_slope_layout",
        "build": "damjax.core.model:build_slope",
        "_problems": "damjax.validation:slope_problems",
    },
)
