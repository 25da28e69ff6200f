"""A release on terrain: snow cover and slab thickness from the ground, a weak layer that
holds its own slab, outflow over the grid's edge, the domain's edge in the summary, random
triggers in the start zone. Small sizes (seconds each)."""

from __future__ import annotations

import dataclasses
import math
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from damjax import PSTParams, SlopeSetup, fields, scenario, simulate_slope, snow_cover
from damjax.core.loop import integrate
from damjax.core.model import build_slope, make_slope_layout
from damjax.scenario import slope_fields
from damjax.slope import simulation
from damjax.slope.simulation import (
    arrival_sources,
    domain_edge_fraction,
    prepare,
    sliding_region,
)

SLAB = PSTParams(thickness=0.5, tensile_strength=4000.0, softening=1.0)


def quiet_parse(doc: dict, **kw) -> scenario.Scenario:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return scenario.parse(doc, **kw)


def quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kw)


# --------------------------------------------------------------------------- snow cover


def test_slope_correction_values():
    """The Swiss guidelines' factor 0.291 / (sin psi - 0.202 cos psi): 1.00 at 28 deg,
    0.71 at 35, 0.52 at 45, 0.41 at 55; held at its 28 deg value on gentler ground."""
    f = snow_cover.slope_correction([28.0, 35.0, 45.0, 55.0])
    np.testing.assert_allclose(f, [1.00, 0.71, 0.52, 0.41], atol=0.005)
    assert snow_cover.slope_correction(15.0) == snow_cover.slope_correction(28.0)
    assert snow_cover.depth_to_thickness(2.0, 60.0) == pytest.approx(1.0)


def _tilted_dem(tmp_path, nx=61, ny=41, steep_from=8.0):
    """An ESRI ASCII DEM rising along +x (1 m nodes), slope 30 deg below x = steep_from and
    rising 2 deg per metre above (70 deg at 28 m), and a mask raster (1 for y < 8 m)."""
    from damjax import terrain

    x = np.arange(nx, dtype=float)
    y = np.arange(ny, dtype=float)
    xs = np.linspace(0.0, nx - 1, 20 * (nx - 1) + 1)
    psi = np.radians(np.clip(30.0 + 2.0 * np.maximum(xs - steep_from, 0.0), 30.0, 70.0))
    zs = np.concatenate([[0.0], np.cumsum(0.5 * (np.tan(psi[1:]) + np.tan(psi[:-1])) * 0.05)])
    z = np.repeat(np.interp(x, xs, zs)[:, None], ny, axis=1)
    terrain.save_esri_ascii(terrain.Terrain(x, y, z), tmp_path / "dem.asc")
    mask = np.zeros((nx, ny))
    mask[:, y < 8.0] = 1.0
    terrain.save_esri_ascii(terrain.Terrain(x, y, mask), tmp_path / "forest.asc")
    hs = np.full((nx, ny), 0.6)
    terrain.save_esri_ascii(terrain.Terrain(x, y, hs), tmp_path / "hs.asc")
    return tmp_path / "dem.asc"


def _dem_doc(dem, **snow) -> dict:
    return {
        "type": "slope",
        "name": "tilted",
        "params": {"thickness": 0.3, "tensile_strength": 4000.0, "softening": 1.0},
        "setup": {
            "length": 30.0,
            "width": 30.0,
            "dx": 0.25,
            "duration": 0.05,
            "particles_per_cell": 1,
            "chunk_steps": 20,
            "start": [4.0, 20.0],
        },
        "terrain": {"kind": "dem", "file": str(dem), "origin": [1.0, 1.0], "upslope": "+x"},
        "snow": {"kind": "uniform", **snow},
        "strength": {"kind": "stability", "mean": 1.42, "cov": 0.1, "length_scale": 4.0},
    }


def _cell_map_points(dem, scn):
    """The raw DEM slope angle [deg] and the map points [m] of the scenario's cell
    centres (origin (1, 1), up-slope +x as `_dem_doc`)."""
    psi, _, px, py = slope_fields.dem_fields(
        __import__("damjax").terrain.load_dem(dem),
        *slope_fields.cell_centres(scn.setup),
        (1.0, 1.0),
        "+x",
        map_points=True,
    )
    return psi, px, py


def test_no_particle_on_steep_or_masked_cells(tmp_path):
    """Cells steeper than snow.max_slope_deg and cells under snow.mask hold no particle
    (and the rest of the domain does)."""
    dem = _tilted_dem(tmp_path, steep_from=4.0)
    doc = _dem_doc(dem, max_slope_deg=60.0, mask="forest.asc")
    scn = quiet_parse(doc, base_dir=tmp_path)
    inp = slope_fields.resolve_inputs(scn)
    psi_raw, px, py = _cell_map_points(dem, scn)
    steep = psi_raw > 60.0
    masked = py < 7.5  # the mask's nearest pixel is 1 below y = 7.5 m (map)
    assert steep.any() and masked.any() and (~steep & ~masked).any()
    layout = make_slope_layout(scn.params, scn.setup, inp.max_slope_deg)
    setup = dataclasses.replace(scn.setup, start=inp.start)
    model, _, xp, yp = build_slope(
        scn.params, setup, layout, inp.slope_deg, inp.tau_peak, inp.fall_deg, **inp.snow_kwargs()
    )
    i, j = (xp / setup.dx).astype(int), (yp / setup.dx).astype(int)
    assert not np.any(steep[i, j]) and not np.any(masked[i, j])
    assert xp.size == np.sum(~steep & ~masked)
    assert np.array_equal(inp.cover, ~steep & ~masked)
    # no particle work where there is no snow: the run's particle count is the cover's
    res = quiet(slope_fields.simulate, scn)
    assert res.summary["n_particles"] == xp.size
    assert res.summary["snow_area_m2"] == pytest.approx(xp.size * setup.dx**2)
    assert np.array_equal(res.snow, inp.cover)
    # the slope map is the terrain's also where no slab lies (a rock face has its angle)
    np.testing.assert_allclose(res.slope_deg[~inp.cover], psi_raw[~inp.cover], rtol=1e-6)
    assert np.all(res.slope_deg[steep] > 60.0)


def test_depth_map_and_slope_corrected_thickness(tmp_path):
    """snow.kind = "depth_map": h = HS cos(psi) per cell; "slope_corrected": d0* f(psi);
    a cell thinner than snow.min_thickness holds no slab."""
    dem = _tilted_dem(tmp_path)
    doc = _dem_doc(dem, max_slope_deg=60.0)
    doc["snow"] = {"kind": "depth_map", "file": "hs.asc", "min_thickness": 0.25}
    doc["setup"]["dx"] = 0.2
    scn = quiet_parse(doc, base_dir=tmp_path)
    inp = slope_fields.resolve_inputs(scn)
    psi = np.asarray(inp.slope_deg)
    want = 0.6 * np.cos(np.radians(psi))
    np.testing.assert_allclose(inp.thickness[inp.cover], want[inp.cover], rtol=1e-9)
    # 0.6 cos(psi) < 0.25 above 65.4 deg; the 60 deg limit comes first here
    assert np.all(inp.thickness[inp.cover] >= 0.25)
    doc["snow"] = {"kind": "slope_corrected", "reference_thickness": 0.8}
    inp = slope_fields.resolve_inputs(quiet_parse(doc, base_dir=tmp_path))
    want = 0.8 * snow_cover.slope_correction(psi)
    np.testing.assert_allclose(inp.thickness[inp.cover], want[inp.cover], rtol=1e-9)


def test_a_snow_raster_without_a_crs_on_a_dem_with_one_is_said(tmp_path):
    """A depth raster or mask that states no CRS is read in the DEM's: said, where it was
    taken silently (a raster in another CRS is refused, one without none was not)."""
    from pyproj import CRS

    dem = _tilted_dem(tmp_path)
    doc = _dem_doc(dem, max_slope_deg=60.0)
    doc["snow"] = {"kind": "depth_map", "file": "hs.asc"}
    doc["setup"]["dx"] = 0.2
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scenario.parse(doc, base_dir=tmp_path)  # no CRS anywhere: nothing to say
    assert not [w for w in caught if "states no CRS" in str(w.message)]
    dem.with_suffix(".prj").write_text(CRS.from_epsg(2056).to_wkt(version="WKT1_ESRI"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scenario.parse(doc, base_dir=tmp_path)
    said = [str(w.message) for w in caught if "states no CRS" in str(w.message)]
    assert said == [
        "snow.file = 'hs.asc': states no CRS; read in the DEM's ('CH1903+ / LV95')"
        ": give the file its CRS (a .prj, or the GeoTIFF's) if it is another"
    ]


def test_snow_key_errors_name_the_key(tmp_path):
    dem = _tilted_dem(tmp_path)
    for snow, match in (
        ({"max_slope_deg": 95.0}, r"snow.max_slope_deg = 95.0: must be a number in \(0, 90\]"),
        ({"kind": "depth_map"}, "snow.file: missing"),
        ({"kind": "deep"}, "snow.kind"),
        ({"reference_thickness": 1.0}, 'only for snow.kind = "slope_corrected"'),
    ):
        doc = _dem_doc(dem)
        doc["snow"] = {"kind": "uniform", **snow}
        with pytest.raises(ValueError, match=match):
            quiet_parse(doc, base_dir=tmp_path)
    doc = _dem_doc(dem)
    doc["strength"] = {"kind": "stability", "mean": 0.9}
    with pytest.raises(ValueError, match=r"strength.mean = 0.9: must be a number in \(1, inf\)"):
        quiet_parse(doc, base_dir=tmp_path)
    doc["strength"] = {"kind": "coulomb", "cohesion": 300.0}
    with pytest.raises(ValueError, match="strength.friction_coefficient: missing"):
        quiet_parse(doc, base_dir=tmp_path)


def _flat_top_dem(tmp_path):
    """An ESRI ASCII DEM rising at 35 deg along +x up to x = 20 m and flat above it
    (a bench: slope exactly 0), 1 m nodes."""
    from damjax import terrain

    x, y = np.arange(41, dtype=float), np.arange(31, dtype=float)
    z = np.repeat((np.minimum(x, 20.0) * math.tan(math.radians(35.0)))[:, None], y.size, axis=1)
    terrain.save_esri_ascii(terrain.Terrain(x, y, z), tmp_path / "bench.asc")
    return tmp_path / "bench.asc"


def test_flat_cells_hold_a_slab_and_a_stability_layer_needs_a_floor_there(tmp_path):
    """Flat ground (0 deg) is terrain too: its cells hold a slab that cannot slide. A
    stability-ratio weak layer has no strength there (S rho g h sin 0 = 0): the scenario
    says so and names the remedies; with a friction floor, or a coulomb layer, it loads."""
    dem = _flat_top_dem(tmp_path)
    doc = _dem_doc(dem)
    doc["setup"].update(length=36.0, width=18.0, dx=0.3, start=[6.0, 9.0])
    doc["params"]["thickness"] = 0.5
    remedies = r"cells are flat \(0 deg\).*friction_coefficient.*snow.mask"
    with pytest.raises(ValueError, match=remedies):
        quiet_parse(doc, base_dir=tmp_path)
    doc["strength"]["friction_coefficient"] = 0.3
    inp = slope_fields.resolve_inputs(quiet_parse(doc, base_dir=tmp_path))
    flat = np.asarray(inp.slope_deg) < 1e-9
    assert flat.any() and (~flat).any() and inp.cover is None  # a slab on the bench too
    rho_g_h = 250.0 * 9.81 * 0.5
    np.testing.assert_allclose(inp.tau_peak[flat], 0.3 * rho_g_h, rtol=1e-9)
    doc["strength"] = {"kind": "coulomb", "cohesion": 500.0, "friction_coefficient": 0.3}
    scn = quiet_parse(doc, base_dir=tmp_path)
    res = quiet(slope_fields.simulate, scn)
    assert res.summary["fault"] is None and res.summary["initial_failure_area_m2"] == 0.0


def test_a_start_on_a_cell_without_snow_is_refused():
    """The crack starts in the slab: a start on a cell without snow is an input error
    naming the start, not a failure after the run."""
    setup = SlopeSetup(length=4.0, width=4.0, dx=0.2, duration=0.01, start=(3.0, 3.0))
    cover = np.zeros((20, 20), bool)
    cover[:8, :8] = True
    with pytest.raises(ValueError, match=r"start = \(3.0, 3.0\): lies on a cell without snow"):
        quiet(simulate_slope, SLAB, setup, slope_deg=38.0, stability=1.4, cover=cover)
    setup = dataclasses.replace(setup, start=(1.0, 1.0), duration=0.002)
    with pytest.warns(UserWarning, match="tau_peak is not used with stability"):
        simulate_slope(SLAB, setup, slope_deg=38.0, tau_peak=900.0, stability=1.4)


def test_the_crack_band_slab_runs_on_a_snow_cover_with_gaps(tmp_path):
    """The crack-band slab sums its band openings over the particles' lattice: on a
    cover with gaps (rock above the snow limit, a mask) the lattice keeps its sites and
    the sites without snow open by 0; on a full cover no site index is kept (the model
    of earlier versions)."""
    dem = _tilted_dem(tmp_path, steep_from=4.0)
    doc = _dem_doc(dem, max_slope_deg=60.0, mask="forest.asc")
    doc["setup"]["slab_fracture"] = "crack_band"
    scn = quiet_parse(doc, base_dir=tmp_path)
    inp = slope_fields.resolve_inputs(scn)
    assert not inp.cover.all()
    prep = slope_fields.prepare(scn)
    model = simulation.build(prep)[0]
    sites = np.asarray(model.fracture.lattice_index)
    assert sites.size == inp.cover.sum() and np.array_equal(
        np.flatnonzero(inp.cover.ravel()), np.sort(sites)
    )
    res = quiet(slope_fields.simulate, scn)
    assert res.summary["fault"] is None and res.summary["release_area_m2"] > 0.0
    assert np.all(np.isfinite(res.height[inp.cover]))
    full = quiet_parse(_plain_doc(setup={**_plain_doc()["setup"], "slab_fracture": "crack_band"}))
    assert simulation.build(slope_fields.prepare(full))[0].fracture.lattice_index is None


def test_a_polygon_mask_is_the_raster_mask_it_draws(tmp_path):
    """snow.mask as polygons (a forest layer: .shp, .gpkg, .geojson) takes the snow off the
    cells inside them, as the raster of the same area does; it need not cover the domain;
    a layer without polygons or in another CRS is refused, naming the key."""
    gpd = pytest.importorskip("geopandas")
    from shapely.geometry import Point, box

    dem = _tilted_dem(tmp_path)
    raster = slope_fields.resolve_inputs(
        quiet_parse(_dem_doc(dem, max_slope_deg=60.0, mask="forest.asc"), base_dir=tmp_path)
    )
    # the raster's pixels with 1 (1 m nodes, y < 8 m) reach y = 7.5 m: the same area
    forest = gpd.GeoDataFrame({"id": [1]}, geometry=[box(-5.0, -5.0, 100.0, 7.5)], crs=2056)
    for name in ("forest.shp", "forest.gpkg", "forest.geojson"):
        forest.to_file(tmp_path / name)
        doc = _dem_doc(dem, max_slope_deg=60.0, mask=name)
        inp = slope_fields.resolve_inputs(quiet_parse(doc, base_dir=tmp_path))
        assert np.array_equal(inp.cover, raster.cover), name
        assert 0 < np.sum(~inp.cover) < inp.cover.size
    # a small stand of trees inside the domain: only its cells lose their snow
    gpd.GeoDataFrame({"id": [1]}, geometry=[box(10.0, 20.0, 14.0, 24.0)], crs=2056).to_file(
        tmp_path / "stand.shp"
    )
    scn = quiet_parse(_dem_doc(dem, max_slope_deg=60.0, mask="stand.shp"), base_dir=tmp_path)
    inp = slope_fields.resolve_inputs(scn)
    _, px, py = _cell_map_points(dem, scn)
    stand = (px >= 10.0) & (px <= 14.0) & (py >= 20.0) & (py <= 24.0)
    assert 16 * 16 < stand.sum() < 16 * 24  # 4 m of map across, 4 m / cos(30 deg) along
    assert np.array_equal(~inp.cover, stand)
    gpd.GeoDataFrame({"id": [1]}, geometry=[Point(10.0, 20.0)], crs=2056).to_file(
        tmp_path / "pt.shp"
    )
    with pytest.raises(ValueError, match=r"snow.mask = 'pt.shp': holds no polygon"):
        quiet_parse(_dem_doc(dem, mask="pt.shp"), base_dir=tmp_path)
    with pytest.raises(ValueError, match=r"snow.mask = 'none.shp': no such file"):
        quiet_parse(_dem_doc(dem, mask="none.shp"), base_dir=tmp_path)
    (tmp_path / "dir.gpkg").mkdir()
    with pytest.raises(ValueError, match=r"snow.mask = 'dir.gpkg': is a folder"):
        quiet_parse(_dem_doc(dem, mask="dir.gpkg"), base_dir=tmp_path)
    (tmp_path / "csv.geojson").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match=r"'csv.geojson': not a polygon layer GDAL can read"):
        quiet_parse(_dem_doc(dem, mask="csv.geojson"), base_dir=tmp_path)
    (tmp_path / "stand.shx").unlink()
    with pytest.raises(ValueError, match=r"'stand.shp': its index file stand.shx is missing"):
        quiet_parse(_dem_doc(dem, mask="stand.shp"), base_dir=tmp_path)
    # a bow tie overlapping a second polygon is repaired, not a GEOS error; polygons in a
    # geometry collection count; a layer that misses the domain warns
    from shapely.geometry import GeometryCollection, LineString, Polygon

    bow = Polygon([(10, 20), (14, 24), (14, 20), (10, 24)])
    gpd.GeoDataFrame(geometry=[bow, box(12, 21, 16, 23)], crs=2056).to_file(tmp_path / "bow.gpkg")
    inp = slope_fields.resolve_inputs(
        quiet_parse(_dem_doc(dem, max_slope_deg=60.0, mask="bow.gpkg"), base_dir=tmp_path)
    )
    assert 0 < np.sum(~inp.cover) < stand.sum() * 2
    coll = GeometryCollection([LineString([(0, 0), (1, 1)]), box(10.0, 20.0, 14.0, 24.0)])
    gpd.GeoDataFrame(geometry=[coll], crs=2056).to_file(tmp_path / "coll.geojson")
    inp = slope_fields.resolve_inputs(
        quiet_parse(_dem_doc(dem, max_slope_deg=60.0, mask="coll.geojson"), base_dir=tmp_path)
    )
    assert np.array_equal(~inp.cover, stand)
    gpd.GeoDataFrame(geometry=[box(500.0, 500.0, 600.0, 600.0)], crs=2056).to_file(
        tmp_path / "far.gpkg"
    )
    with pytest.warns(UserWarning, match=r"snow.mask = 'far.gpkg': no polygon reaches the domain"):
        scenario.parse(_dem_doc(dem, max_slope_deg=60.0, mask="far.gpkg"), base_dir=tmp_path)
    pyproj = pytest.importorskip("pyproj")
    (tmp_path / "dem.prj").write_text(pyproj.CRS.from_epsg(2056).to_wkt())
    forest.set_crs(21781, allow_override=True).to_file(tmp_path / "forest21781.gpkg")
    with pytest.raises(ValueError, match=r"snow.mask = 'forest21781.gpkg': CRS .* differs"):
        quiet_parse(_dem_doc(dem, mask="forest21781.gpkg"), base_dir=tmp_path)


def test_snow_rasters_are_checked_where_they_are_read(tmp_path):
    """A snow raster must cover the domain, hold no negative depth and share the DEM's
    CRS; snow.min_thickness is > 0 and holds for a uniform slab too; the start zone's
    lower edge is below its upper one; terrain.buffer needs a polygon."""
    from damjax import terrain

    dem = _tilted_dem(tmp_path)
    x, y = np.arange(61, dtype=float), np.arange(41, dtype=float)
    small = terrain.Terrain(x[:20], y, np.full((20, 41), 0.6))
    terrain.save_esri_ascii(small, tmp_path / "hs_small.asc")
    neg = np.full((61, 41), 0.6)
    neg[:, 20:] = -0.5
    terrain.save_esri_ascii(terrain.Terrain(x, y, neg), tmp_path / "hs_neg.asc")
    doc = _dem_doc(dem, max_slope_deg=60.0)
    for snow, match in (
        ({"kind": "depth_map", "file": "hs_small.asc"}, r"snow.file = .*hs_small.asc.*covers "),
        ({"kind": "depth_map", "file": "hs_neg.asc"}, r"snow depths down to -0.5 m"),
        ({"kind": "depth_map", "file": "nope.asc"}, r"snow.file = .*nope.asc.*no such file"),
        ({"mask": "hs_small.asc"}, r"snow.mask = .*hs_small.asc.*covers "),
        ({"min_thickness": 0.0}, r"snow.min_thickness = 0.0: must be a number in \(0, inf\)"),
        ({"min_thickness": 0.5}, "no cell of the domain holds a slab"),  # uniform 0.3 m
        ({"start_min_slope_deg": 65.0}, "must be at most snow.max_slope_deg = 60.0"),
    ):
        doc["snow"] = {"kind": "uniform", "max_slope_deg": 60.0, **snow}
        with pytest.raises(ValueError, match=match):
            quiet_parse(doc, base_dir=tmp_path)
    terrain.save_esri_ascii(terrain.Terrain(x, y, np.full((61, 41), 8.0)), tmp_path / "hs8.asc")
    doc["snow"] = {"kind": "depth_map", "file": "hs8.asc", "max_slope_deg": 60.0}
    doc["setup"]["dx"] = 0.2  # 8 m x cos 30 deg the thickest slab
    with pytest.warns(UserWarning, match=r"slab thicknesses up to 6.93 m, above the 5 m"):
        scenario.parse(doc, base_dir=tmp_path)
    doc["setup"]["dx"] = 0.25
    doc["snow"] = {"kind": "uniform"}
    doc["terrain"]["buffer"] = 50.0
    with pytest.raises(ValueError, match="terrain.buffer: the terrain around a release polygon"):
        quiet_parse(doc, base_dir=tmp_path)
    pyproj = pytest.importorskip("pyproj")
    del doc["terrain"]["buffer"]
    (tmp_path / "dem.prj").write_text(pyproj.CRS.from_epsg(2056).to_wkt())
    (tmp_path / "hs.prj").write_text(pyproj.CRS.from_epsg(21781).to_wkt())
    doc["snow"] = {"kind": "depth_map", "file": "hs.asc"}
    with pytest.raises(ValueError, match=r"snow.file = .*hs.asc.*CRS .* differs from the DEM"):
        quiet_parse(doc, base_dir=tmp_path)


# --------------------------------------------------------------------------- bitwise


def _plain_doc(**extra) -> dict:
    doc = {
        "type": "slope",
        "name": "plain",
        "params": {"thickness": 0.5, "tensile_strength": 4000.0, "softening": 1.0},
        "setup": {
            "length": 8.0,
            "width": 4.0,
            "dx": 0.1,
            "duration": 0.12,
            "start": [3.0, 2.0],
            "particles_per_cell": 1,
            "chunk_steps": 40,
        },
        "terrain": {"kind": "generic", "toe_length": 2.0, "roll_length": 2.0},
        "strength": {"kind": "grf", "mean": 1000.0, "std": 100.0, "length_scale": 2.0},
    }
    doc.update(extra)
    return doc


def test_uniform_thickness_is_bitwise_todays_run():
    """A uniform snow cover (scenario [snow] kind = "uniform", or a uniform thickness map
    through the API) runs the scalar model: bitwise the maps of the run without it; and
    the step with outflow (every slope now) is bitwise the step without it (the run of
    earlier versions) while no particle leaves."""
    base = quiet_parse(_plain_doc())
    snow = quiet_parse(_plain_doc(snow={"kind": "uniform", "max_slope_deg": 60.0}))
    a = quiet(slope_fields.simulate, base)
    b = quiet(slope_fields.simulate, snow)
    for name in ("height", "arrival_time", "tension", "opening", "tau_peak"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.summary["release_area_m2"] > 1.0  # a cut that failed the layer: not at rest
    slope, fall, tau, start = slope_fields.resolve_fields(base)
    setup = dataclasses.replace(base.setup, start=start)
    layout = make_slope_layout(base.params, setup, float(np.max(slope)))
    nx, ny = layout.n_cells
    runs = []
    for kw in ({"outflow": False}, {"thickness": np.full((nx, ny), 0.5)}):
        model, state, _, _ = build_slope(base.params, setup, layout, slope, tau, fall, **kw)
        final, *_ = integrate(model, state, layout.n_chunks, layout.chunk_steps)
        runs.append(final)
    assert runs[0].outflow is None and runs[1].outflow is not None
    old, new = (dataclasses.replace(r, outflow=None) for r in runs)
    for x, y in zip(jax.tree.leaves(old), jax.tree.leaves(new), strict=True):
        assert np.array_equal(np.asarray(x), np.asarray(y), equal_nan=True)


# --------------------------------------------------------------------------- weak layer


def test_an_implausibly_wide_stability_field_is_noted():
    doc = _plain_doc()
    doc["strength"] = {"kind": "stability", "mean": 1.42, "cov": 2.0, "length_scale": 2.0}
    with pytest.warns(UserWarning, match=r"strength.cov = 2.0: far above the 10-30 %"):
        scenario.parse(doc)


def test_stability_field_stays_above_one():
    """S - 1 log-normal: S > 1 on every cell of a drawn field, whatever the spread, with
    the mean and coefficient of variation asked for (over many correlation lengths)."""
    x = (np.arange(400) + 0.5) * 0.5
    for seed, cov in ((0, 0.1), (1, 0.3), (2, 0.6)):
        s = fields.stability_field(
            jax.random.key(seed), x, 400, 0.5, mean=1.42, cov=cov, length_scale=4.0
        )
        assert s.min() > 1.0
        assert s.mean() == pytest.approx(1.42, rel=0.05)
        assert s.std() / s.mean() == pytest.approx(cov, rel=0.2)


def _strength_map(tmp_path, doc, weak_at, tau=5000.0, weak=100.0) -> None:
    """A CSV strength map on the run's cell centres, ``weak`` Pa at one cell."""
    s = doc["setup"]
    x = (np.arange(round(s["length"] / s["dx"])) + 0.5) * s["dx"]
    y = (np.arange(round(s["width"] / s["dx"])) + 0.5) * s["dx"]
    xx, yy = np.meshgrid(x, y, indexing="ij")
    t = np.full(xx.shape, tau)
    i, j = np.argmin(np.abs(x - weak_at[0])), np.argmin(np.abs(y - weak_at[1]))
    t[i, j] = weak
    rows = np.column_stack([xx.ravel(), yy.ravel(), t.ravel()])
    np.savetxt(tmp_path / "tau.csv", rows, delimiter=",", header="x_m,y_m,tau_peak_pa", comments="")
    doc["strength"] = {"kind": "map", "file": str(tmp_path / "tau.csv")}


def test_one_cell_failing_under_its_own_slab_refuses_the_run(tmp_path):
    """One snow-covered cell outside the trigger whose weak layer fails under its own slab
    at t = 0 stops the scenario with one line (how many, where); one inside the trigger
    does not; strength.natural_release = true runs it."""
    doc = _plain_doc()
    _strength_map(tmp_path, doc, weak_at=(6.0, 1.0))
    with pytest.raises(ValueError) as err:
        quiet_parse(doc)
    msg = str(err.value)
    assert "\n" not in msg and "on 1 snow-covered cells" in msg
    assert "x = 6.0 m, y = 1.0 m" in msg and "strength.natural_release" in msg
    doc["strength"]["natural_release"] = True
    with pytest.warns(UserWarning, match="natural release"):
        scenario.parse(doc)
    _strength_map(tmp_path, doc, weak_at=(3.5, 2.5))  # within 2 m of the start
    quiet_parse(doc)


def test_t0_failures_report_no_crack_speed():
    """A weak layer that fails everywhere under its own slab at t = 0 releases the area
    at once: the summary has its area, and no crack speed (no front ran)."""
    setup = SlopeSetup(length=8.0, width=4.0, dx=0.1, duration=0.1, start=(4.0, 2.0),
                       particles_per_cell=1, chunk_steps=50)  # fmt: skip
    res = quiet(simulate_slope, SLAB, setup, slope_deg=40.0, tau_peak=400.0)
    s = res.summary
    assert s["initial_failure_area_m2"] == pytest.approx(32.0, rel=1e-6)
    assert s["release_area_m2"] == pytest.approx(32.0, rel=1e-6)
    for key in ("upslope_crack_speed_over_cs", "crossslope_crack_speed_over_cs"):
        assert s[key] is None, key


def test_coulomb_strength_follows_the_normal_stress():
    """strength.kind = "coulomb": tau_p = cohesion + mu rho g h0 cos(psi) at each
    particle."""
    setup = SlopeSetup(length=2.0, width=2.0, dx=0.1, duration=0.01, start=(1.0, 1.0),
                       particles_per_cell=1, chunk_steps=5)  # fmt: skip
    psi = np.full((20, 20), 38.0)
    h = np.full((20, 20), 0.4)
    h[10:] = 0.8
    layout = make_slope_layout(SLAB, setup, 38.0)
    model, *_ = build_slope(SLAB, setup, layout, psi, 300.0, thickness=h, wl_friction=0.6)
    want = 300.0 + 0.6 * 250.0 * 9.81 * np.asarray(model.slab.thickness) * math.cos(
        math.radians(38)
    )
    np.testing.assert_allclose(np.asarray(model.weak_layer.tau_peak), want, rtol=1e-5)


def test_stability_with_a_friction_floor_holds_on_flat_snow(tmp_path):
    """strength.kind = "stability" with friction_coefficient: tau_p = S tau_g + mu rho g
    h0 cos(psi), so a flat bench keeps a strength that follows its slab's load (S tau_g
    alone vanishes there); the crack still starts at the weakest S."""
    doc = _plain_doc()
    doc["strength"] = {"kind": "stability", "mean": 1.42, "cov": 0.0, "length_scale": 2.0}
    plain = slope_fields.resolve_inputs(quiet_parse(doc))
    doc["strength"]["friction_coefficient"] = 0.3
    inp = slope_fields.resolve_inputs(quiet_parse(doc))
    assert plain.wl_friction is None and inp.wl_friction == 0.3
    assert inp.start == plain.start
    setup = SlopeSetup(length=2.0, width=2.0, dx=0.1, duration=0.01, start=(1.0, 1.0),
                       particles_per_cell=1, chunk_steps=5)  # fmt: skip
    psi = np.full((20, 20), 1.0)
    layout = make_slope_layout(SLAB, setup, 1.0)
    model, *_ = build_slope(SLAB, setup, layout, psi, 1.0, stability=1.42, wl_friction=0.3)
    rho_g_h = 250.0 * 9.81 * 0.5
    want = rho_g_h * (1.42 * math.sin(math.radians(1.0)) + 0.3 * math.cos(math.radians(1.0)))
    np.testing.assert_allclose(np.asarray(model.weak_layer.tau_peak), want, rtol=1e-5)
    assert want > 10 * rho_g_h * 1.42 * math.sin(math.radians(1.0))  # S tau_g: 30 Pa
    doc["strength"]["friction_coefficient"] = -0.1
    with pytest.raises(ValueError, match="strength.friction_coefficient"):
        quiet_parse(doc)


# --------------------------------------------------------------------------- thickness


def test_thickness_step_at_rest_has_a_continuous_membrane_force():
    """A slab whose thickness steps from 0.4 to 0.8 m across a generic slope, on a weak
    layer that holds it: at rest, its membrane force N = sigma_xx h0 is continuous across
    the step (each column carries its own weight on its own layer, the mass, the
    pre-load and the internal force follow the particle's thickness)."""
    from damjax import terrain

    setup = SlopeSetup(length=12.0, width=2.0, dx=0.1, duration=0.3, start=(0.5, 1.0),
                       particles_per_cell=2, chunk_steps=100)  # fmt: skip
    params = dataclasses.replace(SLAB, saw_speed=1e-4, tensile_strength=math.inf)
    x = (np.arange(120) + 0.5) * 0.1
    psi = np.asarray(terrain.generic_slope_angle(x, length=12.0, toe_length=3.0, roll_length=3.0))
    psi = np.repeat(psi[:, None], 20, axis=1)
    h = np.where(x[:, None] < 6.0, 0.4, 0.8) * np.ones((1, 20))
    res = quiet(simulate_slope, params, setup, slope_deg=psi, tau_peak=1e6, thickness=h)
    n = res.tension * res.thickness  # [N/m]
    scale = 250.0 * 9.81 * 0.8 * math.sin(math.radians(35.0)) * 0.5  # rho g h sin(psi) x 0.5 m
    jump = np.abs(n[60, 5:15] - n[59, 5:15])
    assert np.max(jump) < 1e-3 * scale
    assert np.max(np.abs(n)) < 1e-2 * scale
    assert res.summary["release_area_m2"] < 0.1 and res.summary["fault"] is None


# --------------------------------------------------------------------------- domain


def test_outflow_leaves_the_run_and_is_counted():
    """A released slab sliding over the grid's lower edge leaves the run (counted in the
    summary), instead of stopping it with a fault."""
    setup = SlopeSetup(length=8.0, width=4.0, dx=0.1, duration=0.8, start=(4.0, 2.0),
                       particles_per_cell=1, chunk_steps=50)  # fmt: skip
    layout = make_slope_layout(SLAB, setup, 40.0)
    nx = layout.n_cells[0]
    pad = 3  # a lower edge 3 cells below the slab: it slides out
    layout = dataclasses.replace(
        layout,
        pad=(pad, layout.pad[1]),
        grid_shape=(pad + nx + layout.pad[1], layout.grid_shape[1]),
    )
    res = quiet(simulate_slope, SLAB, setup, slope_deg=40.0, tau_peak=400.0, layout=layout)
    s = res.summary
    assert s["fault"] is None and s["n_steps"] == layout.n_steps
    assert s["outflow_particles"] > 0
    assert s["outflow_area_m2"] == pytest.approx(s["outflow_particles"] * 0.01)
    assert np.all(np.isfinite(res.height))


def test_domain_edge_fraction_counts_boundary_faces():
    rel = np.zeros((6, 5), bool)
    rel[0:2, 1:4] = True  # on the rectangle's lower edge: 3 of its 10 faces
    assert domain_edge_fraction(rel) == pytest.approx(3 / 10)
    dom = np.ones_like(rel)
    dom[2, :] = False  # outside the domain above it: 3 more faces
    assert domain_edge_fraction(rel, dom) == pytest.approx(6 / 10)
    assert domain_edge_fraction(np.zeros_like(rel)) is None


def test_a_domain_the_slidable_terrain_overruns_is_said_before_the_run():
    """With a domain (a polygon's buffer), the snow steeper than the friction angle that
    the start connects to is where a crack runs if nothing else stops it: when its
    boundary lies on the domain's edge, `prepare` says so before the run; gentle ground
    around it inside the domain bounds it, and nothing is said."""
    setup = SlopeSetup(length=30.0, width=20.0, dx=0.25, duration=0.1, start=(15.0, 10.0))
    x, y = np.meshgrid((np.arange(120) + 0.5) * 0.25, (np.arange(80) + 0.5) * 0.25, indexing="ij")
    domain = np.ones((120, 80), bool)
    plane = np.full((120, 80), 35.0)
    region = sliding_region(plane, 27.0, setup.start, 0.25, domain=domain)
    assert region.all() and domain_edge_fraction(region, domain) == 1.0
    notes = prepare(SLAB, setup, slope_deg=plane, tau_peak=2000.0, domain=domain).notes
    assert any("bounded by the domain, not the terrain" in n.text() for n in notes)
    bowl = np.where(np.hypot(x - 15.0, y - 10.0) < 6.0, 35.0, 10.0)
    region = sliding_region(bowl, 27.0, setup.start, 0.25, domain=domain)
    assert 0.8 * math.pi * 36 < region.sum() * 0.0625 < 1.2 * math.pi * 36
    assert domain_edge_fraction(region, domain) == 0.0
    notes = prepare(SLAB, setup, slope_deg=bowl, tau_peak=2000.0, domain=domain).notes
    assert not any("bounded by the domain" in n.text() for n in notes)
    # a start on gentle ground reaches nothing
    assert not sliding_region(bowl, 27.0, (2.0, 2.0), 0.25).any()
    with pytest.raises(ValueError, match="slope_deg has shape"):
        sliding_region(35.0, 27.0, setup.start, 0.25)
    with pytest.raises(ValueError, match="domain has shape"):
        sliding_region(bowl, 27.0, setup.start, 0.25, domain=domain[1:])
    with pytest.raises(ValueError, match="start = \\(50, 10\\) m; must lie in"):
        sliding_region(bowl, 27.0, (50.0, 10.0), 0.25)
    with pytest.raises(ValueError, match="dx = 0"):
        sliding_region(bowl, 27.0, setup.start, 0.0)
    for phi in (float("nan"), -1.0, 90.0, "steep"):
        with pytest.raises(ValueError, match="friction_deg = .*must be an angle in \\[0, 90\\)"):
            sliding_region(bowl, phi, setup.start, 0.25)
    # a float mask's NaN (no data) is no snow
    assert not sliding_region(
        bowl, 27.0, setup.start, 0.25, cover=np.full(bowl.shape, np.nan)
    ).any()
    with pytest.raises(ValueError, match="released has shape"):
        domain_edge_fraction(region[0])


def test_random_triggers_lie_in_the_start_zone(tmp_path):
    """strength.trigger = "random" starts each seed's crack in the start zone (snow-covered,
    28-60 deg), at different places for different seeds (an ensemble's members)."""
    dem = _tilted_dem(tmp_path, steep_from=2.0)
    doc = _dem_doc(dem, max_slope_deg=60.0, start_min_slope_deg=40.0)
    doc["strength"]["trigger"] = "random"
    del doc["setup"]["start"]
    starts = []
    for seed in range(4):
        doc["strength"]["seed"] = seed
        inp = slope_fields.resolve_inputs(quiet_parse(doc, base_dir=tmp_path))
        i, j = int(inp.start[0] / 0.25), int(inp.start[1] / 0.25)
        psi = np.asarray(inp.slope_deg)[i, j]
        assert inp.start_zone[i, j] and 40.0 <= psi <= 60.0
        starts.append(inp.start)
    assert len(set(starts)) == 4


def test_arrival_sources_counts_independent_starts():
    x, y = np.meshgrid(np.arange(100) * 0.1, np.arange(80) * 0.1, indexing="ij")
    one = np.hypot(x - 3, y - 4) / 50.0
    assert arrival_sources(one, 0.1) == 1
    two = np.minimum(one, np.hypot(x - 8, y - 1) / 50.0 + 0.01)
    assert arrival_sources(two, 0.1) == 2
    assert arrival_sources(np.full_like(one, np.inf), 0.1) == 0
    # a cell with next to no strength 0.8 m ahead of the front fails before the tip
    # arrives: the same front within a reach of 0.96 m, a source of its own within 0.5 m
    ahead = one.copy()
    ahead[60, 40] = one[52, 40] + 1e-4
    assert arrival_sources(ahead, 0.1, reach_m=0.96) == 1
    assert arrival_sources(ahead, 0.1, reach_m=0.5) == 2
    # two spots failing at once: one source within the reach of one another, two beyond
    both = np.full_like(one, np.inf)
    both[20, 20] = both[26, 20] = 0.0
    assert arrival_sources(both, 0.1, reach_m=0.7) == 1
    assert arrival_sources(both, 0.1, reach_m=0.5) == 2
    # spots failing on their own are one source only within the reach, measured between
    # cell centres: 3 m apart with a 3 m reach, not 3.16 or 4.24 m
    for (a, b), want in (((3, 0), 1), ((3, 1), 2), ((3, 3), 2)):
        spots = np.full((30, 30), np.inf)
        spots[10, 10], spots[10 + a, 10 + b] = 1.0, 2.0
        assert arrival_sources(spots, 1.0, reach_m=3.0) == want, (a, b)
    with pytest.raises(ValueError, match="arrival_time is float64 of shape"):
        arrival_sources(one[0], 0.1)
    with pytest.raises(ValueError, match="arrival_time is bool"):
        arrival_sources(np.isfinite(one), 0.1)
    with pytest.raises(ValueError, match="reach_m = -1"):
        arrival_sources(one, 0.1, reach_m=-1.0)
    with pytest.raises(ValueError, match="reach_m = inf"):
        arrival_sources(one, 0.1, reach_m=math.inf)


def test_weak_spots_failing_by_themselves_are_sources_of_their_own():
    """A run's summary counts each weak spot that fails under its own slab at t = 0, 2 m
    apart (beyond the reach of one failure, 0.96 m here), as a source; a run from the
    trigger alone has one."""
    setup = SlopeSetup(length=8.0, width=4.0, dx=0.1, duration=0.1, start=(2.0, 2.0),
                       particles_per_cell=1, chunk_steps=100)  # fmt: skip
    tau = np.full((80, 40), 1000.0)  # tau_g = 788 Pa at 40 deg under 0.5 m
    one = quiet(simulate_slope, SLAB, setup, slope_deg=40.0, tau_peak=tau).summary
    tau[64:67, 8:11] = tau[64:67, 29:32] = 400.0
    two = quiet(simulate_slope, SLAB, setup, slope_deg=40.0, tau_peak=tau).summary
    assert one["arrival_sources"] == 1 and one["sawn_area_m2"] > 0.0
    assert two["initial_failure_area_m2"] == pytest.approx(0.18, rel=1e-6)
    assert two["arrival_sources"] == 2
    # their cracks lead the saw from the first step: no cut radius was critical
    assert two["saw_stopped"] and two["critical_cut_radius_m"] is None


def test_snow_cover_runs_stay_differentiable_and_vmappable():
    """A run with a thickness map, a cover with holes and a stability field is traced as
    any other: jax.grad of the smooth release area with respect to the stability map is
    finite and non-zero, and jax.vmap over two maps gives each member's own run."""
    setup = SlopeSetup(length=2.0, width=1.5, dx=0.1, duration=0.02, start=(1.0, 0.7),
                       particles_per_cell=1, chunk_steps=10)  # fmt: skip
    cover = np.ones((20, 15), bool)
    cover[:, :3] = False
    h = np.full((20, 15), 0.4)
    h[10:] = 0.6
    brittle = dataclasses.replace(SLAB, softening=0.0)  # the pre-load is 1 / S of u_r

    def area(s):
        r = simulate_slope(brittle, setup, slope_deg=38.0, tau_peak=1.0, thickness=h,
                           cover=cover, stability=s)  # fmt: skip
        return r.summary["release_area_smooth_m2"]

    s0 = jnp.full((20, 15), 1.3)
    g = quiet(jax.grad(area), s0)
    assert np.all(np.isfinite(g)) and np.any(g != 0)
    both = quiet(jax.vmap(area), jnp.stack([s0, 1.2 * s0]))
    one = quiet(area, 1.2 * s0)
    assert float(both[1]) == pytest.approx(float(one), rel=1e-5)


def test_the_gis_frame_is_the_runs_own_where_the_domain_leaves_the_dem(tmp_path):
    """A snow-covered rectangle whose up-slope end lies past the DEM (a buffer's rectangle
    clipped to the terrain): the GIS frame (AvaFrame and GeoTIFF exports) maps the cells
    to the map points the run was built on instead of failing off the DEM."""
    import xarray as xr

    from damjax import terrain
    from damjax.export import gis

    dem = _tilted_dem(tmp_path)
    dx = 0.5
    x = (np.arange(180) + 0.5) * dx  # 90 m along the surface: the DEM ends before
    y = (np.arange(60) + 0.5) * dx
    ter = terrain.load_dem(dem)
    with pytest.raises(ValueError):  # a rectangle that must lie on the DEM
        slope_fields.dem_fields(ter, x, y, (1.0, 1.0), "+x")
    _, _, px, py = slope_fields.dem_fields(
        ter, x, y, (1.0, 1.0), "+x", nodata=True, map_points=True
    )
    ds = xr.Dataset(coords={"x": x, "y": y})
    doc = {"terrain": {"kind": "dem", "file": str(dem), "origin": [1.0, 1.0], "upslope": "+x"}}
    fr = gis.frame_of(ds, scenario=doc)
    X, Y = np.meshgrid(x, y, indexing="ij")
    mx, my = fr.to_map(X, Y)
    np.testing.assert_allclose(mx, px, atol=1e-6)
    np.testing.assert_allclose(my, py, atol=1e-6)


def test_summary_crack_speeds_leave_out_speeds_no_front_reaches():
    """Along a band, a front at 50 m/s and then a stretch whose arrival times barely rise
    (cells failing together, or a front from the side crossing the band at a slant): the
    peak and mean speeds leave out what is faster than the slab's wave speed."""
    from damjax import theory
    from damjax.slope.simulation import _front_speed

    limit = float(theory.plane_stress_wave_speed(PSTParams()))
    coord = np.arange(0.0, 40.0, 0.25) + 0.125
    t = np.where(coord < 20.0, coord / 50.0, 0.4 + (coord - 20.0) / 5000.0)
    mean0, peak0 = _front_speed(coord, t, 0.0, 40.0)
    assert peak0 > 10 * limit  # without the limit: an apparent speed
    mean, peak = _front_speed(coord, t, 0.0, 40.0, limit=limit)
    assert 50.0 * (1 - 1e-6) <= peak <= limit
    assert math.isnan(mean) or mean <= limit
    # a front that runs throughout keeps its speeds
    m1, p1 = _front_speed(coord, coord / 50.0, 0.0, 40.0, limit=limit)
    assert m1 == pytest.approx(50.0) and p1 == pytest.approx(50.0)


def test_the_resolution_warning_is_at_the_thinnest_slab():
    """dx = 0.1 m resolves Lambda/5 of the 0.5 m slab (0.132 m), not of the 0.258 m one
    a 45 deg slope's correction leaves (0.095 m): the warning names the thinner slab."""
    import tomllib

    doc = tomllib.loads(scenario.resolve("slope-quick").read_text())
    doc["params"]["slope_deg"] = 45.0
    for snow, said in (({"kind": "uniform"}, False), ({"kind": "slope_corrected"}, True)):
        doc["snow"] = snow
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            scenario.parse(doc)
        lines = [str(w.message) for w in caught if "Lambda/5" in str(w.message)]
        assert bool(lines) == said, lines
    assert "Lambda/5 = 0.0952 m at the thinnest slab, 0.258 m:" in lines[0]
