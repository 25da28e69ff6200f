"""Data files shipped with damjax (package data; see README.md in this folder)."""

from __future__ import annotations

from pathlib import Path

_HERE = Path(__file__).resolve().parent


def synthetic_strength_map_path() -> Path:
    """Path of ``synthetic_strength_map.csv``: a synthetic weak-layer strength map.

    Columns x_m, y_m [m] (a 25 x 30 grid, 2 m spacing, x up-slope) and tau_peak_pa [Pa];
    made by `damjax.fields.grf` with a fixed seed, not measured. Read it with
    `damjax.fields.load_strength_map`.
    """
    return _HERE / "synthetic_strength_map.csv"
