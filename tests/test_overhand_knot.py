"""An overhand knot pulled tight by its ends (demos/overhand_knot.py, docs/contact.md "An
overhand knot pulled tight"): self-contact holds a knot as it tightens.

The demo (the knot settled with its ends held, then the end pulled 0.3 m over 3 s)
asserts that no step lets two segments touch through the barrier, that the knot holds,
and that the tension follows the loose knot's scaling of Audoly, Clauvelin & Neukirch
(PRL 99, 164301, 2007), F h^2 / B = eps^4 / 2 with eps = sqrt(h / R): F ~ R^-2.  Here its
table is read back.  ~5 min serially at load 15-19 on 2 cores (two runs of 100 cells:
400 steps of 1 ms, then 150 outputs of the adaptive stepper)."""

from pathlib import Path

import numpy as np
import pytest

from test_demos import run_demo

ROOT = Path(__file__).resolve().parents[1]
H, B = 0.003, 1e7 * np.pi * 0.003**4 / 4      # the scenes' radius and EI


@pytest.mark.slow
def test_overhand_knot_tightens_with_the_published_scaling():
    out = run_demo("overhand_knot", 1, timeout=2400)
    assert "Audoly et al. 2007" in out
    knot = np.genfromtxt(ROOT / "results/overhand_knot/knot.csv", delimiter=",", names=True)
    assert np.all(knot["pairs"] > 0)                   # the knot holds: strands in contact
    # the knot tightened: the end shortening e = L - |x(L) - x(0)| fell by the 0.3 m
    # pulled along e3 (times the cosine of the ends' 2-degree tilt off e3: 1 - 7e-4)
    assert knot["e"][0] - knot["e"][-1] == pytest.approx(0.3, abs=1e-3)
    assert knot["R"][-1] < 0.6 * knot["R"][0]           # measured 11.5 h -> 5.5 h
    # F ~ R^-2 and, the loop's shape scaling with R, F ~ e^-2: the exponents of the fits
    # over the pull (F x 5).  Measured -2.14 and -2.13; the two ends' reactions differ
    # by up to 15 % (the drag on the moving knot, ~ +-6 % about their mean, which enters
    # the fit unevenly: the knot at rest at t = 0), over ln(R0 / R1) = 0.74 a spread of
    # ~0.1 in the exponent: within 0.3 of -2.
    slope_r = np.polyfit(np.log(knot["R"]), np.log(knot["F"]), 1)[0]
    slope_e = np.polyfit(np.log(knot["e"]), np.log(knot["F"]), 1)[0]
    assert abs(slope_r + 2.0) < 0.3 and abs(slope_e + 2.0) < 0.3
    # The prefactor F R^2 / B: the published 1/2 is the loose limit eps -> 0 (a
    # contact-free loop closed by a short braid); measured 0.28-0.34 at eps = 0.29-0.43 on
    # 100 cells (0.296 at 150 cells).  Not a test of the 1/2: this knot is not loose
    # (contact on 57-82 % of its nodes, the free rod's first integral B kappa^2/2 - F (1 -
    # t.e) swinging by +-1.1 F along the knot where a loose loop keeps it constant;
    # docs/contact.md), and where R is taken moves it (the loop's apex: 0.32-0.41); so
    # asserted as the published value's order only: between 1/4 and 1/2.
    ratio = knot["FR2_over_B"]
    assert np.all((ratio > 0.25) & (ratio < 0.5))
