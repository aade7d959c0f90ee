"""Loads and prescribed motions as written in a scene, one syntax for all (issue 25
item 6): ``{type = "step" | "ramp" | "smooth_step" | "table" | "constant", value, t0,
duration, follower, profile}`` -> :class:`HistorySpec`, which builds the
:mod:`dolfin_rod.loads` history the models evaluate.  ``follower`` is for rod loads,
``profile`` (a function of s) for distributed loads only, ``s`` (where) for point loads.
A muscle's travelling wave of active moment, ``loads.muscle = {axis, amplitude, period,
wave_length, phase, ramp, origin, follower}`` -> the keywords of
rod/external_forces.TravellingWave (``muscle``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .. import loads as load_histories
from .values import (BadValue, Coefficient, boolean, choice, number, profile, real,
                     refuse_unknown, toml_value, type_name, vector3)

HISTORY_TYPES = ("step", "ramp", "smooth_step", "table", "constant")


@dataclass(frozen=True)
class HistorySpec:
    """A load history as written in the scene: {type = ..., ...}."""

    type: str
    value: float | tuple[float, ...] = 0.0
    t0: float = 0.0            # step: time of the jump; ramp, smooth step: start
    duration: float = 1.0      # ramp: time to reach value; smooth_step: width
    times: tuple[float, ...] = ()
    values: tuple = ()         # numbers, or 3-vectors (a vector table)
    follower: bool = False     # rod loads: components in the material (rotating) frame
    profile: Coefficient | None = None   # distributed loads: the factor profile(s)
    s: float | None = None     # point loads: where on the rod (its own arc length)

    def build(self, component: int | None = None):
        """The loads.LoadHistory (component of a vector value if given)."""
        if self.type == "table":
            values = self.values if component is None else [x[component] for x in self.values]
            return load_histories.table(self.times, values)
        v = self.value if component is None else self.value[component]
        if self.type == "step":
            return load_histories.step(v, self.t0)
        if self.type == "ramp":
            return load_histories.ramp(v, self.duration, self.t0)
        if self.type == "smooth_step":
            return load_histories.smooth_step(v, self.duration, self.t0)
        return load_histories.constant(v)

    @property
    def is_vector(self) -> bool:
        if self.type == "table":
            return isinstance(self.values[0], tuple)
        return isinstance(self.value, tuple)

    def vector(self):
        """t -> the 3-vector value (rod end motions): a loads.VectorHistory."""
        return load_histories.VectorHistory(tuple(self.build(i) for i in range(3)))

    @property
    def jumps_at_start(self) -> bool:
        return self.type == "step" and self.t0 == 0.0 and self.value != 0.0

    def fastest_change(self) -> tuple[float, str]:
        """The shortest time over which the history changes and the key that sets it:
        0 for a jump (a step of a nonzero value, at any t0), a ramp's or smooth step's
        duration, the shortest table segment that changes the value; inf if constant."""
        moves = bool(np.any(np.asarray(self.value, dtype=float) != 0.0))
        if self.type == "step" and moves:
            return 0.0, "t0"
        if self.type in ("ramp", "smooth_step") and moves:
            return self.duration, "duration"
        if self.type == "table":
            values = np.asarray(self.values, dtype=float).reshape(len(self.times), -1)
            spans = np.diff(self.times)[np.any(np.diff(values, axis=0) != 0.0, axis=1)]
            return (float(spans.min()), "times") if spans.size else (math.inf, "")
        return math.inf, ""

    def breakpoints(self) -> tuple[float, ...]:
        """Times where the history is not smooth (for the ODE integrator)."""
        if self.type == "step":
            return (self.t0,)
        if self.type in ("ramp", "smooth_step"):
            return (self.t0, self.t0 + self.duration)
        if self.type == "table":
            return self.times
        return ()


_HISTORY_KEYS = {
    "step": {"value": True, "t0": False},
    "ramp": {"value": True, "duration": True, "t0": False},
    "smooth_step": {"value": True, "duration": True, "t0": False},
    "constant": {"value": True},
    "table": {"times": True, "values": True},
}


def history(vector_ok: bool, follower_ok: bool = False, profile_ok: bool = False,
            point: bool = False):
    """The checker of a load or motion {type, value, t0, duration, times, values} (type
    "constant" if not given), with follower (rod loads), profile (distributed loads)
    and s (point loads: required) where they apply."""
    def check(v):
        if not isinstance(v, dict):
            raise BadValue(f"must be a table {{type = \"step\"|\"ramp\"|...}}, got {type_name(v)}")
        v, extra = dict(v), {}
        if point and "s" not in v:
            raise BadValue("missing required key: where on the rod the load acts (its arc "
                           "length, 0 <= s <= geometry.length)", "s")
        for key, allowed, checker, where in (
                ("follower", follower_ok, boolean, "3-D rod loads"),
                ("profile", profile_ok, profile, "distributed loads"),
                ("s", point, real(), "point loads")):
            if key in v and not allowed:
                raise BadValue(f"{'a profile along s' if key == 'profile' else key} is for "
                               f"{where} only", key)
            if key in v:
                try:
                    extra[key] = checker(v.pop(key))
                except BadValue as bad:
                    raise BadValue(bad.reason, f"{key}.{bad.key}" if bad.key else key) from None
        try:
            kind = choice(*HISTORY_TYPES)(v.get("type", "constant"))
        except BadValue as bad:
            raise BadValue(bad.reason, "type") from None
        keys = _HISTORY_KEYS[kind]
        refuse_unknown(v, {"type", *keys}, also=[k for k, ok in (("follower", follower_ok),
                                                                 ("profile", profile_ok),
                                                                 ("s", point)) if ok])
        for k, required in keys.items():
            if required and k not in v:
                raise BadValue(f"missing required key for a {kind} history", k)
        out: dict[str, Any] = {"type": kind}
        for k in keys:
            if k not in v:
                continue
            try:
                if k == "value":
                    out[k] = (vector3()(v[k]) if vector_ok and isinstance(v[k], list)
                              else number(v[k]))
                elif k == "t0":
                    out[k] = real(0.0)(v[k])
                elif k == "duration":
                    out[k] = real(0.0, lo_strict=True)(v[k])
                else:
                    if not isinstance(v[k], list) or not v[k]:
                        raise BadValue("must be a non-empty array of numbers")
                    vectors = k == "values" and vector_ok and isinstance(v[k][0], list)
                    out[k] = tuple((vector3()(x) if vectors else number(x)) for x in v[k])
            except BadValue as bad:
                raise BadValue(bad.reason, k) from None
        if kind == "table":
            if len(out["times"]) != len(out["values"]):
                raise BadValue(f"times and values must have the same length, got "
                           f"{len(out['times'])} and {len(out['values'])}", "values")
            if any(b <= a for a, b in zip(out["times"], out["times"][1:])):
                raise BadValue("must be strictly increasing", "times")
        return HistorySpec(**out, **extra)
    return check


def distributed(v):
    """A distributed load per unit reference length, value profile(s) history(t): the one
    load syntax {type, value, t0, duration, follower, profile}.  The old form {value,
    profile, history = {...}} is refused with its new spelling."""
    if isinstance(v, dict) and "history" in v:
        raise BadValue("the load syntax changed: the history's keys now sit in the load "
                       f"itself, write {toml_value(_new_form(v))}", "history")
    return history(True, follower_ok=True, profile_ok=True)(v)


def _new_form(old: dict) -> dict:
    """The new spelling of an old distributed load {value, profile, history, follower}:
    the history's keys with its value (or table values) times the old value."""
    h = old["history"] if isinstance(old["history"], dict) else {}
    scale = old.get("value", 1.0)

    def times_scale(x):
        if isinstance(scale, list) and isinstance(x, (int, float)):
            return [x * c for c in scale]
        return x * scale if isinstance(x, (int, float)) and isinstance(scale, (int, float)) else x
    new = {k: x for k, x in h.items()}
    new.setdefault("type", "constant")
    if "value" in h or new["type"] != "table":
        new["value"] = times_scale(h.get("value", 1.0))
    if "values" in h and isinstance(h["values"], list):
        new["values"] = [times_scale(x) for x in h["values"]]
    new.update({k: old[k] for k in ("follower", "profile") if k in old})
    return new


def muscle(v) -> dict:
    """{axis, amplitude, period, wave_length, phase, ramp, origin, follower}: axis a
    non-zero 3-vector, amplitude a number or >= 4 B-spline control values, period and
    wave_length > 0, ramp >= 0, origin "start" | "end": the checked keyword arguments of
    rod/external_forces.TravellingWave (numbers only: the scene layer loads no DOLFINx)."""
    if not isinstance(v, dict):
        raise BadValue(f"must be a table {{axis, amplitude, period, wave_length, ...}}, got "
                       f"{type_name(v)}")
    checkers = {"axis": vector3(), "amplitude": _amplitude, "period": real(0.0, True),
                "wave_length": real(0.0, True), "phase": number, "ramp": real(0.0),
                "origin": choice("start", "end"), "follower": boolean}
    refuse_unknown(v, set(checkers))
    out = {}
    for key, checker in checkers.items():
        if key in ("axis", "amplitude", "period", "wave_length") and key not in v:
            raise BadValue("missing required key", key)
        if key in v:
            try:
                out[key] = checker(v[key])
            except BadValue as bad:
                raise BadValue(bad.reason, key) from None
    if not np.linalg.norm(out["axis"]) > 0:
        raise BadValue("must not be the zero vector", "axis")
    return out


def _amplitude(v):
    """A number (N m) or the B-spline's control values (at least 4 numbers)."""
    if not isinstance(v, list):
        return number(v)
    if len(v) < 4:
        raise BadValue(f"a B-spline's control values: at least 4 numbers, got {len(v)}")
    return tuple(number(x) for x in v)
