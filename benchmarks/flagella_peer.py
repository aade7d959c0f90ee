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

from pathlib import Path

import numpy as np

from snake_peer import bench_folder, peer_parser, pyelastica_speeds, scene_speeds, write_report

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
    return {"code": "PyElastica", "dt": dt, "cells": cells,
            **pyelastica_speeds(sim, rod, dt, t_end, PERIOD)}


def dolfin_rod(dt: float, t_end: float, out: Path, cells: int = 50) -> dict:
    """scenes/continuum_flagella.toml at dt on ``cells`` cells."""
    return {"code": "dolfin_rod", "dt": dt, "cells": cells, **scene_speeds(
        SCENE, {"time.dt": dt, "geometry.n_cells": cells}, t_end, PERIOD, out)}


def main() -> None:
    parser = peer_parser(__doc__, 10.01, "flagella_peer")
    parser.add_argument("--dt", type=float, nargs="*", default=[4e-3, 2e-3],
                        help="dolfin_rod's time steps")
    parser.add_argument("--peer-dt", type=float, nargs="*", default=[1e-4, 5e-5],
                        help="PyElastica's time steps")
    parser.add_argument("--cells", type=int, default=50, help="elements or cells (both)")
    args = parser.parse_args()
    t_end, folder, rows = PERIOD * (4.01 if args.quick else args.periods), bench_folder(), []
    if "pyelastica" in args.codes:
        rows += [pyelastica(dt, t_end, args.cells) for dt in args.peer_dt]
    if "dolfin_rod" in args.codes:
        rows += [dolfin_rod(dt, t_end, folder / "flagella_runs", args.cells)
                 for dt in args.dt]
    write_report(rows, t_end, folder / f"{args.out}.json")


if __name__ == "__main__":
    main()
