"""The import paths that moved on 2026-11-24 warn and forward to the new modules."""

from __future__ import annotations

import importlib
import sys

import pytest

import damjax
from damjax import calibrate, core, params, pst, scenario, slope, validation
from damjax.core import model
from damjax.slope import results as _slope_results  # noqa: F401  (slope.results below)


def _import_fresh(name: str):
    for mod in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
        del sys.modules[mod]
    with pytest.warns(DeprecationWarning, match=name.replace(".", r"\.") + " is deprecated"):
        return importlib.import_module(name)


@pytest.mark.parametrize(
    "old, name, new",
    [
        ("damjax.config", "PSTParams", params.PSTParams),
        ("damjax.config", "PSTSetup", params.PSTSetup),
        ("damjax.config", "validate", validation.validate),
        ("damjax.config", "G_ACC", damjax.constants.G_ACC),
        ("damjax.config", "_problem", validation._problem),
        ("damjax.scenarios.pst", "simulate_pst", pst.simulate_pst),
        ("damjax.scenarios.pst", "build", model.build),
        ("damjax.scenarios.slope", "simulate_slope", slope.simulate_slope),
        ("damjax.scenarios.slope", "SlopeSetup", params.SlopeSetup),
        ("damjax.scenarios.slope", "make_layout", model.make_slope_layout),
        ("damjax.scenarios.slope", "build", model.build_slope),
        ("damjax.scenarios.slope", "_problems", validation.slope_problems),
        ("damjax.scenarios.generic_slope", "FIG12A", slope.generic.FIG12A),
        ("damjax.slope_scenario", "resolve_fields", scenario.slope_fields.resolve_fields),
        ("damjax.slope_scenario", "check", scenario.slope.check),
        ("damjax.slope_scenario", "crack_speed_map", slope.results.crack_speed_map),
        ("damjax.slope_calibration", "calibrate_slope", calibrate.slope.calibrate_slope),
    ],
)
def test_old_paths_warn_and_forward(old, name, new):
    module = _import_fresh(old)
    assert getattr(module, name) is new


def test_old_paths_name_what_is_missing():
    module = _import_fresh("damjax.config")
    with pytest.raises(AttributeError, match="'damjax.config' has no attribute 'nope'"):
        module.nope  # noqa: B018


def test_the_new_paths_do_not_warn():
    # a fresh interpreter: reloading damjax.params here would make new classes, and every
    # later test's PSTParams would no longer be the one damjax checks arguments against
    import subprocess

    code = (
        "import warnings\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    import damjax.params, damjax.validation, damjax.pst, damjax.slope\n"
        "bad = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)\n"
        "       and 'damjax' in str(w.message)]\n"
        "raise SystemExit('\\n'.join(bad) or None)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert core.model.build is pst.build  # the PST module names its model builder
