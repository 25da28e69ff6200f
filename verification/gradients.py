"""Gradients through the solver against what they differentiate (docs/guide/gradients.md,
docs/verification/inversion.md).

    python -m verification.gradients events    # 40 m PSTs, float64, 4 fields x 2 softenings
    python -m verification.gradients full      # the paper's brittle baseline, theta (~16 min)
    python -m verification.gradients fd        # full-size AD against central differences
    python -m verification.gradients inversion # theta recovered from event-based arrests

- ``events``: `damjax.gradient_check` (AD of the continuous crack length against the
  least-squares slope of the event-based arrest over +-10 %, 11 runs) of theta, E, G_wl and
  tau_p on a 40 m PST (L_ss 10 m, theta 800 Pa/m, dx 0.04 m, float64) at softening 0 and 0.3;
- ``full``: the same check for theta on the paper's brittle baseline (100 m, dx 0.02 m, 3 s,
  softening 0, float32), one member at a time;
- ``fd``: the smooth arrest position's gradient on the full baseline (softening 1 and 0)
  against central differences of 0.5 and 1 % (float64 unless ``DAMJAX_BENCH_DTYPE``);
- ``inversion``: `damjax.calibrate.invert` of theta at softening 0 from event-based
  arrests observed on a twice finer grid with 0.1 m noise (30 m PSTs, L_ss 4 / 5 / 6 m,
  dx 0.05 m model), from theta 400 and 900 Pa/m.

One JSON line per field or run, with the date, commit and machine.
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np

from benchmarks.cases import emit


def fd() -> None:
    """Full-size gradients of the smooth arrest position vs central differences (2 steps)."""
    import os

    import jax

    from damjax import PSTParams, PSTSetup, pst

    dtype = os.environ.get("DAMJAX_BENCH_DTYPE", "float64")
    if dtype == "float64":
        jax.config.update("jax_enable_x64", True)
    setup = PSTSetup(dtype=dtype)
    for base in (PSTParams(softening=1.0), PSTParams()):
        layout = pst.make_layout(base, setup)  # fixed step count for every perturbation
        fwd = jax.jit(lambda q, lay=layout: pst.arrest_position_smooth(q, setup, lay))
        grad = jax.jit(jax.grad(lambda q, lay=layout: pst.arrest_position_smooth(q, setup, lay)))
        g = grad(base)
        for name in ("strength_gradient", "softening"):
            x0 = float(getattr(base, name))
            if x0 == 0.0:
                continue  # delta = 0 is the edge of the valid range: no central difference
            ad = float(getattr(g, name))
            for rel in (0.005, 0.01):
                h = rel * x0
                up = float(fwd(dataclasses.replace(base, **{name: x0 + h})))
                dn = float(fwd(dataclasses.replace(base, **{name: x0 - h})))
                fd = (up - dn) / (2 * h)
                emit(
                    case="pst_grad_fd",
                    dtype=dtype,
                    field=name,
                    at=x0,
                    softening=float(base.softening),
                    rel_step=rel,
                    ad=ad,
                    fd=fd,
                    rel_error=abs(ad - fd) / max(abs(fd), 1e-12),
                    arrest_position_smooth_m=float(fwd(base)),
                    n_particles=layout.n_particles,
                    n_steps=layout.n_steps,
                )


def _gradient_rows(case_name: str, params, setup, fields, batch_size=None) -> None:
    from damjax import gradient_check

    t0 = time.perf_counter()
    checks = gradient_check(params, setup, list(fields), batch_size=batch_size)
    wall = time.perf_counter() - t0
    for c in checks:
        emit(
            case=case_name,
            field=c.field,
            at=c.at,
            softening=float(params.softening),
            steady_length=float(params.steady_length),
            length=setup.length,
            dx=setup.dx,
            duration=setup.duration,
            dtype=setup.dtype,
            window=[c.values[0], c.values[-1]],
            n_runs=len(c.values),
            ad_mean=c.ad_mean,
            ad_center=c.ad,
            event_slope=c.event_slope,
            length_slope=c.length_slope,
            relative_error=round(c.relative_error, 4),
            ok=c.ok,
            arrests_m=list(c.arrests),
            ad_values=list(c.ad_values),
            wall_time_s_all_fields=round(wall, 1),
        )


def events() -> None:
    """AD of the crack length vs the event-based arrest's slope (+-10 %, 11 runs): theta,
    E, G_wl, tau_peak at softening 0 and 0.3 (40 m PST, L_ss 10, theta 800, dx 0.04, f64)."""
    import jax

    from damjax import PSTParams, PSTSetup

    jax.config.update("jax_enable_x64", True)
    setup = PSTSetup(length=40.0, dx=0.04, duration=1.0, dtype="float64")
    fields = ("strength_gradient", "youngs_modulus", "wl_shear_modulus", "tau_peak")
    for delta in (0.0, 0.3):
        params = PSTParams(steady_length=10.0, strength_gradient=800.0, softening=delta)
        _gradient_rows("gradient_events", params, setup, fields)


def full() -> None:
    """The same check on the paper's brittle baseline (theta 500, L_ss 20, softening 0,
    100 m, dx 0.02 m, 3 s, float32), for theta."""
    from damjax import PSTParams, PSTSetup

    # one member at a time: the memory of one gradient of the full baseline
    _gradient_rows("gradient_full", PSTParams(), PSTSetup(), ("strength_gradient",), 1)


def inversion() -> None:
    """Gradient inversion through the solver at softening 0: theta from event-based
    arrests observed on a twice finer grid with noise (30 m PST, dx 0.05 m model; long
    enough that the crack arrests inside it from both starts, theta 400 and 900 Pa/m)."""
    from damjax import PSTParams, PSTSetup, calibrate, simulate_pst

    truth = PSTParams(steady_length=5.0, strength_gradient=600.0, softening=0.0)
    model_setup = PSTSetup(length=30.0, dx=0.05, duration=1.2)
    obs_setup = dataclasses.replace(model_setup, dx=0.025)
    rng = np.random.default_rng(0)
    noise = 0.1  # [m]
    observations = []
    for lss in (4.0, 5.0, 6.0):  # three PSTs of one snowpack: the steady length varies
        r = simulate_pst(dataclasses.replace(truth, steady_length=lss), obs_setup)
        observed = r.arrest_position + float(rng.normal(0.0, noise))
        observations.append(({"steady_length": lss}, observed))
        emit(
            case="inversion_brittle_observation",
            steady_length=lss,
            arrest_position_m=r.arrest_position,
            observed_m=observed,
            dx=obs_setup.dx,
        )
    for start in (400.0, 900.0):
        t0 = time.perf_counter()
        inv = calibrate.invert(
            observations,
            dataclasses.replace(truth, strength_gradient=start),
            model_setup,
            ["strength_gradient"],
            noise_std=noise,
            steps=30,
            learning_rate=0.05,
        )
        est = inv.estimates["strength_gradient"]
        emit(
            case="inversion_brittle",
            truth=600.0,
            start=start,
            estimate=est,
            relative_error=abs(est / 600.0 - 1.0),
            std_error=inv.std_errors["strength_gradient"],
            loss=inv.loss,
            loss_history=[round(v, 3) for v in inv.history],
            dx_model=model_setup.dx,
            dx_observed=obs_setup.dx,
            noise_m=noise,
            wall_time_s=round(time.perf_counter() - t0, 1),
        )


PARTS = {"events": events, "full": full, "fd": fd, "inversion": inversion}


def main(argv: list[str]) -> int:
    unknown = [a for a in argv if a not in PARTS]
    if unknown or not argv:
        sys.stderr.write(f"name one or more parts of {list(PARTS)}\n")
        return 2
    for name in argv:
        PARTS[name]()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
