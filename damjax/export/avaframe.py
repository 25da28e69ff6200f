"""AvaFrame export: an avalanche directory whose release areas are damjax's release zones.

AvaFrame (avaframe.org, com1DFA: dense flow avalanche runout) reads an avalanche
directory ``AVADIR/Inputs/`` with exactly one DEM (``.asc`` or ``.tif``) and one or more
release-area shapefiles in ``Inputs/REL/`` (`avaframe.in1Data.getInput.getInputDataCom1DFA`);
with its default ``relThFromFile = True`` the release thickness of each polygon is the
shapefile attribute ``thickness`` (or ``d0``; names are lower-cased,
`avaframe.in2Trans.shpConversion.readThickness`), "measured normal to the slope"
(com1DFACfg.ini), as damjax's slab thickness is. `export_avaframe` writes

- ``Inputs/<dem>.asc`` (+ ``.prj``): the run's DEM as an ESRI ASCII grid (copied, or
  converted from GeoTIFF / NetCDF);
- ``Inputs/REL/<name>.shp`` (+ ``.dbf``, ``.shx``, ``.prj``, ``.cpg``): the release zones
  (`damjax.export.gis.release_zones`, interior rings dropped: AvaFrame reads each part of
  a polygon as an outline) with ``name`` (rel1, rel2, ...) and ``thickness`` [m] (mean
  final slab column height over the zone: its slab volume / area) and damjax's area
  attributes;
- the other input folders AvaFrame's ``initializeFolderStruct`` creates (empty), and
  ``damjax_export.json`` (source run, zones, thickness rule).

Running com1DFA on it: ``verification/avaframe_runout.py``. AvaFrame pins numpy < 2 (jax needs
numpy >= 2): install it in its own environment (``pip install avaframe``) and point the
benchmark (or the test) at its Python with ``DAMJAX_AVAFRAME_PYTHON``.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

from damjax.export import gis

INPUT_FOLDERS = ("CFGs", "RES", "REL", "SECREL", "ENT", "POINTS", "LINES", "POLYGONS", "RELTH")
INPUT_FOLDERS += ("RASTERS",)


def export_avaframe(
    run: str | os.PathLike,
    avadir: str | os.PathLike,
    *,
    scenario: Any = None,
    dem: str | os.PathLike | None = None,
    crs: Any = None,
    threshold: float = 0.5,
    min_cells: int = 4,
    name: str | None = None,
    thickness: float | None = None,
) -> dict[str, Path]:
    """Write an AvaFrame avalanche directory for the release zones of a DEM slope run.

    Args:
        run: a slope run folder (``results.nc``), an ensemble folder or either file.
        avadir: the avalanche directory (created; its ``Inputs/`` DEM and ``Inputs/REL``
            shapefiles are replaced).
        scenario: as for `damjax.export.gis.frame_of`.
        dem: as for `damjax.export.gis.frame_of`.
        crs: as for `damjax.export.gis.frame_of`.
        threshold: an ensemble's zones are where release_probability >= threshold.
        min_cells: zones of fewer cells are left out.
        name: the release scenario's name (the shapefile stem; default the run's
            scenario name, else "damjax_release").
        thickness: release thickness [m] for every zone instead of the zone's mean
            column height.

    Returns {name: path} of the files written. A run on a "plane" or "generic" terrain has
    no DEM for AvaFrame: ValueError.
    """
    ds = gis.open_run(run)
    frame = gis.frame_of(ds, scenario, dem=dem, crs=crs)
    if frame.local or frame.dem is None:
        raise ValueError(
            f"{run}: the run's terrain is not a DEM; AvaFrame needs one (terrain.kind = "
            '"dem" in the scenario)'
        )
    if thickness is not None and not (thickness > 0 and thickness < 100):
        raise ValueError(f"thickness = {thickness}: must be in (0, 100) m")
    zones = gis.release_zones(
        ds, frame, threshold=threshold, min_cells=min_cells, scenario=scenario, fill_holes=True
    )
    if len(zones) == 0:
        raise ValueError(f"{run}: no release zone of at least {min_cells} cells to export")
    if thickness is not None:
        zones["thickness"] = float(thickness)
    if name is None:
        table = gis._maybe_table(ds, scenario) or {}
        name = str(table.get("name") or "damjax_release")
    stem = "".join(c if c.isalnum() or c in "-_" else "_" for c in name)
    root = Path(avadir)
    inputs = root / "Inputs"
    for sub in INPUT_FOLDERS:
        (inputs / sub).mkdir(parents=True, exist_ok=True)
    files: dict[str, Path] = {}
    # exactly one DEM in Inputs/ (AvaFrame's getDEMPath)
    for old in list(inputs.glob("*.asc")) + list(inputs.glob("*.tif")):
        old.unlink()
        old.with_suffix(".prj").unlink(missing_ok=True)
    src = Path(frame.dem)
    dem_out = inputs / f"{src.stem}.asc"
    if src.suffix.lower() == ".asc":
        shutil.copyfile(src, dem_out)
    else:
        from damjax import terrain

        terrain.save_esri_ascii(terrain.load_dem(src), dem_out)
    files["dem"] = dem_out
    if frame.crs is not None:
        prj = dem_out.with_suffix(".prj")
        prj.write_text(frame.crs.to_wkt(version="WKT1_ESRI"), encoding="utf-8")
        files["dem_prj"] = prj
    rel = inputs / "REL"
    for old in rel.iterdir():
        if old.is_file():
            old.unlink()
    files.update(gis.write_release_zones(zones, rel, stem=stem, formats=("shp",)))
    files["release"] = files.pop("zones_shp")
    from damjax import io

    meta = {
        "source": str(Path(run).resolve()),
        "dem": str(src),
        "crs": frame.crs.to_string() if frame.crs is not None else None,
        "release_scenario": stem,
        "thickness_rule": "given" if thickness is not None else "mean final slab column height",
        "zones": zones.drop(columns="geometry").to_dict("records"),
    }
    io.write_json(root / "damjax_export.json", meta)
    files["metadata"] = root / "damjax_export.json"
    return files
