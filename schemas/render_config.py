"""
The render configuration: what ``lbscene render CONFIG.yaml`` draws.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Document, StrictModel, Vec3_mm
from .booth import GeometryName
from .refs import FileRef

__all__ = ["RenderConfig", "Camera", "RenderOutput", "Exposure"]


class Camera(StrictModel):
    """Camera; default: the booth's observer looking at the sample."""

    type: Literal["observer", "free"] = "observer"
    position_mm: Vec3_mm | None = None
    look_at_mm: Vec3_mm | None = None
    vertical_fov_deg: float = Field(30.0, gt=1, lt=170)


class RenderOutput(StrictModel):
    png: str = Field("render.png", description="Display-encoded image, relative to the config file.")
    xyz: str | None = Field(None, description="Float XYZ image (.exr or .npy) for analysis.")
    width_px: int = Field(1024, ge=16, le=8192)
    height_px: int = Field(768, ge=16, le=8192)


class Exposure(StrictModel):
    """How absolute luminances are put on the display."""

    mode: Literal["relative_white", "absolute"] = Field(
        "relative_white",
        description="relative_white: a perfect white diffuser at the sample is shown at `white_fraction` "
                    "of the display's white luminance; absolute: XYZ in cd/m² as they are (mapped into "
                    "the display's gamut). Chromatic adaptation is set apart, by `adaptation`.")
    white_fraction: float = Field(1.0, gt=0, le=10, description="See `mode`.")


class RenderConfig(Document):
    """Booth, lighting, geometry, sample, display and camera of one rendering."""

    kind: Literal["render_config"] = Field(description="Document kind.")
    booth: str = Field(description="Booth folder or booth.yaml (relative to this file; may be outside "
                                   "this file's folder).")
    lighting: str = Field(description="Lighting configuration name of the booth.")
    geometry: GeometryName | None = Field(None, description="Viewing geometry (booths that have them).")
    sample: FileRef = Field(description="Sample document.")
    display: str = Field(description="Display document (path; may be outside this file's folder), or "
                                     "'builtin:srgb' for the sRGB reference display.")
    bake: str | None = Field(None, description="Bake output folder (default: the build folder's bakes).")
    diffuse: Literal["auto", "baked", "analytic"] = Field(
        "auto", description="Diffuse light: 'baked' needs bake products (an error names the bake to run), "
                            "'analytic' uses the forward model, 'auto' the bake when there is one.")
    exposure: Exposure = Exposure()
    adaptation: Literal["cat16", "none"] = Field(
        "cat16",
        description="Chromatic adaptation. cat16: colours are taken from the white of the lighting at the "
                    "sample to the display's white with CAT16 (von Kries, full adaptation): what a person "
                    "in the booth sees (a grey under illuminant A looks grey). none: shown as they are: "
                    "what a camera with a D65 white balance sees (a grey under A looks orange).")
    dither: bool = Field(True, description="Blue-noise dithering before 8-bit quantisation.")
    camera: Camera = Camera()
    output: RenderOutput = RenderOutput()
