"""``python -m benchmarks sweep256 slope_large --dry-run``: the throughput cases run at toy
size on any device and print their JSON rows, so that the commands cannot rot."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
META = ("case", "device", "platform", "date", "commit", "dry_run", "particle_steps_per_s")


def test_throughput_dry_runs_print_their_rows():
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
    }
    cmd = [sys.executable, "-m", "benchmarks", "sweep256", "slope_large", "--dry-run"]
    out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    rows = {}
    for line in out.stdout.splitlines():
        if line.strip():
            row = json.loads(line)
            rows[row["case"]] = row
    assert list(rows) == [
        "sweep256_sequential",
        "sweep256_batch",
        "slope_large_single",
        "slope_large_ensemble",
    ]
    for row in rows.values():
        assert not [k for k in META if k not in row], row
        assert row["dry_run"] is True and row["particle_steps_per_s"] > 0
    batch = rows["sweep256_batch"]
    assert batch["members"] == 8 and batch["slice_size_chosen_by"] == "memory"
    assert 1 <= batch["slice_size"] <= 8 and batch["ratio_over_sequential"] > 0
    assert batch["slices_per_device"] * batch["slice_size"] >= 8
    for name in ("slope_large_single", "slope_large_ensemble"):
        row = rows[name]
        assert row["extrapolated"] is True and row["window"]["steps"] == 20
        assert row["wall_time_s"] > row["window_time_s"] > 0
    ens = rows["slope_large_ensemble"]
    assert ens["members"] == 32 and ens["slices"] * ens["slice_size"] >= 32
