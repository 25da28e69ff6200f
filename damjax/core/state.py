"""Particle state and per-run model constants of the DA-MPM core.

Particles are slab columns. Arrays carry the particle index last (structure of arrays):
vectors are (dim, n), the affine velocity (dim, dim, n). Strains and stresses are tuples of
three (n,) rows in (xx, yy, xy) order, not stacked (3, n) arrays: the step works on rows,
and a stacked array costs a slice per row forward and a pad-and-add per row in reverse mode.
``dim`` is 1 for a width-uniform strip (PST) and 2 for a slope.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import jax.numpy as jnp

from damjax.materials import mcc, weak_layer

# fault codes raised by the runtime guards (bit flags)
FAULT_NAN = 1
FAULT_EDGE = 2
FAULT_THICKNESS = 4
FAULT_MESSAGES = {
    FAULT_NAN: "non-finite velocity (numerical instability)",
    FAULT_EDGE: "a particle reached the edge of the grid",
    FAULT_THICKNESS: "slab column height h <= 0",
}


def raise_on_fault(value: Any, fault: Any) -> Any:
    """``value``, with a runtime error (`equinox.error_if`) for each fault bit set in
    ``fault`` (`FAULT_MESSAGES`): a differentiable summary of a traced run (a smooth
    arrest position or release area) is meaningless after a fault, and under `jax.grad`
    or `jax.jit` nobody reads the fault code beside it. Concrete runs stop at the fault
    and report it instead (`PSTResult.fault`)."""
    import equinox as eqx

    for bit, message in FAULT_MESSAGES.items():
        value = eqx.error_if(
            value,
            (fault & bit) != 0,
            f"the run hit a runtime fault: {message}; its smooth summary would be "
            "meaningless (a shorter duration, a larger domain, or a smaller time step)",
        )
    return value


def zero_components(n: int, dtype: Any) -> tuple[Any, Any, Any]:
    """Three zero rows (n,): an unstrained (xx, yy, xy) strain or stress."""
    return tuple(jnp.zeros((n,), dtype) for _ in range(3))


class Model(eqx.Module):
    """Everything a time step needs that does not evolve (traced leaves + static layout).

    Units: SI. Per-particle arrays have shape (n,) or (dim, n).
    """

    # static layout
    grid_shape: tuple[int, ...] = eqx.field(static=True)
    dx: float = eqx.field(static=True)
    periodic: tuple[bool, ...] = eqx.field(static=True)  # wrap-around axes
    lateral: str = eqx.field(static=True)  # strip lateral condition (dim == 1 only)
    saw_stops: bool = eqx.field(static=True)  # False: controlled cut for the whole run
    # particle reference positions (cell units) and saw coordinate [m]
    cell0: Any  # (dim, n) int32
    frac0: Any  # (dim, n) in [0, 1)
    saw_coord: Any  # (n,) distance along the saw path in the reference configuration [m]
    # time step and slab
    dt: Any  # [s] (traced: a new E never recompiles)
    density: Any  # rho [kg/m^3]
    # h0 [m]: a scalar (a uniform slab, every PST), or (n,) per particle (a slope's snow
    # cover from the terrain or a depth map, `damjax.core.model.build_slope`)
    thickness: Any
    area0: Any  # reference column-base area per particle [m^2] (1D: per unit width)
    youngs_modulus: Any
    poisson: Any
    # Modified Cam Clay slab (p0_init = inf: elastic slab)
    plastic: bool = eqx.field(static=True)  # False: skip the return mapping entirely
    p0_init: Any
    mcc_m: Any
    mcc_beta: Any
    mcc_xi: Any
    fracture_energy: Any  # slab G_f [J/m^2] of the crack-band softening (inf: none)
    # gravity [m/s^2]: slope-parallel components (dim, n) and the normal component (n,)
    g_tangent: Any
    g_normal: Any
    # weak layer
    stiffness: Any  # K_wl [Pa/m]
    tau_peak: Any  # (n,) [Pa]
    softening: Any
    u_res: Any  # (n,) residual displacement u_r [m] (inf where unbreakable)
    friction: Any  # tan(phi) [-]
    # saw
    saw_speed: Any  # [m/s]
    saw_lead: Any  # the saw stops once the crack leads it by this much [m]
    # stress invariants of the MCC yield function ("3d" or "plane", see materials.mcc)
    mcc_invariants: str = eqx.field(static=True, default="3d")
    # the particles as a regular lattice in their reference positions, x-major (particles
    # per axis), its spacing [m], and the half-width in particles of the window over which
    # the plastic opening strain is summed into a band opening [m]
    # (`damjax.materials.slab_fracture.band_opening`); () : no lattice, opening = strain x dx
    lattice: tuple[int, ...] = eqx.field(static=True, default=())
    lattice_spacing: float = eqx.field(static=True, default=0.0)
    opening_window: int = eqx.field(static=True, default=0)
    # slab fracture model (`damjax.materials.slab_fracture`): True for "crack_band" (p0
    # softens with the band opening, needs the lattice), False for "paper" (with a finite
    # G_f it softens with the opening strain x dx, one cell)
    crack_band: bool = eqx.field(static=True, default=False)
    # how P2G adds the particles' contributions (`damjax.core.transfer.p2g_channels`):
    # "fixed" (deterministic fixed point) or "float" (plain float scatter-adds)
    accumulation: str = eqx.field(static=True, default="fixed")
    # constants derived from the fields above, once when the model is built
    # (`with_constants`; `with_fields` replaces fields and derives them again): the weak
    # layer's front width [m] (n,) (`damjax.core.step.front_width`) and the crack band's
    # w_c [m] (`damjax.materials.slab_fracture.crack_band_opening`). None: derived where
    # they are used, in every step
    front_width: Any = None
    band_w_c: Any = None
    # the smallest particle mass [kg] where the thickness is per particle (None with a
    # scalar thickness: every particle weighs `mass`): the grid's empty-node threshold
    mass_ref: Any = None

    def with_constants(self) -> Model:
        """This model with `front_width`, `band_w_c` and `mass_ref` derived from its
        fields."""
        spacing = self.area0 if len(self.grid_shape) == 1 else jnp.sqrt(self.area0)
        lam = jnp.sqrt(
            self.youngs_modulus
            * self.thickness
            / ((1.0 - self.poisson * self.poisson) * self.stiffness)
        )
        w_c = mcc.crack_band_opening(
            self.p0_init, self.fracture_energy, self.mcc_m, self.mcc_beta, self.mcc_invariants
        )
        mass_ref = None if jnp.ndim(self.thickness) == 0 else jnp.min(self.mass)
        return dataclasses.replace(
            self,
            front_width=weak_layer.front_width(self.u_res, spacing, lam),
            band_w_c=w_c,
            mass_ref=mass_ref,
        )

    def with_fields(self, **changes: Any) -> Model:
        """This model with fields replaced (``u_res=...``, ``p0_init=...``; traceable) and
        the derived constants derived again: the way to change a built model."""
        derived = {"front_width", "band_w_c", "mass_ref"} & set(changes)
        if derived:
            raise ValueError(f"with_fields: {sorted(derived)} are derived, not set")
        return dataclasses.replace(self, **changes).with_constants()

    @property
    def dim(self) -> int:
        return len(self.grid_shape)

    @property
    def n_nodes(self) -> int:
        n = 1
        for s in self.grid_shape:
            n *= s
        return n

    @property
    def mass(self) -> Any:
        """Particle mass rho h0 A0 [kg] (constant: h A = h0 A0); (n,) where the thickness
        is per particle."""
        return self.density * self.thickness * self.area0


class State(eqx.Module):
    """Evolving state of a DA-MPM run."""

    u: Any  # (dim, n) displacement from the reference position = weak-layer slip [m]
    v: Any  # (dim, n) velocity [m/s]
    C: Any  # (dim, dim, n) affine velocity (APIC/MLS) [1/s]
    eps: Any  # (xx, yy, xy) rows (n,) of the in-plane small strain [-]
    sigma: Any  # (xx, yy, xy) rows (n,) of the depth-averaged in-plane stress [Pa]
    eps_p: Any  # (xx, yy, xy) rows (n,) of the in-plane plastic strain [-]
    opening: Any  # (n,) accumulated tensile plastic strain (fracture indicator) [-]
    # (n,) the part of ``opening`` along y: each increment's share n_y^2 for the direction
    # n of its largest principal plastic strain (2D; zero in 1D). `band_opening` sums the
    # x part along x and this along y, the two components of the band's jump [m]
    opening_y: Any
    t_fracture: Any  # (n,) time the band opening first reached the fracture opening [s]
    t_broken: Any  # (n,) time the weak layer under the particle lost all cohesion [s]
    u_max: Any  # (n,) maximum slip reached (damage history) [m]
    time: Any  # [s]
    saw_pos: Any  # position of the saw along saw_coord [m]
    saw_active: Any  # bool
    tip: Any  # furthest saw_coord where the layer has lost all cohesion [m]
    fault: Any  # int32 bit flags, FAULT_*
    fault_time: Any  # simulated time of the first fault [s] (nan if none)
    # (n,) bool: particles that slid out over the grid's edge (outflow: they no longer
    # interact and stay where they left). None: no outflow, a particle reaching the edge
    # is a fault (FAULT_EDGE; every PST)
    outflow: Any = None
