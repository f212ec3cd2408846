r"""
Display characterisation with ambient light: absolute XYZ ↔ drive values.

The forward model (see :mod:`lbscene.schemas.display` for the document)::

    XYZ_seen(d) = XYZ_floor + M · f(d),      XYZ_floor = XYZ_black + XYZ_ambient      (1)

``d`` drive values in [0, 1]; ``f`` the per-channel tone responses (normalised,
black-corrected); ``M`` the black-corrected primary matrix in cd/m² (columns:
XYZ of each primary at full drive minus the black level), built with
colour-science's ``normalised_primary_matrix`` from the primaries and the
chromaticity of ``XYZ_white − XYZ_black``; ``XYZ_ambient`` the diffusely
reflected room light, ``ρ_screen · E_lx / π`` cd/m² at the ambient's
chromaticity.  This is the structure of the seed's MDCIM (display primaries,
tone response, black level, and the ambient light the screen reflects).

The inverse :meth:`DisplayModel.xyz_to_drive` subtracts the floor, solves
``rgb = M⁻¹ (XYZ − XYZ_floor)``, maps colours outside the gamut, and inverts
the tone responses.

Out-of-gamut mapping (documented, mirrored by ``runtimes/shaders/lib_display.glsl``)
-----------------------------------------------------------------------------------
A target is out of gamut when a linear channel of ``rgb`` leaves [0, 1]
(tolerance 1e-9).  Two mappings:

``"chroma"`` (default) — constant luminance, straight toward the display's
    neutral: with ``Y'`` the target's luminance above the floor clipped to
    ``[0, Y_span]`` (``Y_span = Y_white − Y_black``), the grey of equal
    luminance is ``g = (Y'/Y_span)·(1, 1, 1)``; the shown colour is
    ``g + s·(rgb − g)`` with the largest ``s ∈ [0, 1]`` that keeps every
    channel in [0, 1].  Because both end points have the same luminance, the
    result keeps the target's luminance (whenever it is displayable) and moves
    its chromaticity along the straight line toward the display white in the
    CIE 1931 xy diagram (constant dominant wavelength) — only chroma is lost.
    Targets darker than the floor (ambient reflection + black) become black;
    brighter than white become white.
``"clip"`` — each channel clipped to [0, 1] (the shader's ``GAMUT_MAPPING 0``).

The report (:class:`GamutReport`) counts the out-of-gamut items and says by
how much: the largest linear-channel excess and the ΔE00 between the target
and what is shown (CIE 2000, relative to a reference white, default the
display's full white as seen, ambient included).

Examples
--------
>>> from lbscene.schemas.display import Display
>>> doc = Display.model_validate({
...     "version": 1, "kind": "display", "name": "sRGB", "provenance": {"status": "published"},
...     "primaries_xy": {"red": [0.64, 0.33], "green": [0.30, 0.60], "blue": [0.15, 0.06]},
...     "white_xy": [0.3127, 0.3290], "white_luminance_cd_m2": 80,
...     "tone_response": {c: {"type": "srgb"} for c in ("red", "green", "blue")}})
>>> model = DisplayModel(doc)
>>> import numpy as np
>>> d = np.array([0.5, 0.25, 0.75])
>>> np.allclose(model.xyz_to_drive(model.drive_to_xyz(d)), d)
True
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Literal

import numpy as np

__all__ = [
    "ToneCurve",
    "tone_curve",
    "GamutReport",
    "DisplayModel",
    "load_display",
    "GAMUT_MAPPINGS",
    "IN_GAMUT_TOLERANCE",
    "TONE_KIND_SRGB",
    "TONE_KIND_GOG",
    "TONE_KIND_LUT",
]

GAMUT_MAPPINGS = ("chroma", "clip")
IN_GAMUT_TOLERANCE = 1e-9
TONE_KIND_SRGB, TONE_KIND_GOG, TONE_KIND_LUT = 0, 1, 2


# --------------------------------------------------------------------------- tone responses

@dataclass(frozen=True)
class ToneCurve:
    """One channel's tone response: ``forward`` drive → normalised luminance, and its inverse.

    ``glsl`` holds the shader form: ``("srgb", None)``, ``("gog", (gain, offset, gamma))``
    or ``("lut", None)``.
    """

    kind: str
    forward: Callable[[np.ndarray], np.ndarray]
    inverse: Callable[[np.ndarray], np.ndarray]
    gog: tuple[float, float, float] | None = None


def _srgb_forward(d):
    d = np.clip(d, 0.0, 1.0)
    return np.where(d <= 0.04045, d / 12.92, ((d + 0.055) / 1.055) ** 2.4)


def _srgb_inverse(x):
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def tone_curve(spec) -> ToneCurve:
    """Build a :class:`ToneCurve` from a ``tone_response`` node of a display document."""
    t = spec.type
    if t == "srgb":
        return ToneCurve("srgb", _srgb_forward, _srgb_inverse)
    if t in ("gamma", "gog"):
        if t == "gamma":
            gain, offset, gamma = 1.0, 0.0, float(spec.gamma)
        else:
            # normalise so that f(1) = 1 exactly (the schema allows |gain + offset − 1| ≤ 1e-3)
            tot = float(spec.gain) + float(spec.offset)
            gain, offset, gamma = float(spec.gain) / tot, float(spec.offset) / tot, float(spec.gamma)

        def fwd(d, g=gain, o=offset, y=gamma):
            return np.maximum(g * np.clip(d, 0.0, 1.0) + o, 0.0) ** y

        def inv(x, g=gain, o=offset, y=gamma):
            # the highest drive giving x (at x = 0: the drive where light starts, −o/g)
            return np.clip((np.clip(x, 0.0, 1.0) ** (1.0 / y) - o) / g, 0.0, 1.0)

        return ToneCurve("gog", fwd, inv, (gain, offset, gamma))
    if t == "lut":
        dr = np.asarray(spec.drive, float)
        out = np.asarray(spec.output, float)

        def fwd(d, dr=dr, out=out):
            return np.interp(np.clip(d, 0.0, 1.0), dr, out)

        def inv(x, dr=dr, out=out):
            return np.interp(np.clip(x, 0.0, 1.0), out, dr)

        return ToneCurve("lut", fwd, inv)
    raise ValueError(f"unknown tone response type {t!r}")  # pragma: no cover - schema prevents it


# --------------------------------------------------------------------------- gamut report

@dataclass
class GamutReport:
    """Out-of-gamut colours of one conversion and by how much they were moved."""

    mapping: str
    total: int
    mask: np.ndarray = field(repr=False)               # bool, True: out of gamut
    excess: np.ndarray = field(repr=False)             # largest linear-channel excess, 0 inside
    delta_e00: np.ndarray = field(repr=False)          # target vs shown, 0 inside
    below_floor: int = 0                               # darker than ambient reflection + black
    above_white: int = 0                               # brighter than the display white

    @property
    def count(self) -> int:
        return int(self.mask.sum())

    @property
    def fraction(self) -> float:
        return self.count / self.total if self.total else 0.0

    @property
    def max_excess(self) -> float:
        return float(self.excess.max()) if self.excess.size else 0.0

    @property
    def max_delta_e00(self) -> float:
        return float(self.delta_e00.max()) if self.delta_e00.size else 0.0

    @property
    def mean_delta_e00(self) -> float:
        """Mean ΔE00 over the out-of-gamut items (0 when there are none)."""
        return float(self.delta_e00[self.mask].mean()) if self.count else 0.0

    def to_json(self) -> dict:
        return {"mapping": self.mapping, "count": self.count, "total": self.total,
                "fraction": self.fraction, "max_excess": self.max_excess,
                "max_dE00": self.max_delta_e00, "mean_dE00": self.mean_delta_e00,
                "below_floor": self.below_floor, "above_white": self.above_white}


def _lab(xyz: np.ndarray, white_xyz: np.ndarray) -> np.ndarray:
    import colour

    white = np.asarray(white_xyz, float)
    return colour.XYZ_to_Lab(np.asarray(xyz, float) / white[1], colour.XYZ_to_xy(white))


def _delta_e00(xyz_a, xyz_b, white_xyz) -> np.ndarray:
    import colour

    return np.asarray(colour.delta_E(_lab(xyz_a, white_xyz), _lab(xyz_b, white_xyz),
                                     method="CIE 2000"), float)


# --------------------------------------------------------------------------- the model

class DisplayModel:
    """A characterised display in its viewing environment (equation 1).

    Parameters
    ----------
    display
        A validated :class:`lbscene.schemas.display.Display`.
    resolve
        Resolves file references of the document (``LoadedDocument.resolve``),
        needed when the ambient spectrum is a CSV or instrument file.
    mapping
        Default out-of-gamut mapping, ``"chroma"`` or ``"clip"``.
    """

    def __init__(self, display, resolve=None, *, mapping: Literal["chroma", "clip"] = "chroma",
                 display_name: str = "<display>"):
        import colour

        from lbscene.engine.spectra.evaluate import cmfs_1nm, evaluate_spectrum

        if mapping not in GAMUT_MAPPINGS:
            raise ValueError(f"mapping must be one of {GAMUT_MAPPINGS}")
        self.document = display
        self.name = display.name
        self.mapping = mapping
        self.curves = tuple(tone_curve(getattr(display.tone_response, c))
                            for c in ("red", "green", "blue"))
        yw, yk = float(display.white_luminance_cd_m2), float(display.black_luminance_cd_m2)
        self.xyz_white_emitted = colour.xyY_to_XYZ(np.array([*display.white_xy, yw]))
        black_xy = display.black_xy or display.white_xy
        self.xyz_black = colour.xyY_to_XYZ(np.array([*black_xy, yk])) if yk > 0 else np.zeros(3)
        span = self.xyz_white_emitted - self.xyz_black
        primaries = np.array([display.primaries_xy.red, display.primaries_xy.green,
                              display.primaries_xy.blue], float)
        npm = colour.normalised_primary_matrix(primaries, colour.XYZ_to_xy(span))
        #: linear RGB (0..1) → black-corrected XYZ, cd/m²
        self.rgb_to_xyz = npm * span[1]
        self.xyz_to_rgb = np.linalg.inv(self.rgb_to_xyz)
        self.y_span_cd_m2 = float(span[1])
        if display.ambient is not None and display.ambient.illuminance_lx > 0 \
                and display.screen_reflectance > 0:
            spd = evaluate_spectrum(display.ambient.spd, resolve, "emission",
                                    display=f"{display_name}: ambient.spd")
            xyz = spd @ cmfs_1nm()
            if not xyz[1] > 0:
                from lbscene.engine.files.diagnostics import LbsceneUserError

                raise LbsceneUserError.single("LB104", "ambient spectrum has no visible light",
                                              display_name, expected="a spectrum with Y > 0")
            luminance = display.screen_reflectance * display.ambient.illuminance_lx / np.pi
            self.xyz_ambient = xyz / xyz[1] * luminance
        else:
            self.xyz_ambient = np.zeros(3)
        #: what the observer sees at drive (0, 0, 0): black level plus reflected ambient
        self.xyz_floor = self.xyz_black + self.xyz_ambient
        #: what the observer sees at drive (1, 1, 1)
        self.xyz_white_seen = self.xyz_floor + self.rgb_to_xyz @ np.ones(3)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_file(cls, path, **kwargs) -> "DisplayModel":
        return load_display(path, **kwargs)

    # ------------------------------------------------------------------ forward
    def drive_to_linear(self, drive) -> np.ndarray:
        d = np.asarray(drive, float)
        return np.stack([self.curves[c].forward(d[..., c]) for c in range(3)], axis=-1)

    def linear_to_drive(self, rgb_linear) -> np.ndarray:
        x = np.asarray(rgb_linear, float)
        return np.stack([self.curves[c].inverse(x[..., c]) for c in range(3)], axis=-1)

    def drive_to_xyz(self, drive) -> np.ndarray:
        """Absolute XYZ (cd/m²) the observer sees for drive values (..., 3) in [0, 1]."""
        return self.xyz_floor + self.drive_to_linear(drive) @ self.rgb_to_xyz.T

    def codes_to_xyz(self, codes) -> np.ndarray:
        """Forward model of integer codes (0 … 2^bit_depth − 1)."""
        levels = 2 ** self.document.bit_depth - 1
        return self.drive_to_xyz(np.asarray(codes, float) / levels)

    # ------------------------------------------------------------------ inverse
    def xyz_to_linear(self, xyz_abs) -> np.ndarray:
        """Unmapped linear RGB: ``M⁻¹ (XYZ − XYZ_floor)`` (may leave [0, 1])."""
        return (np.asarray(xyz_abs, float) - self.xyz_floor) @ self.xyz_to_rgb.T

    def map_linear(self, rgb, y_above_floor, mapping: str | None = None) -> np.ndarray:
        """Apply the out-of-gamut mapping to linear RGB (see the module notes)."""
        mapping = mapping or self.mapping
        rgb = np.asarray(rgb, float)
        if mapping == "clip":
            return np.clip(rgb, 0.0, 1.0)
        if mapping != "chroma":
            raise ValueError(f"mapping must be one of {GAMUT_MAPPINGS}")
        g = np.clip(np.asarray(y_above_floor, float) / self.y_span_cd_m2, 0.0, 1.0)[..., None]
        diff = rgb - g
        with np.errstate(divide="ignore", invalid="ignore"):
            hi = np.where(rgb > 1.0, (1.0 - g) / diff, np.inf)
            lo = np.where(rgb < 0.0, g / -diff, np.inf)
        s = np.clip(np.minimum(hi, lo).min(axis=-1, keepdims=True), 0.0, 1.0)
        return np.clip(g + s * diff, 0.0, 1.0)

    def adaptation_matrix(self, white_source_xyz, method: str = "cat16") -> np.ndarray:
        """3×3 chromatic adaptation from a scene white to this display's white as seen.

        ``XYZ_shown = A @ XYZ_scene`` (luminance kept); see :mod:`lbscene.engine.colour.adaptation`.
        ``method``: ``"cat16"`` (what a person adapted to the scene sees) or ``"none"`` (identity:
        what a camera sees).
        """
        from .adaptation import adaptation_matrix

        return adaptation_matrix(white_source_xyz, self.xyz_white_seen, method)

    def xyz_to_drive(self, xyz_abs, *, mapping: str | None = None, report: bool = False,
                     white_xyz=None, adapt_from_white_xyz=None, adaptation: str = "cat16"):
        """Drive values (..., 3) in [0, 1] that reproduce absolute XYZ (cd/m²) as seen.

        Parameters
        ----------
        xyz_abs
            Target tristimulus values as the observer should see them, (..., 3), cd/m².
        mapping
            ``"chroma"`` or ``"clip"`` (default: the model's).
        report
            Also return a :class:`GamutReport`.
        white_xyz
            Reference white for the report's ΔE00 (default :attr:`xyz_white_seen`).
        adapt_from_white_xyz
            White of the scene the targets were seen in (e.g. a perfect white diffuser under
            the booth's lighting).  When given, the targets are first taken to their corresponding
            colours under the display's white with :meth:`adaptation_matrix` (``adaptation``:
            ``"cat16"`` or ``"none"``).
        """
        xyz = np.asarray(xyz_abs, float)
        if adapt_from_white_xyz is not None:
            xyz = xyz @ self.adaptation_matrix(adapt_from_white_xyz, adaptation).T
        rgb = self.xyz_to_linear(xyz)
        y_rel = xyz[..., 1] - self.xyz_floor[1]
        mapping = mapping or self.mapping
        out = (rgb < -IN_GAMUT_TOLERANCE) | (rgb > 1 + IN_GAMUT_TOLERANCE)
        oog = out.any(axis=-1)
        mapped = np.where(oog[..., None], self.map_linear(rgb, y_rel, mapping),
                          np.clip(rgb, 0.0, 1.0))
        drive = self.linear_to_drive(mapped)
        if not report:
            return drive
        excess = np.maximum(np.maximum(-rgb, rgb - 1.0), 0.0).max(axis=-1) * oog
        de = np.zeros(oog.shape)
        if oog.any():
            shown = self.xyz_floor + mapped[oog] @ self.rgb_to_xyz.T
            de[oog] = _delta_e00(xyz[oog], shown,
                                 self.xyz_white_seen if white_xyz is None else white_xyz)
        rep = GamutReport(mapping=mapping, total=int(oog.size), mask=oog, excess=excess,
                          delta_e00=de, below_floor=int(np.sum(oog & (y_rel < 0))),
                          above_white=int(np.sum(oog & (y_rel > self.y_span_cd_m2))))
        return drive, rep

    def gamut_report(self, xyz_abs, *, mapping: str | None = None, white_xyz=None) -> GamutReport:
        """Only the out-of-gamut report of :meth:`xyz_to_drive`."""
        return self.xyz_to_drive(xyz_abs, mapping=mapping, report=True, white_xyz=white_xyz)[1]

    def max_luminance_cd_m2(self, xy) -> float:
        """Highest luminance (as seen, floor included) displayable at chromaticity ``xy``.

        0 when no luminance of that chromaticity is displayable.
        """
        c = np.array([xy[0] / xy[1], 1.0, (1 - xy[0] - xy[1]) / xy[1]])
        u = self.xyz_to_rgb @ c            # rgb(t) = t·u − v must stay in [0, 1]
        v = self.xyz_to_rgb @ self.xyz_floor
        lo, hi = 0.0, np.inf
        tiny = 1e-9 * float(np.abs(u).max())
        for ui, vi in zip(u, v):
            if abs(ui) <= tiny:             # this channel does not change along the ray
                if not (-1e-9 <= -vi <= 1 + 1e-9):
                    return 0.0
                continue
            a, b = vi / ui, (1 + vi) / ui
            lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
        return float(hi) if hi >= lo else 0.0

    # ------------------------------------------------------------------ shader export
    def tone_kind(self) -> int:
        kinds = {c.kind for c in self.curves}
        if kinds == {"srgb"}:
            return TONE_KIND_SRGB
        if kinds == {"gog"}:
            return TONE_KIND_GOG
        return TONE_KIND_LUT

    def glsl_uniforms(self, *, lut_size: int = 4096) -> dict:
        """Everything a GLSL ES 3.00 shader needs to mirror :meth:`xyz_to_drive`, as plain floats.

        Keys
        ----
        ``xyz_to_rgb``
            3×3 nested rows: ``rgb = xyz_to_rgb · (XYZ − xyz_offset)``; XYZ in cd/m².
        ``xyz_to_rgb_column_major``
            The same 9 numbers in the order a GLSL ``mat3`` uniform takes them.
        ``xyz_offset``
            XYZ of black level + reflected ambient (cd/m²).
        ``rgb_to_xyz``, ``rgb_to_xyz_column_major``
            The forward matrix (black-corrected), for previews of what is seen.
        ``white_Y_cd_m2``
            Luminance of drive (1, 1, 1) in a dark room; ``y_span_cd_m2`` its part
            above the black level; ``inv_y_span`` its reciprocal (chroma mapping).
        ``tone_kind``
            0: sRGB piecewise on every channel, 1: gain-offset-gamma on every channel
            (``tone_params[c] = (gain, offset, gamma, 0)``, ``f(d) = max(gain·d + offset, 0)^gamma``,
            inverse ``(l^(1/gamma) − offset)/gain``), 2: inverse table ``tone_lut``.
        ``tone_lut``
            ``lut_size`` rows × 3: the drive for linear value ``i/(lut_size − 1)`` (kind 2 only;
            ``None`` otherwise).
        ``gamut_mapping``
            0: clip, 1: chroma (constant luminance toward the neutral; see module notes).
        """
        kind = self.tone_kind()
        params = [[1.0, 0.0, 2.2, 0.0]] * 3
        if kind == TONE_KIND_GOG:
            params = [[*c.gog, 0.0] for c in self.curves]
        lut = None
        if kind == TONE_KIND_LUT:
            x = np.linspace(0.0, 1.0, lut_size)
            lut = self.linear_to_drive(np.stack([x] * 3, axis=-1)).tolist()

        def flt(a):
            return [float(v) for v in np.asarray(a, float).ravel()]

        return {
            "name": self.name,
            "white_Y_cd_m2": float(self.document.white_luminance_cd_m2),
            "y_span_cd_m2": self.y_span_cd_m2,
            "inv_y_span": 1.0 / self.y_span_cd_m2,
            "xyz_to_rgb": [flt(r) for r in self.xyz_to_rgb],
            "xyz_to_rgb_column_major": flt(self.xyz_to_rgb.T),
            "rgb_to_xyz": [flt(r) for r in self.rgb_to_xyz],
            "rgb_to_xyz_column_major": flt(self.rgb_to_xyz.T),
            "xyz_offset": flt(self.xyz_floor),
            "xyz_white_seen": flt(self.xyz_white_seen),
            "tone_kind": kind,
            "tone_params": [flt(p) for p in params],
            "tone_lut": lut,
            "tone_lut_size": lut_size if lut is not None else 0,
            "gamut_mapping": 1 if self.mapping == "chroma" else 0,
            "bit_depth": int(self.document.bit_depth),
        }

    #: alias with the brief's wording
    shader_parameters = glsl_uniforms


def load_display(path, *, mapping: Literal["chroma", "clip"] = "chroma") -> DisplayModel:
    """Load a display YAML file (located diagnostics on errors) and build its model."""
    from lbscene.engine.files.load import load_document
    from lbscene.schemas.display import Display

    doc = load_document(Path(path), Display)
    return DisplayModel(doc.model, doc.resolve, mapping=mapping, display_name=doc.file)
