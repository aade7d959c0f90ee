"""The TOML scene schema: parsing, defaults and validation.

A scene is one TOML file; every table and key is listed in ``SCHEMA`` below with its
type, default and rule.  Anything wrong with a scene (bad TOML, an unknown key, a wrong
type, a missing required value, a non-physical value, an inconsistent combination) is
reported as ONE :class:`SceneError` naming the file, the key path and the reason, e.g.

    scenes/bad.toml: [material.alpha]: must be > 0, got -1.0

Nothing else escapes :func:`load_scene` / :func:`parse_scene` (the test suite fuzzes
them with hypothesis).  Torsion scenes use the paper's dimensionless Section 5 variables
(alpha, alpha_d, mu, mu_d, nu, errata item 5); 3-D rod scenes use the tensors of the
quadratic energy (eq. ``quadenergy``) and the viscosities M, N, M_d, N_d in the user's
consistent units.  A key that does not apply to the scene's model (a torsion key in a
rod scene, a rod key in a torsion scene, natural-strain data of a non-evolving rod, ...)
is an error.
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

__all__ = ["SceneError", "Scene", "Coefficient", "HistorySpec", "Tensor", "load_scene",
           "parse_scene", "load_entry_point", "SCHEMA", "SCHEMA_NOTES", "MODEL_NAMES",
           "path_problem"]

MODEL_NAMES = ("auto", "ode", "torsion", "rod")
VARIANTS = ("local", "uniform")
ROD_MODELS = ("evolving", "kelvin_voigt", "hyperelastic")
ROD_ENDS = ("clamped", "pinned", "free")
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
            coeffs = _polynomial_numbers(v)
            c = Coefficient(polynomial=coeffs)
            s = sample_points(1.0)
            reason = profile_violation(c.values(s), s, strict)
            if reason:
                raise _Bad(f"{reason} (the polynomial)")
            if len(coeffs) == 1 or not any(coeffs[1:]):
                return Coefficient(constant=coeffs[0])
            return c
        return Coefficient(constant=real(0.0, lo_strict=strict)(v))
    return check


def _polynomial(v) -> tuple[float, ...]:
    if not isinstance(v, dict):
        raise _Bad(f"must be {{polynomial = [c0, c1, ...]}}, got {_type_name(v)}")
    _unknown(v, {"polynomial"})
    if "polynomial" not in v:
        raise _Bad("missing required key", "polynomial")
    p = v["polynomial"]
    if not isinstance(p, list) or not p:
        raise _Bad("must be a non-empty array", "polynomial")
    return tuple(p)


def _polynomial_numbers(v) -> tuple[float, ...]:
    try:
        return tuple(_number(c) for c in _polynomial(v))
    except _Bad as bad:
        raise _Bad(bad.reason, bad.key or "polynomial") from None


def profile(v):
    """A load profile along s: a number or {polynomial = [c0, c1, ...]}, any sign."""
    if not isinstance(v, dict):
        return Coefficient(constant=_number(v))
    coeffs = _polynomial_numbers(v)
    if len(coeffs) == 1 or not any(coeffs[1:]):
        return Coefficient(constant=coeffs[0])
    return Coefficient(polynomial=coeffs)


@dataclass(frozen=True)
class Tensor:
    """A 3x3 material tensor T(s) = T_0 + T_1 s + T_2 s^2 + ... (s in [0, L]); each T_k
    written as 3 diagonal entries or a 3x3 array."""

    terms: tuple[np.ndarray, ...]

    @property
    def is_zero(self) -> bool:
        return not any(np.any(t) for t in self.terms)

    def at(self, s: float) -> np.ndarray:
        return sum(t * s**k for k, t in enumerate(self.terms))

    def value(self):
        """RodParameters' form: the 3x3 array, or a callable of s (floats and UFL)."""
        if len(self.terms) == 1:
            return self.terms[0]
        terms = self.terms
        return lambda s: [[sum(t[i, j] * s**k for k, t in enumerate(terms)) for j in range(3)]
                          for i in range(3)]


def _matrix(v) -> np.ndarray:
    if isinstance(v, list) and len(v) == 3 and all(isinstance(r, list) for r in v):
        rows = []
        for i, r in enumerate(v):
            if len(r) != 3:
                raise _Bad(f"row {i} must have 3 numbers, got {r!r}")
            rows.append([_number(x) for x in r])
        return np.array(rows)
    return np.diag(vector3()(v))


def tensor(v) -> Tensor:
    """[a, b, c] (diagonal), [[...], [...], [...]] (3x3), or {polynomial = [T0, T1, ...]}."""
    if isinstance(v, dict):
        try:
            terms = tuple(_matrix(t) for t in _polynomial(v))
        except _Bad as bad:
            raise _Bad(bad.reason, bad.key or "polynomial") from None
    else:
        terms = (_matrix(v),)
    for t in terms:
        if not np.allclose(t, t.T, rtol=1e-12, atol=0.0):
            raise _Bad(f"must be symmetric, got {t.tolist()}")
    return Tensor(terms)


def entry_point(v) -> str:
    """"package.module:function": imported (from the scene's folder or sys.path)."""
    v = string(v)
    module, sep, name = v.partition(":")
    if not (sep and module and name.isidentifier()):
        raise _Bad(f"must be \"quadratic\" or an entry point \"package.module:function\", "
                   f"got {v!r}")
    return v


def load_entry_point(spec: str, folder: Path | None = None):
    """The callable named by ``package.module:function`` (folder: tried first)."""
    import importlib
    import sys
    module, _, name = spec.partition(":")
    added = folder is not None and str(folder) not in sys.path
    if added:
        sys.path.insert(0, str(folder))
    try:
        obj = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as err:
        raise _Bad(f"cannot import {spec!r}: {err}") from None
    finally:
        if added:
            sys.path.remove(str(folder))
    if not callable(obj):
        raise _Bad(f"{spec!r} is not callable")
    return obj


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
    values: tuple = ()         # numbers, or 3-vectors (a vector table)
    follower: bool = False     # rod loads: components in the material (rotating) frame

    def build(self, component: int | None = None):
        """The loads.LoadHistory (component of a vector value if given)."""
        if self.type == "table":
            values = self.values if component is None else [x[component] for x in self.values]
            return load_histories.table(self.times, values)
        v = self.value if component is None else self.value[component]
        if self.type == "step":
            return load_histories.step(v, self.t0)
        if self.type == "ramp":
            return load_histories.ramp(v, self.duration)
        if self.type == "smooth_step":
            return load_histories.smooth_step(v, self.duration)
        return load_histories.constant(v)

    @property
    def is_vector(self) -> bool:
        if self.type == "table":
            return isinstance(self.values[0], tuple)
        return isinstance(self.value, tuple)

    def vector(self):
        """t -> the 3-vector value (rod end motions)."""
        parts = [self.build(i) for i in range(3)]
        return lambda t: np.array([float(h(t)) for h in parts])

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


def history(vector_ok: bool, follower_ok: bool = False):
    def check(v):
        if not isinstance(v, dict):
            raise _Bad(f"must be a table {{type = \"step\"|\"ramp\"|...}}, got {_type_name(v)}")
        follower = False
        if follower_ok and "follower" in v:
            v = dict(v)
            try:
                follower = boolean(v.pop("follower"))
            except _Bad as bad:
                raise _Bad(bad.reason, "follower") from None
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
                    vectors = k == "values" and vector_ok and isinstance(v[k][0], list)
                    out[k] = tuple((vector3()(x) if vectors else _number(x)) for x in v[k])
            except _Bad as bad:
                raise _Bad(bad.reason, k) from None
        if kind == "table":
            if len(out["times"]) != len(out["values"]):
                raise _Bad(f"times and values must have the same length, got "
                           f"{len(out['times'])} and {len(out['values'])}", "values")
            if any(b <= a for a, b in zip(out["times"], out["times"][1:])):
                raise _Bad("must be strictly increasing", "times")
        return HistorySpec(**out, follower=follower)
    return check


def distributed(v):
    """{value = [x, y, z] (rod) , profile = number | {polynomial}, history = {...},
    follower = bool (rod)}: value profile(s) history(t) per unit reference length."""
    if not isinstance(v, dict):
        raise _Bad(f"must be a table {{profile = ..., history = {{...}}}}, got {_type_name(v)}")
    _unknown(v, {"value", "profile", "history", "follower"})
    out = {"value": None, "follower": False}
    checks = (("value", vector3(), None), ("profile", profile, 1.0),
              ("history", history(False), {"type": "constant", "value": 1.0}),
              ("follower", boolean, False))
    for k, check, default in checks:
        if k not in v and default is None:
            continue
        try:
            out[k] = check(v.get(k, default))
        except _Bad as bad:
            raise _Bad(bad.reason, f"{k}.{bad.key}" if bad.key else k) from None
    return out


def _inertia(v) -> tuple[float, float]:
    """I_11 = I_22 (a number) or [I_11, I_22], each >= 0."""
    if isinstance(v, list):
        if len(v) != 2:
            raise _Bad(f"must be a number or [I_11, I_22], got {v!r}")
        return (real(0.0)(v[0]), real(0.0)(v[1]))
    x = real(0.0)(v)
    return (x, x)


def ts_type_name(v) -> str:
    from ..integrators.ts import parse_ts_type
    v = string(v)
    try:
        parse_ts_type(v)
    except ValueError as err:
        raise _Bad(str(err)) from None
    return v


def petsc_table(v) -> dict:
    """PETSc options: names without the leading '-', values numbers, strings or booleans."""
    if not isinstance(v, dict):
        raise _Bad(f"must be a table of PETSc options, got {_type_name(v)}")
    for k, x in v.items():
        if k.startswith("-") or not k.replace("_", "").isalnum():
            raise _Bad("must be a PETSc option name without the leading '-'", k)
        if not isinstance(x, (bool, int, float, str)) or (isinstance(x, float)
                                                         and not math.isfinite(x)):
            raise _Bad(f"must be a number, string or boolean, got {_type_name(x)}", k)
    return dict(v)


# --- the schema ----------------------------------------------------------------------------

REQUIRED = object()


@dataclass(frozen=True)
class Key:
    check: Callable[[Any], Any]
    default: Any = REQUIRED
    doc: str = ""


SCHEMA_NOTES = """\
**Two kinds of scene.** A scene with `material.stiffness`/`viscosity` (or density,
section_inertia, drag) is a **3-D rod** (RodModel): it is in the user's consistent units,
e.g. SI: lengths in m, time in s, A = (EI_1, EI_2, GJ) in N m^2, B = (GA_1, GA_2, EA) in N,
M, M_d in N m^2 s, N, N_d in N s, density rho A in kg/m, section_inertia rho I in kg m,
gravity in m/s^2, forces in N, couples in N m, distributed loads per metre
(`scenes/gravity_cantilever.toml` is an SI example).  Otherwise it is a **torsion** scene
(the ODE or TorsionModel): the paper's dimensionless Section 5.1 variables (alpha, alpha_d,
mu, mu_d, nu; s in [0, 1], errata item 5).  Keys marked "3-D rod:" or "torsion:" belong to
one kind; giving one to the other kind is an error.

**Values.** A load history is a table `{type = "step" | "ramp" | "smooth_step" | "table" |
"constant", ...}` with `value`, `t0` (step), `duration` (ramp, smooth step), `times` and
`values` (table); rod loads and end motions take `value = [x, y, z]` (a table: `values` of
3-vectors), end loads also `follower = true` (components in the end's material frame).
A torsion coefficient or a density/drag/profile is a number or `{polynomial = [c0, c1,
...]}` in s.  A rod tensor (A, B, A_d, B_d, M, N, M_d, N_d) is `[a, b, c]` (diagonal),
`[[..], [..], [..]]` (a full symmetric 3x3 matrix) or `{polynomial = [T0, T1, ...]}`
(T(s) = T0 + T1 s + ..., each T_k diagonal or 3x3; s in [0, L]).  The uniform variant's
law integrates over s (eq. unatevolunif), so its M_d carries a length factor:
switching variant on a rod with L != 1 rescales time by L.
"""

R = "3-D rod: "
T = "torsion: "
SCHEMA: dict[str, dict[str, Key]] = {
    "scene": {
        "name": Key(run_name, None, "run name, a folder name: letters, digits, '.', '_', '-' "
                                   "(default: the file's stem, other characters as '_')"),
        "description": Key(string, "", "free text"),
        "model": Key(choice(*MODEL_NAMES), "auto", "auto | ode | torsion | rod"),
    },
    "geometry": {
        "length": Key(real(0.0, True), 1.0, "rod length L (torsion: dimensionless, must be 1)"),
        "n_cells": Key(integer(1, 100_000), 32, "number of cells along s"),
        "degree": Key(integer(1, 3), 1, T + "Lagrange degree of phi (the rod is P1)"),
        "reference_curvature": Key(vector3(), (0.0, 0.0, 0.0),
                                   R + "curvature u_ref of the stress-free initial shape (a "
                                   "helix or circle; not a natural strain)"),
        "reference_stretch": Key(vector3(), (0.0, 0.0, 1.0),
                                 R + "stretch v_ref of the stress-free initial shape "
                                 "(v_ref,3 > 0)"),
    },
    "material": {
        "variant": Key(choice(*VARIANTS), "local", "local | uniform evolution law of the "
                       "natural strains (uniform: the M_d law integrates over s, so M_d "
                       "carries a length factor)"),
        "model": Key(choice(*ROD_MODELS), "evolving",
                     R + "evolving (natural strains evolve) | kelvin_voigt (viscosities M, "
                     "N only) | hyperelastic"),
        "energy": Key(entry_point, None,
                      R + "free energy psi(u_d, v_d, u, v): \"package.module:function\" "
                      "returning a UFL scalar (the scene's folder is on the import path); "
                      "default: eq. quadenergy with the stiffness tensors"),
        "alpha": Key(coefficient(True), None, T + "torsional stiffness (default 1)"),
        "alpha_d": Key(coefficient(True), None, T + "natural-twist stiffness (default 1)"),
        "mu": Key(coefficient(False), None, T + "Kelvin-Voigt viscosity (default 0)"),
        "mu_d": Key(coefficient(True), None, T + "natural-configuration viscosity (default 1)"),
        "nu": Key(coefficient(False), None, T + "rotary inertia (default 0: quasi-static)"),
        "stiffness": Key(lambda v: _tensors(v, ("A", "B", "A_d", "B_d")), None,
                         R + "{A, B, A_d, B_d}: bending/torsion A = (EI_1, EI_2, GJ), "
                         "shear/axial B = (GA_1, GA_2, EA), natural-strain stiffnesses A_d, "
                         "B_d (evolving model); each a tensor (see above)"),
        "viscosity": Key(lambda v: _tensors(v, ("M", "N", "M_d", "N_d")), None,
                         R + "{M, N, M_d, N_d}: Kelvin-Voigt M, N (default 0), natural-"
                         "configuration M_d, N_d (evolving model; the uniform variant's M_d, N_d carry one "
                         "more length factor than the local ones, docs/rod.md); each a tensor"),
        "density": Key(coefficient(False), None, R + "mass per length rho A (number or "
                       "{polynomial}); > 0: dynamic, 0 (default): quasi-static"),
        "section_inertia": Key(_inertia, None, R + "I_11 = I_22 (a number) or [I_11, I_22]: "
                               "section mass moments per length (rho J, Section 2.2)"),
        "drag": Key(coefficient(False), None, R + "linear drag f = -c dr/dt (c per length)"),
        "constraints": Key(choice(*CONSTRAINTS), "none",
                           R + "none | unshearable | inextensible_unshearable"),
    },
    "initial": {
        "natural_twist": Key(real(), None, T + "u_d at t = 0 (default 0)"),
        "natural_curvature": Key(vector3(), None, R + "u_d at t = 0 (evolving; default: "
                                 "the reference strains, i.e. unstressed)"),
        "natural_stretch": Key(vector3(), None, R + "v_d at t = 0 (evolving; default: "
                               "the reference strains)"),
    },
    "boundary": {
        "start": Key(choice(*ROD_ENDS), "clamped", "s = 0: clamped | pinned | free "
                     "(torsion: clamped)"),
        "end": Key(choice("free", "rotation", "clamped", "pinned"), "free",
                   "s = L: free | clamped | pinned (rod); free | rotation (torsion: "
                   "prescribed end rotation)"),
        "end_rotation": Key(history(True), None, "torsion: history of Phi(t); 3-D rod: "
                            "rotation vector (value = [x, y, z]) superposed on the end's "
                            "initial rotation"),
        "start_rotation": Key(history(True), None, R + "as end_rotation, at s = 0"),
        "end_displacement": Key(history(True), None, R + "prescribed displacement of s = L "
                                "from its initial position (value = [x, y, z])"),
        "start_displacement": Key(history(True), None, R + "as end_displacement, at s = 0"),
    },
    "loads": {
        "end_torsion": Key(history(False), None, T + "applied torsion m(t) at s = 1"),
        "distributed_couple": Key(distributed, None,
                                  "l(s, t) = value profile(s) history(t) per length (torsion: "
                                  "no value; rod: value = [x, y, z], follower = true for "
                                  "material components)"),
        "distributed_force": Key(distributed, None, R + "as distributed_couple, a force"),
        "gravity": Key(vector3(), None, R + "g = [x, y, z]: the distributed force rho_A g "
                       "(needs density > 0)"),
        "end_force": Key(history(True, True), None, R + "force at s = L: a history with value "
                         "= [x, y, z] (or a table of 3-vectors); follower = true: material "
                         "components (rotating with the end)"),
        "end_couple": Key(history(True, True), None, R + "couple at s = L (as end_force)"),
        "start_force": Key(history(True, True), None, R + "force at s = 0 (as end_force)"),
        "start_couple": Key(history(True, True), None, R + "couple at s = 0 (as end_force)"),
    },
    "time": {
        "t_end": Key(real(0.0, True), REQUIRED, "final time"),
        "dt": Key(real(0.0, True), REQUIRED, "time step (also the output interval of the ODE; "
                  "the initial step of adaptive TS)"),
        "scheme": Key(scheme_name, "bdf2", "a name of integrators.schemes (stepper)"),
        "integrator": Key(choice("stepper", "ts"), "stepper", "stepper | ts (PETSc TS)"),
        "ts_type": Key(ts_type_name, None, "ts: a PETSc TS type of integrators.ts, e.g. "
                       "\"arkimex:4\", \"bdf:3\", \"alpha:0.5\", \"alpha2\" (dynamic torsion); "
                       "default: the scheme's counterpart"),
        "adaptive": Key(boolean, False, "ts: adaptive time steps (error control with "
                        "ts_rtol, ts_atol; outputs at each accepted step)"),
        "ts_rtol": Key(real(0.0, True, 1.0), 1e-6, "ts, adaptive: relative local error "
                       "tolerance"),
        "ts_atol": Key(real(0.0, True, 1.0), 1e-8, "ts, adaptive: absolute local error "
                       "tolerance"),
        "predictor": Key(choice("linear", "constant"), "linear", "stepper: Newton's initial "
                         "guess (linear extrapolation or the last state)"),
        "rtol": Key(real(0.0, True, 1.0), 1e-10, "relative tolerance (SNES / solve_ivp)"),
        "atol": Key(real(0.0, True, 1.0), 1e-10,
                    "absolute tolerance (SNES residual / solve_ivp); keep it above the "
                    "round-off floor of the residual (~1e-12 fails at 64 cells)"),
        "max_step_cuts": Key(integer(0, 30), 6, "step halvings before giving up"),
        "ode_solution": Key(choice("exact", "scheme"), "exact",
                            "ODE model: closed form/solve_ivp, or the FE model's scheme"),
    },
    "solver": {
        "preset": Key(choice("default", "native_lu", "jacobian_reuse"), "default",
                      "default (Newton, MUMPS LU) | native_lu (PETSc LU, serial only) | "
                      "jacobian_reuse (modified Newton, dynamics with small steps); "
                      "solvers.py"),
        "options": Key(petsc_table, None, "PETSc options (without prefix) over the preset, "
                       "e.g. {snes_max_it = 50, ksp_type = \"preonly\"}"),
    },
    "outputs": {
        "directory": Key(path_text, "results", "parent folder of the run folders"),
        "every": Key(integer(1), 1, "write rod.bp and animation frames every N steps (and "
                                    "at the end)"),
        "fields": Key(boolean, True, "rod.bp for ParaView (ADIOS2VTXReader): the deformed "
                                     "centre line with directors, strains, natural strains, "
                                     "forces, dissipation (FE models)"),
        "animation": Key(boolean, True, "3-D rod: animation.gif and snapshots.png of the "
                                        "moving centre line coloured by |u_d - u_ref|; "
                                        "torsion: spacetime.png of phi(s, t), u_d(s, t)"),
        "plots": Key(boolean, True, "PNG plots of the main histories"),
        "checkpoint_every": Key(integer(0), 0, "adios4dolfinx checkpoint every N steps (0: off; "
                                               "integrator = \"stepper\" only)"),
        "progress": Key(boolean, True, "tqdm progress bar (rank 0, TTY, not CI)"),
    },
}
REQUIRED_TABLES = ("time",)
TORSION_KEYS = ("alpha", "alpha_d", "mu", "mu_d", "nu")
ROD_KEYS = ("stiffness", "viscosity", "density", "section_inertia", "drag")
# keys of one model family only: (table, key) -> the family that reads it
TORSION_ONLY = {("material", k) for k in TORSION_KEYS} | {
    ("geometry", "degree"), ("initial", "natural_twist"), ("loads", "end_torsion")}
ROD_ONLY = {("material", k) for k in ROD_KEYS + ("model", "energy", "constraints")} | {
    ("geometry", "reference_curvature"), ("geometry", "reference_stretch"),
    ("initial", "natural_curvature"), ("initial", "natural_stretch"),
    ("boundary", "start_rotation"), ("boundary", "end_displacement"),
    ("boundary", "start_displacement"), ("loads", "distributed_force"), ("loads", "gravity"),
    ("loads", "end_force"), ("loads", "end_couple"), ("loads", "start_force"),
    ("loads", "start_couple")}
RENAMED = {("geometry", "reference_twist"): "initial.natural_twist (u_d at t = 0 is an "
                                            "initial natural strain, not a reference shape)"}
TORSION_DEFAULTS = {"alpha": 1.0, "alpha_d": 1.0, "mu": 0.0, "mu_d": 1.0, "nu": 0.0}


def _tensors(v, names) -> dict[str, Tensor]:
    """The tensors of a stiffness/viscosity table (required ones checked per model)."""
    if not isinstance(v, dict):
        raise _Bad(f"must be a table with {', '.join(names)}, got {_type_name(v)}")
    _unknown(v, set(names))
    out = {}
    for n in names:
        if n in v:
            try:
                out[n] = tensor(v[n])
            except _Bad as bad:
                raise _Bad(bad.reason, f"{n}.{bad.key}" if bad.key else n) from None
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


def load_scene(path: str | Path, overrides: dict[str, Any] | None = None) -> Scene:
    """Read and validate a scene file; every failure is a SceneError.  ``overrides``
    {"table.key": value} (None: remove the key) change the file's values first, e.g.
    ``load_scene("scenes/torsion_creep.toml", {"material.variant": "uniform"})``."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise SceneError(str(path), "", f"cannot read the scene: {err.strerror or err}") from None
    try:
        text = raw.decode("utf-8-sig")   # a UTF-8 byte-order mark is allowed
    except UnicodeDecodeError as err:
        raise SceneError(str(path), "", f"not UTF-8 text: {err.reason} at byte {err.start}") from None
    return parse_scene(text, source=str(path), default_name=path.stem, overrides=overrides)


def parse_scene(text: str, source: str = "<string>", default_name: str = "scene",
                overrides: dict[str, Any] | None = None) -> Scene:
    """Parse and validate TOML text (with ``overrides``, see load_scene); every failure
    is a SceneError.  ``scene.text`` is the scene as run (the overridden values in)."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SceneError(source, "", f"invalid TOML: {err}") from None
    except (ValueError, TypeError, RecursionError) as err:   # e.g. lone surrogates
        raise SceneError(source, "", f"invalid TOML: {err}") from None
    if overrides:
        for name, value in overrides.items():
            table, _, key = name.partition(".")
            if not key:
                raise SceneError(source, name, "an override is named \"table.key\"")
            section = raw.setdefault(table, {})
            if value is None:
                section.pop(key, None)
            elif isinstance(section, dict):
                section[key] = value
        text = f"# {source} with overrides {overrides}\n" + to_toml(raw)
    scene = validate(raw, source, default_name)
    scene.text = text
    return scene


def to_toml(raw: dict) -> str:
    """A scene dict as TOML (tables of keys with inline values), for scene.toml."""
    def value(v) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
    out = []
    for table, keys in raw.items():
        out.append(f"[{table}]")
        out += [f"{k if k.replace('_', '').isalnum() else value(k)} = {value(v)}"
                for k, v in keys.items()]
        out.append("")
    return "\n".join(out)


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
            if (table, k) in RENAMED:
                raise SceneError(source, f"{table}.{k}", f"renamed: use {RENAMED[table, k]}")
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
    rod = scene.is_rod_material
    wrong = ROD_ONLY if not rod else TORSION_ONLY
    for table, key in sorted(wrong):
        if key in scene.given[table]:
            raise scene.error(f"{table}.{key}", (
                "applies to the 3-D rod only; this scene has a torsion material (give "
                "material.stiffness, viscosity for a rod)") if not rod else (
                "applies to the torsion model only; this scene has a 3-D rod material"))
    _check_time(scene)
    if rod:
        _check_rod_material(scene)
        _check_rod_ends(scene)
    else:
        _check_torsion(scene)


def _check_time(scene: Scene) -> None:
    tim, given, err = scene["time"], scene.given["time"], scene.error
    ts = tim["integrator"] == "ts"
    for key in ("ts_type", "adaptive", "ts_rtol", "ts_atol"):
        if key in given and not ts:
            raise err(f"time.{key}", "applies to integrator = \"ts\" only")
    if ts and "predictor" in given:
        raise err("time.predictor", "applies to integrator = \"stepper\" only")
    if ts and "ts_type" in given and "scheme" in given:
        raise err("time.scheme", "give either time.scheme (per-step schemes) or time.ts_type "
                                 "(PETSc TS), not both")
    for key in ("ts_rtol", "ts_atol"):
        if key in given and not tim["adaptive"]:
            raise err(f"time.{key}", "an error tolerance of adaptive TS: set adaptive = true")
    if scene["outputs"]["checkpoint_every"] and ts:
        raise err("outputs.checkpoint_every", "checkpoints (and --resume) need integrator = "
                                              "\"stepper\": PETSc TS runs the whole interval "
                                              "in one call")
    if tim["dt"] > tim["t_end"]:
        raise err("time.dt", f"must be <= t_end = {tim['t_end']:g}, got {tim['dt']:g}")
    if tim["t_end"] / tim["dt"] > 1e7:
        raise err("time.dt", f"t_end/dt = {tim['t_end'] / tim['dt']:.3g} steps is more than "
                             "10^7")


def _check_torsion(scene: Scene) -> None:
    """Torsion scenes (dimensionless, Section 5.1)."""
    d, err = scene.data, scene.error
    mat, bnd, lds, tim = d["material"], d["boundary"], d["loads"], d["time"]
    for k in TORSION_KEYS:
        if mat[k] is None:
            mat[k] = Coefficient(constant=TORSION_DEFAULTS[k])
    if mat["variant"] == "uniform" and not mat["mu_d"].is_constant:
        raise err("material.mu_d", "must be a constant for the uniform variant (M_d is one "
                                   "tensor for the whole rod, eq. unatevolunif)")
    if bnd["start"] != "clamped":
        raise err("boundary.start", "the torsion model is clamped at s = 0 (phi(0) = 0)")
    if bnd["end"] not in ("free", "rotation"):
        raise err("boundary.end", "torsion: free (an applied end torsion) or rotation (a "
                                  "prescribed end rotation)")
    if bnd["end_rotation"] is not None and bnd["end_rotation"].is_vector:
        raise err("boundary.end_rotation.value", "torsion: the end rotation Phi is a number")
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
    couple = lds["distributed_couple"]
    for k in ("value", "follower"):
        if couple is not None and couple[k] not in (None, False):
            raise err(f"loads.distributed_couple.{k}", "torsion: the couple is "
                                                       "profile(s) history(t), a number")
    if d["geometry"]["length"] != 1.0:
        raise err("geometry.length", "torsion scenes are dimensionless on s in [0, 1] "
                                     "(Section 5.1): length must be 1")
    dynamic = not (mat["nu"].is_constant and mat["nu"].constant == 0.0)
    if dynamic and bnd["end"] == "rotation" and bnd["end_rotation"].jumps_at_start:
        raise err("boundary.end_rotation", "a step at t = 0 but nu > 0: a rod with "
                                           "inertia cannot follow a jump in rotation; use "
                                           "type = \"smooth_step\" or \"ramp\"")
    if not dynamic and get_scheme(tim["scheme"]).explicit:
        raise err("time.scheme", f"{tim['scheme']} is explicit, but quasi-static torsion "
                                 "(nu = 0) is differential-algebraic: use an implicit scheme")


def _sampled(value, L: float) -> list[np.ndarray]:
    return [np.asarray(value(s) if callable(value) else value, dtype=float)
            for s in sample_points(L)]


def _check_rod_material(scene: Scene) -> None:
    """3-D rod material: the tensors each model needs, and only those."""
    d, err = scene.data, scene.error
    mat, L = d["material"], d["geometry"]["length"]
    evolving = mat["model"] == "evolving"
    stiff, visc = mat["stiffness"] or {}, mat["viscosity"] or {}
    needed = {"stiffness": ("A", "B") + (("A_d", "B_d") if evolving else ()),
              "viscosity": ("M_d", "N_d") if evolving else ()}
    for table, have in (("stiffness", stiff), ("viscosity", visc)):
        for k in needed[table]:
            if k not in have:
                raise err(f"material.{table}.{k}", f"missing: the {mat['model']} model needs it")
        for k in have:
            if k in ("A_d", "B_d", "M_d", "N_d") and not evolving:
                raise err(f"material.{table}.{k}", f"a natural-strain tensor; the "
                                                  f"{mat['model']} model has none")
    if mat["model"] == "hyperelastic" and any(k in visc for k in ("M", "N")):
        raise err("material.viscosity", "the hyperelastic model has no viscosity")
    if mat["model"] == "kelvin_voigt" and all(visc.get(k) is None or visc[k].is_zero
                                              for k in ("M", "N")):
        raise err("material.viscosity", "the kelvin_voigt model needs M or N")
    for table, have in (("stiffness", stiff), ("viscosity", visc)):
        for k, t in have.items():
            semidefinite = k in ("M", "N")
            for si, a in zip(sample_points(L), _sampled(t.at, L)):
                low = np.linalg.eigvalsh(a).min()
                if low < 0 or (low == 0 and not semidefinite):
                    rule = "positive semidefinite" if semidefinite else "positive definite"
                    raise err(f"material.{table}.{k}", f"must be {rule}; eigenvalue {low:g} "
                                                       f"at s = {si:g}")
    for key in ("variant",):
        if key in scene.given["material"] and not evolving:
            raise err(f"material.{key}", f"the natural strains of the {mat['model']} model "
                                         "do not evolve: drop it")
    for key in ("natural_curvature", "natural_stretch"):
        if d["initial"][key] is not None and not evolving:
            raise err(f"initial.{key}", f"the {mat['model']} model has no natural strains")
    if d["initial"]["natural_stretch"] is not None and \
            mat["constraints"] == "inextensible_unshearable":
        raise err("initial.natural_stretch", "an inextensible, unshearable rod has no "
                                             "natural stretch")
    if d["geometry"]["reference_stretch"][2] <= 0:
        raise err("geometry.reference_stretch", "v_ref,3 must be > 0 (eq. v3pos)")
    _check_rod_inertia(scene)
    if mat["energy"] is not None:
        folder = Path(scene.source).parent if Path(scene.source).is_file() else None
        try:
            load_entry_point(mat["energy"], folder)
        except _Bad as bad:
            raise err("material.energy", bad.reason) from None


def _check_rod_inertia(scene: Scene) -> None:
    mat, lds, err = scene["material"], scene["loads"], scene.error
    L = scene["geometry"]["length"]
    for k in ("density", "drag"):
        c = mat[k]
        if c is not None and min(np.min(v) for v in _sampled(c, L)) < 0:
            raise err(f"material.{k}", "must be >= 0 on [0, L]")
    inertia = mat["section_inertia"] or (0.0, 0.0)
    density = mat["density"] or Coefficient(constant=0.0)
    dynamic = not (density.is_constant and density.constant == 0.0)
    if dynamic != (min(inertia) > 0):
        raise err("material.section_inertia", "density and section_inertia (I_11, I_22) must "
                                              "be all > 0 (dynamic) or all 0 (quasi-static)")
    mat["dynamic"] = dynamic
    if dynamic and mat["constraints"] != "none":
        raise err("material.constraints", "a dynamic rod (density > 0) with constraint "
                                          "multipliers is an index-3 DAE, which no integrator "
                                          "here solves reliably: use a quasi-static rod or a "
                                          "stiff shear/axial B instead")
    if lds["gravity"] is not None and not dynamic:
        raise err("loads.gravity", "the weight rho_A g needs material.density > 0 (a "
                                   "dynamic rod); quasi-static: use loads.distributed_force")
    if not dynamic and get_scheme(scene["time"]["scheme"]).explicit:
        raise err("time.scheme", f"{scene['time']['scheme']} is explicit, but a quasi-static "
                                 "rod is differential-algebraic: use an implicit scheme")


def _check_rod_ends(scene: Scene) -> None:
    """Supports, prescribed end motions and end loads of the 3-D rod."""
    bnd, lds, err = scene["boundary"], scene["loads"], scene.error
    fixed_x, fixed_q = [], []
    for end in ("start", "end"):
        kind = bnd[end]
        if kind == "rotation":
            raise err(f"boundary.{end}", "3-D rod: clamped, pinned or free; a prescribed "
                                         f"rotation is boundary.{end}_rotation")
        for motion in ("displacement", "rotation"):
            spec = bnd[f"{end}_{motion}"]
            if spec is not None and not spec.is_vector:
                raise err(f"boundary.{end}_{motion}.value", "3-D rod: a vector [x, y, z]")
        x = kind in ("clamped", "pinned") or bnd[f"{end}_displacement"] is not None
        q = kind == "clamped" or bnd[f"{end}_rotation"] is not None
        fixed_x.append(x), fixed_q.append(q)
        for load, fixed, what in (("force", x, "position"), ("couple", q, "rotation")):
            spec = lds[f"{end}_{load}"]
            if spec is None:
                continue
            if not spec.is_vector:
                raise err(f"loads.{end}_{load}.value", "3-D rod: a vector value = [x, y, z] "
                                                       "(or a table of 3-vectors)")
            if fixed:
                raise err(f"loads.{end}_{load}", f"acts where the {what} is prescribed "
                                                 f"(boundary.{end} = {kind!r}): the support "
                                                 "takes it")
    for k in ("distributed_force", "distributed_couple"):
        if lds[k] is not None and lds[k]["value"] is None:
            raise err(f"loads.{k}.value", "missing: 3-D rod: value = [x, y, z]")
    if not scene["material"]["dynamic"] and not (any(fixed_x) and any(fixed_q)):
        raise err("boundary.start", "a quasi-static rod needs a fixed position and a fixed "
                                    "rotation somewhere (e.g. start = \"clamped\"); rigid "
                                    "motions are free otherwise")
