"""Release-probability ensembles: one slope scenario, many random weak layers.

An ensemble runs a slope scenario (`damjax.scenario.slope`) for N members that differ in
the seed of the weak layer's Gaussian random field and, optionally, in parameters drawn
from stated distributions. Its products: the probability that each cell of the release
area releases (the member mean of the 0/1 ``released`` map) and the distributions of the
release area and of the up-slope arrest distance (5 %, 50 %, 95 % quantiles)::

    ens = damjax.ensemble.load("slope-generic-50x60", members=32)
    ds = damjax.ensemble.run(ens, "out/fig12a-ensemble")
    ds["release_probability"].plot()              # then plt.savefig(...) in a script

or ``damjax ensemble slope-generic-50x60 --members 32 --out out/fig12a-ensemble``.

Scenario files take an optional ``[ensemble]`` table (SI units, as the rest)::

    [ensemble]
    members = 32                 # default member count (--members overrides)
    seeds = [0, 1, 2]            # optional: the GRF seed of member i is seeds[i];
                                 # default strength.seed + i
    param_seed = 0               # seed of the parameter draws (member i draws from its
                                 # own stream: a member never changes with N)
    slice_size = 8               # optional: members per vmapped slice (default: chosen
                                 # from the measured memory of the compiled step)

    [ensemble.params.tensile_strength]   # any scalar [params] field
    dist = "lognormal"           # "normal" | "lognormal": mean, std of the value itself;
    mean = 4000.0                #   bounds = [low, high] truncates (optional)
    std = 800.0                  # "uniform": low, high
    bounds = [2000.0, 8000.0]

    [ensemble.strength.trend]    # numbers of the [strength] table (grf: mean, mean_at,
    dist = "uniform"             #   trend, std, length_scale, angle_deg, trend_deg;
    low = 15.0                   #   constant: tau_peak, trend)
    high = 25.0

With the "crack_band" slab (``slab_fracture`` in [setup]) each member also draws its own
tensile-strength field: member i uses ``setup.seed + i``.

How it runs. Members run as vmapped batches of the shared 2D step (`damjax.core.loop.
run_chunk`, the step `simulate_slope` integrates), in slices of ``slice_size`` members,
each slice sharded over the process's devices (one member group per device,
`jax.shard_map`). All members share one layout: the grid padding and the time step of the
member that needs the most (members that differ only in their seed have the layout of a
single run and equal `damjax.scenario.slope_fields.simulate` of their member scenario,
`member_scenario`). A member whose run faults keeps the state of the chunk that faulted,
as a single run stops there.

The slice size is chosen from memory: the step compiled for a trial slice reports its
peak (arguments, outputs and temporaries, XLA's `memory_analysis`), and the slice is the
largest that fits ``memory_fraction`` of the free memory (host memory on CPU, the device's
limit on GPU), at most 8 members per device (a kill loses at most one slice per process).
On CPU devices a slice holds one member per device: vmapping slope members on a CPU device
ran slower per member than running them one at a time, so a CPU host is split into one
device per core instead (``damjax ensemble --cpu-devices``, by default the cores this
process may use) and the devices run their members side by side.

Files in the output folder (each written atomically, `damjax.io.atomic_path`):

- ``plan.json``: the ensemble's key (scenario and [ensemble] table), slice size and
  layout, written once; a rerun into the folder must match it;
- ``slices/members_AAAAA-BBBBB.nc``: members A..B-1, written when their slice finishes;
- ``ensemble.nc``: every member (``member`` dimension: per-member summaries, drawn
  parameters, seeds, maps ``released``, ``arrival_time``, ``height``, ``tau_peak``) and the
  products (``release_probability``, ``release_area_m2_quantiles``,
  ``upslope_extent_m_quantiles``, ``upslope_arrest_distance_m_quantiles`` over the
  members whose up-slope front arrested); no wall-clock numbers, so a killed and resumed
  ensemble gives the same file as an uninterrupted one, bit for bit (the members' strength
  fields are drawn on the host, `damjax.fields.grf`, so they do not depend on what else
  the devices run);
- ``ensemble.png`` (`plot_ensemble`), ``ensemble_summary.json`` (quantiles, timings);
- ``.damjax-ensemble.lock`` while a run writes into the folder: it names the run's pid and
  host, and a second run into the folder stops with an error naming them (the lock is the
  kernel's, so a killed run leaves none behind that counts).

Resume: run the same command again. Finished slices are read, not run; a larger
``--members`` adds members to a finished ensemble. Several processes
(`damjax.distributed`) share the slices round robin (slice k on process k mod P) and meet
in the output folder, which must be on a file system they all see.

Modules: `spec` (the ``[ensemble]`` table, distributions, member scenarios), `batch`
(layout, slice size, the vmapped slices, resume), `products` (slice files, ``ensemble.nc``,
quantiles), `plot` (the figure), `cli` (``damjax ensemble``).
"""

from __future__ import annotations

from damjax.ensemble.batch import (
    MAX_PER_DEVICE,
    MEMORY_FRACTION,
    PLAN_FILE,
    Plan,
    run,
    shared_layout,
)
from damjax.ensemble.cli import add_arguments, command, main
from damjax.ensemble.plot import plot_ensemble
from damjax.ensemble.products import (
    ENSEMBLE_FILE,
    FIGURE,
    QUANTILES,
    SLICE_DIR,
    SUMMARY_FILE,
    SUMMARY_KEYS,
    assemble,
    quantile_summary,
)
from damjax.ensemble.spec import (
    DISTRIBUTIONS,
    ENSEMBLE_KEYS,
    STRENGTH_DRAWS,
    Distribution,
    Ensemble,
    check_table,
    from_scenario,
    key_of,
    load,
    member_draws,
    member_scenario,
    member_seed,
)

__all__ = [
    "DISTRIBUTIONS",
    "ENSEMBLE_FILE",
    "ENSEMBLE_KEYS",
    "FIGURE",
    "MAX_PER_DEVICE",
    "MEMORY_FRACTION",
    "PLAN_FILE",
    "QUANTILES",
    "SLICE_DIR",
    "STRENGTH_DRAWS",
    "SUMMARY_FILE",
    "SUMMARY_KEYS",
    "Distribution",
    "Ensemble",
    "Plan",
    "add_arguments",
    "assemble",
    "check_table",
    "command",
    "from_scenario",
    "key_of",
    "load",
    "main",
    "member_draws",
    "member_scenario",
    "member_seed",
    "plot_ensemble",
    "quantile_summary",
    "run",
    "shared_layout",
]
