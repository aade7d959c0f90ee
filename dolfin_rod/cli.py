"""The command line: ``dolfin-rod check SCENE.toml``, ``dolfin-rod run SCENE.toml`` and
``dolfin-rod fit SCENE.toml DATA.csv --params ...`` (fit/command.py): argument parsing and
exit statuses; a run is run.py's.

    dolfin-rod check scenes/torsion_creep.toml            validate, print the model and why
    dolfin-rod run scenes/torsion_creep.toml --out DIR    run, results in DIR
    dolfin-rod run SCENE --out DIR --resume               continue from DIR/checkpoint
    dolfin-rod run SCENE --out DIR --overwrite            replace the run folder DIR
    dolfin-rod run SCENE --set outputs.every=5            a key changed for this run
    dolfin-rod buckle SCENE --count 4                     run, then the buckling modes
    dolfin-rod modes SCENE --count 6                      run, then the vibration modes
    dolfin-rod plot DIR [quantities] [--color u_d]        draw DIR's pictures again
    mpirun -n 2 python3 -m dolfin_rod run SCENE           only rank 0 prints and writes

Exit status: 0 success, 2 a bad scene, folder or checkpoint (SceneError, OutputError:
one line on stderr, nothing written), 3 the integration failed or diverged (what was
computed before is kept), 130 interrupted (Ctrl-C or SIGTERM; also while the pictures
are drawn after the last step: summary.json says "pictures": "interrupted").  Failures
always go to stderr, --quiet or not.  Under MPI every error ends every rank and reaches
the user whichever rank saw it: expected errors are raised collectively (mpi.agree), or,
seen by one rank inside collective work, reported by that rank, which leaves with exit
2 (mpi.alone, mpi.leave); anything else calls MPI_Abort, so no rank is left waiting.  A scene needs
2 cells per rank.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from .mpi import agree, print_on_root
from .run import ANALYSES, analyse, choose_model, run, scene_warnings
from .scenes.scene import Scene, SceneError

__all__ = ["main", "schema_markdown"]


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
    _add_set(check)
    run_cmd = sub.add_parser("run", help="run a scene")
    run_cmd.add_argument("scene", type=Path)
    _add_set(run_cmd)
    run_cmd.add_argument("--out", type=Path, default=None, help="results folder (default: a "
                         "new <outputs.directory>/<name>-<time>)")
    mode = run_cmd.add_mutually_exclusive_group()
    mode.add_argument("--resume", action="store_true",
                      help="continue the run in --out from its last checkpoint")
    mode.add_argument("--overwrite", action="store_true",
                      help="replace the run folder --out if it is not empty")
    run_cmd.add_argument("--quiet", action="store_true", help="no progress output (failures "
                         "are still reported on stderr)")
    plot = sub.add_parser("plot", help="draw the pictures of a finished run again "
                          "(histories.png, snapshots, animation), nothing recomputed")
    plot.add_argument("folder", type=Path, help="a run folder of dolfin-rod run")
    plot.add_argument("quantities", nargs="*", help="panels of histories.png (tip_deflection, "
                      "end_torque, ...) or columns of timeseries.csv; default the scene's")
    plot.add_argument("--color", default="auto", help="the field colouring the 3-D pictures "
                      "(outputs.color: u, v, u_d, v_d, n, m, xi; default the scene's)")
    plot.add_argument("--to", type=Path, default=None, help="the histories figure's file "
                      "(default FOLDER/histories.png)")
    sub.add_parser("schema", help="print every scene key with its default and meaning "
                                  "(Markdown, as in docs/scenes.md)")
    _add_fit_parser(sub)
    _add_analysis_parsers(sub)
    return p


def _add_set(command) -> None:
    command.add_argument("--set", action="append", default=[], metavar="TABLE.KEY=VALUE",
                         help="change a scene key for this run (repeatable), VALUE in TOML "
                              "(a bare word is a string): --set outputs.every=5 --set "
                              "boundary.start_spring='{rotational = 400}'")


def overrides(scene: Path, given: list[str]) -> dict:
    """{"table.key": value} of the --set options (run.run's overrides); a SceneError
    naming the option if one is not TABLE.KEY=VALUE."""
    import tomllib
    out = {}
    for item in given:
        name, equals, text = item.partition("=")
        name = name.strip()
        if not equals or "." not in name:
            raise SceneError(str(scene), name, f"--set {item!r}: give TABLE.KEY=VALUE, e.g. "
                                               "--set outputs.every=5")
        try:
            out[name] = tomllib.loads(f"value = {text}")["value"]
        except tomllib.TOMLDecodeError:
            out[name] = text.strip()          # a bare word: the string
    return out


def _add_fit_parser(sub) -> None:
    """The ``fit`` sub-command (fit/command.py)."""
    fit = sub.add_parser("fit", help="fit scene parameters to a measured time series "
                                     "(CSV: time, load, response; docs/fitting.md)")
    fit.add_argument("scene", type=Path)
    fit.add_argument("data", type=Path, help="CSV with columns time, load, response")
    fit.add_argument("--params", required=True,
                     help="comma-separated scene key paths, e.g. alpha_d,mu_d or "
                          "material.viscosity.M_d[1]")
    fit.add_argument("--out", type=Path, default=None, help="results folder (must be "
                     "empty; default: a new <outputs.directory>/fit-<name>-<time>)")
    fit.add_argument("--quiet", action="store_true", help="print only the status line")


def _add_analysis_parsers(sub) -> None:
    """``buckle`` and ``modes``: run a scene, then analyse its end state (run.analyse)."""
    helps = {"buckle": "run a quasi-static rod scene, then its critical load factors and "
                       "buckling modes about the end state (buckle.json, buckle.bp, buckle.png)",
             "modes": "run a rod scene with mass, then its natural frequencies and "
                      "vibration modes about the end state (modes.json, modes.bp, modes.png)"}
    for kind, default in ANALYSES.items():
        cmd = sub.add_parser(kind, help=helps[kind])
        cmd.add_argument("scene", type=Path)
        cmd.add_argument("--count", type=int, default=default,
                         help=f"number of modes (default {default})")
        cmd.add_argument("--out", type=Path, default=None, help="results folder (default: "
                         "a new <outputs.directory>/<name>-<time>)")
        cmd.add_argument("--overwrite", action="store_true",
                         help="replace the run folder --out if it is not empty")
        cmd.add_argument("--quiet", action="store_true", help="no progress output")
        _add_set(cmd)


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


def _check(scene: Scene, out: Path | None, comm) -> None:
    """``dolfin-rod check``: the scene, its model and the output location; "OK" only when
    every rank found the scene fine (mpi.agree)."""
    from .output.from_run import previous_state
    from .output.run_folders import OutputError, folder_problem
    lines = agree(comm, lambda: _check_lines(scene, comm.size), (SceneError,))
    previous = previous_state(scene, choose_model(scene, comm.size).model, comm,
                              missing_ok=True)
    if previous is not None:                 # [initial] from_run: the state it starts from
        lines.append(f"starts from: {previous.run}, its state at t = "
                     f"{previous.meta['time']:g} (step {previous.meta['step']})")
        if previous.unfinished:
            lines.append(f"warning: {previous.unfinished}")
    elif scene["initial"]["from_run"] is not None:
        lines.append(f"starts from: {scene['initial']['from_run']}, not there yet: run the "
                     "scene that writes it first")
    target = out if out is not None else Path(scene["outputs"]["directory"])
    problem = folder_problem(target) if comm.rank == 0 else None
    problem = comm.bcast(problem, root=0)
    if problem:
        what = "--out" if out is not None else f"{scene.source}: [outputs.directory]"
        raise OutputError(f"{what} {problem}")
    for line in lines:
        print_on_root(comm, line)
    scene_warnings(scene, comm)


def _check_lines(scene: Scene, ranks: int) -> list[str]:
    """What ``check`` prints for a valid scene: OK, the model, why, how it steps."""
    choice = choose_model(scene, ranks)
    lines = [f"{scene.source}: OK", f"model: {choice.model}", f"why: {choice.reason}"]
    if choice.model == "rod":
        from .scenes.builders import initial_centre_lines
        from .scenes.contact import contact_lines, touching
        from .scenes.physical import describe
        from .scenes.rules import rod_rotations_reason
        from .scenes.schema import UNITS
        system = None if scene["scene"]["units"] in (None, "SI") else \
            UNITS[scene["scene"]["units"]]
        for rod in scene.rods or [None]:          # [[rods]]: each rod's derived tensors
            own = rod.scene if rod else scene
            label = f"rod {rod.name}: " if rod else ""
            lines += [f"derived: {label}{line}"
                      for line in describe(own["material"]["derived"] or {}, system)]
        lines += kink_lines(scene)
        lines += [f"joint: {j.kind} {j.rods[0]}-{j.rods[1]} at {list(j.point)}"
                  + (f" about {list(j.axis)}" if j.axis is not None else "")
                  for j in scene.joints]
        lines.append(f"rotations: {rod_rotations_reason(scene)}")
        lines += contact_lines(scene, initial_centre_lines(scene)) if touching(scene) else []
    if choice.model != "ode":                      # (the ODE prints its own solution)
        from .scenes.rules import time_stepping
        lines.append(f"time stepping: {time_stepping(scene)}")
    return lines


def kink_lines(scene: Scene) -> list[str]:
    """``check``'s line for each rod whose stress-free polyline is split at its corners
    into rigidly joined pieces (rod/kinks.py): where, and the pieces' cells."""
    from .rod.kinks import describe
    from .rod.start import curve
    lines = []
    for rod in scene.rods or [None]:
        geo = (rod.scene if rod else scene)["geometry"]
        said = describe(f"rod {rod.name!r}" if rod else "the rod",
                        curve(geo["reference_shape"]), geo["length"], geo["n_cells"])
        lines += [f"kinks: {said}"] if said else []
    return lines


def main(argv: list[str] | None = None) -> int:
    """The command line; every error ends every rank: expected ones (a bad scene or
    folder) with exit 2, collectively where every rank saw them, else by the rank that
    saw one leaving with exit 2 (mpi.alone, mpi.leave); anything else by MPI_Abort after its
    traceback.  The arguments are parsed first: ``--help``, ``--version`` and a usage error
    end before MPI_Init (0.15-0.2 s of their time)."""
    args = _parser().parse_args(argv)
    from mpi4py import MPI

    from .fit.inputs import FitInputError
    from .mpi import alone, leave
    from .output.run_folders import OutputError
    comm = MPI.COMM_WORLD
    guard = comm.Dup() if comm.size > 1 else None    # for mpi.alone only
    try:
        return _main(args, comm)
    except (SceneError, OutputError, FitInputError) as err:
        if alone(guard):
            print(f"error: {err} (seen on rank {comm.rank} only)", file=sys.stderr, flush=True)
            leave(2)                               # the other ranks may wait in a collective
        print_on_root(comm, f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:                      # Ctrl-C before the run loop
        if alone(guard):    # the signal reached the other ranks in a collective, or not
            print(f"interrupted (rank {comm.rank}; the other ranks were not, or were "
                  "waiting for it)", file=sys.stderr, flush=True)
            leave(130)      # (a return would wait for them in MPI_Finalize for ever)
        print_on_root(comm, "interrupted", file=sys.stderr)
        return 130
    except Exception:
        if comm.size == 1:
            raise
        import traceback
        print(f"rank {comm.rank}: {traceback.format_exc()}", file=sys.stderr, flush=True)
        comm.Abort(1)                              # the other ranks may wait in a collective
        return 1


def _main(args: argparse.Namespace, comm) -> int:
    from .fit.command import fit_command
    from .scenes import load_scene
    if args.command == "schema":
        print_on_root(comm, schema_markdown())
        return 0
    if args.command == "fit":
        return fit_command(args, comm)
    if args.command == "plot":
        from .output.redraw import redraw
        with warnings.catch_warnings(record=True) as notes:   # a deprecated column name
            warnings.simplefilter("always", DeprecationWarning)
            try:
                written = redraw(args.folder, args.quantities, args.color, args.to) \
                    if comm.rank == 0 else []
            finally:                  # also before an error that names the new name
                for note in notes:
                    print(f"warning: {note.message}", file=sys.stderr)
        for path in written:
            print(f"wrote {path}")
        return 0
    scene = agree(comm, lambda: load_scene(args.scene, overrides(args.scene, args.set)),
                  (SceneError,))
    if args.command == "check":
        _check(scene, args.out, comm)
        return 0
    if args.command in ANALYSES:
        if args.count < 1:
            raise SceneError(str(args.scene), "", f"--count: a positive integer, got "
                                                  f"{args.count}")
        summary = analyse(scene, args.command, count=args.count, out=args.out, comm=comm,
                          overwrite=args.overwrite, quiet=args.quiet).summary
        return _exit_status(summary)
    if args.resume and args.out is None:
        raise SceneError(str(args.scene), "", "--resume needs --out (the run folder)")
    summary = run(scene, out=args.out, comm=comm, resume=args.resume, quiet=args.quiet,
                  overwrite=args.overwrite).summary
    return _exit_status(summary)


def _exit_status(summary: dict) -> int:
    if summary["pictures"] == "interrupted" and summary["status"] != "failed":
        return 130
    return {"completed": 0, "stopped": 0, "interrupted": 130,
            "completed (unstable equilibrium)": 4}.get(summary["status"], 3)


if __name__ == "__main__":
    sys.exit(main())
