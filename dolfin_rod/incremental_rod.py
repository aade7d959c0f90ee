"""The rod with 6 unknowns per node: displacement x and incremental rotation vector theta.

Prototype of issue 12's discretisation (not yet the RodModel default).  Per node:

    x      P1, 3 comps     centre line r = X + x
    theta  P1, 3 comps     material rotation increment on top of the stored nodal unit
                           quaternion q_n (P1, 4 comps, not an unknown): the rod's nodal
                           quaternions are q_a = q_n,a c(theta_a), with the normalised
                           Cayley map c(theta) = (2, theta)/sqrt(4 + |theta|^2);
                           after each accepted step q_n <- q_n c(theta), theta <- 0.

Strains at the 1-point rule exactly as RodModel's (u = 2 vec(conj(q) q_s)/|q|^2,
v = R(q)^T r_s with q the P1 interpolant of the nodal q_a, at the cell midpoint), so
the spatial discretisation is the same; but the nodal quaternions are unit by
construction: no gauge multiplier, no saddle point.  In 1-D a P1 field's nodal values
are UFL expressions at any point of the cell, f_a = f(s) + (s_a - s) f_s(s), so q_a,
q_b, and with them the midpoint strains, are available at every quadrature point: the
internal work is one kernel on the 1-point rule; inertia and loads (consistent) are on
the 2-point Gauss rule.  The strains depend only on the current nodal unit
quaternions, so objectivity (q -> q_Q q) and path independence are exact.

Dynamics is second order in time (velocities are not unknowns): see
:class:`LieGeneralizedAlpha`.  Natural strains (local variant) are DG0 unknowns.
"""

from __future__ import annotations

import dolfinx
import dolfinx.fem as fem
import numpy as np
import ufl
from mpi4py import MPI

from . import balance
from .energy import derivatives, quadratic_energy
from .problem import SecondOrderProblem, TimeDependentValue
from .rotations import conj, np_qmul, qmul, rotation_matrix, vec


def cayley(theta):
    """Unit quaternion of the rotation vector theta by the normalised Cayley map (UFL):
    rotation angle 2 atan(|theta|/2) = |theta| + O(|theta|^3) about theta/|theta|."""
    return (ufl.as_vector((2.0, theta[0], theta[1], theta[2]))
            / ufl.sqrt(4.0 + ufl.dot(theta, theta)))


def _RT(q):
    return ufl.transpose(rotation_matrix(q))


def rotate_back(m, y):
    """R(m/|m|)^T y for any quaternion m != 0 (UFL): y + 2 (mv x (mv x y) - m_0 mv x y)/|m|^2."""
    mv = vec(m)
    c = ufl.cross(mv, y)
    return y + 2.0 / ufl.dot(m, m) * (ufl.cross(mv, c) - m[0] * c)


def strains(k_a, k_b, r_s, q_n_a, p_n, h):
    """(u, v) of one cell: RodModel's strains of the P1 quaternion interpolant at the
    midpoint, q_mid = (q_a + q_b)/2, for the nodal rotations q_a = q_n,a k_a/|k_a|,
    q_b = q_n,b k_b/|k_b| (UFL; k_a, k_b quaternions of any norm, e.g. k = (2, theta)
    for the Cayley map; q_n,a and p_n = conj(q_n,a) q_n,b unit, per cell; h the cell
    length).  Both strains are homogeneous of degree 0 in (m, d), with
    m = k_a + (|k_a|/|k_b|) p_n k_b = 2 |k_a| conj(q_n,a) q_mid and
    d = (|k_a|/|k_b|) p_n k_b - k_a = h |k_a| conj(q_n,a) q_s:

        u = 2 vec(conj(q_mid) q_s)/|q_mid|^2 = 4 vec(conj(m) d)/(h |m|^2),
        v = R(q_mid)^T r_s = R(m)^T R(q_n,a)^T r_s.

    One square root, one quaternion product, one rotation of the unknowns: the Jacobian
    kernel (the second derivative of this graph) has 14.1k flops against 27.2k for
    p = conj(c_a) p_n c_b, u = 4 vec(p)/(h (1 + p_0)), v = R(1 + p)^T R(c_a)^T R(q_n,a)^T r_s
    (same strains to round-off).
    """
    pk_b = ufl.sqrt(ufl.dot(k_a, k_a) / ufl.dot(k_b, k_b)) * qmul(p_n, k_b)
    m, d = k_a + pk_b, pk_b - k_a
    mv, dv = vec(m), vec(d)
    u = 4 * (m[0] * dv - d[0] * mv - ufl.cross(mv, dv)) / (h * ufl.dot(m, m))
    return u, rotate_back(m, ufl.dot(_RT(q_n_a), r_s))


def np_cayley(theta):
    theta = np.asarray(theta, dtype=float)
    q = np.concatenate([np.full(theta.shape[:-1] + (1,), 2.0), theta], axis=-1)
    return q / np.sqrt(4.0 + np.sum(theta * theta, axis=-1))[..., None]


class IncrementalRod:
    """Clamped-free (or free-free) dynamic rod, hyperelastic or with the local evolution
    law of the natural strains; dead or follower distributed loads and right-end loads."""

    def __init__(self, params, n_cells: int = 32, model: str = "hyperelastic",
                 ends=("clamped", "free"), distributed_loads=(), end_loads=(),
                 comm=MPI.COMM_WORLD):
        self.params, self.model = params, model
        self.evolving = model == "evolving"
        self.length = L = float(params.length)
        self.mesh = mesh = dolfinx.mesh.create_interval(comm, n_cells, [0.0, L])
        self.dx_r = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 1})
        self.dx_m = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 2})
        spaces = {"displacement": fem.functionspace(mesh, ("Lagrange", 1, (3,))),
                  "rotation_increment": fem.functionspace(mesh, ("Lagrange", 1, (3,)))}
        if self.evolving:
            spaces["natural_curvature"] = fem.functionspace(mesh, ("DG", 0, (3,)))
            spaces["natural_stretch"] = fem.functionspace(mesh, ("DG", 0, (3,)))
        self.names = list(spaces)
        self.f = {n: fem.Function(S, name=n) for n, S in spaces.items()}
        self.r = {n: fem.Function(S, name=f"{n}_rate") for n, S in spaces.items()}
        self.a = {n: fem.Function(S, name=f"{n}_acceleration") for n, S in spaces.items()
                  if n in ("displacement", "rotation_increment")}
        self.t = {n: ufl.TestFunction(S) for n, S in spaces.items()}
        self._stored_rotations(mesh)
        self.u, self.v = self._strains()
        F = self._balance(self._coefficients(params))
        self.loads = []
        self._add_loads(F, distributed_loads, end_loads)
        self.bcs = self._clamps(ends, spaces)
        self.residual = F
        self.problem = SecondOrderProblem(
            [self.f[n] for n in self.names], [self.r[n] for n in self.names],
            [F[n] for n in self.names], self.loads, self.bcs,
            accelerations=[self.a.get(n) for n in self.names], after_step=self.update_rotation,
            time_orders=[2 if n in self.a else 1 for n in self.names])

    def _stored_rotations(self, mesh) -> None:
        """q_n (P1), per cell its left node's q_n,a and p_n (DG0), the cell midpoints."""
        self.s_mid = fem.Function(fem.functionspace(mesh, ("DG", 0)), name="cell_midpoint")
        self.s_mid.interpolate(lambda X: X[0])
        Q = fem.functionspace(mesh, ("Lagrange", 1, (4,)))
        ncell = mesh.topology.index_map(1).size_local + mesh.topology.index_map(1).num_ghosts
        nodes = Q.dofmap.list[:ncell]
        sx = Q.tabulate_dof_coordinates()[:, 0]
        swap = sx[nodes[:, 0]] > sx[nodes[:, 1]]
        self.q_n = fem.Function(Q, name="q_n")
        self._cell_nodes = (np.where(swap, nodes[:, 1], nodes[:, 0]),
                            np.where(swap, nodes[:, 0], nodes[:, 1]))
        S4 = fem.functionspace(mesh, ("DG", 0, (4,)))
        self.qa_n, self.p_n = fem.Function(S4, name="q_n_left"), fem.Function(S4, name="p_n")

    def _strains(self):
        """(u, v) of the cell (eq. strains of RodModel's P1 interpolant at the midpoint)."""
        s, h = ufl.SpatialCoordinate(self.mesh)[0], ufl.CellVolume(self.mesh)
        x, th = self.f["displacement"], self.f["rotation_increment"]
        th_a, th_b = (th + (s_node - s) * th.dx(0)
                      for s_node in (self.s_mid - h / 2, self.s_mid + h / 2))
        # c(theta) = k/|k| with k = (2, theta)
        k_a, k_b = (ufl.as_vector((2.0, t[0], t[1], t[2])) for t in (th_a, th_b))
        r_s = ufl.as_vector((0.0, 0.0, 1.0)) + x.dx(0)
        return strains(k_a, k_b, r_s, self.qa_n, self.p_n, h)

    def _coefficients(self, params) -> dict:
        c = {}
        for n in ("A", "B", "A_d", "B_d", "M_d", "N_d"):
            val = np.asarray(getattr(params, n), float)
            c[n] = fem.Constant(self.mesh, np.diag(val) if val.shape == (3,) else val)
        for n in ("rho_A", "I11", "I22"):
            c[n] = fem.Constant(self.mesh, float(getattr(params, n)))
        return c

    def _balance(self, c) -> dict:
        """Internal work (1-point rule), inertia (2-point Gauss), evolution laws."""
        zero3 = ufl.as_matrix(np.zeros((3, 3)).tolist())
        if self.evolving:
            u_d, v_d = self.f["natural_curvature"], self.f["natural_stretch"]
            psi_fn = quadratic_energy(c["A"], c["A_d"], c["B"], c["B_d"])
        else:
            u_d, v_d = ufl.as_vector((0.0, 0.0, 0.0)), ufl.as_vector((0.0, 0.0, 1.0))
            psi_fn = quadratic_energy(c["A"], zero3, c["B"], zero3)
        u, v, dx_r = self.u, self.v, self.dx_r
        self.psi, m, n, dpsi_dud, dpsi_dvd = derivatives(psi_fn, u_d, v_d, u, v)
        x, th = self.f["displacement"], self.f["rotation_increment"]
        xt, tht = self.t["displacement"], self.t["rotation_increment"]
        # material virtual rotation of q = q_n c(theta); q at the points of the Gauss rule
        self.dTheta = 2 * vec(qmul(conj(cayley(th)), ufl.derivative(cayley(th), th, tht)))
        self.q_here = qmul(self.q_n, cayley(th))
        J = ufl.diag(ufl.as_vector((c["I22"], c["I11"], c["I11"] + c["I22"])))
        W, W_t = self.r["rotation_increment"], self.a["rotation_increment"]
        F = {"displacement": balance.internal_work(m, n, u, v, [x], [xt], dx_r)
             + c["rho_A"] * ufl.inner(self.a["displacement"], xt) * self.dx_m,
             "rotation_increment": balance.internal_work(m, n, u, v, [th], [tht], dx_r)
             + ufl.inner(ufl.dot(J, W_t) + ufl.cross(W, ufl.dot(J, W)), self.dTheta) * self.dx_m}
        if self.evolving:
            F["natural_curvature"] = ufl.inner(ufl.dot(c["M_d"], self.r["natural_curvature"])
                                               + dpsi_dud, self.t["natural_curvature"]) * dx_r
            F["natural_stretch"] = ufl.inner(ufl.dot(c["N_d"], self.r["natural_stretch"])
                                             + dpsi_dvd, self.t["natural_stretch"]) * dx_r
        return F

    def _add_loads(self, F, distributed_loads, end_loads) -> None:
        s = ufl.SpatialCoordinate(self.mesh)[0]
        ds = ufl.Measure("ds", domain=self.mesh)
        # end loads: at the right end only (ds over both ends, weighted by s/L)
        for load, measure, weight in [*((ld, self.dx_m, 1.0) for ld in distributed_loads),
                                      *((ld, ds, s / self.length) for ld in end_loads)]:
            amp = fem.Constant(self.mesh, 0.0)
            self.loads.append(TimeDependentValue(amp, load.history))
            val = amp * fem.Constant(self.mesh, np.asarray(load.value, float)) * weight
            if load.kind == "force":
                F["displacement"] -= balance.force_work(
                    val, self.q_here, self.t["displacement"], load.follower) * measure
            else:
                F["rotation_increment"] -= balance.couple_work(
                    val, self.q_here, self.dTheta, load.follower) * measure

    def _clamps(self, ends, spaces) -> list:
        bcs = []
        for end, kind in zip((0.0, self.length), ends):
            if kind == "clamped":
                for name in ("displacement", "rotation_increment"):
                    S = spaces[name]
                    dofs = fem.locate_dofs_geometrical(S, lambda X, e=end: np.isclose(X[0], e))
                    bcs.append(fem.dirichletbc(np.zeros(3), dofs, S))
        return bcs

    def set_initial_state(self) -> None:
        """Straight, unstressed, at rest (natural strains = (0, e_3))."""
        for g in [*self.f.values(), *self.r.values(), *self.a.values()]:
            g.x.array[:] = 0.0
        self.set_nodal_rotations((1.0, 0.0, 0.0, 0.0))
        if self.evolving:
            self.f["natural_stretch"].x.array.reshape(-1, 3)[:, 2] = 1.0

    def update_rotation(self) -> None:
        """q_n <- q_n c(theta) nodally, theta <- 0 (after an accepted step)."""
        th = self.f["rotation_increment"].x.array.reshape(-1, 3)
        q = np_qmul(self.q_n.x.array.reshape(-1, 4), np_cayley(th))
        th[:] = 0.0
        self.set_nodal_rotations(q / np.sqrt(np.einsum("ij,ij->i", q, q))[:, None])

    def set_nodal_rotations(self, q) -> None:
        """Stored nodal unit quaternions q_n := q (rows, local + ghost nodes), and from them
        per cell the left node's q_n,a and p_n = conj(q_n,a) q_n,b (DG0)."""
        qn = self.q_n.x.array.reshape(-1, 4)
        qn[:] = q
        left, right = self._cell_nodes
        self.qa_n.x.array.reshape(-1, 4)[:] = qn[left]
        self.p_n.x.array.reshape(-1, 4)[:] = np_qmul(qn[left] * [1, -1, -1, -1], qn[right])

    def strains(self) -> np.ndarray:
        """(u, v) at the cell midpoints, (n_cells, 6)."""
        e = fem.Expression(ufl.as_vector([*self.u, *self.v]), np.array([[0.5]]))
        n = self.mesh.topology.index_map(1).size_local
        return e.eval(self.mesh, np.arange(n, dtype=np.int32)).reshape(n, 6)
