"""Deprecated since 2026-11-24: `damjax.scenario.slope` (the format),
`damjax.scenario.slope_fields` (fields and runs of a scenario) and `damjax.slope.results`
(crack-speed map, NetCDF dataset, results read back)."""

from damjax._deprecated import forward

__getattr__ = forward(
    "damjax.slope_scenario",
    ["damjax.scenario.slope", "damjax.scenario.slope_fields", "damjax.slope.results"],
)
