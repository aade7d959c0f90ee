"""Peer comparison with PyElastica: its continuum flagella (examples/ContinuumFlagellaCase,
Gazzola et al., R. Soc. open sci. 2018, section 5.2.1) against
scenes/continuum_flagella.toml, the same rod, muscle wave and slender-body fluid drag
(docs/rod.md, "Fluid drag"; docs/gallery.md, "Coming from PyElastica").

The measure is the flagellum's average forward speed, as for the snake
(benchmarks/snake_peer.py): the displacement of its centre of mass from t = 2 T (after
the muscle's ramp, T = 1 s) to the last whole period, over that time, its forward (+z)
and lateral (x) parts.  Each code at two time steps, to show its speed converged in dt:

    PyElastica 1.0  its example as written (the coefficients of its fallback, without
                    optimized_coefficients.txt): 50 elements, PositionVerlet, dt = 1e-4
                    and 5e-5, SlenderBodyTheory with mu = 1e4 Pa s,
                    AnalyticalLinearDamper 0.625 (here: PyElastica's API driven by this
                    script, not its example file)
    dolfin_rod      scenes/continuum_flagella.toml (50 cells, generalized-alpha on the
                    rotation group), dt = 4e-3 and 2e-3

``--periods N`` (default 10.01, PyElastica's); ``--quick``: 4 periods; ``--cells N``
(default 50, the example's) for both; ``--dt``, ``--peer-dt`` the time steps.  Prints the
JSON and writes results/bench/flagella_peer.json (``--out`` another name).
"""

from __future__ import annotations

import argparse
import json
from time import perf_counter
from pathlib import Path

import numpy as np

from snake_peer import scene_speeds, speeds

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "continuum_flagella.toml"
PERIOD, LENGTH, RADIUS, WAVE_LENGTH = 1.0, 1.0, 0.025, 0.38
SPLINE = np.array([0.0, 17.4, 48.5, 5.4, 14.7, 0.0])


def pyelastica(dt: float, t_end: float, cells: int = 50) -> dict:
    """PyElastica's continuum flagella, the example's parameters (``cells`` elements); the
    centre of mass every 0.01 s."""
    import elastica as ea

    class Flagella(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping,
                   ea.CallBacks):
        pass

    sim = Flagella()
    E = 1e7
    rod = ea.CosseratRod.straight_rod(cells, np.zeros(3), np.array([0.0, 0.0, 1.0]),
                                      np.array([0.0, 1.0, 0.0]), LENGTH, RADIUS, 1000.0,
                                      youngs_modulus=E, shear_modulus=E / 1.5)
    sim.append(rod)
    sim.add_forcing_to(rod).using(
        ea.MuscleTorques, base_length=LENGTH, b_coeff=SPLINE, period=PERIOD,
        wave_number=2 * np.pi / WAVE_LENGTH, phase_shift=0.0, rest_lengths=rod.rest_lengths,
        ramp_up_time=PERIOD, direction=np.array([0.0, 1.0, 0.0]), with_spline=True)
    viscosity = LENGTH**2 / (PERIOD * 1e-4)       # fluid density 1, Reynolds number 1e-4
    sim.add_forcing_to(rod).using(ea.SlenderBodyTheory, dynamic_viscosity=viscosity)
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, damping_constant=0.625, time_step=dt)
    record: dict = {"time": [], "com": []}
    every = max(1, int(round(0.01 / dt)))

    class Record(ea.CallBackBaseClass):
        def make_callback(self, system, time, current_step):
            if current_step % every == 0:
                record["time"].append(time)
                record["com"].append(system.compute_position_center_of_mass().copy())

    sim.collect_diagnostics(rod).using(Record)
    sim.finalize()
    start = perf_counter()
    ea.integrate(ea.PositionVerlet(), sim, t_end, int(round(t_end / dt)), progress_bar=False)
    wall = perf_counter() - start
    t, com = np.array(record["time"]), np.array(record["com"])
    return {"code": "PyElastica", "dt": dt, "cells": cells, "wall_s": wall,
            **speeds(t, com, t_end, PERIOD)}


def dolfin_rod(dt: float, t_end: float, out: Path, cells: int = 50) -> dict:
    """scenes/continuum_flagella.toml at dt on ``cells`` cells."""
    return {"code": "dolfin_rod", "dt": dt, "cells": cells, **scene_speeds(
        SCENE, {"time.dt": dt, "geometry.n_cells": cells}, t_end, PERIOD, out)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--periods", type=float, default=10.01)
    parser.add_argument("--quick", action="store_true", help="4 periods")
    parser.add_argument("--dt", type=float, nargs="*", default=[4e-3, 2e-3],
                        help="dolfin_rod's time steps")
    parser.add_argument("--peer-dt", type=float, nargs="*", default=[1e-4, 5e-5],
                        help="PyElastica's time steps")
    parser.add_argument("--cells", type=int, default=50, help="elements or cells (both)")
    parser.add_argument("--codes", nargs="*", default=["pyelastica", "dolfin_rod"])
    parser.add_argument("--out", default="flagella_peer")
    args = parser.parse_args()
    t_end = PERIOD * (4.01 if args.quick else args.periods)
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    if "pyelastica" in args.codes:
        rows += [pyelastica(dt, t_end, args.cells) for dt in args.peer_dt]
    if "dolfin_rod" in args.codes:
        rows += [dolfin_rod(dt, t_end, folder / "flagella_runs", args.cells)
                 for dt in args.dt]
    report = {"t_end": t_end, "runs": rows}
    peers = [r for r in rows if r["code"] == "PyElastica"]
    ours = [r for r in rows if r["code"] == "dolfin_rod" and "speed" in r]
    if peers and ours:
        report["ratio_forward"] = ours[-1]["forward"] / peers[-1]["forward"]
    text = json.dumps(report, indent=1)
    print(text)
    (folder / f"{args.out}.json").write_text(text + "\n")


if __name__ == "__main__":
    main()
