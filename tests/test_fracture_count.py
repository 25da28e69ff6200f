"""The perfectly plastic slab's fractures, counted by what they do to the crack
(`damjax.diagnostics.crack_fractures`): speed drops, separations, the crown."""

from __future__ import annotations

import numpy as np

from damjax import PSTParams, PSTSetup, diagnostics, simulate_pst

CS = 78.4  # shear-wave speed of the baseline slab [m/s]
DT = 1e-4  # sampling of the synthetic tip histories [s]


def _tip(speed: np.ndarray) -> np.ndarray:
    return np.cumsum(speed) * DT


def test_a_steady_deceleration_is_no_speed_drop():
    t = np.arange(0.0, 1.2, DT)
    # accelerates, levels off at 125 m/s, then decelerates steadily to rest (a gradient)
    v = np.clip(np.minimum(1000.0 * t, 125.0) - np.maximum(t - 0.4, 0.0) * 200.0, 0.0, None)
    assert diagnostics.speed_drops(t, _tip(v), CS) == []


def test_a_sudden_drop_of_the_crack_speed_is_found_where_it_happens():
    t = np.arange(0.0, 1.0, DT)
    v = 100.0 - 50.0 * t - np.where(t >= 0.5, 20.0, 0.0)  # 0.26 c_s lost at t = 0.5 s
    (d,) = diagnostics.speed_drops(t, _tip(v), CS)
    assert abs(d["t_s"] - 0.5) <= diagnostics.DROP_SAMPLE
    assert d["speed_drop_m_per_s"] >= 0.9 * 20.0
    # below the stated size (0.1 c_s = 7.8 m/s) it is none
    small = 100.0 - 50.0 * t - np.where(t >= 0.5, 5.0, 0.0)
    assert diagnostics.speed_drops(t, _tip(small), CS) == []


def test_separations_are_stretches_of_a_decimetre_over_a_metre():
    x = np.arange(0.0, 60.0, 0.01)
    # perfectly plastic stretching (3 mm per metre) and two openings of 0.3 and 0.05 m
    slip = -5.0 + 0.003 * x + 0.3 * (x > 40.0) + 0.05 * (x > 20.0)
    (s,) = diagnostics.separations(x, slip)
    assert abs(s["x_m"] - 40.0) <= 0.5
    assert abs(s["opening_m"] - 0.3) <= 0.01
    # the same slab as a 2D strip (four particles across at each x): the same separation
    x2, slip2 = np.repeat(x, 4), np.repeat(slip, 4) + np.tile([-1e-3, 0.0, 0.0, 1e-3], x.size)
    (s2,) = diagnostics.separations(x2, slip2)
    assert s2["x_m"] == s["x_m"] and abs(s2["opening_m"] - s["opening_m"]) <= 1e-9


def test_a_fracture_is_a_speed_drop_with_a_separation_behind_the_tip_or_the_crown():
    t = np.arange(0.0, 1.0, DT)
    v = np.clip(100.0 - 50.0 * t - np.where(t >= 0.3, 30.0, 0.0) - (t >= 0.6) * 400.0, 0, None)
    tip = _tip(v)
    x = np.arange(0.0, 60.0, 0.01)
    tip_at_drop = float(np.interp(0.3, t, tip))
    crown = float(tip[-1]) - 0.3
    behind = tip_at_drop - 2.0
    slip = -5.0 + 0.4 * (x > behind) + 1.0 * (x > crown)
    arrest_time = float(t[np.argmax(v == 0.0)])
    out = diagnostics.crack_fractures(t, tip, x, slip, CS, float(tip[-1]), arrest_time, 126.0)
    assert [round(f["x_m"], 0) for f in out] == [round(behind, 0), round(crown, 0)]
    assert abs(out[0]["t_s"] - 0.3) <= diagnostics.DROP_SAMPLE and out[1]["t_s"] == arrest_time
    # the same drop with no separation within reach (the onset of a strength gradient)
    far = -5.0 + 0.4 * (x > tip_at_drop - 10.0) + 1.0 * (x > crown)
    out = diagnostics.crack_fractures(t, tip, x, far, CS, float(tip[-1]), arrest_time, 126.0)
    assert [round(f["x_m"], 0) for f in out] == [round(crown, 0)]
    # a crack that decelerates steadily and runs through: no drop, no crown
    steady = _tip(100.0 - 50.0 * t)
    assert diagnostics.crack_fractures(t, steady, x, far, CS, None, None, 126.0) == []


def test_the_paper_slab_counts_the_same_fractures_on_two_grids():
    # 30 m PST with a steep gradient beyond L_ss = 10 m: the crack arrests near 18 m at a
    # crown (measured 2026-11-26: 17.98 / 17.85 m, one fracture at 17.5 / 17.4 m on
    # dx 0.08 / 0.04, with the slab separated by about 0.5 m there)
    params = PSTParams(
        tensile_strength=6000.0, strength_gradient=300.0, softening=0.0, steady_length=10.0
    )
    runs = [simulate_pst(params, PSTSetup(length=30.0, dx=dx, duration=1.2)) for dx in (0.08, 0.04)]
    assert all(r.setup.slab_fracture == "paper" for r in runs)  # the default
    counts = [len(r.summary["slab_fractures"]) for r in runs]
    assert counts == [1, 1]
    for r in runs:
        (f,) = r.summary["slab_fractures"]
        assert set(f) == {"x_m", "t_s", "opening_m"}
        assert abs(f["x_m"] - r.summary["arrest_position_m"]) <= diagnostics.FRACTURE_GAP
        assert f["opening_m"] >= diagnostics.SEPARATION_OPENING
    a, b = (r.summary["slab_fractures"][0]["x_m"] for r in runs)
    assert abs(a - b) <= 0.5
