"""The shared eigen-solve (dolfin_rod/analysis/eigen.py) on matrices with closed-form
spectra, distributed over the ranks (the same numbers under mpirun -n 2).

The second-difference matrix tridiag(-1, 2, -1) of size n has the eigenvalues
4 sin^2(k pi / (2 (n + 1))), k = 1..n, with the eigenvectors sin(j k pi / (n + 1))
(the discrete sine transform).  Tolerances: SLEPc's 1e-10 relative residual bounds the
eigenvalue error of a symmetric pencil by about 1e-10 |lambda|; 1e-9 leaves room for the
factorisation's round-off (condition number ~ n^2 = 400)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from dolfin_rod.analysis.eigen import eigenpairs

N = 20


def matrix(diagonal: float, off: float, scale=lambda i: 1.0) -> PETSc.Mat:
    """tridiag(off, diagonal, off) with row i scaled by scale(i), distributed."""
    A = PETSc.Mat().createAIJ([N, N], nnz=3, comm=MPI.COMM_WORLD)
    start, end = A.getOwnershipRange()
    for i in range(start, end):
        A[i, i] = diagonal * scale(i)
        for j in (i - 1, i + 1):
            if 0 <= j < N and off:
                A[i, j] = off * scale(i)
    A.assemble()
    return A


def exact(k: int) -> float:
    return 4 * math.sin(k * math.pi / (2 * (N + 1))) ** 2


@pytest.mark.mpi
def test_the_lowest_eigenpairs_of_the_second_difference_matrix():
    """A x = lambda x and A x = lambda (2 I) x: the three lowest values and the lowest
    vector (against the sine, up to its normalisation x^T B x = 1)."""
    A = matrix(2.0, -1.0)
    plain = eigenpairs(A, count=3)
    assert plain.values == pytest.approx([exact(k) for k in (1, 2, 3)], rel=1e-9)
    assert max(plain.residuals) < 1e-9 and not plain.imaginary.any()
    B = matrix(2.0, 0.0)
    scaled = eigenpairs(A, B, count=3)
    assert scaled.values == pytest.approx([exact(k) / 2 for k in (1, 2, 3)], rel=1e-9)
    sine = np.sin(np.arange(1, N + 1) * math.pi / (N + 1))
    sine /= math.sqrt(2 * sine @ sine)                       # x^T (2 I) x = 1
    start, end = A.getOwnershipRange()
    local = scaled.vectors[0].getArray(readonly=True)
    assert np.max(np.abs(local - sine[start:end]), initial=0) < 1e-8


@pytest.mark.mpi
def test_an_indefinite_pencil_and_a_target():
    """B = diag(+-1) (sign alternating with the row: a symmetric indefinite B, as the
    load's derivative of a buckling analysis): A x = lambda B x has the real eigenvalues
    of B^-1 A, here of the matrix with rows of alternating sign; against numpy's dense
    eigenvalues of that small matrix.  And the values nearest a target of 1.5."""
    A = matrix(2.0, -1.0)
    sign = lambda i: 1.0 if i % 2 == 0 else -1.0                      # noqa: E731
    B = matrix(1.0, 0.0, sign)
    dense = np.diag(np.full(N, 2.0)) - np.eye(N, k=1) - np.eye(N, k=-1)
    reference = np.linalg.eigvals(np.diag([sign(i) for i in range(N)]) @ dense)
    reference = sorted(reference.real, key=lambda v: (round(abs(v), 9), v))   # -l, +l
    pairs = eigenpairs(A, B, count=4, kind="symmetric_indefinite")
    assert pairs.values == pytest.approx(reference[:4], rel=1e-9)
    general = eigenpairs(A, B, count=4, kind="general")
    assert general.values == pytest.approx(reference[:4], rel=1e-9)
    near = eigenpairs(A, count=2, target=1.5)
    values = sorted((exact(k) for k in range(1, N + 1)), key=lambda v: abs(v - 1.5))
    assert near.values == pytest.approx(values[:2], rel=1e-9)


def test_bad_arguments_are_refused():
    A = matrix(2.0, -1.0)
    with pytest.raises(ValueError, match="kind"):
        eigenpairs(A, kind="hermitian")
    with pytest.raises(ValueError, match="count"):
        eigenpairs(A, count=0)
