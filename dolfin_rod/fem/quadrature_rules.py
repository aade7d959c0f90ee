"""Forms split so that no compiled kernel mixes quadrature rules (FFCx 0.9 to 0.11).

FFCx compiles the integrals of one type and subdomain of a form into one kernel, one
quadrature loop per rule.  It first computes, for every rule, the sub-expressions that
are constant on the cell (its "piecewise" partition) into ONE scope shared by all the
loops, keyed by the UFL expression; a loop then skips any sub-expression already in that
scope.  Under a 1-point rule (the rod's ``dx_r``) every basis table has one point, so
every sub-expression counts as constant and is evaluated at the midpoint; the same
sub-expression in another rule's loop (``dx``: inertia, loads, drag, momenta) then takes
that midpoint value instead of its value at each of its points.  Plain DOLFINx shows it:
on [0, 1] with u = s (P1), ``u sin(u) (dx(degree=1) + dx(degree=4))`` assembles to
2 x 0.2397 (twice the midpoint rule) instead of 0.2397 + 0.3012 (tests/test_assembly.py,
``test_one_kernel_per_quadrature_rule``).  Whether a form is hit depends on which
sub-expressions the rules share; the error is O(h^2 |u''|)-sized, not round-off (the
fused diagnostics: up to 27 % on a contact scene's kinetic energy, docs/verification.md).

One kernel per rule avoids it: the integrals of each rule go to their own form.
"""

from __future__ import annotations

import ufl


def rule_of(integral: ufl.classes.Integral) -> tuple:
    """The quadrature metadata of an integral (integrals without a given degree: one
    group, UFL's estimate per integral)."""
    return tuple(sorted(integral.metadata().items()))


def one_rule_per_kernel(integrals) -> list[ufl.Form]:
    """``integrals`` as the fewest forms in which each kernel has one quadrature rule, by
    integral type (not by subdomain: UFL adds the integrals over everywhere to each
    subdomain's kernel): an integral type with r of the n rules has them in the last r
    forms, so that a type with one rule (the end points' facets) is assembled after every
    cell rule, as in one kernel (the same sums in the same order)."""
    kernels: dict = {}
    for itg in integrals:
        rules = kernels.setdefault(itg.integral_type(), {})
        rules.setdefault(rule_of(itg), []).append(itg)
    n = max((len(rules) for rules in kernels.values()), default=0)
    forms: list[list] = [[] for _ in range(n)]
    for rules in kernels.values():
        for k, group in enumerate(rules.values(), start=n - len(rules)):
            forms[k] += group
    return [ufl.Form(group) for group in forms]
