"""The helpers used after a run (diagnostics, plots, result files) on wrong input: one
line naming the argument and its valid range, never a NaN, a zero that looks like a
result, or an error from inside numpy, matplotlib or PIL; and result files that read
back as the result they were written from."""

from __future__ import annotations

import json

import numpy as np
import pytest

import damjax
from damjax import diagnostics as dg
from damjax import plot, runner
from damjax.slope import results as slope_results


@pytest.fixture(scope="module")
def pst():
    p = damjax.PSTParams(steady_length=5.0, strength_gradient=800.0, softening=1.0)
    return damjax.simulate_pst(p, damjax.PSTSetup(length=20.0, dx=0.05, duration=1.0))


@pytest.fixture(scope="module")
def slope():
    setup = damjax.SlopeSetup(length=8.0, width=4.0, dx=0.25, duration=0.3, start=(2.0, 2.0))
    with pytest.warns(UserWarning):  # the release reaches the small area's edges
        return damjax.simulate_slope(damjax.PSTParams(), setup, slope_deg=38.0, tau_peak=1000.0)


def test_diagnostics_name_bad_arguments(pst):
    t, tip = pst.time, pst.tip
    assert dg.crack_speed(list(t), list(tip)).max() == dg.crack_speed(t, tip).max() > 0
    for call, needle in (
        (lambda: dg.crack_speed(t, tip[:-10]), "time has 6000 values and tip 5990"),
        (lambda: dg.crack_speed(t, tip, window=-1.0), "window = -1.0; must be a finite"),
        (lambda: dg.crack_speed(t, tip, window=float("nan")), "window = nan"),
        (lambda: dg.crack_speed(t[::-1], tip), "time must increase"),
        (lambda: dg.crack_speed(t, np.stack([tip, tip])), "tip has shape (2, 6000)"),
        (lambda: dg.arrest(t, tip, -20.0, 0.05), "length = -20.0"),
        (lambda: dg.arrest(t, tip, 20.0, float("nan")), "dx = nan"),
        (lambda: dg.arrest(t, np.full_like(tip, np.nan), 20.0, 0.05), "tip holds NaN"),
        (lambda: dg.tension_gradient(pst.x, pst.sigma_xx, -1.0), "cut = -1.0"),
        (lambda: dg.tension_gradient(pst.x, pst.sigma_xx[:-3], 5.0), "sigma_xx 797"),
    ):
        with pytest.raises(ValueError) as exc:
            call()
        assert needle in str(exc.value)
    with pytest.raises(TypeError, match="crack_speed: time must be a 1-D array .*PSTResult"):
        dg.crack_speed(pst, tip)


def test_plots_refuse_the_wrong_result_and_path_before_drawing(pst, slope, tmp_path):
    with pytest.raises(TypeError, match="plot_pst takes a damjax.PSTResult, got SlopeResult"):
        plot.plot_pst(slope)
    with pytest.raises(TypeError, match="plot_slope takes a damjax.SlopeResult, got PSTResult"):
        plot.plot_slope(pst)
    with pytest.raises(TypeError, match="got Dataset .*damjax.runner.load_result"):
        plot.plot_pst(pst.to_dataset())
    with pytest.raises(ValueError, match="plot_pst: path .*unsupported figure format 'xyz'"):
        plot.plot_pst(pst, tmp_path / "x.xyz")
    with pytest.raises(TypeError, match="plot_pst: path must be a file name"):
        plot.plot_pst(pst, 123)
    with pytest.raises(ValueError, match="animate_slope: path .*must end in .gif"):
        plot.animate_slope(slope, tmp_path / "a.png")
    with pytest.raises(ValueError, match="not a slope run's summary"):
        plot.slope_outcome(pst.summary)
    plot.plot_pst(pst, tmp_path / "new" / "folder" / "pst.png")  # its folder is made
    assert (tmp_path / "new" / "folder" / "pst.png").stat().st_size > 0


def test_result_files_read_back(pst, slope, tmp_path):
    pst.to_netcdf(tmp_path / "pst.nc")
    scn, back = runner.load_result(tmp_path / "pst.nc")  # the file itself, not a folder
    assert scn.type == "pst" and np.array_equal(back.tip, pst.tip)
    slope.to_netcdf(tmp_path / "slope.nc")
    ds = damjax.io.open_dataset(tmp_path / "slope.nc")
    params = json.loads(ds.attrs["params"])
    # the slope and strength that ran, not the parameters' defaults (35 deg, 1 kPa + ...)
    assert params["slope_deg"] == 38.0 and params["tau_peak"] == 1000.0
    assert "wall_time_s" not in json.loads(ds.attrs["summary"])
    back = slope_results.load_result(tmp_path / "slope.nc")
    assert back.params.slope_deg == 38.0 and back.setup.start == slope.setup.start
    assert np.array_equal(back.height, slope.height)
    assert np.array_equal(back.arrival_time, slope.arrival_time)


def test_a_slope_run_says_which_pst_parameters_it_does_not_use():
    setup = damjax.SlopeSetup(length=6.0, width=4.0, dx=0.2, duration=0.05, start=(1.0, 2.0))
    p = damjax.PSTParams(slope_profile=[10.0, 80.0], strength_gradient=100.0)
    prep = damjax.slope.simulation.prepare(p, setup)
    lines = [n.text() for n in prep.notes if n.category == "pst_only"]
    assert lines == [
        "simulate_slope: strength_gradient, slope_profile not used: a PST's; a slope run's "
        "strength is tau_peak (a scalar or an (nx, ny) map) and its slope slope_deg"
    ]
    assert not [
        n
        for n in damjax.slope.simulation.prepare(damjax.PSTParams(), setup).notes
        if n.category == "pst_only"
    ]
