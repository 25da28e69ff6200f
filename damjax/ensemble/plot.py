"""The ensemble's figure: the release probability over the terrain with the start window
and the members' starts, and histograms of the release area and of the up-slope extent
with their quantiles."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from damjax import io


def plot_ensemble(ds: Any, path: str | os.PathLike[str] | None = None) -> Any:
    """Release probability over the terrain (slope-angle contours, the start window and
    the members' starts; the legend below the map), and histograms of the release area
    and of the up-slope extent of the release from the start (members whose up-slope front
    arrested darker) with their 5/50/95 % quantiles, on whole member counts. Returns the
    Figure; writes it to ``path``."""
    from damjax.plot import _plt

    plt = _plt()
    x, y = ds["x"].values, ds["y"].values
    fig, axes = plt.subplots(
        1, 3, figsize=(15, 5.5), constrained_layout=True, gridspec_kw={"width_ratios": [1.4, 1, 1]}
    )
    ax = axes[0]
    ext = [y[0], y[-1], x[0], x[-1]]
    im = ax.imshow(
        ds["release_probability"].values,
        origin="lower",
        extent=ext,
        cmap="magma_r",
        vmin=0,
        vmax=1,
        aspect="equal",
    )
    fig.colorbar(im, ax=ax, label="release probability")
    cs = ax.contour(
        y, x, ds["slope_angle"].values, levels=[25, 28, 30, 32, 34], colors="0.4", linewidths=0.7
    )
    ax.clabel(cs, fmt="%g°", fontsize=7)
    try:
        import tomllib

        win = tomllib.loads(ds.attrs.get("scenario", "")).get("strength", {}).get("start_window")
    except Exception:  # noqa: BLE001 - no scenario text: no window
        win = None
    if win:
        from damjax.slope.generic import full_window

        x0, x1, y0, y1 = full_window(tuple(win), float(y[-1] + 0.5 * (y[1] - y[0])))
        ax.add_patch(
            plt.Rectangle(
                (y0, x0), y1 - y0, x1 - x0, fill=False, ec="tab:blue", lw=1.2, label="start window"
            )
        )
    ax.plot(ds["start_y"].values, ds["start_x"].values, "*", color="tab:blue", ms=6, label="starts")
    # below the map: inside it the legend covered the contours' labels
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, fontsize=8, frameon=False)
    ax.set_xlabel("y across [m]")
    ax.set_ylabel("x up-slope [m]")
    ax.set_title(f"{ds.sizes['member']} members")
    from matplotlib.ticker import MaxNLocator

    up = "upslope_extent_m" if "upslope_extent_m" in ds else "upslope_arrest_distance_m"
    for ax, name, label in (
        (axes[1], "release_area_m2", "release area [m²]"),
        (axes[2], up, "up-slope extent of the release from the start [m]"),
    ):
        vals = ds[name].values
        ok = np.isfinite(vals)
        bins = np.histogram_bin_edges(vals[ok], bins=max(5, min(30, int(ok.sum()) // 2)))
        if name == "upslope_extent_m" and "upslope_front" in ds:
            # the members whose up-slope front arrested apart from the others
            state = ds["upslope_front"].values.astype(str)
            ax.hist(
                [vals[ok & (state == "arrested")], vals[ok & (state != "arrested")]],
                bins=bins,
                stacked=True,
                color=["0.45", "0.8"],
                label=["arrested", "reached the top or still moving"],
            )
            ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=8, frameon=False)
        else:
            ax.hist(vals[ok], bins=bins, color="0.6")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # member counts are whole
        for q, v in zip(ds["quantile"].values, ds[f"{name}_quantiles"].values, strict=True):
            if not np.isfinite(v):
                continue
            ax.axvline(v, color="tab:red", ls="--" if q != 0.5 else "-", lw=1)
            ax.text(
                v,
                ax.get_ylim()[1] * 0.95,
                f"q{round(100 * q):02d}",
                rotation=90,
                va="top",
                ha="right",
                fontsize=7,
                color="tab:red",
            )
        ax.set_xlabel(label)
        ax.set_ylabel("members")
    if path is not None:
        io.save_figure(fig, path)
    return fig
