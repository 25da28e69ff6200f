"""Scaling-law fits and inversion through the solver."""

import dataclasses

import numpy as np
import pytest

from damjax import PSTParams, PSTSetup, calibrate


def test_power_law_fit_recovers_known_exponent_with_interval():
    rng = np.random.default_rng(0)
    x = np.exp(rng.uniform(-2, 2, 64))
    y = 0.8 * x**1.5 * np.exp(rng.normal(0, 0.05, x.size))
    fit = calibrate.fit_power_law(x, y)
    assert fit.exponent == pytest.approx(1.5, abs=0.03)
    assert fit.prefactor == pytest.approx(0.8, rel=0.05)
    assert fit.exponent_ci95[0] < 1.5 < fit.exponent_ci95[1]
    assert fit.r2_log > 0.99
    # agrees with the closed-form least squares
    b, a = np.polyfit(np.log(x), np.log(y), 1)
    assert fit.exponent == pytest.approx(b, abs=1e-3)


def test_power_law_fit_rejects_bad_data():
    with pytest.raises(ValueError, match="positive"):
        calibrate.fit_power_law([1.0, 2.0, -3.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="at least 3"):
        calibrate.fit_power_law([1.0, 2.0], [1.0, 2.0])
    # the optimiser's options, as invert checks them: steps = 0 returned the starting
    # guess as a fit, a NaN rate an all-NaN fit, a negative one an OverflowError
    x = [1.0, 2.0, 4.0, 8.0]
    for kw, match in [
        ({"steps": 0}, "steps = 0: must be an integer >= 1"),
        ({"learning_rate": float("nan")}, "learning_rate = nan: must be a number in"),
        ({"learning_rate": -1.0}, "learning_rate = -1.0: must be a number in"),
    ]:
        with pytest.raises(ValueError, match=f"fit_power_law: {match}"):
            calibrate.fit_power_law(x, [0.5 * v**1.5 for v in x], **kw)


@pytest.mark.min_versions
def test_inversion_recovers_a_known_strength_gradient():
    setup = PSTSetup(length=10.0, dx=0.05, duration=0.5, chunk_steps=250)
    truth = PSTParams(steady_length=4.0, strength_gradient=800.0, softening=1.0)
    from damjax import pst

    observed = float(pst.arrest_position_smooth(truth, setup))
    start = PSTParams(steady_length=4.0, strength_gradient=1200.0, softening=1.0)
    inv = calibrate.invert(
        [({}, observed)],
        start,
        setup,
        ["strength_gradient"],
        noise_std=0.05,
        steps=25,
        learning_rate=0.08,
    )
    assert inv.estimates["strength_gradient"] == pytest.approx(800.0, rel=0.05)
    assert inv.history[-1] < inv.history[0]
    # 25 updates: 26 iterates, the start and the last included; the estimates are the
    # best of them, and their loss is its entry (not one lower than every entry)
    assert len(inv.history) == 26
    assert inv.loss == min(inv.history) == inv.history[inv.best_step]
    from damjax import pst as pst_mod

    best = dataclasses.replace(start, strength_gradient=inv.estimates["strength_gradient"])
    at_best = float(pst_mod.arrest_position_smooth(best, setup))
    assert ((at_best - observed) / 0.05) ** 2 == pytest.approx(inv.loss, rel=1e-3, abs=1e-6)
    assert np.isfinite(inv.condition_number)
    for kw, needle in [
        ({"fields": ["strength_gradiant"]}, "not a PSTParams field"),
        ({"fields": ["softening"], "params0": PSTParams(softening=0.0)}, "params0.softening"),
        ({"observations": []}, "observations: empty"),
        ({"observations": [({}, float("nan"))]}, r"observations\[0\]: L_observed = nan"),
        ({"observations": [({}, None)]}, r"observations\[0\]: L_observed = None: must be"),
        ({"observations": [({}, "abc")]}, r"observations\[0\]: L_observed = 'abc': must be"),
        # an override of the fitted field was dropped silently ({**o, **fitted})
        ({"observations": [({"tau_peak": -1.0}, observed)]}, r"overrides \['tau_peak'\], fitted"),
        ({"observations": [({"softening": "x"}, observed)]}, "override softening = 'x': must be"),
    ]:
        args = {"observations": [({}, observed)], "params0": start, "fields": ["tau_peak"]}
        args.update(kw)
        with pytest.raises(ValueError, match=needle):
            calibrate.invert(setup=setup, **args)


def test_scaling_fits_say_which_runs_were_left_out():
    from types import SimpleNamespace

    from damjax.calibrate import fit_elastic_scaling, fit_plastic_scaling

    running = SimpleNamespace(arrested=False)
    with pytest.raises(ValueError, match=r"need at least 3 runs to fit, got 0 of 2: 2 not arr"):
        fit_elastic_scaling([running, running])
    with pytest.raises(ValueError, match="not arrested with a finite tensile strength"):
        fit_plastic_scaling([running])


def test_inversion_and_the_smooth_arrest_check_their_options():
    """Options are checked before any run: a user's slip is named, not a NaN later."""
    import jax

    import damjax

    params = PSTParams(steady_length=3.0, strength_gradient=3000.0, softening=1.0)
    setup = PSTSetup(length=8.0, dx=0.1, duration=0.2)
    obs = [({"strength_gradient": 3000.0}, 4.0)]
    for kw, msg in [
        (dict(noise_std=0.0), r"noise_std = 0.0: must be a number in \(0, inf\)"),
        (dict(fields=["softening", "softening"]), r"\['softening'\] named more than once"),
        (dict(smooth_width=-1.0), r"smooth_width = -1.0: must be None or a number in \(0, 1\]"),
        (dict(fields=["strength_profile"]), "strength_profile = None: a fitted field"),
        (dict(steps=0), r"steps = 0: must be an integer >= 1"),
        (dict(steps=2.5), r"steps = 2.5: must be an integer >= 1"),
        (dict(learning_rate=-0.05), r"learning_rate = -0.05: must be a number in \(0, inf\)"),
        (dict(learning_rate=float("nan")), r"learning_rate = nan: must be a number in"),
    ]:
        kw = {"fields": ["softening"], **kw}
        with pytest.raises(ValueError, match=msg):
            calibrate.invert(obs, params, setup, **kw)
    with pytest.raises(ValueError, match=r"overrides \['strength_gradiant'\] are not PSTP"):
        calibrate.invert([({"strength_gradiant": 1.0}, 4.0)], params, setup, ["softening"])
    with pytest.raises(ValueError, match=r"L_observed = 50.0: must be in \(0, 8\] m"):
        calibrate.invert([({}, 50.0)], params, setup, ["softening"])
    with pytest.raises(TypeError, match="invert: params0 must be damjax.PSTParams, got dict"):
        calibrate.invert(obs, {"softening": 1.0}, setup, ["softening"])
    # one field by its name is that field, not its letters (one line)
    with pytest.raises(ValueError, match=r"^fields: 'steady_lenght' is not a PSTParams field$"):
        calibrate.invert(obs, params, setup, "steady_lenght")
    # arrest positions without their overrides: the form the observations take
    with pytest.raises(ValueError, match=r"observations: must be a list of \(overrides, L_obs"):
        calibrate.invert(np.array([5.0, 4.0]), params, setup, "softening")
    assert calibrate.inversion.optimizer_problems(1, 0.1, -1.0) == [
        "tol = -1.0: must be a number in [0, inf)"
    ]
    from damjax.calibrate.slope import observation_grid

    with pytest.raises(ValueError, match=r"cell = 0.0: must be a number in \(0, inf\) m"):
        observation_grid(damjax.SlopeSetup(length=4.0, width=4.0), 0.0)
    layout = damjax.make_layout(params, setup)
    with pytest.raises(ValueError, match=r"width = 5.0: must be None or a number in \(0, 1\]"):
        damjax.arrest_position_smooth(params, setup, layout, width=5.0)
    # under jax.grad with a layout the values JAX holds are checked as without one
    with pytest.raises(ValueError, match=r"strength_gradient \(--strength-gradient\) = nan"):
        jax.grad(
            lambda th: damjax.arrest_position_smooth(
                dataclasses.replace(params, strength_gradient=th), setup, layout
            )
        )(float("nan"))


def test_a_fit_on_a_flat_misfit_stops_and_says_so():
    """A crack that never leaves the saw cut (0.2 s on 8 m) arrests where the saw stopped
    whatever steady_length is: the gradient is exactly zero and Adam would return the
    start as a "fit"; the run stops at once with a warning and stop_reason."""
    setup = PSTSetup(length=8.0, dx=0.1, duration=0.2)
    p0 = PSTParams(steady_length=3.0, strength_gradient=3000.0, softening=1.0)
    with pytest.warns(UserWarning, match=r"invert: the loss's gradient is exactly zero at it"):
        r = calibrate.invert([({}, 5.0)], p0, setup, ["steady_length"], steps=3)
    assert r.stop_reason == "zero_gradient" and len(r.history) == 1
    assert r.path == {"steady_length": [pytest.approx(3.0)]}


def test_a_start_outside_the_valid_range_is_named_before_any_run():
    """params0 and each observation's overrides are checked as given (30.0, not its
    float32 round trip), once for params0 and per observation for an override."""
    setup = PSTSetup(length=8.0, dx=0.1, duration=0.2)
    p0 = PSTParams(steady_length=30.0, softening=1.0)
    obs = [({"strength_gradient": 600.0}, 5.0), ({"strength_gradient": 900.0}, 4.0)]
    with pytest.raises(ValueError, match=r"^params0: steady_length = 30.0: must be in \[0, le"):
        calibrate.invert(obs, p0, setup, ["softening"])
    p0 = PSTParams(steady_length=3.0, softening=1.0)
    obs[1] = ({"strength_gradient": float("nan")}, 4.0)
    with pytest.raises(ValueError, match=r"^observations\[1\]: strength_gradient = nan: must"):
        calibrate.invert(obs, p0, setup, ["softening"])
    with pytest.raises(TypeError, match="invert: layout must be a Layout"):
        calibrate.invert(obs[:1], p0, setup, ["softening"], layout="abc")


def test_a_fit_whose_iterate_leaves_the_valid_range_stops_with_the_best_one():
    """The jitted gradient sees tracers, so the concrete iterate is checked between steps:
    a step that takes tau_peak below the slab's own shear (a failed weak layer) stops the
    fit with a warning and the best valid iterate, not an error that loses the fit."""
    setup = PSTSetup(length=12.0, dx=0.1, duration=1.0)
    p0 = PSTParams(steady_length=5.0, strength_gradient=800.0, softening=1.0, tau_peak=800.0)
    with pytest.warns(UserWarning, match=r"invert: stopped at iterate 1.*tau_peak"):
        r = calibrate.invert([({}, 11.9)], p0, setup, ["tau_peak"], steps=6, learning_rate=0.3)
    assert r.estimates["tau_peak"] == pytest.approx(800.0) and len(r.history) == 1
    assert r.stop_reason == "invalid_iterate"


def test_a_fit_whose_override_fixes_the_layout_takes_its_layout():
    """A stiffer slab in an override needs a shorter time step than params0's layout
    has: the error says to make one, and `invert(layout=...)` takes it."""
    import damjax

    setup = PSTSetup(length=12.0, dx=0.1, duration=1.0)
    p0 = PSTParams(steady_length=5.0, strength_gradient=800.0, softening=1.0)
    stiff = {"youngs_modulus": 4 * p0.youngs_modulus}
    with pytest.raises(ValueError, match="make_layout"):
        calibrate.invert([(stiff, 6.9)], p0, setup, ["tau_peak"], steps=1)
    layout = damjax.make_layout(dataclasses.replace(p0, **stiff), setup)
    r = calibrate.invert([(stiff, 6.9)], p0, setup, ["tau_peak"], steps=1, layout=layout)
    # (its crack ends where it ends whatever tau_peak: a zero gradient, said, after one run)
    assert r.history and all(np.isfinite(r.history)) and r.stop_reason == "zero_gradient"
