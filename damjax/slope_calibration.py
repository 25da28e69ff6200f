"""Deprecated since 2026-11-24: `damjax.calibrate.slope`."""

from damjax._deprecated import forward

__getattr__ = forward("damjax.slope_calibration", ["damjax.calibrate.slope"])
