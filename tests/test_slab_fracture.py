"""Slab tensile fracture with crack-band softening: the release does not depend on the grid.

The paper's perfectly plastic MCC slab localises a fracture in one cell, so what a fracture
costs, and the release area it leaves, changes with dx. `PSTParams.slab_fracture_energy`
(G_f) softens p0 with the band's opening so that a fracture dissipates G_f per unit area on
any grid (the material-point check is in test_mcc.py).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from damjax import PSTParams, PSTSetup, SlopeSetup, fields, simulate_slope
from damjax.pst import simulate_pst
from damjax.slope.generic import fig12_params

L, W = 30.0, 8.0


def _release_area(dx: float, fracture_energy: float) -> dict:
    # the slope calibration benchmark's truth case: planar 35 deg, GRF strength rising
    # 125 Pa/m up-slope, drawn once on a 0.125 m grid and interpolated to each grid
    xf, yf = np.arange(0.0, L + 1e-9, 0.125), np.arange(0.0, W + 1e-9, 0.125)
    tau = np.asarray(
        fields.grf(
            jax.random.key(7),
            (xf.size, yf.size),
            0.125,
            mean=1000.0,
            std=100.0,
            length_scale=4.0,
            trend=(125.0, 0.0),
        )
    )
    xc, yc = (np.arange(round(L / dx)) + 0.5) * dx, (np.arange(round(W / dx)) + 0.5) * dx
    setup = SlopeSetup(
        length=L,
        width=W,
        dx=dx,
        duration=1.5,
        start=(2.0, W / 2),
        particles_per_cell=1,
        chunk_steps=50,
    )
    params = fig12_params(tensile_strength=4000.0, slab_fracture_energy=fracture_energy)
    res = simulate_slope(
        params, setup, slope_deg=35.0, tau_peak=fields.map_on_grid(xf, yf, tau, xc, yc)
    )
    assert res.summary["fault"] is None
    return res.summary


def test_crack_band_release_area_is_grid_independent():
    # measured: G_f = 1 J/m^2 releases 57.7 / 56.9 m^2 on dx 0.25 / 0.125 m (and 57.8 /
    # 58.5 m^2 on 0.125 / 0.0625 m with 2 x 2 particles per cell, benchmarks); the perfectly
    # plastic slab releases 86.1 / 78.1 m^2 (-9 % per halving, the control below)
    coarse, fine = _release_area(0.25, 1.0), _release_area(0.125, 1.0)
    for s in (coarse, fine):
        assert s["slab_fracture_area_m2"] > 0.0  # the slab did fracture
        assert s["upslope_arrest_distance_m"] < L - 2.0 - 5.0  # and the crack arrested
    assert fine["release_area_m2"] == pytest.approx(coarse["release_area_m2"], rel=0.05)
    assert fine["upslope_arrest_distance_m"] == pytest.approx(
        coarse["upslope_arrest_distance_m"], abs=0.5
    )
    plastic_coarse = _release_area(0.25, math.inf)["release_area_m2"]
    plastic_fine = _release_area(0.125, math.inf)["release_area_m2"]
    assert plastic_fine < 0.95 * plastic_coarse


def test_infinite_fracture_energy_is_the_perfectly_plastic_slab(small_setup, arresting_params):
    # G_f = inf must leave the paper's model untouched, bit for bit
    small_setup = dataclasses.replace(small_setup, slab_fracture="paper")
    p = PSTParams(
        steady_length=arresting_params.steady_length,
        strength_gradient=arresting_params.strength_gradient,
        tensile_strength=3000.0,
    )
    a = simulate_pst(p, small_setup)
    b = simulate_pst(dataclasses.replace(p, slab_fracture_energy=math.inf), small_setup)
    np.testing.assert_array_equal(a.sigma_xx, b.sigma_xx)
    assert a.summary["slab_fractures"] == b.summary["slab_fractures"]
    # a finite G_f changes the slab (it softens after yield) but stays finite
    c = simulate_pst(dataclasses.replace(p, slab_fracture_energy=0.3), small_setup)
    assert np.all(np.isfinite(c.sigma_xx))
    assert not np.array_equal(a.sigma_xx, c.sigma_xx)


def test_fracture_marker_is_an_opening_the_same_on_every_grid():
    # a fracture is a band opening of max(1 mm, ln(100) w_c) [m] for both slab models and
    # every dx: with G_f = 3 J/m^2 the band keeps 1 % of its strength beyond 1 mm
    from damjax import pst
    from damjax.materials.slab_fracture import (
        FRACTURE_OPENING,
        crack_band_opening,
        fracture_opening,
    )

    out = {}
    for dx in (0.04, 0.02):
        for model_name in ("paper", "crack_band"):
            for g_f in (None, 0.3, 3.0):
                setup = PSTSetup(
                    length=5.0, dx=dx, duration=0.01, chunk_steps=10, slab_fracture=model_name
                )
                params = PSTParams(tensile_strength=6000.0, slab_fracture_energy=g_f)
                model = pst.build(params, setup, pst.make_layout(params, setup))[0]
                w = np.asarray(fracture_opening(model.fracture))
                w_c = np.asarray(crack_band_opening(model.fracture))
                expected = np.where(
                    np.isfinite(w_c), np.maximum(FRACTURE_OPENING, np.log(100.0) * w_c), 1e-3
                )
                np.testing.assert_allclose(w, np.broadcast_to(expected, w.shape), rtol=1e-6)
                out[dx, model_name, g_f] = float(np.mean(w))
    for key in (("paper", None), ("paper", 0.3), ("crack_band", 0.3)):
        assert out[(0.04, *key)] == out[(0.02, *key)] == pytest.approx(FRACTURE_OPENING)
    assert out[0.04, "paper", 3.0] == pytest.approx(out[0.02, "paper", 3.0], rel=1e-6)
    assert out[0.04, "paper", 3.0] > 4.0 * FRACTURE_OPENING
    # with the random strength field w_c varies along the slab, the same on both grids
    assert out[0.04, "crack_band", 3.0] == pytest.approx(out[0.02, "crack_band", 3.0], rel=0.02)
    assert out[0.04, "crack_band", 3.0] != pytest.approx(out[0.04, "paper", 3.0], rel=1e-4)


def test_fracture_energy_sweeps_like_any_parameter(small_setup, arresting_params):
    # a vmapped batch over G_f (inf and finite together) equals the runs one by one
    from damjax.sweep import sweep

    base = dict(
        steady_length=arresting_params.steady_length,
        strength_gradient=arresting_params.strength_gradient,
        tensile_strength=3000.0,
    )
    batch = PSTParams(**base, slab_fracture_energy=np.array([math.inf, 0.3]))
    swept = sweep(batch, small_setup)
    ones = [
        simulate_pst(PSTParams(**base, slab_fracture_energy=g_f), small_setup)
        for g_f in (math.inf, 0.3)
    ]
    # float32 rounding differs between the vmapped and the single program, and a yielding
    # slab carries it on: compare to 1e-3 of the stress scale, and check that each member
    # is much closer to its own single run than to the other's
    scale = float(np.max(np.abs(ones[0].sigma_xx)))
    for i, (r, one) in enumerate(zip(swept, ones, strict=True)):
        np.testing.assert_allclose(r.sigma_xx, one.sigma_xx, atol=1e-3 * scale)
        other = ones[1 - i].sigma_xx
        assert np.max(np.abs(r.sigma_xx - other)) > 10 * np.max(np.abs(r.sigma_xx - one.sigma_xx))
        assert r.summary["arrest_position_m"] == pytest.approx(
            one.summary["arrest_position_m"], abs=0.05
        )


def test_band_openings_on_a_lattice_with_gaps_are_the_full_lattice_with_no_opening_there():
    """A snow cover with gaps (`Fracture.lattice_index`): the particles' band openings are
    those of the whole lattice whose sites without a particle open by 0 (no slab there),
    bit for bit, with and without the y part of the opening."""
    from damjax.materials import slab_fracture as sf

    kw = dict(
        plastic=True,
        p0_init=1.0,
        mcc_m=1.0,
        mcc_beta=0.5,
        mcc_xi=0.0,
        fracture_energy=0.12,
        cell_width=0.1,
        crack_band=True,
        lattice=(12, 10),
        lattice_spacing=0.1,
        opening_window=2,
    )
    rng = np.random.default_rng(3)
    keep = rng.random(120) > 0.25
    keep[40:46] = False  # a gap across a band
    sites = np.flatnonzero(keep)
    full = sf.Fracture(**kw)
    gaps = sf.Fracture(**kw, lattice_index=jnp.asarray(sites, jnp.int32))
    o = np.where(keep, rng.random(120) * 1e-3, 0.0).astype(np.float32)
    oy = (o * rng.random(120)).astype(np.float32)
    for y_full, y_gaps in ((None, None), (jnp.asarray(oy), jnp.asarray(oy[sites]))):
        want = sf.band_openings(full, jnp.asarray(o), y_full)
        got = sf.band_openings(gaps, jnp.asarray(o[sites]), y_gaps)
        for a, b in zip(want, got, strict=True):
            np.testing.assert_array_equal(np.asarray(a)[sites], np.asarray(b))
    assert float(np.max(np.asarray(sf.band_openings(full, jnp.asarray(o))[0]))) > 0.0


def test_a_slab_too_wide_for_the_doubled_embedding_gets_its_strength_field():
    """The crack-band slab's strength field on a domain hundreds of metres wide (a real
    path's buffer on the 0.1 m field grid): the doubled circulant embedding would exceed
    the GRF's node limit, so each axis is padded by 5 MAX_STRENGTH_LENGTH only; a small
    slab keeps the embedding, and so the field, it had."""
    from damjax.fields import embedding_shape
    from damjax.materials import slab_fracture as sf

    small = (100, 80)
    assert sf._strength_embedding(small, 0.1, (10.0, 8.0)) == embedding_shape(
        small, 0.1, sf.MAX_STRENGTH_LENGTH
    )
    wide = (8145, 4765)  # 814 m x 476 m
    with pytest.raises(ValueError, match="periodic embedding would exceed"):
        embedding_shape(wide, 0.1, sf.MAX_STRENGTH_LENGTH)
    embed = sf._strength_embedding(wide, 0.1, (814.4, 476.4))
    pad = 5 * sf.MAX_STRENGTH_LENGTH / 0.1
    assert all(n + pad <= m < 2 * n for n, m in zip(wide, embed, strict=True))
    with pytest.raises(ValueError, match=r'slab_fracture = "crack_band": the slab.s tensile'):
        sf._strength_embedding((30000, 30000), 0.1, (3000.0, 3000.0))
