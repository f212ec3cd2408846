"""
The measurement-set document: what a user measured in a booth.

A measurement set names the booth, the lighting configuration, the
instruments and the data files (CSV, or instrument exports colour-science
reads).  Booth coordinates: millimetres, origin at the centre of the booth
floor, +x to the observer's right, +y from the open front toward the rear
wall, +z up.

Example (YAML)::

    version: 1
    kind: measurement_set
    name: SpectraLight QC, D65, 55-point A3 grid
    booth: ../../booths/xrite-spectralight-qc
    lighting: D65
    instrument: {illuminance_meter: Konica Minolta CL-500A, repeatability_percent: 1.0}
    illuminance:
      - path: grid.csv            # x_mm,y_mm,illuminance_lx[,z_mm][,orientation|normal_x,normal_y,normal_z]
    white_tile:
      radiance: {type: csv, path: tile.csv}       # wavelength_nm,radiance (W·sr⁻¹·m⁻²·nm⁻¹)
      reflectance: {type: constant, value: 0.99}

Illuminance CSV columns: ``x_mm``, ``y_mm``, ``illuminance_lx`` (required),
``z_mm`` (default: the file entry's ``z_mm``, 0 = floor), the sensor
orientation as ``orientation`` (``up``, ``down``, ``+x``, ``-x``, ``+y``,
``-y``) or as ``normal_x,normal_y,normal_z`` (default: up), and an optional
free-text ``label``.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .base import Direction, Document, Identifier, Provenance, StrictModel, Vec3_mm
from .refs import FileRef
from .spectrum import SpectrumSpec

__all__ = ["MeasurementSet", "IlluminanceFile", "WhiteTile", "Instrument", "ORIENTATIONS"]

#: Named sensor orientations (the direction the sensor's surface faces).
ORIENTATIONS: dict[str, tuple[float, float, float]] = {
    "up": (0.0, 0.0, 1.0), "down": (0.0, 0.0, -1.0),
    "+x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0),
    "+y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0),
}


class Instrument(StrictModel):
    """The instruments used, with their repeatability (the noise the fit should expect)."""

    illuminance_meter: str = Field("", max_length=200, description="Make and model of the meter.")
    spectroradiometer: str = Field("", max_length=200, description="Make and model (white tile).")
    repeatability_percent: float | None = Field(
        None, gt=0, le=50,
        description="1σ noise of one illuminance reading, % of the reading (default: estimated "
                    "from the data).")
    spectral_noise_percent: float | None = Field(
        None, gt=0, le=50, description="1σ noise of a band value of the radiance, % (default 1).")


class IlluminanceFile(StrictModel):
    """One CSV of illuminance readings."""

    path: FileRef = Field(description="CSV: x_mm,y_mm,illuminance_lx[,z_mm][,orientation|normal_*].")
    z_mm: float = Field(0.0, ge=0, description="Sensor height when the CSV has no z_mm column.")
    orientation: Literal["up", "down", "+x", "-x", "+y", "-y"] = Field(
        "up", description="Sensor orientation when the CSV has no orientation/normal columns.")
    description: str = Field("", max_length=2000)


class WhiteTile(StrictModel):
    """A white reference tile measured with a tele-spectroradiometer."""

    position_mm: Vec3_mm | None = Field(None, description="Tile centre (default: the booth's sample "
                                                          "position).")
    normal: Direction = Field((0.0, 0.0, 1.0), description="Tile normal.")
    radiance: SpectrumSpec = Field(description="Measured spectral radiance, W·sr⁻¹·m⁻²·nm⁻¹ "
                                               "(CSV header wavelength_nm,radiance).")
    reflectance: SpectrumSpec = Field(
        {"type": "constant", "value": 0.99},
        description="Calibrated reflectance factor of the tile (CSV header wavelength_nm,reflectance).")


class MeasurementSet(Document):
    """Measurements taken in one booth under one lighting configuration."""

    kind: Literal["measurement_set"] = Field(description="Document kind.")
    name: str = Field(min_length=1, max_length=200)
    booth: str = Field(min_length=1, max_length=1024,
                       description="Booth folder or booth.yaml, relative to this file (the booth is "
                                   "a document you name, so it may live anywhere).")
    lighting: Identifier = Field(description="Lighting configuration of the booth that was on.")
    instrument: Instrument = Instrument()
    date: str = Field("", max_length=100)
    provenance: Provenance | None = None
    illuminance: list[IlluminanceFile] = Field(default_factory=list, max_length=64)
    white_tile: WhiteTile | None = None
    surface_reflectances: dict[Identifier, SpectrumSpec] = Field(
        default_factory=dict,
        description="Measured reflectance of booth materials (material id → spectrum); replaces the "
                    "booth's values in the model.")
    known_output_groups: list[Identifier] = Field(
        default_factory=list,
        description="Lamp groups whose output is known for this session (added to the booth's "
                    "fit.known_output_groups): not fitted, so a level mismatch is evidence.")
    model_uncertainty_percent: float = Field(
        0.0, ge=0, le=50,
        description="Relative uncertainty of the booth model itself (one standard deviation, %): folded "
                    "into the meter noise, so residuals it covers are not taken as a missing effect.")
    notes: str = Field("", max_length=4000)

    @model_validator(mode="after")
    def _has_data(self):
        if not self.illuminance and self.white_tile is None:
            raise ValueError("a measurement set needs `illuminance:` files or a `white_tile:`")
        return self
