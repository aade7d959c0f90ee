"""Run outputs: one folder per run, written as the run goes.

    <run>/scene.toml        the scene, copied verbatim
    <run>/timeseries.csv    one row per output time, appended and flushed every step
    <run>/timeseries.json   the same columns, written at the end (also if interrupted)
    <run>/summary.json      model and why, status, end values, impulse, versions
    <run>/timings.json      wall-clock seconds of setup, integration, output
    <run>/histories.png     end torsion, end rotation, natural twist, energies, balance
    <run>/rod.bp            ParaView (ADIOS2VTXReader) of FE models: the deformed centre
                            line with directors d1, d2, d3 (points) and u, v, u_d, v_d, n,
                            m, xi (cells); torsion: phi (points), u, u_d, m, xi (cells)
    <run>/animation.gif     3-D rod: the moving centre line, coloured by |u_d - u_ref|
    <run>/snapshots.png     3-D rod: selected frames; torsion: spacetime.png (phi, u_d)
    <run>/checkpoint/step-N/  adios4dolfinx state.bp + meta.json after step N, for resume

A checkpoint is written into ``step-N.partial`` and renamed to ``step-N`` when complete
(one atomic rename), then older ones are removed: a crash at any moment leaves the last
complete checkpoint, never a state of one step with the metadata of another.  Resuming
verifies that the scene's physics (``Scene.physics``), the model and the number of
degrees of freedom are those of the checkpoint, before anything is written.

summary.json lists every file of the run folder (``files``).  The CSV has LF line ends;
a value that does not exist (the power residual of row 0) is an empty field.

Columns: the model's diagnostics (TorsionModel.diagnostics keys) plus
``total_dissipation`` = int_0^t int xi ds dt (trapezoidal rule) and ``power_residual`` =
d/dt(K + Psi) + D - P on each interval [t_{k-1}, t_k]: the difference quotient of the
stored energy plus the trapezoidal means of dissipation rate D and load power P (the
power balance of ERRATA.md).  It is O(dt^2) for smooth histories; an idealised step at
t = 0 makes the first interval's value O(1) (the 0+ rates are not known to the FE model).

Only rank 0 writes files (the fields along the rod are gathered there, line_fields.py);
adios4dolfinx checkpoint writes are collective.  A file-system error on rank 0 is raised
on every rank as :class:`OutputError` (``on_root``), so no rank waits in a collective
call for one that failed.
"""

from __future__ import annotations

import csv
import datetime
import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

COLUMNS = ["step", "time", "<the model's diagnostics>", "total_dissipation",
           "power_residual"]   # torsion models: end_torsion, end_rotation, ... (see models)


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
    from .scenes.schema import path_problem
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


RUN_FILES = ("scene.toml", "timeseries.csv", "summary.json", "checkpoint")


def prepare_run_folder(folder: Path, resume: bool, overwrite: bool) -> None:
    """Rank 0: make ``folder`` ready; a non-empty folder is reused only to resume, or
    replaced with ``overwrite`` if it is a run folder (never any other folder)."""
    problem = folder_problem(folder)
    if problem:
        raise OutputError(f"--out {problem}")
    if resume:
        if not folder.is_dir():
            raise OutputError(f"--resume: {folder} is not a run folder")
        return
    if folder.is_dir() and any(folder.iterdir()):
        if not overwrite:
            raise OutputError(f"{folder} is not empty: pass --resume to continue its run or "
                              "--overwrite to replace it")
        if not any((folder / name).exists() for name in RUN_FILES):
            raise OutputError(f"--overwrite: {folder} is not a dolfin-rod run folder (none of "
                              f"{', '.join(RUN_FILES)}); refusing to delete it")
        shutil.rmtree(folder)
    folder.mkdir(parents=True, exist_ok=True)


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
            return folder
        except FileExistsError:
            continue
    raise OutputError(f"no free run folder name {name}-{stamp}-N in {parent}")


def versions() -> dict[str, str]:
    import adios4dolfinx
    import dolfinx
    import petsc4py
    import scipy
    from petsc4py import PETSc

    from . import __version__
    return {"dolfin_rod": __version__, "python": sys.version.split()[0],
            "dolfinx": dolfinx.__version__, "petsc4py": petsc4py.__version__,
            "petsc": ".".join(str(v) for v in PETSc.Sys.getVersion()),
            "numpy": np.__version__, "scipy": scipy.__version__,
            "adios4dolfinx": adios4dolfinx.__version__}


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
            energy = lambda x: x["free_energy"] + x["kinetic_energy"]   # noqa: E731
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
        """``folder`` exists (prepare_run_folder); a resumed run keeps its scene.toml."""
        self.folder, self.scene, self.choice, self.sim, self.comm = Path(folder), scene, choice, sim, comm
        self.rank = comm.rank
        self.outputs = scene["outputs"]
        self.balance = PowerBalance()
        self.rows: list[dict] = []
        self.timings = {"output": 0.0}
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

    # -- time series ------------------------------------------------------------------
    def open(self, keep_until_step: int | None = None) -> None:
        """Start the CSV (keeping rows <= keep_until_step of an earlier run when resuming);
        the header is written with the first record, from the model's diagnostics."""
        if self.rank != 0 or keep_until_step is None:
            return
        path = self.folder / "timeseries.csv"
        if path.exists():
            with path.open() as f:
                reader = csv.DictReader(f)
                self.columns = list(reader.fieldnames or [])
                self._kept = [r for r in reader if int(r["step"]) <= keep_until_step]
        for r in self._kept:
            self.rows.append({k: (int(v) if k == "step" else _csv_float(v))
                              for k, v in r.items()})
        if self.lines is not None and self.rows:
            self.lines.keep_until = self.rows[-1]["time"]

    def _start_csv(self, row: dict) -> None:
        if self.columns is None:
            self.columns = list(row)
        self._csv_file = (self.folder / "timeseries.csv").open("w", newline="")
        self._csv = csv.DictWriter(self._csv_file, fieldnames=self.columns,
                                   extrasaction="ignore", lineterminator="\n")
        self._csv.writeheader()
        for r in self._kept:
            self._csv.writerow(r)

    def record(self, step: int, t: float, diag: dict) -> dict:
        t0 = time.perf_counter()
        total, residual = self.balance.update(diag)
        row = {"step": step, "time": t, **{k: v for k, v in diag.items() if k != "time"},
               "total_dissipation": total, "power_residual": residual}
        if self.rank == 0:
            if self._csv is None:
                self._start_csv(row)
            self.rows.append(row)
            self._csv.writerow({k: (_csv_text(v) if k != "step" else v)
                                for k, v in row.items()})
            self._csv_file.flush()
        self.timings["output"] += time.perf_counter() - t0
        return row

    # -- fields along the rod: ParaView file and animation frames ------------------------
    def write_fields(self, t: float) -> None:
        """Collective: sample the fields along the rod at time t (ParaView, animation)."""
        if self.lines is None:
            return
        t0 = time.perf_counter()
        self.lines.write(t)
        self.timings["output"] += time.perf_counter() - t0

    # -- checkpoints ------------------------------------------------------------------------
    def _named_functions(self) -> tuple[dict, dict]:
        """The model's checkpointed functions by name, and the rest of its state."""
        state = self.sim.state()
        functions = state.pop("functions", {})
        named = {f"field_{i}": f for i, f in enumerate(self.sim.fields)} | functions
        return named, state

    def fingerprint(self) -> dict:
        """What a checkpoint must match: the scene's physics, the model, the dofs."""
        named, _ = self._named_functions()
        dofs = {name: f.function_space.dofmap.index_map.size_global
                * f.function_space.dofmap.index_map_bs for name, f in named.items()}
        data = {"scene": self.scene.physics(), "model": self.sim.name, "dofs": dofs}
        data = json.loads(json.dumps(data))          # tuples -> lists, as read back
        digest = hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()
        return {**data, "sha256": digest}

    def checkpoint(self, step: int, t: float) -> None:
        """Collective: the state after ``step`` so that ``resume`` continues exactly,
        written to step-N.partial and made visible by one rename (module docstring)."""
        t0 = time.perf_counter()
        root = self.folder / "checkpoint"
        partial, final = root / f"step-{step:09d}.partial", root / f"step-{step:09d}"

        def make_partial():
            root.mkdir(exist_ok=True)
            shutil.rmtree(partial, ignore_errors=True)
            partial.mkdir()
        on_root(self.comm, make_partial, f"cannot write a checkpoint in {root}")
        named, state = self._named_functions()
        real: dict[str, list[float]] = {}
        import adios4dolfinx
        for name, f in named.items():
            if _is_real(f):   # adios4dolfinx cannot read real spaces back in parallel
                f.x.scatter_forward()
                real[name] = f.x.array.tolist()
            else:
                adios4dolfinx.write_function_on_input_mesh(partial / "state.bp", f, time=0.0,
                                                           name=name)
        meta = {"step": step, "time": t, "model": self.sim.name, "sim": state, "real": real,
                "balance": self.balance.state(), "fingerprint": self.fingerprint()}

        def publish():
            write_checkpoint_meta(partial, meta)
            partial.rename(final)
            for old in root.iterdir():
                if old != final:
                    shutil.rmtree(old, ignore_errors=True)
        self.comm.barrier()                            # every rank's state.bp is written
        on_root(self.comm, publish, f"cannot write a checkpoint in {root}")
        self.timings["output"] += time.perf_counter() - t0

    def restore_checkpoint(self, meta: dict) -> None:
        """Collective: check the model and dofs against ``meta`` (read_checkpoint_meta),
        then restore the model and the power balance; nothing is written."""
        mine = self.fingerprint()
        if meta["fingerprint"]["sha256"] != mine["sha256"]:
            raise OutputError(f"cannot resume from {meta['folder']}: "
                              + fingerprint_difference(meta["fingerprint"], mine))
        import adios4dolfinx
        named, _ = self._named_functions()
        for name, f in named.items():
            if name in meta["real"]:
                f.x.array[:] = meta["real"][name][0]   # one global value (owned + ghost)
            else:
                adios4dolfinx.read_function(Path(meta["folder"]) / "state.bp", f, time=0.0,
                                            name=name)
            f.x.scatter_forward()
        self.sim.restore(meta["sim"])
        self.balance.restore(meta["balance"])

    # -- the end --------------------------------------------------------------------------
    def finish(self, summary: dict, timings: dict) -> None:
        if self.rank != 0:
            return
        if self._csv is not None:
            self._csv_file.close()
        series = {k: [r.get(k) for r in self.rows] for k in (self.columns or [])}
        _dump(self.folder / "timeseries.json", _finite(series))
        if self.outputs["plots"] and len(self.rows) > 1:
            plot_histories(self.rows, self.folder / "histories.png", summary.get("title", ""))
        if self.lines is not None:
            t0 = time.perf_counter()
            self.lines.finish(summary.get("title", ""))
            self.timings["pictures"] = time.perf_counter() - t0
        _dump(self.folder / "timings.json", {**timings, **self.timings})
        files = sorted(set(files_in(self.folder)) | {"summary.json"})
        _dump(self.folder / "summary.json", _finite({**summary, "versions": versions(),
                                                     "files": files}))


class FieldOutputs:
    """The fields along the rod of an FE model (RodModel or TorsionModel, anything with
    ``observables()``): ``rod.bp`` (ParaView) and the pictures of animation.py, from
    LineSampler samples gathered on rank 0.  ``model = None`` (ODE runs): nothing.
    Usable from scripts:

        out = FieldOutputs(folder, model, comm)     # collective
        ... out.write(t) after each step (collective) ...
        out.finish("title")                         # rank 0: close rod.bp, draw
    """

    POINT = ("centre_line", "d1", "d2", "d3", "phi")    # vertex values; others per cell

    def __init__(self, folder: Path, model, comm, fields: bool = True, animation: bool = True):
        self.folder, self.comm = Path(folder), comm
        self.outputs = {"fields": fields, "animation": animation}
        self.sampler = None
        if model is not None and hasattr(model, "observables"):
            from .line_fields import LineSampler
            self.sampler = LineSampler(model.mesh, model.observables(), self.POINT)
        self.keep_until: float | None = None     # resume: steps of rod.bp kept up to here
        self.vtx = None
        self.frames = None

    def write(self, t: float) -> None:
        """Collective: one sample; rank 0 writes it to rod.bp and keeps it as a frame."""
        if self.sampler is None:
            return
        sample = self.sampler.sample()
        if sample is None:
            return
        if self.frames is None:
            self._start()
        if self.outputs["fields"]:
            self.vtx.write(t, _geometry(sample), *self._data(sample))
        self.frames.add(t, sample)

    def _start(self) -> None:
        from .animation import FrameStore
        from .vtx import LineVTX
        self.frames = FrameStore()
        if self.outputs["fields"]:
            self.vtx = LineVTX(self.folder / "rod.bp", keep_until=self.keep_until)
            for step in self.vtx.kept:   # resume: earlier frames come back from rod.bp
                self.frames.add(step["time"], _sample_from_vtx(step))

    @staticmethod
    def _data(sample) -> tuple[dict, dict]:
        """Point data (arc length s first) and cell data; the centre line is the geometry."""
        point = {"s": sample.s_nodes, **{k: v for k, v in sample.point.items()
                                         if k != "centre_line"}}
        return point, dict(sample.cell)

    def finish(self, title: str) -> None:
        """Rank 0: close rod.bp; the animation and pictures (outputs.animation)."""
        from . import animation
        if self.comm.rank != 0:
            return
        if self.vtx is not None:
            self.vtx.close()
        frames = self.frames.all() if self.frames is not None else []
        if not (self.outputs["animation"] and len(frames) > 1):
            return
        if "centre_line" in frames[0][1].point:
            animation.rod_animation(frames, self.folder / "animation.gif", title)
            animation.rod_snapshots(frames, self.folder / "snapshots.png", title)
        else:
            animation.torsion_spacetime(frames, self.folder / "spacetime.png", title)


def _geometry(sample) -> np.ndarray:
    """The points of rod.bp: the centre line (3-D rod) or s e_3 (torsion, dimensionless)."""
    if "centre_line" in sample.point:
        return sample.point["centre_line"]
    s = sample.s_nodes
    return np.column_stack([np.zeros_like(s), np.zeros_like(s), s])


def _sample_from_vtx(step: dict):
    """A LineSample from a step of rod.bp (resume: the frames before the checkpoint)."""
    from .line_fields import LineSample
    point = dict(step["point"])
    s_nodes = point.pop("s")
    if "phi" not in point:
        point["centre_line"] = step["points"]
    return LineSample(s_nodes, 0.5 * (s_nodes[1:] + s_nodes[:-1]), point, dict(step["cell"]))


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


def _csv_text(value) -> str:
    """A CSV field: repr of a finite float (round trip exact), empty if not a number."""
    x = float(value)
    return repr(x) if np.isfinite(x) else ""


def _csv_float(text: str) -> float:
    return float(text) if text != "" else float("nan")


def write_checkpoint_meta(folder: Path, meta: dict) -> None:
    """Rank 0: meta.json of a checkpoint (its own function so that tests can make a
    crash happen between state.bp and meta.json)."""
    (folder / "meta.json").write_text(json.dumps(meta))


def read_checkpoint_meta(run: Path, comm, scene) -> dict:
    """Collective: the newest complete checkpoint of ``run`` (``meta["folder"]``),
    refused with OutputError unless it was written by a scene with the same physics
    (Scene.physics) and ends before time.t_end.  Reads only."""
    def newest():
        root = run / "checkpoint"
        done = sorted(p for p in root.glob("step-*") if p.suffix != ".partial"
                      and (p / "meta.json").is_file()) if root.is_dir() else []
        if not done:
            raise OutputError(f"--resume: no complete checkpoint in {root} (the scene "
                              "needs outputs.checkpoint_every > 0)")
        return {**json.loads((done[-1] / "meta.json").read_text()), "folder": str(done[-1])}
    meta = on_root(comm, newest, f"--resume: cannot read the checkpoint of {run}")
    theirs = meta.get("fingerprint", {}).get("scene")
    mine = json.loads(json.dumps(scene.physics()))
    if theirs != mine:
        raise OutputError(f"cannot resume from {meta['folder']}: "
                          + fingerprint_difference({"scene": theirs}, {"scene": mine}))
    if meta["time"] >= scene["time"]["t_end"]:
        raise OutputError(f"cannot resume from {meta['folder']}: it is at t = "
                          f"{meta['time']:g}, not before time.t_end = "
                          f"{scene['time']['t_end']:g}")
    return meta


def fingerprint_difference(theirs: dict, mine: dict) -> str:
    """The first entries where a checkpoint's fingerprint and this run's differ."""
    diffs = []

    def walk(a, b, path):
        if isinstance(a, dict) and isinstance(b, dict):
            first = ("model", "scene")                 # the likely cause before its dofs
            for k in sorted(set(a) | set(b), key=lambda k: (k not in first, k)):
                walk(a.get(k), b.get(k), f"{path}.{k}" if path else k)
        elif a != b:
            diffs.append(f"{path}: {a!r} in the checkpoint, {b!r} now")
    walk(theirs, mine, "")
    shown = "; ".join(d.removeprefix("scene.") for d in diffs[:4])
    return (f"it was written by a different run ({shown or 'unreadable fingerprint'}"
            f"{'; ...' if len(diffs) > 4 else ''}); nothing was changed")


def _is_real(f) -> bool:
    """A scifem real space (one global unknown, e.g. the uniform natural twist)."""
    V = f.function_space
    return (V.dofmap.index_map.size_global * V.dofmap.index_map_bs == 1
            and V.mesh.topology.index_map(V.mesh.topology.dim).size_global > 1)


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


def plot_histories(rows: list[dict], path: Path, title: str = "") -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = np.array([r["time"] for r in rows])
    col = lambda k: np.array([r[k] for r in rows], dtype=float)   # noqa: E731
    fig, ax = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    if "end_torsion" in rows[0]:       # torsion models
        ax[0, 0].plot(t, col("end_torsion")); ax[0, 0].set_ylabel("end torsion m")
        ax[0, 1].plot(t, col("end_rotation"), label="end rotation phi(1)")
        ax[0, 1].plot(t, col("mean_natural_twist"), label="mean natural twist")
    else:                              # 3-D rod
        for c in "xyz":
            ax[0, 0].plot(t, col(f"tip_position_{c}"), label=f"tip {c}")
        ax[0, 0].legend()
        ax[0, 1].plot(t, col("tip_rotation_angle"), label="tip rotation angle")
    ax[0, 1].legend()
    ax[1, 0].plot(t, col("free_energy") + col("kinetic_energy"), label="K + Psi")
    ax[1, 0].plot(t, col("total_dissipation"), label="int D dt")
    ax[1, 0].legend(); ax[1, 0].set_xlabel("t")
    ax[1, 1].semilogy(t[1:], np.abs(col("power_residual")[1:]) + 1e-300)
    ax[1, 1].set_ylabel("|d/dt(K+Psi) + D - P|"); ax[1, 1].set_xlabel("t")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
