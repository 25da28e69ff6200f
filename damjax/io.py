"""Files of a run: atomic writes, pytrees as ``.npz``, results as CF-style NetCDF.

Every writer goes through `atomic_path`: the data is written to a temporary file in the
destination folder, flushed to disk, then moved over the destination with `os.replace`,
so a run killed at any moment leaves either the old file or the new one, never half of
one. Nothing here knows a scenario or the solver: results are read by attribute
(``result.x``, ``result.tip``, ...), pytrees by `jax.tree_util` paths.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io as _io
import json
import math
import os
import tempfile
import time as _time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

TMP_SUFFIX = ".tmp"
# summary keys that differ between identical runs (timings): kept out of results files
TIMING_KEYS = ("compile_time_s", "wall_time_s", "particle_steps_per_s", "phases_s")
_UMASK = os.umask(0o022)
os.umask(_UMASK)

# name -> (CF units, long_name); names not listed keep their name as long_name
VARIABLES: dict[str, tuple[str, str]] = {
    "x": ("m", "distance along the PST from its lower end (particle reference position)"),
    "time": ("s", "simulated time after each time step"),
    "crack_tip": ("m", "crack tip position along the PST"),
    "crack_speed": ("m s-1", "crack speed (central difference of the crack tip)"),
    "sigma_xx": ("Pa", "depth-averaged slab tension sigma_xx at the end of the run"),
    "height": ("m", "slab column height h at the end of the run"),
    "slip": ("m", "slope-parallel weak-layer slip u at the end of the run"),
    "u_max": ("m", "maximum weak-layer slip reached during the run"),
    "tau_peak": ("Pa", "weak-layer peak shear strength tau_p"),
    "opening": ("1", "accumulated tensile plastic strain of the slab (fracture indicator)"),
    "wl_shear": ("Pa", "weak-layer shear stress magnitude at the end of the run"),
    "snapshot_time": ("s", "simulated time at the end of each chunk"),
    "snapshot_tip": ("m", "crack tip position at the end of each chunk"),
    "snapshot_sigma_xx": ("Pa", "depth-averaged slab tension sigma_xx at the end of each chunk"),
    "snapshot_height": ("m", "slab column height h at the end of each chunk"),
    "snapshot_slip": ("m", "slope-parallel weak-layer slip u at the end of each chunk"),
}
_SERIES = ("x", "time", "tip")  # result attributes that are coordinates or series


# --------------------------------------------------------------------------- atomic


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it over ``path`` on success.

    On an exception (or KeyboardInterrupt) the temporary file is removed and ``path``
    is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TMP_SUFFIX)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give the usual permissions
    try:
        yield Path(tmp)
        with open(tmp, "rb+") as fh:  # the data reaches the disk before the rename
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.errno is not None:  # name the file it was for
            raise OSError(exc.errno, f"cannot write {path}: {exc.strerror or exc}") from exc
        raise


def remove_stale_temporaries(folder: str | os.PathLike[str]) -> None:
    """Delete temporary files a killed writer left in ``folder``."""
    for p in Path(folder).glob(f".*{TMP_SUFFIX}"):
        with contextlib.suppress(OSError):
            p.unlink()


def write_text(path: str | os.PathLike[str], text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _finite_or_none(obj: Any) -> Any:
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_or_none(v) for v in obj]
    if isinstance(obj, np.generic):
        return _finite_or_none(obj.item())
    return obj


def to_json(obj: Any) -> str:
    """Strict JSON (non-finite floats become null)."""
    return json.dumps(_finite_or_none(obj), allow_nan=False)


def write_json(path: str | os.PathLike[str], obj: Any) -> None:
    write_text(path, json.dumps(_finite_or_none(obj), indent=2, allow_nan=False) + "\n")


def write_npz(path: str | os.PathLike[str], arrays: dict[str, Any]) -> None:
    """Uncompressed ``.npz`` (no pickles: strings are stored as unicode arrays)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **{k: np.asarray(v) for k, v in arrays.items()})


def read_npz(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """The arrays of an .npz archive; ValueError naming the file if it is not one or is
    damaged (truncated by a full disk or a copy)."""
    import zipfile

    with open(path, "rb") as fh:
        if fh.read(2) != b"PK":
            raise ValueError(f"{path}: not an .npz archive")
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
        raise ValueError(f"{path}: damaged .npz archive ({exc})") from None


def check_figure_path(path: str | os.PathLike[str], field: str = "--plot") -> Path:
    """ValueError unless matplotlib can write ``path``'s format (the suffix; none: PNG)
    and its folder can be made: checked before a run, so the run is not lost."""
    from matplotlib.backend_bases import FigureCanvasBase

    path = Path(path)
    fmt = path.suffix.lstrip(".").lower() or "png"
    formats = FigureCanvasBase.get_supported_filetypes()
    if fmt not in formats:
        raise ValueError(
            f"{field} {path}: unsupported figure format '{fmt}' (supported: "
            + ", ".join(sorted(formats))
            + ")"
        )
    if path.is_dir():
        raise ValueError(f"{field} {path}: is a folder; give a file, e.g. {path / 'pst.png'}")
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{field} {path}: cannot write into {parent} (not a folder)")
    try:  # a real write: permissions alone say nothing for root or on /proc
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError as e:
        raise ValueError(
            f"{field} {path}: cannot write into {parent} ({e.strerror or e})"
        ) from None
    return path


def save_figure(fig: Any, path: str | os.PathLike[str]) -> None:
    """Write a matplotlib figure atomically (format from the suffix) and close it."""
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=fmt, dpi=120)
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


# --------------------------------------------------------------------------- pytrees


def tree_to_arrays(tree: Any, prefix: str) -> dict[str, np.ndarray]:
    """Every leaf of a pytree as a numpy copy, keyed ``prefix + path`` (``state.u``)."""
    import jax

    leaves, _ = jax.tree_util.tree_flatten_with_path(tree)
    return {prefix + jax.tree_util.keystr(p): np.array(x, copy=True) for p, x in leaves}


def arrays_to_tree(arrays: dict[str, np.ndarray], template: Any, prefix: str) -> Any:
    """Inverse of `tree_to_arrays` on the structure of ``template`` (ValueError if the
    saved leaves do not match its names, shapes and dtypes)."""
    import jax

    leaves, treedef = jax.tree_util.tree_flatten_with_path(template)
    names = [prefix + jax.tree_util.keystr(p) for p, _ in leaves]
    saved = sorted(k for k in arrays if k.startswith(prefix))
    if sorted(names) != saved:
        missing = sorted(set(names) - set(saved))
        extra = sorted(set(saved) - set(names))
        raise ValueError(
            f"saved state does not match this damjax version's State (missing: {missing}, "
            f"unexpected: {extra})"
        )
    out = []
    for name, (_, ref) in zip(names, leaves, strict=True):
        arr = arrays[name]
        if arr.shape != np.shape(ref) or arr.dtype != np.asarray(ref).dtype:
            raise ValueError(
                f"saved state leaf {name} has shape {arr.shape} and dtype {arr.dtype}, "
                f"expected {np.shape(ref)} and {np.asarray(ref).dtype}"
            )
        out.append(jax.device_put(arr))
    return jax.tree_util.tree_unflatten(treedef, out)


# --------------------------------------------------------------------------- results


def _var(name: str, dims: tuple[str, ...], data: np.ndarray, meta: Any = None) -> Any:
    """A variable with CF ``units`` and ``long_name`` (from `VARIABLES`, or from the
    ``units``/``long_name`` metadata of the result's dataclass field)."""
    import xarray as xr

    units, long_name = VARIABLES.get(name, (None, name.replace("_", " ")))
    if meta:
        units, long_name = meta.get("units", units), meta.get("long_name", long_name)
    attrs = {"long_name": long_name}
    if units is not None:
        attrs["units"] = units
    return xr.Variable(dims, np.asarray(data), attrs)


def _particle_dims(name: str, arr: np.ndarray, n_x: int, lead: tuple[str, ...]) -> tuple:
    """Dimension names: the particle axis is 'x' when it matches the x coordinate."""
    last = "x" if arr.shape[-1] == n_x else "particle"
    extra = tuple(f"{name}_dim{i}" for i in range(arr.ndim - 1 - len(lead)))
    return lead + extra + (last,)


def result_dataset(
    result: Any,
    *,
    crack_speed: np.ndarray,
    attrs: dict[str, Any],
    snapshots: bool = True,
) -> Any:
    """An `xarray.Dataset` of a PST result (CF-style ``units`` and ``long_name``).

    Coordinates ``x`` (particle reference position) and ``time`` (after each step);
    series ``crack_tip``, ``crack_speed``; every other 1-D array attribute of the
    result (final fields: sigma_xx, height, slip, u_max, tau_peak, ...) on ``x`` (a 2-D
    strip's are width averages; an array of another length goes on ``particle``); the
    per-chunk snapshots as
    ``snapshot_*`` on ``chunk``. ``attrs`` become global attributes.
    """
    import xarray as xr

    x = np.asarray(result.x)
    data: dict[str, Any] = {
        "crack_tip": _var("crack_tip", ("time",), result.tip),
        "crack_speed": _var("crack_speed", ("time",), np.asarray(crack_speed, result.tip.dtype)),
    }
    coords: dict[str, Any] = {
        "x": _var("x", ("x",), x),
        "time": _var("time", ("time",), result.time),
    }
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if f.name in _SERIES or not isinstance(value, np.ndarray) or value.ndim == 0:
            continue
        dims = _particle_dims(f.name, value, x.size, ())
        data[f.name] = _var(f.name, dims, value, f.metadata)
    if snapshots and result.snapshots:
        for key, value in result.snapshots.items():
            value = np.asarray(value)
            name = f"snapshot_{key}"
            if key == "time":
                coords[name] = _var(name, ("chunk",), value)
            elif value.ndim == 1:
                data[name] = _var(name, ("chunk",), value)
            else:
                data[name] = _var(name, _particle_dims(name, value, x.size, ("chunk",)), value)
    clean = {k: (json.dumps(v) if isinstance(v, bool) else v) for k, v in attrs.items()}
    return xr.Dataset(data, coords=coords, attrs={k: v for k, v in clean.items() if v is not None})


def netcdf_engine() -> str:
    """``h5netcdf`` (NetCDF4/HDF5) when its h5py backend is installed, else ``scipy``
    (NetCDF3 with 64-bit offsets; scipy comes with jax)."""
    import importlib.util

    if importlib.util.find_spec("h5netcdf") and importlib.util.find_spec("h5py"):
        return "h5netcdf"
    return "scipy"


def write_dataset(path: str | os.PathLike[str], ds: Any, engine: str | None = None) -> None:
    """Write a dataset as NetCDF (engine: `netcdf_engine` unless given)."""
    engine = engine or netcdf_engine()
    fmt = "NETCDF4" if engine == "h5netcdf" else "NETCDF3_64BIT"
    # coordinates have no missing values (CF): no _FillValue on them
    encoding: dict[str, dict[str, Any]] = {str(k): {"_FillValue": None} for k in ds.coords}
    if engine == "h5netcdf":  # maps and snapshots compress 1.5-5x (deflate, lossless)
        for k, v in ds.data_vars.items():
            if v.dtype.kind in "fiub" and v.size >= 1024:
                encoding[str(k)] = {"zlib": True, "complevel": 4, "shuffle": True}
    with atomic_path(path) as tmp:
        if engine != "h5netcdf":
            ds.to_netcdf(tmp, engine=engine, format=fmt, encoding=encoding)
            return
        # in memory first: a full disk is then an OSError of the write below, not an
        # HDF5 error while the library closes a file it could not write (a segfault)
        buf = _io.BytesIO()
        ds.to_netcdf(buf, engine=engine, format=fmt, encoding=encoding)
        tmp.write_bytes(buf.getbuffer())


def _engine(path: str | os.PathLike[str]) -> str:
    """xarray's engine for a results file, from its first bytes (NetCDF4/HDF5 or NetCDF3)."""
    with open(path, "rb") as fh:
        return "h5netcdf" if fh.read(4) == b"\x89HDF" else "scipy"


def dataset_attrs(path: str | os.PathLike[str]) -> dict[str, Any]:
    """A results file's global attributes, without reading its variables."""
    import xarray as xr

    with xr.open_dataset(path, engine=_engine(path), decode_times=False) as ds:
        return dict(ds.attrs)


def open_dataset(path: str | os.PathLike[str]) -> Any:
    """Read a results file fully into memory (no time decoding: times are seconds).

    The format (NetCDF4/HDF5 or NetCDF3) is recognised from the file's first bytes.
    """
    import xarray as xr

    engine = _engine(path)
    try:
        with xr.open_dataset(path, engine=engine, decode_times=False, decode_timedelta=False) as ds:
            return ds.load()
    except (OSError, ValueError, TypeError, KeyError, RuntimeError) as exc:
        # an empty, truncated or foreign file: xarray's engines fail in their own words
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ValueError(f"{path}: not a readable NetCDF file ({first})") from None


def dataset_fields(ds: Any) -> dict[str, Any]:
    """Arrays of a results dataset under the result's attribute names (``x``, ``time``,
    ``tip``, the final fields, and ``snapshots`` as a dict)."""
    out: dict[str, Any] = {
        "x": ds["x"].values,
        "time": ds["time"].values,
        "tip": ds["crack_tip"].values,
    }
    snaps: dict[str, np.ndarray] = {}
    for name in ds.variables:
        if name in ("x", "time", "crack_tip", "crack_speed"):
            continue
        if name.startswith("snapshot_"):
            snaps[name[len("snapshot_") :]] = ds[name].values
        else:
            out[name] = ds[name].values
    out["snapshots"] = snaps
    return out


# --------------------------------------------------------------------------- TOML


def plain(value: Any) -> Any:
    """A value as plain python for TOML or JSON (floats, lists of floats, str, bool, int)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    arr = np.asarray(value)
    if arr.dtype == bool:
        return bool(arr) if arr.ndim == 0 else arr.tolist()
    if np.issubdtype(arr.dtype, np.integer):
        return int(arr) if arr.ndim == 0 else arr.tolist()
    arr = arr.astype(float)
    return float(arr) if arr.ndim == 0 else arr.tolist()


def plain_fields(obj: Any) -> dict[str, Any]:
    """The fields of a dataclass (parameters, a setup) as plain python, None left out."""
    out = {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    return {k: v for k, v in out.items() if v is not None}


def _toml_str(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def toml_value(v: Any) -> str:
    """A value as TOML writes it (``inf``, ``"text"``, ``[1.0, 2.0]``, ...)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, np.ndarray) or np.isscalar(v):
        return toml_value(plain(v))
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def toml_dumps(data: dict[str, Any]) -> str:
    """TOML text of a dict: top-level keys first, then one table per dict value."""
    lines = [f"{k} = {toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append("")
            lines.append(f"[{k}]")
            lines += [f"{kk} = {toml_value(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- folder locks


def lock_folder(out: Path, name: str, who: str) -> tuple[Any, str | None]:
    """Take ``out/name`` for this run (``who``: the command, for the message): an exclusive
    `fcntl.flock` on a file naming the holder (pid, host, start). The kernel drops the lock
    when its process ends, however it ends, so the file a killed run left behind is taken
    over. Returns the open file (holding the lock) and the text a killed run had left in
    it, or None. ValueError naming the holder when a running process has it. Without
    `fcntl` (Windows): no lock."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not a POSIX system
        return None, None
    import socket

    path = out / name
    for _ in range(10):
        fh = open(path, "a+", encoding="utf-8")  # noqa: SIM115 - held for the run
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip() or "another process"
            fh.close()
            raise ValueError(
                f"{out}: in use by another {who} ({holder}); wait for it to finish, or "
                "give another --out"
            ) from None
        # the holder before us may have removed the file as we opened it: ours must be
        # the file at the path, else try again
        try:
            same = os.stat(path).st_ino == os.fstat(fh.fileno()).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        fh.close()
    else:  # pragma: no cover - the path replaced ten times over
        raise ValueError(f"{out}: cannot take {name}; give another --out")
    fh.seek(0)
    left = fh.read().strip() or None
    fh.seek(0)
    fh.truncate()
    fh.write(
        f"pid {os.getpid()} on {socket.gethostname()}, started "
        f"{_time.strftime('%Y-%m-%d %H:%M:%S')}\n"
    )
    fh.flush()
    return fh, left


@contextlib.contextmanager
def folder_lock(out: Path, name: str, who: str) -> Iterator[str | None]:
    """`lock_folder` for the ``with`` block (yields the text a killed run had left in the
    lock file, or None), then `unlock_folder`."""
    held, left = lock_folder(out, name, who)
    try:
        yield left
    finally:
        unlock_folder(out, name, held)


def unlock_folder(out: Path, name: str, fh: Any) -> None:
    """Remove the lock file, then release it (a process waiting on the removed file
    sees that it is gone and opens the path again)."""
    if fh is None:
        return
    try:
        (out / name).unlink(missing_ok=True)
    finally:
        fh.close()
