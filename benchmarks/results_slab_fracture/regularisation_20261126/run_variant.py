"""Run a module (benchmark or script) with a nonlocal crack-band variant switched on.

    python /work/cb_diag/run_variant.py VARIANT -m benchmarks.slab_fracture_acceptance ARGS...
    python /work/cb_diag/run_variant.py VARIANT /work/cb_diag/energy.py 1,2

VARIANT: none | onset_elastic | onset_elastic_max | onset_plastic | nonlocal_softening
"""

import runpy
import sys

from damjax.materials import slab_fracture

variant = sys.argv[1]
slab_fracture.NONLOCAL_VARIANT = None if variant == "none" else variant
assert slab_fracture.NONLOCAL_VARIANT in (None, *slab_fracture.NONLOCAL_VARIANTS)
if sys.argv[2] == "-m":
    sys.argv = [sys.argv[3], *sys.argv[4:]]
    runpy.run_module(sys.argv[0], run_name="__main__", alter_sys=True)
else:
    sys.argv = sys.argv[2:]
    runpy.run_path(sys.argv[0], run_name="__main__")
