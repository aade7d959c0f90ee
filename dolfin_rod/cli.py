"""The command line: ``dolfin-rod check SCENE.toml``, ``dolfin-rod run SCENE.toml`` and
``dolfin-rod fit SCENE.toml DATA.csv --params ...`` (dolfin_rod/fit_cli.py).

    dolfin-rod check scenes/torsion_creep.toml            validate, print the model and why
    dolfin-rod run scenes/torsion_creep.toml --out DIR    run, results in DIR
    dolfin-rod run SCENE --out DIR --resume               continue from DIR/checkpoint
    dolfin-rod run SCENE --out DIR --overwrite            replace the run folder DIR
    mpirun -n 2 python3 -m dolfin_rod run SCENE           only rank 0 prints and writes

Exit status: 0 success, 2 a bad scene, folder or checkpoint (SceneError, OutputError:
one line on stderr, nothing written), 3 the integration failed or diverged (what was
computed before is kept), 130 interrupted (Ctrl-C or SIGTERM; also while the pictures
are drawn after the last step: summary.json says "pictures": "interrupted").  Failures
always go to stderr, --quiet or not.  Under MPI every error ends every rank and reaches
the user whichever rank saw it: expected errors are raised collectively (mpi.agree), or,
seen by one rank inside collective work, reported by that rank with MPI_Abort(2)
(mpi.alone); anything else calls MPI_Abort, so no rank is left waiting.  A scene needs
2 cells per rank.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

from .output.divergence import EnergyBound
from .integrators.stepper import IntegrationError
from .scenes import Scene, SceneError, build, load_scene, select_model
from .torsion.stability import explicit_stability_warning
from .fem.solvers import SolverError

__all__ = ["main", "run_scene"]


def print_on_root(comm, *args, file=None) -> None:
    """print on rank 0 only (flushed: stdout and stderr interleave as written)."""
    if comm.rank == 0:
        print(*args, file=file or sys.stdout, flush=True)


class _InterruptFlag:
    """SIGINT or SIGTERM sets a flag; the run stops after the current step (a step is
    never cut in half, and PETSc callbacks never see a KeyboardInterrupt)."""

    SIGNALS = ("SIGINT", "SIGTERM")

    def __init__(self):
        import signal
        import threading
        self.raised = False
        self._old = {}
        if threading.current_thread() is threading.main_thread():
            self._old = {name: signal.signal(getattr(signal, name), self._handle)
                         for name in self.SIGNALS}

    def _handle(self, signum, frame):
        self.raised = True

    def restore(self):
        import signal
        for name, old in self._old.items():
            signal.signal(getattr(signal, name), old)
        self._old = {}



def _run_folder(scene: Scene, out: Path | None, comm, resume: bool, overwrite: bool) -> Path:
    """The results folder, ready on rank 0 (errors on every rank as OutputError)."""
    from .output.run_folders import new_run_folder, on_root, prepare_run_folder
    if out is None:
        parent = Path(scene["outputs"]["directory"])
        return Path(on_root(comm, lambda: str(new_run_folder(parent, scene.name)),
                            f"cannot create a run folder in {parent}"))
    on_root(comm, lambda: prepare_run_folder(Path(out), resume, overwrite),
            f"cannot use --out {out}")
    return Path(out)


def run_scene(scene: Scene | Path | str, out: Path | str | None = None, comm=None, resume: bool = False,
              stop_after: int | None = None, quiet: bool = False,
              overwrite: bool = False) -> dict:
    """Run a scene (validated, or the path of a scene file); returns the summary (same on
    every rank).

    ``out``: the results folder; if it is not empty, ``resume`` continues its run from
    its last checkpoint (verified against this scene) and ``overwrite`` replaces it.
    ``stop_after``: stop after that many steps (as an interrupted run would), keeping
    the outputs and the last checkpoint; used to test ``resume``.
    Raises OutputError (nothing written) for an unusable folder or checkpoint.
    """
    from mpi4py import MPI

    from .output.checkpoints import read_checkpoint_meta
    from .mpi import agree
    from .output.writer import RunWriter
    comm = comm or MPI.COMM_WORLD
    if not isinstance(scene, Scene):                 # a scene file's path
        scene = agree(comm, lambda: load_scene(scene), (SceneError,))
    clock = {"start": time.perf_counter()}
    choice = agree(comm, lambda: _choose(scene, comm.size), (SceneError,))
    if (resume or stop_after is not None) and scene["time"]["integrator"] == "ts":
        raise scene.error("time.integrator", "resume/stop_after need integrator = \"stepper\"")
    meta = read_checkpoint_meta(Path(out), comm, scene) if resume else None
    made = not resume and (out is None or not os.path.exists(out))   # (False on errors)
    folder = _run_folder(scene, None if out is None else Path(out), comm, resume, overwrite)
    if not quiet:
        print_on_root(comm, f"model: {choice.model} ({choice.reason})")
    _warn_if_unstable(scene, comm)
    try:
        sim = build(scene, choice.model, comm)
        impulse = sim.start()
    except BaseException:
        if made and comm.rank == 0:              # nothing half-written: no empty folder
            _remove_if_empty(folder)
        raise
    clock["setup"] = time.perf_counter() - clock["start"]
    writer = RunWriter(folder, scene, choice, sim, comm, resume=resume)
    if meta is not None:
        writer.restore_checkpoint(meta)
        writer.open(keep_until_step=meta["step"])
        if not quiet:
            print_on_root(comm, f"resumed at step {meta['step']}, t = {meta['time']:g}")
    else:
        writer.open()
    t_run = time.perf_counter()
    status, message, t = _integrate(scene, sim, writer, comm, 0 if meta is None else
                                    meta["step"], stop_after, quiet)
    status, message = _unstable_end(scene, sim, status, message)
    clock["integration"] = time.perf_counter() - t_run
    summary = _summary(scene, choice, sim, writer, comm, status, message, t, impulse)
    clock["total"] = time.perf_counter() - clock["start"]
    writer.finish(summary, {k: v for k, v in clock.items() if k != "start"})
    summary["pictures"] = comm.bcast(summary.get("pictures"), root=0)
    summary["folder"] = str(folder)
    if summary["pictures"] == "interrupted":
        message = "; ".join([*filter(None, [message]), "interrupted while drawing the "
                             "pictures: summary.json lists the ones missing"])
    line = f"{status}: t = {t:g}, results in {folder}" + (f" ({message})" if message else "")
    if status in ("failed", "interrupted", "completed (unstable equilibrium)") \
            or summary["pictures"] == "interrupted":
        print_on_root(comm, line, file=sys.stderr)
    elif not quiet:
        print_on_root(comm, line)
    if not quiet:
        print_on_root(comm, "\n".join(writer.closing_lines(time.perf_counter()
                                                            - clock["start"])))
    comm.barrier()     # no rank ends (mpirun then stops the others) before rank 0 reported
    return summary


def _remove_if_empty(folder: Path) -> None:
    """Remove a run folder that holds nothing but its marker."""
    from .output.run_folders import MARKER
    try:
        if [p.name for p in folder.iterdir()] == [MARKER]:
            (folder / MARKER).unlink()
        folder.rmdir()
    except OSError:
        pass


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
               quiet: bool) -> tuple[str, str, float]:
    """Steps done+1 .. n (PETSc TS: the whole run), recording each; (status, message, t)
    with t the time of the last recorded row."""
    from mpi4py import MPI

    from .output.writer import show_progress
    from .output.run_folders import OutputError
    tim, outs = scene["time"], scene["outputs"]
    n_steps = max(1, math.ceil(tim["t_end"] / tim["dt"] - 1e-9))
    times = [min(k * tim["dt"], tim["t_end"]) for k in range(n_steps + 1)]
    bar = None
    if show_progress(outs["progress"] and not quiet, comm.rank):
        from tqdm import tqdm
        bar = tqdm(total=n_steps, initial=done, unit="step", desc=scene.name)
    progress = {"k": done, "t": times[done]}
    interrupted = _InterruptFlag()

    def after_step(t_k: float) -> None:
        diag = sim.diagnostics(t_k)
        _report_stability_changes(sim, comm)
        bound.check(diag)
        k = progress["k"] = progress["k"] + 1
        writer.record(k, t_k, diag)
        progress["t"] = t_k
        if k % outs["every"] == 0 or k == n_steps:
            writer.write_fields(t_k)
        if outs["checkpoint_every"] and k % outs["checkpoint_every"] == 0:
            writer.checkpoint(k, t_k)
        if bar is not None:
            bar.update(1)
        if comm.allreduce(interrupted.raised, op=MPI.LOR):   # stop between steps
            raise KeyboardInterrupt

    status, message = "completed", ""
    try:
        if done == 0:
            _first_row(sim, writer, times[0], outs["every"])
        bound = EnergyBound(writer.balance.previous)
        if getattr(sim, "ts", None) is not None:      # PETSc TS drives the whole run
            sim.run_all(times[0], tim["t_end"], tim["dt"], after_step)
        for k in range(done + 1, n_steps + 1) if getattr(sim, "ts", None) is None else ():
            sim.advance(times[k - 1], times[k])
            after_step(times[k])
            if stop_after is not None and k >= stop_after and k < n_steps:
                status, message = "stopped", f"stopped after step {k} (stop_after)"
                break
    except KeyboardInterrupt:
        status, message = "interrupted", f"interrupted at t = {progress['t']:g}"
    except (IntegrationError, SolverError, OutputError) as err:   # keep what was computed
        status, message = "failed", f"{type(err).__name__}: {err}"
    finally:
        interrupted.restore()
        if bar is not None:
            bar.close()
    return status, message, progress["t"]


def _report_stability_changes(sim, comm) -> None:
    """A warning for each change of the tangent's negative eigenvalues not yet shown."""
    monitor = getattr(sim, "stability", None)
    while monitor is not None and len(monitor.changes) > monitor.reported:
        t, before, after = monitor.changes[monitor.reported]
        monitor.reported += 1
        state = "unstable" if after else "stable again"
        print_on_root(comm, f"warning: t = {t:g}: the equilibrium is {state}: {after} "
                            f"negative eigenvalue(s) of the tangent stiffness (was {before}; "
                            "docs/stability.md)", file=sys.stderr)


def _unstable_end(scene, sim, status: str, message: str) -> tuple[str, str]:
    """A completed quasi-static run that ends on an unstable equilibrium is not a result
    unless stability.follow_unstable says so."""
    monitor = getattr(sim, "stability", None)
    if status != "completed" or monitor is None or not monitor.negative \
            or scene["stability"]["follow_unstable"]:
        return status, message
    return "completed (unstable equilibrium)", (
        f"the end state has {monitor.negative} negative eigenvalue(s) of the tangent "
        "stiffness: an unstable equilibrium (stability.follow_unstable = true accepts it)")


def _summary(scene, choice, sim, writer, comm, status, message, t, impulse) -> dict:
    summary = {
        "scene": scene.name, "source": scene.source, "model": choice.model,
        "reason": choice.reason, "method": getattr(sim, "describe", lambda: "")(),
        "status": status, "message": message, "t_end_reached": t,
        "steps": len(writer.rows) - 1 if comm.rank == 0 else None,
        "end_torsion_impulse_at_0": impulse,
        "final": dict(writer.balance.previous or {}),
        "total_dissipation": writer.balance.total_dissipation,
        "title": f"{scene.name}: {choice.model} model",
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


def _parser() -> argparse.ArgumentParser:
    from . import __version__
    p = argparse.ArgumentParser(prog="dolfin-rod", description="Cosserat rods with evolving "
                                "natural configurations: run or check a TOML scene")
    p.add_argument("--version", action="version", version=f"dolfin-rod {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    check = sub.add_parser("check", help="validate a scene and its output folder, print the "
                                         "chosen model and why")
    check.add_argument("scene", type=Path)
    check.add_argument("--out", type=Path, default=None, help="check this results folder "
                       "too (default: outputs.directory)")
    run = sub.add_parser("run", help="run a scene")
    run.add_argument("scene", type=Path)
    run.add_argument("--out", type=Path, default=None,
                     help="results folder (default: a new <outputs.directory>/<name>-<time>)")
    mode = run.add_mutually_exclusive_group()
    mode.add_argument("--resume", action="store_true",
                      help="continue the run in --out from its last checkpoint")
    mode.add_argument("--overwrite", action="store_true",
                      help="replace the run folder --out if it is not empty")
    run.add_argument("--quiet", action="store_true", help="no progress output (failures "
                                                          "are still reported on stderr)")
    sub.add_parser("schema", help="print every scene key with its default and meaning "
                                  "(Markdown, as in docs/scenes.md)")
    from .fit.command import add_fit_parser
    add_fit_parser(sub)
    return p


def schema_markdown() -> str:
    """The scene schema as Markdown tables (docs/scenes.md is generated from it)."""
    from .scenes.schema import ARRAY_TABLES, REQUIRED, SCHEMA, SCHEMA_NOTES
    lines = [SCHEMA_NOTES]
    for table, keys in SCHEMA.items():
        title = f"[[{table}]] (an array of tables)" if table in ARRAY_TABLES else f"[{table}]"
        lines += [f"### {title}", "", "| key | default | meaning |", "|---|---|---|"]
        for name, key in keys.items():
            default = "required" if key.default is REQUIRED else (
                "-" if key.default is None else f"`{key.default!r}`")
            doc = key.doc.replace("|", "\\|")
            lines.append(f"| `{name}` | {default} | {doc} |")
        lines.append("")
    return "\n".join(lines)


def _warn_if_unstable(scene: Scene, comm) -> None:
    warning = explicit_stability_warning(scene)
    if warning:
        print_on_root(comm, f"warning: {warning}", file=sys.stderr)


def _check(scene: Scene, out: Path | None, comm) -> None:
    """``dolfin-rod check``: the scene, its model and the output location; "OK" only when
    every rank found the scene fine (mpi.agree)."""
    from .mpi import agree
    from .output.run_folders import OutputError, folder_problem
    lines = agree(comm, lambda: _check_lines(scene, comm.size), (SceneError,))
    target = out if out is not None else Path(scene["outputs"]["directory"])
    problem = folder_problem(target) if comm.rank == 0 else None
    problem = comm.bcast(problem, root=0)
    if problem:
        what = "--out" if out is not None else f"{scene.source}: [outputs.directory]"
        raise OutputError(f"{what} {problem}")
    for line in lines:
        print_on_root(comm, line)
    _warn_if_unstable(scene, comm)


def _choose(scene: Scene, ranks: int):
    """The scene's model (select_model), refused with a SceneError naming
    geometry.n_cells if an FE model would leave a rank too few cells."""
    from .fem.fe_model import check_n_cells
    choice = select_model(scene)
    if choice.model != "ode":
        try:
            check_n_cells(scene["geometry"]["n_cells"], ranks)
        except ValueError as err:
            raise scene.error("geometry.n_cells", str(err)) from None
    return choice


def _check_lines(scene: Scene, ranks: int) -> list[str]:
    """What ``check`` prints for a valid scene: OK, the model, why, how it steps."""
    choice = _choose(scene, ranks)
    lines = [f"{scene.source}: OK", f"model: {choice.model}", f"why: {choice.reason}"]
    if choice.model == "rod":
        from .scenes.physical import describe
        from .scenes.rules import rod_rotations
        for rod in scene.rods or [None]:          # [[rods]]: each rod's derived tensors
            own = rod.scene if rod else scene
            label = f"rod {rod.name}: " if rod else ""
            lines += [f"derived: {label}{line}"
                      for line in describe(own["material"]["derived"] or {})]
        lines += [f"joint: {j.kind} {j.rods[0]}-{j.rods[1]} at {list(j.point)}"
                  for j in scene.joints]
        lines.append(f"rotations: {rod_rotations(scene)} (geometry.rotations = "
                     f"{scene['geometry']['rotations']!r})")
    if choice.model != "ode":                      # (the ODE prints its own solution)
        from .scenes.rules import time_stepping
        lines.append(f"time stepping: {time_stepping(scene)}")
    return lines


def main(argv: list[str] | None = None) -> int:
    """The command line; every error ends every rank: expected ones (a bad scene or
    folder) with exit 2, collectively where every rank saw them, else by MPI_Abort(2)
    from the rank that saw one (mpi.alone); anything else by MPI_Abort after its
    traceback."""
    from mpi4py import MPI

    from .fit.command import FitInputError
    from .mpi import alone
    from .output.run_folders import OutputError
    comm = MPI.COMM_WORLD
    guard = comm.Dup() if comm.size > 1 else None    # for mpi.alone only
    try:
        return _main(argv, comm)
    except (SceneError, OutputError, FitInputError) as err:
        if alone(guard):
            print(f"error: {err} (seen on rank {comm.rank} only)", file=sys.stderr, flush=True)
            comm.Abort(2)                          # the other ranks may wait in a collective
        print_on_root(comm, f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:                      # Ctrl-C before the run loop
        print_on_root(comm, "interrupted", file=sys.stderr)
        return 130
    except Exception:
        if comm.size == 1:
            raise
        import traceback
        print(f"rank {comm.rank}: {traceback.format_exc()}", file=sys.stderr, flush=True)
        comm.Abort(1)                              # the other ranks may wait in a collective
        return 1


def _main(argv: list[str] | None, comm) -> int:
    from .fit.command import fit_command
    from .mpi import agree
    args = _parser().parse_args(argv)
    if args.command == "schema":
        print_on_root(comm, schema_markdown())
        return 0
    if args.command == "fit":
        return fit_command(args, comm)
    scene = agree(comm, lambda: load_scene(args.scene), (SceneError,))
    if args.command == "check":
        _check(scene, args.out, comm)
        return 0
    if args.resume and args.out is None:
        raise SceneError(str(args.scene), "", "--resume needs --out (the run folder)")
    summary = run_scene(scene, args.out, comm, resume=args.resume, quiet=args.quiet,
                        overwrite=args.overwrite)
    if summary["pictures"] == "interrupted" and summary["status"] != "failed":
        return 130
    return {"completed": 0, "stopped": 0, "interrupted": 130,
            "completed (unstable equilibrium)": 4}.get(summary["status"], 3)


if __name__ == "__main__":
    sys.exit(main())
