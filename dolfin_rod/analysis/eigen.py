"""Eigenpairs of a matrix pencil A x = lambda B x near a target, by SLEPc: the one
eigen-solve of the analyses (buckling, vibration modes, the lowest eigenvalues of the
tangent stiffness, branch switching; docs/stability.md).

Shift-and-invert about the target sigma: the operator (A - sigma B)^-1 B, whose largest
eigenvalues 1/(lambda - sigma) are the lambda nearest sigma; (A - sigma B) is factorised
once by MUMPS (LU: also indefinite and saddle-point A).  Rows of B that are zero (the
Dirichlet dofs of the analyses: A's rows there are the identity) give lambda = infinity,
out of the way.  Works in parallel: A, B distributed PETSc matrices (MPIAIJ), the
vectors in A's layout.

    pairs = eigenpairs(K, G, count=4)               # K v = lambda G v, lambda nearest 0
    pairs.values[0], pairs.vectors[0], pairs.residuals[0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

__all__ = ["Eigenpairs", "eigenpairs", "EigenError"]

KINDS = ("symmetric", "symmetric_indefinite", "general")


class EigenError(RuntimeError):
    """SLEPc found fewer eigenpairs than asked (reason and count in the message)."""


@dataclass
class Eigenpairs:
    """``values`` (real parts; ``imaginary`` their imaginary parts, 0 for the symmetric
    kinds), ``vectors`` (PETSc Vecs in A's layout, normalised: x^T B x = 1 for a
    positive-definite B, else |x|_2 = 1; of a complex pair the real part) and the
    relative residuals |A z - lambda B z| / (|A| + |lambda| |B|) |z| (z complex for a
    complex pair), ordered by |lambda - target| (equal
    distances by value: -lambda before lambda)."""

    values: np.ndarray
    imaginary: np.ndarray
    vectors: list
    residuals: np.ndarray


def eigenpairs(A: PETSc.Mat, B: PETSc.Mat | None = None, count: int = 1,
               target: float = 0.0, kind: str = "symmetric", tolerance: float = 1e-10,
               max_iterations: int = 200) -> Eigenpairs:
    """The ``count`` eigenpairs of A x = lambda B x (B None: the identity) nearest
    ``target`` (kind "general": count + 1 when the count would cut a complex conjugate
    pair in two).

    kind: "symmetric" (A symmetric, B symmetric positive semi-definite: GHEP),
          "symmetric_indefinite" (both symmetric, B indefinite: GHIEP; e.g. the load's
          derivative of a buckling analysis), "general" (GNHEP).
    Raises ValueError for a bad argument, EigenError when fewer than ``count`` pairs
    converged.
    """
    from slepc4py import SLEPc
    if kind not in KINDS:
        raise ValueError(f"kind: one of {', '.join(KINDS)}, got {kind!r}")
    if int(count) != count or count < 1:
        raise ValueError(f"count: a positive integer, got {count!r}")
    types = {"symmetric": SLEPc.EPS.ProblemType.GHEP if B is not None
             else SLEPc.EPS.ProblemType.HEP,
             "symmetric_indefinite": SLEPc.EPS.ProblemType.GHIEP,
             "general": SLEPc.EPS.ProblemType.GNHEP if B is not None
             else SLEPc.EPS.ProblemType.NHEP}
    eps = SLEPc.EPS().create(A.getComm())
    eps.setOperators(A, B) if B is not None else eps.setOperators(A)
    eps.setProblemType(types[kind])
    eps.setDimensions(int(count))
    eps.setTarget(float(target))
    eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    st = eps.getST()
    st.setType(SLEPc.ST.Type.SINVERT)
    ksp = st.getKSP()
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    eps.setTolerances(tolerance, max_iterations)
    try:
        eps.solve()
        found = eps.getConverged()
        if found < count:
            raise EigenError(f"SLEPc converged {found} of {count} eigenpairs near {target:g} "
                             f"(reason {eps.getConvergedReason()})")
        return _pairs(eps, A, B, found, int(count), target, kind)
    finally:
        eps.destroy()


def _pairs(eps, A, B, found: int, count: int, target: float, kind: str) -> Eigenpairs:
    values, vectors, residuals = [], [], []
    norm_A = A.norm(PETSc.NormType.INFINITY)
    norm_B = 1.0 if B is None else B.norm(PETSc.NormType.INFINITY)
    for i in range(found):
        x, y = A.createVecRight(), A.createVecRight()
        value = complex(eps.getEigenpair(i, x, y))       # x + i y (real arithmetic)
        values.append(value)
        if value.imag == 0.0:
            y.set(0.0)
        scale = _normalise(x, B if kind == "symmetric" else None)
        y.scale(scale)
        residuals.append(_residual(A, B, value, x, y) / (norm_A + abs(value) * norm_B))
        y.destroy()
        vectors.append(x)
    # by distance, equal distances (to 9 digits: +-lambda pairs) by value
    order = sorted(range(found), key=lambda i: (float(f"{abs(values[i] - target):.9e}"),
                                                values[i].real))
    last = values[order[count - 1]]
    whole = count < found and last.imag != 0.0 and \
        abs(values[order[count]] - last.conjugate()) <= 1e-12 * abs(last)
    order = order[:count + 1 if whole else count]       # a complex pair is not cut
    values = np.array(values)[order]
    for i in set(range(found)) - set(order):
        vectors[i].destroy()
    return Eigenpairs(values.real.copy(), values.imag.copy(), [vectors[i] for i in order],
                      np.array(residuals)[order])


def _residual(A: PETSc.Mat, B: PETSc.Mat | None, value: complex, x: PETSc.Vec,
              y: PETSc.Vec) -> float:
    """|A z - lambda B z| / |z| for z = x + i y (y = 0 for a real pair)."""
    def times(M, v):
        w = v.copy() if M is None else M.createVecLeft()
        if M is not None:
            M.mult(v, w)
        return w
    Ax, Ay, Bx, By = times(A, x), times(A, y), times(B, x), times(B, y)
    Ax.axpy(-value.real, Bx)            # real part: A x - a B x + b B y
    Ax.axpy(value.imag, By)
    Ay.axpy(-value.real, By)            # imaginary: A y - a B y - b B x
    Ay.axpy(-value.imag, Bx)
    return float(np.hypot(Ax.norm(), Ay.norm()) / np.hypot(x.norm(), y.norm()))


def _normalise(x: PETSc.Vec, B: PETSc.Mat | None) -> float:
    """x^T B x = 1 (B positive semi-definite and x^T B x > 0), else |x|_2 = 1; the sign
    such that the largest entry in magnitude is positive (reproducible across ranks);
    returns the factor x was scaled by."""
    size = x.norm()
    if B is not None:
        Bx = B.createVecLeft()
        B.mult(x, Bx)
        mass = x.dot(Bx)
        if mass > 0:
            size = np.sqrt(mass)
    x.scale(1.0 / size)
    local = x.getArray(readonly=True)
    big = local[np.argmax(np.abs(local))] if len(local) else 0.0
    comm = x.getComm().tompi4py()
    biggest = comm.allgather(big)
    if biggest[int(np.argmax(np.abs(biggest)))] < 0:
        x.scale(-1.0)
        return -1.0 / size
    return 1.0 / size
