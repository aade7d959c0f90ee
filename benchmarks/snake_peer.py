"""Peer comparison with PyElastica: its continuum snake (examples/ContinuumSnakeCase,
after Zhang et al., Nat. Comm. 2021) against scenes/continuum_snake.toml, the same rod,
muscle wave and directional friction (docs/scenes.md, "Coming from PyElastica").

The measure is the snake's average forward speed: the displacement of its centre of
mass from t = 2 T (after the muscle's ramp, T = 2 s the wave's period) to the last whole
period, over that time (PyElastica's own measure averages the centre of mass's velocity
from 2 T on, projected on the mean direction of travel: over whole periods the same
number), its forward (+z) and lateral (x) parts.  Each code at two time steps, to show
its speed converged in dt:

    PyElastica 1.0  its example as written: 50 elements, PositionVerlet, dt = 1e-4 and
                    5e-5, its RodPlaneContactWithAnisotropicFriction (1.0's name of the
                    AnisotropicFrictionalPlane) with k = 1, nu = 1e-6, slip tolerance
                    1e-8 with static coefficients 0, AnalyticalLinearDamper 2e-3 (here:
                    PyElastica's API driven by this script, not its example file)
    dolfin_rod      scenes/continuum_snake.toml (50 cells, generalized-alpha on the
                    rotation group), dt = 2e-3 and 1e-3, slip tolerance 1e-3 m/s and
                    (--eps) others: the smoothed Coulomb law's scale

``--periods N`` (default 11, PyElastica's 11.01 periods); ``--quick``: 4 periods.  Prints
the JSON and writes results/bench/snake_peer.json.
"""

from __future__ import annotations

import argparse
import json
from time import perf_counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "continuum_snake.toml"
PERIOD, LENGTH, G = 2.0, 0.35, 9.80665
SPLINE = np.array([3.4e-3, 3.3e-3, 4.2e-3, 2.6e-3, 3.6e-3, 3.5e-3])


def speeds(t: np.ndarray, com: np.ndarray, t_end: float, period: float = PERIOD) -> dict:
    """Average speed of the centre of mass over [2 T, the last whole period <= t_end] (T
    the wave's ``period``): its size, forward (+z) and lateral (x) parts."""
    t0, t1 = 2 * period, period * np.floor(t_end / period + 1e-9)
    a, b = (int(np.argmin(np.abs(t - s))) for s in (t0, t1))
    shift = (com[b] - com[a]) / (t[b] - t[a])
    return {"speed": float(np.linalg.norm(shift[[0, 2]])), "forward": float(shift[2]),
            "lateral": float(shift[0]), "window": [float(t[a]), float(t[b])]}


def pyelastica(dt: float, t_end: float) -> dict:
    """PyElastica's continuum snake, the example's parameters; the centre of mass every
    0.01 s."""
    import elastica as ea

    class Snake(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping,
                ea.CallBacks, ea.Contact):
        pass

    sim = Snake()
    radius, E = LENGTH * 0.011, 1e6
    rod = ea.CosseratRod.straight_rod(50, np.zeros(3), np.array([0.0, 0.0, 1.0]),
                                      np.array([0.0, 1.0, 0.0]), LENGTH, radius, 1000.0,
                                      youngs_modulus=E, shear_modulus=E / 1.5)
    sim.append(rod)
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([0.0, -G, 0.0]))
    sim.add_forcing_to(rod).using(
        ea.MuscleTorques, base_length=LENGTH, b_coeff=SPLINE, period=PERIOD,
        wave_number=2 * np.pi, phase_shift=0.0, rest_lengths=rod.rest_lengths,
        ramp_up_time=PERIOD, direction=np.array([0.0, 1.0, 0.0]), with_spline=True)
    mu = LENGTH / (PERIOD**2 * G * 0.1)
    ground = ea.Plane(plane_origin=np.array([0.0, -radius, 0.0]),
                      plane_normal=np.array([0.0, 1.0, 0.0]))
    sim.append(ground)
    sim.detect_contact_between(rod, ground).using(
        ea.RodPlaneContactWithAnisotropicFriction, k=1.0, nu=1e-6,
        slip_velocity_tol=1e-8, static_mu_array=np.zeros(3),
        kinetic_mu_array=np.array([mu, 1.5 * mu, 2.0 * mu]))
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, damping_constant=2e-3, time_step=dt)
    return {"code": "PyElastica", "dt": dt, **pyelastica_speeds(sim, rod, dt, t_end, PERIOD)}


def pyelastica_speeds(sim, rod, dt: float, t_end: float, period: float) -> dict:
    """PyElastica's ``sim`` run to t_end by PositionVerlet, the centre of mass of ``rod``
    recorded every 0.01 s: the time loop's wall time and the speeds."""
    import elastica as ea
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
    return {"wall_s": wall, **speeds(t, com, t_end, period)}


def dolfin_rod(dt: float, t_end: float, eps: float, out: Path) -> dict:
    """scenes/continuum_snake.toml at dt, slip tolerance eps."""
    return {"code": "dolfin_rod", "dt": dt, "eps": eps, **scene_speeds(
        SCENE, {"time.dt": dt, "contact.slip_tolerance": eps}, t_end, PERIOD, out)}


def scene_speeds(scene: Path, overrides: dict, t_end: float, period: float,
                 out: Path) -> dict:
    """A scene's run to t_end (``overrides``: more keys) and its speeds (the centre of
    mass every 0.01 s from rod.pvd, the trapezoidal rule of the P1 centre line: exact)
    and the wall time of its time loop; its status and message if it did not complete."""
    from dolfin_rod import read_pvd, run
    every = max(1, int(round(0.01 / overrides["time.dt"])))
    result = run(str(scene), {"time.t_end": t_end, **overrides, "outputs.every": every,
                              "outputs.animation": False, "outputs.plots": False,
                              "outputs.directory": str(out), "outputs.progress": False},
                 quiet=True)
    if result.status != "completed":
        return {"status": result.status, "message": result.summary.get("message")}
    steps = read_pvd(result.folder / "rod.pvd")
    t = np.array([s["time"] for s in steps])
    com = np.array([centre(s["points"]) for s in steps])
    wall = json.loads((result.folder / "timings.json").read_text())["integration"]
    return {"wall_s": wall, **speeds(t, com, t_end, period)}


def centre(points: np.ndarray) -> np.ndarray:
    """The mean of the P1 centre line over its length (nodes equally spaced along s)."""
    w = np.ones(len(points))
    w[[0, -1]] = 0.5
    return w @ points / w.sum()


def peer_parser(doc: str, periods: float, out: str) -> argparse.ArgumentParser:
    """The peer benchmarks' common options: --periods, --quick (4 periods), --codes,
    --out (the JSON's name in results/bench/)."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("--periods", type=float, default=periods)
    parser.add_argument("--quick", action="store_true", help="4 periods")
    parser.add_argument("--codes", nargs="*", default=["pyelastica", "dolfin_rod"])
    parser.add_argument("--out", default=out)
    return parser


def main() -> None:
    parser = peer_parser(__doc__, 11.01, "snake_peer")
    parser.add_argument("--eps", type=float, nargs="*", default=[1e-3])
    args = parser.parse_args()
    t_end, folder, rows = PERIOD * (4.01 if args.quick else args.periods), bench_folder(), []
    if "pyelastica" in args.codes:
        rows += [pyelastica(dt, t_end) for dt in (1e-4, 5e-5)]
    if "dolfin_rod" in args.codes:
        rows += [dolfin_rod(dt, t_end, eps, folder / "snake_runs")
                 for eps in args.eps for dt in (2e-3, 1e-3)]
    write_report(rows, t_end, folder / f"{args.out}.json")


def bench_folder() -> Path:
    """results/bench/, made if missing."""
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def write_report(rows: list, t_end: float, path: Path) -> None:
    """The runs as JSON, printed and written to ``path``, with the ratio of the forward
    speeds of the last dolfin_rod run that completed and the last PyElastica run."""
    report = {"t_end": t_end, "runs": rows}
    peers = [r for r in rows if r["code"] == "PyElastica"]
    ours = [r for r in rows if r["code"] == "dolfin_rod" and "speed" in r]
    if peers and ours:
        report["ratio_forward"] = ours[-1]["forward"] / peers[-1]["forward"]
    text = json.dumps(report, indent=1)
    print(text)
    path.write_text(text + "\n")


if __name__ == "__main__":
    main()
