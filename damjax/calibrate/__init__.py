"""Calibration: parameters from observations, by fits and by gradients through the solver.

- `scaling`: power laws fitted to sweeps (paper Eqs. 9-10: `fit_power_law`,
  `fit_elastic_scaling`, `fit_plastic_scaling`);
- `inversion`: PST parameters from observed arrest positions through the solver
  (`invert`);
- `slope`: slab parameters from an observed release zone through the 2D solver
  (`calibrate_slope`, with its `slope_problem`, `damage_map`, ...).
"""

from damjax.calibrate import slope
from damjax.calibrate.inversion import Inversion, invert
from damjax.calibrate.scaling import (
    PowerLawFit,
    fit_elastic_scaling,
    fit_plastic_scaling,
    fit_power_law,
)
from damjax.calibrate.slope import calibrate_slope

__all__ = [
    "Inversion",
    "PowerLawFit",
    "calibrate_slope",
    "fit_elastic_scaling",
    "fit_plastic_scaling",
    "fit_power_law",
    "invert",
    "slope",
]
