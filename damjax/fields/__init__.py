"""Weak-layer strength fields [Pa] on grids in metres: a leaf of the package.

- `grf`: Gaussian random fields (`grf`, `plateau_trend_field`, `correlation`);
- `grf_fit`: their maximum-likelihood fit to a measured map (`fit_grf`, `GRFFit`);
- `profiles`: PST strength profiles and their fits to measured transects (paper
  Figs. 11-12: `linear_profile`, `power_law_profile`, `pst_strength_profile`, ...);
- `maps`: strength maps (CSV / NetCDF / GeoTIFF), `map_on_grid`, `transect`.

Every public name is re-exported here: ``from damjax import fields; fields.grf(...)``.
"""

from damjax.fields.grf import (
    TAU_FLOOR,
    CovarianceModel,
    box_sum,
    correlation,
    embedding_shape,
    grf,
    grid_coordinates,
    plateau_trend_field,
    stability_field,
    trend_direction,
    trend_distance,
)
from damjax.fields.grf_fit import GRFFit, fit_grf
from damjax.fields.maps import load_strength_map, map_on_grid, transect
from damjax.fields.profiles import (
    PROFILE_FITS,
    LinearProfileFit,
    PowerLawProfileFit,
    fit_linear_profile,
    fit_power_law_profile,
    linear_profile,
    load_strength_profile,
    power_law_profile,
    pst_profile,
    pst_strength_profile,
)

__all__ = [
    "PROFILE_FITS",
    "TAU_FLOOR",
    "CovarianceModel",
    "GRFFit",
    "LinearProfileFit",
    "PowerLawProfileFit",
    "box_sum",
    "correlation",
    "embedding_shape",
    "fit_grf",
    "fit_linear_profile",
    "fit_power_law_profile",
    "grf",
    "grid_coordinates",
    "linear_profile",
    "load_strength_map",
    "load_strength_profile",
    "map_on_grid",
    "plateau_trend_field",
    "power_law_profile",
    "pst_profile",
    "pst_strength_profile",
    "stability_field",
    "transect",
    "trend_direction",
    "trend_distance",
]
