import dataclasses
import sys

import numpy as np

sys.path.insert(0, "tests")  # run from the repository root
from test_slab_length_scale import _plastic_work, _small_pst

from damjax.pst import slab_fractures

dims = [int(a) for a in sys.argv[1].split(",")]
for dim in dims:
    for dx in (0.08, 0.04):
        params, setup = _small_pst(dx)
        if dim == 2:
            setup = dataclasses.replace(setup, dim=2, width=0.3)
        model, final, ow, cw = _plastic_work(params, setup)
        x = np.asarray(model.saw_coord)
        fr = slab_fractures(model, final)
        W = model.lattice[1] * model.lattice_spacing if dim == 2 else 1.0
        gfh = float(model.fracture_energy) * float(model.thickness) * W
        if not fr:
            print(dim, dx, "no fracture; total opening work/GfhW", ow.sum() / gfh)
            continue
        near = np.abs(x - fr[0]["x_m"]) < 0.5
        op = x[near & (np.asarray(final.opening) * model.lattice_spacing > 1e-4)]
        print(
            dim,
            dx,
            "fractures",
            [(round(f["x_m"], 2), round(f["t_s"], 3)) for f in fr],
            f"open work/GfhW {ow[near].sum() / gfh:.3f} "
            f"closing {cw[near].sum() / gfh:.3f} total-open {ow.sum() / gfh:.3f}",
            "band width",
            (op.max() - op.min()) if op.size else None,
            flush=True,
        )
