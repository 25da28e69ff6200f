"""Slope calibration: the release-map loss is differentiable through the 2D solver and its
gradient in sigma_t points towards the value that produced the observation."""

import math
import warnings

import jax.numpy as jnp
import numpy as np
import pytest

from damjax import SlopeSetup
from damjax.calibrate import slope as sc
from damjax.slope.generic import fig12_params

L, W, DX = 16.0, 3.0, 0.3


def _problem(fracture_energy: float = math.inf) -> sc.SlopeProblem:
    nx, ny = int(round(L / DX)), int(round(W / DX))
    xc = (np.arange(nx) + 0.5) * DX
    # a PST-like strength: 1 kPa on the first 5 m, then rising 300 Pa/m
    tau = np.repeat((1000.0 + 300.0 * np.maximum(xc - 5.0, 0.0))[:, None], ny, axis=1)
    setup = SlopeSetup(
        length=L,
        width=W,
        dx=DX,
        duration=0.8,
        start=(1.0, W / 2),
        particles_per_cell=1,
        chunk_steps=50,
    )
    params = fig12_params(slab_fracture_energy=fracture_energy)
    return sc.slope_problem(params, setup, slope_deg=35.0, tau_peak=tau)


@pytest.fixture(scope="module")
def problem():
    return _problem()


@pytest.mark.parametrize("fracture_energy", [math.inf, 1.0])
def test_release_loss_gradient_is_finite_and_points_to_the_truth(fracture_energy):
    # perfectly plastic slab (the paper's) and crack-band softening (G_f = 1 J/m^2)
    problem = _problem(fracture_energy)
    grid = sc.observation_grid(problem.setup, 1.0)
    truth = sc.damage_map(problem, 4000.0, 1.0, grid)
    observed = (np.asarray(truth) > 0.5).astype(float)
    # a stronger slab carries the crack further: more released cells
    low = sc.damage_map(problem, 2500.0, 1.0, grid)
    high = sc.damage_map(problem, 6500.0, 1.0, grid)
    assert float(jnp.sum(low)) < float(jnp.sum(truth)) < float(jnp.sum(high))
    vg = sc.loss_and_grad(problem, observed, grid, ("tensile_strength",))
    fixed = jnp.asarray([4000.0, 1.0])
    for sigma_t, sign in ((2500.0, -1.0), (6500.0, 1.0)):
        val, g = vg(jnp.asarray([math.log(sigma_t)]), fixed)
        assert np.isfinite(float(val)) and np.isfinite(float(g[0]))
        assert float(val) > 0.0
        assert sign * float(g[0]) > 0.0, (sigma_t, float(g[0]))


def test_calibrate_slope_returns_its_best_evaluated_iterate(problem):
    """The estimates are the lowest-loss iterate of the history, with that loss."""
    grid = sc.observation_grid(problem.setup, 1.0)
    observed = (np.asarray(sc.damage_map(problem, 4000.0, 1.0, grid)) > 0.5).astype(float)
    fit = sc.calibrate_slope(
        problem, observed, grid, initial={"tensile_strength": 2500.0}, steps=4, learning_rate=0.2
    )
    losses = [h["loss"] for h in fit.history]
    k = int(np.argmin(losses))
    assert fit.best_iteration == k and fit.loss == pytest.approx(losses[k])
    assert fit.estimates["tensile_strength"] == pytest.approx(
        fit.history[k]["tensile_strength"], rel=1e-6
    )
    assert fit.loss <= losses[0] and fit.estimates["softening"] == 1.0
    assert np.isfinite(fit.gradient["tensile_strength"])


@pytest.mark.parametrize("fracture_energy", [math.inf, 1.0])
def test_finite_difference_gradient_points_to_the_truth_and_agrees_with_reverse_mode(
    fracture_energy,
):
    problem = _problem(fracture_energy)
    grid = sc.observation_grid(problem.setup, 1.0)
    observed = (np.asarray(sc.damage_map(problem, 4000.0, 1.0, grid)) > 0.5).astype(float)
    fd = sc.loss_and_fd_grad(problem, observed, grid, ("tensile_strength",), step=0.02)
    ad = sc.loss_and_grad(problem, observed, grid, ("tensile_strength",))
    fixed = jnp.asarray([4000.0, 1.0])
    for sigma_t, sign in ((2500.0, -1.0), (6500.0, 1.0)):
        x = jnp.asarray([math.log(sigma_t)])
        (val, g), (val_ad, g_ad) = fd(x, fixed), ad(x, fixed)
        assert float(val) == pytest.approx(float(val_ad), rel=1e-5)
        assert sign * float(g[0]) > 0.0, (sigma_t, float(g[0]))
        # the same sign as reverse mode where that is verified (this smooth case)
        assert float(g[0]) * float(g_ad[0]) > 0.0, (sigma_t, float(g[0]), float(g_ad[0]))


def test_calibrate_slope_rejects_an_unknown_gradient_or_step(problem):
    grid = sc.observation_grid(problem.setup, 1.0)
    observed = np.zeros(grid.shape)
    with pytest.raises(ValueError, match="gradient must be 'ad' or 'fd'"):
        sc.calibrate_slope(problem, observed, grid, steps=1, gradient="adjoint")
    with pytest.raises(ValueError, match=r"fd_step must be in \(0, 0.5\]"):
        sc.calibrate_slope(problem, observed, grid, steps=1, gradient="fd", fd_step=0.0)
    # what a user gets wrong before any run: a misspelled field, a map of another grid,
    # unobserved (NaN) cells, a start the logarithm cannot take
    with pytest.raises(ValueError, match=r"initial \['tensile_strenght'\]: not one of"):
        sc.calibrate_slope(problem, observed, grid, steps=1, initial={"tensile_strenght": 3e3})
    with pytest.raises(ValueError, match=r"observed has shape \(2, 2\): must be the obs"):
        sc.calibrate_slope(problem, np.zeros((2, 2)), grid, steps=1)
    with pytest.raises(ValueError, match="observed has 1 non-finite cells"):
        one_nan = observed.copy()
        one_nan[0, 0] = np.nan
        sc.calibrate_slope(problem, one_nan, grid, steps=1)
    with pytest.raises(ValueError, match=r"initial tensile_strength = -2500.0: must be a n"):
        sc.calibrate_slope(problem, observed, grid, steps=1, initial={"tensile_strength": -2500})
    with pytest.raises(ValueError, match=r"\['tensile_strenght'\]"):  # one name, not letters
        sc.calibrate_slope(problem, observed, grid, steps=1, fields="tensile_strenght")


def test_a_slope_problem_warns_of_a_strength_below_the_slab_s_weight_and_names_a_nan_angle():
    """What simulate_slope says of its inputs, slope_problem says too: a strength map in
    kPa instead of Pa fails under the slab at once; a NaN slope angle is named."""
    nx, ny = int(round(L / DX)), int(round(W / DX))
    setup = SlopeSetup(length=L, width=W, dx=DX, duration=0.1, start=(1.0, W / 2))
    kpa = np.linspace(1.0, 4.3, nx * ny).reshape(nx, ny)
    with pytest.warns(UserWarning, match=r"on 100 % of the area.*in kPa instead of Pa"):
        sc.slope_problem(fig12_params(), setup, slope_deg=35.0, tau_peak=kpa)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no all-NaN RuntimeWarning either
        with pytest.raises(ValueError, match=r"slope_deg field: is nan: must be a finite number"):
            sc.slope_problem(fig12_params(), setup, slope_deg=math.nan, tau_peak=1000.0)


def test_calibrate_slope_checks_its_start_and_grid_and_stops_on_a_flat_loss(problem, monkeypatch):
    """Every start value is checked as simulate_slope checks it (softening -1: an error;
    sigma_t 4, meant in kPa: a note), the observation grid must be the problem's, and a
    loss whose gradient is exactly zero (as sigma_t 4 Pa's: every cell breaks alike)
    stops with a warning, not as converged through its tol test."""
    from damjax.validation import DubiousInputWarning

    grid = sc.observation_grid(problem.setup, 1.0)
    observed = np.zeros(grid.shape)
    with pytest.raises(ValueError, match=r"initial softening = -1.0: must be in \[0, inf\)"):
        sc.calibrate_slope(problem, observed, grid, steps=1, initial={"softening": -1.0})
    other = sc.observation_grid(SlopeSetup(length=30.0, width=W, dx=DX), 1.0)
    with pytest.raises(ValueError, match=r"grid has \(30, 3\) cells .* needs \(16, 3\)"):
        sc.calibrate_slope(problem, np.zeros((30, 3)), other, steps=1)
    with pytest.raises(ValueError, match="cell = 100.0: must be at most the release area's"):
        sc.observation_grid(problem.setup, 100.0)
    with pytest.raises(TypeError, match="problem must be a SlopeProblem"):
        sc.calibrate_slope(None, observed, grid, steps=1)
    # the flat loss without compiling the run's gradient again (the loss's own tests do)
    monkeypatch.setattr(
        sc, "loss_and_grad", lambda *a, **k: lambda x, fixed: (jnp.asarray(0.4), 0.0 * x)
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = sc.calibrate_slope(
            problem, observed, grid, steps=3, initial={"tensile_strength": 4.0}
        )
    said = [(w.category, str(w.message)) for w in caught]
    assert any(c is DubiousInputWarning and "4 kPa = 4000 Pa" in m for c, m in said), said
    assert any("gradient is exactly zero at iterate 0" in m for _, m in said), said
    assert fit.stop_reason == "zero_gradient" and len(fit.history) == 1
