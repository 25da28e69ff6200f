"""Weak-layer strength fields: GRF statistics, gradients, profile fits and CSV loaders."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from damjax import fields
from damjax.data import synthetic_strength_map_path

N_SAMPLES = 500
SHAPE = (32, 32)
DX = 1.0


def _lag_correlation(f: np.ndarray, lag: tuple[int, int]) -> float:
    """Pooled correlation of zero-mean fields (batch, nx, ny) at a lag in cells."""
    i, j = lag
    nx, ny = f.shape[1:]
    lo, hi = max(0, -j), ny - max(0, j)  # columns q with q and q + j on the grid
    a = f[:, : nx - i, lo:hi]
    b = f[:, i:, lo + j : hi + j]
    return float(np.mean(a * b) / np.mean(f**2))


LAGS = [(3, 0), (0, 3), (2, 2), (2, -2)]  # (2, 2) and (2, -2) tell the rotation's sense
ANISO = dict(length_scale=(6.0, 3.0), angle_deg=30.0)
MEAN, STD, TREND = 1000.0, 100.0, (20.0, -5.0)


def _draw(key, **kw) -> np.ndarray:
    """N_SAMPLES fields on SHAPE, unclipped."""
    keys = jax.random.split(key, N_SAMPLES)
    return np.asarray(
        jax.vmap(lambda k: fields.grf(k, SHAPE, DX, floor=None, **kw))(keys), dtype=float
    )


@pytest.fixture(scope="module")
def aniso_samples() -> np.ndarray:
    """500 anisotropic, rotated Gaussian-covariance fields with a trend [Pa]."""
    return _draw(jax.random.key(0), mean=MEAN, std=STD, trend=TREND, **ANISO)


def _standardised(f: np.ndarray) -> np.ndarray:
    x, y = fields.grid_coordinates(SHAPE, DX)
    return (f - (MEAN + TREND[0] * x[:, None] + TREND[1] * y[None, :])) / STD


def test_grf_mean_and_trend(aniso_samples):
    z = _standardised(aniso_samples)
    # per node, the mean of 500 unit-variance samples is within 5 standard errors of 0
    assert np.max(np.abs(z.mean(axis=0))) < 5.0 / np.sqrt(N_SAMPLES)


@pytest.mark.parametrize("model", ["gaussian", "exponential"])
def test_grf_matches_analytic_covariance(model, aniso_samples):
    """Sample variance and correlations at four lags match C(h) within 5 % (no gstools)."""
    if model == "gaussian":
        z = _standardised(aniso_samples)
        kw = ANISO
    else:
        kw = dict(length_scale=(4.0, 4.0), angle_deg=0.0)
        z = _draw(jax.random.key(1), mean=0.0, std=1.0, model=model, **kw)
    assert np.mean(z**2) == pytest.approx(1.0, rel=0.05)
    for lag in LAGS:
        expect = float(
            fields.correlation(lag, kw["length_scale"], angle_deg=kw["angle_deg"], model=model)
        )
        assert _lag_correlation(z, lag) == pytest.approx(expect, rel=0.05), lag


def test_grf_matches_gstools(aniso_samples):
    """Same variance and correlations (anisotropic, rotated) as gstools over 500 samples."""
    gs = pytest.importorskip("gstools")
    ls, angle = ANISO["length_scale"], ANISO["angle_deg"]
    model = gs.Gaussian(dim=2, var=1.0, len_scale=list(ls), angles=np.radians(angle))
    # the randomisation method's covariance is exact in expectation for any mode count
    srf = gs.SRF(model, mode_no=128)
    x, y = fields.grid_coordinates(SHAPE, DX)
    ref = np.stack([srf.structured([x, y], seed=s) for s in range(N_SAMPLES)])
    z = _standardised(aniso_samples)
    assert np.mean(z**2) == pytest.approx(np.mean(ref**2), rel=0.05)
    for lag in LAGS:
        assert _lag_correlation(z, lag) == pytest.approx(_lag_correlation(ref, lag), rel=0.05)


def test_grf_floor_and_1d():
    low = fields.grf(jax.random.key(3), (25, 30), 2.0, mean=0.0, std=100.0, length_scale=5.0)
    assert float(low.min()) == fields.TAU_FLOOR
    line = fields.grf(
        jax.random.key(4), (200,), 0.5, mean=0.0, std=1.0, length_scale=3.0, trend=1.0, floor=None
    )
    assert line.shape == (200,)
    assert np.all(np.isfinite(np.asarray(line)))


def test_grf_reproducible_with_seed():
    kw = dict(mean=1000.0, std=100.0, length_scale=(10.0, 5.0), trend=20.0)
    a = fields.grf(jax.random.key(7), (25, 30), 2.0, **kw)
    b = fields.grf(jax.random.key(7), (25, 30), 2.0, **kw)
    c = fields.grf(jax.random.key(8), (25, 30), 2.0, **kw)
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert float(jnp.max(jnp.abs(a - c))) > 10.0


@pytest.mark.min_versions
def test_grf_sample_does_not_depend_on_the_precision_mode():
    # a float64 run (or anything that enables jax_enable_x64 in the session) must see the
    # same field for the same seed as a float32 run, to rounding (the white noise is drawn
    # in float32 either way; the float32 transform drops more near-zero eigenvalues)
    kw = dict(mean=1000.0, std=100.0, length_scale=(8.0, 8.0), trend=(20.0, 0.0))
    a = np.asarray(fields.grf(jax.random.key(3), (40, 50), 0.5, **kw), dtype=float)
    with jax.enable_x64(True):
        b = np.asarray(fields.grf(jax.random.key(3), (40, 50), 0.5, **kw))
    assert b.dtype == np.float64
    assert np.max(np.abs(a - b)) < 2.0  # Pa, against a std of 100 Pa
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.9999


def test_grf_gradients_are_finite_and_match_finite_differences():
    """d var(field) / d (std, l) by jax.grad agrees with central differences (float64)."""
    with jax.enable_x64(True):
        key = jax.random.key(5)

        def stat(std, ls):
            f = fields.grf(
                key,
                (25, 30),
                2.0,
                mean=1000.0,
                std=std,
                length_scale=(ls, 0.7 * ls),
                angle_deg=20.0,
                trend=20.0,
                floor=None,
                embed_shape=(128, 128),
            )
            return jnp.var(f)

        g_std, g_ls = jax.grad(stat, argnums=(0, 1))(100.0, 10.0)
        eps = 1e-4
        fd_std = (stat(100.0 + eps, 10.0) - stat(100.0 - eps, 10.0)) / (2 * eps)
        fd_ls = (stat(100.0, 10.0 + eps) - stat(100.0, 10.0 - eps)) / (2 * eps)
        assert np.isfinite(g_std) and np.isfinite(g_ls)
        assert float(g_std) == pytest.approx(float(fd_std), rel=1e-5)
        assert float(g_ls) == pytest.approx(float(fd_ls), rel=1e-3)
    # float32 default, exponential model, embedding derived from the concrete length
    g = jax.grad(
        lambda ls: jnp.mean(
            fields.grf(
                key,
                (16, 16),
                1.0,
                mean=0.0,
                std=1.0,
                length_scale=ls,
                model="exponential",
                floor=None,
            )
            ** 2
        )
    )(4.0)
    assert np.isfinite(float(g))


@pytest.mark.min_versions
def test_grf_jit_needs_embed_shape_for_traced_lengths():
    key = jax.random.key(0)
    shape = (25, 30)

    def sample(ls, embed_shape=None):
        return fields.grf(
            key, shape, 2.0, mean=1000.0, std=100.0, length_scale=ls, embed_shape=embed_shape
        )

    with pytest.raises(ValueError, match="embed_shape"):
        jax.jit(sample)(5.0)
    embed = fields.embedding_shape(shape, 2.0, 20.0)
    jitted = jax.jit(lambda ls: sample(ls, embed))
    assert jitted(5.0).shape == shape
    # the jitted field runs XLA's FFT, the concrete one numpy's in float64 on the host: in
    # float64 they are the same field to 1e-8 relative (measured 2026-11-27: 5.6e-12 with
    # jax 0.10.2, 2.4e-9 with jax 0.8.0); in float32 to the float32 transforms' rounding
    # (0.0095 Pa measured, against a std of 100 Pa)
    with jax.enable_x64(True):
        np.testing.assert_allclose(
            jax.jit(lambda ls: sample(ls, embed))(5.0), sample(5.0, embed), rtol=1e-8
        )
    np.testing.assert_allclose(jitted(5.0), sample(5.0, embed), rtol=0, atol=0.02)


def test_concrete_grf_is_the_same_bits_while_xla_is_busy():
    """XLA:CPU's FFT, on a host split into 2 devices, gave another float32 rounding of the
    same seed in 2-9 of 100 draws while a matrix product ran on another thread (two runs
    of one ensemble then differed, 2026-11-27); a concrete draw runs numpy's FFT on the
    host and gives the same bits every time. In a subprocess: the device count is fixed
    when JAX starts."""
    import os
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent(
        """
        import threading
        import jax, jax.numpy as jnp, numpy as np
        from damjax import fields
        kw = dict(mean=0.0, std=150.0, length_scale=2.0, floor=None)
        stop = threading.Event()
        def busy():
            x = jnp.ones((600, 600))
            while not stop.is_set():
                (x @ x).block_until_ready()
        worker = threading.Thread(target=busy)
        worker.start()
        try:
            draws = [np.asarray(fields.grf(jax.random.key(0), (120, 60), 0.1, **kw))
                     for _ in range(60)]
        finally:
            stop.set()
            worker.join()
        print(sum(not np.array_equal(d, draws[0]) for d in draws))
        """
    )
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=2"}
    env["JAX_PLATFORMS"] = "cpu"
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["0"], out.stdout


def test_fit_grf_recovers_parameters():
    """Maximum likelihood on a noisy 16 x 16 map recovers the generating parameters."""
    shape = (16, 16)
    truth = dict(mean=1000.0, std=100.0, length_scale=(4.0, 2.5), trend=(20.0, -5.0))
    tau = np.asarray(fields.grf(jax.random.key(0), shape, 1.0, floor=None, **truth), float)
    tau = tau + np.random.default_rng(0).normal(0.0, 10.0, shape)  # measurement noise
    x, y = np.meshgrid(*fields.grid_coordinates(shape, 1.0), indexing="ij")
    tau[3, 5] = np.nan  # a missing value is ignored
    fit = fields.fit_grf(x, y, tau)
    assert fit.converged and fit.n_points == 255
    np.testing.assert_allclose(fit.length_scale, truth["length_scale"], rtol=0.2)
    assert fit.std == pytest.approx(100.0, rel=0.3)
    assert fit.nugget_std == pytest.approx(10.0, rel=0.2)
    np.testing.assert_allclose(fit.trend, truth["trend"], atol=8.0)
    assert fit.mean == pytest.approx(1000.0, abs=60.0)
    assert set(fit.grf_kwargs()) <= {"mean", "std", "length_scale", "angle_deg", "model", "trend"}


def test_fit_grf_multistart_escapes_a_local_maximum():
    """The shipped map (25 x 16 nodes, truth std 100 Pa, l 8 m) has a second likelihood
    maximum at l 8.7 m, std 254 Pa, where a single start from a fifth of the map size
    ended (before 2026-11-24). The default fit starts from several lengths and keeps the best."""
    x, y, tau = fields.load_strength_map(synthetic_strength_map_path())
    X, Y = np.meshgrid(x, y[:16], indexing="ij")
    t = tau[:, :16]
    fit = fields.fit_grf(X, Y, t, isotropic=True)
    singles = [fields.fit_grf(X, Y, t, isotropic=True, length_scale0=l0) for l0 in (3.0, 9.6)]
    assert fit.converged
    assert fit.neg_log_likelihood <= min(f.neg_log_likelihood for f in singles) + 1e-6
    assert max(f.neg_log_likelihood for f in singles) > fit.neg_log_likelihood + 10.0
    assert fit.std == pytest.approx(100.0, rel=0.2)
    assert fit.length_scale[0] == pytest.approx(8.0, rel=0.1)
    assert fit.trend[0] == pytest.approx(20.0, abs=2.0)
    with pytest.raises(ValueError, match="length_scale0"):
        fields.fit_grf(X, Y, t, length_scale0=[4.0, -1.0])


# --------------------------------------------------------------------------------------
# PST strength profiles
# --------------------------------------------------------------------------------------


def test_linear_and_power_law_profiles():
    x = jnp.array([0.0, 20.0, 30.0, 120.0])
    np.testing.assert_allclose(
        fields.linear_profile(x, 1000.0, 20.0, 500.0), [1000.0, 1000.0, 6000.0, 51000.0]
    )
    np.testing.assert_allclose(
        fields.power_law_profile(x, 500.0, 1.0), fields.linear_profile(x, 1000.0, 20.0, 500.0)
    )
    np.testing.assert_allclose(fields.power_law_profile(x, 2.0, 2.0)[2], 1200.0)
    # gradients in a, b finite also where x <= L_ss (0^b)
    g = jax.grad(lambda ab: jnp.sum(fields.power_law_profile(x, ab[0], ab[1])))(
        jnp.array([2.0, 0.5])
    )
    assert np.all(np.isfinite(np.asarray(g)))


def test_linear_fit_recovers_gradient_with_standard_errors():
    rng = np.random.default_rng(1)
    x = np.linspace(5.0, 25.0, 41)
    tau = 900.0 + 15.0 * (x - 5.0) + rng.normal(0.0, 20.0, x.size)
    fit = fields.fit_linear_profile(x, tau)
    se_theory = 20.0 / np.sqrt(np.sum((x - x.mean()) ** 2))
    assert fit.theta_se == pytest.approx(se_theory, rel=0.3)
    assert abs(fit.theta - 15.0) < 4 * fit.theta_se
    assert abs(fit.tau0 - 900.0) < 4 * fit.tau0_se
    assert fit.x0 == 5.0 and fit.residual_std == pytest.approx(20.0, rel=0.3)


@pytest.mark.parametrize("offset", [True, False])
def test_power_law_fit_recovers_parameters(offset):
    rng = np.random.default_rng(2)
    x = np.linspace(0.0 if offset else 0.5, 30.0, 61)
    a, b, tau0 = 3.0, 1.6, (950.0 if offset else 0.0)
    tau = tau0 + a * x**b + rng.normal(0.0, 10.0, x.size)
    fit = fields.fit_power_law_profile(x, tau, offset=offset)
    for est, true, se in [(fit.a, a, fit.a_se), (fit.b, b, fit.b_se)]:
        assert 0 < se < 0.2 * true
        assert abs(est - true) < 4 * se
    if offset:
        assert abs(fit.tau0 - tau0) < 4 * fit.tau0_se
    assert fit.residual_std == pytest.approx(10.0, rel=0.3)
    np.testing.assert_allclose(fit(x), tau, atol=40.0)


def test_pst_profile_shifts_to_1kpa_at_steady_length():
    x_meas = np.linspace(10.0, 30.0, 21)
    lin = fields.fit_linear_profile(x_meas, 700.0 + 15.0 * (x_meas - 10.0))
    x = np.linspace(0.0, 100.0, 501)
    np.testing.assert_allclose(
        fields.pst_profile(lin, x), fields.linear_profile(x, 1000.0, 20.0, 15.0), atol=1e-8
    )
    pw = fields.fit_power_law_profile(x_meas, 700.0 + 2.0 * (x_meas - 10.0) ** 1.5)
    tau = fields.pst_profile(pw, x, steady_length=25.0)
    np.testing.assert_allclose(
        tau, fields.power_law_profile(x, 2.0, 1.5, steady_length=25.0), rtol=1e-6
    )
    assert tau[0] == 1000.0 and np.all(np.diff(tau) >= 0)


# --------------------------------------------------------------------------------------
# CSV loaders
# --------------------------------------------------------------------------------------

GOOD = "# a transect\nx_m,tau_peak_pa,note\n0.0,1000,a\n1.5,1010,b\n\n3.0,1030.5,c\n"


def test_load_strength_profile(tmp_path):
    path = tmp_path / "ok.csv"
    path.write_text(GOOD)
    x, tau = fields.load_strength_profile(path)
    np.testing.assert_array_equal(x, [0.0, 1.5, 3.0])
    np.testing.assert_array_equal(tau, [1000.0, 1010.0, 1030.5])


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ("x_m,tau_peak_pa\n0,1000\n2,1010\n1,1020\n", ":4: column 'x_m' (1): unsorted"),
        ("x_m,tau_peak_pa\n0,1000\n2,1010\n2,1020\n", ":4: column 'x_m' (1): duplicate"),
        ("x_m,tau_peak_pa\n0,1000\n2,\n", ":3: column 'tau_peak_pa' (2): missing"),
        ("tau_peak_pa,x_m\n1000,0\nNaN,2\n", ":3: column 'tau_peak_pa' (1): missing"),
        ("x_m,tau_peak_pa\n0,1000\n2,-5\n", ":3: column 'tau_peak_pa' (2): negative"),
        ("x_m,tau_peak_pa\n-1,1000\n2,5\n", ":2: column 'x_m' (1): negative"),
        ("x_m,tau_peak_pa\n0,1000\n2,abc\n", ":3: column 'tau_peak_pa' (2): 'abc' is not"),
        ("x,tau_peak_pa\n0,1000\n", ":1: header has no column 'x_m'"),
        ("x_m,tau_peak_pa\n0,1000\n2,1010,7\n", ":3: 3 fields"),
    ],
)
def test_load_strength_profile_errors(tmp_path, body, needle):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(ValueError) as info:
        fields.load_strength_profile(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}:")
    assert needle in message


def test_synthetic_strength_map_is_package_data_and_reproducible():
    path = synthetic_strength_map_path()
    assert path.is_file() and "SYNTHETIC" in path.read_text().splitlines()[0]
    x, y, tau = fields.load_strength_map(path)
    assert tau.shape == (25, 30) and x[1] - x[0] == 2.0 and y[-1] == 58.0
    with jax.enable_x64(True):
        again = fields.grf(
            jax.random.key(20240611),
            (25, 30),
            2.0,
            mean=1000.0,
            std=100.0,
            length_scale=(8.0, 8.0),
            model="gaussian",
            trend=(20.0, 0.0),
        )
    np.testing.assert_allclose(tau, np.asarray(again), atol=0.051)  # file rounds to 0.1 Pa
    # the up-slope mean gradient is the paper's 20 Pa/m (within the sampling error)
    assert fields.fit_linear_profile(x, tau.mean(axis=1)).theta == pytest.approx(20.0, abs=5.0)


@pytest.mark.parametrize(
    "kw,needle",
    [
        ({"length_scale": -4.0}, "length_scale = -4.0: must be in (0, inf) m"),
        ({"length_scale": 0.0}, "length_scale = 0.0: must be in (0, inf) m"),
        ({"length_scale": (1.0, 2.0, 3.0)}, "must have 1 or 2 value(s)"),
        ({"length_scale": 1e4}, "periodic embedding would exceed"),
        ({"std": -100.0}, "std = -100.0: must be in [0, inf) Pa"),
        ({"trend": (1.0, 2.0, 3.0)}, "trend = (1.0, 2.0, 3.0)"),
    ],
)
def test_grf_rejects_bad_arguments_at_once(kw, needle):
    """A negative length scale used to hang (the embedding size search never ended);
    the others failed deep inside jax or were silently dropped."""
    args = {"mean": 1000.0, "std": 100.0, "length_scale": 4.0, **kw}
    with pytest.raises(ValueError) as exc:
        fields.grf(jax.random.key(0), (20, 20), 0.5, **args)
    assert needle in str(exc.value)


def test_grf_inside_jit_with_a_constant_length_scale():
    key = jax.random.key(3)
    f = lambda s: fields.grf(key, (16, 16), 0.5, mean=1000.0, std=s, length_scale=3.0)  # noqa: E731
    np.testing.assert_allclose(np.asarray(jax.jit(f)(100.0)), np.asarray(f(100.0)), rtol=1e-5)


def test_profile_fits_and_terrain_profile_reject_degenerate_input():
    from damjax import calibrate, terrain

    with pytest.raises(ValueError, match="at least 2 different values"):
        fields.fit_linear_profile(np.zeros(5), np.arange(5.0))  # returned theta 0, se 0
    with pytest.raises(ValueError, match="b_bounds"):
        fields.fit_power_law_profile(np.arange(6.0), 1000 + np.arange(6.0) ** 2, b_bounds=(-1, 2))
    with pytest.raises(ValueError, match="same length"):
        calibrate.fit_power_law([1.0, 2.0, 3.0, 4.0, 5.0], [1.0, 2.0, 3.0, 4.0])
    with pytest.raises(ValueError, match="toe_length = 0"):
        terrain.generic_slope_angle(1.0, toe_length=0.0)  # NaN before


def test_strength_map_csv_problems_name_the_file(tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("x_m,y_m,tau_peak_pa\n")
    with pytest.raises(ValueError, match=r"empty.csv: no data rows"):
        fields.load_strength_map(empty)
    uneven = tmp_path / "uneven.csv"
    uneven.write_text(
        "x_m,y_m,tau_peak_pa\n" + "\n".join(f"{x},{y},1000" for x in (0, 1, 3) for y in (0, 1))
    )
    with pytest.raises(ValueError, match=r"uneven.csv: column 'x_m' is not evenly spaced"):
        fields.load_strength_map(uneven)


def test_plateau_trend_field_follows_its_direction():
    """trend_deg turns the trend; mean_at is measured from the edge the trend starts at."""
    dx, nx, ny = 0.5, 20, 30  # a 10 m x 15 m area
    x = (np.arange(nx) + 0.5) * dx
    y = (np.arange(ny) + 0.5) * dx
    kw = dict(mean=1000.0, mean_at=2.0, trend=20.0, std=0.0, length_scale=4.0)
    key = jax.random.key(0)
    up = fields.plateau_trend_field(key, x, ny, dx, **kw)
    np.testing.assert_allclose(up, 1000.0 + 20.0 * np.maximum(x - 2.0, 0.0)[:, None] + 0 * y)
    # -90 deg: rising from the y = 15 m edge towards y = 0, no x dependence
    across = fields.plateau_trend_field(key, x, ny, dx, trend_deg=-90.0, **kw)
    want = 1000.0 + 20.0 * np.maximum(15.0 - y - 2.0, 0.0)
    np.testing.assert_allclose(across, np.broadcast_to(want, (nx, ny)))
    # +90 deg: from the y = 0 edge; 180 deg: down-slope from the top edge
    np.testing.assert_allclose(
        fields.plateau_trend_field(key, x, ny, dx, trend_deg=90.0, **kw)[0],
        1000.0 + 20.0 * np.maximum(y - 2.0, 0.0),
    )
    np.testing.assert_allclose(
        fields.plateau_trend_field(key, x, ny, dx, trend_deg=180.0, **kw)[:, 0],
        1000.0 + 20.0 * np.maximum(10.0 - x - 2.0, 0.0),
        atol=1e-9,
    )
    # with noise the trend is added to the same stationary sample
    kw["std"] = 50.0
    noisy = fields.plateau_trend_field(key, x, ny, dx, **kw)
    noisy_across = fields.plateau_trend_field(key, x, ny, dx, trend_deg=-90.0, **kw)
    np.testing.assert_allclose(noisy - up, noisy_across - across, atol=1e-6)
