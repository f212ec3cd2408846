"""Options shared by several commands (one definition, one help text)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Optional

import typer

__all__ = ["Format", "allow_path_option", "measurements_argument", "booth_override_option"]


class Format(str, Enum):
    """Output format of a command: human text (rich) or one JSON object."""

    text = "text"
    json = "json"


def allow_path_option():
    return typer.Option(None, "--allow-path", help="Extra folder file references may point into.")


def measurements_argument():
    return typer.Argument(..., help="Measurement-set YAML (kind: measurement_set).")


def booth_override_option() -> Optional[Path]:
    return typer.Option(None, "--booth", help="Booth folder/file (overrides the measurement set's booth:).")
