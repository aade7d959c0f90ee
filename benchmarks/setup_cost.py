"""Benchmark (not a test): what a user waits for around the time loop (issue 30, targets
1 and 3).

1. Set-up of a second model of the same structure in a process: the gravity-cantilever
   rod of benchmarks/cantilever.py ("elastic") built as a user would (``RodModel(...)``,
   ``set_initial_state()``, ``TimeStepper(model.problem)`` and its step forms) at 8, 16,
   32, 64 cells after a first model, median of --repeats (and the least: the cost with
   the least disturbance from other users of a shared machine); model and stepper apart; in
   a new process (twice, alternating with --baseline DIR, a folder holding an older
   dolfin_rod package, so that both see the same load).
2. The first model in a new process, by parts: ``import dolfin_rod`` and DOLFINx, the
   model, the initial state, the stepper (warm FFCx and form caches).
3. Process start to exit: ``python3 -c "import dolfin_rod"`` (a lazy package: it
   imports no DOLFINx), the import of the finite-element stack a run makes
   (``run.import_finite_elements``), ``python3 -c "import dolfin_rod, dolfinx.fem.petsc"``
   (the compute stack: the honest baseline of target 3), ``dolfin-rod --help``,
   ``dolfin-rod check`` and ``dolfin-rod run scenes/gravity_cantilever.toml`` (into a
   temporary folder; its timings.json gives the run's integration and pictures), median
   of --repeats each, for this tree and the --baseline alternating; target 3's ratio
   run / (2 import + integration) with each import; with --baseline, the paired ratios
   (this tree over the baseline, repeat by repeat, median) of wall and CPU time.

Prints the medians and the machine's load, writes results/bench/setup_cost.json.

    ./rodenv python3 benchmarks/setup_cost.py [--repeats 3] [--baseline scratch/base]
                                              [--second-only | --processes-only]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "gravity_cantilever.toml"
CELLS = (8, 16, 32, 64)

FIRST_MODEL = """
import json, sys, time
t0 = time.perf_counter()
import dolfinx, dolfin_rod
from dolfin_rod import TimeStepper
sys.path.insert(0, sys.argv[1])
import cantilever as cant
t1 = time.perf_counter()
from mpi4py import MPI
from dolfin_rod import RodModel
params, name, loads = cant.dolfin_rod_parameters(cant.SCENES["elastic"])
model = RodModel(params, n_cells=16, model=name, variant="local", start="clamped", end="free",
                 distributed_loads=loads, comm=MPI.COMM_WORLD)
t2 = time.perf_counter()
model.set_initial_state()
t3 = time.perf_counter()
stepper = TimeStepper(model.problem)
stepper.compile()
t4 = time.perf_counter()
print(json.dumps({"imports_s": t1 - t0, "model_s": t2 - t1, "initial_state_s": t3 - t2,
                  "stepper_s": t4 - t3, "total_s": t4 - t0}))
"""


SECOND_MODEL = """
import json, statistics, sys, time
sys.path.insert(0, sys.argv[1])
import cantilever as cant
from dolfin_rod import TimeStepper


def second_model(n_cells):
    t0 = time.perf_counter()
    model = cant.dolfin_rod_model(n_cells, "elastic")
    t1 = time.perf_counter()
    TimeStepper(model.problem).compile()
    t2 = time.perf_counter()
    return {"model_s": t1 - t0, "stepper_s": t2 - t1, "total_s": t2 - t0}


second_model(16)                                  # the first model of the structure
out = {}
for n in map(int, sys.argv[3:]):
    runs = [second_model(n) for _ in range(int(sys.argv[2]))]
    out[n] = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    out[n]["least_total_s"] = min(r["total_s"] for r in runs)
print(json.dumps(out))
"""


def second_models(package_folder: Path, repeats: int) -> dict:
    """Seconds to build model (with its initial state) and stepper of the elastic
    cantilever in a process that built one of its structure before (median of
    ``repeats`` per cell count), importing dolfin_rod from ``package_folder``."""
    env = {**os.environ, "PYTHONPATH": str(package_folder)}
    out = subprocess.run([sys.executable, "-c", SECOND_MODEL, str(ROOT / "benchmarks"),
                          str(repeats), *map(str, CELLS)], env=env, capture_output=True,
                         text=True, check=True, cwd="/")
    return json.loads(out.stdout.strip().splitlines()[-1])


def process_seconds(command: list[str], package_folder: Path) -> float:
    """Wall seconds from starting ``command`` to its exit (it must succeed), importing
    dolfin_rod from ``package_folder``."""
    env = {**os.environ, "PYTHONPATH": str(package_folder)}
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, cwd="/", env=env)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({done.returncode}):\n{done.stderr}")
    return time.perf_counter() - start


def cpu_seconds() -> float:
    """User + system CPU seconds of this process's finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def median_of(runs: list[dict]) -> dict:
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--baseline", type=Path, help="folder holding an older dolfin_rod"
                        " (e.g. git archive COMMIT dolfin_rod | tar -x -C scratch/base)")
    parser.add_argument("--second-only", action="store_true",
                        help="measure the second models only (parts 2 and 3 skipped)")
    parser.add_argument("--processes-only", action="store_true",
                        help="measure the processes of part 3 only")
    args = parser.parse_args()
    load = [os.getloadavg()[0]]
    variants = {"this tree": ROOT}
    if args.baseline:
        variants = {"baseline": args.baseline.resolve(), **variants}
    if args.processes_only:
        out = {"load_average_1min": load, "repeats": args.repeats,
               "processes": processes_of(variants, args.repeats)}
        load.append(os.getloadavg()[0])
        save(out, load)
        return
    rounds = [{name: second_models(folder, args.repeats) for name, folder in variants.items()}
              for _ in range(2)]                      # alternated: both see the same load
    second_all = {name: {n: {**median_of([r[name][n] for r in rounds]),
                             "least_total_s": min(r[name][n]["least_total_s"] for r in rounds)}
                         for n in rounds[0][name]} for name in variants}
    out = {"load_average_1min": load, "repeats": args.repeats,
           "second_model": second_all}
    print_second(second_all)
    if args.second_only:
        load.append(os.getloadavg()[0])
        save(out, load)
        return
    first = median_of([json.loads(subprocess.run(
        [sys.executable, "-c", FIRST_MODEL, str(Path(__file__).resolve().parent)],
        check=True, capture_output=True, text=True, cwd="/").stdout)
        for _ in range(args.repeats)])
    load.append(os.getloadavg()[0])
    print("first model in a new process (s): " + ", ".join(
        f"{k} {v:.3f}" for k, v in first.items()))
    out["first_model_new_process"] = first
    out["processes"] = processes_of(variants, args.repeats)
    load.append(os.getloadavg()[0])
    save(out, load)


COMMANDS = {
    "python3 -c 'import dolfin_rod'": ["-c", "import dolfin_rod"],
    "import the finite-element stack": [
        "-c", "import basix.ufl, dolfinx.fem.petsc, ufl"],   # run.py's (no checkpoints)
    "python3 -c 'import dolfin_rod, dolfinx.fem.petsc'": [      # the compute stack: the
        "-c", "import dolfin_rod, dolfinx.fem.petsc"],            # honest baseline
    "dolfin-rod --help": ["-m", "dolfin_rod", "--help"],
    "dolfin-rod check": ["-m", "dolfin_rod", "check", str(SCENE)],
    "dolfin-rod run gravity_cantilever": ["-m", "dolfin_rod", "run", str(SCENE), "--quiet",
                                          "--out"],
}


def processes_of(variants: dict, repeats: int) -> dict:
    """Process start to exit of each command (median of ``repeats``, the variants
    alternating), the run's integration and pictures (its timings.json), and the ratio
    of target 3: run / (2 import + integration)."""
    seconds = {name: {c: [] for c in COMMANDS} for name in variants}
    cpu = {name: {c: [] for c in COMMANDS} for name in variants}
    timings = {name: [] for name in variants}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(repeats):
            for name, folder in variants.items():
                for command, argv in COMMANDS.items():
                    run_folder = Path(tmp) / f"{name}-{k}".replace(" ", "_")
                    extra = [str(run_folder)] if argv[-1] == "--out" else []
                    cpu_before = cpu_seconds()
                    seconds[name][command].append(process_seconds(
                        [sys.executable, *argv, *extra], folder))
                    cpu[name][command].append(cpu_seconds() - cpu_before)
                    if extra:
                        timings[name].append(json.loads(
                            (run_folder / "timings.json").read_text()))
    out = {}
    for name in variants:
        med = {c: statistics.median(v) for c, v in seconds[name].items()}
        med_cpu = {c: statistics.median(v) for c, v in cpu[name].items()}
        integration = statistics.median(t["integration"] for t in timings[name])
        pictures = statistics.median(t.get("pictures", 0.0) for t in timings[name])
        run_s = med["dolfin-rod run gravity_cantilever"]
        out[name] = {"seconds": seconds[name], "median_s": med, "cpu_s": cpu[name],
                     "median_cpu_s": med_cpu, "integration_s": integration,
                     "pictures_s": pictures,
                     "run_over_2_import_plus_integration": run_s / (
                         2 * med["python3 -c 'import dolfin_rod'"] + integration),
                     "run_over_2_stack_import_plus_integration": run_s / (
                         2 * med["import the finite-element stack"] + integration),
                     "run_over_2_compute_stack_plus_integration": run_s / (
                         2 * med["python3 -c 'import dolfin_rod, dolfinx.fem.petsc'"]
                         + integration)}
        if name != "baseline" and "baseline" in variants:
            out[name]["paired_over_baseline"] = paired_ratios(seconds, cpu, name)
        print(f"{name}: " + ", ".join(f"{c} {v:.2f} s (CPU {med_cpu[c]:.2f} s)"
                                      for c, v in med.items()))
        print(f"  run: integration {integration:.2f} s, pictures {pictures:.2f} s; "
              f"run / (2 import dolfin_rod + integration) = "
              f"{out[name]['run_over_2_import_plus_integration']:.2f}, run / (2 import of "
              f"the FE stack + integration) = "
              f"{out[name]['run_over_2_stack_import_plus_integration']:.2f}, run / (2 "
              f"import dolfin_rod, dolfinx.fem.petsc + integration) = "
              f"{out[name]['run_over_2_compute_stack_plus_integration']:.2f} (target <= 1)")
    return out


def paired_ratios(seconds: dict, cpu: dict, name: str) -> dict:
    """Per command, the median over the repeats of ``name``'s wall and CPU seconds over
    the baseline's of the same repeat (run next to each other: a load that drifts over
    the benchmark cancels)."""
    out = {}
    for c in COMMANDS:
        ratios = {kind: statistics.median(a / b for a, b in zip(of[name][c], of["baseline"][c]))
                  for kind, of in (("wall", seconds), ("cpu", cpu))}
        out[c] = ratios
        print(f"  {c}: {name} / baseline, paired medians: wall {ratios['wall']:.3f}, "
              f"CPU {ratios['cpu']:.3f}")
    return out


def print_second(second_all: dict) -> None:
    for name, second in second_all.items():
        print(f"second model of the structure, {name} (median, ms): " + ", ".join(
            f"n={n}: model {1e3 * v['model_s']:.1f} + stepper {1e3 * v['stepper_s']:.1f}"
            f" = {1e3 * v['total_s']:.1f} (least {1e3 * v['least_total_s']:.1f})"
            for n, v in second.items()))


def save(out: dict, load: list) -> None:
    print("load average (1 min):", " ".join(f"{a:.1f}" for a in load))
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "setup_cost.json").write_text(json.dumps(out, indent=1))
    print(f"wrote {folder / 'setup_cost.json'}")


if __name__ == "__main__":
    main()
