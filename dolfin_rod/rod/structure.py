"""A rod model's structure as data (issue 30, target 1): a text that is equal for two
models whose residual forms are equal up to the values of their fem.Constants and
Functions, built from the model's inputs without any UFL.

The step integrators key their compiled kernels by the UFL signatures of the residual
(fem/form_cache.py), which cost most of a stepper's set-up; with this text as
``SemiDiscreteProblem.structure`` a second model of the same structure in a process
reuses the key found for the first one.  The text is conservative: the material
coefficients that become fem.Constants (material.coefficients: the tensors and scalars
of RodParameters given as numbers) enter by whether they are zero (which terms the
residual has) and by shape; every other number enters with its value; a history of a
load or an end motion enters as "history" (its values reach the residual only through
Constants set at each time, and its jumps through the chosen rotation unknowns, which
are part of the text); a muscle's profile (external_forces.WaveProfile) by its
structure, its numbers being Constants; an energy function of this package
(dolfin_rod.dna:psi) by its name; anything else that is not plain data (a coefficient,
load or a user's energy given as a function, whose UFL may hold numbers) gives no text
(None): such a model's key is computed from its signatures.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .external_forces import WaveProfile
from .material import SCALAR_FIELDS, TENSORS, is_zero, scalars, tensors

HISTORIES = ("history", "end_displacement", "end_rotation")   # fields holding histories


class _NotData(Exception):
    """A value that cannot be written as data (a function)."""


def structure(rods, model: str, variant: str, constraint: str | None, rotations: str,
              comm_size: int, joints=(), obstacles=(), contact=None) -> str | None:
    """The structure of the model of ``rods`` (rods.Rod) as text, or None (see above).
    Cell counts enter only for several rods (their layout)."""
    try:
        return "|".join([
            model, variant, repr(constraint), rotations, str(comm_size),
            _data([rod.n_cells for rod in rods]) if len(rods) > 1 else "",
            *(_rod(rod) for rod in rods), _data(list(joints)), _data(list(obstacles)),
            _data(contact)])
    except _NotData:
        return None


def _rod(rod) -> str:
    params = rod.params
    coefficients = []
    for name, value in {**tensors(params), **scalars(params)}.items():
        if callable(value):
            raise _NotData(name)
        coefficients.append(f"{name}:" + ("0" if is_zero(value) else str(np.shape(value))))
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if f.name in TENSORS + SCALAR_FIELDS:
            continue
        if f.name == "energy":
            coefficients.append(f"energy:{_energy(value)}")
        else:
            coefficients.append(f"{f.name}:{_data(value)}")
    return ";".join(coefficients) + _record(rod, skip=("params", "n_cells"))


def _energy(psi) -> str:
    """The quadratic energy (None), or a function of this package at module level (pure:
    dolfin_rod.dna:psi) by name and identity; any other function is not data (a user's
    may read numbers that change between models)."""
    if psi is None:
        return "None"
    module, name = getattr(psi, "__module__", None) or "", getattr(psi, "__qualname__", "")
    if (module.split(".")[0] != __name__.split(".")[0] or "<" in name
            or getattr(psi, "__closure__", None) or not hasattr(psi, "__code__")):
        raise _NotData("energy")
    return f"{module}.{name}@{id(psi)}"


def _record(value, skip=()) -> str:
    """A dataclass instance's fields as text; histories as "history"."""
    return type(value).__qualname__ + "{" + ",".join(
        f"{f.name}:{_field(f.name, getattr(value, f.name))}"
        for f in dataclasses.fields(value) if f.name not in skip) + "}"


def _field(name: str, value) -> str:
    if name not in HISTORIES or value is None:
        return _data(value)
    if isinstance(value, dict):       # {end: history}
        return "{" + ",".join(f"{end!r}:history" for end in sorted(value)) + "}"
    return "history"


def _data(value) -> str:
    """Plain data as text (_NotData for anything else)."""
    if value is None or isinstance(value, (bool, int, float, str, np.number)):
        return repr(value)
    if isinstance(value, np.ndarray):
        return repr(value.tolist())
    if isinstance(value, (list, tuple)):
        return "(" + ",".join(_data(v) for v in value) + ")"
    if isinstance(value, dict):
        return "{" + ",".join(f"{_data(k)}:{_data(v)}" for k, v in
                              sorted(value.items(), key=lambda kv: repr(kv[0]))) + "}"
    if isinstance(value, WaveProfile):       # its numbers are Constants
        return value.structure()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return _record(value)
    raise _NotData(type(value).__name__)
