"""``python -m benchmarks gpu --dry-run``: every part of the prepared GPU command runs at
toy size on any device and prints valid JSON lines, so that the command cannot rot on
machines without a GPU."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
META = ("part", "case", "device", "platform", "jax", "jaxlib", "date", "commit", "dry_run")


def test_gpu_dry_run_prints_one_valid_line_per_part():
    from benchmarks import gpu

    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
    }
    # a generous limit: the parts share two busy cores with the rest of the suite
    cmd = [sys.executable, "-m", "benchmarks", "gpu", "--dry-run", "--timeout", "900"]
    out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=1200)
    rows = [json.loads(line) for line in out.stdout.splitlines() if line.strip()]
    assert rows, out.stderr[-3000:]
    for row in rows:
        missing = [k for k in META if k not in row]
        assert not missing, (missing, row)
        assert row["dry_run"] is True
        assert "error" not in row, row
    by_part: dict[str, list[dict]] = {}
    for row in rows:
        by_part.setdefault(row["part"], []).append(row)
    assert list(by_part) == list(gpu.PARTS)  # every part, in order
    assert out.returncode == 0, out.stderr[-3000:]
    (env_row,) = by_part["environment"]
    assert env_row["n_devices"] >= 1 and env_row["device"] == env_row["devices"][0]
    # the figures: what each part is for
    (pst,) = by_part["pst_f32"]
    assert pst["n_steps"] > 0 and pst["us_per_step"] > 0
    (rep,) = by_part["repeat"]
    assert rep["bitwise_equal"] is (max(rep["max_abs_diff"].values()) == 0.0)
    (grad,) = by_part["pst_grad"]
    assert grad["grad_over_forward"] > 0
    checks = by_part["gradient_check"]
    assert {(c["field"], c["softening"]) for c in checks} == {
        (f, d) for f in gpu.GRADIENT_FIELDS for d in (0.0, 0.3)
    }
    assert all(isinstance(c["all_finite"], bool) for c in checks)
    acc = by_part["accumulation"]
    if "skipped" not in acc[0]:
        assert {r["case"] for r in acc} == {"accumulation_pst_f32", "accumulation_slope"}
        assert all(r["fixed_over_float"] > 0 for r in acc)
    assert {r["case"] for r in by_part["ensemble16"]} == {
        "ensemble16_sequential",
        "ensemble16_ensemble",
    }
    assert by_part["slope"][0]["ns_per_particle_step"] > 0
    assert by_part["slope_1m"][0]["ns_per_particle_step"] > 0
    # the throughput figures: the older code alternated with this checkout, the sweep, the
    # large slope (a window, extrapolated) and mpm88
    old_rows = by_part["pst_f32_old"]
    assert sorted(r["side"] for r in old_rows[:-1]) == ["new", "old"]
    assert old_rows[-1]["case"] == "pst_f32_old_new" and old_rows[-1]["new_over_old"] > 0
    assert [r["case"] for r in by_part["sweep256"]] == ["sweep256_sequential", "sweep256_batch"]
    single, ens = by_part["slope_large"]
    assert single["extrapolated"] is True and ens["slices_timed"] == 1
    assert ens["wall_time_s"] > 0 and ens["slices"] * ens["slice_size"] >= ens["members"]
    (path,) = by_part["real_path"]
    assert path["n_steps"] > 0 and path["particle_steps_per_s"] > 0 and path["fault"] == 0
    (m88,) = by_part["mpm88"]
    assert m88["particle_steps_per_s"] > 0 and m88["particles_per_cell"] > 0
    (tests,) = by_part["tests"]
    assert tests["returncode"] == 0 and tests["passed"] == len(gpu.DRY_TESTS)
    assert tests["failed"] == 0


def test_a_failing_part_is_a_line_and_the_rest_still_run(monkeypatch):
    from benchmarks import gpu

    printed: list[dict] = []
    monkeypatch.setattr(gpu, "_run_child", lambda name, dry, timeout: ([], {}, "boom"))
    rows = gpu.run(["pst_f32", "slope"], dry=True, timeout=60, workers=0, print_row=printed.append)
    assert [r["part"] for r in rows] == ["pst_f32", "slope"]
    assert all(r["error"] == "boom" for r in rows) and printed == rows
    # a spent time budget: the part is reported as not run
    rows = gpu.run(["pst_f32"], dry=True, timeout=0, workers=0, print_row=printed.append)
    assert rows[0]["error"].startswith("not run")


def test_tests_part_names_each_failure_and_keeps_the_log(monkeypatch, tmp_path):
    # a run cut at its limit names what failed so far ("-v" lines); a finished one adds
    # each failure's message from the summary; the whole output lands in the log
    from benchmarks import gpu

    cut = (
        "[gw7] [ 69%] FAILED tests/test_ensemble.py::test_two \n"
        "[gw6] [ 92%] PASSED tests/test_mcc.py::test_a \n"
    )
    monkeypatch.setattr(gpu, "_run_group", lambda cmd, env, timeout: (cut, "", None))
    row = gpu._run_tests(False, 4, 10.0, tmp_path)
    assert row["failed_tests"] == ["tests/test_ensemble.py::test_two"]
    assert row["error"].startswith("timed out") and (tmp_path / "pytest.log").read_text() == cut
    done = cut + (
        "FAILED tests/test_ensemble.py::test_two - RuntimeError: boom\n"
        "=== 1 failed, 1 passed in 3.0s ===\n"
    )
    monkeypatch.setattr(gpu, "_run_group", lambda cmd, env, timeout: (done, "", 1))
    row = gpu._run_tests(False, 4, 10.0)
    assert row["failed_tests"] == ["tests/test_ensemble.py::test_two"]
    assert row["failure_messages"] == [
        "FAILED tests/test_ensemble.py::test_two - RuntimeError: boom"
    ]
    assert (row["failed"], row["passed"]) == (1, 1)
    assert "-x" not in row["command"].split()
