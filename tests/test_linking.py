"""Writhe, twist and linking (rod/linking.py) against Calugareanu-White's theorem
Lk = Tw + Wr on closed ribbons, Gauss's double integral by brute-force quadrature, and
the writhe 0 of planar curves."""

from __future__ import annotations

import numpy as np
import pytest

from dolfin_rod.rod.linking import linking_number, twist, writhe


def _ribbon(n_nodes: int, turns: int, wave: float):
    """A closed wavy ring r(th) = (cos th, sin th, wave sin 3 th) with a normal field
    turning 'turns' times (right-handed) about the tangent relative to the frame
    (e_r, e_z): u = cos(turns th) e_r - sin(turns th) e_z (e_theta x e_z = e_r), made
    normal to the tangent."""
    th = np.linspace(0.0, 2 * np.pi, n_nodes, endpoint=False)
    r = np.stack([np.cos(th), np.sin(th), wave * np.sin(3 * th)], axis=1)
    t = np.stack([-np.sin(th), np.cos(th), 3 * wave * np.cos(3 * th)], axis=1)
    t /= np.linalg.norm(t, axis=1)[:, None]
    e_r = np.stack([np.cos(th), np.sin(th), 0 * th], axis=1)
    e_z = np.tile([0.0, 0.0, 1.0], (n_nodes, 1))
    u = np.cos(turns * th)[:, None] * e_r - np.sin(turns * th)[:, None] * e_z
    u -= np.einsum("ij,ij->i", u, t)[:, None] * t
    return r, u / np.linalg.norm(u, axis=1)[:, None]


@pytest.mark.parametrize("turns, wave", [(0, 0.0), (3, 0.0), (2, 0.4), (-1, 0.8)])
def test_link_is_twist_plus_writhe(turns, wave):
    """Lk of the centre line with its ribbon edge r + 1e-3 u (Gauss's linking integral,
    an integer) = Tw + Wr to round-off (1e-7), and Lk = turns (the frame's turns; the
    ring turns its frame (e_r, e_z) by none)."""
    for n in (400, 800):
        r, u = _ribbon(n, turns, wave)
        lk = linking_number(r, r + 1e-3 * u)
        assert lk == pytest.approx(round(lk), abs=1e-6)
        assert round(lk) == turns
        assert twist(r, u, closed=True) + writhe(r, closed=True) == pytest.approx(
            lk, abs=1e-7)


def _trefoil(n_nodes: int, turns: int):
    """The (2, 3) torus knot r = ((2 + cos 3th) cos 2th, (2 + cos 3th) sin 2th, sin 3th)
    with the normal from its torus's core circle, turned 'turns' more times about the
    tangent."""
    th = np.linspace(0.0, 2 * np.pi, n_nodes, endpoint=False)
    c2, s2, c3, s3 = np.cos(2 * th), np.sin(2 * th), np.cos(3 * th), np.sin(3 * th)
    r = np.stack([(2 + c3) * c2, (2 + c3) * s2, s3], axis=1)
    t = np.stack([-3 * s3 * c2 - 2 * (2 + c3) * s2, -3 * s3 * s2 + 2 * (2 + c3) * c2,
                  3 * c3], axis=1)
    t /= np.linalg.norm(t, axis=1)[:, None]
    u0 = np.stack([c3 * c2, c3 * s2, s3], axis=1)
    u0 -= np.einsum("ij,ij->i", u0, t)[:, None] * t
    u0 /= np.linalg.norm(u0, axis=1)[:, None]
    u = np.cos(turns * th)[:, None] * u0 + np.sin(turns * th)[:, None] * np.cross(t, u0)
    return r, u


@pytest.mark.parametrize("turns", [0, 2])
def test_link_is_twist_plus_writhe_on_a_knot(turns):
    """The trefoil (writhe -3.518, not an integer): Tw + Wr = Lk (an integer, 'turns'
    more for 'turns' more frame turns) to round-off (1e-8: White's formula holds for the
    polygon and its discrete twist), and the polygon's writhe converges at second order
    in h to the curve's (differences 200 -> 400 -> 800 nodes fall 4-fold)."""
    wr, links = [], []
    for n in (200, 400, 800):
        r, u = _trefoil(n, turns)
        lk = linking_number(r, r + 1e-4 * u)
        assert lk == pytest.approx(round(lk), abs=1e-6)
        links.append(round(lk))
        wr.append(writhe(r, closed=True))
        assert twist(r, u, closed=True) + wr[-1] == pytest.approx(lk, abs=1e-8)
    assert links == [links[0]] * 3 and links[0] == -6 + turns
    assert (wr[1] - wr[0]) / (wr[2] - wr[1]) == pytest.approx(4.0, rel=0.05)


def test_planar_curves_have_no_writhe():
    th = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    ellipse = np.stack([2 * np.cos(th), np.sin(th), 0 * th], axis=1)
    assert abs(writhe(ellipse, closed=True)) < 1e-12
    spiral = np.stack([th * np.cos(th), th * np.sin(th), 0 * th], axis=1)
    assert abs(writhe(spiral)) < 1e-12


def test_writhe_is_gauss_double_integral():
    """The polygon's exact writhe against the double integral by the midpoint rule on each
    pair of segments split 20 times (non-adjacent pairs; the integrand is smooth there)."""
    th = np.linspace(0, 4 * np.pi, 25)
    helix = np.stack([np.cos(th), np.sin(th), 0.3 * th], axis=1)
    m = 20
    u = (np.arange(m) + 0.5) / m
    a, b = helix[:-1], helix[1:]
    pts = a[:, None, :] + u[None, :, None] * (b - a)[:, None, :]     # (segments, m, 3)
    total = 0.0
    for i in range(len(a)):
        for j in range(i + 2, len(a)):
            d = pts[i][:, None, :] - pts[j][None, :, :]
            cross = np.cross(b[i] - a[i], b[j] - a[j])
            total += np.sum(d @ cross / np.linalg.norm(d, axis=-1) ** 3) / m**2
    assert writhe(helix) == pytest.approx(2 * total / (4 * np.pi), rel=2e-3)


def test_clamped_rod_closure():
    """An open rod with its ends on the axis e_3 (rod/linking.clamped_rod_linking): a
    straight ribbon turned 1.3 times has Tw = 1.3, Wr = 0 (1e-12: the closure's far
    loop is planar with the axis); a looped rod with an untwisted ribbon (normals made
    from a fixed vector, so Lk = 0) has Tw + Wr = 0 to 1e-9 with Wr != 0, and its mirror
    image has the opposite writhe."""
    from dolfin_rod.rod.linking import clamped_rod_linking
    s = np.linspace(0.0, 1.0, 61)
    phi = 2 * np.pi * 1.3 * s
    straight = np.stack([0 * s, 0 * s, s], axis=1)
    tw, wr = clamped_rod_linking(straight, np.stack([np.cos(phi), np.sin(phi), 0 * s], 1),
                                 (0, 0, 1), (0, 0, 1))
    assert tw == pytest.approx(1.3, abs=1e-12) and abs(wr) < 1e-12
    a = 0.2 * np.sin(np.pi * s) ** 2
    looped = np.stack([a * np.cos(4 * np.pi * s), a * np.sin(4 * np.pi * s), s], axis=1)
    normals = np.cross(np.gradient(looped, axis=0), (1.0, 0.0, 0.0))
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    tw, wr = clamped_rod_linking(looped, normals, (0, 0, 1), (0, 0, 1))
    assert abs(wr) > 0.5 and abs(tw + wr) < 1e-9
    mirror = looped * (1.0, -1.0, 1.0)
    m_normals = np.cross(np.gradient(mirror, axis=0), (1.0, 0.0, 0.0))
    m_normals /= np.linalg.norm(m_normals, axis=1)[:, None]
    assert clamped_rod_linking(mirror, m_normals, (0, 0, 1), (0, 0, 1))[1] == \
        pytest.approx(-wr, abs=1e-9)
