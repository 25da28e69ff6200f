"""Slope ensemble throughput: 16 members of the paper's Fig. 13a generic slope (50 m x 60 m,
dx 0.2 m, 1 particle per cell, 2 s; the shipped ``slope-generic-50x60`` with its GRF seeds
0..15) as one `damjax.ensemble` against 16 sequential `simulate_slope` runs of the same
member scenarios, and the same ensemble on two processes (`jax.distributed` on localhost)
against one process.

    python -m benchmarks ensemble16                 # as a benchmark case
    python -m benchmarks.ensemble16 [--members 16] [--duration 2.0] > ensemble16.jsonl

Each part runs in its own process (clean peak-memory figures) and prints one JSON line:

- ``ensemble16_sequential``: 16 `damjax.scenario.slope_fields.simulate` runs; the warm
  wall time (compilation excluded, as in every timing row) and the end-to-end time;
- ``ensemble16_ensemble``: `damjax.ensemble.run` in one process with the CPU split into one
  device per core (as ``damjax ensemble`` does): run time of the slices (compilation
  excluded), end to end, the slice size chosen automatically, XLA's peak estimate per
  device and the budget it was checked against, and ``ratio``: sequential warm wall time
  over the ensemble's run time (the throughput ratio); the largest difference of a
  member's release area and up-slope arrest distance from its sequential run;
- ``ensemble16_two_processes``: the same ensemble by two processes on this machine, each
  with one CPU device (the same devices as the one process); ``ratio``: the one process's
  end-to-end time over the two processes' (>= 1: no slower), and whether both wrote the
  same ``ensemble.nc``.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

SCENARIO = "slope-generic-50x60"


def _ensemble(members: int, duration: float):  # noqa: ANN202 - damjax.ensemble.Ensemble
    from damjax import ensemble, scenario

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scn = scenario.load(SCENARIO).replace(
            setup={"duration": duration}, output={"plot": False, "snapshots": False}
        )
    return ensemble.from_scenario(scn, {"seeds": list(range(members))}, members=members)


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def _peak_rss_mb() -> float:
    import resource

    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1)


def part_sequential(members: int, duration: float, out: Path) -> dict:
    from damjax import ensemble
    from damjax.scenario import slope_fields

    ens = _ensemble(members, duration)
    wall, compile_s, rows = 0.0, 0.0, []
    t0 = time.perf_counter()
    for i in range(members):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = slope_fields.simulate(ensemble.member_scenario(ens, i)).summary
        wall += s["wall_time_s"]
        compile_s += s["compile_time_s"]
        rows.append([s["release_area_m2"], s["upslope_extent_m"]])
    end_to_end = time.perf_counter() - t0
    (out / "sequential.json").write_text(json.dumps(rows))
    return dict(
        case="ensemble16_sequential",
        members=members,
        n_particles=s["n_particles"],
        n_steps=s["n_steps"],
        duration_s=duration,
        compile_time_s=round(compile_s, 2),
        wall_time_s=round(wall, 2),
        end_to_end_s=round(end_to_end, 2),
        particle_steps_per_s=round(members * s["n_particles"] * s["n_steps"] / wall),
        peak_rss_mb=_peak_rss_mb(),
    )


def part_ensemble(members: int, duration: float, out: Path) -> dict:
    """One process, the CPU split into one device per core (as ``damjax ensemble``)."""
    import jax

    jax.config.update("jax_num_cpu_devices", _cores())
    from damjax import ensemble

    ens = _ensemble(members, duration)
    folder = out / "one"
    t0 = time.perf_counter()
    ds = ensemble.run(ens, folder, plot=False)
    end_to_end = time.perf_counter() - t0
    s = json.loads(ds.attrs["run_summary"])
    n_particles = int(ds.sizes["x"] * ds.sizes["y"])
    row = dict(
        case="ensemble16_ensemble",
        members=members,
        devices=len(jax.local_devices()),
        n_particles=n_particles,
        n_steps=s["n_steps"],
        duration_s=duration,
        slice_size=s["slice_size"],
        slice_size_chosen_by=s["slice_size_chosen_by"],
        xla_peak_mb_per_device=round(s["peak_bytes_per_device"] / 2**20, 1)
        if s["peak_bytes_per_device"] is not None
        else None,
        budget_mb_per_device=round(s["budget_bytes_per_device"] / 2**20, 1),
        compile_time_s=round(s["compile_time_s"], 2),
        wall_time_s=round(s["run_time_s"], 2),
        end_to_end_s=round(end_to_end, 2),
        particle_steps_per_s=round(members * n_particles * s["n_steps"] / s["run_time_s"]),
        release_area_m2_quantiles=s["release_area_m2_quantiles"],
        upslope_arrest_distance_m_quantiles=s["upslope_arrest_distance_m_quantiles"],
        peak_rss_mb=_peak_rss_mb(),
    )
    seq = out / "sequential.json"
    if seq.is_file():
        ref = json.loads(seq.read_text())
        area = ds["release_area_m2"].values
        up = ds["upslope_extent_m"].values
        row["max_release_area_diff_vs_sequential_m2"] = float(
            max(abs(a - r[0]) for a, r in zip(area, ref, strict=True))
        )
        row["max_arrest_diff_vs_sequential_m"] = float(
            max(abs(a - r[1]) for a, r in zip(up, ref, strict=True))
        )
    return row


def part_two_processes(members: int, duration: float, out: Path) -> dict:
    """Two processes of `damjax.ensemble.main` with a manual coordinator on localhost."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code = (
        "import sys, warnings; warnings.simplefilter('ignore');"
        "from benchmarks.ensemble16 import _two_main; sys.exit(_two_main())"
    )
    procs = []
    t0 = time.perf_counter()
    for i in range(2):
        env = {
            **os.environ,
            "ENS_PORT": str(port),
            "ENS_PID": str(i),
            "ENS_OUT": str(out / "two"),
            "ENS_MEMBERS": str(members),
            "ENS_DURATION": str(duration),
        }
        procs.append(
            subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE)
        )
    outs = [p.communicate(timeout=3600)[0].decode() for p in procs]
    end_to_end = time.perf_counter() - t0
    if any(p.returncode for p in procs):
        raise RuntimeError(f"two-process run failed: {[p.returncode for p in procs]}")
    s = json.loads(outs[0].strip().splitlines()[-2])
    rss = [json.loads(o.strip().splitlines()[-1])["peak_rss_mb"] for o in outs]
    row = dict(
        case="ensemble16_two_processes",
        members=members,
        duration_s=duration,
        processes=2,
        devices_per_process=s["devices_per_process"],
        slice_size=s["slice_size"],
        compile_time_s=round(s["compile_time_s"], 2),
        wall_time_s=round(s["run_time_s"], 2),
        end_to_end_s=round(s["wall_time_s"], 2),
        end_to_end_with_start_s=round(end_to_end, 2),
        peak_rss_mb=max(rss),
        peak_rss_mb_per_process=rss,
    )
    one = out / "one" / "ensemble_summary.json"
    if one.is_file():
        from damjax import io

        o = json.loads(one.read_text())
        row["peer"] = f"one process, {_cores()} CPU devices"
        row["peer_end_to_end_s"] = round(o["wall_time_s"], 2)
        row["ratio"] = round(o["wall_time_s"] / s["wall_time_s"], 3)
        a = io.open_dataset(out / "one" / "ensemble.nc")
        b = io.open_dataset(out / "two" / "ensemble.nc")
        row["same_ensemble_nc"] = bool(a.identical(b))
    return row


def _two_main() -> int:
    from damjax import distributed, ensemble

    distributed.initialize("127.0.0.1:" + os.environ["ENS_PORT"], 2, int(os.environ["ENS_PID"]))
    ens = _ensemble(int(os.environ["ENS_MEMBERS"]), float(os.environ["ENS_DURATION"]))
    ds = ensemble.run(ens, os.environ["ENS_OUT"], plot=False)
    if distributed.process_index() == 0:
        print(ds.attrs["run_summary"], flush=True)
    print(json.dumps({"peak_rss_mb": _peak_rss_mb()}), flush=True)
    return 0


PARTS = {
    "sequential": part_sequential,
    "ensemble": part_ensemble,
    "two_processes": part_two_processes,
}


def rows(members: int = 16, duration: float = 2.0) -> list[dict]:
    """Every part in its own process, in order (the later parts compare with the earlier
    ones' files); one row per part."""
    out = []
    with tempfile.TemporaryDirectory(prefix="ensemble16-") as tmp:
        for part in PARTS:
            args = ["--part", part, "--members", str(members), "--duration", str(duration)]
            cmd = [sys.executable, "-m", "benchmarks.ensemble16", *args, "--dir", tmp]
            res = subprocess.run(cmd, stdout=subprocess.PIPE, check=True)
            out.append(json.loads(res.stdout.decode().strip().splitlines()[-1]))
            print(json.dumps(out[-1]), file=sys.stderr, flush=True)
    seq, vm = out[0], out[1]
    vm["peer"] = f"{members} sequential simulate_slope"
    vm["peer_wall_time_s"] = seq["wall_time_s"]
    vm["ratio"] = round(seq["wall_time_s"] / vm["wall_time_s"], 3)
    vm["ratio_end_to_end"] = round(seq["end_to_end_s"] / vm["end_to_end_s"], 3)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.ensemble16")
    p.add_argument("--members", type=int, default=16)
    p.add_argument("--duration", type=float, default=2.0)
    p.add_argument("--part", choices=tuple(PARTS), default=None)
    p.add_argument("--dir", default=None, help="working folder shared by the parts")
    ns = p.parse_args(argv)
    if ns.members < 1 or not ns.duration > 0:
        p.error("--members must be >= 1 and --duration > 0")
    if ns.part is None:
        for row in rows(ns.members, ns.duration):
            print(json.dumps(row), flush=True)
        return 0
    folder = Path(ns.dir or tempfile.mkdtemp(prefix="ensemble16-"))
    print(json.dumps(PARTS[ns.part](ns.members, ns.duration, folder)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
