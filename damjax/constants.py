"""Physical constants and the named choices of the setups (a leaf: imports nothing).

- `G_ACC`: gravitational acceleration [m/s^2];
- `LATERAL_CONDITIONS`, `DTYPES`, `P0_RULES`, `MCC_INVARIANTS`, `SLAB_FRACTURE_MODELS`,
  `ACCUMULATIONS`: the valid values of the string fields of `damjax.PSTSetup` /
  `damjax.SlopeSetup` (declared with them in `damjax.params`).
"""

from __future__ import annotations

G_ACC = 9.81  # gravitational acceleration [m/s^2]

LATERAL_CONDITIONS = ("free", "constrained")
DTYPES = ("float32", "float64")
P0_RULES = ("paper", "uniaxial")
MCC_INVARIANTS = ("3d", "plane")
SLAB_FRACTURE_MODELS = ("crack_band", "paper")  # see damjax.materials.slab_fracture
ACCUMULATIONS = ("auto", "fixed", "float")  # P2G sums, see damjax.core.transfer
