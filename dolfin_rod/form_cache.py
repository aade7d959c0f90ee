"""Compiled forms shared by every model of the same structure (issue 12: set-up time).

Building a rod's step forms costs seconds of UFL processing (derivative expansion,
replacement, signatures) even with a warm FFCx cache, while the kernels depend only on
the model's structure, not on its mesh size or data.  A cache entry is keyed by a
structure key (the UFL signatures of the model's residual plus what the integrator
bakes in); it keeps the compiled DOLFINx forms and, for each of their coefficients and
constants, its position in an ordered list of the objects of the instance (the
"registry": the model's Functions and Constants in creation order, then the
integrator's and the assembler's own).  A new instance with the same key binds the
compiled kernels to its own objects, mesh and spaces without building any UFL.
"""

from __future__ import annotations

import hashlib

import dolfinx.fem as fem
import ufl
from dolfinx.fem.forms import form_cpp_class

from . import compat

_ENTRIES: dict[str, list] = {}


def registry(forms) -> list:
    """The Functions and Constants of ``forms`` in creation order (UFL count)."""
    objs = set()
    for form in forms:
        objs.update(form.coefficients())
        objs.update(form.constants())
    return sorted(objs, key=lambda c: (isinstance(c, ufl.Constant), c.count()))


def structure_key(forms, *extra) -> str:
    """A key for the kernels of ``forms`` (their UFL signatures) and ``extra`` items."""
    text = "|".join([*(form.signature() for form in forms), *map(repr, extra)])
    return hashlib.sha1(text.encode()).hexdigest()


def clear() -> None:
    """Forget every compiled form (the next model of each structure compiles again)."""
    _ENTRIES.clear()


def lookup(key: str | None):
    return _ENTRIES.get(key) if key else None


def store(key: str, compiled: list[fem.Form], ufl_forms: list[ufl.Form], objects) -> None:
    """Remember compiled forms with the registry positions of their data (skipped when a
    form integrates over tagged subdomains, whose tags are not in the registry)."""
    if any(itg.subdomain_data() is not None for form in ufl_forms for itg in form.integrals()):
        return
    index = {id(obj): i for i, obj in enumerate(objects)}
    entry = []
    for form, uform in zip(compiled, ufl_forms):
        ufcx = form.ufcx_form
        coefficients = uform.coefficients()
        roles = [index[id(coefficients[ufcx.original_coefficient_positions[i]])]
                 for i in range(ufcx.num_coefficients)]
        entry.append((form, roles, [index[id(c)] for c in uform.constants()]))
    _ENTRIES[key] = entry


def bind(entry, objects, space, mesh) -> list[fem.Form]:
    """The cached kernels with the data of ``objects``, arguments in ``space``."""
    return [_bound_form(form, [objects[i] for i in roles], [objects[i] for i in const_roles],
                        space, mesh) for form, roles, const_roles in entry]


def _bound_form(form: fem.Form, coefficients, constants, space, mesh) -> fem.Form:
    """A DOLFINx form from a compiled one with other data (the C++ constructor: the one
    call here that differs between DOLFINx 0.9 and 0.11)."""
    ufcx, module = form.ufcx_form, form.module
    pointer = module.ffi.cast("uintptr_t", module.ffi.addressof(ufcx))
    old = compat.DOLFINX_VERSION < (0, 10)
    f = form_cpp_class(form.dtype)(
        pointer if old else [int(pointer)],
        [space._cpp_object] * form.rank, [c._cpp_object for c in coefficients],
        [c._cpp_object for c in constants], {t: [] for t in form.integral_types},
        {} if old else [], mesh._cpp_object)
    return fem.Form(f, ufcx, form.code, module)
