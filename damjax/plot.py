"""Matplotlib figures of PST results (paper Figs. 3, 4 and 8 style)."""

from __future__ import annotations

from typing import Any

import numpy as np

from damjax import diagnostics, theory


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def plot_pst(result: Any, path: str | None = None) -> Any:
    """Three panels: weak-layer strength, slab tension profile, crack speed over x.

    Returns the matplotlib Figure; writes it to ``path`` when given.
    """
    plt = _plt()
    p, s = result.params, result.setup
    cs = float(theory.shear_wave_speed(p))
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True, constrained_layout=True)

    ax = axes[0]
    tau_r = float(theory.residual_shear(p))
    if np.all(np.isfinite(result.tau_peak)):
        ax.plot(result.x, result.tau_peak, "k-", label=r"strength $\tau_p$")
        ax.plot(result.x, result.tau_peak - tau_r, "k:", label=r"cohesion $\tau_p-\tau_r$")
    ax.plot(result.x, result.wl_shear, color="tab:green", lw=0.8,
            label=r"weak-layer shear $\tau_{xz}$ (final)")
    ax.axhline(float(theory.gravity_shear(p)), color="tab:blue", ls="--", label=r"$\tau_g$")
    ax.set_ylabel("shear stress [Pa]")
    ax.legend(loc="upper left", fontsize=8)

    ax = axes[1]
    snaps = result.snapshots
    if snaps and snaps["sigma_xx"].shape[-1] == result.x.size:
        n = len(snaps["time"])
        for k in range(0, n, max(1, n // 8)):
            ax.plot(
                result.x,
                snaps["sigma_xx"][k],
                color=plt.cm.viridis(k / max(1, n - 1)),
                lw=0.8,
                label=f"t = {snaps['time'][k]:.2f} s",
            )
    ax.plot(result.x, result.sigma_xx, "k-", lw=1.2, label="final")
    st = float(p.tensile_strength)
    if np.isfinite(st):
        from damjax.materials import mcc

        p0 = mcc.p0_from_tensile_strength(st, float(p.mcc_m), float(p.mcc_beta), s.p0_rule)
        st_eff = float(mcc.uniaxial_strengths(p0, float(p.mcc_m), float(p.mcc_beta))[0])
        ax.axhline(st, color="tab:red", ls="--", label=r"$\sigma_t$")
        if abs(st_eff - st) > 1e-3 * st:
            ax.axhline(st_eff, color="tab:red", ls=":", label="uniaxial yield")
    ax.set_ylabel(r"slab tension $\sigma_{xx}$ [Pa]")
    ax.legend(loc="upper left", fontsize=7, ncol=2)

    ax = axes[2]
    speed = diagnostics.crack_speed(result.time, result.tip)
    ax.plot(result.tip, speed / cs, "tab:orange")
    ax.axhline(1.6, color="k", ls="--", lw=0.8, label=r"$1.6\,c_s$")
    for frac in result.summary.get("slab_fractures", []):
        for a in axes:
            a.axvline(frac["x_m"], color="k", ls=":", lw=0.8)
    if result.summary.get("arrested"):
        ax.axvline(
            result.summary["arrest_position_m"],
            color="tab:red",
            lw=0.8,
            label=f"arrest {result.summary['arrest_position_m']:.1f} m",
        )
    if not s.controlled:
        ax.axvline(float(p.steady_length), color="gray", lw=0.6, ls="-.", label=r"$L_{ss}$")
    ax.set_ylabel(r"crack speed $\dot a / c_s$")
    ax.set_xlabel("x along the PST [m]")
    ax.set_xlim(0, s.length)
    ax.legend(loc="upper right", fontsize=8)
    fig.suptitle(
        f"PST: theta = {float(p.strength_gradient):g} Pa/m, delta = {float(p.softening):g}, "
        f"E = {float(p.youngs_modulus) / 1e6:g} MPa, lateral = {s.lateral}"
    )
    if path:
        fig.savefig(path, dpi=120)
    return fig
