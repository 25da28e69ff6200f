"""Elastic PST targets (docs/verification/pst.md): full-size PSTs (100 m, dx 0.02 m, 3 s,
float32) against the closed forms of the paper's Appendix A and its arrests and speeds.

    python -m verification.pst                      # both parts, about 4 min on 2 idle cores
    python -m verification.pst kx elastic > results/pst.jsonl

- ``kx``: controlled sawing at adot / c_s = 0.2, 0.8, 1.4 for both lateral conditions:
  the tension gradient k_x behind the cut against `damjax.theory.dynamic_gradient`;
- ``elastic``: self-propagating elastic PSTs (theta 500 Pa/m, L_ss 20 m) at softening 0
  and 2, and at E 2 and 6 MPa, for both lateral conditions: arrest and crack speed.

One JSON line per run, with the date, commit and machine.
"""

from __future__ import annotations

import sys

from benchmarks.cases import _pst_row, emit


def kx() -> None:
    """Controlled sawing at adot/c_s = 0.2, 0.8, 1.4: k_x against Appendix A."""
    from damjax import PSTParams, PSTSetup, simulate_pst, theory

    cs = float(theory.shear_wave_speed(PSTParams()))
    for lateral in ("free", "constrained"):
        for ratio in (0.2, 0.8, 1.4):
            adot = ratio * cs
            setup = PSTSetup(controlled=True, lateral=lateral, duration=min(3.0, 80.0 / adot))
            s = simulate_pst(PSTParams(saw_speed=adot), setup).summary
            kx, kth = s["tension_gradient_pa_per_m"], s["tension_gradient_theory_pa_per_m"]
            emit(
                case="kx_controlled",
                lateral=lateral,
                adot_over_cs=ratio,
                k_x=kx,
                k_x_theory=kth,
                rel_error=kx / kth - 1,
                n_particles=s["n_particles"],
                n_steps=s["n_steps"],
                dtype="float32",
                compile_time_s=s["compile_time_s"],
                wall_time_s=s["wall_time_s"],
                particle_steps_per_s=s["particle_steps_per_s"],
            )


def elastic() -> None:
    """Self-propagating elastic PSTs (theta 500, L_ss 20): arrest and crack speed."""
    from damjax import PSTParams, PSTSetup, theory

    for lateral in ("free", "constrained"):
        for delta, E in ((0.0, 4e6), (2.0, 4e6), (0.0, 2e6), (0.0, 6e6)):
            params = PSTParams(softening=delta, youngs_modulus=E)
            row = _pst_row("pst_elastic", params, PSTSetup(lateral=lateral))
            # the strip's wave speed over c_s: the bound of a crack's speed
            strip = float(theory.longitudinal_wave_speed(params, lateral))
            strip /= float(theory.shear_wave_speed(params))
            speed = row["max_crack_speed_over_cs"]
            emit(
                **row,
                softening=delta,
                youngs_modulus=E,
                arrested=row["arrest_position_m"] is not None,
                strip_wave_speed_over_cs=strip,
                max_crack_speed_over_strip=None if speed is None else speed / strip,
            )


PARTS = {"kx": kx, "elastic": elastic}


def main(argv: list[str]) -> int:
    unknown = [a for a in argv if a not in PARTS]
    if unknown:
        sys.stderr.write(f"unknown part(s) {unknown}; choose from {list(PARTS)}\n")
        return 2
    for name in argv or list(PARTS):
        PARTS[name]()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
