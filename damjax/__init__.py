"""damjax: differentiable depth-averaged MPM for snow slab avalanche release.

Public API (one screen):

- `PSTParams`, `PSTSetup`: physical parameters (differentiable) and numerics (static);
- `simulate_pst`: run a propagation saw test, returns a `PSTResult`;
- `sweep`: a batch of PSTs as one vmapped (sharded) computation;
- `arrest_position_smooth`: differentiable surrogate of the arrest position (JAX), with
  `make_layout` (the static grid and step count) for use under `jax.grad`/`jit`/`vmap`;
- `calibrate`: scaling-law fits and parameter inversion through the solver (optax);
- `scenario`, `runner`: TOML scenario files, runs with NetCDF output and restart;
- `theory`: closed forms of the paper (tau_g, k_f, k_x, Lambda, ...);
- `diagnostics`: crack tip, speed, arrest, tension gradient.
"""

from damjax import calibrate, diagnostics, plot, runner, scenario, theory
from damjax.config import PSTParams, PSTSetup
from damjax.scenarios.pst import PSTResult, arrest_position_smooth, make_layout, simulate_pst
from damjax.sweep import sweep

__version__ = "0.1.0"

__all__ = [
    "PSTParams",
    "PSTResult",
    "PSTSetup",
    "__version__",
    "arrest_position_smooth",
    "calibrate",
    "diagnostics",
    "make_layout",
    "plot",
    "runner",
    "scenario",
    "simulate_pst",
    "sweep",
    "theory",
]
