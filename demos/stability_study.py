# # Stability of the time integrators (numbers and figures for docs/stability.md)
#
# (a) explicit Euler's critical step vs mesh size on the dynamic torsion rod,
# (b) Crank-Nicolson vs L-stable schemes after a step load in the stiff limit,
# (c) energy drift of the dynamic schemes on the conservative wave (mu = 0, u_d frozen),
# (d) Newton failure at a too large step and recovery by step cutting.
# Figures: docs/figures/stability_*.png; numbers: results/stability/stability.json.
# Serial (the bisection in (a) reads local arrays).  Run: `make stability`.

from __future__ import annotations

import json
import pathlib
import sys
import time

import numpy as np
import scipy.linalg as sla
import ufl
import dolfinx.fem as fem
import matplotlib.pyplot as plt

from dolfin_rod import (closed_forms as cf, loads, SolverError, TimeStepper, TorsionModel,
                        TorsionParameters, TSIntegrator)

FIG = pathlib.Path("docs/figures")
OUT = pathlib.Path("results/stability")
results = {}


# ## (a) Explicit Euler on nu phi_tt = (alpha (phi_s - u_d) + mu phi_st)_s, u_d frozen
# The system solved (torsion.py, local variant, P1 phi and w, DG0 u_d, Dirichlet ends):
#   nu M w' + alpha K phi - alpha C^T u_d + mu K w = 0      (consistent mass M, K = stiffness)
#   mu_d Mq u_d' - alpha C phi + (alpha + alpha_d) Mq u_d = 0   (C_ij = int q_i phi_j,s)
#   ML (phi' - w) = 0                                     (vertex quadrature: ML diagonal)
# i.e. E y' + A y = 0 on the free dofs.  ML is diagonal, so phi' = w holds nodally and the
# lumping does not enter the spectrum.  Forward Euler: y_{n+1} = G y_n, G = I - dt E^-1 A.
# With u_d frozen (mu_d -> infinity) a mode K v = kappa M v obeys
# nu x'' + mu kappa x' + alpha kappa x = 0, lambda^2 + a lambda + b = 0, a = mu kappa/nu,
# b = alpha kappa/nu, and |1 + dt lambda| <= 1 needs
#   underdamped (a^2 < 4b): 1 - a dt + b dt^2 <= 1  ->  dt <= a/b = mu/alpha (Kelvin-Voigt);
#   overdamped  (a^2 >= 4b): dt <= 2/|lambda_-|, lambda_- = -(a + sqrt(a^2 - 4b))/2
#                           -> 2 nu/(mu kappa_max) = nu h^2/(6 mu) (diffusive; kappa_max
#                           -> 12/h^2 for P1 with consistent mass).
# The two meet at kappa_c = 4 alpha nu/mu^2.  Independent prediction: the spectral radius
# of G assembled here from forms written out below (not the model's residual), with the
# u_d block kept (mu_d = 1e8), bisection on dt for rho(G) = 1.
# Measurement: TimeStepper("explicit_euler") with the library's default solver, from the
# highest mode (phi = v_max, w = u_d = 0); "unstable" := the model's energy (kinetic +
# free, model.diagnostics) exceeds GROWTH * E(0) within N_STEPS steps.  With a finite
# N_STEPS that threshold lies slightly above rho = 1 (growth rho^(2N) = GROWTH); the same
# criterion applied to G^n z0 predicts it (dt_pred_N).
NU, ALPHA, ALPHA_D, MU, MU_D = 1.0, 1.0, 1.0, 0.05, 1e8
MESHES = (4, 8, 16, 32, 64)
N_STEPS, GROWTH = 1000, 1e3


def torsion_rod(n):
    model = TorsionModel(TorsionParameters(ALPHA, ALPHA_D, MU, MU_D, nu=NU), n_cells=n,
                         end_rotation=loads.constant(0.0))
    model.set_initial_state()
    return model


def assembled_system(model):
    """E, A (E y' + A y = 0) and the energy matrix H (E = y.H y/2) on the free dofs
    y = [phi interior, u_d, w interior], from forms written here."""
    phi, ud, w = model.problem.fields
    V, Q, W = phi.function_space, ud.function_space, w.function_space
    dx = ufl.dx(domain=model.mesh)
    dx_v = ufl.Measure("dx", domain=model.mesh,
                       metadata={"quadrature_rule": "vertex", "quadrature_degree": 1})

    def dense(a):
        return fem.assemble_matrix(fem.form(a)).to_dense()

    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    M = dense(u * v * dx)
    K = dense(u.dx(0) * v.dx(0) * dx)
    ML = dense(ufl.TrialFunction(W) * ufl.TestFunction(W) * dx_v)
    p, q = ufl.TrialFunction(Q), ufl.TestFunction(Q)
    Mq = dense(p * q * dx)
    C = dense(u.dx(0) * q * dx)                     # rows: u_d tests, columns: phi
    s = V.tabulate_dof_coordinates()[:, 0]
    free = ~(np.isclose(s, 0.0) | np.isclose(s, 1.0))
    assert np.allclose(s, W.tabulate_dof_coordinates()[:, 0])
    M, K, ML, C = M[np.ix_(free, free)], K[np.ix_(free, free)], ML[np.ix_(free, free)], C[:, free]
    m, k = free.sum(), Mq.shape[0]
    Z = np.zeros
    E = np.block([[Z((m, m)), Z((m, k)), NU * M],
                  [Z((k, m)), MU_D * Mq, Z((k, m))],
                  [ML, Z((m, k)), Z((m, m))]])
    A = np.block([[ALPHA * K, -ALPHA * C.T, MU * K],
                  [-ALPHA * C, (ALPHA + ALPHA_D) * Mq, Z((k, m))],
                  [Z((m, m)), Z((m, k)), -ML]])
    H = np.block([[ALPHA * K, -ALPHA * C.T, Z((m, m))],
                  [-ALPHA * C, (ALPHA + ALPHA_D) * Mq, Z((k, m))],
                  [Z((m, m)), Z((m, k)), NU * M]])
    return dict(E=E, A=A, H=H, M=M, K=K, free=free, m=m, k=k)


def bisect(unstable, lo, hi, rtol=1e-10):
    """The boundary of a monotone 'unstable' predicate in [lo, hi] (geometric bisection)."""
    assert not unstable(lo) and unstable(hi), (lo, hi)
    while hi / lo > 1 + rtol:
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    return np.sqrt(lo * hi)


def dt_modal(kappa):
    a, b = MU * kappa / NU, ALPHA * kappa / NU
    if a * a < 4 * b:
        return MU / ALPHA
    return 2.0 / ((a + np.sqrt(a * a - 4 * b)) / 2)


def predictions(sysm, z0):
    """dt at which rho(G) = 1 (bisection on numpy eig of G), the same from the eigenvalues
    sigma of E^-1 A (|1 - dt sigma| <= 1 iff dt <= 2 Re sigma/|sigma|^2), the same with u_d
    dropped (the 2(n-1) x 2(n-1) [phi, w] system), and the finite-N threshold dt_pred_N."""
    EA = np.linalg.solve(sysm["E"], sysm["A"])
    I = np.eye(EA.shape[0])

    def rho(dt, B=EA):
        return np.abs(np.linalg.eigvals(np.eye(B.shape[0]) - dt * B)).max()

    dt_rho = bisect(lambda dt: rho(dt) > 1 + 1e-12, 1e-6, 1.0)
    sig = np.linalg.eigvals(EA)
    dt_sigma = np.min(2 * sig.real / np.abs(sig) ** 2)
    m, k = sysm["m"], sysm["k"]
    keep = np.r_[0:m, m + k:2 * m + k]
    EA2 = np.linalg.solve(sysm["E"][np.ix_(keep, keep)], sysm["A"][np.ix_(keep, keep)])
    dt_rho_2n = bisect(lambda dt: rho(dt, EA2) > 1 + 1e-12, 1e-6, 1.0)
    H = sysm["H"]
    e0 = z0 @ H @ z0

    def grows(dt):
        G, z = I - dt * EA, z0.copy()
        for _ in range(N_STEPS):
            z = G @ z
            if z @ H @ z > GROWTH * e0:
                return True
        return False

    dt_N = bisect(grows, 0.9 * dt_rho, 2.0 * dt_rho, rtol=1e-7)
    return dict(dt_rho=dt_rho, dt_sigma=dt_sigma, dt_rho_2n=dt_rho_2n, dt_pred_N=dt_N,
                rho_at_dt_pred_N=rho(dt_N))


def energy(model):
    d = model.diagnostics(0.0)
    return d["kinetic_energy"] + d["free_energy"]


def set_state(model, sysm, z):
    phi, ud, w = model.problem.fields
    m, k, free = sysm["m"], sysm["k"], sysm["free"]
    for f in (phi, ud, w):
        f.x.array[:] = 0.0
    phi.x.array[free], ud.x.array[:], w.x.array[free] = z[:m], z[m:m + k], z[m + k:]


def log_growth(model, sysm, z0, dt):
    """ln(max_{n <= N_STEPS} E_n/E_0) of a TimeStepper run (stops once above GROWTH^2)."""
    set_state(model, sysm, z0)
    st = TimeStepper(model.problem, "explicit_euler")
    e0, top = energy(model), 1.0
    for i in range(N_STEPS):
        try:
            st.step(i * dt, dt)
        except SolverError:
            return np.inf
        top = max(top, energy(model) / e0)
        if top > GROWTH**2:
            break
    return np.log(top)


def measured_dt(model, sysm, z0, guess):
    """Root of ln(max E_n/E_0) = ln GROWTH by the Illinois method (bracketed secant)."""
    target = np.log(GROWTH)
    lo, hi = 0.99 * guess, 1.01 * guess
    glo, ghi = log_growth(model, sysm, z0, lo) - target, log_growth(model, sysm, z0, hi) - target
    runs = 2
    while glo >= 0:
        lo *= 0.95
        glo, runs = log_growth(model, sysm, z0, lo) - target, runs + 1
    while ghi <= 0:
        hi *= 1.05
        ghi, runs = log_growth(model, sysm, z0, hi) - target, runs + 1
    side = 0
    while hi / lo > 1 + 2e-5:
        ghi_eff = min(ghi, np.log(GROWTH))  # a clipped (blown-up) value: plain secant on it
        mid = hi - ghi_eff * (hi - lo) / (ghi_eff - glo)
        mid = min(max(mid, lo + 1e-3 * (hi - lo)), hi - 1e-3 * (hi - lo))
        g = log_growth(model, sysm, z0, mid) - target
        runs += 1
        if abs(g) < 1e-2:  # E_max/E_0 within 1 % of GROWTH: dt to ~1e-6 relative
            return mid, runs
        if g > 0:
            hi, ghi = mid, g
            if side == 1:
                glo /= 2
            side = 1
        else:
            lo, glo = mid, g
            if side == -1:
                ghi /= 2
            side = -1
    return np.sqrt(lo * hi), runs


def study_a():
    rows = []
    for n in MESHES:
        t0 = time.perf_counter()
        model = torsion_rod(n)
        sysm = assembled_system(model)
        kap, vecs = sla.eigh(sysm["K"], sysm["M"])
        z0 = np.zeros(sysm["E"].shape[0])
        z0[:sysm["m"]] = vecs[:, -1] / np.abs(vecs[:, -1]).max()  # highest mode, at rest
        pred = predictions(sysm, z0)
        # one step of the solver = one application of G (the matrices are the system solved)
        set_state(model, sysm, z0)
        dt1 = pred["dt_rho"]
        TimeStepper(model.problem, "explicit_euler").step(0.0, dt1)
        phi, ud, w = model.problem.fields
        z1 = np.r_[phi.x.array[sysm["free"]], ud.x.array, w.x.array[sysm["free"]]]
        Gz0 = z0 - dt1 * np.linalg.solve(sysm["E"], sysm["A"] @ z0)
        one_step = float(np.abs(z1 - Gz0).max() / np.abs(Gz0).max())
        me, runs = measured_dt(model, sysm, z0, pred["dt_pred_N"])
        row = dict(n=n, h=1 / n, kappa_max=kap[-1], kappa_c=4 * ALPHA * NU / MU**2,
                   regime="Kelvin-Voigt" if kap[-1] < 4 * ALPHA * NU / MU**2 else "diffusive",
                   dt_modal=dt_modal(kap[-1]), **pred, dt_measured=me, runs=runs,
                   one_step_rel_diff=one_step, diffusive_limit=NU / (6 * MU * n**2),
                   kv_limit=MU / ALPHA)
        rows.append(row)
        print(f"(a) h = 1/{n} ({row['regime']}): kappa_max = {kap[-1]:.1f}; dt_crit: "
              f"rho(G) = 1 {pred['dt_rho']:.7g} [modal {dt_modal(kap[-1]) / pred['dt_rho'] - 1:+.0e},"
              f" 2 Re s/|s|^2 {pred['dt_sigma'] / pred['dt_rho'] - 1:+.0e}, without u_d "
              f"{pred['dt_rho_2n'] / pred['dt_rho'] - 1:+.0e}]; finite-N prediction "
              f"{pred['dt_pred_N']:.7g}, measured {me:.7g} ({runs} runs, {time.perf_counter() - t0:.0f} s;"
              f" measured/rho=1 - 1 = {me / pred['dt_rho'] - 1:+.2e}, "
              f"measured/pred_N - 1 = {me / pred['dt_pred_N'] - 1:+.0e}); "
              f"one step vs G: {one_step:.0e}")
    results["a_explicit_euler"] = dict(
        params=dict(nu=NU, alpha=ALPHA, alpha_d=ALPHA_D, mu=MU, mu_d=MU_D, n_steps=N_STEPS,
                    growth=GROWTH, initial_state="highest mode of (K, M), w = u_d = 0"),
        rows=rows)
    h = np.array([r["h"] for r in rows])
    hh = np.geomspace(h.min() / 1.3, h.max() * 1.3, 200)
    kc = lambda hv: 6 / hv**2 * (1 - np.cos(np.pi * (1 - hv))) / (2 + np.cos(np.pi * (1 - hv)))
    plt.figure(figsize=(5.5, 4.2))
    plt.loglog(hh, [dt_modal(kc(x)) for x in hh], "-", c="C0", lw=1,
               label="theory: min(mu/alpha, 2/|lambda_-(kappa_max)|)")
    plt.loglog(h, [r["dt_rho"] for r in rows], "s", mfc="none", ms=9, c="C0",
               label="predicted: rho(G) = 1 (assembled, numpy eig)")
    plt.loglog(h, [r["dt_pred_N"] for r in rows], "x", ms=8, c="C2",
               label=f"predicted: E grows {GROWTH:.0e} in {N_STEPS} steps")
    plt.loglog(h, [r["dt_measured"] for r in rows], "o", ms=4, c="C3",
               label="measured (TimeStepper, same criterion)")
    plt.loglog(hh, NU * hh**2 / (6 * MU), ":", c="gray", label="nu h^2/(6 mu)")
    plt.axhline(MU / ALPHA, ls="--", c="gray", lw=1, label="mu/alpha")
    plt.ylim(3e-4, 0.1)
    plt.xlabel("h"), plt.ylabel("critical dt (explicit Euler)")
    plt.title(f"nu = {NU:g}, alpha = {ALPHA:g}, mu = {MU:g}, mu_d = {MU_D:g}", fontsize=9)
    plt.legend(fontsize=7), plt.tight_layout()
    plt.savefig(FIG / "stability_explicit.png", dpi=100)


# ## (b) Step relaxation, stiff limit k dt = 60 (k = (alpha + alpha_d)/mu_d)
# Amplification of u_d - u_d(inf) per step: CN (1 - z/2)/(1 + z/2) -> -1 (A- not L-stable:
# undamped sign-alternating oscillation), BE 1/(1 + z) -> 0, BDF2 roots -> 0.
def study_b():
    mu_d, dt = 0.005, 0.1
    k = (2.0 + 1.0) / mu_d
    out = {}
    plt.figure(figsize=(5.5, 4))
    for label, make in [("step crank_nicolson", lambda p: TimeStepper(p, "crank_nicolson")),
                        ("step backward_euler", lambda p: TimeStepper(p, "backward_euler")),
                        ("step bdf2", lambda p: TimeStepper(p, "bdf2")),
                        ("ts crank_nicolson", lambda p: TSIntegrator(p, "crank_nicolson")),
                        ("ts bdf:2", lambda p: TSIntegrator(p, "bdf:2"))]:
        model = TorsionModel(TorsionParameters(2.0, 1.0, 0.0, mu_d), n_cells=4,
                             end_rotation=loads.step(0.5))
        model.set_initial_state()
        rec = []
        make(model.problem).run(0.0, 2.0, dt, observer=lambda t, s: rec.append(
            (t, model.diagnostics(t)["mean_natural_twist"])))
        t, ud = np.array(rec).T
        exact, _ = cf.relaxation(t, 0.5, 2.0, 1.0, mu_d)
        out[label] = float(np.max(np.abs(ud - exact)[-5:]))
        plt.plot(t, ud, ".-", ms=3, label=label)
        print(f"(b) k dt = {k * dt:.0f}: {label}: |u_d - exact| over the last 5 steps {out[label]:.3g}")
    plt.xlabel("t"), plt.ylabel("u_d"), plt.legend(fontsize=7), plt.tight_layout()
    plt.savefig(FIG / "stability_crank_nicolson.png", dpi=100)
    results["b_stiff_step"] = dict(k_dt=k * dt, cn_factor=(1 - k * dt / 2) / (1 + k * dt / 2),
                                   late_error=out)


# ## (c) Energy drift: nu phi_tt = alpha phi_ss, u_d frozen (mu_d = 1e8), mu = 0
# E = nu/2 int w^2 + alpha/2 int (phi_s - u_d)^2 is conserved by the PDE; midpoint (and
# CN, identical on a linear problem) conserve the discrete quadratic energy exactly.
def study_c():
    out = {}
    plt.figure(figsize=(5.5, 4))
    for label, make in [("step implicit_midpoint", lambda p: TimeStepper(p, "implicit_midpoint")),
                        ("step crank_nicolson", lambda p: TimeStepper(p, "crank_nicolson")),
                        ("step backward_euler", lambda p: TimeStepper(p, "backward_euler")),
                        ("step bdf2", lambda p: TimeStepper(p, "bdf2")),
                        ("step generalized_alpha", lambda p: TimeStepper(p, "generalized_alpha")),
                        ("ts alpha", lambda p: TSIntegrator(p, "alpha")),
                        ("ts bdf:2", lambda p: TSIntegrator(p, "bdf:2"))]:
        model = TorsionModel(TorsionParameters(1.0, 1.0, 0.0, 1e8, nu=1.0), n_cells=16,
                             end_rotation=loads.constant(0.0))
        model.set_initial_state()
        model.phi.interpolate(lambda x: 0.1 * np.sin(np.pi * x[0]) + 0.02 * np.sin(7 * np.pi * x[0]))
        rec = []
        make(model.problem).run(0.0, 20.0, 0.05, observer=lambda t, s: rec.append(
            (t, (lambda d: d["kinetic_energy"] + d["free_energy"])(model.diagnostics(t)))))
        t, e = np.array(rec).T
        out[label] = float(e[-1] / e[0] - 1)
        plt.plot(t, e / e[0], label=label)
        print(f"(c) {label}: relative energy change over t in [0, 20] = {out[label]:.3e}")
    plt.xlabel("t"), plt.ylabel("E(t)/E(0)"), plt.legend(fontsize=7), plt.tight_layout()
    plt.savefig(FIG / "stability_energy.png", dpi=100)
    results["c_energy_drift"] = out


# ## (d) Newton failure: y' = y^2, y(0) = 1 (blow-up at t = 1).  A backward Euler step
# y - dt y^2 = y_n has no real root when 4 dt y_n > 1: from y_n = 1, dt = 0.3 fails.
def study_d():
    sys.path.insert(0, "tests")
    from test_integrators import blow_up_problem
    out = {}
    for label, make in [("step backward_euler", lambda p: TimeStepper(p, "backward_euler")),
                        ("ts backward_euler", lambda p: TSIntegrator(p, "backward_euler")),
                        ("ts bdf:2", lambda p: TSIntegrator(p, "bdf:2"))]:
        problem, value = blow_up_problem()
        integ = make(problem)
        integ.run(0.0, 0.6, 0.3)
        out[label] = dict(steps=integ.stats.steps, rejected=integ.stats.rejected,
                          y=value(), exact=1 / 0.4)
        print(f"(d) {label}: {out[label]}")
    results["d_newton_failure"] = out


if __name__ == "__main__":
    FIG.mkdir(parents=True, exist_ok=True)
    OUT.mkdir(parents=True, exist_ok=True)
    only = sys.argv[1:]  # e.g. `python3 demos/stability_study.py a`: one study
    for name, study in (("a", study_a), ("b", study_b), ("c", study_c), ("d", study_d)):
        if not only or name in only:
            study()
    out = OUT / "stability.json"
    if only and out.exists():  # a partial run updates its studies only
        results = {**json.loads(out.read_text()), **results}
    out.write_text(json.dumps(results, indent=1, default=float))
