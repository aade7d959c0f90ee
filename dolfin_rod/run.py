"""A run of a scene, in one room: ``dolfin_rod.run(scene, overrides)`` reads and checks
the scene, chooses its model, builds it, steps it over the output times, writes the run
folder and returns the results.  ``dolfin-rod run`` (cli.py), the demos and a notebook
call it alike; ``march`` is the one loop over the output times, which the fit
(fit/least_squares.py) shares.

    result = dolfin_rod.run("scenes/torsion_creep.toml", {"time.dt": 0.005}, quiet=True)
    result.status, result.folder, result.series["end_rotation"]

The way through the package: scenes/ (load_scene: schema, values, rules; select_model)
-> scenes/builders.py (the model of rod/ or torsion/ and its integrator,
integrators/choice.py) -> ``march`` (``Simulation.advance`` per output interval, or
PETSc TS over the whole run) -> output/ (RunWriter: time series, fields, checkpoints;
divergence.py stops a run that diverges).

``out``: the results folder (default a new <outputs.directory>/<name>-<time>); if it is
not empty, ``resume`` continues its run from its last checkpoint (verified against this
scene) and ``overwrite`` replaces it.  ``stop_after``: stop after that many steps (as an
interrupted run would), keeping the outputs and the last checkpoint.  A bad scene raises
SceneError, an unusable folder or checkpoint OutputError, both before anything is
written; a run that fails or diverges returns with status "failed" (what was computed is
kept).  Under MPI every rank returns the same result; only rank 0 prints and writes.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .mpi import agree, print_on_root
from .scenes.scene import Scene, SceneError

__all__ = ["run", "run_scene", "analyse", "RunResult", "march", "choose_model",
           "scene_warnings"]


@dataclass
class RunResult:
    """What a run returns (the same on every rank): ``summary`` as in summary.json,
    ``series`` the time series by column as in timeseries.json, the run ``folder``."""

    summary: dict
    series: dict[str, list]
    folder: Path

    @property
    def status(self) -> str:
        """"completed", "completed (unstable equilibrium)", "stopped" (stop_after),
    "interrupted" or "failed"."""
        return self.summary["status"]

    def plot(self, quantities: list[str] | None = None, colour: str = "auto") -> list[Path]:
        """Draw the run's pictures again (output/redraw.py): histories.png of the scene's
        panels or of ``quantities`` (panels or CSV columns), the 3-D pictures coloured by
        ``colour``; returns the files written (rank 0; [] on other ranks)."""
        from mpi4py import MPI
        if MPI.COMM_WORLD.rank != 0:
            return []
        from .output.redraw import redraw
        return redraw(self.folder, quantities, colour)

    def dataframe(self):
        """The time series as a pandas DataFrame, one column per column of ``series``
        (timeseries.csv), in its order; an ImportError that says how to install pandas
        when it is missing (``series`` holds the same columns as lists)."""
        try:
            import pandas
        except ImportError as err:
            raise ImportError(
                "RunResult.dataframe() needs pandas, which is not installed: install it "
                "with 'pip install pandas' (or 'apt install python3-pandas'); "
                "result.series holds the same columns as lists") from err
        return pandas.DataFrame(self.series)


def run(scene: Scene | str | Path, overrides: dict[str, Any] | None = None, *,
        out: Path | str | None = None, comm=None, resume: bool = False,
        overwrite: bool = False, quiet: bool = False,
        stop_after: int | None = None) -> RunResult:
    """Run a scene (a validated Scene or a TOML file) with ``overrides`` {"table.key":
    value} (load_scene); see the module's docstring."""
    from mpi4py import MPI
    comm = comm or MPI.COMM_WORLD
    given = scene
    scene = agree(comm, lambda: _scene(given, overrides), (SceneError,))
    from .fem import compile_notice
    with compile_notice.listening(None if quiet or comm.rank != 0 else sys.stdout):
        return _run(scene, None if out is None else Path(out), comm, resume, overwrite,
                    quiet, stop_after)


def analyse(scene: Scene | str | Path, kind: str, overrides: dict[str, Any] | None = None,
            *, count: int | None = None, out: Path | str | None = None, comm=None,
            overwrite: bool = False, quiet: bool = False) -> RunResult:
    """Run a scene, then analyse its end state: ``kind`` "buckle" (the critical load
    factors and buckling modes about it, analysis/buckling.py: a quasi-static rod) or
    "modes" (natural frequencies and vibration modes, analysis/vibration.py: a rod with
    mass); ``count`` modes (default 4 and 6).  The run folder holds the run's files and
    <kind>.json, <kind>.bp (output/modes.py); ``summary[kind]`` the table.  A scene the
    analysis cannot take raises SceneError naming the key, before any work."""
    from mpi4py import MPI

    from .scenes.rules import analysis_problem, rate_force_key
    from .scenes.selection import at_rest
    if kind not in ANALYSES:
        raise ValueError(f"kind: one of {', '.join(ANALYSES)}, got {kind!r}")
    count = ANALYSES[kind] if count is None else count
    if int(count) != count or count < 1:
        raise ValueError(f"count: a positive integer, got {count!r}")
    comm = comm or MPI.COMM_WORLD
    given = scene
    scene = agree(comm, lambda: _scene(given, overrides), (SceneError,))
    rest = agree(comm, lambda: at_rest(scene) if kind == "buckle" else None, (SceneError,))
    note = None if rest is None else rest[1]
    if rest is not None:
        scene = agree(comm, lambda: _scene(scene, rest[0]), (SceneError,))
    agree(comm, lambda: analysis_problem(scene, kind), (SceneError,))
    damping = rate_force_key(scene) if kind == "modes" else None
    if damping is not None:
        note = (f"undamped: the modes leave out the rod's {damping} (K phi = omega^2 M "
                "phi: the natural frequencies of the rod without it; docs/stability.md)")
    if note is not None and not quiet:
        print_on_root(comm, f"{kind}: {note}")
    return _run(scene, None if out is None else Path(out), comm, False, overwrite, quiet,
                None, _modes_of(scene, kind, int(count), comm, quiet, note))


ANALYSES = {"buckle": 4, "modes": 6}        # the analyses of an end state, default counts


class AnalysisError(RuntimeError):
    """The analysis of a run's end state found fewer modes than asked (the run's files
    are kept: status "failed")."""


def _modes_of(scene: Scene, kind: str, count: int, comm, quiet: bool, note: str | None):
    """The analysis of a run's end state: (sim, t, folder) -> its summary entry (with
    ``note``, how the scene was changed for the analysis: scenes.selection.at_rest)."""
    def analysis(sim, t: float, folder: Path) -> dict:
        from .analysis.eigen import EigenError
        try:
            return end_state_modes(sim, t, folder)
        except EigenError as err:
            raise AnalysisError(
                f"{kind} at t = {t:g}: {err} (--count {count}: a rod has at most one mode "
                "per unknown its supports leave free; ask for fewer)") from None

    def end_state_modes(sim, t: float, folder: Path) -> dict:
        from .output.modes import table, write_modes
        model = sim.model
        if kind == "buckle":
            from .analysis.buckling import buckling_modes
            try:
                found = buckling_modes(model, t, count)
            except ValueError as err:               # e.g. loads constant at t
                raise scene.error("loads", str(err)) from None
            rows = [{"mode": k + 1, "load_factor": float(f), "critical_time": float(c),
                     "residual": float(r)} for k, (f, c, r) in enumerate(
                         zip(found.load_factors, found.times, found.residuals))]
        else:
            from .analysis.vibration import vibration_modes
            found = vibration_modes(model, t, count)
            rows = [{"mode": k + 1, "omega": float(w), "frequency": float(f),
                     **({"growth_rate": float(g)} if found.flutter else {}),
                     "residual": float(r)} for k, (w, f, g, r) in enumerate(
                         zip(found.omega, found.frequencies, found.growth_rates,
                             found.residuals))]
        files = write_modes(folder, model, kind, rows, found.shapes, comm)
        if not quiet:
            print_on_root(comm, f"{kind} at t = {t:g}:\n{table(rows)}")
        entry = {"t": t, "modes": rows, "files": files}
        return {kind: entry if note is None else {**entry, "note": note}}
    return analysis


def run_scene(scene: Scene | str | Path, out: Path | str | None = None, comm=None,
              resume: bool = False, stop_after: int | None = None, quiet: bool = False,
              overwrite: bool = False) -> dict:
    """``run(scene, ...).summary``: the summary of a run of a scene (validated, or the
    path of a scene file)."""
    return run(scene, out=out, comm=comm, resume=resume, overwrite=overwrite, quiet=quiet,
               stop_after=stop_after).summary


def _scene(scene: Scene | str | Path, overrides: dict[str, Any] | None) -> Scene:
    from .scenes import load_scene, parse_scene
    if not isinstance(scene, Scene):
        return load_scene(scene, overrides)
    if not overrides:
        return scene
    return parse_scene(scene.text, scene.source, scene.name, overrides)


def choose_model(scene: Scene, ranks: int):
    """The scene's model (select_model), refused with a SceneError naming
    geometry.n_cells if an FE model would leave a rank too few cells."""
    from .checks import check_n_cells
    from .scenes import select_model
    choice = select_model(scene)
    if choice.model != "ode":
        try:
            check_n_cells(scene["geometry"]["n_cells"], ranks)
        except ValueError as err:
            raise scene.error("geometry.n_cells", str(err)) from None
    return choice


def scene_warnings(scene: Scene, comm) -> None:
    """Warn (stderr, rank 0) before a run that explicit Euler would make diverge, of a
    section not small against the rod's length, of a Newton time.atol not small against
    the forces, of a load that starts only after the run, of a ring whose stress-free
    curvature is not its start's (scenes/run_warnings.py)."""
    from .scenes.run_warnings import (explicit_stability_warning, late_history_warnings,
                                      ring_curvature_warning, slenderness_warnings,
                                      tolerance_warning)
    for warning in [explicit_stability_warning(scene), *slenderness_warnings(scene),
                    tolerance_warning(scene), *late_history_warnings(scene),
                    ring_curvature_warning(scene)]:
        if warning:
            print_on_root(comm, f"warning: {warning}", file=sys.stderr)


def draws_alone(scene: Scene, comm) -> bool:
    """Whether a run draws pictures in one process of one rank (a drawing.Painter may
    draw them: no MPI peer shares the process's memory)."""
    outputs = scene["outputs"]
    return comm.size == 1 and bool(outputs["plots"] or outputs["animation"])


def import_finite_elements(checkpoints: bool) -> None:
    """Import DOLFINx and its stack (with adios4dolfinx if the run writes or reads
    ``checkpoints``: 0.1 s of a run's start otherwise) with Ctrl-C and SIGTERM recorded,
    not raised, until the imports are complete: an interrupt raised inside an import
    leaves a package half imported (DOLFINx's module initialisation then aborts, or its
    dependency check fails); recorded, it ends the start-up right after
    (KeyboardInterrupt: exit 130).  Numba is hidden meanwhile: DOLFINx then skips its
    optional numba helpers, whose import is a third of its own (docs/performance.md); it
    stays importable after."""
    import signal
    caught: list[int] = []
    names = ("SIGINT", "SIGTERM")
    previous = {name: signal.signal(getattr(signal, name), lambda signum, _: caught.append(signum))
                for name in names}
    numba_absent = "numba" not in sys.modules
    if numba_absent:   # DOLFINx's numba helpers (dolfinx.utils), unused here: 0.4-0.5 s
        sys.modules["numba"] = None
    try:
        if checkpoints:
            import adios4dolfinx  # noqa: F401
        import basix.ufl  # noqa: F401
        import dolfinx.fem.petsc  # noqa: F401
        import ufl  # noqa: F401
    finally:
        if numba_absent and sys.modules.get("numba", 0) is None:
            del sys.modules["numba"]           # importable again, e.g. by PyElastica
        for name, handler in previous.items():
            signal.signal(getattr(signal, name), handler)
    if caught:
        raise KeyboardInterrupt


def _run(scene: Scene, out: Path | None, comm, resume: bool, overwrite: bool, quiet: bool,
         stop_after: int | None, analysis: Callable | None = None) -> RunResult:
    from .output.checkpoints import read_checkpoint_meta
    from .output.from_run import check_out, previous_state, start_from
    from .output.writer import RunWriter
    from .scenes import build
    clock = {"start": time.perf_counter()}
    choice = agree(comm, lambda: choose_model(scene, comm.size), (SceneError,))
    if (resume or stop_after is not None) and scene["time"]["integrator"] == "ts":
        raise scene.error("time.integrator", "resume/stop_after need integrator = \"stepper\"")
    if (resume or stop_after is not None) and scene["continuation"]["method"] != "load_steps":
        raise scene.error("continuation.method", "resume/stop_after need method = "
                                                 "\"load_steps\"")
    meta = read_checkpoint_meta(out, comm, scene) if resume else None
    previous = previous_state(scene, choice.model, comm) if meta is None else None
    check_out(scene, previous, out)
    made = not resume and (out is None or not os.path.exists(out))   # (False on errors)
    folder = _run_folder(scene, out, comm, resume, overwrite)
    if not quiet:
        print_on_root(comm, f"model: {choice.model} ({choice.reason})")
    scene_warnings(scene, comm)
    from .output.drawing import painting
    from .output.notices import listed, noticed
    with painting(draws_alone(scene, comm)) as painter, noticed(comm) as seen:
        try:
            outs = scene["outputs"]
            import_finite_elements(resume or previous is not None or bool(
                outs["checkpoint_every"] or outs["final_checkpoint"]))
            sim = build(scene, choice.model, comm)
            impulse = sim.start()
            continued = None if previous is None else start_from(sim, previous, scene)
            if previous is not None:     # the impulse of a step at t = 0 from rest: not
                impulse = None           # this start's (a saved state, not rest)
                if previous.unfinished:
                    warnings.warn(previous.unfinished, stacklevel=1)
        except BaseException:
            if made and comm.rank == 0:          # nothing half-written: no empty folder
                _remove_if_empty(folder)
            raise
        clock["setup"] = time.perf_counter() - clock["start"]
        writer = RunWriter(folder, scene, choice, sim, comm, resume=resume)
        started = previous.summary(continued) if previous is not None else (
            meta.get("from_run") if meta is not None else None)   # a resume: as it began
        writer.checkpoints.started_from = started
        writer.painter = painter
        if meta is not None:
            writer.restore_checkpoint(meta)
            writer.open(keep_until_step=meta["step"])
            if not quiet:
                print_on_root(comm, f"resumed at step {meta['step']}, t = {meta['time']:g}")
        else:
            writer.open()
            if previous is not None and not quiet:
                print_on_root(comm, f"started from {previous.run} at its t = "
                                    f"{previous.meta['time']:g} (step {previous.meta['step']})"
                                    + (", continuing its time integration" if continued else ""))
        t_run = time.perf_counter()
        def provisional(t: float) -> None:     # at a signal: mpirun may end the ranks soon
            writer.provisional_summary(_summary(
                scene, choice, sim, writer, comm, "interrupted", f"interrupted at t = {t:g} "
                "(a signal; this summary was written at once, as mpirun ends its ranks "
                "within half a second of a Ctrl-C or SIGTERM sent to it)", t, impulse, seen))
        status, message, t, fault = _integrate(scene, sim, writer, comm, 0 if meta is None
                                               else meta["step"], stop_after, quiet,
                                               provisional)
        status, message = _unstable_end(scene, sim, status, message)
        clock["integration"] = time.perf_counter() - t_run
        summary = _summary(scene, choice, sim, writer, comm, status, message, t, impulse,
                           seen)
        if started is not None:
            summary["from_run"] = started
        if analysis is not None and status.startswith("completed"):
            t_analysis = time.perf_counter()
            try:
                summary.update(analysis(sim, t, folder))
                summary["warnings"] = listed(seen)      # with the analysis's
            except AnalysisError as err:    # the run's files kept and closed, its summary
                status, message = "failed", str(err)
                summary.update(status=status, message=message)
            clock["analysis"] = time.perf_counter() - t_analysis
        clock["total"] = time.perf_counter() - clock["start"]
        writer.finish(summary, {k: v for k, v in clock.items() if k != "start"})
        if fault is not None:   # the files closed and the summary written: now its traceback
            raise fault
    summary["pictures"] = comm.bcast(summary.get("pictures"), root=0)
    summary["folder"] = str(folder)
    _report(summary, status, message, t, folder, comm, quiet)
    if not quiet:
        print_on_root(comm, "\n".join(writer.closing_lines(time.perf_counter()
                                                            - clock["start"])))
    comm.barrier()     # no rank ends (mpirun then stops the others) before rank 0 reported
    series = comm.bcast(writer.series() if comm.rank == 0 else None, root=0)
    return RunResult(summary, series, folder)


def _report(summary: dict, status: str, message: str, t: float, folder: Path, comm,
            quiet: bool) -> None:
    """The last line: on stderr for a failed, interrupted or unstable run (also with
    --quiet)."""
    if summary["pictures"] == "interrupted":
        message = "; ".join([*filter(None, [message]), "interrupted while drawing the "
                             "pictures: summary.json lists the ones missing"])
    line = f"{status}: t = {t:g}, results in {folder}" + (f" ({message})" if message else "")
    if status in ("failed", "interrupted", "completed (unstable equilibrium)") \
            or summary["pictures"] == "interrupted":
        print_on_root(comm, line, file=sys.stderr)
    elif not quiet:
        print_on_root(comm, line)


def _run_folder(scene: Scene, out: Path | None, comm, resume: bool, overwrite: bool) -> Path:
    """The results folder, ready on rank 0 (errors on every rank as OutputError)."""
    from .output.run_folders import new_run_folder, on_root, prepare_run_folder
    if out is None:
        parent = Path(scene["outputs"]["directory"])
        return Path(on_root(comm, lambda: str(new_run_folder(parent, scene.name)),
                            f"cannot create a run folder in {parent}"))
    on_root(comm, lambda: prepare_run_folder(out, resume, overwrite), f"cannot use --out {out}")
    return out


def _remove_if_empty(folder: Path) -> None:
    """Remove a run folder that holds nothing but its marker."""
    from .output.run_folders import MARKER
    try:
        if [p.name for p in folder.iterdir()] == [MARKER]:
            (folder / MARKER).unlink()
        folder.rmdir()
    except OSError:
        pass


def march(sim, time_table: dict, after_step: Callable[[float], None], done: int = 0,
          stop_after: int | None = None) -> int | None:
    """The one loop over the output times of a scene's [time] table (output_times):
    ``sim.advance`` over each interval from output ``done`` on, ``after_step(t)`` after
    each; PETSc TS (``sim.ts``) or an arc-length continuation drives the whole run
    itself (a multistep history must not restart at every output time).  Returns the step after which ``stop_after``
    stopped the run early, else None."""
    from .integrators.step_control import output_times
    times = output_times(time_table["t_end"], time_table["dt"])
    if getattr(sim, "ts", None) is not None or getattr(sim, "continuation", None) is not None:
        sim.run_all(times[0], time_table["t_end"], time_table["dt"], after_step)
        return None
    for k in range(done + 1, len(times)):
        sim.advance(times[k - 1], times[k])
        after_step(times[k])
        if stop_after is not None and stop_after <= k < len(times) - 1:
            return k
    return None


class _InterruptFlag:
    """SIGINT or SIGTERM sets a flag; the run stops after the current step (a step is
    never cut in half, and PETSc callbacks never see a KeyboardInterrupt).  ``at_once()``
    at the first signal, in the handler: a native mpirun kills its ranks 0.2-0.5 s after
    a Ctrl-C or SIGTERM sent to it (SIGCONT, SIGTERM 0.25 s later, SIGKILL 0.2 s later,
    measured with Open MPI 5), often before the step ends (issue 28 item 22).  A signal
    received during the start-up and dropped by Python is ``raised`` from the start."""

    SIGNALS = ("SIGINT", "SIGTERM")

    def __init__(self, at_once=lambda: None):
        import signal
        import threading
        self.raised = False
        self._at_once = at_once
        self._old = {}
        if threading.current_thread() is threading.main_thread():
            self._old = {name: signal.signal(getattr(signal, name), self._handle)
                         for name in self.SIGNALS}
        # a start-up signal that Python dropped (dolfin_rod.__main__.StartUpInterrupt)
        self.raised = any(getattr(old, "received", False) for old in self._old.values())

    def _handle(self, signum, frame):
        if not self.raised:
            self.raised = True
            try:
                self._at_once()
            except OSError:            # (a full disk: the summary at the end says so)
                pass

    def restore(self):
        import signal
        for name, old in self._old.items():
            signal.signal(getattr(signal, name), old)
        self._old = {}


def _first_row(sim, writer, t0: float, fields: bool) -> None:
    """Row 0 after the integrator's start (sim.begin, where it has one), also when that
    fails (then the state as given, and the error goes on)."""
    try:
        getattr(sim, "begin", lambda t: None)(t0)
    finally:
        writer.record(0, t0, sim.diagnostics(t0))
        if fields:
            writer.write_fields(t0)


def _integrate(scene: Scene, sim, writer, comm, done: int, stop_after: int | None,
               quiet: bool, provisional=None) -> tuple[str, str, float, Exception | None]:
    """Steps done+1 .. n (PETSc TS: the whole run), recording each; (status, message, t)
    with t the time of the last recorded row.  ``provisional(t)`` at the first SIGINT or
    SIGTERM (rank 0): the summary of the rows so far, before the step ends."""
    from mpi4py import MPI

    from .fem.solvers import SolverError
    from .integrators.step_control import IntegrationError, output_times
    from .output.divergence import EnergyBound
    from .output.run_folders import OutputError
    from .output.writer import show_progress
    tim, outs = scene["time"], scene["outputs"]
    times = output_times(tim["t_end"], tim["dt"])
    n_steps = len(times) - 1
    bar = None
    if show_progress(outs["progress"] and not quiet, comm.rank):
        from tqdm import tqdm
        bar = tqdm(total=n_steps, initial=done, unit="step", desc=scene.name)
    progress = {"k": done, "t": times[done]}
    interrupted = _InterruptFlag(lambda: provisional(progress["t"]) if provisional else None)
    if comm.allreduce(interrupted.raised, op=MPI.LOR):   # Ctrl-C during the start-up
        interrupted.restore()
        raise KeyboardInterrupt

    def after_step(t_k: float) -> None:
        diag = sim.diagnostics(t_k)
        # a continuation's steps are not a motion: its power balance does not hold
        bound.check(diag, jump=_report_stability_changes(sim)
                    or getattr(sim, "continuation", None) is not None)
        k = progress["k"] = progress["k"] + 1
        writer.record(k, t_k, diag)
        progress["t"] = t_k
        if k % outs["every"] == 0 or k == n_steps:
            writer.write_fields(t_k)
        if _checkpoint_due(outs, k):
            writer.checkpoint(k, t_k)
        if bar is not None:
            bar.update(1)
        if comm.allreduce(interrupted.raised, op=MPI.LOR):   # stop between steps
            raise KeyboardInterrupt

    status, message, fault = "completed", "", None
    try:
        if done == 0:
            _first_row(sim, writer, times[0], outs["every"])
        bound = EnergyBound(writer.balance.previous)
        stopped = march(sim, tim, after_step, done, stop_after)
        if stopped is not None:
            status, message = "stopped", f"stopped after step {stopped} (stop_after)"
        elif outs["final_checkpoint"] and not _checkpoint_due(outs, progress["k"]):
            writer.checkpoint(progress["k"], progress["t"])    # the end state (from_run)
    except KeyboardInterrupt:
        status, message = "interrupted", f"interrupted at t = {progress['t']:g}"
    except (IntegrationError, SolverError, OutputError) as err:   # keep what was computed
        status, message = "failed", f"{type(err).__name__}: {err}"
    except Exception as err:     # a fault of the package: kept too, then raised (run)
        status, message = "failed", (f"{type(err).__name__}: {err} (an internal error of "
                                     "dolfin_rod, not of the scene: please report it with "
                                     "the traceback that follows)")
        fault = err
    finally:
        interrupted.restore()
        if bar is not None:
            bar.close()
    return status, message, progress["t"], fault


def _checkpoint_due(outputs: dict, k: int) -> bool:
    """A checkpoint after step k (outputs.checkpoint_every)."""
    return bool(outputs["checkpoint_every"]) and k % outputs["checkpoint_every"] == 0


def _report_stability_changes(sim) -> bool:
    """A warning for each branch switch and each change of the tangent's negative
    eigenvalues not yet shown (a run's warnings: on rank 0's stderr and in summary.json,
    output/notices.py); whether the state switched branches since the last call."""
    branches = getattr(sim, "branches", None)
    monitor = getattr(sim, "stability", None)
    switched = False
    while branches is not None and len(branches.switches) > branches.reported:
        switch = branches.switches[branches.reported]
        branches.reported += 1
        switched = switched or switch.after is not None
        text = _switch_text(switch, monitor is None or monitor.conservative)
        warnings.warn(f"t = {switch.t:g}: {text}", RuntimeWarning, stacklevel=2)
    while monitor is not None and len(monitor.changes) > monitor.reported:
        t, before, after = monitor.changes[monitor.reported]
        monitor.reported += 1
        state = "unstable" if after else "stable again"
        warnings.warn(f"t = {t:g}: the equilibrium is {state}: {after} negative "
                      f"eigenvalue(s) of the tangent stiffness (was {before}; "
                      f"docs/stability.md){_energy_criterion(monitor)}", RuntimeWarning,
                      stacklevel=2)
    return switched


def _energy_criterion(monitor) -> str:
    """What the count means under non-conservative loads (follower loads, couples):
    appended to its warnings and to an unstable end's message; "" otherwise."""
    if monitor.conservative:
        return ""
    return ("; the loads are not conservative (couples, follower loads): the count is "
            "that of K's symmetric part, the energy criterion, which neither proves nor "
            "excludes instability; `dolfin-rod modes` with a density decides (flutter, "
            "divergence; docs/stability.md, \"Couples\")")


def _switch_text(switch, conservative: bool) -> str:
    """What a branch switch (analysis/branches.Switch) did, in words (under
    non-conservative loads a rise of the count is no bifurcation: _energy_criterion)."""
    met = (f"{'a bifurcation: ' if conservative else ''}the path's equilibrium became "
           f"unstable ({switch.unstable} negative eigenvalue(s) of the tangent stiffness, "
           f"was {switch.stable})")
    if switch.after is None:
        return f"{met}; no stable branch found along the critical mode, the path goes on"
    return (f"{met}; switched to a stable branch, down the energy from the critical mode's "
            f"{'+' if switch.sign > 0 else '-'} side (stability.at_bifurcation = \"stay\" "
            "keeps the path; docs/stability.md)")


def _unstable_end(scene, sim, status: str, message: str) -> tuple[str, str]:
    """A completed quasi-static run that ends on an unstable equilibrium is not a result
    unless stability.follow_unstable says so."""
    monitor = getattr(sim, "stability", None)
    if status != "completed" or monitor is None or not monitor.negative \
            or scene["stability"]["follow_unstable"]:
        return status, message
    return "completed (unstable equilibrium)", (
        f"the end state has {monitor.negative} negative eigenvalue(s) of the tangent "
        "stiffness: an unstable equilibrium (stability.follow_unstable = true accepts it)"
        + _energy_criterion(monitor))


def _summary(scene, choice, sim, writer, comm, status, message, t, impulse,
             seen: list[str]) -> dict:
    from .output.notices import listed
    summary = {
        "scene": scene.name, "source": scene.source,
        "scene_folder": str((scene.folder or Path()).resolve()), "model": choice.model,
        "reason": choice.reason, "method": getattr(sim, "describe", lambda: "")(),
        "status": status, "message": message, "t_end_reached": t,
        "steps": len(writer.rows) - 1 if comm.rank == 0 else None,
        "end_torsion_impulse_at_0": impulse,
        "final": dict(writer.balance.previous or {}),
        "total_dissipation": writer.balance.total_dissipation,
        "title": f"{scene.name}: {choice.model} model",
        "warnings": listed(seen),
    }
    if scene.is_rod_material and scene["material"]["derived"]:
        summary["derived"] = scene["material"]["derived"]    # from the physical input
    stats = getattr(sim, "stats", None)
    if stats is not None:
        summary["newton_iterations"] = stats.newton_iterations
        summary["rejected_steps"] = stats.rejected
    monitor = getattr(sim, "stability", None)
    if monitor is not None and monitor.checks:
        summary["stability_check_ms_per_step"] = 1e3 * monitor.seconds / monitor.checks
    return summary
