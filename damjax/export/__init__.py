"""Exports of slope runs to the tools downstream: GIS rasters and polygons, AvaFrame.

- `damjax.export.gis`: GeoTIFFs of the slab thickness change, crack arrival time,
  released mask (and release probability of an ensemble) in the DEM's coordinate
  reference system, and the release zones as polygons (GeoPackage, ESRI shapefile,
  optionally GeoJSON) with area and thickness attributes. Needs ``damjax[geo]``.
- `damjax.export.avaframe`: an AvaFrame avalanche directory (``Inputs/`` with the DEM as
  an ESRI ASCII grid and the release zones as a shapefile in ``Inputs/REL/`` with the
  ``thickness`` attribute com1DFA reads). Needs ``damjax[geo]``; running AvaFrame itself
  needs ``avaframe`` (see ``verification/avaframe_runout.py``).

Both read a slope run's folder (``results.nc`` written by ``damjax run``) or an ensemble's
``ensemble.nc`` (with the scenario given separately). Nothing here is imported by
``import damjax``; the optional libraries are imported inside the functions.
"""

from __future__ import annotations

__all__ = ["avaframe", "gis"]


def __getattr__(name: str) -> object:
    # `damjax.export.gis.export_gis(...)` without importing the submodule first
    if name in __all__:
        import importlib

        return importlib.import_module(f"damjax.export.{name}")
    raise AttributeError(f"module 'damjax.export' has no attribute {name!r}")
