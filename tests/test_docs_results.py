"""The figures the docs quote come from the results files they cite (docs/results_hook.py):
every marker of every page resolves, a marker that does not stops the build, and the
figures written out in README.md equal the results their comments cite."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
# pages whose headline figures are markers (each must keep at least one)
QUOTING = ("quickstart.md", "verification/pst.md", "verification/weac.md")


def _hook():
    spec = importlib.util.spec_from_file_location("damjax_results_hook", DOCS / "results_hook.py")
    hook = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hook)
    return hook


def test_every_marker_of_every_page_resolves():
    hook = _hook()
    pages = sorted(DOCS.rglob("*.md"))
    for page in pages:
        text = page.read_text()
        out = hook.substitute(text)  # raises on a marker that does not resolve
        assert "{{" not in out, page
    for name in QUOTING:
        assert hook.MARKER.search((DOCS / name).read_text()), name


def test_a_marker_that_does_not_resolve_stops_the_build(tmp_path, monkeypatch):
    hook = _hook()
    rows = [
        {"case": "a", "field": "f", "x": 1.25, "y": None},
        {"case": "b", "x": -2.0, "y": "text", "z": [1.5, 2.5], "dx0.5": {"n": 3}},
    ]
    (tmp_path / "toy.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    monkeypatch.setattr(hook, "RESULTS", tmp_path)
    assert hook.substitute('{{ result("toy", "x", case="a", digits=1) }} m') == "1.2 m"
    assert hook.substitute('{{ result("toy", "x", case="a", scale=100, sign=True) }}') == "+125.0"
    assert hook.substitute('{{ result("toy", "x", case="b", unit=" m") }}') == "-2.0 m"
    assert hook.substitute('{{ result("toy", "x", case="a", scale=4/10*2, digits=2) }}') == "1.00"
    assert hook.substitute('{{ result("toy", "x", field="f") }}') == "1.25"  # a column "field"
    assert hook.substitute('{{ result("toy", "z.-1", case="b") }}') == "2.5"
    assert hook.substitute('{{ result("toy", "dx0.5.n", case="b") }}') == "3"  # a dotted key
    assert hook.substitute(
        '{{ result("toy", "y", case="a", unit=" m", none="runs through") }}'
    ) == ("runs through")
    assert hook.substitute('{{ result("toy", "y", case="b") }}') == "text"
    for marker, needle in (
        ('{{ result("nope", "x") }}', "no results file results/nope.jsonl"),
        ('{{ result("toy", "z", case="a") }}', "no field 'z'"),
        ('{{ result("toy", "z.2", case="b") }}', "no field 'z.2'"),
        ('{{ result("toy", "dx0.5.m", case="b") }}', "no field 'dx0.5.m'"),
        ('{{ result("toy", "x") }}', "2 rows match"),
        ('{{ result("toy", "x", case="c") }}', "0 rows match"),
        ('{{ result("toy", "y", case="a") }}', "is null"),
        ('{{ figure("toy", "x") }}', "unknown marker 'figure'"),
        ('{{ result("toy") }}', "takes two names"),
        ('{{ result("toy", "x", case=a) }}', "cannot read"),
        ('{{ result("toy", "x", case="a", scale=1-2) }}', "cannot read"),
        ('{{ result("toy", "x", case="a", scale="2") }}', "not a number"),
        ('{{ result("toy", "x",\ncase="a") }}', "does not close on its line"),
    ):
        with pytest.raises(hook.ResultError, match=re.escape(needle)):
            hook.substitute(marker)
    mkdocs = pytest.importorskip("mkdocs.exceptions")

    class Page:  # what the hook reads of mkdocs' page
        class file:
            src_uri = "toy.md"

    with pytest.raises(mkdocs.PluginError, match="toy.md: no results file"):
        hook.on_page_markdown('{{ result("nope", "x") }}', page=Page)


def test_readme_figures_equal_the_results_they_cite():
    hook = _hook()
    text = (ROOT / "README.md").read_text()
    assert hook.readme_mismatches(text) == []
    # every figure of damjax's column in "Verification at a glance" cites its result
    section = text.split("## Verification at a glance", 1)[1].split("\n## ", 1)[0]
    table = [ln for ln in section.splitlines() if ln.startswith("|") and "---" not in ln][1:]
    assert table
    for line in table:
        cell = line.split("|")[2]
        bare = hook.README_MARKER.sub("", cell)
        assert not re.search(r"\d", bare), line
    # a written figure that differs from its result is found
    wrong = hook.README_MARKER.sub(lambda m: "x0.123" + m.group(0)[len(m.group(1)) :], text)
    assert len(hook.readme_mismatches(wrong)) == len(hook.README_MARKER.findall(text))
    # the date, commit and machine quoted beside the table are the results'
    for name in ("date", "commit", "machine"):
        assert f'"{name}"' in section or f"'{name}'" in section, name
