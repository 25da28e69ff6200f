"""Every public name has a docstring (the docs build checks the same, docs/hooks.py)."""

import importlib.util
from pathlib import Path


def test_public_names_have_docstrings() -> None:
    path = Path(__file__).resolve().parent.parent / "docs" / "hooks.py"
    spec = importlib.util.spec_from_file_location("damjax_docs_hooks", path)
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    assert hooks.missing_docstrings() == []
