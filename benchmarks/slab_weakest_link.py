"""Does a heterogeneous slab stop the crack at its weakest section? One JSON line per run.

Reads crack-band PST rows written by `benchmarks.slab_fracture_acceptance` (default: the
G_f / CoV scan, results_slab_fracture/gf_cov_scan.jsonl), rebuilds each run's seeded
tensile-strength field and compares

- f = (arrest - L_ss) / (x_h - L_ss), the arrest as a fraction of the homogeneous slab's
  run-out beyond L_ss (x_h: the CoV-0 run with the same G_f and theta in the same file), with
- the field's weakest section on [0, arrest]: the smallest p0 / mean p0 (the tensile yield
  stress is proportional to p0) and where it lies.

Quasi-statically a perfectly plastic slab transmits at most sigma_y h, and the crack stops
where theta (x - L_ss) lambda reaches it (docs/model/slab.md), so a slab whose weakest
section carries a fraction r of the mean strength arrests near f = r.

    python -m benchmarks.slab_weakest_link --fracture-energy 250
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import damjax
from damjax.core.model import build, make_layout

RESULTS = Path(__file__).parent / "results_slab_fracture" / "gf_cov_scan.jsonl"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=Path, default=RESULTS)
    ap.add_argument("--fracture-energy", type=float, default=250.0)
    ap.add_argument("--steady-length", type=float, default=20.0)
    args = ap.parse_args(argv)
    rows = [json.loads(line) for line in args.rows.read_text().splitlines() if line.strip()]
    rows = [
        r
        for r in rows
        if "arrest_position_m" in r and r["slab_fracture_energy"] == args.fracture_energy
    ]
    homogeneous = {r["theta"]: r["arrest_position_m"] for r in rows if r["slab_strength_cov"] == 0}
    l_ss = args.steady_length
    for r in rows:
        if r["slab_strength_cov"] == 0 or r["theta"] not in homogeneous:
            continue
        params = damjax.PSTParams(
            tensile_strength=r.get("sigma_t", 6000.0),
            strength_gradient=r["theta"],
            softening=r["delta"],
            steady_length=l_ss,
            slab_fracture_energy=r["slab_fracture_energy"],
            slab_strength_cov=r["slab_strength_cov"],
            slab_strength_length=r["slab_strength_length"],
        )
        setup = damjax.PSTSetup(
            length=r["length"],
            dx=r["dx"],
            duration=0.01,  # only the field is needed
            slab_fracture=r["slab_fracture"],
            seed=r["seed"],
            p0_rule=r["p0_rule"],
        )
        model, _ = build(params, setup, make_layout(params, setup))
        x = np.asarray(model.saw_coord)
        ratio = np.asarray(model.p0_init) / float(np.mean(model.p0_init))
        arrest = r["arrest_position_m"]
        on = x <= arrest
        weakest = int(np.argmin(np.where(on, ratio, np.inf)))
        print(
            json.dumps(
                {
                    "theta": r["theta"],
                    "seed": r["seed"],
                    "dx": r["dx"],
                    "slab_fracture_energy": r["slab_fracture_energy"],
                    "slab_strength_cov": r["slab_strength_cov"],
                    "arrest_m": arrest,
                    "homogeneous_arrest_m": homogeneous[r["theta"]],
                    "runout_fraction": (arrest - l_ss) / (homogeneous[r["theta"]] - l_ss),
                    "weakest_strength_ratio": float(ratio[weakest]),
                    "weakest_x_m": float(x[weakest]),
                }
            ),
            flush=True,
        )


if __name__ == "__main__":
    main()
