"""Package metadata: the licences, and the dependency floors that the minimum-versions
check (`python -m benchmarks`-free: ``.ci/min_versions``) runs against."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def test_licences_are_stated_and_shipped():
    project = PYPROJECT["project"]
    assert project["license"] == "MIT AND EUPL-1.2"
    files = project["license-files"]
    assert files == ["LICENSE", "damjax/data/paths/LICENSE-EUPL-1.2.txt"]
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")
    eupl = (ROOT / files[1]).read_text(encoding="utf-8")
    assert "EUROPEAN UNION PUBLIC LICENCE v. 1.2" in eupl
    # the EUPL data are package data, and the README's table names every licensed folder
    data = PYPROJECT["tool"]["setuptools"]["package-data"]["damjax"]
    assert "data/paths/*.txt" in data and "data/paths/*/*" in data
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for name in (
        "damjax/data/paths/",
        "tests/data/profiles/snowpilot-21449.caaml.xml",
        "tests/data/profiles/sarp-example.pro",
        "MIT AND EUPL-1.2",
    ):
        assert name in readme, name
    # no licence classifier beside the expression (PEP 639 forbids both)
    assert not any(c.startswith("License ::") for c in project.get("classifiers", []))
