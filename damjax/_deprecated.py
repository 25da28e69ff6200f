"""Forwarding of the module paths that moved on 2026-11-24 (see CHANGELOG.md): each old
module warns once on import (DeprecationWarning) and forwards its names to the new ones."""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from typing import Any


def forward(
    old: str, new: list[str], aliases: dict[str, str] | None = None
) -> Callable[[str], Any]:
    """Warn that module ``old`` is deprecated and return a module ``__getattr__`` that looks
    names up in the modules ``new`` (first hit wins); ``aliases`` maps an old name to a
    ``"module:name"`` that was renamed."""
    warnings.warn(
        f"{old} is deprecated (moved on 2026-11-24): use {' / '.join(new)}",
        DeprecationWarning,
        stacklevel=3,
    )
    aliases = aliases or {}

    def __getattr__(name: str) -> Any:
        if name in aliases:
            module, attr = aliases[name].split(":")
            return getattr(importlib.import_module(module), attr)
        for module in new:
            mod = importlib.import_module(module)
            if hasattr(mod, name):
                return getattr(mod, name)
        raise AttributeError(f"module {old!r} has no attribute {name!r}")

    return __getattr__
