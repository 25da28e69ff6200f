"""Figures of the documentation: ``python -m verification.figures`` draws every PNG under
``docs/images/`` (about 5 min on 2 CPU cores).

    python -m verification.figures                  # all of them
    python -m verification.figures pst_elastic      # some (names: --list)

Each figure is damjax's version of a paper figure or of a user-guide plot, drawn from the
rows already stored in ``results/`` where they exist, and otherwise from small runs whose
size (dx, length, duration) the figure states. The paper's values are marked where the
paper gives numbers. Every figure carries a footer with the command, the date and the
commit it was drawn at, and ``docs/images/figures.json`` records the same with each
figure's run time.
"""

from __future__ import annotations

import datetime
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from benchmarks.cases import git_commit

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "images"
COMMAND = "python -m verification.figures"
DPI = 100
WIDTH = 8.0  # [in] at DPI 100: 800 px, the width of a page's text column
FIGURES: dict[str, Callable[[], str]] = {}


def figure(fn: Callable[[], str]) -> Callable[[], str]:
    FIGURES[fn.__name__] = fn
    return fn


STAMP = {
    "command": COMMAND,
    "date": datetime.date.today().isoformat(),
    "commit": git_commit() or "unknown",
}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 9, "axes.titlesize": 9, "legend.fontsize": 8})
    return plt


def _save(fig, name: str, note: str) -> str:
    """Footer (command, date, commit, what was run), PNG at DPI under docs/images."""
    fig.text(
        0.01,
        0.005,
        f"{COMMAND} ({name}); {STAMP['date']}, commit {STAMP['commit']}; {note}",
        fontsize=6.5,
        color="0.35",
        ha="left",
        va="bottom",
    )
    path = OUT / f"{name}.png"
    fig.savefig(path, dpi=DPI)
    _plt().close(fig)
    return note


def _rows(path: str | Path) -> list[dict]:
    with open(ROOT / path) as fh:
        return [json.loads(line) for line in fh if line.strip()]


def _quiet() -> None:
    warnings.filterwarnings("ignore")


# --------------------------------------------------------------------------- verification


@figure
def pst_kx() -> str:
    """k_x against Appendix A (controlled sawing, free and constrained), small runs."""
    from damjax import PSTParams, PSTSetup, simulate_pst, theory

    plt = _plt()
    p = PSTParams()
    cs = float(theory.shear_wave_speed(p))
    dx = 0.05
    ratios = np.linspace(0.0, 1.6, 81)
    fig, ax = plt.subplots(figsize=(WIDTH, 3.6))
    fig.subplots_adjust(left=0.09, right=0.98, top=0.92, bottom=0.2)
    for lateral, color in (("free", "tab:blue"), ("constrained", "tab:orange")):
        kth = [float(theory.dynamic_gradient(p, r * cs, lateral)) for r in ratios]
        ax.plot(ratios, kth, color=color, lw=1.2, label=f"Appendix A, {lateral}")
        meas = []
        for r in (0.2, 0.8, 1.4):
            setup = PSTSetup(
                controlled=True, lateral=lateral, dx=dx, duration=min(3.0, 80 / (r * cs))
            )
            res = simulate_pst(PSTParams(saw_speed=r * cs), setup)
            meas.append(res.summary["tension_gradient_pa_per_m"])
        ax.plot(
            (0.2, 0.8, 1.4),
            meas,
            "o",
            color=color,
            mfc="none",
            ms=8,
            label=f"damjax, {lateral} (dx {dx} m)",
        )
    ax.axhline(
        float(theory.quasi_static_gradient(p)),
        color="0.5",
        ls=":",
        lw=0.8,
        label="quasi-static k_f",
    )
    ax.set_xlabel(r"cut speed $\dot a / c_s$")
    ax.set_ylabel(r"tension gradient $k_x$ [Pa/m]")
    ax.set_title("Controlled sawing: slab tension gradient behind the cut (paper Fig. 3, App. A)")
    ax.legend(ncol=2)
    return _save(fig, "pst_kx", f"controlled runs: 100 m PST, dx {dx} m, float32")


@figure
def pst_elastic() -> str:
    """Elastic self-propagating PSTs: crack tip and speed, paper's arrests marked."""
    from damjax import PSTParams, PSTSetup, diagnostics, simulate_pst, theory

    plt = _plt()
    dx = 0.05
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(WIDTH, 3.6))
    fig.subplots_adjust(left=0.08, right=0.98, top=0.85, bottom=0.2, wspace=0.25)
    targets = {0.0: 62.0, 2.0: 35.0}
    colors = {0.0: "tab:blue", 2.0: "tab:green"}
    for delta, target in targets.items():
        p = PSTParams(softening=delta)
        cs = float(theory.shear_wave_speed(p))
        r = simulate_pst(p, PSTSetup(dx=dx))
        c = colors[delta]
        ax0.plot(r.time, r.tip, color=c, label=f"delta {delta:g}: arrest {r.arrest_position:.1f} m")
        ax0.axhspan(0.9 * target, 1.1 * target, color=c, alpha=0.15, lw=0)
        ax0.axhline(target, color=c, ls="--", lw=0.8)
        speed = diagnostics.crack_speed(r.time, r.tip) / cs
        ax1.plot(r.tip, speed, color=c, lw=1, label=f"delta {delta:g}")
        ax1.axvspan(0.9 * target, 1.1 * target, color=c, alpha=0.15, lw=0)
    ax0.plot([], [], "k--", lw=0.8, label="paper: 62 m / 35 m, band +-10 %")
    ax0.set_xlabel("time [s]")
    ax0.set_ylabel("crack tip [m]")
    ax0.set_title("Crack tip over time")
    ax0.legend(loc="lower right")
    ax1.axhline(1.6, color="k", ls="--", lw=0.8, label=r"paper: ~1.6 $c_s$")
    ax1.set_xlabel("crack tip [m]")
    ax1.set_ylabel(r"crack speed $\dot a / c_s$")
    ax1.set_xlim(0, 100)
    ax1.set_ylim(0, 2)
    ax1.set_title("Crack speed along the PST (paper Fig. 4)")
    ax1.legend(loc="lower left")
    fig.suptitle("Elastic PST baseline: theta 500 Pa/m, L_ss 20 m, E 4 MPa, free strip", y=0.99)
    return _save(fig, "pst_elastic", f"100 m PST, dx {dx} m, 3 s, float32")


@figure
def plastic() -> str:
    """Elasto-plastic PSTs (Fig. 8): theta 150 and 30, slab_fracture='paper'."""
    from damjax import PSTParams, PSTSetup, simulate_pst

    plt = _plt()
    dx = 0.05
    fig, axes = plt.subplots(1, 2, figsize=(WIDTH, 3.6))
    fig.subplots_adjust(left=0.08, right=0.98, top=0.86, bottom=0.2, wspace=0.25)
    for ax, theta, target in ((axes[0], 150.0, 34.0), (axes[1], 30.0, 94.0)):
        p = PSTParams(tensile_strength=6000.0, strength_gradient=theta, softening=0.0)
        r = simulate_pst(p, PSTSetup(dx=dx, slab_fracture="paper"))
        s = r.summary
        end = f"arrest {s['arrest_position_m']:.1f} m" if s.get("arrested") else "no arrest"
        ax.plot(r.time, r.tip, "tab:blue", label=f"damjax: {end}")
        ax.axhline(target, color="tab:red", ls="--", lw=1, label=f"paper: arrest {target:g} m")
        fx = [f["x_m"] for f in s.get("slab_fractures", [])]
        ft = [f.get("t_s", np.nan) for f in s.get("slab_fractures", [])]
        if fx:
            ax.plot(ft, fx, "kx", ms=7, label=f"slab fractures ({len(fx)})")
        ax.set_title(f"theta {theta:g} Pa/m")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("crack tip [m]")
        ax.set_ylim(0, 102)
        ax.legend(loc="lower right")
    fig.suptitle(
        "Elasto-plastic slab (sigma_t 6 kPa, delta 0, L_ss 20 m, free), "
        'slab_fracture="paper" (paper Fig. 8)',
        y=0.99,
    )
    return _save(fig, "plastic", f"100 m PST, dx {dx} m, 3 s, float32")


@figure
def fig9() -> str:
    """A_ca against theta and sigma_t (Fig. 9), one vmapped sweep per curve."""
    import jax.numpy as jnp

    from damjax import PSTParams, PSTSetup, sweep

    plt = _plt()
    dx = 0.05
    setup = PSTSetup(dx=dx, slab_fracture="paper")
    base = dict(tensile_strength=6000.0, softening=1.0, steady_length=20.0)
    thetas = np.array([20.0, 30.0, 50.0, 100.0, 150.0, 300.0, 1000.0])
    res = sweep(PSTParams(**base, strength_gradient=jnp.asarray(thetas)), setup)

    def aca(r):
        return r.summary["arrest_position_m"] - 20.0 if r.summary.get("arrested") else np.nan

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(WIDTH, 3.6))
    fig.subplots_adjust(left=0.09, right=0.98, top=0.86, bottom=0.2, wspace=0.28)
    a = np.array([aca(r) for r in res])
    nf = [len(r.summary.get("slab_fractures", [])) for r in res]
    ax0.loglog(thetas, a, "o-", color="tab:blue", label="damjax")
    for t, v, n in zip(thetas, a, nf, strict=True):
        if np.isfinite(v):
            ax0.annotate(str(n), (t, v), textcoords="offset points", xytext=(4, 4), fontsize=7)
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    ax0.set_yticks([2, 5, 10, 20, 50])
    for axis in (ax0.xaxis, ax0.yaxis):
        axis.set_major_formatter(ScalarFormatter())
        axis.set_minor_formatter(NullFormatter())
    ax0.set_xlabel(r"strength gradient $\theta$ [Pa/m]")
    ax0.set_ylabel(r"$A_{ca} = L_{ca} - L_{ss}$ [m]")
    ax0.set_title("A_ca against theta (labels: slab fractures)")
    ax0.legend()
    sig = np.array([2000.0, 4000.0, 6000.0, 8000.0, 10000.0])
    for theta, c in ((50.0, "tab:green"), (300.0, "tab:purple")):
        kw = dict(base, tensile_strength=jnp.asarray(sig), strength_gradient=theta)
        rs = sweep(PSTParams(**kw), setup)
        ax1.plot(sig / 1e3, [aca(r) for r in rs], "o-", color=c, label=f"theta {theta:g} Pa/m")
    ax1.set_xlabel(r"slab tensile strength $\sigma_t$ [kPa]")
    ax1.set_ylabel(r"$A_{ca}$ [m]")
    ax1.set_title("A_ca against sigma_t")
    ax1.legend()
    fig.suptitle(
        'Fig. 9-like sweep: sigma_t 6 kPa, delta 1, L_ss 20 m, E 4 MPa, slab_fracture="paper"',
        y=0.99,
    )
    return _save(fig, "fig9", f"100 m PSTs, dx {dx} m, 3 s, float32 (the page's table: 0.04 m)")


@figure
def inversion() -> str:
    """Inversion: the stored brittle descents, and d L_ca / d sigma_t of the surrogate."""
    import jax

    from damjax import PSTParams, PSTSetup, arrest_position_smooth, make_layout

    plt = _plt()
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(WIDTH, 3.6))
    fig.subplots_adjust(left=0.09, right=0.98, top=0.86, bottom=0.2, wspace=0.3)
    for row in _rows("results/inversion_brittle.jsonl"):
        if row["case"] == "inversion_brittle":
            ax0.semilogy(
                row["loss_history"],
                label=f"from theta {row['start']:g}: {row['estimate']:.0f} Pa/m "
                f"({100 * row['relative_error']:.1f} %)",
            )
    ax0.set_xlabel("Adam iteration")
    ax0.set_ylabel("misfit")
    ax0.set_title("theta from 3 arrests (truth 600 Pa/m)\nresults/inversion_brittle.jsonl")
    ax0.legend()
    setup = PSTSetup(length=30.0, dx=0.04, duration=1.2)
    truth = dict(softening=1.0, steady_length=10.0, strength_gradient=300.0)
    sig = np.array([3000.0, 4500.0, 6000.0, 7500.0, 9000.0])
    layout = make_layout(PSTParams(tensile_strength=6000.0, **truth), setup)

    def f(s):
        return arrest_position_smooth(
            PSTParams(tensile_strength=s, **truth), setup, layout, width=0.5
        )

    vg = jax.jit(jax.value_and_grad(f))
    vals, grads = zip(*[(float(v), float(g)) for v, g in (vg(float(s)) for s in sig)], strict=True)
    ax1.plot(sig / 1e3, vals, "o", color="tab:blue", label="smooth arrest (width 0.5)")
    for s, v, g in zip(sig, vals, grads, strict=True):
        ds = 600.0
        ax1.plot([(s - ds) / 1e3, (s + ds) / 1e3], [v - g * ds, v + g * ds], "tab:red", lw=1.2)
    ax1.plot([], [], "tab:red", label="AD gradient")
    ax1.set_xlabel(r"$\sigma_t$ [kPa]")
    ax1.set_ylabel("arrest position [m]")
    ax1.set_title(
        "smooth arrest L_ca(sigma_t) and its AD slope\ntheta 300 Pa/m, delta 1, L_ss 10 m"
    )
    ax1.legend(loc="upper left")
    return _save(fig, "inversion", "right: 30 m PST, dx 0.04 m, 1.2 s (the inversion's model grid)")


@figure
def weac() -> str:
    """Critical cut length: damjax theory and PST against weac (stored rows)."""
    plt = _plt()
    rows = _rows("results/weac_crosscheck.jsonl")
    labels = [
        f"h {r['thickness_m']:g}\nE {r['youngs_modulus_pa'] / 1e6:g}\npsi {r['slope_deg']:g}"
        for r in rows
    ]
    x = np.arange(len(rows))
    fig, ax = plt.subplots(figsize=(WIDTH, 3.8))
    fig.subplots_adjust(left=0.08, right=0.98, top=0.91, bottom=0.25)
    w = 0.27
    ax.bar(x - w, [r["damjax_theory_a_c_m"] for r in rows], w, label="damjax theory (bar)")
    ax.bar(x, [r["damjax_sim_a_c_m"] for r in rows], w, label="damjax PST run")
    ax.bar(x + w, [r["weac_a_c_m"] for r in rows], w, label="weac (beam, downslope cut)")
    ax.set_xticks(x, labels, fontsize=7)
    ax.set_ylabel("critical cut length a_c [m]")
    ax.set_xlabel("slab: h [m], E [MPa], slope psi [deg]", labelpad=2)
    ax.set_title("Critical cut length against weac 2.6 (matched toughness, no friction)")
    ax.legend()
    return _save(fig, "weac", "rows: results/weac_crosscheck.jsonl")


@figure
def slopes() -> str:
    """Fig. 13a: a release map (small run, dx 0.4 m) and the stored arrests at dx 0.2 m."""
    from damjax import runner, scenario

    plt = _plt()
    rows = [
        r for r in _rows("results/slope_acceptance.jsonl") if r.get("case") == "slope_acceptance"
    ]
    fig, (ax0, ax1) = plt.subplots(
        1, 2, figsize=(WIDTH, 4.2), gridspec_kw={"width_ratios": [1.15, 1]}
    )
    fig.subplots_adjust(left=0.07, right=0.98, top=0.88, bottom=0.17, wspace=0.3)
    dx = 0.3  # the coarsest the validation takes here (Lambda/2 = 0.33 m)
    scn = scenario.load("slope-generic-50x60", warn=False)
    scn = scn.replace(setup={"dx": dx, "duration": 4.0})
    with tempfile.TemporaryDirectory() as tmp:
        r = runner.run(scn, tmp).result
    at = np.where(np.isfinite(r.arrival_time), r.arrival_time, np.nan)
    cmap = plt.get_cmap("viridis").copy()
    cmap.set_bad("0.85")  # intact weak layer
    im = ax0.pcolormesh(r.y, r.x, at, cmap=cmap, shading="auto")
    cs = ax0.contour(r.y, r.x, r.slope_deg, levels=[22, 26, 30, 34], colors="k", linewidths=0.5)
    ax0.clabel(cs, fontsize=6, fmt="%g deg")
    ax0.set_aspect("equal")
    ax0.set_xlabel("across [m]")
    ax0.set_ylabel("up-slope x [m]")
    fig.colorbar(im, ax=ax0, label="weak-layer failure time [s]", shrink=0.9)
    up = r.summary.get("upslope_arrest_distance_m")
    what = "no arrest" if up is None else f"arrest {up:.1f} m from the start"
    ax0.set_title(f"seed 0, dx {dx} m: {what}\n(grey: intact)")
    names = []
    dist = []
    for row in rows:
        names.append(row.get("run", row.get("label", "?")))
        # rows before 2026-11-27 have no upslope_extent_m (their arrest distance was it)
        dist.append(row.get("upslope_extent_m", row["upslope_arrest_distance_m"]))
    y = np.arange(len(rows))
    ax1.barh(y, dist, color="tab:blue")
    ax1.axvspan(40, 50, color="tab:red", alpha=0.15, lw=0)
    ax1.set_yticks(y, names)
    ax1.invert_yaxis()
    ax1.set_xlabel("up-slope arrest distance from the start [m]")
    ax1.set_title("stored rows, dx 0.2 m, 4 s\nshaded: the paper's 40-50 m")
    fig.suptitle("Generic slope 50 m x 60 m (paper Fig. 13a)", y=0.99)
    return _save(fig, "slopes", f"left: slope-generic-50x60 at dx {dx} m, 4 s; right: stored rows")


@figure
def slope_calibration() -> str:
    """Slope calibration iterates of sigma_t (stored rows), truth 4 kPa."""
    plt = _plt()
    rows = _rows("results/slab_fracture/slope_calibration_crack_band.jsonl")
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(WIDTH, 3.6))
    fig.subplots_adjust(left=0.09, right=0.98, top=0.88, bottom=0.2, wspace=0.28)
    runs = [r for r in rows if r["case"] == "slope_calibration"]
    for r in runs:
        grad = r.get("gradient", "ad")
        tag = f"{grad.upper()}, from {r['start']:.0f} Pa"
        if "commit" in r:
            tag += f" ({r['commit']})"
        hist = r["history"]
        it = np.arange(len(hist))
        ax0.plot(it, [h["tensile_strength"] for h in hist], "o-", ms=3, label=tag)
        ax1.plot(it, [h["loss"] for h in hist], "o-", ms=3, label=tag)
    ax0.axhline(4000.0, color="k", ls="--", lw=0.8, label="truth 4000 Pa")
    ax0.axhspan(3600, 4400, color="k", alpha=0.08, lw=0)
    ax0.set_xlabel("iteration")
    ax0.set_ylabel(r"$\sigma_t$ [Pa]")
    ax0.legend(fontsize=6.5)
    ax0.set_title("sigma_t iterates (band: truth +-10 %)")
    ax1.set_xlabel("iteration")
    ax1.set_ylabel("release-map loss")
    ax1.set_title("loss")
    fig.suptitle("Slope calibration, crack-band slab, 30 m x 8 m release area", y=0.99)
    return _save(
        fig,
        "slope_calibration",
        "rows: results/slab_fracture/slope_calibration_crack_band.jsonl",
    )


# --------------------------------------------------------------------------- user guide


def _cli(*args: str, cwd: Path) -> None:
    """``damjax ARGS`` in ``cwd`` with this interpreter; its output only on failure."""
    proc = subprocess.run(
        [sys.executable, "-m", "damjax", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONWARNINGS="ignore"),
    )
    if proc.returncode:
        tail = proc.stderr[-2000:]
        raise RuntimeError(f"damjax {' '.join(args)}: exit {proc.returncode}\n{tail}")


@figure
def quickstart_pst() -> str:
    """The quick start's ``damjax pst --plot pst.png``, copied as is."""
    with tempfile.TemporaryDirectory() as tmp:
        _cli("pst", "--plot", "pst.png", cwd=Path(tmp))
        shutil.copy(Path(tmp) / "pst.png", OUT / "quickstart_pst.png")
    return "damjax pst --plot pst.png (full size: 100 m, dx 0.02 m, 3 s), its own output"


@figure
def slope_quick() -> str:
    """The release map of ``damjax run slope-quick`` (its own slope.png)."""
    with tempfile.TemporaryDirectory() as tmp:
        _cli("run", "slope-quick", "--out", "run", "--quiet", cwd=Path(tmp))
        png = sorted((Path(tmp) / "run").glob("*.png"))
        shutil.copy(png[0], OUT / "slope_quick.png")
    return f"damjax run slope-quick, its own {png[0].name}"


ENSEMBLE_TOML = """\
type = "slope"
name = "slope-quick-grf"
description = "slope-quick with a Gaussian random strength field, for an ensemble"

[params]
slope_deg = 35.0

[setup]
length = 12.0
width = 6.0
dx = 0.1
duration = 0.8
particles_per_cell = 1
chunk_steps = 100

[terrain]
kind = "plane"

[strength]
kind = "grf"
mean = 1000.0        # [Pa] at the lower edge
trend = 280.0        # [Pa/m] up-slope
std = 100.0          # [Pa] 10 % of the mean, the low end of the 10-30 % of penetrometer
                     # strength maps (Kronholm and Schweizer 2003): the weak layer holds
                     # its slab (703 Pa) before the trigger in every member
length_scale = 2.0   # [m]
seed = 0
start_window = [2.0, 4.0]
"""


@figure
def ensemble_quick() -> str:
    """``damjax ensemble`` on a small random-field slope (8 members): its ensemble.png."""
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "ensemble_quick.toml").write_text(ENSEMBLE_TOML)
        _cli(
            "ensemble",
            "ensemble_quick.toml",
            "--members",
            "8",
            "--out",
            "ens",
            "--quiet",
            cwd=Path(tmp),
        )
        shutil.copy(Path(tmp) / "ens" / "ensemble.png", OUT / "ensemble_quick.png")
        (OUT / "ensemble_quick.toml").write_text(ENSEMBLE_TOML)
    return "damjax ensemble ensemble_quick.toml --members 8 (docs/images/ensemble_quick.toml)"


@figure
def gis_export() -> str:
    """``damjax run slope-dem-gully`` exported with ``--to gis``, read back and mapped."""
    import geopandas as gpd
    import rasterio
    from rasterio.plot import plotting_extent

    from damjax.scenario import library_dir

    plt = _plt()
    with tempfile.TemporaryDirectory() as tmp:
        _cli("run", "slope-dem-gully", "--out", "run", "--quiet", cwd=Path(tmp))
        _cli("export", "run", "--to", "gis", "gis", cwd=Path(tmp))
        with rasterio.open(Path(tmp) / "gis" / "arrival_time.tif") as src:
            at = src.read(1, masked=True)
            ext = plotting_extent(src)
            crs = src.crs
        zones = gpd.read_file(Path(tmp) / "gis" / "release_zones.gpkg")
    dem = np.loadtxt(library_dir() / "slope-dem-gully.asc", skiprows=6)
    with open(library_dir() / "slope-dem-gully.asc") as fh:
        head = dict(line.split() for _, line in zip(range(6), fh, strict=False))
    nrows, ncols = dem.shape
    x0 = float(head.get("xllcorner", head.get("xllcenter", 0)))
    y0 = float(head.get("yllcorner", head.get("yllcenter", 0)))
    cell = float(head["cellsize"])
    xs = x0 + cell * (np.arange(ncols) + 0.5)
    ys = y0 + cell * (np.arange(nrows)[::-1] + 0.5)
    fig, ax = plt.subplots(figsize=(WIDTH, 4.8))
    fig.subplots_adjust(left=0.14, right=0.97, top=0.88, bottom=0.12)
    pad = 15.0  # [m] of map around the release area
    view = (
        (xs > ext[0] - pad)[None, :]
        & (xs < ext[1] + pad)[None, :]
        & (ys > ext[2] - pad)[:, None]
        & (ys < ext[3] + pad)[:, None]
    )
    levels = np.arange(np.floor(dem[view].min()), dem[view].max() + 2.0, 2.0)
    cs = ax.contour(xs, ys, dem, levels=levels, colors="0.55", linewidths=0.5)
    ax.clabel(cs, fontsize=6, fmt="%.0f m")
    im = ax.imshow(at, extent=ext, cmap="viridis", zorder=2)
    zones.boundary.plot(ax=ax, color="tab:red", lw=1.2, zorder=3)
    area = float(zones["area_m2"].sum())
    ax.set_xlim(ext[0] - pad, ext[1] + pad)
    ax.set_ylim(ext[2] - pad, ext[3] + pad)
    ax.set_aspect("equal")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_xlabel(f"easting [m] ({crs.to_string() if crs else 'no CRS'})")
    ax.set_ylabel("northing [m]")
    fig.colorbar(im, ax=ax, label="arrival_time.tif: weak-layer failure time [s]", shrink=0.8)
    ax.set_title(
        f"damjax export run --to gis gis: arrival_time.tif and release_zones.gpkg\n"
        f"({len(zones)} zone(s), {area:.0f} m^2 on the map, red) over the DEM's 2 m contours"
    )
    return _save(fig, "gis_export", "slope-dem-gully as shipped (dx 0.2 m, 2 s)")


# --------------------------------------------------------------------------- main


def main(argv: list[str]) -> int:
    if {"--list", "-h", "--help"} & set(argv):
        for name, fn in FIGURES.items():
            print(f"{name:18s} {(fn.__doc__ or '').strip().splitlines()[0]}")
        return 0
    names = argv or list(FIGURES)
    unknown = [n for n in names if n not in FIGURES]
    if unknown:
        sys.stderr.write(f"unknown figure(s) {unknown}; choose from {list(FIGURES)}\n")
        return 2
    _quiet()
    OUT.mkdir(parents=True, exist_ok=True)
    manifest_path = OUT / "figures.json"
    manifest = json.loads(manifest_path.read_text()) if manifest_path.is_file() else {}
    t_all = time.perf_counter()
    for name in names:
        t0 = time.perf_counter()
        note = FIGURES[name]()
        dt = round(time.perf_counter() - t0, 1)
        png = OUT / f"{name}.png"
        png = png if png.is_file() else next(OUT.glob(f"{name}*.png"))
        row = dict(
            STAMP,
            command=f"{COMMAND} {name}",
            figure=name,
            file=f"docs/images/{png.name}",
            what=note,
            wall_s=dt,
            kb=round(png.stat().st_size / 1024),
        )
        manifest[name] = row
        print(json.dumps(row), flush=True)
    manifest_path.write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n")
    sys.stderr.write(f"[figures: {time.perf_counter() - t_all:.1f} s]\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
