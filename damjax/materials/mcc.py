"""Modified Cam Clay (MCC) slab in plane stress (paper Eq. 5-6; Gaume et al. 2019).

Yield function (paper Eq. 5), compression positive for p:

    y(p, q) = q^2 (1 + 2 beta) + M^2 (p + beta p0) (p - p0)  <= 0

Stress invariants (`invariants`, a static choice; the vertical stress, ~0.5 kPa for the
baseline, is not included: the paper derives Eq. 6 "considering the plane stress
hypothesis"):

- ``"3d"`` (default): the usual invariants of the 3D stress tensor with sigma_zz = 0,
  p = -(sigma_xx + sigma_yy) / 3, q = sqrt(3/2 s:s) with s the 3D deviator, i.e.
  q^2 = sigma_xx^2 + sigma_yy^2 - sigma_xx sigma_yy + 3 sigma_xy^2. Uniaxial tension
  sigma gives (p, q) = (-sigma/3, sigma). This is what 3D MPM codes evaluate.
- ``"plane"``: invariants of the 2D in-plane tensor, p = -(sigma_xx + sigma_yy) / 2,
  q = sqrt(3/2 s:s) with s = sigma - (tr sigma / 2) I; uniaxial tension gives
  (p, q) = (-sigma/2, sqrt(3) sigma/2).

In the in-plane variables (p2, q2) of the "plane" choice, both yield surfaces are
ellipses y = alpha q2^2 + gamma (p2 - p_c)^2 - R (since q_3d^2 = q2^2 + p2^2 and
p_3d = 2 p2 / 3 in plane stress), so one return mapping serves both (`_ellipse`).

p0 from the tensile strength sigma_t (`p0_rule`):

- ``"paper"``: Eq. 6 exactly as printed, with p_t = sqrt(3) sigma_t / 2 and
  q_t = -sigma_t / 2. A uniaxial tension test then yields at 0.534 sigma_t with the
  "3d" invariants (3.2 kPa for sigma_t = 6 kPa) and at 0.617 sigma_t with "plane".
- ``"uniaxial"``: p0 such that a uniaxial tension test yields at exactly sigma_t (with
  "plane" this is Eq. 6 with the printed pair swapped; physics.md).

Hardening/softening (`xi`): p0 = K sinh(-xi eps_v^p + asinh(p0_init / K)) with the
in-plane volumetric plastic strain eps_v^p (dilation positive) and the in-plane bulk
modulus K = E / (2 (1 - nu)) (explicit, as in the "SinhExpl" law of the MATTER MPM code);
xi = 0 is perfect plasticity. Dilation softens the slab in tension.

Return mapping: associative closest-point projection, solved for the plastic multiplier
with a safeguarded Newton iteration of fixed length (vmappable, NaN-free,
differentiable). Width-uniform strips with free edges (sigma_yy = 0) use the exact
uniaxial projection.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from damjax.materials import slab

P0_RULES = ("paper", "uniaxial")
INVARIANTS = ("3d", "plane")
_NEWTON_ITERS = 8
# Newton steps of the softening return map: for a fixed band opening 6 reach 4e-8
# relative over sigma_trial in (1, 3) sigma_y, band widths 0.005-0.08 m and 0-5 w_c of
# other openings (float64); 5 reach 4e-3. With the band's openings updated at each step
# (`damjax.core.step.constitutive`), 4 give 0.99-1.00 G_f h per fracture on a 20 m PST
# (dx 0.08-0.02; 3: 0.98; 6: 1.000) at 0.86 of the 1.09 ms per step that 6 take.
_SOFTENING_ITERS = 4
# fixed-point iterations of the plane-stress softening map (`return_map_plane_softening`):
# a fracture across a 0.3 m strip (20 m PST, dx 0.08) dissipated 1.73 / 1.31 / 1.06 /
# 1.03 G_f h W with 0 / 1 / 4 / 8 of them (1.09 and 1.06 with 4 on dx 0.04 and 0.02)
_PLANE_SOFTENING_ITERS = 4
SETTLED = 1e-4  # p0 of a band / its intact p0 at or below which the band has let go


def _sqrt(x: Any) -> Any:
    """sqrt with a finite gradient at 0 (the double-where idiom)."""
    pos = x > 0.0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


@jax.custom_jvp
def _div(x: Any, y: Any) -> Any:
    """x / y (x / 1 where y = 0: callers select another value there), with a finite
    gradient everywhere: exact where y^2 is a normal float (above 4x the smallest), zero
    below. Reverse mode takes d(x / y) / dy = -x y^-2: for |y| below ~1e-19 in float32
    y^2 is subnormal, which XLA flushes to zero (on CPUs and GPUs), so y^-2 = inf, and
    0 * inf = NaN even where the cotangent is zero, as in a branch that a `jnp.where` or
    a `jnp.maximum` discards. The value is x / y unchanged, from one division (a custom
    JVP carries the guarded derivative: two divisions in the forward pass made the Fig.
    12a slope, whose plane return map divides in every Newton iteration, 1.2 x slower)."""
    return x / jnp.where(y != 0.0, y, 1.0)


@_div.defjvp
def _div_jvp(primals: Any, tangents: Any) -> Any:
    x, y = primals
    dx, dy = tangents
    q = _div(x, y)
    tiny = 4.0 * float(jnp.finfo(jnp.result_type(y)).tiny)
    big = y * y > tiny
    # (dx - q dy) / y where y^2 is normal, else 0: both coefficients finite
    return q, jnp.where(big, (dx - q * dy) / jnp.where(big, y, 1.0), 0.0)


def p0_from_tensile_strength(
    sigma_t: Any, M: Any, beta: Any, rule: str = "paper", invariants: str = "3d"
) -> Any:
    """Consolidation pressure p0 [Pa] from the tensile strength sigma_t [Pa] (Eq. 6)."""
    finite = jnp.isfinite(sigma_t)
    st = jnp.where(finite, sigma_t, 1.0)
    if rule == "paper":
        p_t, q_t = jnp.sqrt(3.0) * st / 2.0, -st / 2.0
        p0 = -(1.0 - beta) * p_t / (2.0 * beta) + jnp.sqrt(
            ((beta + 1.0) * p_t / (2.0 * beta)) ** 2 + (q_t / M) ** 2 * (1.0 + 2.0 * beta) / beta
        )
    elif rule == "uniaxial":  # the uniaxial tensile strength is proportional to p0
        p0 = st / uniaxial_strengths(jnp.ones_like(st), M, beta, invariants)[0]
    else:
        raise ValueError(f"p0_rule = {rule!r}: must be in {{paper, uniaxial}}")
    return jnp.where(finite, p0, jnp.inf)


def _ellipse(p0: Any, M: Any, beta: Any, invariants: str) -> tuple[Any, Any, Any, Any]:
    """(alpha, gamma, p_c, R) of y = alpha q2^2 + gamma (p2 - p_c)^2 - R in the in-plane
    invariants (p2, q2) of the "plane" choice (see the module doc)."""
    alpha = 1.0 + 2.0 * beta
    if invariants == "plane":
        return alpha, M**2, -0.5 * (beta - 1.0) * p0, (M * 0.5 * (beta + 1.0) * p0) ** 2
    if invariants != "3d":
        raise ValueError(f"mcc_invariants = {invariants!r}: must be in {{3d, plane}}")
    # alpha (q2^2 + p2^2) + M^2 (2 p2 / 3 + beta p0) (2 p2 / 3 - p0)
    gamma = alpha + 4.0 * M**2 / 9.0
    p_c = -(M**2) * (beta - 1.0) * p0 / (3.0 * gamma)
    return alpha, gamma, p_c, gamma * p_c**2 + M**2 * beta * p0**2


def yield_function(p: Any, q: Any, p0: Any, M: Any, beta: Any) -> Any:
    """y(p, q) [Pa^2] (paper Eq. 5); <= 0 inside the surface."""
    return q**2 * (1.0 + 2.0 * beta) + M**2 * (p + beta * p0) * (p - p0)


def invariants(sigma: Any, kind: str = "3d") -> tuple[Any, Any]:
    """(p, q) [Pa] of in-plane stress components (3, n) = (xx, yy, xy), sigma_zz = 0."""
    if kind == "3d":
        p = -(sigma[0] + sigma[1]) / 3.0
        q = _sqrt(sigma[0] ** 2 + sigma[1] ** 2 - sigma[0] * sigma[1] + 3.0 * sigma[2] ** 2)
        return p, q
    p = -0.5 * (sigma[0] + sigma[1])
    half = 0.5 * (sigma[0] - sigma[1])
    q = _sqrt(1.5 * (2.0 * half**2 + 2.0 * sigma[2] ** 2))
    return p, q


def uniaxial_strengths(p0: Any, M: Any, beta: Any, invariants: str = "3d") -> tuple[Any, Any]:
    """(tensile, compressive) uniaxial yield stresses [Pa], both positive, for p0."""
    alpha, gamma, p_c, R = _ellipse(p0, M, beta, invariants)
    # (p2, q2) = (-sigma/2, sqrt(3)/2 |sigma|) on the ellipse: a sigma^2 + b sigma + c = 0
    a = (3.0 * alpha + gamma) / 4.0
    b = gamma * p_c
    c = gamma * p_c**2 - R
    disc = jnp.sqrt(b * b - 4.0 * a * c)
    return (-b + disc) / (2.0 * a), (b + disc) / (2.0 * a)


def softened_p0(p0_init: Any, eps_pv: Any, xi: Any, bulk: Any) -> Any:
    """SinhExpl law: p0 = K sinh(-xi eps_v^p + asinh(p0_init / K)), floored at 1e-2 Pa.

    Evaluated as cosh(a) p0_init + sinh(a) sqrt(K^2 + p0_init^2), a = -xi eps_v^p (the
    same function): no asinh, and one exp. XLA:CPU evaluates sinh and asinh through scalar
    expm1 and log1p: they were a quarter of a 1D PST step (100 m, dx 0.02: 0.30 -> 0.22
    ms). xi = 0 gives p0_init exactly.
    """
    finite = jnp.isfinite(p0_init)
    p0i = jnp.where(finite, p0_init, 1.0)
    a = -xi * eps_pv
    e = jnp.exp(a)
    small = jnp.abs(a) < 1e-2  # sinh from its series: (e - 1 / e) / 2 cancels
    sinh = jnp.where(small, a * (1.0 + a * a / 6.0), 0.5 * (e - 1.0 / e))
    cosh = 0.5 * (e + 1.0 / e)
    p0 = cosh * p0i + sinh * jnp.sqrt(bulk * bulk + p0i * p0i)
    return jnp.where(finite, jnp.maximum(p0, 1e-2), jnp.inf)


def crack_band_opening(
    p0_init: Any, fracture_energy: Any, M: Any, beta: Any, invariants: str = "3d"
) -> Any:
    """Characteristic opening w_c = G_f / sigma_y [m] of the crack-band softening
    (`crack_band_factor`); inf where G_f or p0 is infinite (no softening)."""
    finite = jnp.isfinite(p0_init) & jnp.isfinite(fracture_energy)
    sigma_y = uniaxial_strengths(jnp.where(finite, p0_init, 1.0), M, beta, invariants)[0]
    return jnp.where(finite, jnp.where(finite, fracture_energy, 1.0) / sigma_y, jnp.inf)


def crack_band_factor(opening: Any, band_width: Any, w_c: Any) -> Any:
    """Crack-band softening of p0 (Bazant & Oh 1983): the factor exp(-w / w_c) [-].

    A perfectly plastic slab localises its tensile fracture in one cell, so the work a
    fracture dissipates, and with it when the slab lets go, scales with the grid spacing.
    Here the band's opening displacement w = ``opening`` x ``band_width`` [m] (the
    accumulated tensile plastic strain times the band width, the grid spacing) softens
    p0, hence the uniaxial tensile yield stress sigma_y, as sigma_y exp(-w / w_c) with
    w_c = G_f / sigma_y (`crack_band_opening`): a fracture then dissipates G_f [J/m^2] per
    unit crack area (slab thickness x crack length) on any grid. w_c = inf gives 1.
    """
    return jnp.exp(-opening * band_width / w_c)


def _flow_uniaxial(sig: Any, p0: Any, M: Any, beta: Any, invariants: str) -> Any:
    """d eps_yy^p / d eps_xx^p of associative flow at the uniaxial state sigma_xx = sig."""
    alpha, gamma, p_c, _ = _ellipse(p0, M, beta, invariants)
    y_p = 2.0 * gamma * (-0.5 * sig - p_c)
    y_q = 2.0 * alpha * (jnp.sqrt(3.0) / 2.0) * jnp.abs(sig)
    sgn = jnp.where(sig >= 0.0, 1.0, -1.0)
    n_xx = -0.5 * y_p + jnp.sqrt(3.0) / 2.0 * sgn * y_q
    n_yy = -0.5 * y_p - jnp.sqrt(3.0) / 2.0 * sgn * y_q
    safe = jnp.abs(n_xx) > 0.0
    return jnp.where(safe, n_yy / jnp.where(safe, n_xx, 1.0), -1.0)


def return_map_uniaxial(
    sig_trial: Any, p0: Any, M: Any, beta: Any, youngs_modulus: Any, invariants: str = "3d"
) -> tuple[Any, Any, Any]:
    """Exact projection of a uniaxial trial stress (free strip, sigma_yy = 0).

    Returns (sigma_xx, d eps_xx^p, d eps_yy^p).
    """
    finite = jnp.isfinite(p0)
    p0s = jnp.where(finite, p0, 1.0)
    st, sc = uniaxial_strengths(p0s, M, beta, invariants)
    sig = jnp.where(finite, jnp.clip(sig_trial, -sc, st), sig_trial)
    d_xx = (sig_trial - sig) / youngs_modulus
    d_yy = d_xx * _flow_uniaxial(sig, p0s, M, beta, invariants)
    return sig, d_xx, d_yy


def _secant(u: Any) -> tuple[Any, Any]:
    """phi(u) = (1 - exp(-u)) / u, the mean of exp(-x) over [0, u], and phi'(u) (u >= 0).

    1 - exp(-u), not expm1: XLA:CPU calls a scalar expm1 (a 100 m PST step took 1.5 x
    longer); below u = 0.01 the series is used, above it 1 - exp(-u) keeps ~1e-5 in float32.
    """
    small = u < 1e-2
    us = jnp.where(small, 1.0, u)
    phi = jnp.where(small, 1.0 - u / 2.0 + u * u / 6.0, (1.0 - jnp.exp(-us)) / us)
    dphi = jnp.where(small, -0.5 + u / 3.0, (jnp.exp(-us) * (1.0 + us) - 1.0) / (us * us))
    return phi, dphi


def return_map_uniaxial_softening(
    sig_trial: Any,
    p0: Any,
    p0_band: Any,
    rate: Any,
    other: Any,
    M: Any,
    beta: Any,
    youngs_modulus: Any,
    invariants: str = "3d",
    settled: Any = 0.0,
) -> tuple[Any, Any, Any]:
    """`return_map_uniaxial` for a crack band whose strength falls as exp(-w / w_c) over
    the step: energy-consistent, so a fracture dissipates G_f on any time step.

    The band opens by ``other`` w_c (the other particles of the band, [-]) plus ``rate``
    x d (this particle's plastic strain increment d; ``rate`` = particle spacing / w_c)
    in the step. The stress after the step is the strength averaged over that opening,
    Y phi(other + rate d), phi(u) = (1 - exp(-u)) / u, with Y = sigma_y(``p0_band``) the
    band's strength at the start; the step's work then equals the integral of the
    softening curve, G_f exactly over a whole fracture. With the strength of the step's
    start (explicit), a step that opens the band by a fraction h of w_c dissipates about
    1 + h / 2 times too much; with the strength of its end (implicit) 1 - h / 2 times
    (here h is 0.5-1: the band opens by tens of micrometres per step and w_c is 37 um).
    A particle yields when the trial stress exceeds its own strength (``p0``: intact
    particles at full strength, so the band does not spread over a tension plateau).
    d solves E d + Y phi(other + rate d) = sigma_trial: for a fixed ``other`` the left
    side is convex in d and negative at 0 for a yielding particle, so the root is unique
    and Newton from sigma_trial / E (right of it) converges monotonically. ``other`` may
    be a function of every particle's current iterate d (the band's openings, coupling
    its particles); it is then re-evaluated at each Newton step (`_SOFTENING_ITERS`).
    ``settled``: p0 [Pa] at or below which a band has let go; the Newton steps are
    skipped while every yielding particle's band is there (0: never skipped).
    Compression: unchanged.
    """
    sig, d_xx, d_yy = return_map_uniaxial(sig_trial, p0, M, beta, youngs_modulus, invariants)
    finite = jnp.isfinite(p0)
    tension = finite & (
        sig_trial > uniaxial_strengths(jnp.where(finite, p0, 1.0), M, beta, invariants)[0]
    )
    st, _ = uniaxial_strengths(jnp.where(finite, p0_band, 1.0), M, beta, invariants)
    E = youngs_modulus
    d = jnp.where(tension, sig_trial / E, 0.0)

    def newton(_: Any, d: Any) -> Any:
        o = other(d) if callable(other) else other
        phi, dphi = _secant(o + rate * d)
        g = E * d + st * phi - sig_trial
        dg = E + st * rate * dphi
        return jnp.where(tension & (dg > 0.0), d - g / jnp.where(dg > 0.0, dg, 1.0), d)

    # a loop, not unrolled: unrolled, XLA:CPU's fusions made a 100 m PST step 1.8 x slower.
    # Skipped while every yielding particle's band has let go (p0_band <= ``settled``):
    # its stress after the step, Y phi <= Y, is then at most the strength of that p0
    # whatever the steps do (the skip leaves it at 0), and what it would still dissipate
    # is the tail of the softening curve, settled / p0 of G_f. After a fracture its band
    # keeps opening at about zero strength: without the skip the steps ran in 9 of 10
    # steps of a 100 m PST (theta 150, 40 000 steps).
    softening = tension & (p0_band > settled)
    d = jax.lax.cond(
        jnp.any(softening),
        lambda d: jax.lax.fori_loop(0, _SOFTENING_ITERS, newton, d),
        lambda d: d,
        d,
    )
    d = jnp.maximum(d, 0.0)
    # d_yy scales with d. d_xx > 0 where tension in exact arithmetic, but XLA recomputes
    # the strength and the trial stress in fusions that round apart (seen on CPU, float64:
    # d_xx = 1e-54 where sig_trial <= st); the reverse, tension where d_xx = 0, made
    # d / d_xx inf and d_yy x inf NaN. There d_yy is d times the flow ratio, and `_div`
    # keeps the gradient of a tiny d_xx finite
    pulled = tension & (d_xx > 0.0)
    ratio = jnp.where(pulled, _div(d, jnp.where(pulled, d_xx, 1.0)), 1.0)
    flow = _flow_uniaxial(sig, jnp.where(finite, p0, 1.0), M, beta, invariants)
    d_yy_t = jnp.where(pulled, d_yy * ratio, d * flow)
    return (
        jnp.where(tension, sig_trial - E * d, sig),
        jnp.where(tension, d, d_xx),
        jnp.where(tension, d_yy_t, d_yy),
    )


def return_map_plane(
    eps_e: Any,
    p0: Any,
    M: Any,
    beta: Any,
    youngs_modulus: Any,
    poisson: Any,
    invariants: str = "3d",
) -> tuple[Any, Any]:
    """Closest-point projection of a plane-stress elastic trial strain (xx, yy, xy).

    ``eps_e`` is three (n,) rows (a tuple or a (3, n) array). Returns (sigma, plastic strain
    increment), each a tuple of three (n,) rows. Elastic states pass through unchanged (bit
    for bit).
    """
    kappa = youngs_modulus / (2.0 * (1.0 - poisson))  # in-plane bulk modulus
    G = youngs_modulus / (2.0 * (1.0 + poisson))
    tr = eps_e[0] + eps_e[1]
    dev = (eps_e[0] - 0.5 * tr, eps_e[1] - 0.5 * tr, eps_e[2])
    p_tr = -kappa * tr
    s_tr = tuple(2.0 * G * d for d in dev)
    q_tr = _sqrt(1.5 * (s_tr[0] ** 2 + s_tr[1] ** 2 + 2.0 * s_tr[2] ** 2))
    finite = jnp.isfinite(p0)
    p0s = jnp.where(finite, p0, 1.0)
    alpha, gamma, p_c, R = _ellipse(p0s, M, beta, invariants)
    plastic = finite & (alpha * q_tr**2 + gamma * (p_tr - p_c) ** 2 - R > 0.0)

    # In the in-plane invariants the surface is alpha q^2 + gamma (p - p_c)^2 = R and
    #   f(dl) = A / (1 + a dl)^2 + B / (1 + 2 b dl)^2 - C,
    # A = alpha q_tr^2, B = gamma (p_tr - p_c)^2, C = R: convex and decreasing,
    # so Newton started below the root converges monotonically (never overshoots).
    a = 6.0 * G * alpha
    b = kappa * gamma
    A = alpha * q_tr**2
    B = gamma * (p_tr - p_c) ** 2
    C = R
    # each one-term root is a lower bound of the root
    dl = jnp.maximum(jnp.maximum((_sqrt(A / C) - 1.0) / a, (_sqrt(B / C) - 1.0) / (2.0 * b)), 0.0)
    for _ in range(_NEWTON_ITERS):
        uq = 1.0 / (1.0 + a * dl)
        up = 1.0 / (1.0 + 2.0 * b * dl)
        f = A * uq**2 + B * up**2 - C
        df = -2.0 * a * A * uq**3 - 4.0 * b * B * up**3
        # _div: an elastic particle (dl discarded) with a trial stress of 1e-17 Pa (its
        # strain 1e-23, round-off; beta = 1 centres the surface on p = 0) has df ~ 1e-27,
        # whose square flushes to zero: the discarded step's gradient was 0 * inf = NaN
        dl = jnp.maximum(dl - _div(f, jnp.where(df < 0.0, df, -1.0)), 0.0)
    dl = jnp.where(plastic, dl, 0.0)
    q = q_tr / (1.0 + a * dl)
    p = p_c + (p_tr - p_c) / (1.0 + 2.0 * b * dl)
    scale = jnp.where(q_tr > 0.0, q / jnp.where(q_tr > 0.0, q_tr, 1.0), 0.0)
    s = tuple(c * scale for c in s_tr)
    sigma_pl = (s[0] - p, s[1] - p, s[2])
    sigma_el = slab.plane_stress(eps_e, youngs_modulus, poisson)
    sigma = tuple(jnp.where(plastic, a, b) for a, b in zip(sigma_pl, sigma_el, strict=True))
    # plastic strain = trial elastic strain - elastic strain of the returned stress
    tr_new = -2.0 * p / (2.0 * kappa)
    dev_new = tuple(c / (2.0 * G) for c in s)
    eps_e_new = (dev_new[0] + 0.5 * tr_new, dev_new[1] + 0.5 * tr_new, dev_new[2])
    d_eps_p = tuple(jnp.where(plastic, eps_e[i] - eps_e_new[i], 0.0) for i in range(3))
    return sigma, d_eps_p


def return_map_plane_softening(
    eps_e: Any,
    p0: Any,
    p0_band: Any,
    increase: Any,
    M: Any,
    beta: Any,
    youngs_modulus: Any,
    poisson: Any,
    invariants: str = "3d",
    settled: Any = 0.0,
) -> tuple[Any, Any]:
    """`return_map_plane` for a crack band whose strength falls as exp(-w / w_c): the
    plane-stress counterpart of `return_map_uniaxial_softening`, energy-consistent.

    A particle yields when its trial state leaves the surface of its own ``p0`` (intact
    particles at full strength). One that yields on the dilatant side (opening, not
    compaction) returns onto the surface of its band's strength averaged over the step's
    opening, p0_band phi(u), phi(u) = (1 - exp(-u)) / u: the surface scales with p0, so the
    stress is the softening curve's mean over the step and a whole fracture dissipates
    G_f. ``increase(d_eps_p)`` is u, the increase of the band's opening over the step in
    units of w_c, given every particle's plastic strain increment (the band's particles
    open together).

    s = phi(u) is found by fixed-point iteration from s = 1 for all particles at once: a
    smaller s lets every yielding particle open further, so s -> phi(u(s)) is
    order-preserving and the iterates fall monotonically towards its largest fixed point
    (`_PLANE_SOFTENING_ITERS` of them; they stay above it, towards the strength of the
    step's start). Skipped while every such particle's band has let go (``p0_band`` at most
    ``settled`` [Pa]). Compaction and elastic states: `return_map_plane` with ``p0``.
    """
    args = (M, beta, youngs_modulus, poisson, invariants)
    sigma, d_eps_p = return_map_plane(eps_e, p0, *args)
    dilates = (d_eps_p[0] + d_eps_p[1]) > 0.0

    def surface(s: Any) -> tuple[Any, Any]:
        return return_map_plane(eps_e, jnp.where(dilates, p0_band * s, p0), *args)

    def iterate(_: Any, s: Any) -> Any:
        return _secant(increase(surface(s)[1]))[0]

    s = jax.lax.cond(
        jnp.any(dilates & (p0_band > settled)),
        lambda s: jax.lax.fori_loop(0, _PLANE_SOFTENING_ITERS, iterate, s),
        lambda s: s,
        jnp.ones_like(p0_band),
    )
    sig_s, d_s = surface(s)
    return (
        tuple(jnp.where(dilates, a, b) for a, b in zip(sig_s, sigma, strict=True)),
        tuple(jnp.where(dilates, a, b) for a, b in zip(d_s, d_eps_p, strict=True)),
    )
