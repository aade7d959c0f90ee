"""dolfin_rod against PyElastica on cosseratbench's four validation experiments (issue 25
item 7) and its contact experiments crossing, capstan and pile (issue 26 item 9): each solver through cosseratbench's own ``experiment.run`` (a warm-up run first,
then the timed run; its metrics), the same elements per rod for both, every default of
both adapters.  Prints a markdown table of the metrics and the wall-time ratio
PyElastica / dolfin_rod, saves results/bench/<--out>.json.

    ./rodenv python3 benchmarks/cosseratbench_peer.py            # 20 elements per rod
    ./rodenv python3 benchmarks/cosseratbench_peer.py --n 50     # cosseratbench's default
    ./rodenv python3 benchmarks/cosseratbench_peer.py --n 0 --experiments crossing capstan \
        pile --out cosseratbench_contact  # each at cosseratbench's own resolution
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from cosseratbench import registry
from cosseratbench.experiment import run

EXPERIMENTS = ("cantilever", "catenary", "pendulum", "twist")    # the default
CONTACT = ("crossing", "capstan", "pile")
SOLVERS = ("pyelastica", "dolfin_rod")
ROOT = Path(__file__).resolve().parents[1]


def load(solver: str):
    """The solver's adapter: PyElastica's from cosseratbench's registry, dolfin_rod's
    directly (the same class its entry point names; tests/test_cosseratbench.py)."""
    if solver == "dolfin_rod":
        from dolfin_rod import cosseratbench
        return cosseratbench.DolfinRodSolver()
    return registry.load_solver(solver)


def measure(n: int, experiments) -> list[dict]:
    rows = []
    for name in experiments:
        experiment = registry.load_experiment(name)
        cells = n or experiment.n_elements
        for solver in SOLVERS:
            result = run(experiment, load(solver), n_elements=cells)
            rows.append({"experiment": name, "solver": solver, "n_elements": cells,
                         "load": os.getloadavg()[0], "outcome": result.outcome, "failure": result.failure,
                         "missing": list(result.missing), "wall_time": result.wall_time,
                         "metrics": dict(result.metrics),
                         "observations": dict(result.observations),
                         "settings": {k: v for k, v in result.settings.items()
                                      if isinstance(v, (int, float, str))}})
            print(f"{name:10s} {solver:10s} {result.outcome:9s} wall {result.wall_time or 0:8.3f} s"
                  f" (load {os.getloadavg()[0]:.1f})  {dict(result.metrics)}", flush=True)
    return rows


def table(rows: list[dict], experiments) -> str:
    """Markdown: per experiment and metric both solvers' values (metrics and cosseratbench's
    observations), and the wall-time ratio; an outcome other than completed as such."""
    out = ["| experiment | metric | PyElastica | dolfin_rod |", "|---|---|---|---|"]
    for name in experiments:
        by = {r["solver"]: r for r in rows if r["experiment"] == name}
        if any(by[s]["outcome"] != "completed" for s in SOLVERS):
            out.append(f"| {name} | outcome | " + " | ".join(
                by[s]["outcome"] + "".join(f": {m}" for m in by[s]["missing"])
                for s in SOLVERS) + " |")
            continue
        for metric in [*by["dolfin_rod"]["metrics"], "max_penetration", "max_rod_overlap"]:
            values = [{**by[s]["observations"], **by[s]["metrics"]}.get(metric)
                      for s in SOLVERS]
            out.append(f"| {name} | {metric} | " + " | ".join(
                "-" if v is None or v != v else f"{v:.3g}" for v in values) + " |")
        walls = [by[s]["wall_time"] for s in SOLVERS]
        ratio = walls[0] / walls[1] if all(walls) else float("nan")
        out.append(f"| {name} | wall time (s) | {walls[0]:.3g} | {walls[1]:.3g} "
                   f"(PyElastica / dolfin_rod = {ratio:.3g}x) |")
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20,
                        help="elements per rod (0: each experiment's own default)")
    parser.add_argument("--out", default="cosseratbench_peer")
    parser.add_argument("--experiments", nargs="+", default=EXPERIMENTS,
                        choices=EXPERIMENTS + CONTACT)
    args = parser.parse_args()
    rows = measure(args.n, args.experiments)
    text = table(rows, args.experiments)
    print(text)
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{args.out}.json").write_text(json.dumps({"rows": rows, "table": text},
                                                        indent=1, default=str))


if __name__ == "__main__":
    main()
