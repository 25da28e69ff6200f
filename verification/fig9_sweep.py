"""Acceptance sweep: a sweep like the paper's Fig. 9 (elasto-plastic slab, softening 1),
and the two Fig. 8 cases with the non-default lateral condition.

    python -m verification.fig9_sweep                    # sweep at dx 0.04 m + dx 0.02 check
    python -m verification.fig9_sweep --fig8             # only the two Fig. 8 cases
    python -m verification.fig9_sweep --small            # a few members, 40 m (smoke test)

The sweep varies one parameter at a time around the paper's elasto-plastic baseline
(sigma_t = 6 kPa, E = 4 MPa, L_ss = 20 m, delta = 1, 100 m PST), at a low and a high
strength gradient theta, so each trend is read at fixed other parameters:

- theta:   20, 30, 50, 100, 150, 300, 1000 Pa/m;
- sigma_t: 2, 4, 6, 8, 10 kPa             (theta 50 and 300 Pa/m);
- E:       2, 4, 6 MPa                     (theta 50 and 300 Pa/m);
- L_ss:    10, 20, 30 m                    (theta 50 and 1000 Pa/m).

Each group of members runs as one vmapped `damjax.sweep` (one compilation, one time
step for the group). dx = 0.04 m by default (Lambda/16.5) to keep the whole sweep at a
few minutes on one CPU core; ``--check-dx`` reruns one member at dx 0.02 m and prints
both. Output: one JSON line per member (``params``, ``arrested``, ``L_ca_m``,
``A_ca_m`` = L_ca - L_ss, ``n_fractures``, ``fracture_x_m``), then the trend table.

``--fig8``: theta = 30 and 150 Pa/m, sigma_t = 6 kPa, softening 0, 100 m, dx 0.02 m,
with ``--lateral`` (default "constrained", the non-default condition): arrest position
and fracture count of each.

Measured (commit a618928, MCC with 3D invariants, paper Eq. 6 p0; 1 CPU core shared with
other jobs; sweep 278 s for 29 members at dx 0.04 m; A_ca [m] (fracture count)):

    theta    20: 69.5 (2) | 30: 46.5 (1) | 50: 28.0 (1) | 100: 14.2 (2) | 150: 9.6 (1)
            300:  5.0 (1) | 1000: 1.7 (1)            (all arrest, theta 20 at 89.5 m)
    sigma_t 2/4/6/8/10 kPa, theta 50:   4.9  16.3  28.0  39.8  51.7   (grows, ~5.9 m/kPa)
                            theta 300:  1.1   3.1   5.0   7.0   8.9   (grows, ~1 m/kPa)
    E 2/4/6 MPa,            theta 50:  42.6  28.0  21.6               (falls)
                            theta 300:  7.3   5.0   4.0               (falls)
    L_ss 10/20/30 m,        theta 50:  28.0  28.0  28.0               (no L_ss effect)
                            theta 1000: 1.5   1.7   1.7               (flat; paper: falls)
    dx check (theta 300): L_ca 24.99 m at dx 0.04, 24.945 m at dx 0.02, one fracture
    (24.91 / 24.92 m).
    Fig. 8, constrained, dx 0.02 m (139 s for both): theta 30 no arrest, 4 fractures
    (38.7, 46.2, 61.0, 73.6 m); theta 150 arrests at 36.83 m, 1 fracture (36.74 m).

Fracture counts do not separate by theta as cleanly as the paper's Fig. 9 (multiple below,
single above ~100 Pa/m): two at theta 20 and 100, one elsewhere.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

import numpy as np

from damjax import PSTParams, PSTSetup
from damjax.sweep import sweep

BASE = dict(tensile_strength=6000.0, youngs_modulus=4.0e6, steady_length=20.0, softening=1.0)
GROUPS: dict[str, tuple[str, list[float], list[float]]] = {
    # name: (varied field, values, theta values [Pa/m])
    "theta": ("strength_gradient", [20.0, 30.0, 50.0, 100.0, 150.0, 300.0, 1000.0], []),
    "sigma_t": ("tensile_strength", [2e3, 4e3, 6e3, 8e3, 10e3], [50.0, 300.0]),
    "E": ("youngs_modulus", [2e6, 4e6, 6e6], [50.0, 300.0]),
    "L_ss": ("steady_length", [10.0, 20.0, 30.0], [50.0, 1000.0]),
}


def members(group: str, small: bool = False) -> list[dict[str, float]]:
    """Parameter overrides of every member of a group (BASE plus the varied fields)."""
    field, values, thetas = GROUPS[group]
    if small:
        values = values[:: max(1, len(values) // 2)]
    if not thetas:
        return [{**BASE, field: v} for v in values]
    return [{**BASE, field: v, "strength_gradient": t} for t in thetas for v in values]


def run_batch(rows: list[dict[str, float]], setup: PSTSetup) -> list[dict[str, Any]]:
    """Run the rows as one vmapped sweep; one result dict per row."""
    keys = sorted({k for r in rows for k in r})
    batch = PSTParams(**{k: np.array([r[k] for r in rows]) for k in keys})
    t0 = time.perf_counter()
    results = sweep(batch, setup)
    wall = time.perf_counter() - t0
    out = []
    for r, res in zip(rows, results, strict=True):
        s = res.summary
        fr = res.fractures
        out.append(
            {
                "params": r,
                "dx": setup.dx,
                "length": setup.length,
                "lateral": setup.lateral,
                "slab_fracture": setup.slab_fracture,
                "seed": setup.seed,
                "arrested": bool(s["arrested"]),
                "L_ca_m": s["arrest_position_m"],
                "A_ca_m": s["arrest_length_m"],
                "final_tip_m": s["final_tip_m"],
                "L_smooth_m": s["arrest_position_smooth_m"],
                "n_fractures": len(fr),
                "fracture_x_m": [round(f["x_m"], 2) for f in fr],
                "fault": s["fault"],
                "batch_wall_s": round(wall, 1),
            }
        )
    return out


def _fmt(v: Any) -> str:
    return "  -  " if v is None else f"{v:5.1f}"


def trend_table(rows: list[dict[str, Any]]) -> list[str]:
    """Human-readable trend table (A_ca [m] and fracture counts) of the sweep rows."""
    lines = []
    by_group: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        by_group.setdefault(r["group"], []).append(r)
    for group, rs in by_group.items():
        field, values, thetas = GROUPS[group]
        lines.append(f"== {group} ({field}); entries: A_ca [m] (n_fractures); '-': no arrest")
        for t in thetas or [None]:
            sel = [r for r in rs if t is None or r["params"]["strength_gradient"] == t]
            head = f"theta={t:g}" if t is not None else "theta"
            cells = [
                f"{r['params'][field]:g}: {_fmt(r['A_ca_m'])} ({r['n_fractures']})" for r in sel
            ]
            lines.append(f"  {head:11s} " + " | ".join(cells))
    return lines


def trends(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Machine-readable trend checks (monotonicity over arrested members)."""

    def series(group: str, theta: float | None) -> list[tuple[float, float | None]]:
        field = GROUPS[group][0]
        return [
            (r["params"][field], r["A_ca_m"])
            for r in rows
            if r["group"] == group and (theta is None or r["params"]["strength_gradient"] == theta)
        ]

    def monotone(s: list[tuple[float, float | None]], sign: int) -> bool | None:
        a = [v for _, v in s if v is not None]
        if len(a) < 2:
            return None
        return all(sign * (b - c) >= -0.5 for c, b in zip(a, a[1:], strict=False))

    out: dict[str, Any] = {}
    for t in GROUPS["sigma_t"][2]:
        out[f"A_ca_grows_with_sigma_t_theta{t:g}"] = monotone(series("sigma_t", t), +1)
    for t in GROUPS["E"][2]:
        out[f"A_ca_falls_with_E_theta{t:g}"] = monotone(series("E", t), -1)
    for t in GROUPS["L_ss"][2]:
        out[f"A_ca_vs_L_ss_theta{t:g}"] = series("L_ss", t)
    out["fractures_by_theta"] = [
        (r["params"]["strength_gradient"], r["n_fractures"], r["arrested"])
        for r in rows
        if r["group"] == "theta"
    ]
    return out


def fig8(lateral: str, dx: float, duration: float) -> list[dict[str, Any]]:
    """The two Fig. 8 cases (theta 30 and 150, sigma_t 6 kPa, delta 0, 100 m)."""
    rows = [
        dict(tensile_strength=6000.0, softening=0.0, steady_length=20.0, strength_gradient=t)
        for t in (30.0, 150.0)
    ]
    setup = PSTSetup(length=100.0, dx=dx, duration=duration, lateral=lateral, chunk_steps=2000)
    return run_batch(rows, setup)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dx", type=float, default=0.04, help="grid spacing of the sweep [m]")
    ap.add_argument("--length", type=float, default=100.0, help="PST length [m]")
    ap.add_argument("--duration", type=float, default=3.0, help="simulated time [s]")
    ap.add_argument("--groups", default=",".join(GROUPS), help="comma-separated groups")
    ap.add_argument("--small", action="store_true", help="few members, 40 m, 1.5 s")
    ap.add_argument("--no-check-dx", action="store_true", help="skip the dx 0.02 check")
    ap.add_argument("--fig8", action="store_true", help="only the Fig. 8 cases")
    ap.add_argument("--lateral", default="constrained", help="lateral condition for --fig8")
    ap.add_argument(
        "--slab-fracture", default="paper", help="slab fracture model: paper or crack_band"
    )
    ap.add_argument("--seed", type=int, default=0, help="tensile-strength field (crack_band)")
    a = ap.parse_args(argv)
    t_start = time.perf_counter()
    if a.fig8:
        for r in fig8(a.lateral, 0.02, a.duration):
            print(json.dumps({"case": "fig8", **r}), flush=True)
        return 0
    length, duration = (40.0, 1.5) if a.small else (a.length, a.duration)
    slab = dict(slab_fracture=a.slab_fracture, seed=a.seed)
    setup = PSTSetup(length=length, dx=a.dx, duration=duration, chunk_steps=2000, **slab)
    rows: list[dict[str, Any]] = []
    for group in a.groups.split(","):
        todo = members(group, a.small)
        if a.small:
            todo = [{**m, "steady_length": min(m["steady_length"], 10.0)} for m in todo]
        for r in run_batch(todo, setup):
            r["group"] = group
            print(json.dumps(r), flush=True)
            rows.append(r)
    if not a.no_check_dx and not a.small:
        probe = {**BASE, "strength_gradient": 300.0}
        fine = PSTSetup(length=length, dx=0.02, duration=duration, chunk_steps=2000, **slab)
        coarse = next((r for r in rows if r["params"] == probe), None)
        coarse = coarse or run_batch([probe], setup)[0]  # only when the sweep lacks it
        check = run_batch([probe], fine)[0]
        print(
            json.dumps(
                {
                    "case": "dx_check",
                    "params": probe,
                    "dx0.04": {k: coarse[k] for k in ("L_ca_m", "n_fractures", "fracture_x_m")},
                    "dx0.02": {k: check[k] for k in ("L_ca_m", "n_fractures", "fracture_x_m")},
                }
            ),
            flush=True,
        )
    for line in trend_table(rows):
        print(line)
    summary = {"case": "fig9_summary", **trends(rows)}
    summary["wall_s"] = round(time.perf_counter() - t_start, 1)
    summary["n_members"] = len(rows)
    print(json.dumps(summary), flush=True)
    return 0 if all(math.isfinite(r["final_tip_m"] or 0.0) for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
