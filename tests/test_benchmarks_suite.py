"""benchmarks/ is a suite of timing cases: ``python -m benchmarks`` alone lists them and
runs nothing; every verification script names the page it feeds; every results file is
cited where its figures are quoted."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _env() -> dict:
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": path}


def test_benchmarks_without_a_case_lists_one_line_each_and_runs_nothing():
    from benchmarks import __main__ as cli
    from benchmarks.cases import CASES

    out = subprocess.run(
        [sys.executable, "-m", "benchmarks"],
        cwd=ROOT,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    listed = [ln.split()[0] for ln in out.stdout.splitlines() if ln.startswith("  ")]
    assert listed == [*CASES, *cli.COMMANDS]
    assert not out.stderr  # no case ran (each reports its time on stderr)
    assert cli.main(["--list"]) == 0 and cli.main(["nope"]) == 2


def test_every_verification_script_names_an_existing_page():
    from verification.__main__ import PAGES

    scripts = {p.stem for p in (ROOT / "verification").glob("*.py") if not p.stem.startswith("_")}
    assert scripts == set(PAGES)
    for page in PAGES.values():
        first = page.split(",")[0].split(" ")[0].replace("*.png", "")
        assert (ROOT / first).exists(), page


def test_every_results_file_is_cited():
    texts = [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]
    texts += [*(ROOT / "benchmarks").glob("*.py"), *(ROOT / "verification").glob("*.py")]
    cited = "\n".join(p.read_text() for p in texts)
    marked = set(re.findall(r'result\("([^"]+)"', cited))
    for f in sorted((ROOT / "results").rglob("*.jsonl")):
        rel = f.relative_to(ROOT / "results").with_suffix("").as_posix()
        assert (
            f"results/{rel}.jsonl" in cited
            or rel in marked
            or (f.parent.name == "slab_fracture" and f.stem in cited)
        ), f"{f.relative_to(ROOT)} is cited nowhere: delete it or cite it where its figures are"
