"""Deprecated since 2026-11-24: `damjax.params` (SnowParams / PSTParams, PSTSetup,
SlopeSetup), `damjax.validation` (validate and its rules) and `damjax.constants` (G_ACC)."""

from damjax._deprecated import forward

__getattr__ = forward("damjax.config", ["damjax.params", "damjax.validation", "damjax.constants"])
