"""``lbscene accuracy [--booth PATH ...] [--display PATH ...] [--format text|json] [--plot OUT.png]``"""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import List, Optional

import typer

from lbscene.commands.console import echo
from lbscene.commands.options import Format
from lbscene.engine.files.textsafe import json_text


class Mapping(str, Enum):
    chroma = "chroma"
    clip = "clip"


def _repo_dir(name: str) -> Path:
    """``./<name>`` when it exists, else the shipped folder of that name (checkout or wheel)."""
    from lbscene.engine.files.shipped import data_dir

    here = Path.cwd() / name
    if here.is_dir():
        return here
    return data_dir(name) or here


def default_booths() -> list[Path]:
    root = _repo_dir("booths")
    return sorted(p for p in root.glob("*/booth.yaml")) if root.is_dir() else []


def default_displays() -> list[Path]:
    root = _repo_dir("displays")
    return sorted(root.glob("*.yaml")) if root.is_dir() else []


#: the built-in displays ``--display`` accepts by name, as ``render`` and ``export-web`` do
BUILTIN_DISPLAYS = ("builtin:srgb", "srgb")


def builtin_srgb_document():
    """The sRGB reference display of ``builtin:srgb`` as a display document: IEC 61966-2-1
    primaries, D65 white at 80 cd/m², the sRGB transfer function and no flare (the renderer's
    built-in display; ``displays/srgb-reference.yaml`` adds the standard's viewing flare)."""
    from lbscene.schemas.display import Display

    return Display.model_validate({
        "version": 1, "kind": "display", "name": "sRGB (IEC 61966-2-1), builtin",
        "provenance": {"status": "published", "source": "IEC 61966-2-1:1999, without viewing flare"},
        "primaries_xy": {"red": [0.64, 0.33], "green": [0.30, 0.60], "blue": [0.15, 0.06]},
        "white_xy": [0.3127, 0.3290], "white_luminance_cd_m2": 80, "black_luminance_cd_m2": 0,
        "tone_response": {c: {"type": "srgb"} for c in ("red", "green", "blue")},
        "screen_reflectance": 0.0, "bit_depth": 8})


def load_display_arg(text: str, mapping: str):
    """A ``--display`` value: ``builtin:srgb`` or a display file."""
    from lbscene.engine.colour.display_model import DisplayModel, load_display
    from lbscene.engine.files.diagnostics import LbsceneUserError

    t = str(text).strip()
    if t.lower() in BUILTIN_DISPLAYS:
        return DisplayModel(builtin_srgb_document(), None, mapping=mapping, display_name="builtin:srgb")
    if t.lower().startswith("builtin:"):
        raise LbsceneUserError.single("LB500", f"--display: unknown built-in display {t!r}", t,
                                      value=repr(t), expected="builtin:srgb or a display file")
    return load_display(Path(t), mapping=mapping)


def _fmt(x: float | None) -> str:
    if x is None:
        return "-"
    if x == 0:
        return "0"
    if abs(x) < 1e-3:
        return f"{x:.0e}"
    return f"{x:.3f}" if abs(x) < 10 else f"{x:.1f}"


def _text_report(results, rows) -> str:
    from lbscene.engine.colour.accuracy import (
        COLORCHECKER_SET,
        TARGET_MAX_DE00,
        TARGET_MEAN_DE00,
    )

    lines = [f"Band weighting vs 1 nm reference (360-830 nm, CIE 1931 2°), 24 patches of "
             f"{COLORCHECKER_SET}: ΔE00 mean/max",
             f"target for 'projected': mean <= {TARGET_MEAN_DE00}, max <= {TARGET_MAX_DE00}", ""]
    w = max([len(r.lighting) for r in results] + [8])
    head = f"{'lighting':<{w}}  {'projected':>17}  {'cmf_weighted':>13}  {'box':>13}  {'point':>13}  ok"
    lines += [head, "-" * len(head)]
    for r in results:
        b = r.band_dE00

        def mm(m):
            return f"{_fmt(b[m].mean())}/{_fmt(b[m].max())}"

        ok = b["projected"].mean() <= TARGET_MEAN_DE00 and b["projected"].max() <= TARGET_MAX_DE00
        lines.append(f"{r.lighting:<{w}}  {mm('projected'):>17}  {mm('cmf_weighted'):>13}  "
                     f"{mm('box'):>13}  {mm('point'):>13}  {'yes' if ok else 'NO'}")
    disp = [row for row in rows if row.get("display")]
    if disp:
        wd = max(len(row["display"]) for row in disp)
        lines += ["", "Display round trip (target XYZ → drive → predicted XYZ), ΔE00 mean/max over "
                      "in-gamut patches; out of gamut: count (max ΔE00 after mapping)", ""]
        head = (f"{'lighting':<{w}}  {'display':<{wd}}  {'white cd/m2':>11}  {'float':>15}  "
                f"{'8-bit nearest':>13}  {'8-bit dithered':>15}  out of gamut")
        lines += [head, "-" * len(head)]
        for row in disp:
            lines.append(
                f"{row['lighting']:<{w}}  {row['display']:<{wd}}  "
                f"{row['display_scene_white_cd_m2']:>11.1f}  "
                f"{_fmt(row['roundtrip_mean_dE00']) + '/' + _fmt(row['roundtrip_max_dE00']):>15}  "
                f"{_fmt(row['roundtrip_8bit_mean_dE00']) + '/' + _fmt(row['roundtrip_8bit_max_dE00']):>13}  "
                f"{_fmt(row['roundtrip_dithered_mean_dE00']) + '/' + _fmt(row['roundtrip_dithered_max_dE00']):>15}  "
                f"{row['out_of_gamut_count']} ({_fmt(row['out_of_gamut_max_dE00'])})")
    return "\n".join(lines)


def register(app: typer.Typer) -> None:
    @app.command("accuracy")
    def accuracy(
        booth: Optional[List[Path]] = typer.Option(
            None, "--booth", help="Booth folder or file whose lighting configurations to check "
                                  "(repeatable; default: every booth under booths/)."),
        display: Optional[List[str]] = typer.Option(
            None, "--display", help="Display file or builtin:srgb (repeatable; default: every file in "
                                    "displays/)."),
        format: Format = typer.Option(Format.text, "--format", help="text or json."),
        plot: Optional[Path] = typer.Option(None, "--plot", help="Write a per-patch ΔE00 plot (PNG)."),
        cie: bool = typer.Option(True, "--cie/--no-cie",
                                 help="Include CIE D65, A, F2, F7, F11 and a measured TL84."),
        mapping: Mapping = typer.Option(Mapping.chroma, "--mapping",
                                        help="Out-of-gamut mapping: chroma (constant luminance, "
                                             "toward the display white) or clip."),
    ) -> None:
        """Colour accuracy: 16-band weighting vs 1 nm, display round trips, out-of-gamut counts.

        Exit 0 when the band weighting meets its target (mean <= 0.1, max <= 0.3 ΔE00) under
        every lighting, 1 otherwise, 2 on a user error.
        """
        from rich.progress import BarColumn, TextColumn, TimeElapsedColumn

        from lbscene.engine.colour.accuracy import (
            accuracy_rows,
            booth_lighting_spds,
            cie_lighting_spds,
            evaluate_lighting,
            plot_per_patch,
        )
        from lbscene.engine.colour.display_model import load_display
        from lbscene.engine.scene.compile import compile_booth
        from lbscene.engine.files.diagnostics import LbsceneUserError

        if plot is not None and plot.suffix.lower() != ".png":
            raise LbsceneUserError.single("LB500", "--plot must name a .png file", str(plot),
                                          value=str(plot), expected="a path ending in .png")
        from lbscene.engine.files.outputs import check_outputs

        check_outputs([(plot, "--plot")], inputs=[*(booth or ()), *(Path(d) for d in (display or ())
                                                                      if d.strip().lower() not in BUILTIN_DISPLAYS)])
        booths = list(booth) if booth else default_booths()
        displays = [load_display_arg(str(p), mapping.value)
                    for p in (list(display) if display else default_displays())]
        lightings: list[tuple[str, str, object]] = []
        if cie:
            lightings += [(k, "CIE/colour-science", v) for k, v in cie_lighting_spds().items()]
        for b in booths:
            lightings += [(k, str(b), v) for k, v in booth_lighting_spds(compile_booth(b)).items()]
        if not lightings:
            raise LbsceneUserError.single("LB500", "no lighting to check", "<command line>",
                                          expected="--cie or at least one --booth with lighting")
        results = []
        from lbscene.commands.console import err_console, progress

        with progress(TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                      console=err_console(), transient=True,
                      disable=format is Format.json) as prog:
            task = prog.add_task("accuracy", total=len(lightings))
            for label, source, spd in lightings:
                prog.update(task, description=f"accuracy: {label}")
                results.append(evaluate_lighting(label, spd, displays, source=source))
                prog.advance(task)
        rows = accuracy_rows(results)
        if plot is not None:
            plot_per_patch(results, plot)
        if format is Format.json:
            echo(json_text(rows, indent=2, allow_nan=False))
        else:
            echo(_text_report(results, rows))
            if plot is not None:
                echo(f"\nplot: {plot}")
        raise typer.Exit(0 if all(r["band_target_met"] for r in rows) else 1)
