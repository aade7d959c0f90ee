"""``dolfin-rod fit SCENE.toml DATA.csv --params alpha_d,mu_d [--out DIR]``: the command
of the fit (its arguments are parsed in cli.py).  Prints the table (value, standard
error, initial), writes ``fit.json`` (least_squares.FitResult.to_dict) and ``fit.png``
(data and fitted curve, residuals) in DIR (default: a new
<outputs.directory>/fit-<name>-<time>).

Exit status: 0 a fit was made (its status, "identified", "not identifiable" or "not
converged", is printed and in fit.json), 2 bad input (scene, CSV, parameter, folder: one
line, before any model runs, nothing written), 3 the model fails at the initial
parameters.  Under MPI every rank reads the same validated input (the CSV is read on
rank 0) and takes the same steps; only rank 0 prints and writes.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from .least_squares import FitError, FitResult, prepare_fit, run_fit
from .inputs import FitInputError, read_series

__all__ = ["FitInputError", "fit_command", "result_table"]


def fit_command(args, comm) -> int:
    """Run ``dolfin-rod fit``; SceneError/OutputError/FitInputError propagate (exit 2)."""
    from ..mpi import agree, print_on_root
    from ..output.run_folders import on_root
    from ..scenes import SceneError, load_scene
    scene = agree(comm, lambda: load_scene(args.scene), (SceneError,))
    data = _read_on_root(args.data, comm)
    problem = agree(comm, lambda: prepare_fit(scene, data, args.params, comm),
                    (SceneError, FitInputError))
    folder = _fit_folder(scene, args.out, comm)
    say = (lambda *a: None) if args.quiet else (lambda *a: print_on_root(comm, *a))
    say(f"model: {problem.choice.model} ({problem.choice.reason})")
    say(f"data: {problem.experiment.description}; {int(problem.used.sum())} rows")
    if not args.quiet:
        problem.progress = _progress_lines(comm)
    try:
        result = run_fit(problem)
    except FitError as err:
        print_on_root(comm, f"failed: {err}", file=sys.stderr)
        return 3
    say(result_table(result))
    on_root(comm, lambda: _write(folder, result, scene.name), f"cannot write to {folder}")
    line = f"{result.status}: results in {folder}"
    print_on_root(comm, line + (f" ({result.message})" if result.message else ""))
    return 0


PROGRESS_SECONDS = 2.0     # at most one progress line per this many seconds


def _progress_lines(comm):
    """progress(evaluations, rms) printing "model run N: rms residual R" on stderr, the
    first one and then at most every PROGRESS_SECONDS."""
    import time
    last = [-math.inf]

    def progress(evaluations: int, rms: float) -> None:
        now = time.monotonic()
        if now - last[0] >= PROGRESS_SECONDS:
            last[0] = now
            from ..mpi import print_on_root
            print_on_root(comm, f"model run {evaluations}: rms residual {rms:.4g}",
                          file=sys.stderr)
    return progress


def _read_on_root(path: Path, comm):
    """The CSV read and checked on rank 0; its FitInputError raised on every rank."""
    data, error = None, None
    if comm.rank == 0:
        try:
            data = read_series(path)
        except FitInputError as err:
            error = str(err)
    data, error = comm.bcast((data, error), root=0)
    if error is not None:
        raise FitInputError(error)
    return data


def _fit_folder(scene, out: Path | None, comm) -> Path:
    from ..output.run_folders import new_run_folder, on_root, prepare_run_folder
    if out is None:
        parent = Path(scene["outputs"]["directory"])
        return Path(on_root(comm, lambda: str(new_run_folder(parent, f"fit-{scene.name}")),
                            f"cannot create a results folder in {parent}"))
    on_root(comm, lambda: prepare_run_folder(out, False, False, "give a new or empty folder "
                                             "(fit has no --resume or --overwrite)"),
            f"cannot use --out {out}")
    return out


def result_table(result: FitResult) -> str:
    """The parameters as a text table: value, standard error, initial value."""
    width = max(9, *(len(n) for n in result.parameters))
    lines = [f"{'parameter':<{width}}  {'value':>12}  {'std error':>10}  {'initial':>10}"]
    for name, v, e, p0 in zip(result.parameters, result.values, result.std_errors,
                              result.initial):
        value = "not ident." if v is None else f"{v:12.6g}"
        error = "-" if e is None else f"{e:10.3g}"
        lines.append(f"{name:<{width}}  {value:>12}  {error:>10}  {p0:10.4g}")
    lines.append(f"residual std s = {result.residual_std:.4g} over {result.n_data} rows, "
                 f"{result.evaluations} model runs")
    if result.combination:
        lines.append(f"identifiable combination: {result.combination}")
    return "\n".join(lines)


def _write(folder: Path, result: FitResult, name: str) -> None:
    (folder / "fit.json").write_text(json.dumps(result.to_dict(), indent=1) + "\n")
    plot_fit(result, folder / "fit.png", name)


def plot_fit(result: FitResult, path: Path, title: str) -> None:
    """Data and fitted curve over time, and the residuals below."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(6.4, 5.2), sharex=True,
                                      gridspec_kw={"height_ratios": (3, 1)})
    top.plot(result.times, result.data, ".", ms=4, color="0.4", label="data")
    top.plot(result.times, result.fitted, "-", color="C0", label=f"fit ({result.model} model)")
    top.set_ylabel(result.experiment.split("response: ")[-1])
    top.set_title(f"{title}: {result.status}")
    for n, v, e in zip(result.parameters, result.values, result.std_errors):
        top.plot([], [], " ", label=f"{n} = {v:.4g} ± {e:.2g}" if v is not None
                 else f"{n}: not identifiable")
    top.legend(loc="best")
    bottom.plot(result.times, result.data - result.fitted, ".", ms=3, color="C3")
    bottom.axhline(0.0, color="0.5", lw=0.8)
    bottom.set_xlabel("time")
    bottom.set_ylabel("residual")
    from ..output.plots import save_laid_out
    save_laid_out(fig, path, dpi=120)
    plt.close(fig)
