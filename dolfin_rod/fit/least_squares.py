"""Fitting scene parameters to a measured time series by least squares (docs/fitting.md).

    result = fit_scene(load_scene("scenes/torsion_creep.toml"), read_series("creep.csv"),
                       ["alpha_d", "mu_d"])
    result.status          # "identified" | "not identifiable" | "not converged"
    result.values, result.std_errors, result.correlation

The CSV's load drives the cheapest exact model the scene allows (``select_model``:
closed form or ODE, torsion PDE, 3-D rod; inputs.py says what load and response
are).  The parameters p are fitted as theta = log p by ``scipy.optimize.least_squares``
on the residuals r_i = model(t_i; p) - response_i.  At the optimum the Jacobian J is
recomputed by central differences (step H in theta) and

    Cov(p) = s^2 (J_p^T J_p)^{-1},   J_p = J diag(1/p),   s^2 = |r|^2 / (n - k),

n samples, k parameters; the standard errors are sqrt(diag Cov(p)), the correlation
matrix Cov_ij / (sigma_i sigma_j).  Identifiability (docs/fitting.md for the thresholds):
a parameter is **not identifiable** if the response does not depend on it (a zero column
of J), if J's columns are (numerically) linearly dependent (the smallest singular value
of J with unit columns below SINGULAR_RATIO times the largest: only combinations are
determined; for two parameters the identifiable monomial is named), or if its relative
standard error exceeds MAX_RELATIVE_ERROR.  Such parameters get no value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..run import march
from ..scenes import Scene, SceneError, build, select_model
from .inputs import (Experiment, FitInputError, MeasuredSeries, Parameter, experiment_of,
                     parse_parameters, raw_scene, trial_scene)

__all__ = ["FitError", "FitProblem", "FitResult", "fit_scene", "prepare_fit", "run_fit",
           "simulate_response", "identifiability",
           "SINGULAR_RATIO", "MAX_RELATIVE_ERROR"]

# J (unit columns) is numerically singular below this ratio of its extreme singular
# values: the central-difference J carries relative errors ~1e-6 (truncation H^2 = 1e-8,
# solver tolerance 1e-10 / H), so ratios under 1e-3 are indistinguishable from
# collinear columns; for two parameters the ratio is sqrt((1 - |rho|) / (1 + |rho|)),
# i.e. this is a correlation |rho| > 1 - 2e-6.
SINGULAR_RATIO = 1e-3
# sigma_p / p above this: the data do not fix even the order of magnitude of p (its
# 1-sigma interval in log p spans a factor e^2 ~ 7.4).
MAX_RELATIVE_ERROR = 1.0
H = 1e-4                  # central-difference step in log p (0.01 % of p)


@dataclass
class FitResult:
    """A fit's outcome; ``values``/``std_errors`` are None for unidentified parameters."""

    status: str
    parameters: list[str]
    paths: list[str]
    initial: list[float]
    values: list[float | None]
    std_errors: list[float | None]
    correlation: list[list[float]] | None
    residual_std: float
    n_data: int
    model: str
    reason: str
    method: str
    experiment: str
    message: str = ""
    unidentified: list[str] = field(default_factory=list)
    combination: str | None = None
    null_direction: dict[str, float] | None = None   # in log p, largest component 1
    evaluations: int = 0
    last_iterate: list[float] = field(default_factory=list)   # not an estimate (see status)
    times: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    data: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    fitted: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    def to_dict(self) -> dict:
        """JSON data (fit.json): everything but the curves, which are lists."""
        out = {k: v for k, v in self.__dict__.items() if not isinstance(v, np.ndarray)}
        out["curves"] = {"time": self.times.tolist(), "data": self.data.tolist(),
                         "fitted": self.fitted.tolist()}
        return out


def model_step(times: np.ndarray, scene_dt: float) -> float:
    """The model's step: a sampling interval h >= dt divided into ceil(h / dt) steps when
    the samples lie on a grid k h (then every sample is an output time), else the scene's
    dt (the response interpolated linearly between outputs): samples finer than dt cost
    nothing beyond the steps the dynamics need (issue 28 item 29)."""
    h = float(times[1] - times[0])
    on_grid = np.allclose(times / h, np.round(times / h), rtol=0, atol=1e-9)
    if h < scene_dt or not on_grid or not np.allclose(np.diff(times), h, rtol=1e-9, atol=0):
        return scene_dt
    return h / math.ceil(h / scene_dt - 1e-9)


def simulate_response(scene: Scene, model: str, experiment: Experiment, comm,
                      needed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """(times, response, method) of the scene run by ``model`` from t = 0 to t_end (the
    same on every rank: diagnostics are MPI-reduced).  ``needed``: the sample times the
    caller interpolates at; the response is then recorded only at the steps next to
    them (a diagnostic costs as much as a step; issue 30), the steps are the same."""
    sim = build(scene, model, comm)
    sim.start()
    rest = sim.diagnostics(0.0)
    e = experiment.direction

    def response(d: dict) -> float:
        if e is None:
            return d[experiment.response]
        key = experiment.response
        return sum((d[key + c] - (rest[key + c] if experiment.from_rest else 0.0)) * e[i]
                   for i, c in enumerate("xyz"))

    series = getattr(sim, "series", lambda: None)()
    if series is not None:                 # every output at once (the ODE's exact mode)
        return series["time"], response(series), sim.describe()
    from ..integrators.step_control import output_times
    times, values = [0.0], [response(rest)]
    tim = scene["time"]
    ts = getattr(sim, "ts", None) is not None     # PETSc TS: every accepted step
    kept = recorded_steps(np.array(output_times(tim["t_end"], tim["dt"])), needed)
    step = [0]

    def record(t: float) -> None:
        step[0] += 1
        if ts or kept[step[0]]:
            times.append(t)
            values.append(response(sim.diagnostics(t)))

    march(sim, tim, record)
    return np.array(times), np.array(values), getattr(sim, "describe", lambda: "")()


def recorded_steps(grid: np.ndarray, needed: np.ndarray | None) -> np.ndarray:
    """Which grid times linear interpolation at the ``needed`` times reads: grid[k] with
    a needed time strictly between grid[k-1] and grid[k+1] (the exact point when a needed
    time is a grid time, both neighbours otherwise), and the last (all if None)."""
    if needed is None:
        return np.ones(grid.size, bool)
    before = np.concatenate(([-np.inf], grid[:-1]))
    after = np.concatenate((grid[1:], [np.inf]))
    first = np.searchsorted(needed, before, side="right")    # first needed > grid[k-1]
    kept = (first < needed.size) & (needed[np.minimum(first, needed.size - 1)] < after)
    kept[-1] = True
    return kept


class FitProblem:
    """A validated fit (nothing run yet): r(theta) = model(t_i; exp(theta)) - response_i
    over the used rows; inf where the model fails (least_squares then shortens its
    step).  Rank 0's vector on every rank, so every rank takes the same steps."""

    def __init__(self, scene: Scene, data: MeasuredSeries, params: list[Parameter],
                 choice, comm):
        self.scene, self.data, self.params, self.choice, self.comm = (scene, data, params,
                                                                      choice, comm)
        self.model = choice.model
        self.base = raw_scene(scene)
        self.experiment = experiment_of(scene)
        self.dt = model_step(data.time, scene["time"]["dt"])
        # the rod's start() is the rest state before a load at t = 0, not its 0+ limit
        self.used = data.time > 0.0 if self.model == "rod" else np.ones(data.time.size, bool)
        self.evaluations = 0
        self.last_error = self.method = ""
        self.progress = None     # progress(evaluations, rms residual) after each model run

    def curve(self, p: np.ndarray) -> np.ndarray:
        """The model's response at the used sample times for parameters p."""
        self.evaluations += 1
        try:
            trial = trial_scene(self.base, self.scene, self.params, p, self.experiment,
                                self.data, self.dt)
            with np.errstate(over="ignore", invalid="ignore"):    # overflow: inf, below
                t, y, self.method = simulate_response(trial, self.model, self.experiment,
                                                      self.comm, self.data.time[self.used])
                out = np.interp(self.data.time[self.used], t, y)
        except (SceneError, RuntimeError, ArithmeticError) as err:   # RuntimeError:
            # IntegrationError, SolverError, the ODE's solve_ivp failure
            self.last_error = f"{type(err).__name__}: {err}"
            out = np.full(int(self.used.sum()), np.inf)
        out = np.where(np.isfinite(out), out, np.inf)
        out = self.comm.bcast(out, root=0)
        if self.progress is not None:
            r = out - self.data.response[self.used]
            self.progress(self.evaluations, float(np.sqrt(np.mean(r * r))))
        return out

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        return self.curve(np.exp(theta)) - self.data.response[self.used]


def central_jacobian(objective, theta: np.ndarray) -> np.ndarray:
    """d r / d theta by central differences with step H."""
    columns = []
    for i in range(theta.size):
        step = np.zeros_like(theta)
        step[i] = H
        columns.append((objective(theta + step) - objective(theta - step)) / (2 * H))
    return np.column_stack(columns)


@dataclass(frozen=True)
class Identifiability:
    """Which parameters the data determine; ``null`` the direction in log p along which
    the residual does not change (None if there is none)."""

    unidentified: tuple[int, ...]
    reason: str
    null: np.ndarray | None = None


def identifiability(J: np.ndarray, s: float) -> Identifiability:
    """Classify the parameters by J = d r / d log p at the optimum and the residual
    standard deviation s (module docstring: zero columns, collinear columns, relative
    standard errors)."""
    norms = np.linalg.norm(J, axis=0)
    scale = max(float(norms.max()), np.finfo(float).tiny)
    flat = np.flatnonzero(norms <= 1e-12 * scale)
    if flat.size:
        return Identifiability(tuple(flat), "the response does not depend on it")
    _, sv, vt = np.linalg.svd(J / norms, full_matrices=False)
    if sv[-1] < SINGULAR_RATIO * sv[0]:
        w = vt[-1] / norms                     # J (vt / norms) = 0: a null direction in log p
        w = w / np.abs(w).max()
        involved = tuple(np.flatnonzero(np.abs(w) > 0.05))
        return Identifiability(involved, f"J^T J is singular (singular value ratio "
                               f"{sv[-1] / sv[0]:.1e} < {SINGULAR_RATIO:g}): only "
                               "combinations are determined", w)
    cov = s ** 2 * np.linalg.inv(J.T @ J)     # Cov(log p)
    relative = np.sqrt(np.diag(cov))
    loose = tuple(np.flatnonzero(relative > MAX_RELATIVE_ERROR))
    if loose:
        _, vecs = np.linalg.eigh(cov)
        w = vecs[:, -1] / np.abs(vecs[:, -1]).max()
        shown = ", ".join(f"{relative[i]:.2g}" for i in loose)
        return Identifiability(loose, f"relative standard error above "
                               f"{MAX_RELATIVE_ERROR:g} ({shown})", w)
    return Identifiability((), "")


def combination(names: list[str], w: np.ndarray | None, p: np.ndarray) -> str | None:
    """The monomial the data determine when the null direction w involves two parameters:
    p_a^(w_b) p_b^(-w_a) is constant along log p + t w (normalised to p_a^1); with its
    value at the last iterate p (a local statement: w is J's null direction there)."""
    if w is None:
        return None
    big = np.flatnonzero(np.abs(w) > 0.05)
    if big.size != 2:
        return None
    a, b = big
    exponent = -w[a] / w[b]
    return f"{names[a]} * {names[b]}^{exponent:.4g} = {p[a] * p[b] ** exponent:.6g}"


def covariance(J: np.ndarray, s: float, p: np.ndarray) -> np.ndarray:
    """Cov(p) = s^2 (J_p^T J_p)^{-1} with J_p = J diag(1/p) (J = d r / d log p)."""
    Jp = J / p
    return s ** 2 * np.linalg.inv(Jp.T @ Jp)


class FitError(RuntimeError):
    """The model cannot be evaluated at the initial parameters (exit status 3)."""


def prepare_fit(scene: Scene, data: MeasuredSeries, params: list[str] | str,
                comm=None) -> FitProblem:
    """Check everything a fit needs without running a model: the model choice, the
    parameters (inputs.py), the experiment, enough rows.  FitInputError/SceneError."""
    from mpi4py import MPI
    names = params.split(",") if isinstance(params, str) else list(params)
    choice = select_model(scene)
    if scene["initial"]["from_run"] is not None:
        raise scene.error("initial.from_run", "a fit runs its trials from the scene's own "
                          "initial state; a saved state was computed with the saved run's "
                          "parameters, not the trial's")
    if scene.rods:
        raise scene.error("rods", "a fit drives one rod by the data's load and compares its "
                                  "tip: a scene of [[rods]] is not fitted (the load would "
                                  "reach every rod that inherits [loads])")
    parameters = parse_parameters(names, scene, raw_scene(scene))
    problem = FitProblem(scene, data, parameters, choice, comm or MPI.COMM_WORLD)
    for p in parameters:
        if p.path.startswith(problem.experiment.load_key) or p.keys[0] == "time":
            raise FitInputError(f"parameter {p.name!r}: {p.path} is set by the fit from the "
                                "data (the load history, the time span), not a parameter")
    n, k = int(problem.used.sum()), len(parameters)
    if n <= k:
        raise FitInputError(f"{data.source}: {n} usable rows for {k} parameters: need "
                            "more rows than parameters")
    try:      # the scene with the data's load and time span, at the initial values
        trial_scene(problem.base, scene, parameters, [p.initial for p in parameters],
                    problem.experiment, data, problem.dt)
    except SceneError as err:
        raise FitInputError(f"{data.source}: the scene cannot run the data's load and "
                            f"time span (t = 0 .. {data.time[-1]:g}, step {problem.dt:g}): "
                            f"[{err.key}]: {err.reason}") from None
    return problem


def run_fit(problem: FitProblem, max_evaluations: int = 200) -> FitResult:
    """Least squares from the scene's values, then the covariance and identifiability at
    the optimum; FitError if the model fails at the initial parameters or where the
    least-squares Jacobian needs it."""
    from scipy.optimize import least_squares
    theta0 = np.log([p.initial for p in problem.params])
    if not np.all(np.isfinite(problem(theta0))):
        raise FitError(f"the {problem.choice.model} model fails at the initial parameters: "
                       f"{problem.last_error or 'non-finite response'}")
    try:
        res = least_squares(problem, theta0, method="trf", diff_step=1e-6, x_scale=1.0,
                            ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=max_evaluations)
    except ValueError as err:     # a model failure inside scipy's finite differences
        raise FitError(f"the {problem.choice.model} model failed during the fit "
                       f"({problem.last_error or err}); try other initial values") from err
    r = problem(res.x)
    s = float(np.sqrt(r @ r / (r.size - res.x.size)))
    return _result(problem, res, r, s, central_jacobian(problem, res.x))


def fit_scene(scene: Scene, data: MeasuredSeries, params: list[str] | str,
              comm=None, max_evaluations: int = 200) -> FitResult:
    """Fit ``params`` (names, inputs.py) of ``scene`` to ``data`` (read_series).

    Bad input raises FitInputError or SceneError before the model runs; a model that
    fails at the initial parameters raises FitError.  Every rank returns the same result.
    """
    return run_fit(prepare_fit(scene, data, params, comm), max_evaluations)


def _result(problem: FitProblem, res, r, s, J) -> FitResult:
    parameters, choice = problem.params, problem.choice
    names = [p.name for p in parameters]
    p = np.exp(res.x)
    ident = identifiability(J, s) if np.all(np.isfinite(J)) else Identifiability(
        tuple(range(len(p))), "the model fails next to the optimum")
    keep = [i for i in range(len(p)) if i not in ident.unidentified]
    values, errors = [None] * len(p), [None] * len(p)
    correlation = None
    if keep:
        cov = covariance(J[:, keep], s, p[keep])
        sigma = np.sqrt(np.diag(cov))
        for j, i in enumerate(keep):
            values[i], errors[i] = float(p[i]), float(sigma[j])
        corr = cov / np.outer(sigma, sigma) if np.all(sigma > 0) else np.eye(len(keep))
        correlation = [[None] * len(p) for _ in p]      # None: an unidentified parameter
        for a, i in enumerate(keep):
            for b, j in enumerate(keep):
                correlation[i][j] = float(corr[a, b])
    unidentified = [names[i] for i in ident.unidentified]
    status, message = "identified", ""
    if unidentified:
        status = "not identifiable"
        message = f"{', '.join(unidentified)}: {ident.reason}" + (
            f"; the other values are conditional on {', '.join(unidentified)} held at "
            f"{'its' if len(unidentified) == 1 else 'their'} last iterate" if keep else "")
    elif res.status <= 0:
        status, message = "not converged", res.message
    null = None if ident.null is None else dict(zip(names, map(float, ident.null)))
    return FitResult(
        status=status, parameters=names, paths=[q.path for q in parameters],
        initial=[q.initial for q in parameters], values=values, std_errors=errors,
        correlation=correlation, residual_std=s, n_data=int(r.size), model=choice.model,
        reason=choice.reason, method=problem.method,
        experiment=problem.experiment.description, message=message,
        unidentified=unidentified, combination=combination(names, ident.null, p),
        null_direction=null, evaluations=problem.evaluations,
        last_iterate=[float(x) for x in p],
        times=problem.data.time[problem.used], data=problem.data.response[problem.used],
        fitted=r + problem.data.response[problem.used])
