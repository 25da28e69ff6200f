"""CSV reading shared by the strength profiles and maps: named numeric columns, '#'
comments, missing values and one-line errors naming the file and the line."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

# --------------------------------------------------------------------------------------
# CSV loaders
# --------------------------------------------------------------------------------------

_MISSING = {"", "nan", "na", "n/a", "null", "none"}


def _read_csv(
    path: str | os.PathLike, columns: Sequence[str]
) -> tuple[dict[str, np.ndarray], np.ndarray, dict[str, int]]:
    """Read the named numeric columns of a CSV with '#' comments.

    Returns the arrays by name, the (1-based) file line of every row and the (1-based) file
    column of every name. Every problem is a one-line ValueError
    ``"<file>:<line>: column '<name>' (<k>): <problem>"``.
    """
    path = os.fspath(path)
    with open(path, encoding="utf-8-sig") as f:
        lines = f.read().splitlines()
    header, index, rows, linenos = None, {}, [], []
    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        cells = [c.strip() for c in line.split(",")]
        if header is None:
            header = cells
            for name in columns:
                if name not in header:
                    raise ValueError(
                        f"{path}:{lineno}: header has no column {name!r} "
                        f"(found {', '.join(header)}; expected {', '.join(columns)})"
                    )
                index[name] = header.index(name)
            continue
        if len(cells) != len(header):
            raise ValueError(f"{path}:{lineno}: {len(cells)} fields, the header has {len(header)}")
        values = []
        for name in columns:
            k = index[name]
            cell = cells[k]
            where = f"{path}:{lineno}: column {name!r} ({k + 1})"
            if cell.lower() in _MISSING:
                raise ValueError(f"{where}: missing value")
            try:
                v = float(cell)
            except ValueError:
                raise ValueError(f"{where}: {cell!r} is not a number") from None
            if not math.isfinite(v):
                raise ValueError(f"{where}: missing or infinite value {cell!r}")
            values.append(v)
        rows.append(values)
        linenos.append(lineno)
    if header is None:
        raise ValueError(f"{path}: no header line (expected {', '.join(columns)})")
    data = np.asarray(rows, dtype=float).reshape(-1, len(columns))
    cols = {name: data[:, i] for i, name in enumerate(columns)}
    return cols, np.asarray(linenos), {name: k + 1 for name, k in index.items()}


def _check_nonnegative(path, cols: dict, names: Sequence[str], linenos, index: dict) -> None:
    for name in names:
        bad = np.flatnonzero(cols[name] < 0)
        if bad.size:
            i = bad[0]
            raise ValueError(
                f"{os.fspath(path)}:{linenos[i]}: column {name!r} ({index[name]}): "
                f"negative value {cols[name][i]:g}"
            )
