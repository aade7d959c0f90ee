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
"""

from __future__ import annotations

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
