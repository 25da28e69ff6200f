"""Deprecated since 2026-11-24: `damjax.pst` (and `damjax.core.model` for the layout)."""

from damjax._deprecated import forward

__getattr__ = forward("damjax.scenarios.pst", ["damjax.pst", "damjax.core.model"])
