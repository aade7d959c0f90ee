"""Peer comparison with PyElastica 1.0 on its plectoneme case (issue 26).

PyElastica's `examples/RodContactCase/RodSelfContact/PlectonemesCase/plectoneme_case.py`:
a rod (L = 1 m, r = 25 mm, E = 1 MPa, G = E / 1.5, mass 1 kg) clamped at s = 0, its end
s = L free to slide along the axis (no tension) and turned about it at a constant rate,
10 turns over 50 s; `AnalyticalLinearDamper(damping_constant = 2)` (translational: a
drag 2 N s/m^2 per length, as the rod's mass per length is 1 kg/m; rotational: the
couple -2 w per length, numerically the same constant, PyElastica's issue 354); during
the twist the velocity of the middle node is lowered by 1e-4 m/s across the axis every
step: a force m_node 1e-4 / dt = 0.04 N (PyElastica's dt = 0.0025 L / n, m_node = 1/n
kg), the perturbation that picks the plectoneme's plane; `RodSelfContact(k = 1e4,
nu = 10)`; PositionVerlet.  (The example then holds the end for 50 s more; the twist
phase is what is compared here.)

dolfin_rod runs the same rod as a scene (drag = rotational_drag = 2, end_slide along
the axis, end_rotation a ramp, point_force 0.04 N at s = L/2 during the twist,
`contact.self` with the default barrier, generalized-alpha).

Accuracy: each code against its OWN converged reference (a finer run of the same code)
on the end torque (the twisting moment at the turned end) and the writhe (Gauss's
integral of the centre line closed along the axis, rod/linking.py, the same function
for both codes) at the sample times t = 1, 2, .., T:

    error = max(max_t |M - M_ref| / max_t |M_ref|,  max_t |Wr - Wr_ref| / max_t |Wr_ref|).

Wall time: the time loop (PyElastica: the stepping after `finalize` and a warm-up that
compiled numba; dolfin_rod: `run` of the scene after a first run that loaded the form
cache).  Speed-up at equal accuracy: log-log interpolation of wall time at the errors
PyElastica reaches (benchmarks/peer_pyelastica.time_at: where dolfin_rod's fastest run is
already more accurate, its time, so the ratio is a lower bound).

    --quick     T = 15 s (3 turns: the rod buckles, its first loop forms and closes on
                itself), PyElastica n = 19, 38, 75 (reference 150, the case's own),
                dolfin_rod n = 10, 20, 40 (reference 80); the full mode is the twist
                phase, T = 50 s, PyElastica 38, 75, 150 (300), dolfin_rod 32-96 (192)
Writes results/bench/<--out>.json (default peer_plectoneme[_quick]).
"""

from __future__ import annotations

import argparse
from importlib import metadata
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from peer_pyelastica import time_at  # noqa: E402

from dolfin_rod import linking, load_scene, run  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
L, RADIUS, E, G, MASS, NU = 1.0, 0.025, 1e6, 1e6 / 1.5, 1.0, 2.0
TURNS, T_TWIST = 10, 50.0
PERTURBATION = 0.04            # N: PyElastica's 1e-4 m/s per step on the middle node


def pyelastica_twist_writhe(rod, axis):
    """(Tw, Wr) of PyElastica's rod (rod/linking.clamped_rod_linking: the centre line
    closed along the axis, the ribbon of the directors d_1, the last one repeated at the
    end node): the writhe the dolfin_rod scene's time series has, by the same function."""
    d1 = rod.director_collection[0].T
    return linking.clamped_rod_linking(rod.position_collection.T, np.vstack([d1, d1[-1:]]),
                                       axis, axis)


# ---------------------------------------------------------------- PyElastica 1.0
def run_pyelastica(n, t_end, dt_factor=0.0025):
    """PyElastica's plectoneme case at n elements, dt = dt_factor L / n, up to t_end
    (<= 50 s, the twist phase); samples at whole seconds."""
    import elastica as ea

    class Case(ea.BaseSystemCollection, ea.Constraints, ea.Contact, ea.Forcing,
               ea.CallBacks, ea.Damping):
        pass

    dt = dt_factor * L / n
    steps = int(round(t_end / dt))
    dt = t_end / steps
    area = np.pi * RADIUS ** 2
    sim = Case()
    axis, normal = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    rod = ea.CosseratRod.straight_rod(n, np.zeros(3), axis, normal, L, RADIUS,
                                      MASS / (area * L), youngs_modulus=E, shear_modulus=G)
    rod.velocity_collection[2, n // 2] -= 1e-4
    sim.append(rod)
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, damping_constant=NU, time_step=dt)
    rate = 2 * np.pi * TURNS / T_TWIST

    class TwistEnd(ea.ConstraintBase):
        """The example's boundary condition during the twist: start clamped, end held
        across the axis, turned about it at `rate`, the middle node's velocity kick."""

        def constrain_values(self, system, time):
            pass

        def constrain_rates(self, system, time):
            system.velocity_collection[..., 0] = 0.0
            system.omega_collection[..., 0] = 0.0
            system.velocity_collection[0, -1] = 0.0
            system.velocity_collection[2, -1] = 0.0
            d = system.director_collection[..., -1] @ -axis
            system.omega_collection[..., -1] = -rate * d / np.linalg.norm(d)
            system.velocity_collection[2, system.n_elems // 2] -= 1e-4

    sim.constrain(rod).using(TwistEnd, constrained_position_idx=(0, -1),
                             constrained_director_idx=(0, -1))
    sim.detect_contact_between(rod, rod).using(ea.RodSelfContact, k=1e4, nu=10)
    samples = []
    every = int(round(1.0 / dt))

    class Sample(ea.CallBackBaseClass):
        def make_callback(self, system, time, current_step):
            if current_step % every == 0 and current_step > 0:
                samples.append((time, float(system.internal_couple[2, -1]),
                                *pyelastica_twist_writhe(system, axis)))

    sim.collect_diagnostics(rod).using(Sample)
    sim.finalize()
    stepper = ea.PositionVerlet()
    t, start = 0.0, time.perf_counter()
    for _ in range(steps):
        t = stepper.step(sim, t, dt)
    wall = time.perf_counter() - start
    t_s, torque, tw, wr = (np.array(c) for c in zip(*samples))
    return {"n": n, "dt": dt, "steps": steps, "wall_s": wall, "time": t_s.tolist(),
            "torque": torque.tolist(), "writhe": wr.tolist(),
            "linking_error": float(np.max(np.abs(tw + wr - TURNS * t_s / T_TWIST)))}


# ---------------------------------------------------------------- dolfin_rod
SCENE = ROOT / "benchmarks" / "plectoneme_case.toml"
QUIET_OUTPUTS = {"outputs.fields": False, "outputs.animation": False, "outputs.plots": False,
                 "outputs.progress": False}


def run_dolfin_rod(n, dt, t_end, out):
    """The scene at n cells and step dt up to t_end; samples at whole seconds; wall
    time of the time loop (timings.json's integration) and with set-up (total)."""
    every = max(1, int(round(1.0 / dt)))
    scene = load_scene(SCENE, {"geometry.n_cells": n, "time.dt": dt, "time.t_end": t_end,
                               "outputs.every": every, **QUIET_OUTPUTS})
    result = run(scene, out=out / f"dolfin_rod_{n}", overwrite=True, quiet=True)
    if result.status != "completed":
        raise RuntimeError(f"dolfin_rod n = {n}: {result.summary['message']}")
    s = {k: np.asarray(v, float) for k, v in result.series.items()}
    keep = [i for i, t in enumerate(s["time"]) if t > 0.5 and abs(t - round(t)) < 1e-9]
    timings = json.loads((out / f"dolfin_rod_{n}" / "timings.json").read_text())
    return {"n": n, "dt": dt, "steps": int(s["step"][-1]), "wall_s": timings["integration"],
            "total_s": timings["total"], "time": s["time"][keep].tolist(),
            "torque": s["reaction_couple_right_z"][keep].tolist(),
            "writhe": s["writhe"][keep].tolist(),
            "linking_error": float(np.max(np.abs(s["twist"] + s["writhe"] - TURNS * s["time"]
                                                 / T_TWIST))),
            "min_pair_gap": float(s["min_pair_gap"].min())}


# ---------------------------------------------------------------- accuracy, ratios
def errors(r, ref):
    """Relative max-norm errors of the end torque and the writhe against the reference
    (module docstring); the sample times must agree."""
    if not np.allclose(r["time"], ref["time"]):
        raise ValueError(f"sample times differ: {r['time'][:3]} vs {ref['time'][:3]}")
    return {f"{key}_error": float(np.max(np.abs(np.subtract(r[key], ref[key])))
                                  / np.max(np.abs(ref[key]))) for key in ("torque", "writhe")}


def sweep(label, runner, sizes, reference):
    """The reference and the runs at ``sizes`` of one code, each with its errors."""
    ref = runner(reference)
    print(f"[{label}] reference n = {reference}: {ref['wall_s']:.1f} s", flush=True)
    rows = []
    for n in sizes:
        r = runner(n)
        r.update(errors(r, ref))
        r["error"] = max(r["torque_error"], r["writhe_error"])
        rows.append(r)
        print(f"[{label}] n = {n:4d} dt = {r['dt']:.3g} steps = {r['steps']} wall = "
              f"{r['wall_s']:.2f} s torque error {r['torque_error']:.2e} writhe error "
              f"{r['writhe_error']:.2e} |Tw + Wr - Lk| {r['linking_error']:.2g}", flush=True)
    return {"reference": ref, "runs": rows}


def load():
    return dict(zip(("1 min", "5 min", "15 min"), os.getloadavg()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    name = args.out or ("peer_plectoneme_quick" if args.quick else "peer_plectoneme")
    t_end = 15.0 if args.quick else T_TWIST
    pe_sizes, pe_ref = ([19, 38, 75], 150) if args.quick else ([38, 75, 150], 300)
    dr_sizes, dr_ref = ([10, 20, 40], 80) if args.quick else ([32, 48, 64, 96], 192)
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    scratch = ROOT / "results" / "peer_plectoneme"
    out = {"quick": args.quick, "t_end": t_end, "load_start": load()}
    run_dolfin_rod(10, 0.2, 1.0, scratch)               # form cache (excluded)
    run_pyelastica(10, 1.0)                             # numba's compilation (excluded)
    out["dolfin_rod"] = sweep("dolfin_rod", lambda n: run_dolfin_rod(
        n, 2.0 / n, t_end, scratch), dr_sizes, dr_ref)
    out["pyelastica"] = sweep("pyelastica", lambda n: run_pyelastica(n, t_end),
                              pe_sizes, pe_ref)
    out["references_difference"] = errors(out["dolfin_rod"]["reference"],
                                          out["pyelastica"]["reference"])
    out["ratios"] = {}
    for r in out["pyelastica"]["runs"]:
        mine = out["dolfin_rod"]["runs"]
        t = time_at([m["error"] for m in mine], [m["wall_s"] for m in mine], r["error"])
        t_total = time_at([m["error"] for m in mine], [m["total_s"] for m in mine], r["error"])
        out["ratios"][f"pyelastica n = {r['n']}"] = {
            "error": r["error"], "pyelastica_wall_s": r["wall_s"], "dolfin_rod_wall_s": t,
            "speedup": r["wall_s"] / t if t else None,
            "speedup with set-up": r["wall_s"] / t_total if t_total else None}
    out["load_end"] = load()
    from dolfin_rod import versions
    out["versions"] = {**versions(), "pyelastica": metadata.version("pyelastica")}
    (folder / f"{name}.json").write_text(json.dumps(out, indent=1))
    print(f"references differ by {out['references_difference']}")
    for k, v in out["ratios"].items():
        print(f"at {k}'s error {v['error']:.3g}: PyElastica {v['pyelastica_wall_s']:.1f} s, "
              f"dolfin_rod {v['dolfin_rod_wall_s'] or float('nan'):.2f} s, speed-up "
              f"{v['speedup'] or float('nan'):.3g} ({v['speedup with set-up'] or float('nan'):.3g}"
              " with set-up)")
    print(f"load {out['load_start']} -> {out['load_end']}; wrote {folder / name}.json")


if __name__ == "__main__":
    main()
