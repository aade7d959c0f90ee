"""Scene value checkers: each takes a TOML value and returns the cleaned value or raises
:class:`BadValue` (the reason, and the sub-key it concerns), which the schema turns into
one SceneError naming the key path.  Also the validated value types of a scene:
:class:`Coefficient` (torsion coefficients, load profiles) and :class:`Tensor` (rod
material tensors), and the checks of path text and entry points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..integrators.schemes import get_scheme
from ..checks import profile_violation, sample_points


class BadValue(Exception):
    """A value broke a rule; turned into a SceneError with its key path."""

    def __init__(self, reason: str, key: str | None = None):
        super().__init__(reason)
        self.reason, self.key = reason, key


def type_name(v: Any) -> str:
    return {bool: "boolean", int: "integer", float: "float", str: "string", list: "array",
            dict: "table"}.get(type(v), type(v).__name__)


def number(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise BadValue(f"must be a number, got {type_name(v)} {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise BadValue(f"must be finite, got {v!r}")
    return x


def real(lo: float | None = None, lo_strict: bool = False, hi: float | None = None):
    def check(v):
        x = number(v)
        if lo is not None and (x <= lo if lo_strict else x < lo):
            raise BadValue(f"must be {'>' if lo_strict else '>='} {lo:g}, got {x:g}")
        if hi is not None and x > hi:
            raise BadValue(f"must be <= {hi:g}, got {x:g}")
        return x
    return check


def integer(lo: int, hi: int | None = None):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int):
            raise BadValue(f"must be an integer, got {type_name(v)} {v!r}")
        if v < lo or (hi is not None and v > hi):
            raise BadValue(f"must be an integer in [{lo}, {hi if hi is not None else 'inf'}], got {v}")
        return v
    return check


def choice(*options: str):
    def check(v):
        if not isinstance(v, str):
            raise BadValue(f"must be a string, one of {', '.join(options)}; got {type_name(v)}")
        if v not in options:
            raise BadValue(f"must be one of {', '.join(repr(o) for o in options)}, got {v!r}")
        return v
    return check


def string(v):
    if not isinstance(v, str):
        raise BadValue(f"must be a string, got {type_name(v)} {v!r}")
    return v


NAME_MAX = 255     # bytes in one path component (POSIX file systems)
PATH_MAX = 4096    # bytes in a whole path (Linux)


def run_name(v):
    """A scene name is a folder name: letters, digits, '.', '_', '-', not starting with
    '.', so that it can never leave outputs.directory or nest folders."""
    v = string(v)
    if not v or v.startswith(".") or not all(c.isascii() and (c.isalnum() or c in "._-")
                                              for c in v):
        raise BadValue(f"must be a folder name of letters, digits, '.', '_', '-' (not starting "
                   f"with '.'), got {v!r}")
    if len(v) > 100:
        raise BadValue(f"must be at most 100 characters (it names the run folder), got {len(v)}")
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
        raise BadValue(problem)
    return v


def boolean(v):
    if not isinstance(v, bool):
        raise BadValue(f"must be true or false, got {type_name(v)} {v!r}")
    return v


def names_or_boolean(*options: str):
    """true | false | a list of some of ``options`` (in the order shown)."""
    def check(v):
        if isinstance(v, bool):
            return v
        if not isinstance(v, list) or not v or not all(isinstance(x, str) for x in v):
            raise BadValue(f"must be true, false or a list of names from {', '.join(options)}; "
                           f"got {type_name(v)} {v!r}")
        unknown = [x for x in v if x not in options]
        if unknown:
            raise BadValue(f"unknown {', '.join(repr(x) for x in unknown)}; choose from "
                           f"{', '.join(options)}")
        return tuple(v)
    return check


def vector3(lo: float | None = None, lo_strict: bool = False):
    each = real(lo, lo_strict)

    def check(v):
        if not isinstance(v, list) or len(v) != 3:
            raise BadValue(f"must be an array of 3 numbers, got {v!r}")
        out = []
        for i, x in enumerate(v):
            try:
                out.append(each(x))
            except BadValue as bad:
                raise BadValue(f"entry {i} {bad.reason}") from None
        return tuple(out)
    return check


def points3(v) -> tuple:
    """An array of [x, y, z] (a mesh's vertices)."""
    return _points(v, least=1)


def index_triples(v) -> tuple:
    """An array of [i, j, k] of integers >= 0 (a mesh's triangles)."""
    if not isinstance(v, list) or not v:
        raise BadValue(f"must be a non-empty array of [i, j, k], got {type_name(v)}")
    for n, t in enumerate(v):
        if not isinstance(t, list) or len(t) != 3 or \
                not all(isinstance(i, int) and not isinstance(i, bool) and i >= 0 for i in t):
            raise BadValue(f"entry {n} must be 3 integers >= 0, got {t!r}")
    return tuple(tuple(t) for t in v)


def scheme_name(v):
    v = string(v)
    try:
        get_scheme(v)
    except (ValueError, TypeError) as err:
        raise BadValue(str(err)) from None
    return v


@dataclass(frozen=True)
class Coefficient:
    """A material coefficient: a constant or a polynomial c0 + c1 s + c2 s^2 + ... in s."""

    constant: float | None = None
    polynomial: tuple[float, ...] = ()

    @property
    def is_constant(self) -> bool:
        return self.constant is not None

    @property
    def is_zero(self) -> bool:
        return not (self.constant if self.constant is not None else any(self.polynomial))

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
                raise BadValue(f"{reason} (the polynomial)")
            if len(coeffs) == 1 or not any(coeffs[1:]):
                return Coefficient(constant=coeffs[0])
            return c
        return Coefficient(constant=real(0.0, lo_strict=strict)(v))
    return check


def _polynomial(v) -> tuple[float, ...]:
    if not isinstance(v, dict):
        raise BadValue(f"must be {{polynomial = [c0, c1, ...]}}, got {type_name(v)}")
    refuse_unknown(v, {"polynomial"})
    if "polynomial" not in v:
        raise BadValue("missing required key", "polynomial")
    p = v["polynomial"]
    if not isinstance(p, list) or not p:
        raise BadValue("must be a non-empty array", "polynomial")
    return tuple(p)


def _polynomial_numbers(v) -> tuple[float, ...]:
    try:
        return tuple(number(c) for c in _polynomial(v))
    except BadValue as bad:
        raise BadValue(bad.reason, bad.key or "polynomial") from None


def profile(v):
    """A load profile along s: a number or {polynomial = [c0, c1, ...]}, any sign."""
    if not isinstance(v, dict):
        return Coefficient(constant=number(v))
    coeffs = _polynomial_numbers(v)
    if len(coeffs) == 1 or not any(coeffs[1:]):
        return Coefficient(constant=coeffs[0])
    return Coefficient(polynomial=coeffs)


@dataclass(frozen=True)
class VelocityProfile:
    """A starting velocity along the rod, value profile(s) (s the arc length from the
    rod's start, length units): a mode shape's, DisMech's cantilever's."""

    value: tuple[float, float, float]
    profile: Coefficient

    def __call__(self, s) -> np.ndarray:
        """(len(s), 3) velocities at the arc lengths s."""
        s = np.asarray(s, dtype=float)
        return np.outer(self.profile.values(s), self.value)


def velocity_field(v):
    """[x, y, z], or {value = [x, y, z], profile = {polynomial = [c0, c1, ...]}} (the
    distributed loads' profile along s)."""
    if not isinstance(v, dict):
        return vector3()(v)
    refuse_unknown(v, {"value", "profile"})
    for key in ("value", "profile"):
        if key not in v:
            raise BadValue("missing required key", key)
    try:
        value = vector3()(v["value"])
    except BadValue as bad:
        raise BadValue(bad.reason, "value") from None
    try:
        shape = profile(v["profile"])
    except BadValue as bad:
        raise BadValue(bad.reason, f"profile.{bad.key}" if bad.key else "profile") from None
    return VelocityProfile(value, shape)


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
                raise BadValue(f"row {i} must have 3 numbers, got {r!r}")
            rows.append([number(x) for x in r])
        return np.array(rows)
    return np.diag(vector3()(v))


def tensor(v) -> Tensor:
    """[a, b, c] (diagonal), [[...], [...], [...]] (3x3), or {polynomial = [T0, T1, ...]}."""
    if isinstance(v, dict):
        try:
            terms = tuple(_matrix(t) for t in _polynomial(v))
        except BadValue as bad:
            raise BadValue(bad.reason, bad.key or "polynomial") from None
    else:
        terms = (_matrix(v),)
    for t in terms:
        if not np.allclose(t, t.T, rtol=1e-12, atol=0.0):
            raise BadValue(f"must be symmetric, got {t.tolist()}")
    return Tensor(terms)


def spring_table(v) -> dict:
    """{translational = k or [k_x, k_y, k_z], rotational = k or [k_1, k_2, k_3]}, each
    >= 0 (rod/boundary_conditions.EndSpring)."""
    if not isinstance(v, dict):
        raise BadValue(f"must be a table {{translational = ..., rotational = ...}}, got "
                       f"{type_name(v)}")
    refuse_unknown(v, {"translational", "rotational"})
    out = {}
    for k, x in v.items():
        try:
            out[k] = vector3(0.0)(x) if isinstance(x, list) else real(0.0)(x)
        except BadValue as bad:
            raise BadValue(bad.reason, k) from None
    return out


def damping_tensor(v) -> Tensor:
    """A number c (c I), [c_1, c_2, c_3] (diagonal) or a symmetric 3x3 array, positive
    semidefinite."""
    if isinstance(v, dict):
        raise BadValue("must be a number, [c_1, c_2, c_3] or a 3x3 array")
    t = tensor(v) if isinstance(v, list) else Tensor((real(0.0)(v) * np.eye(3),))
    if np.linalg.eigvalsh(t.terms[0]).min() < 0:
        raise BadValue(f"must be positive semidefinite, got {t.terms[0].tolist()}")
    return t


def drag(v) -> Coefficient | Tensor:
    """A number c or {polynomial = [c0, c1, ...]} (isotropic, f = -c v: a Coefficient), or
    [c_1, c_2, c_3] or a symmetric 3x3 array in the directors' frame (f = -R C R^T v: a
    Tensor), positive semidefinite."""
    return damping_tensor(v) if isinstance(v, list) else coefficient(False)(v)


def entry_point(v) -> str:
    """"package.module:function": imported (from the scene's folder or sys.path)."""
    v = string(v)
    module, sep, name = v.partition(":")
    if not (sep and module and name.isidentifier()):
        raise BadValue(f"must be \"quadratic\" or an entry point \"package.module:function\", "
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
        raise BadValue(f"cannot import {spec!r}: {err}") from None
    except Exception as err:     # the module's own code failed: a SyntaxError, a raise
        raise BadValue(f"cannot import {spec!r}: {type(err).__name__}: {err}") from None
    except SystemExit as err:    # the module ends the program when imported
        raise BadValue(f"cannot import {spec!r}: importing it calls sys.exit({err.code!r})") \
            from None
    finally:
        if added:
            sys.path.remove(str(folder))
    if not callable(obj):
        raise BadValue(f"{spec!r} is not callable")
    return obj


def toml_value(v) -> str:
    """A value as inline TOML (for scene.toml and for error messages that show a key's
    new spelling)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"


FRICTION_DIRECTIONS = ("forward", "backward", "lateral")


def friction_coefficients(v):
    """Coulomb's mu >= 0, or {forward, backward, lateral} (each >= 0): coefficients
    relative to the rod's axis, a tuple in that order (rod/contact.py)."""
    if not isinstance(v, dict):
        return real(0.0)(v)
    refuse_unknown(v, set(FRICTION_DIRECTIONS))
    for key in FRICTION_DIRECTIONS:
        if key not in v:
            raise BadValue("missing required key (directional friction: forward, backward, "
                           "lateral)", key)
    out = []
    for key in FRICTION_DIRECTIONS:
        try:
            out.append(real(0.0)(v[key]))
        except BadValue as bad:
            raise BadValue(bad.reason, key) from None
    return tuple(out)


def largest_friction(mu) -> float:
    """The largest coefficient of an obstacle's friction (friction_coefficients)."""
    return max(mu) if isinstance(mu, tuple) else mu


def refuse_unknown(table: dict, known: set[str], also=()) -> None:
    """BadValue naming the first key not in ``known`` (the message lists ``also``, keys
    checked before, as known too)."""
    for k in table:
        if k not in known:
            raise BadValue(f"unknown key (known: {', '.join(sorted({*known, *also}))})", k)


def section_inertia(v) -> tuple[float, float]:
    """I_11 = I_22 (a number) or [I_11, I_22], each >= 0."""
    if isinstance(v, list):
        if len(v) != 2:
            raise BadValue(f"must be a number or [I_11, I_22], got {v!r}")
        return (real(0.0)(v[0]), real(0.0)(v[1]))
    x = real(0.0)(v)
    return (x, x)


def positive_pair(v) -> tuple[float, float]:
    """A number (both entries) or [x_1, x_2], each > 0."""
    if isinstance(v, list):
        if len(v) != 2:
            raise BadValue(f"must be a number or an array of 2 numbers, got {v!r}")
        return (real(0.0, True)(v[0]), real(0.0, True)(v[1]))
    x = real(0.0, True)(v)
    return (x, x)


def ts_type_name(v) -> str:
    from ..integrators.ts import parse_ts_type
    v = string(v)
    try:
        parse_ts_type(v)
    except ValueError as err:
        raise BadValue(str(err)) from None
    return v


def petsc_table(v) -> dict:
    """PETSc options: names without the leading '-', values numbers, strings or booleans."""
    if not isinstance(v, dict):
        raise BadValue(f"must be a table of PETSc options, got {type_name(v)}")
    for k, x in v.items():
        if k.startswith("-") or not k.replace("_", "").isalnum():
            raise BadValue("must be a PETSc option name without the leading '-'", k)
        if not isinstance(x, (bool, int, float, str)) or (isinstance(x, float)
                                                         and not math.isfinite(x)):
            raise BadValue(f"must be a number, string or boolean, got {type_name(x)}", k)
    return dict(v)


def tensor_table(v, names) -> dict[str, Tensor]:
    """The tensors of a stiffness/viscosity table (required ones checked per model)."""
    if not isinstance(v, dict):
        raise BadValue(f"must be a table with {', '.join(names)}, got {type_name(v)}")
    refuse_unknown(v, set(names))
    out = {}
    for n in names:
        if n in v:
            try:
                out[n] = tensor(v[n])
            except BadValue as bad:
                raise BadValue(bad.reason, f"{n}.{bad.key}" if bad.key else n) from None
    return out


# initial.shape: per type its keys with (checker, default; REQUIRED_KEY: must be given)
REQUIRED_KEY = object()
_POSITIVE, _STRETCH = real(0.0, True), (real(0.0, True), 1.0)
SHAPE_KEYS = {
    "straight": {"stretch": _STRETCH},
    "arc": {"radius": (_POSITIVE, REQUIRED_KEY), "stretch": _STRETCH},
    "helix": {"radius": (_POSITIVE, REQUIRED_KEY), "pitch": (real(), REQUIRED_KEY),
              "stretch": _STRETCH},
    "polyline": {"points": (lambda v: _points(v), REQUIRED_KEY),
                 "rest_arc_length": (lambda v: _numbers(v), None),
                 "normal": (vector3(), (1.0, 0.0, 0.0))},
}


def table_type(v: dict, types) -> str:
    """The checked ``type`` key of a table that is one of ``types``."""
    if "type" not in v:
        raise BadValue(f"missing required key (one of {', '.join(types)})", "type")
    try:
        return choice(*types)(v["type"])
    except BadValue as bad:
        raise BadValue(bad.reason, "type") from None


def starting_shape(v) -> dict:
    """{type = "straight" | "arc" | "helix" | "polyline", ...} (SHAPE_KEYS): the checked
    keys with their defaults, and the type."""
    if not isinstance(v, dict):
        raise BadValue(f"must be a table {{type = ..., ...}}, got {type_name(v)}")
    kind = table_type(v, SHAPE_KEYS)
    keys = SHAPE_KEYS[kind]
    refuse_unknown(v, {"type", *keys})
    out = {"type": kind}
    for k, (check, default) in keys.items():
        if k not in v:
            if default is REQUIRED_KEY:
                raise BadValue(f"missing required key of a {kind}", k)
            out[k] = default
            continue
        try:
            out[k] = check(v[k])
        except BadValue as bad:
            raise BadValue(bad.reason, k) from None
    return out


def _points(v, least: int = 2) -> tuple:
    if not isinstance(v, list) or len(v) < least:
        raise BadValue(f"must be an array of at least {('one', 'two')[least - 1]} "
                       f"[x, y, z], got {type_name(v)}")
    out = []
    for i, p in enumerate(v):
        try:
            out.append(vector3()(p))
        except BadValue as bad:
            raise BadValue(f"point {i} {bad.reason}") from None
    return tuple(out)


def _numbers(v) -> tuple:
    if not isinstance(v, list):
        raise BadValue(f"must be an array of numbers, got {type_name(v)}")
    return tuple(number(x) for x in v)
