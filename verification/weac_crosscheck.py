"""Critical cut length: damjax against weac, the analytic layered-slab model, on the same slab.

weac (Rosendahl and Weissgraeber 2020, The Cryosphere 14; ``pip install 'weac<3'``) models
a PST as a Timoshenko beam (the slab, plane strain) on an elastic foundation (the weak
layer, shear and normal springs) and finds the critical cut length where the energy
release rate of the cut reaches the weak layer's toughness. damjax's quasi-static a_c
(`damjax.theory.critical_cut_length`) is a bar on shear springs whose weak layer fails at
tau_p; its PST simulation measures a_c as the saw position when the crack runs ahead of
the saw.

Matched inputs, for every row:

- the same slab (h, rho, E, nu) and weak layer: weac's t = D_wl and E_wl = 2 (1 + nu_wl)
  G_wl (nu_wl = 0.25, weac's default), so weac's shear stiffness k_t = G_wl / D_wl = K;
- E in weac set directly (not from its density relation); damjax with
  ``lateral = "constrained"`` (E / (1 - nu^2)), weac's plane-strain slab;
- toughness G_IIc = tau_p^2 / (2 K) for the brittle law (delta = 0): weac's mode II
  energy release rate at the tip is tau_tip^2 / (2 k_t), so the two criteria are the same
  stress criterion tau_tip = tau_p and the rows compare the tip stresses of the two
  mechanical models;
- no friction on the cut: weac's cut slab hangs free, damjax's friction angle is 0.01 deg
  (the smallest the validation takes, tau_r ~ 0);
- weac's cut at the downslope end of the column (``pst-`` with phi = -psi: the cut slab
  hangs below the intact one and pulls on it, as in damjax's PST), and for comparison at
  the upslope end (phi = +psi), where the cut slab pushes;
- tau_p = 1500 Pa (above tau_g = 1125 Pa of the thickest slab), column 30 lambda + 10 m.

One JSON line per row, then a markdown table:

    python -m verification.weac_crosscheck > results/weac_crosscheck.jsonl

Measured (2026-11-25, 2 shared CPU cores, weac 2.6.4): docs/verification/weac.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
import warnings
from typing import Any

import damjax
from damjax import theory

NU_WL = 0.25  # weac's weak-layer Poisson ratio (only its normal stiffness depends on it)
TAU_PEAK = 1500.0  # [Pa]
FRICTION_DEG = 0.01  # ~ frictionless cut (the validation needs friction_deg > 0)
# one parameter at a time around damjax's baseline slab (h 0.5 m, E 4 MPa, 35 deg)
GRID: tuple[dict[str, float], ...] = (
    {},
    {"thickness": 0.2},
    {"thickness": 0.3},
    {"thickness": 0.8},
    {"youngs_modulus": 1.0e6},
    {"youngs_modulus": 16.0e6},
    {"slope_deg": 30.0},
    {"slope_deg": 40.0},
)


def matched_params(**changes: float) -> damjax.PSTParams:
    """damjax's baseline slab with tau_p 1500 Pa, a frictionless cut and ``changes``."""
    base = damjax.PSTParams(tau_peak=TAU_PEAK, friction_deg=FRICTION_DEG, softening=0.0)
    return dataclasses.replace(base, **changes)


def weac_model(p: damjax.PSTParams) -> Any:
    """A weac ``pst-`` model of the slab and weak layer of ``p`` (units: mm, N, MPa)."""
    import weac

    m = weac.Layered(system="pst-", layers=[[float(p.density), float(p.thickness) * 1e3]])
    e_mpa, nu = float(p.youngs_modulus) / 1e6, float(p.poisson)
    m.slab[:, 2] = e_mpa  # Young's modulus, set directly instead of weac's E(rho)
    m.slab[:, 3] = e_mpa / (2.0 * (1.0 + nu))
    m.slab[:, 4] = nu
    m.set_foundation_properties(
        t=float(p.wl_thickness) * 1e3,
        E=2.0 * (1.0 + NU_WL) * float(p.wl_shear_modulus) / 1e6,
        nu=NU_WL,
        update=True,
    )
    return m


def weac_err(m: Any, a: float, phi: float, column: float) -> tuple[float, float, float]:
    """weac's (G, G_I, G_II) [J/m^2] of a cut ``a`` [m] in a column ``column`` [m] long."""
    segs = m.calc_segments(L=column * 1e3, a=a * 1e3)["crack"]
    c = m.assemble_and_solve(phi=phi, **segs)
    g, g1, g2 = m.gdif(c, phi, **segs, unit="J/m^2")
    return float(g), float(g1), float(g2)


def weac_critical_cut(
    p: damjax.PSTParams, downslope: bool = True, column: float | None = None
) -> dict[str, float]:
    """weac's critical cut length where G_II = G_IIc = tau_p^2 / (2 K) [m] (NaN if G_II
    stays below it up to 20 lambda + 5 m), with G_I / G_II there and the tip shear stress
    of the uncut column sqrt(2 K G_II(0)) [Pa]."""
    from scipy.optimize import brentq

    m = weac_model(p)
    k = float(p.wl_shear_modulus) / float(p.wl_thickness)
    g_c = float(p.tau_peak) ** 2 / (2.0 * k)
    lam = float(theory.bar_length(p, "constrained"))
    column = column if column is not None else 30.0 * lam + 10.0
    phi = -float(p.slope_deg) if downslope else float(p.slope_deg)
    a0, a1 = 1e-3, 20.0 * lam + 5.0

    def excess(a: float) -> float:
        return weac_err(m, a, phi, column)[2] - g_c

    if excess(a0) >= 0.0 or excess(a1) <= 0.0:
        a_c = math.nan
        mix = math.nan
    else:
        a_c = float(brentq(excess, a0, a1, xtol=1e-6))
        _, g1, g2 = weac_err(m, a_c, phi, column)
        mix = g1 / g2
    edge = math.sqrt(2.0 * k * weac_err(m, a0, phi, column)[2])
    return {"a_c": a_c, "mode_ratio": mix, "edge_tau": edge, "g_c": g_c}


def damjax_simulated_cut(p: damjax.PSTParams) -> tuple[float | None, float]:
    """damjax's PST a_c [m] (saw position when the crack runs ahead of the saw) on a
    uniform weak layer, dx = lambda / 10, and the wall time [s]."""
    a_th = float(theory.critical_cut_length(p, "constrained"))
    lam = float(theory.bar_length(p, "constrained"))
    length = float(round(max(4.0, 2.0 * a_th + 3.0)))
    q = dataclasses.replace(p, steady_length=length - 0.5, strength_gradient=0.0)
    setup = damjax.PSTSetup(
        length=length, dx=lam / 10.0, duration=a_th / float(p.saw_speed) + 0.4,
        lateral="constrained",
    )  # fmt: skip
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the frictionless cut is a "dubious" value
        r = damjax.simulate_pst(q, setup, progress=False)
    return r.summary["critical_cut_length_m"], time.perf_counter() - t0


def row(changes: dict[str, float], simulate: bool = True) -> dict[str, Any]:
    """One row of the table: inputs, damjax's theory and simulated a_c, weac's a_c."""
    p = matched_params(**changes)
    down = weac_critical_cut(p, downslope=True)
    up = weac_critical_cut(p, downslope=False)
    sim, wall = damjax_simulated_cut(p) if simulate else (None, 0.0)
    return {
        "benchmark": "weac_crosscheck",
        "thickness_m": float(p.thickness),
        "youngs_modulus_pa": float(p.youngs_modulus),
        "slope_deg": float(p.slope_deg),
        "tau_peak_pa": float(p.tau_peak),
        "tau_g_pa": float(theory.gravity_shear(p)),
        "lambda_m": float(theory.bar_length(p, "constrained")),
        "g_iic_j_m2": down["g_c"],
        "damjax_theory_a_c_m": float(theory.critical_cut_length(p, "constrained")),
        "damjax_sim_a_c_m": sim,
        "weac_a_c_m": down["a_c"],
        "weac_upslope_cut_a_c_m": up["a_c"],
        "weac_mode_ratio_gi_gii": down["mode_ratio"],
        "weac_edge_tau_pa": down["edge_tau"],
        "damjax_sim_wall_s": wall,
    }


def _f(v: Any, nd: int = 2) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{nd}f}"


def table(rows: list[dict[str, Any]]) -> str:
    """The rows as a markdown table."""
    out = [
        "| h [m] | E [MPa] | psi [deg] | tau_g [Pa] | lambda [m] | damjax a_c theory [m] "
        "| damjax a_c PST [m] | weac a_c [m] | weac / damjax theory | weac a_c, upslope "
        "cut [m] | weac G_I/G_II at a_c | weac tip tau, uncut [Pa] |",
        "|" + "---|" * 12,
    ]
    for r in rows:
        ratio = r["weac_a_c_m"] / r["damjax_theory_a_c_m"]
        out.append(
            f"| {r['thickness_m']:.1f} | {r['youngs_modulus_pa'] / 1e6:.0f} "
            f"| {r['slope_deg']:.0f} | {r['tau_g_pa']:.0f} | {r['lambda_m']:.2f} "
            f"| {_f(r['damjax_theory_a_c_m'])} | {_f(r['damjax_sim_a_c_m'])} "
            f"| {_f(r['weac_a_c_m'])} | {_f(ratio)} | {_f(r['weac_upslope_cut_a_c_m'])} "
            f"| {_f(r['weac_mode_ratio_gi_gii'])} | {r['weac_edge_tau_pa']:.0f} |"
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-sim", action="store_true", help="skip the damjax PST runs")
    args = ap.parse_args(argv)
    rows = []
    for changes in GRID:
        r = row(changes, simulate=not args.no_sim)
        rows.append(r)
        print(json.dumps(r), flush=True)
    sys.stderr.write(table(rows) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
