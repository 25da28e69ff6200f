"""The examples of the docs marked to run, run as written and print what the pages say.

A page marks an example with an HTML comment right before its ``bash`` or ``python`` block
(invisible in the site):

    <!-- ci-example -->            the commands exit 0
    <!-- ci-example: status=2 -->  the block's last command exits 2 (a python block: the
                                   script exits 2)

A ``text`` block right after it is the expected output. Each of its lines must be a line
of what the commands printed (stdout and stderr, runs of spaces counted as one); ``...``
lines are skipped. A block that starts with ``{`` is a JSON fragment: each ``"key": value``
shown must be in the printed JSON object, numbers to the digits shown.

Figures in an expected output may be result markers (``{{ result(...) }}``,
docs/results_hook.py): they are compared as the site shows them.

The commands run in bash (a python block: as a script of the python running the tests) in
a fresh folder holding links to the repository's ``docs`` and ``tests`` (so
``tests/data/...`` resolves as in a clone), with ``damjax`` the damjax under test.
Examples are marked where they run in seconds; the pages give the run time and the output
of the others.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
MARK = re.compile(
    r"<!-- ci-example(?::(?P<opts>[^>]*))? -->\s*\n"
    r"```(?P<lang>bash|console|python)\n(?P<code>.*?)```[ \t]*\n"
    r"(?:[ \t]*\n```text\n(?P<out>.*?)```)?",
    re.S,
)


def _results_hook():
    spec = importlib.util.spec_from_file_location(
        "damjax_results_hook", ROOT / "docs" / "results_hook.py"
    )
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    return hook


def _examples() -> list[tuple[str, str, dict[str, str], str | None]]:
    substitute = _results_hook().substitute  # markers stay on their line
    found = []
    for page in PAGES:
        text = substitute(page.read_text(encoding="utf-8"))
        for m in MARK.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            opts = dict(kv.split("=", 1) for kv in (m["opts"] or "").split())
            opts["lang"] = m["lang"]
            found.append((f"{page.relative_to(ROOT)}:{line}", m["code"], opts, m["out"]))
    return found


EXAMPLES = _examples()


def test_the_pages_mark_examples():
    pages = {where.split(":")[0] for where, *_ in EXAMPLES}
    assert {"docs/quickstart.md", "docs/guide/profiles-gis.md", "docs/guide/slopes.md"} <= pages


def _norm(line: str) -> str:
    return " ".join(line.split())


def _check_json(shown: str, printed: str) -> None:
    objects = [ln for ln in printed.splitlines() if ln.startswith("{")]
    assert objects, f"no JSON object printed:\n{printed[-2000:]}"
    got = json.loads(objects[-1])
    for key, value in re.findall(r'"(\w+)": ("[^"]*"|[^,}\s]+)', shown):
        assert key in got, key
        if value.startswith('"'):
            assert got[key] == value.strip('"'), (key, got[key])
        elif value in ("null", "true", "false"):
            assert got[key] == json.loads(value), (key, got[key])
        else:
            decimals = len(value.split(".")[1]) if "." in value else 0
            assert isinstance(got[key], (int, float)), (key, got[key])
            assert math.isclose(got[key], float(value), abs_tol=0.5 * 10.0**-decimals + 1e-12), (
                key,
                got[key],
                value,
            )


@pytest.mark.parametrize(("where", "code", "opts", "out"), EXAMPLES, ids=[e[0] for e in EXAMPLES])
def test_docs_example_runs_as_written(where, code, opts, out, tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    shim = bin_dir / "damjax"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m damjax "$@"\n')
    shim.chmod(0o755)
    work = tmp_path / "work"
    work.mkdir()
    for name in ("docs", "tests"):
        (work / name).symlink_to(ROOT / name)
    env = {
        **os.environ,
        "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
        "MPLBACKEND": "Agg",
    }
    status = int(opts.get("status", "0"))
    if opts["lang"] == "python":
        (work / "example.py").write_text(code)
        command = [sys.executable, "example.py"]
    else:
        command = ["bash", "-c", ("set -e\n" if status == 0 else "") + code]
    done = subprocess.run(
        command,
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=float(opts.get("timeout", "300")),
    )
    printed = done.stdout + done.stderr
    assert done.returncode == status, f"{where}: exit {done.returncode}\n{printed[-3000:]}"
    if out is None:
        return
    if out.lstrip().startswith("{"):
        _check_json(out, done.stdout)
        return
    lines = {_norm(ln) for ln in printed.splitlines()}
    for want in out.splitlines():
        if not want.strip() or want.strip() == "...":
            continue
        assert _norm(want) in lines, f"{where}: not printed: {want!r}\n{printed[-3000:]}"


def _documented(page: str) -> set[str]:
    """The keys named in the tables of a page (every `name` in a table row)."""
    rows = [
        ln for ln in (ROOT / page).read_text(encoding="utf-8").splitlines() if ln.startswith("|")
    ]
    return {k for row in rows for k in re.findall(r"`(\w+)`", row.split("|")[1])}


def test_every_summary_key_is_documented(tmp_path):
    """The PST and slope summaries, as `damjax run` writes them, against the key tables of
    the PST and slope guides."""
    import warnings

    from damjax import runner, scenario

    pst = scenario.loads(
        'type = "pst"\nname = "p"\n[params]\nsteady_length = 1.0\n'
        "[setup]\nlength = 4.0\ndx = 0.1\nduration = 0.05\n",
        warn=False,
    )
    slope = scenario.loads(
        'type = "slope"\nname = "s"\n[setup]\nlength = 4.0\nwidth = 2.0\ndx = 0.2\n'
        "duration = 0.05\nstart = [1.0, 1.0]\nparticles_per_cell = 1\n[output]\nplot = false\n",
        warn=False,
    )
    for scn, page in ((pst, "docs/guide/pst.md"), (slope, "docs/guide/slopes.md")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            outcome = runner.run(scn, tmp_path / scn.name, progress=False)
        keys = set(json.loads((tmp_path / scn.name / "summary.json").read_text()))
        assert keys == set(outcome.summary)
        missing = keys - _documented(page)
        assert not missing, f"{page}: summary keys without a row: {sorted(missing)}"
