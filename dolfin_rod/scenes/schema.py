"""The TOML scene schema: parsing, defaults and validation.

A scene is one TOML file; every table and key is listed in ``SCHEMA`` below with its
type, default and rule.  Anything wrong with a scene (bad TOML, an unknown key, a wrong
type, a missing required value, a non-physical value, an inconsistent combination) is
reported as ONE :class:`SceneError` naming the file, the key path and the reason, e.g.

    scenes/bad.toml: [material.alpha]: must be > 0, got -1.0

Nothing else escapes :func:`load_scene` / :func:`parse_scene` (the test suite fuzzes
them with hypothesis).  Torsion scenes use the paper's dimensionless Section 5 variables
(alpha, alpha_d, mu, mu_d, nu, errata item 5); 3-D rod scenes use the tensors of the
quadratic energy (eq. ``quadenergy``) and the viscosities M, N, M_d, N_d.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .. import loads as load_histories
from ..integrators.schemes import get_scheme
from ..validation import profile_violation, sample_points

__all__ = ["SceneError", "Scene", "Coefficient", "HistorySpec", "load_scene", "parse_scene",
           "SCHEMA", "MODEL_NAMES", "path_problem"]

MODEL_NAMES = ("auto", "ode", "torsion", "rod")
VARIANTS = ("local", "uniform")
ENERGIES = ("quadratic", "kelvin_voigt")
CONSTRAINTS = ("none", "unshearable", "inextensible_unshearable")
HISTORY_TYPES = ("step", "ramp", "smooth_step", "table", "constant")


class SceneError(ValueError):
    """A scene cannot be used: ``source`` (file), ``key`` (dotted path) and ``reason``."""

    def __init__(self, source: str, key: str, reason: str):
        self.source, self.key, self.reason = str(source), key, reason
        where = f"[{key}]: " if key else ""
        super().__init__(f"{self.source}: {where}{reason}")


# --- value checkers: each returns the cleaned value or raises _Bad(reason) --------------


class _Bad(Exception):
    """Internal: a value broke a rule; turned into a SceneError with its key path."""

    def __init__(self, reason: str, key: str | None = None):
        super().__init__(reason)
        self.reason, self.key = reason, key


def _type_name(v: Any) -> str:
    return {bool: "boolean", int: "integer", float: "float", str: "string", list: "array",
            dict: "table"}.get(type(v), type(v).__name__)


def _number(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _Bad(f"must be a number, got {_type_name(v)} {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise _Bad(f"must be finite, got {v!r}")
    return x


def real(lo: float | None = None, lo_strict: bool = False, hi: float | None = None):
    def check(v):
        x = _number(v)
        if lo is not None and (x <= lo if lo_strict else x < lo):
            raise _Bad(f"must be {'>' if lo_strict else '>='} {lo:g}, got {x:g}")
        if hi is not None and x > hi:
            raise _Bad(f"must be <= {hi:g}, got {x:g}")
        return x
    return check


def integer(lo: int, hi: int | None = None):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise _Bad(f"must be an integer, got {_type_name(v)} {v!r}")
        if v < lo or (hi is not None and v > hi):
            raise _Bad(f"must be an integer in [{lo}, {hi if hi is not None else 'inf'}], got {v}")
        return v
    return check


def choice(*options: str):
    def check(v):
        if not isinstance(v, str):
            raise _Bad(f"must be a string, one of {', '.join(options)}; got {_type_name(v)}")
        if v not in options:
            raise _Bad(f"must be one of {', '.join(repr(o) for o in options)}, got {v!r}")
        return v
    return check


def string(v):
    if not isinstance(v, str):
        raise _Bad(f"must be a string, got {_type_name(v)} {v!r}")
    return v


NAME_MAX = 255     # bytes in one path component (POSIX file systems)
PATH_MAX = 4096    # bytes in a whole path (Linux)


def run_name(v):
    """A scene name is a folder name: letters, digits, '.', '_', '-', not starting with
    '.', so that it can never leave outputs.directory or nest folders."""
    v = string(v)
    if not v or v.startswith(".") or not all(c.isascii() and (c.isalnum() or c in "._-")
                                              for c in v):
        raise _Bad(f"must be a folder name of letters, digits, '.', '_', '-' (not starting "
                   f"with '.'), got {v!r}")
    if len(v) > 100:
        raise _Bad(f"must be at most 100 characters (it names the run folder), got {len(v)}")
    return v


def safe_name(stem: str) -> str:
    """The default scene name from a file stem: characters run_name refuses become '_'."""
    name = "".join(c if c.isascii() and (c.isalnum() or c in "._-") else "_" for c in stem)
    return name.lstrip(".")[:100] or "scene"


def path_problem(text: str) -> str | None:
    """Why ``text`` cannot be a file-system path (None if it can): empty, a NUL, a
    component longer than NAME_MAX or the whole longer than PATH_MAX bytes."""
    if not text:
        return "must be a non-empty path"
    if "\0" in text:
        return "must not contain a NUL character"
    encoded = text.encode("utf-8", "surrogateescape")
    if len(encoded) >= PATH_MAX:
        return f"is {len(encoded)} bytes long; paths are limited to {PATH_MAX - 1}"
    longest = max(encoded.split(b"/"), key=len)
    if len(longest) > NAME_MAX:
        return f"has a path component of {len(longest)} bytes; file systems allow {NAME_MAX}"
    return None


def path_text(v):
    problem = path_problem(string(v))
    if problem:
        raise _Bad(problem)
    return v


def boolean(v):
    if not isinstance(v, bool):
        raise _Bad(f"must be true or false, got {_type_name(v)} {v!r}")
    return v


def vector3(lo: float | None = None, lo_strict: bool = False):
    each = real(lo, lo_strict)

    def check(v):
        if not isinstance(v, list) or len(v) != 3:
            raise _Bad(f"must be an array of 3 numbers, got {v!r}")
        out = []
        for i, x in enumerate(v):
            try:
                out.append(each(x))
            except _Bad as bad:
                raise _Bad(f"entry {i} {bad.reason}") from None
        return tuple(out)
    return check


def scheme_name(v):
    v = string(v)
    try:
        get_scheme(v)
    except (ValueError, TypeError) as err:
        raise _Bad(str(err)) from None
    return v


@dataclass(frozen=True)
class Coefficient:
    """A material coefficient: a constant or a polynomial c0 + c1 s + c2 s^2 + ... in s."""

    constant: float | None = None
    polynomial: tuple[float, ...] = ()

    @property
    def is_constant(self) -> bool:
        return self.constant is not None

    def __call__(self, s):
        """Works on numpy arrays and on UFL expressions (Horner's rule)."""
        if self.constant is not None:
            return self.constant
        out = 0.0 * s + self.polynomial[-1]
        for c in reversed(self.polynomial[:-1]):
            out = out * s + c
        return out

    def value(self):
        """A float for TorsionParameters, or this callable for an s-dependent coefficient."""
        return self.constant if self.constant is not None else self

    def values(self, s: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.asarray(self(s), dtype=float), s.shape)


def coefficient(strict: bool):
    """A float, or {polynomial = [c0, c1, ...]} (s in [0, 1]); > 0 (strict) or >= 0."""

    def check(v):
        if isinstance(v, dict):
            c = Coefficient(polynomial=_polynomial(v))
            coeffs = c.polynomial
            s = sample_points(1.0)
            reason = profile_violation(c.values(s), s, strict)
            if reason:
                raise _Bad(f"{reason} (the polynomial)")
            if len(coeffs) == 1 or not any(coeffs[1:]):
                return Coefficient(constant=coeffs[0])
            return c
        return Coefficient(constant=real(0.0, lo_strict=strict)(v))
    return check


def _unknown(table: dict, known: set[str]) -> None:
    for k in table:
        if k not in known:
            raise _Bad(f"unknown key (known: {', '.join(sorted(known))})", k)


# --- load histories ----------------------------------------------------------------------


@dataclass(frozen=True)
class HistorySpec:
    """A load history as written in the scene: {type = ..., ...}."""

    type: str
    value: float | tuple[float, ...] = 0.0
    t0: float = 0.0            # step: time of the jump
    duration: float = 1.0      # ramp: time to reach value; smooth_step: width
    times: tuple[float, ...] = ()
    values: tuple[float, ...] = ()

    def build(self, component: int | None = None):
        """The loads.LoadHistory (component of a vector value if given)."""
        v = self.value if component is None else self.value[component]
        if self.type == "step":
            return load_histories.step(v, self.t0)
        if self.type == "ramp":
            return load_histories.ramp(v, self.duration)
        if self.type == "smooth_step":
            return load_histories.smooth_step(v, self.duration)
        if self.type == "constant":
            return load_histories.constant(v)
        return load_histories.table(self.times, self.values)

    @property
    def is_vector(self) -> bool:
        return isinstance(self.value, tuple)

    @property
    def jumps_at_start(self) -> bool:
        return self.type == "step" and self.t0 == 0.0 and self.value != 0.0

    def breakpoints(self) -> tuple[float, ...]:
        """Times where the history is not smooth (for the ODE integrator)."""
        if self.type == "step":
            return (self.t0,)
        if self.type in ("ramp", "smooth_step"):
            return (0.0, self.duration)
        if self.type == "table":
            return self.times
        return ()


_HISTORY_KEYS = {
    "step": {"value": True, "t0": False},
    "ramp": {"value": True, "duration": True},
    "smooth_step": {"value": True, "duration": True},
    "constant": {"value": True},
    "table": {"times": True, "values": True},
}


def history(vector_ok: bool):
    def check(v):
        if not isinstance(v, dict):
            raise _Bad(f"must be a table {{type = \"step\"|\"ramp\"|...}}, got {_type_name(v)}")
        if "type" not in v:
            raise _Bad(f"missing required key (one of {', '.join(HISTORY_TYPES)})", "type")
        try:
            kind = choice(*HISTORY_TYPES)(v["type"])
        except _Bad as bad:
            raise _Bad(bad.reason, "type") from None
        keys = _HISTORY_KEYS[kind]
        _unknown(v, {"type", *keys})
        for k, required in keys.items():
            if required and k not in v:
                raise _Bad(f"missing required key for a {kind} history", k)
        out: dict[str, Any] = {"type": kind}
        for k in keys:
            if k not in v:
                continue
            try:
                if k == "value":
                    out[k] = (vector3()(v[k]) if vector_ok and isinstance(v[k], list)
                              else _number(v[k]))
                elif k == "t0":
                    out[k] = real(0.0)(v[k])
                elif k == "duration":
                    out[k] = real(0.0, lo_strict=True)(v[k])
                else:
                    if not isinstance(v[k], list) or not v[k]:
                        raise _Bad("must be a non-empty array of numbers")
                    out[k] = tuple(_number(x) for x in v[k])
            except _Bad as bad:
                raise _Bad(bad.reason, k) from None
        if kind == "table":
            if len(out["times"]) != len(out["values"]):
                raise _Bad(f"times and values must have the same length, got "
                           f"{len(out['times'])} and {len(out['values'])}", "values")
            if any(b <= a for a, b in zip(out["times"], out["times"][1:])):
                raise _Bad("must be strictly increasing", "times")
        return HistorySpec(**out)
    return check


def _polynomial(v: dict) -> tuple[float, ...]:
    """The coefficients of {polynomial = [c0, c1, ...]}."""
    _unknown(v, {"polynomial"})
    if "polynomial" not in v:
        raise _Bad("missing required key", "polynomial")
    p = v["polynomial"]
    if not isinstance(p, list) or not p:
        raise _Bad("must be a non-empty array of numbers", "polynomial")
    try:
        return tuple(_number(c) for c in p)
    except _Bad as bad:
        raise _Bad(bad.reason, "polynomial") from None


def profile(v):
    """A load profile along s: a number or {polynomial = [...]}, of any sign (a couple
    density is a load, not a material modulus)."""
    if not isinstance(v, dict):
        return Coefficient(constant=_number(v))
    coeffs = _polynomial(v)
    if len(coeffs) == 1 or not any(coeffs[1:]):
        return Coefficient(constant=coeffs[0])
    return Coefficient(polynomial=coeffs)


def couple(v):
    if not isinstance(v, dict):
        raise _Bad(f"must be a table {{profile = ..., history = {{...}}}}, got {_type_name(v)}")
    _unknown(v, {"profile", "history"})
    out = {}
    for k, check, default in (("profile", profile, 1.0),
                              ("history", history(False), None)):
        if k not in v and default is None:
            raise _Bad("missing required key", k)
        try:
            out[k] = check(v.get(k, default))
        except _Bad as bad:
            raise _Bad(bad.reason, f"{k}.{bad.key}" if bad.key else k) from None
    return out


# --- the schema ----------------------------------------------------------------------------

REQUIRED = object()


@dataclass(frozen=True)
class Key:
    check: Callable[[Any], Any]
    default: Any = REQUIRED
    doc: str = ""


SCHEMA: dict[str, dict[str, Key]] = {
    "scene": {
        "name": Key(run_name, None, "run name, a folder name: letters, digits, '.', '_', '-' "
                                   "(default: the file's stem, other characters as '_')"),
        "description": Key(string, "", "free text"),
        "model": Key(choice(*MODEL_NAMES), "auto", "auto | ode | torsion | rod"),
    },
    "geometry": {
        "length": Key(real(0.0, True), 1.0, "rod length (torsion: dimensionless, must be 1)"),
        "n_cells": Key(integer(1, 100_000), 32, "number of cells along s"),
        "degree": Key(integer(1, 3), 1, "Lagrange degree of the rotation/position fields"),
        "reference_twist": Key(real(), 0.0, "initial natural twist u_d(0) (dimensionless)"),
        "reference_curvature": Key(vector3(), (0.0, 0.0, 0.0),
                                   "initial natural curvature u_d(0) (3-D rod)"),
    },
    "material": {
        "variant": Key(choice(*VARIANTS), "local", "local | uniform natural configuration"),
        "energy": Key(choice(*ENERGIES), "quadratic", "quadratic | kelvin_voigt"),
        "alpha": Key(coefficient(True), None, "torsional stiffness (default 1)"),
        "alpha_d": Key(coefficient(True), None, "natural-twist stiffness (default 1)"),
        "mu": Key(coefficient(False), None, "Kelvin-Voigt viscosity (default 0)"),
        "mu_d": Key(coefficient(True), None, "natural-configuration viscosity (default 1)"),
        "nu": Key(coefficient(False), None, "rotary inertia (default 0: quasi-static)"),
        "stiffness": Key(lambda v: _tensors(v, ("A", "B", "A_d", "B_d"), True), None,
                         "3-D rod: diagonals of A, B, A_d, B_d"),
        "viscosity": Key(lambda v: _tensors(v, ("M", "N", "M_d", "N_d"), False), None,
                         "3-D rod: diagonals of M, N, M_d, N_d; the uniform variant's M_d, "
                         "N_d carry one more length factor than the local ones (its law "
                         "integrates over s, docs/rod.md)"),
        "density": Key(real(0.0), None, "3-D rod: mass per length rho A (default 0: "
                                       "quasi-static)"),
        "section_inertia": Key(real(0.0), None, "3-D rod: I_11 = I_22 of a round section "
                                                "(default 0)"),
        "constraints": Key(choice(*CONSTRAINTS), "none",
                           "3-D rod: none | unshearable | inextensible_unshearable"),
    },
    "boundary": {
        "start": Key(choice("clamped"), "clamped", "s = 0: clamped"),
        "end": Key(choice("free", "rotation"), "free",
                   "s = 1: free (loads act) | rotation (prescribed end rotation)"),
        "end_rotation": Key(history(False), None, "history of the end rotation Phi(t)"),
    },
    "loads": {
        "end_torsion": Key(history(False), None, "applied torsion m(t) at s = 1"),
        "distributed_couple": Key(couple, None, "l(s, t) = profile(s) history(t)"),
        "end_force": Key(history(True), None, "3-D rod: force at s = L (value: 3 numbers)"),
        "end_couple": Key(history(True), None, "3-D rod: couple at s = L (value: 3 numbers)"),
    },
    "time": {
        "t_end": Key(real(0.0, True), REQUIRED, "final time"),
        "dt": Key(real(0.0, True), REQUIRED, "time step (also the output interval of the ODE)"),
        "scheme": Key(scheme_name, "bdf2", "a name of integrators.schemes"),
        "integrator": Key(choice("stepper", "ts"), "stepper", "stepper | ts (PETSc TS)"),
        "rtol": Key(real(0.0, True, 1.0), 1e-10, "relative tolerance (SNES / solve_ivp)"),
        "atol": Key(real(0.0, True, 1.0), 1e-10,
                    "absolute tolerance (SNES residual / solve_ivp); keep it above the "
                    "round-off floor of the residual (~1e-12 fails at 64 cells)"),
        "max_step_cuts": Key(integer(0, 30), 6, "step halvings before giving up"),
        "ode_solution": Key(choice("exact", "scheme"), "exact",
                            "ODE model: closed form/solve_ivp, or the FE model's scheme"),
    },
    "outputs": {
        "directory": Key(path_text, "results", "parent folder of the run folders"),
        "every": Key(integer(1), 1, "write fields every N steps"),
        "fields": Key(boolean, True, "ParaView fields (.bp) of FE models"),
        "plots": Key(boolean, True, "PNG plots of the main histories"),
        "checkpoint_every": Key(integer(0), 0, "adios4dolfinx checkpoint every N steps (0: off; "
                                               "integrator = \"stepper\" only)"),
        "progress": Key(boolean, True, "tqdm progress bar (rank 0, TTY, not CI)"),
    },
}
REQUIRED_TABLES = ("time",)
TORSION_KEYS = ("alpha", "alpha_d", "mu", "mu_d", "nu")
ROD_KEYS = ("stiffness", "viscosity", "density", "section_inertia")
TORSION_DEFAULTS = {"alpha": 1.0, "alpha_d": 1.0, "mu": 0.0, "mu_d": 1.0, "nu": 0.0}


def _tensors(v, names, strict_all: bool):
    if not isinstance(v, dict):
        raise _Bad(f"must be a table with {', '.join(names)}, got {_type_name(v)}")
    _unknown(v, set(names))
    out = {}
    for n in names:
        if n not in v:
            raise _Bad("missing required key", n)
        strict = strict_all or n in ("M_d", "N_d")
        try:
            out[n] = vector3(0.0, strict)(v[n])
        except _Bad as bad:
            raise _Bad(bad.reason, n) from None
    return out


@dataclass
class Scene:
    """A validated scene: ``data[table][key]`` with defaults filled in."""

    data: dict[str, dict[str, Any]]
    source: str = "<string>"
    text: str = ""
    given: dict[str, set[str]] = field(default_factory=dict)  # keys the file set

    def __getitem__(self, table: str) -> dict[str, Any]:
        return self.data[table]

    @property
    def name(self) -> str:
        return self.data["scene"]["name"]

    @property
    def is_rod_material(self) -> bool:
        return any(self.data["material"][k] is not None for k in ROD_KEYS)

    def error(self, key: str, reason: str) -> SceneError:
        return SceneError(self.source, key, reason)

    def physics(self) -> dict[str, dict[str, Any]]:
        """The validated keys that determine the computed states, as plain JSON data
        (what a checkpoint must match to be resumed): everything but the name and
        description, the outputs table, t_end (a run may be extended) and the requested
        model (the chosen model is compared instead)."""
        return {table: {k: _plain(v) for k, v in keys.items()
                        if not (table == "time" and k == "t_end")}
                for table, keys in self.data.items() if table not in ("scene", "outputs")}


def _plain(v: Any) -> Any:
    """Validated values (dataclasses, tuples, floats) as JSON data (lists, dicts)."""
    if hasattr(v, "__dataclass_fields__"):
        return {f: _plain(getattr(v, f)) for f in v.__dataclass_fields__}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file; every failure is a SceneError."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise SceneError(str(path), "", f"cannot read the scene: {err.strerror or err}") from None
    try:
        text = raw.decode("utf-8-sig")   # a UTF-8 byte-order mark is allowed
    except UnicodeDecodeError as err:
        raise SceneError(str(path), "", f"not UTF-8 text: {err.reason} at byte {err.start}") from None
    return parse_scene(text, source=str(path), default_name=path.stem)


def parse_scene(text: str, source: str = "<string>", default_name: str = "scene") -> Scene:
    """Parse and validate TOML text; every failure is a SceneError."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SceneError(source, "", f"invalid TOML: {err}") from None
    except (ValueError, TypeError, RecursionError) as err:   # e.g. lone surrogates
        raise SceneError(source, "", f"invalid TOML: {err}") from None
    scene = validate(raw, source, default_name)
    scene.text = text
    return scene


def validate(raw: Any, source: str = "<dict>", default_name: str = "scene") -> Scene:
    """Validate an already-parsed scene dict; every failure is a SceneError."""
    if not isinstance(raw, dict):
        raise SceneError(source, "", f"a scene must be a table, got {_type_name(raw)}")
    for table in raw:
        if table not in SCHEMA:
            raise SceneError(source, str(table),
                             f"unknown table (known: {', '.join(SCHEMA)})")
    for table in REQUIRED_TABLES:
        if table not in raw:
            raise SceneError(source, table, "missing required table")
    data: dict[str, dict[str, Any]] = {}
    given: dict[str, set[str]] = {}
    for table, keys in SCHEMA.items():
        section = raw.get(table, {})
        if not isinstance(section, dict):
            raise SceneError(source, table, f"must be a table, got {_type_name(section)}")
        given[table] = set(section)
        out = {}
        for k in section:
            if k not in keys:
                raise SceneError(source, f"{table}.{k}",
                                 f"unknown key (known in [{table}]: {', '.join(keys)})")
        for k, spec in keys.items():
            path = f"{table}.{k}"
            if k not in section:
                if spec.default is REQUIRED:
                    raise SceneError(source, path, f"missing required key ({spec.doc})")
                out[k] = spec.default
                continue
            try:
                out[k] = spec.check(section[k])
            except _Bad as bad:
                raise SceneError(source, f"{path}.{bad.key}" if bad.key else path,
                                 bad.reason) from None
        data[table] = out
    if data["scene"]["name"] is None:
        data["scene"]["name"] = safe_name(default_name)
    scene = Scene(data, source, given=given)
    _check_combinations(scene)
    return scene


def _check_combinations(scene: Scene) -> None:
    """Rules that involve more than one key."""
    d, err = scene.data, scene.error
    mat, bnd, lds, tim = d["material"], d["boundary"], d["loads"], d["time"]
    rod_material = scene.is_rod_material
    torsion_given = [k for k in TORSION_KEYS if mat[k] is not None]
    if rod_material and torsion_given:
        raise err(f"material.{torsion_given[0]}",
                  "give either the torsion coefficients (alpha, alpha_d, mu, mu_d, nu) or the "
                  "3-D rod tensors (stiffness, viscosity, density), not both")
    if rod_material:
        for k in ("stiffness", "viscosity"):
            if mat[k] is None:
                raise err(f"material.{k}", "missing: a 3-D rod material needs stiffness "
                                           "and viscosity")
        mat["density"] = mat["density"] or 0.0
        mat["section_inertia"] = mat["section_inertia"] or 0.0
        if (mat["density"] > 0) != (mat["section_inertia"] > 0):
            raise err("material.section_inertia", "density and section_inertia must be both "
                                                  "> 0 (dynamic) or both 0 (quasi-static)")
        if bnd["end"] == "rotation":
            raise err("boundary.end", "a prescribed end rotation of the 3-D rod is not "
                                      "available in scenes yet: use loads.end_couple")
        for k in ("end_force", "end_couple"):
            spec = lds[k]
            if spec is not None and (spec.type == "table" or not spec.is_vector):
                raise err(f"loads.{k}.value", "a 3-D rod load needs a vector value = [x, y, z] "
                                              "(step, ramp, smooth_step or constant)")
    else:
        for k in TORSION_KEYS:
            if mat[k] is None:
                mat[k] = Coefficient(constant=TORSION_DEFAULTS[k])
    if mat["energy"] == "kelvin_voigt" and "variant" in scene.given["material"]:
        raise err("material.variant",
                  "a kelvin_voigt energy does not depend on the natural strains, so the "
                  "natural configuration never evolves: drop 'variant' (Section 4, "
                  "Kelvin-Voigt model)")
    if mat["energy"] == "kelvin_voigt" and not rod_material:
        raise err("material.energy", "the kelvin_voigt energy is a 3-D rod material: give "
                                     "material.stiffness/viscosity/density")
    if mat["variant"] == "uniform" and mat["mu_d"] is not None and not mat["mu_d"].is_constant:
        raise err("material.mu_d", "must be a constant for the uniform variant (M_d is one "
                                   "tensor for the whole rod, eq. unatevolunif)")
    if bnd["end"] == "rotation":
        if bnd["end_rotation"] is None:
            raise err("boundary.end_rotation", "missing: boundary.end = \"rotation\" needs "
                                               "the history of the end rotation")
        if lds["end_torsion"] is not None:
            raise err("loads.end_torsion", "an end torsion cannot be applied where the end "
                                           "rotation is prescribed (boundary.end = \"rotation\")")
    elif bnd["end_rotation"] is not None:
        raise err("boundary.end_rotation", "given but boundary.end is \"free\": set "
                                           "boundary.end = \"rotation\"")
    if not rod_material:
        for k in ("end_force", "end_couple"):
            if lds[k] is not None:
                raise err(f"loads.{k}", "a 3-D rod load; this scene has a torsion material "
                                        "(use loads.end_torsion)")
        if d["geometry"]["length"] != 1.0:
            raise err("geometry.length", "torsion scenes are dimensionless on s in [0, 1] "
                                         "(Section 5.1): length must be 1")
        if any(d["geometry"]["reference_curvature"]):
            raise err("geometry.reference_curvature", "a natural curvature needs the 3-D "
                                                      "rod material (torsion is isolated)")
        dynamic = not (mat["nu"].is_constant and mat["nu"].constant == 0.0)
        if (dynamic and bnd["end"] == "rotation" and bnd["end_rotation"].jumps_at_start):
            raise err("boundary.end_rotation", "a step at t = 0 but nu > 0: a rod with "
                                               "inertia cannot follow a jump in rotation; use "
                                               "type = \"smooth_step\" or \"ramp\"")
        if not dynamic and get_scheme(tim["scheme"]).explicit:
            raise err("time.scheme", f"{tim['scheme']} is explicit, but quasi-static torsion "
                                     "(nu = 0) is differential-algebraic: use an implicit "
                                     "scheme")
    else:
        for k in ("end_torsion", "distributed_couple"):
            if lds[k] is not None:
                raise err(f"loads.{k}", "a torsion load; this scene has a 3-D rod material "
                                        "(use loads.end_couple)")
    if d["outputs"]["checkpoint_every"] and tim["integrator"] == "ts":
        raise err("outputs.checkpoint_every", "checkpoints (and --resume) need integrator = "
                                              "\"stepper\": PETSc TS runs the whole interval "
                                              "in one call")
    if tim["dt"] > tim["t_end"]:
        raise err("time.dt", f"must be <= t_end = {tim['t_end']:g}, got {tim['dt']:g}")
    if tim["t_end"] / tim["dt"] > 1e7:
        raise err("time.dt", f"t_end/dt = {tim['t_end'] / tim['dt']:.3g} steps is more than "
                             "10^7")
