"""Slab fracture with a physical length scale: the pieces that make a fracture grid-independent.

- the tensile-strength field of a seed is the same field on every particle grid;
- the band opening (`damjax.core.step.band_opening`) of a localised band is its
  displacement jump, whatever the grid and however many particles the band spans;
- fractures are counted from openings, with position, time and opening.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from damjax.core.step import band_opening
from damjax.materials import slab_fracture


def _x(dx: float, ppc: int = 2, length: float = 20.0) -> np.ndarray:
    n = int(round(length / dx)) * ppc
    return (np.arange(n) + 0.5) * dx / ppc


def test_strength_field_is_the_same_on_every_grid():
    coarse, fine = _x(0.04), _x(0.01)
    kw = dict(mean=6000.0, cov=0.2, length_scale=1.0, extent=20.0)
    a = np.asarray(slab_fracture.strength_field(3, x=jnp.asarray(coarse, jnp.float32), **kw))
    b = np.asarray(slab_fracture.strength_field(3, x=jnp.asarray(fine, jnp.float32), **kw))
    # the fine grid's values at the coarse particles' positions: linear interpolation of
    # one field on a 0.05 m node grid, so they agree to its interpolation error
    np.testing.assert_allclose(np.interp(coarse, fine, b), a, rtol=2e-3)
    other = np.asarray(slab_fracture.strength_field(4, x=jnp.asarray(coarse, jnp.float32), **kw))
    assert np.max(np.abs(other - a)) > 0.1 * 6000.0  # another seed, another field
    # homogeneous when cov = 0
    c = slab_fracture.strength_field(3, 6000.0, 0.0, 1.0, jnp.asarray(coarse), 20.0)
    assert np.all(np.asarray(c) == 6000.0)


def test_strength_field_mean_and_cov():
    # many correlation lengths along a long slab: sample mean and CoV near the targets
    x = jnp.asarray(_x(0.05, 1, 2000.0), jnp.float32)
    s = np.asarray(slab_fracture.strength_field(0, 6000.0, 0.2, 1.0, x, 2000.0))
    assert s.min() > 0.0
    assert s.mean() == pytest.approx(6000.0, rel=0.03)
    assert s.std() / s.mean() == pytest.approx(0.2, rel=0.1)


class _Lattice:
    """The Model fields `band_opening` reads, for a 1D strip."""

    def __init__(self, dx: float, ppc: int, n: int) -> None:
        self.dx = dx
        self.lattice = (n,)
        self.lattice_spacing = dx / ppc
        self.opening_window = slab_fracture.opening_window(dx / ppc)
        self.dim = 1


@pytest.mark.parametrize("dx", [0.04, 0.02, 0.01])
@pytest.mark.parametrize("width_cells", [1, 2, 3])
def test_band_opening_is_the_jump_on_every_grid(dx, width_cells):
    # a band of `width_cells` cells carrying a 2 mm jump: every particle of the band sees
    # 2 mm, particles a window or more away see nothing
    ppc = 2
    x = _x(dx, ppc, 4.0)
    band = np.abs(x - 2.0) < 0.5 * width_cells * dx
    strain = np.where(band, 2e-3 / (band.sum() * dx / ppc), 0.0)
    model = _Lattice(dx, ppc, x.size)
    w = np.asarray(band_opening(model, jnp.asarray(strain)))
    np.testing.assert_allclose(w[band], 2e-3, rtol=1e-6)
    far = np.abs(x - 2.0) > 2.0 * slab_fracture.OPENING_HALF_WIDTH + width_cells * dx
    assert np.all(w[far] == 0.0)


def test_fractures_are_counted_from_openings():
    x = np.linspace(0.0, 10.0, 1001)
    opening = np.zeros_like(x)
    t = np.full_like(x, np.inf)
    for x0, t0, w0 in ((3.0, 0.5, 4e-3), (3.4, 0.52, 2e-3), (7.0, 0.8, 1e-3)):
        near = np.abs(x - x0) < 0.1
        opening[near] = w0
        t[near] = t0
    out = slab_fracture.fractures(x, opening, t)
    # the bands at 3.0 and 3.4 m are closer than FRACTURE_GAP: one fracture
    assert [round(f["x_m"], 1) for f in out] == [2.9, 6.9]
    assert out[0]["t_s"] == 0.5 and out[0]["opening_m"] == 4e-3
    assert set(out[0]) == {"x_m", "t_s", "opening_m"}


def test_speed_change_of_a_fracture():
    time = np.linspace(0.0, 1.0, 1001)
    tip = np.where(time < 0.5, 100.0 * time, 50.0 + 10.0 * (time - 0.5))
    (c,) = slab_fracture.speed_changes(time, tip, [{"x_m": 40.0, "t_s": 0.5, "opening_m": 0.0}])
    assert c["speed_before_m_per_s"] == pytest.approx(100.0, rel=1e-6)
    assert c["speed_after_m_per_s"] == pytest.approx(10.0, rel=1e-6)
    assert c["speed_drop_m_per_s"] == pytest.approx(90.0, rel=1e-6)
    assert math.isfinite(c["t_s"])
