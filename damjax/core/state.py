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
from damjax.materials.slab import Slab
from damjax.materials.slab_fracture import Fracture
from damjax.materials.weak_layer import WeakLayer

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


class Grid(eqx.Module):
    """The background grid and the particles' reference places on it (static layout and
    (dim, n) arrays), the model's part that the transfers read (`damjax.core.transfer`)."""

    grid_shape: tuple[int, ...] = eqx.field(static=True)  # nodes per axis
    dx: float = eqx.field(static=True)  # grid spacing [m]
    periodic: tuple[bool, ...] = eqx.field(static=True)  # wrap-around axes
    cell0: Any  # (dim, n) int32 reference cell of each particle
    frac0: Any  # (dim, n) its reference position in the cell, in [0, 1)

    @property
    def dim(self) -> int:
        return len(self.grid_shape)

    @property
    def n_nodes(self) -> int:
        n = 1
        for s in self.grid_shape:
            n *= s
        return n


class Saw(eqx.Module):
    """The saw cut that starts the crack (SI units)."""

    saw_coord: Any  # (n,) distance along the saw path in the reference configuration [m]
    saw_speed: Any  # [m/s]
    saw_lead: Any  # the saw stops once the crack leads it by this much [m]
    saw_stops: bool = eqx.field(static=True)  # False: controlled cut for the whole run


class Model(eqx.Module):
    """Everything a time step needs that does not evolve (traced leaves + static layout),
    in parts that the laws take (`PARTS`): ``grid`` (`Grid`), ``slab``
    (`damjax.materials.slab.Slab`), ``fracture``
    (`damjax.materials.slab_fracture.Fracture`: MCC plasticity and tensile fracture),
    ``weak_layer`` (`damjax.materials.weak_layer.WeakLayer`) and ``saw`` (`Saw`); beside
    them the time step, gravity and how P2G adds.

    Units: SI. Per-particle arrays have shape (n,) or (dim, n). `with_fields` changes
    fields by their own names (``u_res=...``, ``p0_init=...``), whichever part holds them.
    """

    grid: Grid
    slab: Slab
    fracture: Fracture
    weak_layer: WeakLayer
    saw: Saw
    dt: Any  # [s] (traced: a new E never recompiles)
    # gravity [m/s^2]: slope-parallel components (dim, n) and the normal component (n,)
    g_tangent: Any
    g_normal: Any
    # how P2G adds the particles' contributions (`damjax.core.transfer.p2g_channels`):
    # "fixed" (deterministic fixed point) or "float" (plain float scatter-adds)
    accumulation: str = eqx.field(static=True, default="fixed")

    def with_constants(self) -> Model:
        """This model with its derived constants derived from its fields, once when the
        model is built: the weak layer's front width [m] (n,) (`WeakLayer.front_width`,
        `damjax.core.step.front_width`), the crack band's w_c [m] (`Fracture.band_w_c`,
        `damjax.materials.slab_fracture.crack_band_opening`) and the smallest particle
        mass where the thickness is per particle (`Slab.mass_ref`)."""
        slab, wl, fr = self.slab, self.weak_layer, self.fracture
        spacing = slab.area0 if self.dim == 1 else jnp.sqrt(slab.area0)
        lam = jnp.sqrt(
            slab.youngs_modulus
            * slab.thickness
            / ((1.0 - slab.poisson * slab.poisson) * wl.stiffness)
        )
        w_c = mcc.crack_band_opening(
            fr.p0_init, fr.fracture_energy, fr.mcc_m, fr.mcc_beta, fr.mcc_invariants
        )
        mass_ref = None if jnp.ndim(slab.thickness) == 0 else jnp.min(slab.mass)
        front = weak_layer.front_width(wl.u_res, spacing, lam)
        return dataclasses.replace(
            self,
            slab=dataclasses.replace(slab, mass_ref=mass_ref),
            fracture=dataclasses.replace(fr, band_w_c=w_c),
            weak_layer=dataclasses.replace(wl, front_width=front),
        )

    def with_fields(self, **changes: Any) -> Model:
        """This model with fields replaced by their own names, whichever part holds them
        (``u_res=...``, ``p0_init=...``, ``dt=...``; traceable), and the derived constants
        derived again: the way to change a built model."""
        derived = set(DERIVED) & set(changes)
        if derived:
            raise ValueError(f"with_fields: {sorted(derived)} are derived, not set")
        unknown = set(changes) - set(PART_OF) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise TypeError(f"with_fields: {sorted(unknown)} are not fields of the model")
        top = {k: v for k, v in changes.items() if k not in PART_OF}
        for part in PARTS:
            kw = {k: v for k, v in changes.items() if PART_OF.get(k) == part}
            if kw:
                top[part] = dataclasses.replace(top.get(part, getattr(self, part)), **kw)
        return dataclasses.replace(self, **top).with_constants()

    @property
    def dim(self) -> int:
        return self.grid.dim

    @property
    def n_nodes(self) -> int:
        return self.grid.n_nodes

    @property
    def mass(self) -> Any:
        """Particle mass rho h0 A0 [kg] (`Slab.mass`)."""
        return self.slab.mass


# the model's parts and their classes, and the part that holds each field (`with_fields`)
PARTS = {"grid": Grid, "slab": Slab, "fracture": Fracture, "weak_layer": WeakLayer, "saw": Saw}
PART_OF = {f.name: part for part, cls in PARTS.items() for f in dataclasses.fields(cls)}
DERIVED = ("front_width", "band_w_c", "mass_ref")  # set by `Model.with_constants`


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
