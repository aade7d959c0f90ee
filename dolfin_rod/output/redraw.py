"""The pictures of a finished run drawn again from its folder (``dolfin-rod plot RUN
[quantities]``, ``RunResult.plot()``): nothing is recomputed.

    histories.png   from timeseries.csv and scene.toml: the scene's panels (plots.py), or
                    the ``quantities`` named: panels (tip_deflection, end_torque, ...) or
                    columns of the CSV (reaction_couple_end_z, ...) against time
    snapshots.png, animation.gif (animation.mp4 where ffmpeg exists)   3-D rod;
    spacetime.png   torsion: from rod.pvd (or rod.bp) when the run wrote its fields,
                    coloured by ``colour``

    redraw("results/gravity_cantilever-...", ["tip_deflection", "reaction_force_start_z"])

A quantity that is neither a panel nor a column, a folder that is not a finished run:
RedrawError naming it (the CLI's exit status 2), before anything is drawn.
"""

from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path

from ..checks import new_column
from ..scenes.schema import COLOURS, PANELS
from .run_folders import OutputError, scene_folder

__all__ = ["redraw", "read_rows", "RedrawError"]


class RedrawError(OutputError):
    """A run folder or a quantity that cannot be drawn."""


def read_rows(folder: Path) -> list[dict]:
    """The rows of timeseries.csv as floats (an empty field, NaN); the end columns of a
    run before the ends took the scene's names (reaction_force_left_x) as named now
    (reaction_force_start_x)."""
    path = Path(folder) / "timeseries.csv"
    if not path.is_file():
        raise RedrawError(f"{folder}: no timeseries.csv (not a run folder of dolfin-rod?)")
    try:
        with path.open() as f:
            rows = [{new_column(k): float(v) if v != "" else float("nan")
                     for k, v in r.items()} for r in csv.DictReader(f)]
    except (ValueError, TypeError, csv.Error) as err:     # binary, cut or extra fields
        raise RedrawError(f"{path}: not a time series of numbers ({err})") from None
    if len(rows) < 2:
        raise RedrawError(f"{path}: fewer than two rows, nothing to draw")
    return rows


def _named_now(quantities: list[str]) -> list[str]:
    """The quantities with an old end column (reaction_couple_right_z) as named now
    (reaction_couple_end_z), each with a DeprecationWarning naming the new name."""
    named = []
    for q in quantities:
        named.append(new_column(q))
        if named[-1] != q:
            warnings.warn(f"quantity {q!r} is deprecated and goes in the next release: use "
                          f"{named[-1]!r} (the ends are named start and end, as in the "
                          "scene)", DeprecationWarning, stacklevel=3)
    return named


def _check_quantities(quantities: list[str], columns) -> None:
    unknown = [q for q in quantities if q not in PANELS and q not in columns]
    if unknown:
        raise RedrawError(f"quantities: {', '.join(unknown)} is neither a panel ("
                          f"{', '.join(PANELS)}) nor a column of timeseries.csv "
                          f"({', '.join(c for c in columns if c not in ('step', 'time'))})")


def _frames(folder: Path) -> list:
    """(t, LineSample) of every step of rod.pvd, else rod.bp; [] if neither is there."""
    from .field_outputs import sample_from_steps
    if (folder / "rod.pvd").is_file():
        from .vtk_xml import read_pvd
        steps = read_pvd(folder / "rod.pvd")
    elif (folder / "rod.bp").is_dir():
        from .vtx import read_vtx
        steps = read_vtx(folder / "rod.bp")
    else:
        return []
    return [(s["time"], sample_from_steps(s)) for s in steps]


PICTURE_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def _target(folder: Path, to: Path | str | None) -> Path:
    """The histories figure's file: RUN/histories.png, or ``to`` if it names a picture
    and replaces no file outside the run folder (a user's file is never overwritten)."""
    if to is None:
        return folder / "histories.png"
    to = Path(to)
    if to.suffix.lower() not in PICTURE_SUFFIXES:
        raise RedrawError(f"--to {to}: name a picture file ({', '.join(PICTURE_SUFFIXES)})")
    if to.exists() and to.resolve().parent != folder.resolve():
        raise RedrawError(f"--to {to}: the file exists; dolfin-rod plot replaces files of "
                          "the run folder only: remove it or name a new file")
    return to


def redraw(folder: Path | str, quantities: list[str] | None = None, colour: str = "auto",
           to: Path | str | None = None) -> list[Path]:
    """Draw the run's pictures again (see module); ``to``: the histories figure's file
    (default RUN/histories.png).  Returns the files written."""
    from ..scenes import load_scene
    from ..scenes.scene import SceneError
    from . import animation
    from .plots import plot_histories
    folder = Path(folder)
    rows = read_rows(folder)
    quantities = _named_now(list(quantities or []))
    _check_quantities(quantities, rows[0])
    if colour not in COLOURS:
        raise RedrawError(f"--color {colour!r}: one of {', '.join(COLOURS)}")
    try:
        scene = load_scene(folder / "scene.toml", files=scene_folder(folder))
    except SceneError as err:
        raise RedrawError(f"{folder}: its scene.toml cannot be read: {err}") from None
    summary = folder / "summary.json"
    title = json.loads(summary.read_text()).get("title", "") if summary.is_file() else ""
    written = [_target(folder, to)]
    plot_histories(rows, written[0], scene, title, list(quantities or []) or None)
    frames = _frames(folder)
    if len(frames) > 1 and "centre_line" in frames[0][1].point:
        look = animation.Look.of(scene, None if colour == "auto" else colour)
        animation.rod_snapshots(frames, folder / "snapshots.png", title, look=look)
        video = folder / animation.animation_name()
        animation.rod_animation(frames, video, title, look)
        written += [folder / "snapshots.png", video]
    elif len(frames) > 1:
        animation.torsion_spacetime(frames, folder / "spacetime.png", title)
        written.append(folder / "spacetime.png")
    return written
