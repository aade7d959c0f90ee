"""A block residual gathered term by term and made into one ufl.Form at the end (issue 30,
target 1: set-up time).

UFL's Form constructor traverses every integrand (to find its constants), and
``form_a + form_b`` constructs a new Form: a residual built by n terms ``F += a * dx``
traverses its first terms n times, a third of a rod model's set-up.  ``GatheredForm``
keeps the integrals of the terms added to it and constructs the Form once (``form``);
``integrate(integrand, measure)`` adds the integral ``integrand * measure`` makes without
making its one-integral Form (one traversal less of the largest integrands, the internal
work's).
UFL sorts a Form's integrals canonically and ``a - b`` is ``a + (-b)``, integral by
integral, so the Form is the one the chain of sums gives (the same signature, the same
kernels).

``LazyForms``: block residuals made when first read.  A model binds its compiled kernels
by the Functions and Constants of its residual (fem/form_cache.registry), which are those
of its terms before the last rewriting (a rod's one-point rule), found by one traversal;
a second model of a structure whose kernels are cached never makes the Forms unless
something reads them (a new compile, an analysis, the reactions).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import ufl


class GatheredForm:
    """The integrals of a sum of forms; ``+=`` and ``-=`` a ufl.Form."""

    def __init__(self, form: ufl.Form | None = None):
        self._integrals = list(form.integrals()) if form is not None else []

    def integrate(self, integrand, measure: ufl.Measure) -> None:
        """Adds the integral of a scalar ``integrand`` over ``measure`` (that of
        ``integrand * measure``)."""
        subdomain = measure.subdomain_id()
        if (measure.ufl_domain() is None or isinstance(subdomain, tuple)
                or integrand.ufl_shape or integrand.ufl_free_indices):
            self += integrand * measure         # UFL finds the domain, or names the error
            return
        self._integrals.append(ufl.Integral(integrand, measure.integral_type(),
                                            measure.ufl_domain(), subdomain,
                                            measure.metadata(), measure.subdomain_data()))

    def __iadd__(self, form: ufl.Form) -> "GatheredForm":
        self._integrals.extend(form.integrals())
        return self

    def __isub__(self, form: ufl.Form) -> "GatheredForm":
        self._integrals.extend(-integral for integral in form.integrals())
        return self

    def integrals(self) -> list:
        return list(self._integrals)

    def form(self) -> ufl.Form:
        return ufl.Form(self._integrals)


def as_form(form) -> ufl.Form:
    """A ufl.Form of a GatheredForm or a ufl.Form."""
    return form.form() if isinstance(form, GatheredForm) else form


def data_of(integrals) -> set:
    """The Functions and Constants (ufl.Coefficient, ufl.Constant) in ``integrals``' integrands
    (those of a Form's ``coefficients()`` and ``constants()``): one traversal of their
    shared expressions, known by identity (UFL's traversal keeps a set of the expressions
    themselves, whose hashes, computed for every new expression, cost a second model of a
    rod 80 % of the traversal)."""
    seen: set[int] = set()
    found: set = set()
    stack = [itg.integrand() for itg in integrals]
    while stack:
        expr = stack.pop()
        if id(expr) in seen:
            continue
        seen.add(id(expr))
        if expr.ufl_operands:
            stack.extend(expr.ufl_operands)
        elif isinstance(expr, (ufl.Coefficient, ufl.Constant)):
            found.add(expr)
    return found


class LazyForms(Sequence):
    """A list of ``count`` ufl.Forms that ``make()`` returns, called at the first read of a
    form; ``data``: the Functions and Constants the forms will have (data_of), known
    before they are made."""

    def __init__(self, make: Callable[[], list[ufl.Form]], count: int, data: set):
        self._make, self._count, self.data = make, count, frozenset(data)
        self._forms: list[ufl.Form] | None = None

    def __len__(self) -> int:
        return self._count

    def __getitem__(self, index):
        if self._forms is None:
            self._forms = list(self._make())
            self._make = None
        return self._forms[index]

    @property
    def made(self) -> bool:
        """Whether the forms were made (read)."""
        return self._forms is not None
