"""damjax: differentiable depth-averaged MPM for snow slab avalanche release.

Public API (one screen):

- `PSTParams`, `PSTSetup`: physical parameters (differentiable) and numerics (static);
- `simulate_pst`: run a propagation saw test, returns a `PSTResult`;
- `theory`: closed forms of the paper (tau_g, k_f, k_x, Lambda, ...);
- `diagnostics`: crack tip, speed, arrest, tension gradient.
"""

from damjax import diagnostics, plot, theory
from damjax.config import PSTParams, PSTSetup
from damjax.scenarios.pst import PSTResult, simulate_pst

__version__ = "0.1.0"

__all__ = [
    "PSTParams",
    "PSTResult",
    "PSTSetup",
    "__version__",
    "diagnostics",
    "plot",
    "simulate_pst",
    "theory",
]
