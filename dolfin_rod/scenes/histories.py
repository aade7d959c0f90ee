"""Load histories and distributed loads as written in a scene: ``{type = "step" |
"ramp" | "smooth_step" | "table" | "constant", ...}`` -> :class:`HistorySpec`, which
builds the :mod:`dolfin_rod.loads` history the models evaluate.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import loads as load_histories
from .values import (BadValue, boolean, number, profile, real, refuse_unknown, table_type,
                     type_name, vector3)

HISTORY_TYPES = ("step", "ramp", "smooth_step", "table", "constant")


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
            raise BadValue(f"must be a table {{type = \"step\"|\"ramp\"|...}}, got {type_name(v)}")
        follower = False
        if follower_ok and "follower" in v:
            v = dict(v)
            try:
                follower = boolean(v.pop("follower"))
            except BadValue as bad:
                raise BadValue(bad.reason, "follower") from None
        kind = table_type(v, HISTORY_TYPES)
        keys = _HISTORY_KEYS[kind]
        refuse_unknown(v, {"type", *keys})
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
        return HistorySpec(**out, follower=follower)
    return check


def distributed(v):
    """{value = [x, y, z] (rod) , profile = number | {polynomial}, history = {...},
    follower = bool (rod)}: value profile(s) history(t) per unit reference length."""
    if not isinstance(v, dict):
        raise BadValue(f"must be a table {{profile = ..., history = {{...}}}}, got {type_name(v)}")
    refuse_unknown(v, {"value", "profile", "history", "follower"})
    out = {"value": None, "follower": False}
    checks = (("value", vector3(), None), ("profile", profile, 1.0),
              ("history", history(False), {"type": "constant", "value": 1.0}),
              ("follower", boolean, False))
    for k, check, default in checks:
        if k not in v and default is None:
            continue
        try:
            out[k] = check(v.get(k, default))
        except BadValue as bad:
            raise BadValue(bad.reason, f"{k}.{bad.key}" if bad.key else k) from None
    return out
