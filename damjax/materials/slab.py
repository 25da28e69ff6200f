"""Slab constitutive laws: depth-averaged in-plane stress in plane stress.

Strains and stresses are Voigt-like components (xx, yy, xy), with the *tensor* shear
strain eps_xy, passed as three (n,) rows (a tuple, or a (3, n) array indexed by row).
Small strains: the slab strains of a PST are ~1e-3 and rotations are negligible.

Width-uniform strips (the 1D path) need a lateral condition for eps_yy:
- "constrained": eps_yy = 0 (periodic in y), sigma_yy = nu sigma_xx, modulus E/(1-nu^2);
- "free": sigma_yy = 0 (free edges of a narrow strip), modulus E, eps_yy = -nu eps_xx.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax.numpy as jnp


class Slab(eqx.Module):
    """The slab's part of a run's model (`damjax.core.state.Model.slab`): its columns and
    elastic constants (SI units; arrays traced, the lateral condition static)."""

    density: Any  # rho [kg/m^3]
    # h0 [m]: a scalar (a uniform slab, every PST), or (n,) per particle (a slope's snow
    # cover from the terrain or a depth map, `damjax.core.model.build_slope`)
    thickness: Any
    area0: Any  # reference column-base area per particle [m^2] (1D: per unit width)
    youngs_modulus: Any  # E [Pa]
    poisson: Any  # nu [-]
    lateral: str = eqx.field(static=True)  # strip lateral condition (dim == 1 only)
    # derived (`damjax.core.state.Model.with_constants`): the smallest particle mass [kg]
    # where the thickness is per particle (None with a scalar thickness: every particle
    # weighs `mass`), the grid's empty-node threshold
    mass_ref: Any = None

    @property
    def mass(self) -> Any:
        """Particle mass rho h0 A0 [kg] (constant: h A = h0 A0); (n,) where the thickness
        is per particle."""
        return self.density * self.thickness * self.area0


def plane_stress(eps: Any, youngs_modulus: Any, poisson: Any) -> tuple[Any, Any, Any]:
    """Linear elastic plane-stress sigma [Pa] rows (xx, yy, xy) of the strain rows eps."""
    c = youngs_modulus / (1.0 - poisson**2)
    exx, eyy, exy = eps[0], eps[1], eps[2]
    return c * (exx + poisson * eyy), c * (eyy + poisson * exx), c * (1.0 - poisson) * exy


def area_ratio(eps: Any) -> Any:
    """J = exp(eps_xx + eps_yy): in-plane (column-base) area ratio [-]; h = h0 / J.

    The strain is the time integral of the rate of deformation, i.e. a logarithmic
    strain (exactly so in 1D, and for rotation-free 2D motion), and det(exp(eps)) =
    exp(tr eps). This stays positive inside localised plastic bands where the strain
    reaches O(1), unlike det(I + eps).
    """
    return jnp.exp(eps[0] + eps[1])
