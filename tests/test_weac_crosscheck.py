"""The weac cross-check (verification/weac_crosscheck.py): the two models get the same slab,
weak layer and load, and the matched toughness is weac's tip-stress criterion."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("weac")
pytest.importorskip("scipy")

from damjax import theory  # noqa: E402
from verification import weac_crosscheck as wc  # noqa: E402


@pytest.mark.parametrize("changes", [{}, {"thickness": 0.3, "youngs_modulus": 16.0e6}])
def test_same_slab_weak_layer_and_load(changes):
    p = wc.matched_params(**changes)
    m = wc.weac_model(p)
    k = float(p.wl_shear_modulus / p.wl_thickness)
    assert m.kt * 1e9 == pytest.approx(k, rel=1e-12)  # N/mm^3 -> Pa/m
    # weac's plane-strain membrane stiffness is damjax's constrained strip modulus x h
    e_h = float(theory.strip_modulus(p, "constrained") * p.thickness)
    assert m.A11 * 1e3 == pytest.approx(e_h, rel=1e-12)  # N/mm -> N/m
    assert m.D11 * 1e-3 == pytest.approx(e_h * float(p.thickness) ** 2 / 12, rel=1e-12)
    # far from the column's ends weac's weak layer carries damjax's tau_g
    phi = -float(p.slope_deg)
    segs = m.calc_segments(L=40e3, a=0.0)["crack"]
    c = m.assemble_and_solve(phi=phi, **segs)
    _, z, xwl = m.rasterize_solution(C=c, phi=phi, num=401, **segs)
    _, tau = m.get_weaklayer_shearstress(x=xwl, z=z, unit="kPa")
    mid = abs(float(tau[len(tau) // 2])) * 1e3
    assert mid == pytest.approx(float(theory.gravity_shear(p)), rel=1e-6)


def test_matched_toughness_is_a_tip_stress_criterion():
    """weac's G_II at the tip is tau_tip^2 / (2 k_t), tau_tip from its own stress field, so
    G_IIc = tau_p^2 / (2 K) compares the two models' tip stresses against the same tau_p."""
    p = wc.matched_params()
    m = wc.weac_model(p)
    phi, a = -float(p.slope_deg), 0.5
    segs = m.calc_segments(L=30e3, a=a * 1e3)["crack"]
    c = m.assemble_and_solve(phi=phi, **segs)
    _, g1, g2 = m.gdif(c, phi, **segs, unit="J/m^2")
    _, z, xwl = m.rasterize_solution(C=c, phi=phi, num=3001, **segs)
    x, tau = m.get_weaklayer_shearstress(x=xwl, z=z, unit="kPa", removeNaNs=True)
    assert list(segs["ki"]) == [True, False]  # "pst-": the cut at the right end
    tip = np.argmax(x)  # the last point on the weak layer
    k = float(p.wl_shear_modulus / p.wl_thickness)
    assert float(tau[tip] * 1e3) ** 2 / (2 * k) == pytest.approx(g2, rel=1e-3)
    assert g1 > 0


def test_critical_cut_lengths_and_what_differs():
    """Two rows of the table (no damjax runs): weac's a_c solves its criterion; its cut at
    the upslope end (pushing) is shorter than at the downslope end (pulling), its uncut
    edge carries less than tau_g (the weight acts at mid-height, the springs at the base)
    and mode I dominates at a_c (the cut slab bends down) - what damjax's bar has not."""
    for changes in ({}, {"thickness": 0.3}):
        r = wc.row(changes, simulate=False)
        p = wc.matched_params(**changes)
        a_c = r["weac_a_c_m"]
        m = wc.weac_model(p)
        g2 = wc.weac_err(m, a_c, -float(p.slope_deg), 30 * r["lambda_m"] + 10)[2]
        assert g2 == pytest.approx(r["g_iic_j_m2"], rel=1e-4)
        assert r["g_iic_j_m2"] == pytest.approx(1500.0**2 / (2 * 0.2e6 / 0.04))
        lam, tg = r["lambda_m"], r["tau_g_pa"]
        assert r["damjax_theory_a_c_m"] == pytest.approx(lam * (1500.0 - tg) / tg, rel=1e-3)
        assert 0 < r["weac_upslope_cut_a_c_m"] < a_c
        assert r["weac_edge_tau_pa"] < tg
        assert r["weac_mode_ratio_gi_gii"] > 1
        assert math.isfinite(a_c) and a_c > 0
