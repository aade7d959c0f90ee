"""Run folders: where a run may write (``folder_problem``), a fresh or resumed results
folder (``prepare_run_folder``, ``new_run_folder``), the files it holds (``files_in``),
the folder of the files its scene.toml names (``scene_folder``), and file-system errors raised on every rank (``on_root``, :class:`OutputError`), so no
rank waits in a collective call for one that failed.

Every folder made here carries the marker file ``.dolfin-rod-run``; ``--overwrite``
replaces only a folder with that marker (never a user's folder that happens to hold a
``scene.toml``), never through a symbolic link, and never one holding a file that no
run wrote (a user's script or notes put into the run folder: ``foreign_files``).
"""

from __future__ import annotations

import datetime
import json
import os
import shutil
import tempfile
from pathlib import Path


class OutputError(RuntimeError):
    """A results folder or checkpoint cannot be used; nothing was written (exit 2)."""


def on_root(comm, action, what: str):
    """``action()`` on rank 0 only, its result on every rank; an OSError or ValueError
    there is raised on every rank as OutputError("what: reason")."""
    result, error = None, None
    if comm.rank == 0:
        try:
            result = action()
        except OutputError as err:
            error = str(err)
        except (OSError, ValueError) as err:
            error = f"{what}: {getattr(err, 'strerror', None) or err}"
    error, result = comm.bcast((error, result), root=0)
    if error is not None:
        raise OutputError(error)
    return result


def folder_problem(path: Path) -> str | None:
    """Why ``path`` cannot become a results folder (None if it can): a NUL, a name too
    long, an existing file, a file or an unwritable folder on the way.  Writability is
    probed by creating and removing a temporary folder (permission bits do not tell a
    root user about read-only file systems)."""
    from ..scenes.values import path_problem
    problem = path_problem(str(path))
    if problem:
        return f"{str(path)[:80]!r}: {problem}"
    if path.exists() and not path.is_dir():
        return f"{path} exists and is not a folder"
    ancestor = path
    while not ancestor.exists():
        if ancestor.is_symlink():
            return f"{ancestor} is a broken symbolic link"
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        return f"{ancestor} is a file, so {path} cannot be a folder"
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".dolfin-rod-probe-", dir=ancestor))
    except OSError as err:
        return f"cannot create folders in {ancestor}: {err.strerror or err}"
    return None


MARKER = ".dolfin-rod-run"


def mark_run_folder(folder: Path) -> None:
    """Rank 0: the marker that makes ``folder`` replaceable by ``--overwrite``."""
    from .. import __version__
    (folder / MARKER).write_text(f"dolfin-rod {__version__} made this run folder; "
                                 "`dolfin-rod run --overwrite` may replace it\n")


def is_run_folder(folder: Path) -> bool:
    """``folder`` (not a link) holds the marker this program wrote (mark_run_folder)."""
    marker = folder / MARKER
    return not folder.is_symlink() and marker.is_file() and not marker.is_symlink()


def prepare_run_folder(folder: Path, resume: bool, overwrite: bool,
                       remedy: str = "pass --resume to continue its run or --overwrite "
                                     "to replace it") -> None:
    """Rank 0: make ``folder`` ready; a non-empty folder is reused only to resume, or
    replaced with ``overwrite`` if this program made it (its marker; never any other
    folder, never through a symbolic link); ``remedy``: what the command offers for a
    folder that is not empty."""
    problem = folder_problem(folder)
    if problem:
        raise OutputError(f"--out {problem}")
    if resume:
        if not folder.is_dir():
            raise OutputError(f"--resume: {folder} is not a run folder")
        return
    if folder.is_dir() and any(folder.iterdir()):
        if not overwrite:
            raise OutputError(f"{folder} is not empty: {remedy}")
        if folder.is_symlink():
            raise OutputError(f"--overwrite: {folder} is a symbolic link (to "
                              f"{os.readlink(folder)}); give the run folder itself, "
                              "nothing was deleted")
        if not is_run_folder(folder):
            raise OutputError(f"--overwrite: {folder} is not a dolfin-rod run folder (it "
                              f"has no {MARKER} marker, which every run folder gets); "
                              "refusing to delete it")
        foreign = foreign_files(folder)
        if foreign:
            shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more"
                                               if len(foreign) > 5 else "")
            raise OutputError(f"--overwrite: {folder} holds files its run did not write "
                              f"({shown}): move them out of it first; nothing was deleted")
        shutil.rmtree(folder)
    folder.mkdir(parents=True, exist_ok=True)
    mark_run_folder(folder)


# what every run writes under these names (the README's table), for a run that ended
# before its summary.json, which lists every file written, could be written
RUN_FILES = (MARKER, "scene.toml", "scene.toml-new", "timeseries.csv", "timeseries.json",
             "summary.json", "timings.json", "histories.png", "snapshots.png",
             "spacetime.png", "animation.gif", "animation.mp4", "rod.pvd", "rod.bp")
RUN_FOLDERS = ("rod", "checkpoint")


def foreign_files(folder: Path) -> list[str]:
    """The files under a run folder that no dolfin-rod command wrote there: neither in
    its summary.json's list of every file written (with `buckle`'s and `modes`' files)
    nor of the names every run writes (RUN_FILES, RUN_FOLDERS)."""
    written = set(RUN_FILES)
    try:
        listed = json.loads((folder / "summary.json").read_text()).get("files", [])
        written |= {str(f) for f in listed} if isinstance(listed, list) else set()
    except (OSError, ValueError, AttributeError):
        pass                                   # killed before its summary: the names only
    return [f for f in files_in(folder)
            if f not in written and Path(f).parts[0] not in RUN_FOLDERS]


def new_run_folder(parent: Path, name: str) -> Path:
    """Rank 0: create <parent>/<name>-<time> (with -2, -3, ... if that exists: mkdir is
    atomic, so two runs started in the same second get different folders)."""
    problem = folder_problem(parent)
    if problem:
        raise OutputError(f"outputs.directory {problem}")
    parent.mkdir(parents=True, exist_ok=True)
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    for n in range(1, 10_000):
        folder = parent / (f"{name}-{stamp}" + (f"-{n}" if n > 1 else ""))
        try:
            folder.mkdir()
            mark_run_folder(folder)
            return folder
        except FileExistsError:
            continue
    raise OutputError(f"no free run folder name {name}-{stamp}-N in {parent}")


def files_in(folder: Path) -> list[str]:
    """Every file under folder, relative; a .bp folder (ADIOS2) counts as one file."""
    out = set()
    for path in Path(folder).rglob("*"):
        rel = path.relative_to(folder)
        bp = next((i for i, part in enumerate(rel.parts) if part.endswith(".bp")), None)
        if bp is not None:
            out.add(str(Path(*rel.parts[:bp + 1])))
        elif path.is_file():
            out.add(str(rel))
    return sorted(out)


def scene_folder(run: Path) -> str | None:
    """The folder of the files that ``run``'s scene.toml names by relative paths (a mesh
    obstacle's file, an energy module): summary.json's ``scene_folder``, the scene's
    folder when it ran (None: no summary, or that folder is gone; then the run folder)."""
    try:
        folder = json.loads((Path(run) / "summary.json").read_bytes()).get("scene_folder")
    except (OSError, ValueError, AttributeError):
        return None
    return folder if isinstance(folder, str) and Path(folder).is_dir() else None
