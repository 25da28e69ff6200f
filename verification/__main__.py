"""List the verification scripts, the page each feeds and what it runs (runs nothing)."""

from __future__ import annotations

import ast
from pathlib import Path

HERE = Path(__file__).resolve().parent
# script -> the page whose figures it produces
PAGES = {
    "pst": "docs/verification/pst.md",
    "fig9_sweep": "docs/verification/fig9.md, plastic.md",
    "slab_fracture_acceptance": "docs/verification/plastic.md, docs/model/slab.md",
    "inversion": "docs/verification/inversion.md",
    "gradients": "docs/guide/gradients.md, docs/verification/inversion.md",
    "slope_acceptance": "docs/verification/slopes.md",
    "slope_runs": "docs/verification/slopes-fig12b.md, docs/guide/slopes.md",
    "slope_calibration_case": "docs/verification/slope-calibration.md",
    "weac_crosscheck": "docs/verification/weac.md",
    "fig12a_ensemble": "docs/guide/sweeps.md",
    "real_path": "docs/guide/real-path.md",
    "real_path_data": "damjax/data/paths (the shipped avalanche paths)",
    "sliding_terrain": "docs/guide/real-path.md",
    "avaframe_runout": "docs/guide/profiles-gis.md",
    "figures": "docs/images/*.png (every page's figures)",
}


def main() -> None:
    for name, page in PAGES.items():
        doc = ast.get_docstring(ast.parse((HERE / f"{name}.py").read_text())) or ""
        first = " ".join(doc.split("\n\n")[0].split())
        print(f"python -m verification.{name}\n    feeds {page}\n    {first}")


if __name__ == "__main__":
    main()
