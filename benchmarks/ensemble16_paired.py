"""Paired check of `benchmarks.ensemble16` on a shared machine: M members of the Fig. 12a
slope for DURATION s, sequential `simulate` runs (one device) and one ensemble (the CPU
split into D devices) alternated ROUNDS times, each in a fresh process, compilation outside
the timed part; one JSON line per run with its wall time, its CPU time (user + system) and
the 1-minute load average before it.

    python -m benchmarks.ensemble16_paired 2 0.3 2 2 > paired.jsonl   # M DURATION ROUNDS D
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

CHILD = r"""
import json, resource, sys, tempfile, time, warnings
mode, M, DUR, D = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
import jax
if mode == "ensemble" and D > 1:
    jax.config.update("jax_num_cpu_devices", D)
from benchmarks.ensemble16 import _ensemble
from damjax import ensemble
from damjax.scenario import slope_fields
warnings.simplefilter("ignore")
ens = _ensemble(M, DUR)
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
if mode == "sequential":
    slope_fields.simulate(ensemble.member_scenario(ens, 0))  # compile
    c0, t0 = cpu(), time.perf_counter()
    for i in range(M):
        slope_fields.simulate(ensemble.member_scenario(ens, i))
    row = {"wall_s": time.perf_counter() - t0, "cpu_s": cpu() - c0}
else:
    ensemble.run(ens, tempfile.mkdtemp(), plot=False)  # compile and plan
    c0, t0 = cpu(), time.perf_counter()
    ds = ensemble.run(ens, tempfile.mkdtemp(), plot=False)
    row = {"wall_s": time.perf_counter() - t0, "cpu_s": cpu() - c0,
           "slice_size": json.loads(ds.attrs["run_summary"])["slice_size"]}
print(json.dumps(row))
"""


def main(argv: list[str]) -> int:
    members, duration, rounds, devices = int(argv[0]), float(argv[1]), int(argv[2]), int(argv[3])
    for r in range(rounds):
        for mode in ("sequential", "ensemble"):
            load = os.getloadavg()[0]
            args = [mode, str(members), str(duration), str(devices)]
            out = subprocess.run(
                [sys.executable, "-c", CHILD, *args], capture_output=True, text=True, check=True
            )
            row = json.loads(out.stdout.strip().splitlines()[-1])
            print(
                json.dumps(
                    {
                        "case": f"ensemble16_paired_{mode}",
                        "round": r,
                        "members": members,
                        "duration_s": duration,
                        "devices": devices if mode == "ensemble" else 1,
                        "load1": round(load, 2),
                        **row,
                    }
                ),
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:] or ["2", "0.3", "2", "2"]))
