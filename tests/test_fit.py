"""Fitting scene parameters to measured time series (dolfin_rod.fit, ``dolfin-rod fit``).

Synthetic data come from the closed forms of Section 5 (closed_forms.creep, .relaxation,
.creep_inviscid: independent of the scene models the fit runs) with known parameters and
seeded Gaussian noise of standard deviation SD; the fit must recover the parameters
within 3 stated standard errors (a 3-sigma test fails by chance with probability
~0.3 % per parameter for the fixed seeds used, i.e. it is deterministic here), and the
stated standard errors must match the scatter of the estimates over seeds.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from dolfin_rod import closed_forms
from dolfin_rod.fit.least_squares import FitError, fit_scene
from dolfin_rod.fit.inputs import FitInputError, MeasuredSeries, check_series, read_series
from dolfin_rod.scenes import SceneError, load_scene, parse_scene
from test_cli import ROOT, cli

EXAMPLES = ROOT / "examples" / "fit"
TRUE = {"alpha": 2.0, "alpha_d": 1.0, "mu": 0.2, "mu_d": 0.5}
SD = 0.01


def creep_data(t, seed: int, sd: float = SD) -> MeasuredSeries:
    """End rotation under a step end torsion m0 = 1 (eq. creepform), plus noise."""
    u, _ = closed_forms.creep(t, 1.0, *TRUE.values())
    noise = np.random.default_rng(seed).normal(0, sd, t.size)
    return MeasuredSeries(t, np.ones_like(t), u + noise)


def relaxation_data(t, seed: int, u0: float = 0.5) -> MeasuredSeries:
    """End torsion under a step end rotation u0 (eq. stressrelax), plus noise."""
    _, m = closed_forms.relaxation(t, u0, TRUE["alpha"], TRUE["alpha_d"], TRUE["mu_d"])
    noise = np.random.default_rng(seed).normal(0, SD, t.size)
    return MeasuredSeries(t, np.full_like(t, u0), m + noise)


def grid(t_end: float, h: float) -> np.ndarray:
    return np.round(np.arange(0.0, t_end + 1e-9, h), 10)


def assert_within_3_sigma(result, names):
    assert result.status == "identified", result.message
    for name, value, sigma in zip(result.parameters, result.values, result.std_errors):
        assert name in names
        assert abs(value - TRUE[name]) < 3 * sigma, (name, value, sigma)


@pytest.mark.mpi
def test_creep_recovers_all_four_parameters():
    """Creep with mu > 0 determines alpha, alpha_d, mu and mu_d: the transfer function
    u/m = (mu_d s + a + a_d) / (mu mu_d s^2 + (mu (a + a_d) + a mu_d) s + a a_d) has four
    independent coefficients, one per parameter."""
    scene = load_scene(EXAMPLES / "creep.toml", {"material.alpha": 1.5, "material.mu": 0.3})
    result = fit_scene(scene, creep_data(grid(3.0, 0.05), seed=1), "alpha,alpha_d,mu,mu_d")
    assert result.model == "ode" and "closed_forms.creep" in result.method
    assert_within_3_sigma(result, TRUE)
    # noise sd 0.01: s^2 estimates SD^2 with relative sd sqrt(2 / (n - k)) = 0.19
    assert abs(result.residual_std / SD - 1) < 3 * np.sqrt(0.5 / (result.n_data - 4))
    corr = np.array(result.correlation, dtype=float)
    assert np.allclose(np.diag(corr), 1.0) and np.allclose(corr, corr.T)


@pytest.mark.mpi
def test_relaxation_recovers_alpha_alpha_d_mu_d():
    """Eq. stressrelax fixes m(0+) = alpha u0, m(inf) = alpha alpha_d u0 / (alpha +
    alpha_d) and the rate (alpha + alpha_d) / mu_d: three parameters, three features."""
    scene = load_scene(EXAMPLES / "relaxation.toml")
    result = fit_scene(scene, relaxation_data(grid(3.0, 0.05), seed=2), "alpha,alpha_d,mu_d")
    assert result.model == "ode" and "closed_forms.relaxation" in result.method
    assert_within_3_sigma(result, TRUE)


def test_standard_errors_match_the_scatter_over_seeds():
    """40 noisy creep curves: the sample sd of the estimates must equal the mean stated
    standard error.  The sample sd of N = 40 normal estimates has relative sd
    1/sqrt(2 (N - 1)) = 0.11, so 3 of those (0.34) bound the difference; the
    linearisation error is O(sigma/p) = 1 %.  And the root mean square of s is SD to
    3 sqrt(1 / (2 N (n - k))) = 4 %."""
    t = grid(3.0, 0.1)
    scene = load_scene(EXAMPLES / "creep.toml")
    fits = [fit_scene(scene, creep_data(t, seed), "alpha_d,mu_d") for seed in range(40)]
    values = np.array([f.values for f in fits])
    stated = np.array([f.std_errors for f in fits]).mean(axis=0)
    scatter = values.std(axis=0, ddof=1)
    assert np.all(np.abs(scatter / stated - 1) < 3 / np.sqrt(2 * 39)), (scatter, stated)
    assert np.all(np.abs(values.mean(axis=0) - [TRUE["alpha_d"], TRUE["mu_d"]])
                  < 3 * stated / np.sqrt(40))
    rms = np.sqrt(np.mean([f.residual_std ** 2 for f in fits]))
    assert abs(rms / SD - 1) < 3 * np.sqrt(1 / (2 * 40 * (t.size - 2)))


def test_a_load_that_is_not_a_step_drives_the_ode_as_a_table():
    """mu = 0 creep under a ramp to m = 1 over t in [0, 0.5], then held: data from the
    convolution of docs/corrections.md item 3 (closed_forms.creep_response, quadrature to 1e-10); the
    CSV's load becomes a table history (its kinks are sample times, so the linear
    interpolation is the ramp) solved by solve_ivp between the kinks (rtol 1e-10).
    Without noise the fit must return the truth to 1e-6 (both references are accurate to
    ~1e-10 and the sensitivities are O(1): measured 7e-10); with noise within 3 sigma."""
    t = grid(3.0, 0.05)
    ramp = lambda s: min(s / 0.5, 1.0)                         # noqa: E731
    u, _ = closed_forms.creep_response(t, ramp, TRUE["alpha"], TRUE["alpha_d"], TRUE["mu_d"])
    scene = load_scene(EXAMPLES / "creep.toml", {"material.mu": 0.0})
    load = np.array([ramp(s) for s in t])
    exact = fit_scene(scene, MeasuredSeries(t, load, u), "alpha_d,mu_d")
    assert "solve_ivp" in exact.method
    assert np.allclose(exact.values, [TRUE["alpha_d"], TRUE["mu_d"]], rtol=1e-6, atol=0)
    noisy = MeasuredSeries(t, load, u + np.random.default_rng(8).normal(0, SD, t.size))
    assert_within_3_sigma(fit_scene(scene, noisy, "alpha_d,mu_d"), TRUE)


@pytest.mark.mpi
def test_mu_is_not_identifiable_from_a_step_relaxation():
    """The regular part of eq. stressrelax (what sampled data at t >= 0+ contain) does
    not contain mu: the Kelvin-Voigt viscosity only weighs the impulse mu u0 delta(t) at
    t = 0.  So {mu, mu_d} from one step relaxation: mu gets no number, mu_d is found."""
    scene = load_scene(EXAMPLES / "relaxation.toml")
    result = fit_scene(scene, relaxation_data(grid(3.0, 0.05), seed=3), "mu,mu_d")
    assert result.status == "not identifiable"
    assert result.unidentified == ["mu"] and result.values[0] is None
    assert result.std_errors[0] is None and "does not depend" in result.message
    assert abs(result.values[1] - TRUE["mu_d"]) < 3 * result.std_errors[1]


@pytest.mark.mpi
def test_late_relaxation_determines_only_the_series_stiffness():
    """Sampled after the relaxation (t >= 5, exp(-(alpha + alpha_d) t / mu_d) = 1e-13),
    eq. stressrelax is m = K u0 with K = alpha alpha_d / (alpha + alpha_d): only K is
    identifiable.  Along the null direction w (in log p) K is constant:
    dK/dlog alpha = K alpha_d/(alpha + alpha_d), dK/dlog alpha_d = K alpha/(alpha +
    alpha_d), so w ~ (alpha, -alpha_d) at the last iterate, and K there must match the
    data (m/u0 averaged over n samples: sd SD/(u0 sqrt(n)))."""
    t = np.round(np.arange(5.0, 10.0 + 1e-9, 0.1), 10)
    scene = load_scene(EXAMPLES / "relaxation.toml")
    result = fit_scene(scene, relaxation_data(t, seed=4), "alpha,alpha_d")
    assert result.status == "not identifiable" and result.values == [None, None]
    assert sorted(result.unidentified) == ["alpha", "alpha_d"]
    a, ad = result.last_iterate
    w = result.null_direction
    assert w["alpha"] / w["alpha_d"] == pytest.approx(-a / ad, rel=1e-3)
    K = a * ad / (a + ad)
    K_true = TRUE["alpha"] * TRUE["alpha_d"] / (TRUE["alpha"] + TRUE["alpha_d"])
    assert abs(K - K_true) < 3 * SD / (0.5 * np.sqrt(t.size))
    assert result.combination.startswith("alpha * alpha_d^")


@pytest.mark.mpi
def test_fit_through_the_torsion_pde():
    """The same creep data fitted through TorsionModel (forced, 4 cells (two per rank under mpirun -n 2), BDF2 at
    dt = 0.0125) and through the closed form: the PDE's O(dt^2) error (measured 1e-3 of
    the values) moves the estimates by far less than their standard errors (< 0.2 sigma)
    and both recover the truth within 3 sigma."""
    data = creep_data(grid(1.0, 0.05), seed=5)
    exact = fit_scene(load_scene(EXAMPLES / "creep.toml"), data, "alpha_d,mu_d")
    scene = load_scene(EXAMPLES / "creep.toml", {"scene.model": "torsion",
                                                 "geometry.n_cells": 4, "time.dt": 0.0125})
    pde = fit_scene(scene, data, "alpha_d,mu_d")
    assert pde.model == "torsion" and "TimeStepper" in pde.method
    assert_within_3_sigma(pde, TRUE)
    for v_pde, v_ode, sigma in zip(pde.values, exact.values, exact.std_errors):
        assert abs(v_pde - v_ode) < 0.2 * sigma


def test_fit_through_the_rod():
    """A quasi-static cantilever (scenes/cantilever_creep.toml, 8 cells) under a small
    step end force F = 1e-3 along x; the tip deflection is exact to ~1e-6 relative
    (tests/test_cli.py, test_run_cantilever_rod: complementary energy, 1-point rule)

        delta(t) = F L^3/3 (1 - 1/(4 N^2)) c(t; A, A_d, M_d) + F L c(t; B, B_d, N_d),

    c = closed_forms.creep_inviscid.  Data from M_d,22 = 0.5 (bending about d2) with noise
    1e-5 (3 % of delta): the fit of material.viscosity.M_d[1] recovers it within 3 sigma.
    BDF2 at dt = 0.05 errs by ~6e-4 of delta (test_cli), 0.02 of the noise: no bias."""
    F, t = 1e-3, grid(1.0, 0.05)
    bend, _ = closed_forms.creep_inviscid(t, 1.0, 1.0, 1.0, 0.5)
    shear, _ = closed_forms.creep_inviscid(t, 1.0, 100.0, 100.0, 1.0)
    delta = F / 3 * (1 - 1 / (4 * 8 ** 2)) * bend + F * shear
    data = MeasuredSeries(t, np.full_like(t, F),
                          delta + np.random.default_rng(6).normal(0, 1e-5, t.size))
    scene = load_scene(ROOT / "scenes" / "cantilever_creep.toml")
    result = fit_scene(scene, data, "material.viscosity.M_d[1]")
    assert result.model == "rod" and result.status == "identified", result.message
    assert result.n_data == t.size - 1            # the row at t = 0 is not used (rod)
    assert abs(result.values[0] - 0.5) < 3 * result.std_errors[0]


STEEL_CANTILEVER = """
[geometry]
length = 1.0
n_cells = 8
[section]
shape = "circle"
radius = 0.01
[material]
model = "hyperelastic"
youngs_modulus = 1.5e11
poisson_ratio = 0.3
[loads]
end_force = { type = "step", value = [1.0, 0.0, 0.0] }
[time]
t_end = 1.0
dt = 0.1
"""


def test_a_tensor_derived_from_the_physical_input_names_the_key_to_fit():
    """A second user trial: fitting material.stiffness.A[0] of a scene that gives
    youngs_modulus and a [section] said only "not a key of this rod scene".  The message
    says A is derived and names material.youngs_modulus; fitting that recovers E from a
    steel cantilever's tip deflection under F = 1 N (8 cells, 1-point rule, as
    test_fit_through_the_rod):

        delta = F L^3 / (3 E I) (1 - 1/(4 N^2)) + F L / (k G a),   I = pi r^4 / 4,

    k = the section's shear factor (summary "derived"), G = E / (2 (1 + nu)).  delta/L =
    2e-4: the geometric nonlinearity (delta/L)^2 ~ 4e-8 is far below the data's noise
    (1e-3 relative), so E = 2e11 Pa must be recovered within 3 stated standard errors."""
    scene = parse_scene(STEEL_CANTILEVER, "steel.toml")
    E, nu, r, F, N = 2e11, 0.3, 0.01, 1.0, 8
    k = scene["material"]["derived"]["shear_factors"][0]
    delta = (F / (3 * E * np.pi * r ** 4 / 4) * (1 - 1 / (4 * N ** 2))
             + F / (k * E / (2 * (1 + nu)) * np.pi * r ** 2))
    t = grid(1.0, 0.1)
    noise = np.random.default_rng(1).normal(0, 1e-3, t.size)
    data = MeasuredSeries(t, np.full_like(t, F), delta * (1 + noise))
    with pytest.raises(FitInputError, match="derived from this scene's physical input.*"
                                            "fit material.youngs_modulus"):
        fit_scene(scene, data, "material.stiffness.A[0]")
    sinking = parse_scene(STEEL_CANTILEVER.replace("[loads]", "fluid_viscosity = 1.0\n[loads]"),
                          "sinking.toml")      # slender-body drag from the viscosity
    with pytest.raises(FitInputError, match="fit material.fluid_viscosity"):
        fit_scene(sinking, data, "material.drag[0]")
    result = fit_scene(scene, data, "material.youngs_modulus")
    assert result.status == "identified", result.message
    assert abs(result.values[0] - E) < 3 * result.std_errors[0]


def test_fit_through_the_rod_reaction_couple():
    """scenes/twisted_rod_relaxation.toml (SI units) with 4 cells: a quarter turn Phi0
    held at s = L, the reaction couple about e_3 relaxes as eq. stressrelax with
    alpha = GJ, alpha_d = A_d,33, mu_d = M_d,33 and the discrete twist
    u_h = 4 tan(dphi/4)/h (demos/twisted_rod_relaxation.py derives both).  Data: 21
    samples on [0, 20 s] with noise 1 % of m(0+); the fit of M_d[2] recovers it within
    3 sigma (BDF2 at dt = 0.5 s, k dt = 0.025: the noise-free fit is off by 0.2 %, sigma
    is ~3 %)."""
    GJ, A_d, M_d = 0.0009817477042468104, 0.0004908738521234052, 0.029452431127404314
    L, N, Phi0 = 0.5, 4, np.pi / 2
    u_h = 4 * np.tan(Phi0 / N / 4) / (L / N)
    t = grid(20.0, 1.0)
    _, m = closed_forms.relaxation(t, u_h, GJ, A_d, M_d)
    sd = 0.01 * GJ * Phi0 / L
    data = MeasuredSeries(t, np.full_like(t, Phi0),
                          m + np.random.default_rng(9).normal(0, sd, t.size))
    scene = load_scene(ROOT / "scenes" / "twisted_rod_relaxation.toml",
                       {"geometry.n_cells": N})
    result = fit_scene(scene, data, "M_d[2]")
    assert "reaction couple" in result.experiment and result.status == "identified"
    assert result.paths == ["material.viscosity.M_d[2]"]
    assert abs(result.values[0] - M_d) < 3 * result.std_errors[0]


def test_a_rod_fit_needs_one_load():
    scene = load_scene(ROOT / "scenes" / "gravity_cantilever.toml")
    with pytest.raises(FitInputError, match="a rod fit needs exactly one of"):
        fit_scene(scene, creep_data(grid(1.0, 0.1), 0), "material.relaxation_time")


# --- bad input ---------------------------------------------------------------------------


def write_csv(path, header, rows):
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


@pytest.mark.parametrize("header, rows, message", [
    ("time,load", ["0,1"], "missing column(s) response"),
    ("time,load,response", ["0,1,0", "0.1,1,nan"], "row 3, column response: must be finite"),
    ("time,load,response", ["0,1,0", "0.1,1,x"], "row 3, column response: not a number"),
    ("time,load,response", ["0,1,0", "0.2,1,0", "0.1,1,0"],
     "row 4, column time: times must be strictly increasing"),
    ("time,load,response", ["-1,1,0", "0,1,0"], "row 2, column time: must be >= 0"),
    ("time,load,response", ["0,1,0"], "need at least 2 rows"),
])
def test_bad_csv_names_the_column_and_row(tmp_path, header, rows, message):
    with pytest.raises(FitInputError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_series(write_csv(tmp_path / "d.csv", header, rows))


def test_csv_variants_read_as_the_same_numbers(tmp_path):
    """The rows parsed by numpy (issue 28 item 29): Windows line ends, quoted numbers,
    spaces, blank lines, columns in any order with others around them: the same table."""
    texts = ["time,load,response\n0,1,2\n0.5,1,3\n",
             "time,load,response\r\n0,1,2\r\n0.5,1,3\r\n",
             'note,response,time,load\nx,"2",0,1\n\ny,3, 0.5 ,1\n   \n']
    for k, text in enumerate(texts):
        (tmp_path / f"{k}.csv").write_text(text, newline="")
        data = read_series(tmp_path / f"{k}.csv")
        assert data.time.tolist() == [0.0, 0.5] and data.load.tolist() == [1.0, 1.0]
        assert data.response.tolist() == [2.0, 3.0], k


def test_samples_finer_than_dt_cost_only_the_scenes_steps():
    """Data sampled 10x finer than the scene's dt (issue 28 item 29: the model stepped
    once per row): the torsion PDE steps at dt (prepare_fit's step) and its response is
    interpolated at the rows.  At the times of the dt grid it equals the run for data on
    that grid (the same steps, 1e-12); there it is the closed form (eq. creepform) to the
    PDE's error (measured 3.3e-3 at the first step, BDF2's backward-Euler start; bound
    5e-3 on values of order 1), and between them to that plus
    linear interpolation's dt^2/8 max |u''| (u'' of the closed form by differences)."""
    from dolfin_rod.fit.least_squares import prepare_fit
    scene = load_scene(EXAMPLES / "creep.toml", {"scene.model": "torsion",
                                                 "geometry.n_cells": 4, "time.dt": 0.0125})
    fine, coarse = creep_data(grid(1.0, 0.00125), seed=5), creep_data(grid(1.0, 0.0125), 5)
    problems = [prepare_fit(scene, data, "alpha_d,mu_d") for data in (fine, coarse)]
    assert [p.dt for p in problems] == [0.0125, 0.0125]
    true = np.array([TRUE["alpha_d"], TRUE["mu_d"]])
    on_fine, on_coarse = (p.curve(true) for p in problems)
    shared = np.isin(fine.time, coarse.time)
    assert shared.sum() == coarse.time.size
    assert np.allclose(on_fine[shared], on_coarse, rtol=1e-12, atol=1e-14)
    exact, _ = closed_forms.creep(fine.time, 1.0, *TRUE.values())
    on_grid = np.abs(on_fine - exact)[shared].max()
    assert on_grid < 5e-3, on_grid
    curvature = np.abs(np.diff(exact, 2)).max() / 0.00125 ** 2      # max |u''|
    bound = on_grid + 0.0125 ** 2 / 8 * curvature
    assert np.abs(on_fine - exact).max() <= bound, (np.abs(on_fine - exact).max(), bound)


def test_nan_in_a_series_from_python():
    t = grid(1.0, 0.1)
    y = np.where(t == 0.5, np.nan, t)
    with pytest.raises(FitInputError, match="row 7, column response"):
        check_series(MeasuredSeries(t, np.ones_like(t), y))


@pytest.mark.parametrize("params, message", [
    ("alpha_q", "'alpha_q': alpha_q is not a key"),
    ("material.viscosity.M_d[1]", "not a key of this torsion scene"),
    ("alpha,alpha", "given twice"),
    ("material.mu[", "not a key path"),
    ("nu", "initial value must be > 0"),
    ("loads.end_torsion.value", "is set by the fit from the data"),
])
def test_bad_parameter_is_refused_before_any_model_runs(params, message):
    scene = load_scene(EXAMPLES / "creep.toml")
    with pytest.raises(FitInputError, match=message.replace("[", r"\[")):
        fit_scene(scene, creep_data(grid(1.0, 0.1), 0), params)


@pytest.mark.parametrize("params, message", [
    # were "material.stiffness.A_d is not a key of this rod scene", which it is
    ("material.stiffness.A_d[5]", "'material.stiffness.A_d[5]': material.stiffness.A_d has "
                                  "3 entries in this scene (indices 0 to 2), got [5]"),
    ("A_d[1][0]", "'A_d[1][0]': material.stiffness.A_d[1] is a number in this scene, not "
                  "an array: drop the index [0]"),
    ("material.stiffness.A_q[0]", "material.stiffness.A_q is not a key of this rod scene"),
])
def test_bad_rod_parameter_index_is_named(params, message):
    """cantilever_creep.toml gives A_d = [1, 1, 1] (diagonal): an index past its end or
    one index too many is said as such, before any model runs."""
    scene = load_scene(ROOT / "scenes" / "cantilever_creep.toml")
    t = grid(1.0, 0.1)
    with pytest.raises(FitInputError, match=re.escape(message)):
        fit_scene(scene, MeasuredSeries(t, np.full_like(t, 0.1), 0.01 + 0.01 * t), params)


def test_a_fit_does_not_start_from_a_saved_state():
    """Each trial must run from the scene's own start: [initial] from_run is refused
    naming the key, before any model runs (the folder is not even read)."""
    scene = load_scene(EXAMPLES / "creep.toml", {"scene.model": "torsion",
                                                 "initial.from_run": "results/nowhere"})
    with pytest.raises(SceneError, match=r"\[initial.from_run\]: a fit runs its trials"):
        fit_scene(scene, creep_data(grid(1.0, 0.05), seed=5), "alpha_d,mu_d")


def test_rod_parameter_naming():
    """A diagonal tensor's entry [i]; a whole tensor is not a number."""
    scene = load_scene(ROOT / "scenes" / "cantilever_creep.toml")
    with pytest.raises(FitInputError, match="not a number"):
        fit_scene(scene, creep_data(grid(1.0, 0.1), 0), "M_d")
    with pytest.raises(FitInputError, match="must be > 0"):
        fit_scene(scene, creep_data(grid(1.0, 0.1), 0), "material.viscosity.M[0]")


def test_model_failure_at_the_initial_parameters():
    """A response that overflows (a load of 1e308 creeps towards 1.5e308 = inf) is a
    model failure (FitError; exit 3 on the command line), not a fit."""
    scene = load_scene(EXAMPLES / "creep.toml")
    data = MeasuredSeries(grid(1.0, 0.1), np.full(11, 1e308), np.zeros(11))
    with pytest.raises(FitError, match="fails at the initial parameters"):
        fit_scene(scene, data, "alpha_d")


# --- the command line --------------------------------------------------------------------


def test_cli_round_trip(tmp_path):
    out = cli("fit", EXAMPLES / "creep.toml", EXAMPLES / "creep.csv",
              "--params", "alpha_d,mu_d", "--out", tmp_path / "fit")
    assert out.returncode == 0, out.stderr
    assert "identified: results in" in out.stdout and "std error" in out.stdout
    result = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert result["status"] == "identified" and result["model"] == "ode"
    assert result["parameters"] == ["alpha_d", "mu_d"] and result["initial"] == [2.0, 1.0]
    for name, value, sigma in zip(result["parameters"], result["values"], result["std_errors"]):
        assert abs(value - TRUE[name]) < 3 * sigma
    data = read_series(EXAMPLES / "creep.csv")
    assert result["curves"]["time"] == data.time.tolist() and result["n_data"] == 61
    assert (tmp_path / "fit" / "fit.png").stat().st_size > 10_000


@pytest.mark.parametrize("args, message", [
    (["--params", "alpha_q"], "parameter 'alpha_q'"),
    (["--params", "alpha_d", "DATA=bad.csv"], "missing column(s) response"),
    (["--params", "alpha_d", "DATA=nan.csv"], "row 3, column response: must be finite"),
])
def test_cli_bad_input_exits_2(tmp_path, args, message):
    write_csv(tmp_path / "bad.csv", "time,load", ["0,1", "1,1"])
    write_csv(tmp_path / "nan.csv", "time,load,response", ["0,1,0", "1,1,nan"])
    data = next((tmp_path / a[5:] for a in args if a.startswith("DATA=")),
                EXAMPLES / "creep.csv")
    args = [a for a in args if not a.startswith("DATA=")]
    out = cli("fit", EXAMPLES / "creep.toml", data, *args, "--out", tmp_path / "fit")
    assert out.returncode == 2, out.stdout + out.stderr
    assert "Traceback" not in out.stderr and message in out.stderr
    assert out.stderr.count("\n") == 1 and not (tmp_path / "fit").exists()


def test_cli_under_mpirun_rank0_writes(tmp_path):
    """Two ranks: one table, one fit.json, the serial numbers (the same arithmetic on
    the same data: 1e-12); bad input exits 2 on every rank, said once."""
    out = cli("fit", EXAMPLES / "relaxation.toml", EXAMPLES / "relaxation.csv",
              "--params", "alpha,alpha_d,mu_d", "--out", tmp_path / "fit", mpi=2)
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("identified: results in") == 1
    assert out.stdout.count("parameter ") == 1
    result = json.loads((tmp_path / "fit" / "fit.json").read_text())
    serial = fit_scene(load_scene(EXAMPLES / "relaxation.toml"),
                       read_series(EXAMPLES / "relaxation.csv"), "alpha,alpha_d,mu_d")
    assert np.allclose(result["values"], serial.values, rtol=1e-12, atol=0)
    bad = cli("fit", EXAMPLES / "relaxation.toml", EXAMPLES / "relaxation.csv",
              "--params", "alpha,beta", mpi=2)
    assert bad.returncode == 2 and bad.stderr.count("parameter 'beta'") == 1


def test_a_model_failure_inside_the_least_squares_is_a_fit_error():
    """scipy's finite-difference Jacobian cannot take the infinite residual of a failed
    model run (ValueError from its SVD; seen with the DNA twist scene's first step at some
    trial viscosities): run_fit reports a FitError naming the model and its last error."""
    from types import SimpleNamespace

    from dolfin_rod.fit.least_squares import FitError, run_fit

    class FailsNextToTheStart:
        params = [SimpleNamespace(initial=1.0, name="p")]
        choice = SimpleNamespace(model="torsion")
        last_error = "SolverError: SNES failed"
        used = np.ones(5, bool)

        def __call__(self, theta):
            return np.full(5, 0.5) if theta[0] == 0.0 else np.full(5, np.inf)

    with pytest.raises(FitError, match="torsion model failed during the fit.*SNES failed"):
        run_fit(FailsNextToTheStart())


def test_trials_give_the_curve_of_a_fresh_model_run():
    """A fit's trials (issue 30: compiled kernels bound, not rebuilt; the start-state
    check remembered; the response recorded only at the steps next to the samples; no
    stability check) give the response of the scene run on its own, every step recorded
    and the stability check on: the same steps, so equal to round-off (1e-12 relative;
    the diagnostics only read the state).  The DNA twist example at 4 cells, two trials
    (the second of a structure already seen) at the scene's M_d,33 and 1.5 x it."""
    from mpi4py import MPI

    from dolfin_rod.fit.inputs import experiment_of
    from dolfin_rod.fit.least_squares import prepare_fit, simulate_response
    data = read_series(EXAMPLES / "dna_twist.csv")
    four = {"geometry.n_cells": 4}
    problem = prepare_fit(load_scene(EXAMPLES / "dna_twist.toml", four), data, "M_d[2]")
    for m_d in (616.5, 924.75):
        trial = problem.curve(np.array([m_d]))
        alone = load_scene(EXAMPLES / "dna_twist.toml",
                           {**four, "material.viscosity": {"M_d": [308.25, 308.25, m_d],
                                                           "N_d": [750.0, 750.0, 1.0]}})
        assert alone["stability"]["check"]
        t, y, _ = simulate_response(alone, "rod", experiment_of(alone), MPI.COMM_WORLD)
        assert t.size == 201                  # every step of dt = 0.025 up to t = 5
        fresh = np.interp(data.time[1:], t, y)
        assert np.allclose(trial, fresh, rtol=1e-12, atol=0), np.abs(trial - fresh).max()
