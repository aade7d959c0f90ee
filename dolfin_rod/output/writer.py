"""Run outputs: one folder per run, written as the run goes.

    <run>/scene.toml        the scene, copied verbatim
    <run>/timeseries.csv    one row per output time, appended and flushed every step
    <run>/timeseries.json   the same columns, written at the end (also if interrupted)
    <run>/summary.json      model and why, status, end values, impulse, versions
    <run>/timings.json      wall-clock seconds of setup, integration, output, pictures
                            (and each picture's, picture_files)
    <run>/histories.png     what the scene is about (plots.py: end torque, force-extension,
                            tip deflection, reactions, ...), energies, relative power balance
    <run>/rod.bp            ParaView (ADIOS2VTXReader) of FE models: the deformed centre
                            line with directors d1, d2, d3 (points) and u, v, u_d, v_d, n,
                            m, xi (cells); torsion: phi (points), u, u_d, m, xi (cells)
    <run>/animation.gif     3-D rod: the moving centre line coloured by outputs.color (an
                            MP4, animation.mp4, where the system's ffmpeg exists)
                            (animation.py), magnified when the motion is small
    <run>/snapshots.png     3-D rod: selected frames; torsion: spacetime.png (phi, u_d)
    <run>/checkpoint/step-N/  adios4dolfinx state.bp + meta.json after step N, for resume

Checkpoints are checkpoints.py, the run folder itself run_folders.py and the fields
along the rod field_outputs.py; this module writes the time series and the summary.

summary.json lists every file of the run folder (``files``).  The CSV has LF line ends;
a value that does not exist (the power residual of row 0) is an empty field.

Columns: the model's diagnostics (TorsionModel.diagnostics keys) plus
``total_dissipation`` = int_0^t int xi ds dt (trapezoidal rule) and ``power_residual`` =
d/dt(K + Psi + E_c) + D - P on each interval [t_{k-1}, t_k]: the difference quotient of the
stored energy plus the trapezoidal means of dissipation rate D and load power P (the
power balance of docs/corrections.md; E_c the contact energy of obstacles, rod/contact.py).  It is
O(dt^2) for smooth histories; an idealised step at t = 0 makes the first interval's value O(1) (the 0+ rates are not known to the FE model).

Only rank 0 writes files (the fields along the rod are gathered there, line_fields.py);
adios4dolfinx checkpoint writes are collective.  A file-system error on rank 0 is raised
on every rank as :class:`OutputError` (``on_root``), so no rank waits in a collective
call for one that failed.
"""

from __future__ import annotations

import csv
import io
import json
import os
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

from .checkpoints import Checkpoints
from .closing import closing_lines
from .drawing import draw_pictures
from .plots import plot_histories
from .field_outputs import FieldOutputs
from .animation import Look
from ..checks import new_column
from .run_folders import OutputError, files_in, on_root


def versions() -> dict[str, str]:
    """The versions of the stack (adios4dolfinx's from its metadata: a run without
    checkpoints does not import it)."""
    from importlib.metadata import version

    import dolfinx
    import petsc4py
    import scipy
    from petsc4py import PETSc

    from .. import __version__
    return {"dolfin_rod": __version__, "python": sys.version.split()[0],
            "dolfinx": dolfinx.__version__, "petsc4py": petsc4py.__version__,
            "petsc": ".".join(str(v) for v in PETSc.Sys.getVersion()),
            "numpy": np.__version__, "scipy": scipy.__version__,
            "adios4dolfinx": version("adios4dolfinx")}


def show_progress(enabled: bool, rank: int) -> bool:
    """A progress bar only on rank 0, on a terminal, outside CI."""
    return enabled and rank == 0 and sys.stdout.isatty() and not os.environ.get("CI")


class PowerBalance:
    """Running total dissipation and the finite-difference power-balance residual."""

    def __init__(self):
        self.previous: dict | None = None
        self.total_dissipation = 0.0

    def update(self, d: dict) -> tuple[float, float]:
        residual = float("nan")
        if self.previous is not None:
            p = self.previous
            h = d["time"] - p["time"]
            energy = lambda x: (x["free_energy"] + x["kinetic_energy"]   # noqa: E731
                                + x.get("contact_energy", 0.0))
            mean_d = 0.5 * (d["dissipation_rate"] + p["dissipation_rate"])
            self.total_dissipation += h * mean_d
            residual = ((energy(d) - energy(p)) / h + mean_d
                        - 0.5 * (d["load_power"] + p["load_power"]))
        self.previous = dict(d)
        return self.total_dissipation, residual

    def state(self) -> dict:
        return {"previous": self.previous, "total_dissipation": self.total_dissipation}

    def restore(self, state: dict) -> None:
        self.previous, self.total_dissipation = state["previous"], state["total_dissipation"]

class RunWriter:
    """Everything a run writes; rank 0 writes files, collective writes on all ranks."""

    def __init__(self, folder: Path, scene, choice, sim, comm, resume: bool = False):
        """``folder`` exists (prepare_run_folder); a resumed run rewrites scene.toml in open()."""
        self.folder, self.scene, self.choice, self.sim, self.comm = Path(folder), scene, choice, sim, comm
        self.rank = comm.rank
        self.outputs = scene["outputs"]
        self.balance = PowerBalance()
        self.rows: list[dict] = []
        self.timings = {"output": 0.0}
        self.written: tuple | None = None      # (summary, files) once finished
        if scene.text and not resume:
            on_root(comm, lambda: (self.folder / "scene.toml").write_text(scene.text),
                    f"cannot write {self.folder / 'scene.toml'}")
        self._csv = None
        self._kept: list[dict] = []
        self.columns: list[str] | None = None
        self.lines = FieldOutputs(self.folder, getattr(sim, "model", None), comm,
                                  self.outputs["fields"], self.outputs["animation"]) \
            if self.outputs["fields"] or self.outputs["animation"] else None
        self.resume = resume
        self.painter = None         # a drawing.Painter started by the run, if any
        self.checkpoints = Checkpoints(self.folder, scene, sim, comm)

    # -- time series ------------------------------------------------------------------
    def open(self, keep_until_step: int | None = None) -> None:
        """Start the CSV (keeping rows <= keep_until_step of an earlier run when resuming,
        which must all be there); the header is written with the first record, from the
        model's diagnostics."""
        if keep_until_step is not None:
            on_root(self.comm, lambda: self._keep_rows(keep_until_step),
                    f"cannot resume: {self.folder / 'timeseries.csv'}")
            if self.scene.text:       # the scene as resumed (its t_end, outputs may differ)
                on_root(self.comm, self._replace_scene_file,
                        f"cannot write {self.folder / 'scene.toml'}")

    def _replace_scene_file(self) -> None:
        """Rank 0: scene.toml replaced by the resumed scene's text (a new file, then a
        rename: a crash leaves the old or the new one)."""
        new = self.folder / "scene.toml-new"
        new.write_text(self.scene.text)
        new.replace(self.folder / "scene.toml")

    def _keep_rows(self, keep_until_step: int) -> None:
        """Rank 0: rows 0 .. keep_until_step of the earlier run (OutputError if any is
        missing: a resume never reports a complete run with a hole in its history)."""
        path = self.folder / "timeseries.csv"
        if path.exists():
            try:
                with path.open() as f:
                    reader = csv.DictReader(f)
                    # an older release's end columns under their names now (new_column)
                    self.columns = [new_column(c) for c in reader.fieldnames or []]
                    self._kept = [{new_column(k) if k is not None else k: v
                                   for k, v in r.items()}
                                  for r in reader if int(r["step"]) <= keep_until_step]
            except (csv.Error, KeyError, TypeError) as err:     # NUL bytes, no step column
                raise OutputError(f"cannot resume: {path} is damaged ({err}); nothing was "
                                  "changed") from None
        for r in self._kept:
            if None in r.values() or None in r:     # too few or too many fields
                raise OutputError(f"cannot resume: {path}: the row of step {r['step']} is "
                                  "incomplete (a half-written file?); nothing was changed")
        steps = [int(r["step"]) for r in self._kept]
        if steps != list(range(keep_until_step + 1)):
            missing = sorted(set(range(keep_until_step + 1)) - set(steps))
            what = (f"lacks the rows of steps {_ranges(missing)}" if missing
                    else "has rows out of order or repeated")
            raise OutputError(f"cannot resume: {path} {what} before the checkpoint (step "
                              f"{keep_until_step}); nothing was changed")
        for r in self._kept:
            self.rows.append({k: (int(v) if k == "step" else _csv_float(v))
                              for k, v in r.items()})
        if self.lines is not None and self.rows:
            self.lines.keep_until = self.rows[-1]["time"]

    def _start_csv(self, row: dict) -> None:
        """The CSV with its header; on resume the kept rows go into a new file that
        replaces the old one by a rename once on disk, so a crash at any moment leaves
        either the old file or the new one, never a cut history."""
        if self.columns is None:
            self.columns = list(row)
        path = self.folder / "timeseries.csv"
        target = path.with_suffix(".csv-new") if self._kept else path
        self._csv_file = target.open("w", newline="")
        start = csv.DictWriter(self._csv_file, fieldnames=self.columns,
                               extrasaction="ignore", lineterminator="\n")
        start.writeheader()
        for r in self._kept:
            start.writerow(r)
        self._csv_file.flush()
        self._line = io.StringIO()          # each later row: formatted here, one os.write
        self._csv = csv.DictWriter(self._line, fieldnames=self.columns,
                                   extrasaction="ignore", lineterminator="\n")
        if self._kept:
            os.fsync(self._csv_file.fileno())
            target.replace(path)
            _sync_folder(self.folder)
        self._csv_complete = self._csv_file.tell()      # the size of complete rows

    def record(self, step: int, t: float, diag: dict) -> dict:
        t0 = time.perf_counter()
        total, residual = self.balance.update(diag)
        row = {"step": step, "time": t, **{k: v for k, v in diag.items() if k != "time"},
               "total_dissipation": total, "power_residual": residual}
        on_root(self.comm, lambda: self._write_row(row),      # (a full disk: every rank)
                f"cannot write {self.folder / 'timeseries.csv'} after step {step - 1}")
        self.timings["output"] += time.perf_counter() - t0
        return row

    def _write_row(self, row: dict) -> None:
        """Rank 0: one row, on disk at once; a failed write (a full disk) is cut back to
        the last complete row before the OSError goes on (never a row cut in half)."""
        if self._csv is None:
            self._start_csv(row)
        self._line.seek(0)
        self._line.truncate()
        self._csv.writerow({k: (_csv_text(v) if k != "step" else v) for k, v in row.items()})
        data, fd = self._line.getvalue().encode(), self._csv_file.fileno()
        try:
            while data:
                data = data[os.write(fd, data):]
        except OSError:
            os.ftruncate(fd, self._csv_complete)
            os.lseek(fd, self._csv_complete, os.SEEK_SET)
            raise
        self._csv_complete = os.lseek(fd, 0, os.SEEK_CUR)
        self.rows.append(row)

    # -- fields along the rod: ParaView file and animation frames ------------------------
    def write_fields(self, t: float) -> None:
        """Collective: sample the fields along the rod at time t (ParaView, animation)."""
        if self.lines is None:
            return
        t0 = time.perf_counter()
        self.lines.write(t)
        self.timings["output"] += time.perf_counter() - t0

    # -- checkpoints (checkpoints.py) ---------------------------------------------------
    def checkpoint(self, step: int, t: float) -> None:
        """Collective: the state after ``step``, for ``--resume``."""
        t0 = time.perf_counter()
        if self.lines is not None:
            on_root(self.comm, self.lines.flush, f"cannot write {self.folder / 'rod.pvd'}")
        self.checkpoints.write(step, t, self.balance.state())
        self.timings["output"] += time.perf_counter() - t0

    def restore_checkpoint(self, meta: dict) -> None:
        """Collective: check ``meta`` (read_checkpoint_meta) against this run, then
        restore the model and the power balance; nothing is written."""
        self.balance.restore(self.checkpoints.restore(meta))

    # -- the end --------------------------------------------------------------------------
    def series(self) -> dict[str, list]:
        """Rank 0: the time series by column, as in timeseries.json (None where a value
        is not finite)."""
        return _finite({k: [r.get(k) for r in self.rows] for k in (self.columns or [])})

    def provisional_summary(self, summary: dict) -> None:
        """Rank 0: summary.json of the rows so far at once (a signal: mpirun may kill
        the ranks before the step ends); ``finish`` replaces it."""
        if self.rank == 0:
            files = sorted(set(files_in(self.folder)) | {"summary.json"})
            _dump(self.folder / "summary.json", _finite({**summary, "versions": versions(),
                                                         "files": files}))

    def finish(self, summary: dict, timings: dict) -> None:
        """Rank 0: the time series closed, timeseries.json, the pictures, timings.json and
        summary.json.  Ctrl-C while the pictures are drawn (every step is done) stops the
        drawing only: the picture being drawn is removed and the summary records
        ``"pictures": "interrupted"`` with the ones missing."""
        if self.rank != 0:
            return
        if self._csv is not None:
            self._csv_file.close()
        try:
            self._finish(summary, timings)
        except OSError as err:                 # a full disk: the rows stay complete
            print(f"warning: cannot write the rest of {self.folder}: "
                  f"{err.strerror or err}", file=sys.stderr, flush=True)

    def _finish(self, summary: dict, timings: dict) -> None:
        if self.lines is not None:
            self.lines.close()
        _dump(self.folder / "timeseries.json", self.series())
        t0 = time.perf_counter()
        missing = self._draw(summary.get("title", ""))
        self.timings["pictures"] = time.perf_counter() - t0
        summary["pictures"] = "interrupted" if missing else "complete"
        if missing:
            summary["pictures_missing"] = missing
        _dump(self.folder / "timings.json", {**timings, **self.timings})
        files = sorted(set(files_in(self.folder)) | {"summary.json"})
        _dump(self.folder / "summary.json", _finite({**summary, "versions": versions(),
                                                     "files": files}))
        self.written = (summary, sorted({f.split("/")[0] for f in files
                                         if not f.startswith(".")}))

    def closing_lines(self, wall: float) -> list[str]:
        """Rank 0 after finish: the closing summary (closing.py); [] on other ranks."""
        if self.rank != 0 or self.written is None:
            return []
        summary, files = self.written
        return closing_lines(summary, self.rows, self.scene, wall, files)

    def _draw(self, title: str) -> list[str]:
        """Rank 0: draw the pictures; the names of those not drawn (Ctrl-C)."""
        pictures = []
        if self.outputs["plots"] and len(self.rows) > 1:
            pictures.append(("histories.png", partial(
                plot_histories, self.rows, self.folder / "histories.png", self.scene, title)))
        if self.lines is not None:
            pictures += self.lines.pictures(title, Look.of(self.scene))
        self.timings["picture_files"], missing = draw_pictures(
            pictures, self.folder, side_by_side=self.comm.size == 1, painter=self.painter)
        return missing



def _ranges(numbers: list[int]) -> str:
    """[3, 4, 5, 9] -> '3-5, 9' (at most five ranges shown)."""
    spans: list[list[int]] = []
    for n in numbers:
        if spans and n == spans[-1][1] + 1:
            spans[-1][1] = n
        else:
            spans.append([n, n])
    text = [f"{a}-{b}" if b > a else f"{a}" for a, b in spans[:5]]
    return ", ".join(text) + (", ..." if len(spans) > 5 else "")


def _sync_folder(folder: Path) -> None:
    """fsync a folder, so that a rename in it survives a power cut."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _csv_text(value) -> str:
    """A CSV field: repr of a finite float (round trip exact), empty if not a number."""
    x = float(value)
    return repr(x) if np.isfinite(x) else ""


def _csv_float(text: str) -> float:
    return float(text) if text != "" else float("nan")


def _finite(obj):
    """NaN/inf -> None so that the JSON is standard."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def _dump(path: Path, data) -> None:
    tmp = path.with_suffix(".json-new")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)
