"""Files of a run: atomic writes, pytrees in .npz, CF-style NetCDF results."""

import dataclasses
import json
import math
import os
import sys

import jax.numpy as jnp
import numpy as np
import pytest

from damjax import io
from damjax.core.state import State


def test_atomic_write_replaces_or_leaves_the_old_file(tmp_path):
    path = tmp_path / "a.txt"
    io.write_text(path, "old")
    with pytest.raises(RuntimeError), io.atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed while writing")
    assert path.read_text() == "old"
    with pytest.raises(KeyboardInterrupt), io.atomic_path(path) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]  # no temporaries left
    io.write_text(path, "new")
    assert path.read_text() == "new"
    assert oct(path.stat().st_mode & 0o777) == oct(0o666 & ~io._UMASK)


def test_stale_temporaries_are_removed(tmp_path):
    (tmp_path / ".results.nc.abc.tmp").write_text("x")
    (tmp_path / "keep.txt").write_text("x")
    io.remove_stale_temporaries(tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_json_is_strict(tmp_path):
    io.write_json(tmp_path / "s.json", {"a": math.nan, "b": [math.inf, 1.0], "c": np.float32(2)})
    assert json.loads((tmp_path / "s.json").read_text()) == {"a": None, "b": [None, 1.0], "c": 2.0}


def _state(n: int = 4) -> State:
    """A State with every leaf filled (generic over its fields): mixed shapes, dtypes,
    inf and nan."""
    kinds = [
        lambda k: jnp.arange(3 * n, dtype=jnp.float32).reshape(3, n) * (k + 0.5),
        lambda k: jnp.full((n,), jnp.inf if k % 2 else jnp.nan, jnp.float32),
        lambda k: jnp.asarray(0.25 * k, jnp.float32),
        lambda k: jnp.asarray(k % 2 == 0),
        lambda k: jnp.asarray(k, jnp.int32),
    ]
    leaves = {f.name: kinds[k % len(kinds)](k) for k, f in enumerate(dataclasses.fields(State))}
    return State(**leaves)


def test_state_round_trips_bitwise_through_npz(tmp_path):
    state = _state()
    arrays = io.tree_to_arrays(state, "state")
    assert set(arrays) == {"state." + f.name for f in dataclasses.fields(State)}
    io.write_npz(tmp_path / "s.npz", {**arrays, "note": np.array("text")})
    back = io.arrays_to_tree(io.read_npz(tmp_path / "s.npz"), state, "state")
    for a, b in zip(jax_leaves(state), jax_leaves(back), strict=True):
        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)


def jax_leaves(tree):
    import jax

    return [np.asarray(x) for x in jax.tree.leaves(tree)]


def test_mismatched_state_is_a_clean_error(tmp_path):
    arrays = io.tree_to_arrays(_state(4), "state")
    first = "state." + dataclasses.fields(State)[0].name
    with pytest.raises(ValueError, match=f"{first} has shape"):
        io.arrays_to_tree(arrays, _state(5), "state")
    del arrays[first]
    with pytest.raises(ValueError, match=f"missing: \\['{first}'\\]"):
        io.arrays_to_tree(arrays, _state(4), "state")


@dataclasses.dataclass
class FakeResult:
    x: np.ndarray
    time: np.ndarray
    tip: np.ndarray
    sigma_xx: np.ndarray
    slip: np.ndarray
    new_field: np.ndarray
    snapshots: dict
    summary: dict


def _fake() -> FakeResult:
    n, m, k = 6, 10, 3
    x = np.linspace(0.0, 1.0, n, dtype=np.float32)
    return FakeResult(
        x=x,
        time=np.arange(1, m + 1) * 1e-3,
        tip=np.linspace(0, 0.5, m).astype(np.float32),
        sigma_xx=np.arange(n, dtype=np.float32),
        slip=np.arange(2 * n, dtype=np.float32),  # per particle of a 2-D strip
        new_field=np.ones(n, np.float32),
        snapshots={
            "time": np.arange(k, dtype=np.float32),
            "sigma_xx": np.zeros((k, n), np.float32),
            "tip": np.zeros(k, np.float32),
        },
        summary={},
    )


@pytest.mark.min_versions
@pytest.mark.parametrize("engine", ["scipy", "h5netcdf"])
def test_results_dataset_is_cf_style_and_round_trips(tmp_path, engine):
    if engine == "h5netcdf" and io.netcdf_engine() != "h5netcdf":
        pytest.skip("h5py is not installed")
    r = _fake()
    attrs = {"scenario": 'name = "é"\n', "damjax_version": "0.1.0", "fault": None, "b": True}
    ds = io.result_dataset(r, crack_speed=np.zeros(10), attrs=attrs)
    for name, var in ds.variables.items():
        assert var.attrs.get("long_name"), name
        if name != "new_field":
            assert "units" in var.attrs, name
    assert ds["sigma_xx"].dims == ("x",) and ds["slip"].dims == ("particle",)
    assert ds["snapshot_sigma_xx"].dims == ("chunk", "x")
    assert ds["crack_speed"].attrs["units"] == "m s-1"
    assert "fault" not in ds.attrs and ds.attrs["b"] == "true"
    io.write_dataset(tmp_path / "r.nc", ds, engine=engine)
    back = io.open_dataset(tmp_path / "r.nc")
    assert back.identical(ds)
    fields = io.dataset_fields(back)
    assert np.array_equal(fields["tip"], r.tip)
    assert set(fields["snapshots"]) == {"time", "sigma_xx", "tip"}
    assert not [p for p in os.listdir(tmp_path) if p.endswith(io.TMP_SUFFIX)]


def test_snapshots_can_be_left_out():
    ds = io.result_dataset(_fake(), crack_speed=np.zeros(10), attrs={}, snapshots=False)
    assert not [v for v in ds.variables if str(v).startswith("snapshot_")]


def test_plot_leaves_a_chosen_matplotlib_backend_alone():
    """damjax.plot picks Agg only when nothing chose a backend: switching a notebook's inline
    backend (or one set with matplotlib.use) would silently stop figures from showing."""
    import subprocess

    code = (
        "import matplotlib; matplotlib.use('svg'); from damjax import plot; plot._plt(); "
        "print(matplotlib.get_backend())"
    )
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip() == "svg", out.stderr
    code = code.replace("matplotlib.use('svg'); ", "")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip().lower() == "agg", out.stderr


@pytest.mark.min_versions
def test_a_python_result_writes_the_results_file_damjax_run_writes(tmp_path):
    import jax

    import damjax
    from damjax import scenario

    params = damjax.PSTParams(steady_length=3.0)
    setup = damjax.PSTSetup(length=6.0, dx=0.05, duration=0.05)
    r = damjax.simulate_pst(params, setup)
    r.to_netcdf(tmp_path / "r.nc")
    ds = io.open_dataset(tmp_path / "r.nc")
    np.testing.assert_array_equal(ds["crack_tip"].values, r.tip)
    np.testing.assert_array_equal(ds["slip"].values, r.slip)
    assert ds["sigma_xx"].attrs["units"] == "Pa" and ds["x"].size == r.x.size
    back = scenario.loads(ds.attrs["scenario"])
    assert back.params == params and back.setup == setup
    assert "wall_time_s" not in ds.attrs["summary"]
    import equinox as eqx

    with_theta = lambda th: eqx.tree_at(lambda p: p.strength_gradient, params, th)  # noqa: E731
    traced = jax.jit(lambda th: damjax.simulate_pst(with_theta(th), setup))(500.0)
    with pytest.raises(TypeError, match="takes the result of one run of concrete parameters"):
        traced.to_dataset()
    from damjax.plot import plot_pst

    with pytest.raises(TypeError, match="plot_pst takes the result of one run"):
        plot_pst(traced)


def test_files_of_float32_and_float64_runs_share_their_coordinates(tmp_path):
    """x and time come from the layout in float64, so the two precisions' files line up
    (xr.concat without NaN padding); coordinates carry no _FillValue (CF), and the
    NetCDF4 file's large variables are deflated."""
    import h5py
    import xarray as xr

    import damjax

    params = damjax.PSTParams(steady_length=3.0)
    files = []
    for dtype in ("float32", "float64"):
        setup = damjax.PSTSetup(length=6.0, dx=0.05, duration=0.3, dtype=dtype)
        r = damjax.simulate_pst(params, setup)
        assert r.x.dtype == np.float64 and r.time[-1] == 0.3 and r.time.size > 1024
        files.append(tmp_path / f"{dtype}.nc")
        r.to_netcdf(files[-1])
    a, b = (io.open_dataset(f) for f in files)
    assert np.array_equal(a["x"], b["x"]) and np.array_equal(a["time"], b["time"])
    both = xr.concat([a["crack_tip"], b["crack_tip"]], dim="run", join="exact")
    assert not np.isnan(both.values).any()
    with h5py.File(files[0]) as f:
        assert "_FillValue" not in f["x"].attrs and "_FillValue" not in f["time"].attrs
        assert f["crack_tip"].compression == "gzip" and f["crack_speed"].compression == "gzip"


def test_show_takes_a_results_file(tmp_path, capsys):
    """`damjax show FILE`: a PST file's figure goes beside it, named after it (it tried
    FILE/pst.png); a slope file is drawn as a slope (it was given to plot_pst)."""
    import damjax
    from damjax.cli import main

    r = damjax.simulate_pst(
        damjax.PSTParams(steady_length=3.0), damjax.PSTSetup(length=6.0, dx=0.05, duration=0.05)
    )
    r.to_netcdf(tmp_path / "one.nc")
    assert main(["show", str(tmp_path / "one.nc")]) == 0
    assert (tmp_path / "one.png").is_file()
    assert main(["run", "slope-quick", "--out", str(tmp_path / "s"), "--quiet",
                 "--set", "setup.duration=0.05"]) in (0, 3)  # fmt: skip
    capsys.readouterr()
    assert (
        main(["show", str(tmp_path / "s" / "results.nc"), "--plot", str(tmp_path / "s.png")]) == 0
    )
    assert (tmp_path / "s.png").is_file() and "start_slope_deg" in capsys.readouterr().out


def test_a_slope_files_parameters_are_strict_json(tmp_path):
    """An elastic slab's tensile_strength (inf) is stored as "inf" (strict JSON: no
    Infinity token) and read back as inf."""
    import damjax
    from damjax.slope.results import load_result

    setup = damjax.SlopeSetup(length=4.0, width=2.0, dx=0.25, duration=0.02, start=(1.0, 1.0))
    params = damjax.PSTParams(tensile_strength=math.inf)
    r = damjax.simulate_slope(params, setup, slope_deg=35.0, tau_peak=2000.0)
    ds = r.to_dataset()
    stored = json.loads(ds.attrs["params"], parse_constant=lambda c: pytest.fail(c))
    assert stored["tensile_strength"] == "inf"
    json.loads(ds.attrs["summary"], parse_constant=lambda c: pytest.fail(c))
    r.to_netcdf(tmp_path / "s.nc")
    assert math.isinf(load_result(tmp_path / "s.nc").params.tensile_strength)
