"""Verification of the isolated-torsion model (Section 5) against independent references.

References: the corrected closed forms (dolfin_rod.closed_forms, themselves checked
against scipy expm/solve_ivp in test_closed_forms.py), a re-derived steady state of an
inhomogeneous rod, the power identity of docs/corrections.md, and the serial run for MPI.
Observed orders in dt of every scheme are in test_integrators.py.
"""

import numpy as np
import pytest
from mpi4py import MPI

from dolfin_rod import closed_forms as cf
from dolfin_rod import loads
from dolfin_rod import TimeStepper
from dolfin_rod.torsion.model import TorsionModel, TorsionParameters
import cases
from serial_reference import serial
from torsion_runs import run, series

ALPHA, ALPHA_D, MU_D = 2.0, 1.0, 0.5


# Under mpirun: the uniform variant (its global unknowns).  The end rotation is a Dirichlet
# condition, the same for both variants; the local variant on two ranks (= serial) is
# test_parallel_run_reproduces_serial[local].
@pytest.mark.parametrize("variant", ["local", pytest.param("uniform", marks=pytest.mark.mpi)])
def test_relaxation_matches_closed_form(variant):
    u0 = 0.5
    p = TorsionParameters(alpha=ALPHA, alpha_d=ALPHA_D, mu=0.0, mu_d=MU_D)
    h = run(p, 2.0, 0.005, "bdf2", n_cells=4, variant=variant, end_rotation=loads.step(u0))
    t = series(h, "time")
    u_d, m = cf.relaxation(t, u0, ALPHA, ALPHA_D, MU_D)
    # The error is dominated by BDF2's backward-Euler start step, whose local error
    # (lambda dt)^2/2 u_d(inf), lambda = (alpha + alpha_d)/mu_d = 6, is carried along
    # undamped in size: bound (lambda dt)^2 u_d(inf) (factor 2 margin).  Space is exact:
    # the homogeneous twist is linear in s.
    bound = (6.0 * 0.005) ** 2 * ALPHA * u0 / (ALPHA + ALPHA_D)
    assert np.max(np.abs(series(h, "mean_natural_twist") - u_d)) < bound
    assert np.max(np.abs(series(h, "end_torsion") - m)) < ALPHA * bound
    assert series(h, "end_rotation") == pytest.approx(u0, abs=1e-12)


@pytest.mark.mpi
def test_relaxation_impulse_of_viscous_rod():
    """mu > 0: the step carries the impulse mu u0 delta(t) (eq. stressrelax)."""
    u0, mu = 0.5, 0.3
    model = TorsionModel(TorsionParameters(alpha=ALPHA, alpha_d=ALPHA_D, mu=mu, mu_d=MU_D),
                         n_cells=6, end_rotation=loads.step(u0))
    assert model.set_initial_state() == pytest.approx(cf.relaxation_impulse(u0, mu), rel=1e-12)


# Serial only: an end torsion on a Kelvin-Voigt rod by BDF2 on two ranks, both variants,
# is test_parallel_run_reproduces_serial (cases.torsion_inhomogeneous: = serial to 1e-9).
@pytest.mark.parametrize("variant", ["local", "uniform"])
def test_creep_with_kelvin_voigt_viscosity(variant):
    m0, mu = 0.8, 0.4
    p = TorsionParameters(alpha=ALPHA, alpha_d=ALPHA_D, mu=mu, mu_d=MU_D)
    h = run(p, 3.0, 0.005, "bdf2", n_cells=4, variant=variant, end_torsion=loads.step(m0))
    t = series(h, "time")
    u, u_d = cf.creep(t, m0, ALPHA, ALPHA_D, mu, MU_D)
    scale = cf.equilibrium_twists(m0, ALPHA, ALPHA_D)[0]
    # BDF2, dt = 5e-3, fastest rate tau + delta ~ 8.6: error ~ (8.6 dt)^2 / 3 ~ 6e-4 relative.
    assert np.max(np.abs(series(h, "end_rotation") - u)) < 1e-3 * scale
    assert np.max(np.abs(series(h, "mean_natural_twist") - u_d)) < 1e-3 * scale


@pytest.mark.parametrize("variant", ["local", "uniform"])
def test_creep_without_kelvin_voigt_viscosity(variant):
    """mu = 0: instantaneous elastic twist m0/alpha at 0+, then creep (errata item 3)."""
    m0 = 0.8
    p = TorsionParameters(alpha=ALPHA, alpha_d=ALPHA_D, mu=0.0, mu_d=MU_D)
    h = run(p, 3.0, 0.005, "bdf2", n_cells=4, variant=variant, end_torsion=loads.step(m0))
    t = series(h, "time")
    u, u_d = cf.creep_inviscid(t, m0, ALPHA, ALPHA_D, MU_D)
    assert series(h, "end_rotation")[0] == pytest.approx(m0 / ALPHA, rel=1e-12)
    scale = cf.equilibrium_twists(m0, ALPHA, ALPHA_D)[0]
    # BDF2 on the single rate alpha_d/mu_d = 2: (2 dt)^2 ~ 1e-4 relative, with margin.
    assert np.max(np.abs(series(h, "end_rotation") - u)) < 2e-4 * scale
    assert np.max(np.abs(series(h, "mean_natural_twist") - u_d)) < 2e-4 * scale


def _inhomogeneous(variant):
    p = TorsionParameters(alpha=lambda s: 1.0 + 3.0 * s, alpha_d=lambda s: 1.0 + 3.0 * s,
                          mu=0.0, mu_d=MU_D)
    return run(p, 20.0, 0.1, "bdf2", n_cells=32, variant=variant,
               end_rotation=loads.step(0.5))[-1]["end_torsion"]


def test_local_and_uniform_agree_for_homogeneous_states():
    p = TorsionParameters(alpha=ALPHA, alpha_d=ALPHA_D, mu=0.1, mu_d=MU_D)
    local, uniform = (run(p, 1.0, 0.01, "bdf2", n_cells=8, variant=v,
                          end_torsion=loads.step(0.7)) for v in ("local", "uniform"))
    for key in ("end_rotation", "mean_natural_twist", "free_energy", "dissipation_rate"):
        # Same discrete equations when the state is homogeneous: Newton tolerance 1e-10.
        assert series(local, key) == pytest.approx(series(uniform, key), abs=1e-9)


def test_local_and_uniform_differ_for_inhomogeneous_rod():
    """Relaxed torsion under end rotation Phi, alpha = alpha_d = 1 + 3s (re-derived).

    Quasi-static: the torsion m is uniform in s.  Local steady state m = alpha_d u_d(s),
    so Phi = m int (1/alpha + 1/alpha_d) ds; uniform: m = (int alpha_d ds) u_d, so
    Phi = m (1/int alpha_d + int 1/alpha).  (If only alpha varies, both variants coincide:
    u_d stays uniform in the local model too.)
    """
    phi, inv = 0.5, np.log(4.0) / 3.0          # int_0^1 ds/(1 + 3s)
    m_local, m_uniform = phi / (2 * inv), phi / (1 / 2.5 + inv)
    # P1/DG0 with 32 cells: O(h^2) ~ 1e-3 relative error in the compliance integrals;
    # t = 20 is 40 relaxation times (slowest rate alpha_d/mu_d >= 2).
    assert _inhomogeneous("local") == pytest.approx(m_local, rel=2e-3)
    assert _inhomogeneous("uniform") == pytest.approx(m_uniform, rel=2e-3)
    assert abs(m_local - m_uniform) > 0.03


def _uniform_with_sign_changing_twist():
    # End torsion -1 and a uniform distributed couple 3: internal torsion -1 + 3(1 - s)
    # changes sign at s = 2/3, with positive mean; Section 4.3 then predicts xi < 0 where
    # the twist is negative (errata item 4).
    p = TorsionParameters(alpha=ALPHA, alpha_d=ALPHA_D, mu=0.0, mu_d=MU_D,
                          couple=lambda s: 3.0 + 0.0 * s)
    return p


def test_uniform_pointwise_dissipation_negative_somewhere_total_nonnegative():
    p = _uniform_with_sign_changing_twist()
    model = TorsionModel(p, n_cells=30, variant="uniform", end_torsion=loads.constant(-1.0))
    model.set_initial_state()
    stepper = TimeStepper(model.problem, "backward_euler")
    stepper.run(0.0, 0.05, 0.01)
    xi = model.pointwise_dissipation()
    total = model.diagnostics(0.05)["dissipation_rate"]
    assert model.mesh.comm.allreduce(xi.min(), op=MPI.MIN) < -1e-3
    # Errata item 4: xi(s) = (alpha u(s) - (alpha + alpha_d) u_d)(int ...)/mu_d, and the
    # total equals mu_d (du_d/dt)^2 > 0.
    assert total > 0
    assert total == pytest.approx(MU_D * model.problem.rates[1].x.array[0] ** 2, rel=1e-10)


def test_local_pointwise_dissipation_nonnegative():
    p = _uniform_with_sign_changing_twist()
    model = TorsionModel(p, n_cells=30, variant="local", end_torsion=loads.constant(-1.0))
    model.set_initial_state()
    TimeStepper(model.problem, "backward_euler").run(0.0, 0.05, 0.01)
    xi = model.pointwise_dissipation()
    assert xi.min() >= 0.0
    assert xi.max() > 1e-3  # the test is not vacuous


def _power_residual(scheme, dt, dynamic):
    p = TorsionParameters(alpha=ALPHA, alpha_d=ALPHA_D, mu=0.2, mu_d=MU_D,
                          nu=0.05 if dynamic else 0.0)
    load = loads.smooth_step(1.0, 0.5)
    h = run(p, 1.0, dt, scheme, n_cells=8, end_torsion=load)
    t = series(h, "time")
    energy = series(h, "free_energy") + series(h, "kinetic_energy")
    # d/dt(K + Psi) + int xi = applied power (docs/corrections.md identity), discretised with the
    # backward difference that matches backward Euler.
    residual = np.diff(energy) / np.diff(t) + series(h, "dissipation_rate")[1:] \
        - series(h, "load_power")[1:]
    return np.max(np.abs(residual))


@pytest.mark.parametrize("dynamic", [False, True])
def test_power_balance_to_first_order_with_backward_euler(dynamic):
    r1, r2 = _power_residual("backward_euler", 0.02, dynamic), \
        _power_residual("backward_euler", 0.01, dynamic)
    order = np.log2(r1 / r2)
    assert abs(order - 1.0) < 0.15, (r1, r2, order)


def test_dynamic_solution_tends_to_quasi_static():
    m0 = 0.8
    base = dict(alpha=ALPHA, alpha_d=ALPHA_D, mu=0.5, mu_d=MU_D)
    ref = run(TorsionParameters(**base), 1.0, 0.01, "backward_euler", n_cells=8,
              end_torsion=loads.smooth_step(m0, 0.2))
    errors = []
    for nu in (1e-2, 1e-3):
        h = run(TorsionParameters(**base, nu=nu), 1.0, 0.01, "backward_euler", n_cells=8,
                end_torsion=loads.smooth_step(m0, 0.2))
        errors.append(np.max(np.abs(series(h, "end_rotation") - series(ref, "end_rotation"))))
    # The inertial correction is O(nu) (a regular perturbation once the Kelvin-Voigt
    # term damps the fast modes): a decade in nu gives a decade in the difference.
    assert np.log10(errors[0] / errors[1]) == pytest.approx(1.0, abs=0.2), errors
    assert errors[1] < 1e-3 * m0


def _steady_state_error(n_cells, degree):
    """Steady twist of an inhomogeneous rod under a uniform couple vs the exact one.

    alpha = 1 + s, alpha_d = 1, l = 1, free end: torsion m(s) = 1 - s, local steady
    state u = m (alpha + alpha_d)/(alpha alpha_d), so phi = 2 ln(1 + s) - s^2/2.
    Backward Euler's fixed point is the exact discrete steady state.
    """
    p = TorsionParameters(alpha=lambda s: 1.0 + s, alpha_d=1.0, mu=0.0, mu_d=1.0,
                          couple=lambda s: 1.0 + 0.0 * s)
    model = TorsionModel(p, n_cells=n_cells, degree=degree, end_torsion=loads.constant(0.0))
    model.set_initial_state()
    TimeStepper(model.problem, "backward_euler").run(0.0, 1e6, 1e5)
    import dolfinx.fem as fem
    import ufl
    s = ufl.SpatialCoordinate(model.mesh)[0]
    exact = 2 * ufl.ln(1 + s) - s**2 / 2
    err = fem.form((model.phi - exact) ** 2 * ufl.dx(metadata={"quadrature_degree": 8}))
    return np.sqrt(model.mesh.comm.allreduce(fem.assemble_scalar(err), op=MPI.SUM))


@pytest.mark.parametrize("degree", [1, 2])
def test_spatial_convergence_on_inhomogeneous_steady_state(degree):
    e = [_steady_state_error(n, degree) for n in (8, 16, 32)]
    rates = np.log2(np.array(e[:-1]) / e[1:])
    # L2 error of P_k twist angle: O(h^{k+1}).
    assert rates == pytest.approx([degree + 1] * 2, abs=0.15), (e, rates)


@pytest.mark.mpi
@pytest.mark.parametrize("variant", ["local", "uniform"])
def test_parallel_run_reproduces_serial(variant):
    world = cases.torsion_inhomogeneous(variant)
    reference = serial("torsion_inhomogeneous", variant)
    for key in cases.KEYS:
        # Same discrete problem, different partition: equal to the Newton tolerance.
        assert world[key] == pytest.approx(reference[key], rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("name, value, match", [
    ("alpha", 0.0, "alpha must be > 0"),
    ("alpha_d", -1.0, "alpha_d must be > 0"),
    ("mu_d", 0.0, "mu_d must be > 0"),
    ("mu", -0.1, "mu must be >= 0"),
    ("nu", -1.0, "nu must be >= 0"),
    ("alpha", lambda s: 1.0 - 2.0 * s, "alpha must be > 0"),
])
def test_bad_coefficients_are_named(name, value, match):
    with pytest.raises(ValueError, match=match):
        TorsionModel(TorsionParameters(**{name: value}), end_torsion=loads.step(1.0))


def test_bad_model_options_are_named():
    p = TorsionParameters()
    with pytest.raises(ValueError, match="unknown evolution variant 'global'"):
        TorsionModel(p, variant="global", end_torsion=loads.step(1.0))
    with pytest.raises(ValueError, match="exactly one of end_torsion"):
        TorsionModel(p)
    with pytest.raises(ValueError, match="mu_d must be a constant for the uniform variant"):
        TorsionModel(TorsionParameters(mu_d=lambda s: 1 + s), variant="uniform",
                     end_torsion=loads.step(1.0))
    with pytest.raises(ValueError, match="nu > 0"):
        TorsionModel(TorsionParameters(nu=0.1), end_rotation=loads.step(1.0))
    model = TorsionModel(p, n_cells=2, end_torsion=loads.step(1.0))
    with pytest.raises(ValueError, match="dt must be > 0"):
        TimeStepper(model.problem).run(0.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="t_end must be >"):
        TimeStepper(model.problem).run(0.0, -1.0, 0.1)
    with pytest.raises(ValueError, match="unknown time scheme 'rk4'"):
        TimeStepper(model.problem, "rk4")
