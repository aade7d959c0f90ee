"""The command line: ``dolfin-rod check SCENE.toml`` and ``dolfin-rod run SCENE.toml``.

    dolfin-rod check scenes/torsion_creep.toml            validate, print the model and why
    dolfin-rod run scenes/torsion_creep.toml --out DIR    run, results in DIR
    dolfin-rod run SCENE --out DIR --resume               continue from DIR/checkpoint
    mpirun -n 2 python3 -m dolfin_rod run SCENE           only rank 0 prints and writes

Exit status: 0 success, 2 a bad scene (SceneError, printed without a traceback) or bad
arguments, 3 the integration stopped early (what was computed is kept), 130 interrupted.
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
import time
from pathlib import Path

from .integrators.stepper import IntegrationError
from .scenes import Scene, SceneError, build, load_scene, select_model
from .solvers import SolverError

__all__ = ["main", "run_scene"]


def _print(comm, *args, file=None) -> None:
    if comm.rank == 0:
        print(*args, file=file or sys.stdout, flush=True)


class _InterruptFlag:
    """SIGINT sets a flag; the run stops after the current step (a step is never cut in
    half, and PETSc callbacks never see a KeyboardInterrupt)."""

    def __init__(self):
        import signal
        import threading
        self.raised = False
        self._old = None
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGINT, self._handle)

    def _handle(self, signum, frame):
        self.raised = True

    def restore(self):
        import signal
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
            self._old = None


def default_run_folder(scene: Scene) -> Path:
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path(scene["outputs"]["directory"]) / f"{scene.name}-{stamp}"


def run_scene(scene: Scene, out: Path | str | None = None, comm=None, resume: bool = False,
              stop_after: int | None = None, quiet: bool = False) -> dict:
    """Run a validated scene; returns the summary (same on every rank).

    ``stop_after``: stop after that many steps (as an interrupted run would), keeping
    the outputs and the last checkpoint; used to test ``resume``.
    """
    from mpi4py import MPI

    from .output import RunWriter, show_progress
    comm = comm or MPI.COMM_WORLD
    clock = {"start": time.perf_counter()}
    choice = select_model(scene)
    folder = Path(out) if out is not None else default_run_folder(scene)
    if out is None:
        folder = Path(comm.bcast(str(folder), root=0))
    if not quiet:
        _print(comm, f"model: {choice.model} ({choice.reason})")
    sim = build(scene, choice.model, comm)
    impulse = sim.start()
    clock["setup"] = time.perf_counter() - clock["start"]
    writer = RunWriter(folder, scene, choice, sim, comm, resume=resume)
    tim, outs = scene["time"], scene["outputs"]
    n_steps = max(1, math.ceil(tim["t_end"] / tim["dt"] - 1e-9))
    times = [min(k * tim["dt"], tim["t_end"]) for k in range(n_steps + 1)]
    first = 1
    if resume:
        meta = writer.read_checkpoint()
        first = meta["step"] + 1
        writer.open(keep_until_step=meta["step"])
        if not quiet:
            _print(comm, f"resumed at step {meta['step']}, t = {meta['time']:g}")
    else:
        writer.open()
        writer.record(0, times[0], sim.diagnostics(times[0]))
        if outs["every"]:
            writer.write_fields(times[0])
    bar = None
    if show_progress(outs["progress"] and not quiet, comm.rank):
        from tqdm import tqdm
        bar = tqdm(total=n_steps, initial=first - 1, unit="step", desc=scene.name)
    status, message, t = "completed", "", times[first - 1]
    t_run = time.perf_counter()
    progress = {"k": first - 1}
    interrupted = _InterruptFlag()

    def after_step(t_k: float) -> None:
        k = progress["k"] = progress["k"] + 1
        writer.record(k, t_k, sim.diagnostics(t_k))
        if k % outs["every"] == 0 or k == n_steps:
            writer.write_fields(t_k)
        if outs["checkpoint_every"] and k % outs["checkpoint_every"] == 0:
            writer.checkpoint(k, t_k)
        if bar is not None:
            bar.update(1)
        if comm.allreduce(interrupted.raised, op=MPI.LOR):   # stop between steps
            raise KeyboardInterrupt

    try:
        if getattr(sim, "ts", None) is not None:      # PETSc TS drives the whole run
            if resume or stop_after is not None:
                raise scene.error("time.integrator", "resume/stop_after need integrator = "
                                                     "\"stepper\"")
            sim.run_all(times[0], tim["t_end"], tim["dt"], after_step)
            t = tim["t_end"]
        for k in range(first, n_steps + 1) if getattr(sim, "ts", None) is None else ():
            sim.advance(times[k - 1], times[k])
            t = times[k]
            after_step(t)
            if stop_after is not None and k >= stop_after and k < n_steps:
                status, message = "stopped", f"stopped after step {k} (stop_after)"
                break
    except KeyboardInterrupt:
        status, message = "interrupted", f"interrupted at t = {t:g}"
    except SceneError:
        raise
    except (IntegrationError, SolverError) as err:   # keep what was computed
        status, message = "failed", f"{type(err).__name__}: {err}"
    finally:
        interrupted.restore()
        if bar is not None:
            bar.close()
    clock["integration"] = time.perf_counter() - t_run
    last = writer.balance.previous or {}
    summary = {
        "scene": scene.name, "source": scene.source, "model": choice.model,
        "reason": choice.reason, "method": getattr(sim, "describe", lambda: "")(),
        "status": status, "message": message, "t_end_reached": t, "steps": len(writer.rows) - 1
        if comm.rank == 0 else None,
        "end_torsion_impulse_at_0": impulse,
        "final": {k: v for k, v in last.items()},
        "total_dissipation": writer.balance.total_dissipation,
        "title": f"{scene.name}: {choice.model} model",
    }
    stats = getattr(getattr(sim, "stepper", None), "stats", None)
    if stats is not None:
        summary["newton_iterations"] = stats.newton_iterations
        summary["rejected_steps"] = stats.rejected
    clock["total"] = time.perf_counter() - clock["start"]
    writer.finish(summary, {k: v for k, v in clock.items() if k != "start"})
    summary["folder"] = str(folder)
    if not quiet:
        _print(comm, f"{status}: t = {t:g}, results in {folder}" + (f" ({message})" if message
                                                                    else ""))
    return summary


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="dolfin-rod", description="Cosserat rods with evolving "
                                "natural configurations: run or check a TOML scene")
    sub = p.add_subparsers(dest="command", required=True)
    check = sub.add_parser("check", help="validate a scene, print the chosen model and why")
    check.add_argument("scene", type=Path)
    run = sub.add_parser("run", help="run a scene")
    run.add_argument("scene", type=Path)
    run.add_argument("--out", type=Path, default=None,
                     help="results folder (default: <outputs.directory>/<name>-<time>)")
    run.add_argument("--resume", action="store_true",
                     help="continue from the checkpoint in --out")
    run.add_argument("--quiet", action="store_true", help="no progress output")
    sub.add_parser("schema", help="print every scene key with its default and meaning "
                                  "(Markdown, as in docs/scenes.md)")
    return p


def schema_markdown() -> str:
    """The scene schema as Markdown tables (docs/scenes.md is generated from it)."""
    from .scenes.schema import REQUIRED, SCHEMA, SCHEMA_NOTES
    lines = [SCHEMA_NOTES]
    for table, keys in SCHEMA.items():
        lines += [f"### [{table}]", "", "| key | default | meaning |", "|---|---|---|"]
        for name, key in keys.items():
            default = "required" if key.default is REQUIRED else (
                "-" if key.default is None else f"`{key.default!r}`")
            doc = key.doc.replace("|", "\\|")
            lines.append(f"| `{name}` | {default} | {doc} |")
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from mpi4py import MPI
    comm = MPI.COMM_WORLD
    args = _parser().parse_args(argv)
    if args.command == "schema":
        _print(comm, schema_markdown())
        return 0
    try:
        scene = load_scene(args.scene)
        if args.command == "check":
            choice = select_model(scene)
            _print(comm, f"{scene.source}: OK")
            _print(comm, f"model: {choice.model}")
            _print(comm, f"why: {choice.reason}")
            return 0
        if args.resume and args.out is None:
            raise SceneError(str(args.scene), "", "--resume needs --out (the run folder)")
        summary = run_scene(scene, args.out, comm, resume=args.resume, quiet=args.quiet)
    except SceneError as err:
        _print(comm, f"error: {err}", file=sys.stderr)
        return 2
    except FileNotFoundError as err:   # --resume without a checkpoint
        _print(comm, f"error: {err}", file=sys.stderr)
        return 2
    return {"completed": 0, "stopped": 0, "interrupted": 130}.get(summary["status"], 3)


if __name__ == "__main__":
    sys.exit(main())
