"""Slope-scale release on terrain: the shared 2D DA-MPM step over a release area.

- `simulation`: `simulate_slope` (setup: `damjax.SlopeSetup`) and its `SlopeResult`;
- `generic`: the paper's generic slopes of Fig. 13 (`GenericSlopeCase`, `FIG12A`,
  `FIG12B`, `run_generic_slope`);
- `results`: the crack-speed map and the NetCDF dataset of a slope run, read back.
"""

from damjax.params import SlopeSetup
from damjax.slope.simulation import SlopeResult, simulate_slope

__all__ = ["SlopeResult", "SlopeSetup", "simulate_slope"]
