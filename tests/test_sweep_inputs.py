"""`damjax.sweep` checks and warns each member as `simulate_pst` checks one run: the
single run's warnings and errors naming the batch member, the unit hint of a mix-up,
members that are not numbers, traced leaves and profiles of different lengths; the
scaling fits and `gradient_check` say what they cannot fit or run."""

import warnings
from types import SimpleNamespace

import jax
import numpy as np
import pytest

import damjax
from damjax import PSTParams, PSTSetup
from damjax.calibrate import fit_elastic_scaling, fit_plastic_scaling
from damjax.validation import DubiousInputWarning

SETUP = PSTSetup(length=10.0, dx=0.1, duration=0.6)


def _messages(record: list[warnings.WarningMessage]) -> list[str]:
    return [str(w.message) for w in record]


def test_a_sweep_warns_each_members_doubtful_values_once_per_kind():
    batch = PSTParams(steady_length=3.0, slope_deg=[35.0, 15.0, 14.0])
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        damjax.sweep(batch, SETUP)
    said = _messages(record)
    outside = [m for m in said if "outside [20, 60] deg" in m]
    below = [m for m in said if "at or below friction_deg" in m]
    assert len(outside) == 1 and len(below) == 1, said
    assert outside[0].startswith("slope_deg (--slope-deg) = 15.0: outside")
    assert outside[0].endswith("(batch members 1, 2)") and below[0].endswith("(batch members 1, 2)")


def test_a_controlled_members_cut_leaving_the_domain_is_warned():
    setup = PSTSetup(length=10.0, dx=0.1, duration=0.6, controlled=True)
    with pytest.warns(DubiousInputWarning) as record:
        damjax.sweep(PSTParams(saw_speed=[10.0, 39.2]), setup)
    left = [m for m in _messages(record) if "leaves the 10 m domain" in m]
    assert len(left) == 1 and "saw_speed (--saw-speed) = 39.2" in left[0]
    assert left[0].endswith("(batch member 1)")


def test_an_invalid_batch_names_its_member_and_warns_the_unit_hint():
    batch = PSTParams(steady_length=3.0, youngs_modulus=[4e6, 4.0])
    with pytest.warns(DubiousInputWarning, match=r"4e6 Pa\? \(batch member 1\)"):
        with pytest.raises(ValueError, match=r"dx \(--dx\) = 0.1: must be at most .*member 1\)$"):
            damjax.sweep(batch, SETUP)
    with pytest.raises(ValueError, match=r"tau_peak .* = 500.0: must exceed .* \(batch member 1\)"):
        damjax.sweep(PSTParams(steady_length=3.0, tau_peak=[1000.0, 500.0]), SETUP)
    batch = PSTParams(density=[250.0, 5000.0])
    with pytest.warns(DubiousInputWarning, match=r"= 5000.0: .* \(batch member 1\)"):
        with pytest.raises(ValueError) as info:
            damjax.sweep(batch, SETUP)
    lines = str(info.value).splitlines()
    assert lines[0].startswith("tau_peak") and lines[0].endswith("(batch member 1)")
    # a shared value's problem is every member's: no member named
    assert lines[1] == "steady_length (--steady-length) = 20.0: must be in [0, length = 10.0) m"


@pytest.mark.parametrize(
    "values, shown, members",
    [
        ([True, 600.0], "True", "member 0"),
        (["500", "600"], "'500'", "members 0, 1"),
        ([None, 600.0], "None", "member 0"),
        (np.array([600.0 + 1j, 600.0]), r"\(600\+1j\)", "members 0, 1"),
        (np.array([True, False]), "True", "members 0, 1"),
    ],
)
def test_members_that_are_not_numbers_are_refused_before_conversion(values, shown, members):
    batch = PSTParams(steady_length=3.0, strength_gradient=values)
    needle = rf"^strength_gradient \(--strength-gradient\) = {shown}: must be in \[0, inf\) "
    with warnings.catch_warnings():
        warnings.simplefilter("error", np.exceptions.ComplexWarning)
        with pytest.raises(ValueError, match=needle + rf"Pa/m \(a number\) \(batch {members}\)$"):
            damjax.sweep(batch, SETUP)


def test_a_shared_value_that_is_not_a_number_is_refused():
    with pytest.raises(ValueError, match=r"= True: must be in \[0, inf\) Pa/m \(a number\)$"):
        damjax.sweep(PSTParams(steady_length=3.0, strength_gradient=True), SETUP)


def test_traced_leaves_under_grad_and_vmap_are_a_clear_type_error():
    def length(g):
        batch = PSTParams(steady_length=3.0, strength_gradient=g)
        return damjax.sweep(batch, SETUP)[0].summary["arrest_position_smooth_m"]

    with pytest.raises(TypeError, match=r"^sweep: called with traced parameters .*jax.grad"):
        jax.grad(length)(600.0)
    with pytest.raises(TypeError, match=r"^sweep: called with traced parameters"):
        jax.vmap(length)(np.array([600.0, 700.0]))


def test_profiles_of_different_lengths_are_one_line():
    profiles = [np.array([1000.0, 4000.0]), np.array([1000.0, 1000.0, 6000.0])]
    with pytest.raises(ValueError) as info:
        damjax.sweep(PSTParams(strength_profile=profiles), SETUP)
    assert str(info.value) == (
        "strength_profile (--strength-profile): profiles of different lengths in one batch, "
        "2 values (batch member 0) and 3 values (batch member 1): a batch of profiles is one "
        "(B, m) array; sample them on one grid (e.g. np.interp)"
    )


def _run(params, arrest):
    return SimpleNamespace(params=params, arrested=True, arrest_position=arrest)


def test_scaling_fits_refuse_runs_of_a_strength_profile():
    x = np.linspace(0, 10, 11)
    runs = [
        _run(PSTParams(strength_profile=1000 + g * np.maximum(x - 3, 0)), 30.0 - g / 200)
        for g in [800.0, 1200.0, 2000.0, 3000.0]
    ]
    for fit in (fit_elastic_scaling, fit_plastic_scaling):
        with pytest.raises(ValueError, match=r"results 0, 1, 2, 3 of 4 ran with a strength_pro"):
            fit(runs)


def test_the_plastic_fit_says_its_runs_are_elastic():
    runs = [_run(PSTParams(steady_length=3.0), 5.0 + i) for i in range(6)]
    runs += [SimpleNamespace(params=PSTParams(), arrested=False)] * 2
    with pytest.raises(ValueError) as info:
        fit_plastic_scaling(runs)
    assert str(info.value) == (
        "fit_plastic_scaling: need at least 3 runs to fit, got 0 of 8: 8 elastic "
        "(tensile_strength = inf: no tensile length L_t), 0 not arrested with a finite "
        "tensile strength, 0 arrested at or below the steady-state length"
    )


def test_a_gradient_check_window_that_leaves_the_valid_values_is_said_so():
    params = PSTParams(steady_length=3.0, strength_gradient=800.0, poisson=0.48)
    with pytest.raises(ValueError) as info:
        damjax.gradient_check(params, SETUP, "poisson", n_runs=3)
    assert str(info.value) == (
        "poisson window [0.432, 0.528] (rel_window = 0.1 around poisson = 0.48): its upper end "
        "leaves the valid range (0, 0.5); narrow the window (rel_window)"
    )
    params = PSTParams(steady_length=3.0, strength_gradient=800.0, tau_peak=760.0)
    with pytest.raises(ValueError) as info:
        damjax.gradient_check(params, SETUP, "tau_peak", n_runs=3)
    text = str(info.value)
    assert text.startswith(
        "tau_peak window [684, 836] (rel_window = 0.1 around tau_peak = 760.0): at its lower "
        "end, tau_peak (--tau-peak) = 684: must exceed the gravitational shear stress"
    )
    assert text.endswith("; narrow the window (rel_window)") and "batch member" not in text
