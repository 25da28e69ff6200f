"""The paper's Fig. 13a slope as a release-probability ensemble: the shipped
``slope-generic-50x60`` scenario (50 m x 60 m, dx 0.2 m, 4 s, GRF std 100 Pa, 8 m) for 32
GRF seeds, as ``damjax ensemble slope-generic-50x60 --members 32`` runs it, and a set of
its members run again one by one with `damjax.scenario.slope_fields.simulate`.

    python -m verification.fig12a_ensemble [--members 32] [--check 0 7 15 31] [--out DIR]

Prints one JSON line per part: ``fig12a_ensemble`` (quantiles of the release area and of
the up-slope arrest distance, the mean release probability, timings, peak RSS) and
``fig12a_member_check`` (for each checked member: its release area, arrest distance and the
largest difference of its ``released`` map from the one-by-one run). The folder keeps
``ensemble.nc`` and ``ensemble.png`` (the probability map over the terrain).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
import warnings

SCENARIO = "slope-generic-50x60"


def _peak_rss_mb() -> float:
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m verification.fig12a_ensemble")
    p.add_argument("--members", type=int, default=32)
    p.add_argument("--check", type=int, nargs="*", default=[0, 7, 15, 31])
    p.add_argument("--out", default="out/fig12a-ensemble")
    ns = p.parse_args(argv)
    if ns.members < 1 or any(not 0 <= i < ns.members for i in ns.check):
        p.error("--members must be >= 1 and every --check index in [0, members)")

    import jax

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    jax.config.update("jax_num_cpu_devices", cores)  # as `damjax ensemble` does on CPU
    import numpy as np

    from damjax import ensemble
    from damjax.scenario import slope_fields

    ens = ensemble.load(SCENARIO, members=ns.members)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = ensemble.run(ens, ns.out, progress=False)
    s = json.loads(ds.attrs["run_summary"])
    prob = ds["release_probability"].values
    row = dict(
        case="fig12a_ensemble",
        scenario=SCENARIO,
        members=ns.members,
        devices=len(jax.local_devices()),
        slice_size=s["slice_size"],
        n_steps=s["n_steps"],
        release_area_m2_quantiles=s["release_area_m2_quantiles"],
        upslope_arrest_distance_m_quantiles=s["upslope_arrest_distance_m_quantiles"],
        release_probability_max=float(np.nanmax(prob)),
        cells_with_probability_ge_0_5=int(np.sum(prob >= 0.5)),
        compile_time_s=round(s["compile_time_s"], 2),
        run_time_s=round(s["run_time_s"], 2),
        end_to_end_s=round(time.perf_counter() - t0, 2),
        peak_rss_mb=_peak_rss_mb(),
        out_dir=ns.out,
    )
    print(json.dumps(row), flush=True)

    checks = []
    for i in ns.check:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = slope_fields.simulate(ensemble.member_scenario(ens, i))
        one = res.summary
        m = ds.isel(member=i)
        released_one = np.isfinite(np.asarray(res.arrival_time))
        released_ens = np.asarray(m["released"].values).astype(bool)
        checks.append(
            dict(
                member=i,
                seed=int(m["seed"].values),
                release_area_m2=float(m["release_area_m2"].values),
                release_area_m2_one_by_one=one["release_area_m2"],
                upslope_arrest_distance_m=float(m["upslope_arrest_distance_m"].values),
                upslope_arrest_distance_m_one_by_one=one["upslope_arrest_distance_m"],
                released_cells_differing=int(np.sum(released_one != released_ens)),
            )
        )
    print(json.dumps(dict(case="fig12a_member_check", members=checks)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
