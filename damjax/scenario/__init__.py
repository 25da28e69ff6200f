"""Scenario files: a whole run (physics, numerics, outputs) in one TOML file.

- `schema`: the format common to every type (the document, ``[output]``, reading,
  writing, the shipped `library/`), and `register` for the scenario types;
- `pst`: ``type = "pst"`` (`damjax.PSTParams`, `damjax.PSTSetup`, ``[strength]`` CSV);
- `slope`: ``type = "slope"`` (``[terrain]``, ``[strength]`` fields of a release area),
  resolved to fields and run by `slope_fields`.

``damjax.scenario.load("quick")`` reads a shipped scenario, checked once: `prepared` gives
the checked run (`damjax.pst.prepare`, `damjax.slope.simulation.prepare`) that
`damjax.runner` runs.
"""

from damjax.scenario import pst, slope  # noqa: F401  (each registers its scenario type)
from damjax.scenario.schema import (
    MAX_PARTICLES,
    PROFILE_KEYS,
    SCENARIO_TYPES,
    SECTIONS,
    STRENGTH_KEYS,
    TOP_KEYS,
    Output,
    Scenario,
    ScenarioWarning,
    describe_shipped,
    dubious,
    dumps,
    library_dir,
    load,
    loads,
    override,
    parse,
    prepared,
    problems,
    register,
    resolve,
    shipped,
)

__all__ = [
    "MAX_PARTICLES",
    "SCENARIO_TYPES",
    "SECTIONS",
    "PROFILE_KEYS",
    "STRENGTH_KEYS",
    "TOP_KEYS",
    "Output",
    "Scenario",
    "ScenarioWarning",
    "describe_shipped",
    "dubious",
    "dumps",
    "library_dir",
    "load",
    "loads",
    "override",
    "parse",
    "prepared",
    "problems",
    "register",
    "resolve",
    "shipped",
]
