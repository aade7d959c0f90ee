"""Peer comparison with PyElastica on a LONG creep scene, "creep_long" (issue 7, item 1).

The "creep" scene of peer_pyelastica.py (tau = 0.1, T = 0.5) ends long before the
cantilever's first bending period (2 pi / omega_1 = 4.5 s, omega_1 = 1.875^2
sqrt(EI / (rho A L^4)) = 1.39 /s): it measures dynamics.  "creep_long" is a creep test:

    same rod, gravity, clamp and evolution law as "creep" (benchmarks/cantilever.py):
        d u_d/dt = (u - 2 u_d)/tau,  d (v_d - e_3)/dt = ((v - e_3) - 2 (v_d - e_3))/tau
    (at a fixed bending moment the strain creeps to twice its elastic value with time
    constant tau: a standard linear solid), with
        tau = 10 s  (> 2 periods of the first bending mode),  T = 3 tau = 30 s,
    and the SAME linear translational drag on both sides, so that the release transient
    (the rod drops from horizontal) dies out in a few seconds and the rest is creep:
        dolfin_rod:  f = -c dr/dt per unit length, c = NU rho A   (RodParameters.drag)
        PyElastica:  AnalyticalLinearDamper, "physical" protocol, per-node
                     translational_damping_constant = NU m_i (m_i: PyElastica's nodal
                     mass = rho A x nodal length, half at the ends), rotational = 0,
                     i.e. v_i <- exp(-NU dt) v_i after every step (exact integration of
                     m_i dv_i/dt = -NU m_i v_i = -c (nodal length) v_i: the same continuum
                     drag lumped per node; no rotational damping on either side).
    NU = 2 /s: damping ratio NU / (2 omega) = 0.7 for the horizontal cantilever's first
    mode and ~0.26 for the hanging rod's pendulum mode (omega ~ sqrt(3 g / 2 L)); the
    creep velocities (~1 cm/s) make the drag force ~0.2 % of the weight.
    The evolution law's own dissipation is too weak to do this: its loss tangent
    omega tau / (2 + (omega tau)^2) is 0.07 at omega tau = 14 (damping ratio ~3.5 %).

Error: max over t = 3, 6, .., 30 s of |r_tip - r_tip,ref| / max |r_tip,ref - r_tip(0)|,
each code against its own reference.  Wall time of the time loop only.

    PyElastica 1.0  PositionVerlet, dt = 0.01 dx (its stable rule, as peer_pyelastica.py),
                    rest_kappa/rest_sigma updated in a forcing (forward Euler per step),
                    plus LaplaceDissipationFilter(filter_order=5), the numerical
                    grid-scale filter PyElastica's examples use: without it the n = 80 and
                    160 runs blow up at t ~ 6-7 s (also without creep, without drag, and at
                    dt/2; measured), i.e. long runs need it.  Even with it, n = 320
                    (108 s) gives NaN between t = 6 and 9 s, so n = 20 .. 160 (T / dt = 3000 n
                    steps); reference: first-order Richardson extrapolation
                    2 r(160) - r(80) (the errors of n = 20, 40 against it halve per
                    doubling: first order; n = 640 would take ~5-7 min and is skipped).
    dolfin_rod      PETSc TS adaptive BDF2 (TSIntegrator, ts_adapt basic, default Newton +
                    MUMPS) with rtol = atol = tol, n and tol varied together (a user's choice
                    for a fast damped transient followed by slow creep); the stepper is
                    restarted at every sample time.  Reference n = 64, tol = 1e-5.

Writes results/bench/peer_pyelastica_long.json and .png.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cantilever as cant  # noqa: E402
from peer_pyelastica import time_at  # noqa: E402

from dolfin_rod import NATIVE_LU  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TAU = 10.0
T_END = 3 * TAU
NU = 2.0                                   # drag rate c / (rho A) [1/s]
DRAG = NU * cant.RHO * cant.AREA           # c [N s / m^2]
SAMPLES = np.linspace(3.0, T_END, 10)
FILTER_ORDER = 5


def tip_error(tips, ref):
    tips, ref = np.asarray(tips), np.asarray(ref)
    scale = np.max(np.linalg.norm(ref - np.array([0.0, 0.0, cant.L]), axis=1))
    return float(np.max(np.linalg.norm(tips - ref, axis=1)) / scale)


# -- dolfin_rod ---------------------------------------------------------------------------

def dolfin_rod_model(n_cells: int):
    from mpi4py import MPI
    from dolfin_rod import DistributedLoad, RodModel, RodParameters
    A = (cant.E * cant.I_SEC, cant.E * cant.I_SEC, cant.G * cant.J_SEC)
    B = (cant.ALPHA_C * cant.G * cant.AREA, cant.ALPHA_C * cant.G * cant.AREA, cant.E * cant.AREA)
    params = RodParameters(length=cant.L, A=A, B=B, density=cant.RHO * cant.AREA,
                           section_inertia=cant.RHO * cant.I_SEC,
                           A_d=A, B_d=B, M_d=tuple(TAU * a for a in A),
                           N_d=tuple(TAU * b for b in B), drag=DRAG)
    model = RodModel(params, n_cells=n_cells, model="evolving", variant="local",
                     start="clamped", end="free", rotations="quaternion",   # PETSc TS
                     distributed_loads=[DistributedLoad(
                         "force", (-cant.RHO * cant.AREA * cant.GRAV, 0.0, 0.0))],
                     comm=MPI.COMM_WORLD)
    model.set_initial_state()
    return model


def run_dolfin_rod(n_cells: int, tol: float, ts_type: str = "bdf:2", options=None,
                   dt0: float = 1e-3) -> dict:
    from dolfin_rod import TSIntegrator
    t0 = time.perf_counter()
    model = dolfin_rod_model(n_cells)
    integ = TSIntegrator(model.problem, ts_type, adaptive=True, rtol=tol, atol=tol,
                         solver_options=options)
    probe = cant.TipProbe(model)
    t1 = time.perf_counter()
    tips, t, dt, steps, its, rej = [], 0.0, dt0, 0, 0, 0
    for ts in SAMPLES:                         # march to each sample exactly
        t = integ.run(t, ts, dt)
        dt = max(integ.ts.getTimeStep(), dt0)  # continue with TS's last step size
        steps += integ.stats.steps
        its += integ.stats.newton_iterations
        rej += integ.stats.rejected
        integ.stats.steps = 0
        tips.append(probe().tolist())
    t2 = time.perf_counter()
    return {"code": "dolfin_rod", "n_cells": n_cells, "tol": tol, "ts_type": ts_type,
            "setup_s": t1 - t0, "wall_s": t2 - t1, "steps": steps,
            "newton_iterations": its, "rejected_steps": rej, "tips": tips}


# -- PyElastica ---------------------------------------------------------------------------

def run_pyelastica(n_elem: int, dt: float, samples=SAMPLES) -> dict:
    ea = cant.ea

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    h = samples[0] / int(round(samples[0] / dt))   # uniform step dividing the sample spacing
    t0 = time.perf_counter()
    sim = Sim()
    rod = ea.CosseratRod.straight_rod(
        n_elem, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]),
        cant.L, cant.RADIUS, cant.RHO, youngs_modulus=cant.E, shear_modulus=cant.G)
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                             constrained_director_idx=(0,))
    sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.array([-cant.GRAV, 0.0, 0.0]))
    sim.add_forcing_to(rod).using(cant.NaturalConfigurationFlow, tau=TAU)
    # per node: m_i dv/dt = -NU m_i v  (continuum drag c = NU rho A), no rotational damping
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, time_step=h,
                          translational_damping_constant=NU * rod.mass.copy(),
                          rotational_damping_constant=0.0)
    if FILTER_ORDER:   # numerical high-wavenumber filter, needed for long-time stability
        sim.dampen(rod).using(ea.LaplaceDissipationFilter, filter_order=FILTER_ORDER)
    sim.finalize()
    stepper = ea.PositionVerlet()
    t1 = time.perf_counter()
    tips, t, steps = [], 0.0, 0
    for ts in samples:
        n = int(round((ts - t) / h))
        for _ in range(n):
            t = stepper.step(sim, t, h)
        t = float(ts)
        steps += n
        tips.append(rod.position_collection[:, -1].copy().tolist())
    t2 = time.perf_counter()
    return {"code": "pyelastica", "n_cells": n_elem, "dt": h, "setup_s": t1 - t0,
            "wall_s": t2 - t1, "steps": steps, "tips": tips}


# -- sweep --------------------------------------------------------------------------------

DR_SWEEP = [(4, 3e-2), (8, 1e-2), (16, 3e-3), (32, 3e-4)]
DR_REF = (64, 1e-5)
PE_SIZES = [20, 40, 80, 160]
PE_REF = (80, 160)          # Richardson: 2 r(160) - r(80); n = 320 diverges (see docstring)


def sweep(quick):
    out = {"scene": "creep_long", "tau": TAU, "T": T_END, "drag_rate_nu": NU, "drag_c": DRAG,
           "samples": SAMPLES.tolist(), "codes": {}}
    dr_sweep = DR_SWEEP[:3] if quick else DR_SWEEP
    dr_ref = (32, 1e-4) if quick else DR_REF
    run_dolfin_rod(4, 1e-2)                    # JIT / cache load (excluded)
    ref = run_dolfin_rod(*dr_ref)
    print(f"  dolfin_rod reference n={dr_ref[0]} tol={dr_ref[1]:g} wall={ref['wall_s']:.1f} s "
          f"steps={ref['steps']}", flush=True)
    rows = []
    for n, tol in dr_sweep:
        r = run_dolfin_rod(n, tol)
        r["error"] = tip_error(r["tips"], ref["tips"])
        rows.append(r)
        print(f"  dolfin_rod bdf:2 n={n:4d} tol={tol:.0e} wall={r['wall_s']:7.2f} s steps={r['steps']} "
              f"its={r['newton_iterations']} rejected={r['rejected_steps']} err={r['error']:.2e}",
              flush=True)
    out["codes"]["dolfin_rod (TS bdf:2 adaptive)"] = {"reference": ref, "runs": rows}
    rows = []
    for n, tol in dr_sweep:               # the same with PETSc's own LU (solvers.NATIVE_LU)
        r = run_dolfin_rod(n, tol, options=NATIVE_LU)
        r["error"] = tip_error(r["tips"], ref["tips"])
        rows.append(r)
        print(f"  dolfin_rod bdf:2 native LU n={n:4d} tol={tol:.0e} wall={r['wall_s']:7.2f} s "
              f"steps={r['steps']} rejected={r['rejected_steps']} err={r['error']:.2e}", flush=True)
    out["codes"]["dolfin_rod (TS bdf:2 adaptive, native LU)"] = {"reference": ref, "runs": rows,
                                                                "options": NATIVE_LU}

    pe_sizes = PE_SIZES[:3] if quick else PE_SIZES
    pe_ref = (40, 80) if quick else PE_REF
    run_pyelastica(10, 1e-3, samples=np.array([0.01]))   # numba compilation (excluded)
    runs = {}
    for n in sorted(set(pe_sizes) | set(pe_ref)):
        runs[n] = run_pyelastica(n, 0.01 / n)
        print(f"  pyelastica n={n:4d} dt={runs[n]['dt']:.2e} steps={runs[n]['steps']} "
              f"wall={runs[n]['wall_s']:7.2f} s", flush=True)
    ref_tips = 2 * np.array(runs[pe_ref[1]]["tips"]) - np.array(runs[pe_ref[0]]["tips"])
    rows = []
    for n in pe_sizes:
        r = runs[n]
        r["error"] = tip_error(r["tips"], ref_tips)
        rows.append(r)
        print(f"  pyelastica n={n:4d} err={r['error']:.2e}", flush=True)
    # estimated error of the finest plain run = its distance to the extrapolation
    est = tip_error(runs[pe_ref[1]]["tips"], ref_tips)
    out["codes"]["pyelastica"] = {
        "reference": {"richardson_from": list(pe_ref), "tips": ref_tips.tolist(),
                      f"n={pe_ref[1]} run": runs[pe_ref[1]],
                      f"error estimate of n={pe_ref[1]}": est},
        "runs": rows}
    out["references_relative_difference"] = tip_error(ref_tips, ref["tips"])
    out["ratios"] = {}
    for target in (1e-2, 1e-3):
        t = {k: time_at([r["error"] for r in v["runs"]], [r["wall_s"] for r in v["runs"]],
                        target) for k, v in out["codes"].items()}
        out["ratios"][f"{target:g}"] = {"wall_s": t, **{
            f"speedup {k} vs pyelastica": t["pyelastica"] / t[k] if t[k] and t["pyelastica"]
            else None for k in out["codes"] if k != "pyelastica"}}
    return out


def plot(res, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.4))
    for (label, data), mk in zip(res["codes"].items(), "s^o"):
        e = [r["error"] for r in data["runs"]]
        w = [r["wall_s"] for r in data["runs"]]
        ax.loglog(w, e, marker=mk, label=label)
        for r in data["runs"]:
            txt = f"{r['n_cells']}" + (f", {r['tol']:.0e}" if "tol" in r else "")
            ax.annotate(txt, (r["wall_s"], r["error"]), fontsize=7,
                        textcoords="offset points", xytext=(3, 3))
    for tgt in (1e-2, 1e-3):
        ax.axhline(tgt, color="0.7", lw=0.8, ls="--")
    ax.set_xlabel("wall time of the time loop [s]")
    ax.set_ylabel("relative tip error vs own reference")
    ax.set_title(f"cantilever creep_long (tau = {TAU:g} s, T = {T_END:g} s, drag {NU:g}/s)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    from dolfin_rod import versions
    res = sweep(args.quick)
    folder = ROOT / "results" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    out = {"versions": {**versions(), "pyelastica": "1.0.0"}, "quick": args.quick,
           "scenes": [res]}
    (folder / "peer_pyelastica_long.json").write_text(json.dumps(out, indent=1))
    plot(res, folder / "peer_pyelastica_long.png")
    print(f"[creep_long] references differ by {res['references_relative_difference']:.2e}")
    for tgt, v in res["ratios"].items():
        print(f"[creep_long] at {tgt}: {v}")
    print(f"wrote {folder / 'peer_pyelastica_long.json'} and .png")


if __name__ == "__main__":
    main()
