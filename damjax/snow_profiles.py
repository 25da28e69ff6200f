"""Snow profiles in: CAAML 6 (SnowPilot) and SNOWPACK ``.pro`` -> slab and weak-layer parameters.

A profile is read into a `SnowProfile`: its layers from the snow surface down (index 0 is
the top layer), each with its depth range [m], density [kg/m^3] where the file has one,
hand hardness, grain form and, for SNOWPACK, the shear strength and critical cut length the
model computed. `SnowProfile.slab(weak_layer)` summarises what lies above a chosen weak
layer (`Slab`: thickness, mean density, effective Young's modulus, the weak layer's own
data) and `pst_params` turns that into a `damjax.PSTParams`::

    import damjax
    from damjax import snow_profiles

    prof = snow_profiles.read_profile("pit.caaml")      # or "station.pro"
    print(prof.table())                                 # layer indices, depths, hardness
    params = snow_profiles.pst_params(prof, weak_layer=4)
    result = damjax.simulate_pst(params, damjax.PSTSetup(length=10.0, dx=0.02))

Readers:

- CAAML 6 (``.xml``, ``.caaml``) through `snowpylot` (``pip install 'damjax[profiles]'``):
  layers, hand hardness, grain forms, the density profile (point samples), the slope angle,
  the observer's layer of concern (the default weak layer) and the PST results.
- SNOWPACK ``.pro`` (text, documented with the SNOWPACK model; codes 0501 element top
  heights [cm], 0502 density, 0513 grain type, 0534 hand hardness, 0601 shear strength
  [kPa], 0606 critical cut length [m]) with a small built-in reader. The community reader
  `snowpat` pins numpy < 2 (jax needs numpy >= 2), so it is not a dependency; the tests
  compare this reader with snowpat's where snowpat is importable.

Why one module: both readers (about 100 and 140 lines) exist only to fill the same
`SnowProfile` / `Layer` types, and what the module is for (`SnowProfile.slab`,
`pst_params`) needs those types, E(rho) (`youngs_modulus`, 70 lines, used by `slab`) and
the hand hardness scale together; split by format, each part would import the others.
A third format is the point to make it a package (``snow_profiles/caaml.py``, ...).

Conventions:

- depths are measured from the snow surface and taken as slope-normal (the convention of
  pit observations on slopes, and the slab thickness h0 of damjax); pass
  ``vertical=True`` to `SnowProfile.slab` / `pst_params` for vertical depths (h0 = d
  cos(psi)).
- the slab's Young's modulus is the thickness-weighted mean of E(rho) over its layers
  (the membrane stiffness sum E_i h_i that a depth-averaged slab carries), with E(rho)
  from `youngs_modulus`; density is interpolated between the samples of a CAAML density
  profile.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import math
import os
import warnings
from typing import Any

import numpy as np

# Young's modulus of snow from density E(rho) [MPa, rho in kg/m^3], as implemented in weac
MODULUS_RELATIONS = ("scapozza", "gerling", "bergfeld")
# density range [kg/m^3] outside which the relations are extrapolations (a warning)
MODULUS_DENSITY_RANGE = (100.0, 450.0)
RHO_ICE = 917.0  # [kg/m^3]

# hand hardness index (ICSSG, Fierz et al. 2009): F 1, 4F 2, 1F 3, P 4, K 5, I 6; +/- 1/3
_HARDNESS = {"F": 1.0, "4F": 2.0, "1F": 3.0, "P": 4.0, "K": 5.0, "I": 6.0}
# SNOWPACK grain type codes F1F2F3: the first digit's class
_SWISS_GRAIN = {1: "PP", 2: "DF", 3: "RG", 4: "FC", 5: "DH", 6: "SH", 7: "MF", 8: "IF", 9: "FCxr"}


def youngs_modulus(density: Any, relation: str = "scapozza") -> Any:
    """Young's modulus of snow E [Pa] from its density rho [kg/m^3].

    Relations (the parametrisations weac implements, ``weac.tools``):

    - ``"scapozza"`` (default): E = 5.07 GPa (rho / rho_ice)^5.13 (Scapozza 2004, ETH
      thesis no. 15357; laboratory tests on dry snow at low strain rates). At 250
      kg/m^3 it gives 6.4 MPa, the order of the 4 MPa the paper's PSTs use, which is why
      it is the default for the depth-averaged slab.
    - ``"gerling"``: E = 6.0e-10 rho^4.6 MPa (Gerling et al. 2017, GRL 44, acoustic
      measurements at high frequency): 64.4 MPa at 250 kg/m^3.
    - ``"bergfeld"``: E = 6.5 GPa (rho / 916.7)^4.4 (Bergfeld et al. 2023, NHESS, from
      PST displacement fields; weac default): 21 MPa at 250 kg/m^3.

    The three differ by an order of magnitude at slab densities: the modulus of snow
    depends on the strain rate and on the method, and the choice matters for Lambda and
    the wave speeds. All are fits over dry slab snow; outside `MODULUS_DENSITY_RANGE`
    (100-450 kg/m^3) they are extrapolations and a warning says so.

    Args:
        density: rho [kg/m^3], a number or an array (numpy or JAX), > 0.
        relation: one of `MODULUS_RELATIONS`.

    Returns:
        E [Pa], same shape as ``density``.
    """
    if relation not in MODULUS_RELATIONS:
        valid = ", ".join(f'"{r}"' for r in MODULUS_RELATIONS)
        raise ValueError(f"relation = {relation!r}: must be one of {{{valid}}}")
    r = np.asarray(density) if not hasattr(density, "aval") else density
    if not hasattr(r, "aval"):
        lo, hi = MODULUS_DENSITY_RANGE
        if r.dtype.kind not in "iuf":  # a string, None, a bool
            raise ValueError(
                f"density = {density!r}: must be a number or an array of numbers > 0 kg/m^3"
            )
        bad = ~(np.isfinite(r) & (r > 0))
        if np.any(bad):
            if np.ndim(r) == 0:
                raise ValueError(f"density = {density}: must be finite and > 0 kg/m^3")
            first = np.asarray(r)[bad].ravel()[0]
            raise ValueError(
                f"density: {int(bad.sum())} of {bad.size} values are not finite and > 0 "
                f"(the first {first:g}): must be finite and > 0 kg/m^3"
            )
        if np.any(r < lo) or np.any(r > hi):
            warnings.warn(
                f"density {np.min(r):.4g}-{np.max(r):.4g} kg/m^3 lies outside "
                f"{lo:g}-{hi:g} kg/m^3: the {relation} E(rho) relation is extrapolated",
                stacklevel=2,
            )
    if relation == "scapozza":
        return 5.07e9 * (r / RHO_ICE) ** 5.13
    if relation == "gerling":
        return 6.0e-10 * r**4.6 * 1e6
    return 6.5e9 * (r / 916.7) ** 4.4  # Bergfeld et al. take rho_ice = 916.7


def hardness_index(code: str | None) -> float:
    """Hand hardness index of an ICSSG code ("F", "4F+", "1F-", "P", "K", "I"; a range
    like "1F-P" gives the mean of its ends); NaN for None or an unknown code."""
    if not code:
        return math.nan
    code = code.strip()
    if "-" in code[1:] and not code.endswith("-"):
        parts = [p for p in code.replace("--", "-").split("-") if p]
        vals = [hardness_index(p) for p in parts]
        return float(np.mean(vals)) if vals and all(np.isfinite(vals)) else math.nan
    sign = 0.0
    if code.endswith("+"):
        sign, code = 1.0 / 3.0, code[:-1]
    elif code.endswith("-"):
        sign, code = -1.0 / 3.0, code[:-1]
    base = _HARDNESS.get(code.upper())
    return math.nan if base is None else base + sign


@dataclasses.dataclass(frozen=True)
class Layer:
    """One layer of a profile (depths from the snow surface).

    Attributes:
        top: depth of its top [m]; bottom: depth of its bottom [m] (> top).
        density: rho [kg/m^3] (NaN where the file has none for this layer).
        hardness: hand hardness code (CAAML) or index as text (SNOWPACK); None if absent.
        hardness_index: hand hardness index 1 (F) to 6 (I) [-]; NaN if absent.
        grain: grain form code (ICSSG, e.g. "FCxr"); "" if absent.
        shear_strength: weak-layer shear strength [Pa] (SNOWPACK 0601); NaN if absent.
        critical_cut_length: critical cut length [m] as computed by SNOWPACK (0606);
            NaN if absent.
    """

    top: float
    bottom: float
    density: float = math.nan
    hardness: str | None = None
    hardness_index: float = math.nan
    grain: str = ""
    shear_strength: float = math.nan
    critical_cut_length: float = math.nan

    @property
    def thickness(self) -> float:
        """Layer thickness [m]."""
        return self.bottom - self.top


@dataclasses.dataclass(frozen=True)
class Slab:
    """The slab above a weak layer and the weak layer itself (`SnowProfile.slab`).

    Attributes:
        weak_layer: index of the weak layer in `SnowProfile.layers` (0 = top).
        thickness: slab thickness h0 [m] (slope-normal).
        density: thickness-weighted mean slab density [kg/m^3].
        youngs_modulus: effective slab modulus [Pa]: thickness-weighted mean of E(rho).
        modulus_relation: the E(rho) relation used (`youngs_modulus`).
        slope_deg: slope angle of the profile site [deg], None if the file has none.
        wl_thickness: weak-layer thickness [m].
        wl_hardness: weak-layer hand hardness code / index text (None if absent).
        wl_grain: weak-layer grain form ("" if absent).
        wl_shear_strength: weak-layer shear strength [Pa] (NaN if absent).
        wl_critical_cut_length: the profile's critical cut length at the weak layer [m]
            (SNOWPACK 0606; NaN if absent).
        pst: observed PSTs at this weak layer (CAAML): dicts with depth_m, cut_length_m,
            column_length_m and fracture_propagation.
        source: the file read.
    """

    weak_layer: int
    thickness: float
    density: float
    youngs_modulus: float
    modulus_relation: str
    slope_deg: float | None
    wl_thickness: float
    wl_hardness: str | None
    wl_grain: str
    wl_shear_strength: float
    wl_critical_cut_length: float
    pst: tuple[dict[str, Any], ...]
    source: str

    def summary(self) -> dict[str, Any]:
        """The fields as a JSON-friendly dict (NaN -> None)."""
        out = dataclasses.asdict(self)
        for k, v in out.items():
            if isinstance(v, float) and not math.isfinite(v):
                out[k] = None
        out["pst"] = [dict(p) for p in self.pst]
        return out


@dataclasses.dataclass(frozen=True)
class SnowProfile:
    """A snow profile: layers from the surface down, plus what the file says about them.

    Attributes:
        layers: the layers, index 0 at the snow surface, depths ascending.
        density_samples: (n, 3) array of density samples (top [m], bottom [m],
            rho [kg/m^3]) of a CAAML density profile; empty for SNOWPACK (per layer).
        slope_deg: slope angle of the site [deg] or None.
        concern: index of the observer's layer of concern (CAAML) or None.
        date: time of the observation / simulation, or None.
        source: the file read.
        pst: observed PSTs (CAAML), dicts with depth_m, cut_length_m, column_length_m,
            fracture_propagation.
    """

    layers: tuple[Layer, ...]
    density_samples: np.ndarray
    slope_deg: float | None = None
    concern: int | None = None
    date: _dt.datetime | None = None
    source: str = ""
    pst: tuple[dict[str, Any], ...] = ()

    def table(self) -> str:
        """A text table of the layers (index, depth range [cm], density, hardness, grain)."""
        lines = [f"{self.source}: {len(self.layers)} layers (index 0 at the surface)"]
        lines.append(" idx  top-bottom [cm]  rho [kg/m3]  hardness  grain  strength [kPa]")
        if self.density_samples.size:
            lines[0] += "; ~rho: from the density profile at the layer's middle"
        for i, ly in enumerate(self.layers):
            mark = "  <- layer of concern" if i == self.concern else ""
            if math.isfinite(ly.density):
                rho = f"{ly.density:8.0f}"
            elif self.density_samples.size:  # interpolated from the density profile
                mid = np.array(0.5 * (ly.top + ly.bottom))
                rho = f"~{float(self.density_at(mid)):.0f}".rjust(8)
            else:
                rho = "       -"
            st = f"{ly.shear_strength / 1e3:.3g}" if math.isfinite(ly.shear_strength) else "-"
            lines.append(
                f"{i:4d}  {100 * ly.top:6.1f}-{100 * ly.bottom:<6.1f}  {rho}     "
                f"{ly.hardness or '-':8s}  {ly.grain or '-':5s}  {st}{mark}"
            )
        return "\n".join(lines)

    def _weak_index(self, weak_layer: int | None) -> int:
        n = len(self.layers)
        if n < 2:
            raise ValueError(
                f"{self.source}: the profile has {n} layer(s); a slab and a weak layer "
                "need at least 2"
            )
        if weak_layer is None:
            if self.concern is None:
                raise ValueError(
                    f"{self.source}: no layer of concern in the file: give weak_layer "
                    f"(--weak-layer, [profile] weak_layer), an integer in [1, {n - 1}] (layer "
                    "index, 0 = top; the layers: SnowProfile.table())"
                )
            weak_layer = self.concern
        if (
            isinstance(weak_layer, bool)
            or not isinstance(weak_layer, (int, np.integer))
            or not 1 <= weak_layer <= n - 1
        ):
            raise ValueError(
                f"{self.source}: weak_layer = {weak_layer!r}: must be an integer in "
                f"[1, {n - 1}] (layer index, 0 = top; layer 0 has no slab above it)"
            )
        return int(weak_layer)

    def density_at(self, depth: np.ndarray) -> np.ndarray:
        """Density [kg/m^3] at depths [m]: CAAML samples interpolated linearly between
        their mid-depths (constant beyond the first and last), else the layer values."""
        depth = np.asarray(depth, dtype=float)
        s = self.density_samples
        if s.size:
            mid = 0.5 * (s[:, 0] + s[:, 1])
            order = np.argsort(mid)
            return np.interp(depth, mid[order], s[order, 2])
        tops = np.array([ly.top for ly in self.layers])
        idx = np.clip(np.searchsorted(tops, depth, side="right") - 1, 0, len(tops) - 1)
        return np.array([self.layers[i].density for i in np.atleast_1d(idx)]).reshape(depth.shape)

    def slab(
        self,
        weak_layer: int | None = None,
        *,
        modulus: str = "scapozza",
        vertical: bool = False,
        resolution: float = 0.001,
    ) -> Slab:
        """The slab above ``weak_layer`` (index into `layers`, 0 = top; default: the
        layer of concern) and the weak layer's data.

        Args:
            weak_layer: layer index in [1, len(layers) - 1].
            modulus: E(rho) relation, see `youngs_modulus`.
            vertical: depths are vertical (h0 = depth cos(psi)) instead of slope-normal.
            resolution: depth step of the density integration [m].
        """
        i = self._weak_index(weak_layer)
        depth = self.layers[i].top
        if not depth > 0:
            raise ValueError(f"{self.source}: weak layer {i} starts at the surface (depth 0)")
        # sub-intervals no longer than `resolution`, split at every layer boundary: the
        # mean over them is exact for layer densities and converges for interpolated ones
        cuts = [0.0] + [ly.bottom for ly in self.layers[:i] if 0 < ly.bottom < depth] + [depth]
        edges = np.unique(
            np.concatenate(
                [
                    np.linspace(a, b, max(2, int(math.ceil((b - a) / resolution)) + 1))
                    for a, b in zip(cuts[:-1], cuts[1:], strict=True)
                    if b > a
                ]
            )
        )
        w = np.diff(edges) / depth
        z = 0.5 * (edges[1:] + edges[:-1])
        rho = self.density_at(z)
        k = next(
            (
                k
                for k, ly in enumerate(self.layers[:i])
                if np.isfinite(ly.density) and ly.density <= 0
            ),
            None,
        )
        if k is not None:
            raise ValueError(
                f"{self.source}: layer {k} ({100 * self.layers[k].top:.1f}-"
                f"{100 * self.layers[k].bottom:.1f} cm) has density {self.layers[k].density:g} "
                "kg/m^3: must be > 0"
            )
        if not np.all(np.isfinite(rho)):
            bad = sorted({k for k, ly in enumerate(self.layers[:i]) if not ly.density > 0})
            raise ValueError(
                f"{self.source}: no density for layers {bad} above weak layer {i} "
                f"(depth {100 * depth:.1f} cm); pass density=... [kg/m^3] to pst_params (--density)"
            )
        if self.density_samples.size and not np.any(
            0.5 * (self.density_samples[:, 0] + self.density_samples[:, 1]) < depth
        ):
            raise ValueError(
                f"{self.source}: no density sample above weak layer {i} (depth "
                f"{100 * depth:.1f} cm); pass density=... [kg/m^3] to pst_params (--density)"
            )
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            e = youngs_modulus(rho, modulus)
        for msg in caught[:1]:
            warnings.warn(f"{self.source}: {msg.message}", stacklevel=2)
        h = depth
        if vertical:
            if self.slope_deg is None:
                raise ValueError(
                    f"{self.source}: vertical=True needs the slope angle, which the file lacks"
                )
            h = depth * math.cos(math.radians(self.slope_deg))
        wl = self.layers[i]
        at = [p for p in self.pst if abs(p.get("depth_m", -1.0) - depth) <= 0.02]
        return Slab(
            weak_layer=i,
            thickness=float(h),
            density=float(np.sum(w * rho)),
            youngs_modulus=float(np.sum(w * e)),
            modulus_relation=modulus,
            slope_deg=self.slope_deg,
            wl_thickness=float(wl.thickness),
            wl_hardness=wl.hardness,
            wl_grain=wl.grain,
            wl_shear_strength=float(wl.shear_strength),
            wl_critical_cut_length=float(wl.critical_cut_length),
            pst=tuple(at),
            source=self.source,
        )


# ----------------------------------------------------------------------------- CAAML


def _cm(v: Any, what: str, path: str) -> float:
    """A snowpylot (value, unit) length as metres."""
    if v is None:
        return math.nan
    value, unit = float(v[0]), str(v[1]).lower() if len(v) > 1 else "cm"
    scale = {"cm": 0.01, "m": 1.0, "mm": 0.001}.get(unit)
    if scale is None:
        raise ValueError(f"{path}: {what} in unit {unit!r} (expected cm, m or mm)")
    return value * scale


def _warn_layer_gaps(path: str, spans: list[tuple[float, float]], hs: float) -> None:
    """Warn (once, the first case) where a profile's layers (top, bottom) [m] from the
    surface down leave a gap, overlap or run below the snow height ``hs`` [m]: a typo in
    a depth or a thickness, or layers in mixed units, that the slab above a weak layer
    would silently absorb."""
    tol = 1e-6
    for k in range(1, len(spans)):
        b0, t1 = spans[k - 1][1], spans[k][0]
        if abs(t1 - b0) > tol:
            what = "a gap" if t1 > b0 else "an overlap"
            warnings.warn(
                f"{path}: layer {k - 1} ends at {100 * b0:g} cm depth, layer {k} starts at "
                f"{100 * t1:g} cm ({what}): check their depths and thicknesses",
                stacklevel=3,
            )
            return
    if math.isfinite(hs) and spans and spans[-1][1] > hs + tol:
        warnings.warn(
            f"{path}: the layers reach {100 * spans[-1][1]:g} cm depth, below the snow "
            f"height hs = {100 * hs:g} cm: check the units of the depths and thicknesses",
            stacklevel=3,
        )


def read_caaml(path: str | os.PathLike) -> SnowProfile:
    """Read a CAAML 6 snow profile (SnowPilot export) with `snowpylot`.

    Needs ``pip install 'damjax[profiles]'`` (snowpylot). Profiles measured "top down"
    are read as is; "bottom up" profiles are turned into depths with the snow height HS.
    """
    try:
        from snowpylot import caaml_parser
    except ImportError as e:
        raise ImportError(
            "reading CAAML profiles needs snowpylot: pip install 'damjax[profiles]' "
            "(or pip install snowpylot)"
        ) from e
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    try:
        pit = caaml_parser(path)
    except Exception as e:  # snowpylot raises whatever ElementTree raises
        raise ValueError(f"{path}: not a readable CAAML profile ({e})") from None
    sp = pit.snow_profile
    raw = list(sp.layers or [])
    if not raw:
        raise ValueError(f"{path}: the profile has no layers")
    direction = (sp.measurement_direction or "top down").lower()
    hs = _cm(sp.hs, "hs", path) if sp.hs else math.nan
    layers = []
    concern = None
    for k, ly in enumerate(raw):
        t = _cm(ly.depth_top, f"layer {k} depth", path)
        d = _cm(ly.thickness, f"layer {k} thickness", path)
        if not (math.isfinite(t) and math.isfinite(d) and d > 0):
            raise ValueError(f"{path}: layer {k} lacks a depth or a positive thickness")
        if direction.startswith("bottom"):
            if not math.isfinite(hs):
                raise ValueError(f"{path}: a bottom-up profile needs the snow height (hs)")
            t = hs - (t + d)
        hard = ly.hardness or ly.hardness_top
        grain = ly.grain_form_primary.grain_form if ly.grain_form_primary else ""
        layers.append(
            (t, t + d, hard, grain or "", bool(ly.layer_of_concern), k),
        )
    layers.sort(key=lambda r: r[0])
    _warn_layer_gaps(path, [(t, b) for t, b, *_ in layers], hs)
    out = []
    for j, (t, b, hard, grain, loc, _) in enumerate(layers):
        out.append(
            Layer(top=t, bottom=b, hardness=hard, hardness_index=hardness_index(hard), grain=grain)
        )
        if loc:
            concern = j
    samples = []
    for k, obs in enumerate(sp.density_profile or []):
        if obs.density is None or obs.depth_top is None:
            continue
        t = _cm(obs.depth_top, f"density sample {k} depth", path)
        d = _cm(obs.thickness, f"density sample {k} thickness", path) if obs.thickness else 0.0
        unit = str(obs.density[1]).lower().replace(" ", "").replace("/", "").replace("^", "")
        if unit not in ("kgm-3", "kgm3"):
            raise ValueError(f"{path}: density sample {k} in unit {obs.density[1]!r}")
        if direction.startswith("bottom") and math.isfinite(hs):
            t = hs - (t + d)
        samples.append((t, t + (d if math.isfinite(d) else 0.0), float(obs.density[0])))
    slope = None
    try:
        s = pit.core_info.location.slope_angle
        if s is not None and float(s[0]) > 0:
            slope = float(s[0])
    except (AttributeError, TypeError, ValueError):
        slope = None
    psts = []
    for t in getattr(pit.stability_tests, "PST", None) or []:
        if t.depth_top is None or t.cut_length is None:
            continue
        psts.append(
            {
                "depth_m": _cm(t.depth_top, "PST depth", path),
                "cut_length_m": _cm(t.cut_length, "PST cut length", path),
                "column_length_m": _cm(t.column_length, "PST column length", path)
                if t.column_length
                else None,
                "fracture_propagation": t.fracture_prop,
            }
        )
    date = None
    try:
        date = _dt.datetime.fromisoformat(str(pit.core_info.date))
    except (AttributeError, TypeError, ValueError):
        date = None
    return SnowProfile(
        layers=tuple(out),
        density_samples=np.array(samples, dtype=float).reshape(-1, 3),
        slope_deg=slope,
        concern=concern,
        date=date,
        source=path,
        pst=tuple(psts),
    )


# ----------------------------------------------------------------------------- SNOWPACK


def _pro_blocks(path: str) -> tuple[dict[str, str], list[tuple[_dt.datetime, dict[str, str]]]]:
    """Station parameters and the [DATA] blocks (date, {code: raw line}) of a .pro file."""
    station: dict[str, str] = {}
    blocks: list[tuple[_dt.datetime, dict[str, str]]] = []
    section = None
    with open(path, encoding="utf-8", errors="replace") as f:
        for lineno, raw in enumerate(f, 1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            if line.startswith("["):
                section = line.strip("[]").strip().upper()
                continue
            if section == "STATION_PARAMETERS" and "=" in line:
                k, v = line.split("=", 1)
                station[k.strip()] = v.strip()
            elif section == "DATA":
                code, _, rest = line.partition(",")
                if code == "0500":
                    try:
                        when = _dt.datetime.strptime(rest.strip(), "%d.%m.%Y %H:%M:%S")
                    except ValueError:
                        raise ValueError(
                            f"{path}:{lineno}: date {rest.strip()!r} is not DD.MM.YYYY HH:MM:SS"
                        ) from None
                    blocks.append((when, {}))
                elif blocks:
                    blocks[-1][1][code] = rest
    if section is None or not blocks:
        raise ValueError(f"{path}: not a SNOWPACK .pro file (no [DATA] section with 0500 dates)")
    return station, blocks


def _pro_values(path: str, code: str, rest: str | None, n: int, n_soil: int = 0) -> np.ndarray:
    """The n per-element values of one data line (missing -999 -> NaN), which holds as
    many values as its count says; a line of a snow field may lack the ``n_soil`` soil
    elements at the bottom (padded with NaN there), no more."""
    if rest is None:
        return np.full(n, np.nan)
    parts = [p for p in rest.split(",")]
    count = _count(path, rest, code)
    try:
        vals = np.array([float(p) for p in parts[1:] if p.strip()], dtype=float)
    except ValueError:
        raise ValueError(f"{path}: code {code}: non-numeric value") from None
    if vals.size != count:
        raise ValueError(
            f"{path}: code {code}: its count says {count} values, the line holds {vals.size}"
        )
    if code == "0513" and vals.size == n + 1:  # a surface-hoar marker at the end
        vals = vals[:n]
    if not n - n_soil <= vals.size <= n:
        raise ValueError(
            f"{path}: code {code}: {vals.size} values for {n} elements (0501), "
            f"{n - n_soil} of them snow"
        )
    if vals.size < n:
        vals = np.concatenate([np.full(n - vals.size, np.nan), vals])
    return np.where(vals <= -999.0, np.nan, vals)


def read_pro(path: str | os.PathLike, date: str | _dt.datetime | None = None) -> SnowProfile:
    """Read one profile of a SNOWPACK ``.pro`` file.

    Args:
        path: the file.
        date: the profile at this time (a datetime or ISO text "2017-11-14T12:00"): the
            last one at or before it; default the last profile in the file.

    Soil elements (heights <= 0) are dropped; layers are returned from the surface down.
    Hand hardness 0534 is read as an index (its sign, which marks the index-steps
    convention of newer SNOWPACK versions, is dropped); values above 6 are newtons and are
    kept as text only. The slope angle is the station's SlopeAngle (None if 0).
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"{path}: no such file")
    station, blocks = _pro_blocks(path)
    if date is None:
        when, block = blocks[-1]
    else:
        try:
            t = _dt.datetime.fromisoformat(date) if isinstance(date, str) else date
        except ValueError:
            raise ValueError(
                f"{path}: date = {date!r} (--profile-date, [profile] date): must be ISO text "
                '("2017-11-14T12:00" or "2017-11-14")'
            ) from None
        before = [b for b in blocks if b[0] <= t]
        if not before:
            raise ValueError(
                f"{path}: date {t.isoformat()} is before the first profile "
                f"({blocks[0][0].isoformat()}); profiles run to {blocks[-1][0].isoformat()}"
            )
        when, block = before[-1]
    if "0501" not in block:
        raise ValueError(f"{path}: the profile of {when.isoformat()} has no heights (0501)")
    heights = _pro_values(path, "0501", block["0501"], _count(path, block["0501"]))
    n = heights.size
    rising = np.diff(heights) > 0
    if not np.all(rising):
        k = int(np.flatnonzero(~rising)[0])
        raise ValueError(
            f"{path}: code 0501 of {when.isoformat()}: heights must rise from the ground "
            f"up; element {k + 2} ({heights[k + 1]:g} cm) is not above element {k + 1} "
            f"({heights[k]:g} cm)"
        )
    soil = int(np.sum(heights <= 0))
    fields = {
        c: _pro_values(path, c, block.get(c), n, soil)
        for c in ("0502", "0513", "0534", "0601", "0606")
    }
    snow = np.flatnonzero(heights > 0)
    if snow.size == 0:
        raise ValueError(f"{path}: no snow on {when.isoformat()} (all heights <= 0)")
    tops = heights[snow] / 100.0
    bottoms = np.concatenate([[0.0], tops[:-1]])
    hs = tops[-1]
    layers = []
    for k in range(snow.size - 1, -1, -1):  # surface first
        e = snow[k]
        g = fields["0513"][e]
        grain = _SWISS_GRAIN.get(int(g) // 100, "") if np.isfinite(g) and g >= 100 else ""
        hh = fields["0534"][e]
        newton = np.isfinite(hh) and abs(hh) > 6
        hidx = math.nan if newton or not np.isfinite(hh) else abs(float(hh))
        layers.append(
            Layer(
                top=float(hs - tops[k]),
                bottom=float(hs - bottoms[k]),
                density=float(fields["0502"][e]),
                hardness=(f"{abs(hh):g} N" if newton else f"{abs(hh):g}")
                if np.isfinite(hh)
                else None,
                hardness_index=hidx,
                grain=grain,
                shear_strength=float(fields["0601"][e]) * 1e3,
                critical_cut_length=float(fields["0606"][e]),
            )
        )
    slope = None
    try:
        s = float(station.get("SlopeAngle", "0"))
        slope = s if s > 0 else None
    except ValueError:
        slope = None
    return SnowProfile(
        layers=tuple(layers),
        density_samples=np.zeros((0, 3)),
        slope_deg=slope,
        concern=None,
        date=when,
        source=path,
    )


def _count(path: str, rest: str, code: str = "0501") -> int:
    """The count that leads a data line (0501: the number of elements)."""
    head = rest.split(",", 1)[0].strip()
    try:
        return int(head)
    except ValueError:
        what = "element count" if code == "0501" else "count"
        raise ValueError(f"{path}: {code} {what} {head!r} is not an integer") from None


def read_profile(path: str | os.PathLike, **kwargs: Any) -> SnowProfile:
    """Read a profile, choosing the reader from the suffix: ``.pro`` (SNOWPACK,
    `read_pro`; ``date=`` picks the profile) or ``.xml`` / ``.caaml`` (`read_caaml`)."""
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    if suffix == ".pro":
        return read_pro(path, **kwargs)
    if suffix in (".xml", ".caaml"):
        if kwargs.get("date") is not None:  # the command line's --profile-date
            raise ValueError(
                f"{os.fspath(path)}: date = {str(kwargs['date'])!r} (--profile-date, [profile] "
                "date) picks one of a SNOWPACK .pro file's profiles; a CAAML file holds one "
                "profile: leave the date out"
            )
        kwargs.pop("date", None)
        if kwargs:
            raise TypeError(f"read_caaml takes no options (got {sorted(kwargs)})")
        return read_caaml(path)
    raise ValueError(
        f"{os.fspath(path)}: unknown profile format {suffix!r} (.pro SNOWPACK, .xml/.caaml CAAML)"
    )


def pst_params(
    profile: SnowProfile | str | os.PathLike,
    weak_layer: int | None = None,
    *,
    modulus: str = "scapozza",
    vertical: bool = False,
    slope_deg: float | None = None,
    use_strength: bool = True,
    date: str | _dt.datetime | None = None,
    **overrides: Any,
) -> Any:
    """`damjax.PSTParams` of the slab above ``weak_layer`` of a profile.

    Set from the profile: ``thickness`` (slab thickness h0 [m]), ``density`` (mean slab
    density [kg/m^3]), ``youngs_modulus`` (thickness-weighted mean of E(rho) [Pa],
    relation ``modulus``), ``slope_deg`` (the site's slope angle, unless given here) and,
    where the profile has the weak layer's shear strength (SNOWPACK 0601) and
    ``use_strength``, ``tau_peak`` [Pa]. Everything else keeps the PSTParams defaults or
    comes from ``overrides`` (any PSTParams field, e.g. ``density=`` when the profile has
    no densities, ``tau_peak=``, ``tensile_strength=``).

    Args:
        profile: a `SnowProfile` or a file (`read_profile`).
        weak_layer: layer index (0 = top; default: the CAAML layer of concern).
        modulus: E(rho) relation (`youngs_modulus`).
        vertical: the profile's depths are vertical, not slope-normal.
        slope_deg: slope angle [deg]; default the profile's, else PSTParams' default.
        use_strength: take tau_peak from the profile's weak-layer strength if it has one.
        date: the profile's date (SNOWPACK files with a time series).
        overrides: PSTParams fields that win over the profile's values.
    """
    from damjax.params import PSTParams

    if not isinstance(profile, SnowProfile):
        profile = read_profile(profile, **({"date": date} if date is not None else {}))
    fields = {f.name for f in dataclasses.fields(PSTParams)}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise TypeError(f"pst_params: unknown PSTParams field(s) {unknown}")
    values: dict[str, Any] = {}
    if "density" in overrides and "youngs_modulus" not in overrides:
        # a given density: E from it (the profile's own densities are not used)
        i = profile._weak_index(weak_layer)
        depth = profile.layers[i].top
        h = depth
        if vertical:
            if profile.slope_deg is None:
                raise ValueError(f"{profile.source}: vertical=True needs the slope angle")
            h = depth * math.cos(math.radians(profile.slope_deg))
        values["thickness"] = float(h)
        values["youngs_modulus"] = float(youngs_modulus(float(overrides["density"]), modulus))
        wl = profile.layers[i]
    else:
        slab = profile.slab(weak_layer, modulus=modulus, vertical=vertical)
        values.update(
            thickness=slab.thickness, density=slab.density, youngs_modulus=slab.youngs_modulus
        )
        wl = profile.layers[slab.weak_layer]
    psi = slope_deg if slope_deg is not None else profile.slope_deg
    if psi is not None:
        values["slope_deg"] = float(psi)
    if use_strength and math.isfinite(wl.shear_strength) and wl.shear_strength > 0:
        values["tau_peak"] = float(wl.shear_strength)
    values.update(overrides)
    return PSTParams(**values)
