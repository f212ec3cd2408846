"""
Colour-accuracy figures: band weighting against 1 nm, display round trips,
out-of-gamut counts (what ``lbscene accuracy`` prints).

Reference
---------
* Tristimulus values: 1 nm, 360–830 nm, CIE 1931 2° observer
  (:func:`lbscene.engine.colour.band_weighting.reference_xyz`, equal to
  colour-science's ``sd_to_XYZ(..., method='Integration')`` on that shape).
* Test colours: the 24 patches of colour-science's ``"ColorChecker N Ohta"``
  set (N. Ohta's measurements of the Macbeth ColorChecker, 380–780 nm at 5 nm),
  interpolated linearly to 1 nm and held constant outside 380–780 nm.
* CIELAB relative to the light's 1 nm white point (perfect reflecting
  diffuser, Y normalised to 100), ΔE00 = colour-science's
  ``delta_E(..., method='CIE 2000')``.  A band method is compared with its
  own rendering of the perfect white as reference white (so an overall scale
  error does not count against it; for the projection both whites agree).

Band methods compared
---------------------
``point``
    Illuminant, reflectance and CMFs sampled at the 16 band centres (× 20 nm).
``box``
    Products of band means of illuminant, reflectance and CMFs (the naive 16-band box).
``cmf_weighted``
    Band means of the reflectance with :func:`band_xyz_weights` (illuminant × CMF
    integrated at 1 nm per band; fixes spiky lamps, not the in-band reflectance).
``projected``
    :func:`project_reflectance` + :func:`band_xyz_weights` (this project's method).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from lbscene.engine.files.outputs import output_path
from lbscene.engine.spectra.bands import DEFAULT_GRID, REFERENCE_WAVELENGTHS_NM, BandGrid, to_reference

from .band_weighting import band_xyz_weights, cmfs_1nm, illuminant_bands, project_reflectance, reference_xyz

__all__ = [
    "COLORCHECKER_SET",
    "CIE_LIGHTINGS",
    "BAND_METHODS",
    "colorchecker_reflectances",
    "cie_lighting_spds",
    "booth_lighting_spds",
    "band_method_xyz",
    "xyz_to_lab",
    "delta_e00",
    "band_delta_e00",
    "DisplayRoundTrip",
    "display_round_trip",
    "LightingResult",
    "evaluate_lighting",
    "accuracy_rows",
    "plot_per_patch",
    "TARGET_MEAN_DE00",
    "TARGET_MAX_DE00",
]

#: colour-science ColorChecker data set used for every figure.
COLORCHECKER_SET = "ColorChecker N Ohta"
#: The issue's targets for the projected band weighting (24 patches, per lighting).
TARGET_MEAN_DE00 = 0.1
TARGET_MAX_DE00 = 0.3

#: Default lightings: label → (colour-science data set, name).
CIE_LIGHTINGS: dict[str, tuple[str, str]] = {
    "CIE D65": ("illuminant", "D65"),
    "CIE A": ("illuminant", "A"),
    "CIE F2": ("illuminant", "FL2"),
    "CIE F7": ("illuminant", "FL7"),
    "CIE F11": ("illuminant", "FL11"),
    "TL84 (Philips TL-84, measured)": ("light_source", "Philips TL-84"),
}

BAND_METHODS = ("point", "box", "cmf_weighted", "projected")


@lru_cache(maxsize=4)
def _colorchecker(set_name: str) -> tuple[tuple[str, ...], np.ndarray]:
    import colour

    sds = colour.SDS_COLOURCHECKERS[set_name]
    names = tuple(sds.keys())
    refl = np.array([to_reference(sd.wavelengths, sd.values, extrapolate="constant")
                     for sd in sds.values()])
    refl.setflags(write=False)
    return names, refl


def colorchecker_reflectances(set_name: str = COLORCHECKER_SET) -> tuple[list[str], np.ndarray]:
    """Patch names and (24, 471) reflectances on the 1 nm reference grid."""
    names, refl = _colorchecker(set_name)
    return list(names), refl


@lru_cache(maxsize=1)
def _cie_spds() -> dict[str, np.ndarray]:
    import colour

    out = {}
    for label, (dataset, name) in CIE_LIGHTINGS.items():
        data = colour.SDS_ILLUMINANTS if dataset == "illuminant" else colour.SDS_LIGHT_SOURCES
        sd = data[name]
        out[label] = to_reference(sd.wavelengths, sd.values, extrapolate="zero")
    return out


def cie_lighting_spds() -> dict[str, np.ndarray]:
    """The default CIE/measured lightings as 1 nm relative SPDs (zero outside their data)."""
    return {k: v.copy() for k, v in _cie_spds().items()}


def booth_lighting_spds(ir) -> dict[str, np.ndarray]:
    """``"<booth name>: <configuration>"`` → 1 nm irradiance at the sample position.

    ``ir`` is a compiled booth (a :class:`~lbscene.engine.scene.ir.SceneIR`, from
    :func:`lbscene.engine.scene.compile.compile_booth`); its
    :meth:`~lbscene.engine.scene.ir.SceneIR.lighting_spd_1nm` gives each lighting's light at
    the sample (lamps, their filters when modelled).  Configurations that put no light on
    the sample are left out.
    """
    out = {}
    for name in ir.lighting:
        spd = np.asarray(ir.lighting_spd_1nm(name), float)
        if np.any(spd > 0) and (spd @ cmfs_1nm())[1] > 0:
            out[f"{ir.booth_name}: {name}"] = spd
    return out


# --------------------------------------------------------------------------- band methods

def band_method_xyz(method: str, reflectance_1nm, illuminant_1nm,
                    grid: BandGrid = DEFAULT_GRID) -> tuple[np.ndarray, np.ndarray]:
    """XYZ of reflectances (..., 471) and of the perfect white by a 16-band method.

    Returns ``(xyz (..., 3), white_xyz (3,))`` on the scale of :func:`reference_xyz`.
    """
    r = np.asarray(reflectance_1nm, float)
    s = np.asarray(illuminant_1nm, float)
    one = np.ones(REFERENCE_WAVELENGTHS_NM.size)
    if method == "point":
        idx = np.searchsorted(REFERENCE_WAVELENGTHS_NM, grid.centres_nm)
        cmf = cmfs_1nm()[idx]
        f = lambda x: (x[..., idx] * s[idx]) @ cmf * grid.width_nm  # noqa: E731
        return f(r), f(one)
    if method == "box":
        sb, cb = grid.integrate(s), grid.integrate(cmfs_1nm().T).T
        f = lambda x: (grid.integrate(x) * sb) @ cb * grid.width_nm  # noqa: E731
        return f(r), f(one)
    eb, w = illuminant_bands(s, grid), band_xyz_weights(s, grid)
    if method == "cmf_weighted":
        return (grid.integrate(r) * eb) @ w, (grid.integrate(one) * eb) @ w
    if method == "projected":
        return ((project_reflectance(r, s, grid) * eb) @ w,
                (project_reflectance(one, s, grid) * eb) @ w)
    raise ValueError(f"unknown band method {method!r}; one of {BAND_METHODS}")


def xyz_to_lab(xyz, white_xyz) -> np.ndarray:
    """CIELAB of XYZ relative to a white (any common scale)."""
    import colour

    white = np.asarray(white_xyz, float)
    return colour.XYZ_to_Lab(np.asarray(xyz, float) / white[1], colour.XYZ_to_xy(white))


def delta_e00(lab_a, lab_b) -> np.ndarray:
    """CIEDE2000 (colour-science ``delta_E(method='CIE 2000')``, kL = kC = kH = 1)."""
    import colour

    return np.asarray(colour.delta_E(lab_a, lab_b, method="CIE 2000"), float)


def band_delta_e00(method: str, reflectance_1nm, illuminant_1nm,
                   grid: BandGrid = DEFAULT_GRID) -> np.ndarray:
    """ΔE00 of a band method against the 1 nm reference for each reflectance."""
    ref_white = reference_xyz(1.0, illuminant_1nm)
    lab_ref = xyz_to_lab(reference_xyz(reflectance_1nm, illuminant_1nm), ref_white)
    xyz, white = band_method_xyz(method, reflectance_1nm, illuminant_1nm, grid)
    return delta_e00(xyz_to_lab(xyz, white), lab_ref)


# --------------------------------------------------------------------------- display round trip

@dataclass
class DisplayRoundTrip:
    """Target XYZ → drive → predicted XYZ for the patches of one lighting on one display."""

    display: str
    scene_white_cd_m2: float                 # luminance the lighting's perfect white is shown at
    float_dE00: np.ndarray                   # per patch, unquantised drive (in-gamut patches)
    nearest_8bit_dE00: np.ndarray            # per patch, drive rounded to the nearest code
    dithered_8bit_dE00: np.ndarray           # per patch, blue-noise dithered, mean over the tile
    out_of_gamut: np.ndarray                 # bool per patch
    gamut_dE00: np.ndarray                   # per patch: target vs shown after mapping
    gamut_max_excess: float

    def summary(self) -> dict:
        inside = ~self.out_of_gamut

        def mm(a):
            a = a[inside]
            # None (JSON null) when no patch is displayable: there is no round trip to measure
            return (float(a.mean()), float(a.max())) if a.size else (None, None)

        f, n, d = mm(self.float_dE00), mm(self.nearest_8bit_dE00), mm(self.dithered_8bit_dE00)
        return {
            "display": self.display,
            "display_scene_white_cd_m2": self.scene_white_cd_m2,
            "roundtrip_mean_dE00": f[0], "roundtrip_max_dE00": f[1],
            "roundtrip_8bit_mean_dE00": n[0], "roundtrip_8bit_max_dE00": n[1],
            "roundtrip_dithered_mean_dE00": d[0], "roundtrip_dithered_max_dE00": d[1],
            "out_of_gamut_count": int(self.out_of_gamut.sum()),
            "out_of_gamut_max_dE00": float(self.gamut_dE00.max()) if self.gamut_dE00.size else 0.0,
            "out_of_gamut_max_excess": self.gamut_max_excess,
        }


def display_round_trip(model, xyz_rel, white_rel, *, white_fraction: float = 0.9,
                       mask_size: int = 64) -> DisplayRoundTrip:
    """Show reflectances' XYZ on a display and measure what comes back.

    Parameters
    ----------
    model
        A :class:`~lbscene.engine.colour.display_model.DisplayModel`.
    xyz_rel, white_rel
        Targets (N, 3) and the lighting's white (3,) on any common scale.
    white_fraction
        Exposure: the perfect white is shown at this fraction of the highest
        luminance the display reaches at the white's chromaticity (floor included;
        of the display white's luminance when that chromaticity is out of gamut).
    mask_size
        Tile of the blue-noise mask: each patch is a tile of this size, dithered,
        and its displayed XYZ averaged (what the eye integrates).
    """
    import colour

    from .dither import blue_noise, dither_quantise

    xyz_rel = np.asarray(xyz_rel, float)
    white_rel = np.asarray(white_rel, float)
    y_white = white_fraction * model.max_luminance_cd_m2(colour.XYZ_to_xy(white_rel))
    if not y_white > 0:
        # the light's own white is outside the display gamut (e.g. a UV lamp's violet
        # residue): show it at the display white's luminance and let the mapping report it
        y_white = white_fraction * float(model.xyz_white_seen[1])
    scale = y_white / white_rel[1]
    target = xyz_rel * scale
    white = white_rel * scale
    drive, rep = model.xyz_to_drive(target, report=True, white_xyz=white)
    levels = 2 ** model.document.bit_depth - 1

    def de(xyz):
        return delta_e00(xyz_to_lab(xyz, white), xyz_to_lab(target, white))

    float_de = de(model.drive_to_xyz(drive))
    nearest_de = de(model.drive_to_xyz(np.round(drive * levels) / levels))
    mask = blue_noise(mask_size)
    tiles = np.broadcast_to(drive[:, None, None, :], (len(drive), mask_size, mask_size, 3))
    shown = np.empty_like(target)
    for i in range(len(drive)):
        codes = dither_quantise(tiles[i], mask, levels=levels)
        shown[i] = model.drive_to_xyz(codes / levels).reshape(-1, 3).mean(axis=0)
    return DisplayRoundTrip(display=model.name, scene_white_cd_m2=float(y_white),
                            float_dE00=float_de, nearest_8bit_dE00=nearest_de,
                            dithered_8bit_dE00=de(shown), out_of_gamut=rep.mask.copy(),
                            gamut_dE00=rep.delta_e00.copy(), gamut_max_excess=rep.max_excess)


# --------------------------------------------------------------------------- per lighting

@dataclass
class LightingResult:
    """Every per-patch figure for one lighting."""

    lighting: str
    source: str
    patch_names: list[str]
    band_dE00: dict[str, np.ndarray]               # method → per-patch ΔE00
    displays: list[DisplayRoundTrip] = field(default_factory=list)

    def rows(self) -> list[dict]:
        base = {"lighting": self.lighting, "source": self.source,
                "patches": len(self.patch_names),
                "band_mean_dE00": float(self.band_dE00["projected"].mean()),
                "band_max_dE00": float(self.band_dE00["projected"].max())}
        for m in BAND_METHODS:
            if m != "projected":
                base[f"{m}_mean_dE00"] = float(self.band_dE00[m].mean())
                base[f"{m}_max_dE00"] = float(self.band_dE00[m].max())
        base["band_target_met"] = bool(base["band_mean_dE00"] <= TARGET_MEAN_DE00
                                       and base["band_max_dE00"] <= TARGET_MAX_DE00)
        if not self.displays:
            return [dict(base, display=None)]
        return [dict(base, **d.summary()) for d in self.displays]


def evaluate_lighting(label: str, spd_1nm, displays=(), *, source: str = "",
                      grid: BandGrid = DEFAULT_GRID) -> LightingResult:
    """All figures for one lighting: band methods and each display's round trip."""
    names, refl = colorchecker_reflectances()
    spd = np.asarray(spd_1nm, float)
    band = {m: band_delta_e00(m, refl, spd, grid) for m in BAND_METHODS}
    res = LightingResult(label, source, names, band)
    if displays:
        xyz = reference_xyz(refl, spd)
        white = reference_xyz(1.0, spd)
        res.displays = [display_round_trip(d, xyz, white) for d in displays]
    return res


def accuracy_rows(results: list[LightingResult]) -> list[dict]:
    """JSON rows: one per lighting × display."""
    return [row for r in results for row in r.rows()]


# --------------------------------------------------------------------------- plot

def plot_per_patch(results: list[LightingResult], out_png) -> Path:
    """Per-patch ΔE00 bar chart, one panel per lighting, written atomically (PNG); lighting
    names are drawn as written (no mathtext)."""
    from lbscene.engine.files.textsafe import plain_text_plots

    with plain_text_plots():
        return _plot_per_patch(results, out_png)


def _plot_per_patch(results: list[LightingResult], out_png) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_png)
    n = len(results)
    fig, axes = plt.subplots(n, 1, figsize=(11, 2.3 * n + 0.8), squeeze=False, sharex=True)
    x = np.arange(len(results[0].patch_names)) if results else np.arange(0)
    shown = [("box", "naive box", "#bbbbbb"), ("cmf_weighted", "illuminant×CMF weights", "#7aa6c2"),
             ("projected", "projected (lbscene)", "#c0392b")]
    for ax, res in zip(axes[:, 0], results):
        for k, (m, label, colour_) in enumerate(shown):
            ax.bar(x + (k - 1) * 0.27, res.band_dE00[m], width=0.27, label=label, color=colour_)
        for d in res.displays:
            inside = ~d.out_of_gamut
            ax.plot(x[inside], d.dithered_8bit_dE00[inside], "k.", ms=4,
                    label=f"{d.display}: 8-bit dithered" if d is res.displays[0] else None)
        ax.axhline(TARGET_MAX_DE00, color="#c0392b", lw=0.6, ls="--")
        ax.set_ylabel("ΔE00")
        p, b = res.band_dE00["projected"], res.band_dE00["box"]
        ax.set_title(f"{res.lighting}   projected {p.mean():.2g}/{p.max():.2g}, "
                     f"naive box {b.mean():.2f}/{b.max():.2f} (mean/max)", fontsize=9, loc="left")
    if results:
        axes[-1, 0].set_xticks(x, results[0].patch_names, rotation=60, ha="right", fontsize=7)
        handles, labels = axes[0, 0].get_legend_handles_labels()
        fig.legend(handles, labels, fontsize=7, ncol=4, loc="upper center",
                   bbox_to_anchor=(0.5, 1 - 0.35 / fig.get_figheight()))
    fig.suptitle(f"Per-patch ΔE00 against the 1 nm reference ({COLORCHECKER_SET}, CIE 1931 2°); "
                 f"dashed: target max {TARGET_MAX_DE00}", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.55 / fig.get_figheight()))
    try:
        with output_path(out, suffix=".png", option="--plot") as tmp:
            fig.savefig(tmp, format="png", dpi=110)
    finally:
        plt.close(fig)
    return out
