"""Matplotlib figures of PST results (paper Figs. 3, 4 and 8 style)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from damjax import diagnostics, io, theory


def _plt() -> Any:
    import os
    import sys

    import matplotlib

    # a file backend for scripts and the CLI, but never switch a backend already chosen:
    # in Jupyter (MPLBACKEND is set by the kernel, or pyplot already imported) that would
    # silently turn off inline figures for the rest of the session
    chosen_by = getattr(matplotlib.rcParams, "_get_backend_or_none", lambda: None)
    if (
        "matplotlib.pyplot" not in sys.modules
        and not os.environ.get("MPLBACKEND")
        and chosen_by() is None
    ):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_pst(result: Any, path: str | None = None) -> Any:
    """Three panels: weak-layer strength, slab tension profile, crack speed over x.

    Returns the matplotlib Figure; writes it to ``path`` when given (its format from the
    suffix, checked before drawing).
    """
    from damjax.pst import PSTResult, one_run_only

    _expect("plot_pst", result, PSTResult, "damjax.runner.load_result(RUN_DIR or FILE)")
    if not isinstance(result.tip, np.ndarray):
        raise TypeError(one_run_only("plot_pst"))
    _check_path("plot_pst", path)
    plt = _plt()
    p, s = result.params, result.setup
    cs = float(theory.shear_wave_speed(p))
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    # fixed margins: a layout engine draws the figure once more (0.25 s of a 0.6 s figure)
    fig.subplots_adjust(left=0.11, right=0.97, bottom=0.06, top=0.95, hspace=0.08)

    ax = axes[0]
    tau_r = float(theory.residual_shear(p))
    if np.all(np.isfinite(result.tau_peak)):
        ax.plot(result.x, result.tau_peak, "k-", label=r"strength $\tau_p$")
        ax.plot(result.x, result.tau_peak - tau_r, "k:", label=r"cohesion $\tau_p-\tau_r$")
    ax.plot(
        result.x,
        result.wl_shear,
        color="tab:green",
        lw=0.8,
        label=r"weak-layer shear $\tau_{xz}$ (final)",
    )
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

        inv = getattr(s, "mcc_invariants", "3d")
        p0 = mcc.p0_from_tensile_strength(st, float(p.mcc_m), float(p.mcc_beta), s.p0_rule, inv)
        st_eff = float(mcc.uniaxial_strengths(p0, float(p.mcc_m), float(p.mcc_beta), inv)[0])
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


def _expect(fn: str, result: Any, cls: type, read: str) -> None:
    """TypeError unless ``result`` is a ``cls``: a Dataset read from a file is named with
    the function ``read`` that rebuilds the result from its folder or file."""
    if isinstance(result, cls):
        return
    kind = type(result).__name__
    hint = ""
    if kind == "Dataset":
        hint = f" (a Dataset read from a results file: rebuild the result with {read})"
    raise TypeError(f"{fn} takes a damjax.{cls.__name__}, got {kind}{hint}")


def _check_path(fn: str, path: Any, gif: bool = False) -> None:
    """The output path checked before drawing (`damjax.io.check_figure_path`; ``gif``: an
    animation's .gif) and its folder made."""
    if path is None or path == "":
        return
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{fn}: path must be a file name (str or Path), got {type(path).__name__}")
    if gif:
        if not str(path).lower().endswith(".gif"):
            raise ValueError(f"{fn}: path {path}: must end in .gif (an animated GIF)")
        io.check_figure_path(str(path)[:-4] + ".png", field=f"{fn}: path")  # its folder
    else:
        io.check_figure_path(path, field=f"{fn}: path")
    Path(path).parent.mkdir(parents=True, exist_ok=True)


def plot_slope(result: Any, path: str | None = None) -> Any:
    """Maps of a slope-scale release: column height with the crown (h < 0.98 h0, blue)
    and the stauchwall (h > 1.02 h0, red), crack arrival time [s], local crack speed
    over c_s (`damjax.slope.results.crack_speed_map`; its colour bar runs from 0 to the
    slab's wave speed, the most a front can run, and cells that failed together, which
    have no front speed, are cyan), weak-layer strength [Pa]. The title says what the
    fronts did (`slope_outcome`)."""
    from damjax.slope.simulation import SlopeResult

    _expect("plot_slope", result, SlopeResult, "damjax.slope.results.load_result(FILE)")
    _check_path("plot_slope", path)
    plt = _plt()
    from matplotlib.colors import ListedColormap

    from damjax.slope.simulation import initial_thickness

    h0 = initial_thickness(result)
    ext = [result.y[0], result.y[-1], result.x[0], result.x[-1]]
    fig, axes = plt.subplots(1, 4, figsize=(17, 5.5), constrained_layout=True)
    ax = axes[0]
    broken = np.isfinite(result.arrival_time)
    ax.imshow(
        broken,
        origin="lower",
        extent=ext,
        cmap=ListedColormap(["white", "0.85"]),
        vmin=0,
        vmax=1,
        aspect="equal",
    )
    marks = np.zeros(result.height.shape)
    marks[result.height < 0.98 * h0] = -1
    marks[result.height > 1.02 * h0] = 1
    masked = np.ma.masked_where(marks == 0, marks)
    ax.imshow(
        masked,
        origin="lower",
        extent=ext,
        cmap=ListedColormap(["tab:blue", "tab:red"]),
        vmin=-1,
        vmax=1,
        aspect="equal",
    )
    x0, y0 = result.setup.start
    ax.plot([y0], [x0], "k*", ms=12)
    ax.set_title("released (grey), crown h<0.98h0 (blue),\nstauchwall h>1.02h0 (red)", fontsize=9)
    ax.set_xlabel("y across [m]")
    ax.set_ylabel("x up-slope [m]")
    ax = axes[1]
    t = np.where(broken, result.arrival_time, np.nan)
    im = ax.imshow(t, origin="lower", extent=ext, cmap="viridis", aspect="equal")
    fig.colorbar(im, ax=ax, shrink=0.8, label="crack arrival time [s]")
    ax.plot([y0], [x0], "k*", ms=12)
    ax.set_xlabel("y across [m]")
    ax = axes[2]
    from damjax.slope.results import (
        crack_speed_map,
        front_speed_limit,
        simultaneous_failure_map,
    )

    cs = float(theory.shear_wave_speed(result.params))
    limit = front_speed_limit(result.params) / cs
    # the map holds no value above the slab's wave speed (cells that failed together
    # have no front speed: drawn apart), so the colour bar spans the true range
    im = ax.imshow(
        crack_speed_map(result) / cs,
        origin="lower",
        extent=ext,
        cmap="plasma",
        vmin=0.0,
        vmax=limit,
        aspect="equal",
    )
    together = simultaneous_failure_map(result)
    if together.any():
        ax.imshow(
            np.ma.masked_where(~together, together),
            origin="lower",
            extent=ext,
            cmap=ListedColormap(["tab:cyan"]),
            vmin=0,
            vmax=1,
            aspect="equal",
        )
    fig.colorbar(im, ax=ax, shrink=0.8, label=r"local crack speed / $c_s$")
    ax.set_title(
        f"crack speed, 0 to the slab's wave speed {limit:.2f} $c_s$;\n"
        f"cyan: failed together, no front ({100 * together.mean():.1f} % of the area)",
        fontsize=9,
    )
    ax.plot([y0], [x0], "k*", ms=12)
    ax.set_xlabel("y across [m]")
    ax = axes[3]
    im = ax.imshow(result.tau_peak, origin="lower", extent=ext, cmap="magma", aspect="equal")
    fig.colorbar(im, ax=ax, shrink=0.8, label=r"weak-layer strength $\tau_p$ [Pa]")
    ax.contour(result.y, result.x, result.slope_deg, colors="w", linewidths=0.6)
    ax.set_xlabel("y across [m]")
    ax.set_title("strength, slope-angle contours (white)", fontsize=9)
    s = result.summary

    def num(key: str, fmt: str) -> str:
        v = s.get(key)
        return "n/a" if v is None or not np.isfinite(v) else format(v, fmt)

    def speed(d: str) -> str:
        # the peak needs a 4 m stretch of front; a short run has only the whole-run mean
        if s.get(f"{d}_crack_speed_over_cs") is not None:
            return f"{num(f'{d}_crack_speed_over_cs', '.2f')} $c_s$"
        if s.get(f"{d}_crack_speed_mean_over_cs") is not None:
            return f"{num(f'{d}_crack_speed_mean_over_cs', '.2f')} $c_s$ (mean)"
        return "n/a"

    fig.suptitle(
        f"{slope_outcome(s)}\nrelease area {num('release_area_m2', '.0f')} m$^2$, up-slope "
        f"speed {speed('upslope')}, cross-slope {speed('crossslope')}"
    )
    if path:
        fig.savefig(path, dpi=110)
    return fig


def slope_outcome(summary: dict[str, Any]) -> str:
    """One line saying what the fronts of a slope run did (`SlopeResult.summary`):
    arrested where and how far from the start, reached an edge, or still moving at the
    end (at what speed). Summaries of older versions (without the front states) get the
    up-slope front only."""
    s = summary
    if not isinstance(s, dict):
        kind = type(s).__name__
        raise TypeError(f"slope_outcome takes a slope run's summary (a dict), got {kind}")
    if not {"upslope_front", "arrested_before_top", "upslope_extent_m"} & set(s):
        raise ValueError(
            "slope_outcome: not a slope run's summary (none of upslope_front, "
            "arrested_before_top, upslope_extent_m: a SlopeResult's .summary)"
        )

    def dist(key: str) -> str:
        v = s.get(key)
        return "n/a" if v is None else f"{v:.1f} m"

    def end_speed(key: str) -> str:
        v = s.get(key)
        return "" if v is None else f" at {v:.2f} $c_s$"

    up = s.get("upslope_front")
    if up is None:  # a summary without the states
        up = "arrested" if s.get("arrested_before_top") else "moving"
    if up == "sawn_only":
        return "the crack never ran ahead of the saw: the release is the cut"
    parts = []
    if up == "arrested":
        parts.append(f"up-slope arrest {dist('upslope_arrest_distance_m')} from the start")
    elif up == "reached_edge":
        parts.append("up-slope: reached the top edge")
    else:
        parts.append(
            "up-slope front still moving at the end"
            f"{end_speed('upslope_front_end_speed_over_cs')} "
            f"({dist('upslope_extent_m')} from the start)"
        )
    cross = s.get("crossslope_front")
    if cross == "arrested":
        parts.append(f"cross-slope arrest {dist('crossslope_arrest_distance_m')} from the start")
    elif cross == "reached_edge":
        parts.append("across: reached the side edges")
    elif cross == "moving":
        parts.append(
            "cross-slope front still moving at the end"
            f"{end_speed('crossslope_front_end_speed_over_cs')} "
            f"({dist('crossslope_extent_m')} from the start)"
        )
    return "; ".join(parts)


def animate_slope(result: Any, path: str, fps: int = 8) -> None:
    """GIF of the release: released weak layer (grey) and column height anomalies."""
    from damjax.slope.simulation import SlopeResult

    _expect("animate_slope", result, SlopeResult, "damjax.slope.results.load_result(FILE)")
    if not result.snapshots:
        raise ValueError("animate_slope: the result has no snapshots (a run without them)")
    _check_path("animate_slope", path, gif=True)
    plt = _plt()
    from matplotlib.animation import FuncAnimation, PillowWriter

    from damjax.slope.simulation import initial_thickness

    snaps = result.snapshots
    h0 = initial_thickness(result)
    h0 = np.where(h0 > 0, h0, np.nan)  # no snow: no anomaly
    ext = [result.y[0], result.y[-1], result.x[0], result.x[-1]]
    fig, ax = plt.subplots(figsize=(5, 5.5), constrained_layout=True)
    im = ax.imshow(
        snaps["height"][0] / h0 - 1,
        origin="lower",
        extent=ext,
        cmap="RdBu_r",
        vmin=-0.03,
        vmax=0.03,
        aspect="equal",
    )
    cover = ax.imshow(
        np.ma.masked_where(snaps["broken"][0] < 0.5, snaps["broken"][0]),
        origin="lower",
        extent=ext,
        cmap="Greys",
        alpha=0.35,
        vmin=0,
        vmax=2,
        aspect="equal",
    )
    fig.colorbar(im, ax=ax, shrink=0.8, label="h / h0 - 1")
    title = ax.set_title("")

    def frame(k: int) -> list[Any]:
        im.set_data(snaps["height"][k] / h0 - 1)
        b = snaps["broken"][k]
        cover.set_data(np.ma.masked_where(b < 0.5, b))
        title.set_text(f"t = {snaps['time'][k]:.2f} s")
        return [im, cover, title]

    anim = FuncAnimation(fig, frame, frames=len(snaps["time"]), blit=False)
    anim.save(path, writer=PillowWriter(fps=fps))
    plt.close(fig)
