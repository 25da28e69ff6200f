"""damjax: differentiable depth-averaged MPM for snow slab avalanche release.

Public API (one screen; the package's layers are mapped in CONTRIBUTING.md):

- `PSTParams`: slab and weak-layer parameters, differentiable leaves (declared with their
  units and ranges in `damjax.params`);
- `PSTSetup`, `simulate_pst` -> `PSTResult`: a propagation saw test;
- `SlopeSetup`, `simulate_slope` -> `SlopeResult`: a slope-scale release on terrain;
- `sweep`: a batch of PSTs as one vmapped (sharded) computation (`last_sweep_plan`: how
  the last one was sliced);
- `gradient_check`: AD of the crack length against the event-based arrest over a window;
- `arrest_position_smooth`: differentiable surrogate of the arrest position (JAX), with
  `make_layout` (the static grid and step count) for use under `jax.grad`/`jit`/`vmap`;
- `calibrate`: scaling-law fits, inversion through the solver, slope calibration (optax);
- `scenario`, `runner`: TOML scenario files, runs with NetCDF output and restart;
- `theory`: closed forms of the paper (tau_g, k_f, k_x, Lambda, ...);
- `diagnostics`: crack tip, speed, arrest, tension gradient; `plot`: figures.
"""

from damjax import calibrate, diagnostics, plot, runner, scenario, theory
from damjax._version import __version__
from damjax.params import PSTParams, PSTSetup, SlopeSetup
from damjax.pst import PSTResult, arrest_position_smooth, make_layout, simulate_pst
from damjax.sensitivity import gradient_check
from damjax.slope import SlopeResult, simulate_slope
from damjax.sweep import last_sweep_plan, sweep

__all__ = [
    "PSTParams",
    "PSTResult",
    "PSTSetup",
    "SlopeResult",
    "SlopeSetup",
    "__version__",
    "arrest_position_smooth",
    "calibrate",
    "diagnostics",
    "gradient_check",
    "make_layout",
    "plot",
    "runner",
    "scenario",
    "simulate_pst",
    "simulate_slope",
    "sweep",
    "last_sweep_plan",
    "theory",
]

# submodules that `import damjax` does not load (optional dependencies, or seldom used),
# reached as attributes on first use: `damjax.distributed.sweep(...)` after `import damjax`
_LAZY = frozenset(
    {
        "distributed",
        "ensemble",
        "export",
        "fields",
        "io",
        "release_area",
        "sensitivity",
        "snow_cover",
        "snow_profiles",
        "terrain",
        "validation",
    }
)


def __getattr__(name: str) -> object:
    if name in _LAZY:
        import importlib

        return importlib.import_module(f"damjax.{name}")
    raise AttributeError(f"module 'damjax' has no attribute {name!r}")
