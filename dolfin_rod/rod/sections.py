"""Cross-sections and materials as a rod user gives them (issue 25 item 1): a section
shape with its dimensions and an isotropic elastic material -> the tensors of the
quadratic energy (eq. quadenergy) and the inertia of Section 2.2.

Section constants (x_1, x_2 along the directors d_1, d_2; SI: m, m^2, m^4):

    area a = int dA,  I_11 = int x_1^2 dA,  I_22 = int x_2^2 dA  (Antman's second
    moments), J the Saint-Venant torsion constant (= I_11 + I_22 for circles and tubes).

Rod data (``section_parameters``): bending u_1 (about d_1) stretches the fibres at x_2,
so A = (E I_22, E I_11, G J) [N m^2]; B = (k_1 G a, k_2 G a, E a) [N] with shear
factors k_1, k_2 (Cowper 1966, J. Appl. Mech. 33, 335, by shape and Poisson's ratio,
unless given); rho A = rho a [kg/m] and the section mass moments (rho I_11, rho I_22)
[kg m] (RodParameters.section_inertia: the rotary inertia rho J = diag(rho I_22,
rho I_11, rho (I_11 + I_22))).  G = E / (2 (1 + nu)) or nu = E / (2 G) - 1.

Natural configuration (evolving model): A_d = r A, B_d = r B (natural_stiffness_ratio
r), and relaxation times tau_u, tau_v [s]: M_d = tau_u (A + A_d), N_d = tau_v (B + B_d),
the time constants of the natural strains at a held strain (eq. dotmfupeq: M_d u_d' =
A (u - u_d) - A_d u_d, i.e. u_d relaxes at the rate (A + A_d)/M_d = 1/tau_u).  The
uniform variant's law integrates over the rod (eq. unatevolunif: M_d u_d' = int_0^L ...),
so the same tau_u needs M_d = tau_u L (A + A_d) (``uniform_length`` L; docs/rod.md).

Fluid drag (``slender_body_drag``): a slender filament of length L and radius r in a
Stokes fluid of viscosity mu feels, to leading order in 1 / ln(L/r), the force per length
f = -(4 pi mu / ln(L/r)) (I - t t^T / 2) v (Cox 1970, J. Fluid Mech. 44, 791; the form of
PyElastica's SlenderBodyTheory, Gazzola et al. 2018, R. Soc. open sci. 5, 171628, eq.
4.13): in the directors' frame (t = d_3) the drag tensor (c_n, c_n, c_t) with c_n = 4 pi
mu / ln(L/r) across the axis and c_t = c_n / 2 along it [N s/m^2]
(RodParameters.drag).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SHAPES = ("circle", "ellipse", "rectangle", "tube")
_SERIES_TERMS = 50       # rectangle torsion series: the n-th term is < (2n-1)^-5 of the first


@dataclass(frozen=True)
class Section:
    """Constants of a cross-section: area, second moments I11 = int x_1^2 dA, I22 =
    int x_2^2 dA, torsion constant J, and its shape (for the default shear factors)."""

    shape: str
    area: float
    I11: float
    I22: float
    J: float
    hole_ratio: float = 0.0      # tube: inner/outer radius

    def shear_factors(self, poisson_ratio: float) -> tuple[float, float]:
        """Cowper's shear factors (k_1, k_2) along d_1, d_2.  Circle 6(1+nu)/(7+6nu),
        rectangle 10(1+nu)/(12+11nu), tube 6(1+nu)(1+m^2)^2/((7+6nu)(1+m^2)^2 +
        (20+12nu) m^2) (m = inner/outer radius); an ellipse takes the circle's value
        (exact for equal semi-axes; give shear_factor for an elongated one)."""
        nu = poisson_ratio
        if self.shape == "rectangle":
            k = 10 * (1 + nu) / (12 + 11 * nu)
        elif self.shape == "tube":
            m2 = self.hole_ratio**2
            k = 6 * (1 + nu) * (1 + m2)**2 / ((7 + 6 * nu) * (1 + m2)**2 + (20 + 12 * nu) * m2)
        else:
            k = 6 * (1 + nu) / (7 + 6 * nu)
        return k, k


def _positive(name: str, value: float) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be > 0, got {value}")
    return value


def circle(radius: float) -> Section:
    """A solid circle: a = pi r^2, I_11 = I_22 = pi r^4/4, J = pi r^4/2."""
    r = _positive("radius", radius)
    return Section("circle", np.pi * r**2, np.pi * r**4 / 4, np.pi * r**4 / 4, np.pi * r**4 / 2)


def ellipse(a1: float, a2: float) -> Section:
    """Semi-axes a1 along d_1, a2 along d_2: a = pi a1 a2, I_11 = pi a1^3 a2/4,
    I_22 = pi a1 a2^3/4, J = pi a1^3 a2^3/(a1^2 + a2^2) (Saint-Venant)."""
    a1, a2 = _positive("semi_axes[0]", a1), _positive("semi_axes[1]", a2)
    return Section("ellipse", np.pi * a1 * a2, np.pi * a1**3 * a2 / 4, np.pi * a1 * a2**3 / 4,
                   np.pi * a1**3 * a2**3 / (a1**2 + a2**2))


def rectangle(b1: float, b2: float) -> Section:
    """Sides b1 along d_1, b2 along d_2: a = b1 b2, I_11 = b1^3 b2/12, I_22 = b1 b2^3/12,
    J = (b t^3/3) (1 - (192 t/(pi^5 b)) sum_{n odd} tanh(n pi b/(2 t))/n^5), b the longer
    and t the shorter side (Saint-Venant's series; Timoshenko & Goodier, Sec. 109)."""
    b1, b2 = _positive("sides[0]", b1), _positive("sides[1]", b2)
    b, t = max(b1, b2), min(b1, b2)
    n = 2.0 * np.arange(_SERIES_TERMS) + 1.0
    series = np.sum(np.tanh(n * np.pi * b / (2 * t)) / n**5)
    J = b * t**3 / 3 * (1 - 192 * t / (np.pi**5 * b) * series)
    return Section("rectangle", b1 * b2, b1**3 * b2 / 12, b1 * b2**3 / 12, J)


def tube(outer_radius: float, inner_radius: float) -> Section:
    """A circular tube: a = pi (ro^2 - ri^2), I_11 = I_22 = pi (ro^4 - ri^4)/4,
    J = pi (ro^4 - ri^4)/2."""
    ro = _positive("outer_radius", outer_radius)
    ri = float(inner_radius)
    if not (np.isfinite(ri) and 0 <= ri < ro):
        raise ValueError(f"inner_radius must be in [0, outer_radius = {ro:g}), got {ri}")
    moment = np.pi * (ro**4 - ri**4) / 4
    return Section("tube", np.pi * (ro**2 - ri**2), moment, moment, 2 * moment, ri / ro)


@dataclass(frozen=True)
class Material:
    """An isotropic elastic material: Young's modulus E [Pa], and the shear modulus G
    [Pa] or Poisson's ratio nu (exactly one), mass density rho [kg/m^3]."""

    youngs_modulus: float
    shear_modulus: float | None = None
    poisson_ratio: float | None = None
    density: float = 0.0

    def moduli(self) -> tuple[float, float, float]:
        """(E, G, nu), checked."""
        E = _positive("youngs_modulus", self.youngs_modulus)
        if (self.shear_modulus is None) == (self.poisson_ratio is None):
            raise ValueError("give exactly one of shear_modulus and poisson_ratio")
        if self.shear_modulus is not None:
            G = _positive("shear_modulus", self.shear_modulus)
            nu = E / (2 * G) - 1
        else:
            nu = float(self.poisson_ratio)
            G = E / (2 * (1 + nu))
        if not (-1 < nu <= 0.5):
            raise ValueError(f"Poisson's ratio must be in (-1, 0.5], got {nu:g} (E = {E:g}, "
                             f"G = {G:g})")
        return E, G, nu


def section_parameters(section: Section, material: Material,
                       shear_factor: tuple[float, float] | None = None,
                       natural_stiffness_ratio: float | None = None,
                       relaxation_time: tuple[float, float] | None = None,
                       uniform_length: float | None = None) -> dict:
    """RodParameters keywords of a section and material: A, B, density (rho a, per
    length), section_inertia (rho I_11, rho I_22) and, with
    natural_stiffness_ratio r, A_d = r A, B_d = r B; with relaxation_time (tau_u, tau_v)
    also M_d, N_d (module docstring; for the uniform variant give the rod's length as
    uniform_length).  Tensors as diagonals (3-tuples)."""
    E, G, nu = material.moduli()
    rho = float(material.density)
    if not (np.isfinite(rho) and rho >= 0):
        raise ValueError(f"density must be >= 0, got {rho}")
    k1, k2 = section.shear_factors(nu) if shear_factor is None else shear_factor
    a = section.area
    out = {"A": (E * section.I22, E * section.I11, G * section.J),
           "B": (k1 * G * a, k2 * G * a, E * a),
           "density": rho * a, "section_inertia": (rho * section.I11, rho * section.I22)}
    if natural_stiffness_ratio is not None:
        r = _positive("natural_stiffness_ratio", natural_stiffness_ratio)
        out["A_d"], out["B_d"] = (tuple(r * x for x in out[k]) for k in ("A", "B"))
    if relaxation_time is not None:
        if "A_d" not in out:
            raise ValueError("relaxation_time needs natural_stiffness_ratio (M_d = tau (A + "
                             "A_d))")
        out.update(relaxation_viscosities(out, relaxation_time, uniform_length))
    return out


def relaxation_viscosities(tensors: dict, relaxation_time: tuple[float, float],
                           uniform_length: float | None = None) -> dict:
    """M_d = tau_u (A + A_d), N_d = tau_v (B + B_d) for diagonal 3-tuples or 3x3 arrays
    A, A_d, B, B_d (the relaxation times of the natural strains at a held strain); times
    the rod's length L = uniform_length for the uniform variant (eq. unatevolunif
    integrates its law over s)."""
    tau_u, tau_v = (_positive("relaxation_time", t) for t in relaxation_time)
    length = 1.0 if uniform_length is None else _positive("uniform_length", uniform_length)

    def total(k):
        return np.asarray(tensors[k], float) + np.asarray(tensors[k + "_d"], float)
    return {"M_d": tau_u * length * total("A"), "N_d": tau_v * length * total("B")}


def slender_body_drag(viscosity: float, length: float, radius: float) -> tuple:
    """The drag tensor (c_n, c_n, c_t) in the directors' frame of a filament of ``length``
    L and ``radius`` r in a fluid of dynamic ``viscosity`` mu (module docstring): c_n =
    4 pi mu / ln(L/r), c_t = c_n / 2."""
    if not (np.isfinite(viscosity) and viscosity >= 0):
        raise ValueError(f"the fluid's viscosity must be >= 0, got {viscosity!r}")
    if not (radius > 0 and np.isfinite(length) and length > np.e * radius):
        raise ValueError(f"slender-body drag needs a slender rod, length > e radius "
                         f"(ln(L/r) > 1), got length {length!r}, radius {radius!r}")
    c_n = 4 * np.pi * viscosity / np.log(length / radius)
    return (c_n, c_n, c_n / 2)
