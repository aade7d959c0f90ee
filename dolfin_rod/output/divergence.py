"""Run health: divergence detection after every step (:class:`EnergyBound`), for every
model and scheme, so a run stops with a reason instead of reporting success over NaNs or
an exploding energy."""

from __future__ import annotations

import math

from ..integrators.step_control import IntegrationError


class EnergyBound:
    """Divergence detection after every step, for every model and scheme: a state that
    is not finite, or a stored energy K + Psi above ``FACTOR`` times what the start and
    the loads can supply, E(t_0) + int_{t_0}^t max(P, 0) dt (the power balance
    d/dt(K + Psi) = P - D with total dissipation D >= 0, docs/corrections.md).  FACTOR = 1e3 is
    the instability criterion of docs/stability.md: far above the transient growth of a
    stable explicit step (x2.4 there) and above the O(dt) error of the trapezoidal work."""

    FACTOR = 1e3

    def __init__(self, start: dict):
        self.previous = start
        self._finite(start, start["time"])
        self.supply = _energy(start)
        self.first_step = True

    def _finite(self, d: dict, t_good: float) -> None:
        bad = [k for k, v in d.items() if not math.isfinite(v)]
        if bad:
            raise IntegrationError(f"the solution diverged: {bad[0]} = {d[bad[0]]} at "
                                   f"t = {d['time']:g} (stopped; results up to t = "
                                   f"{t_good:g} are kept)", t_good)

    def check(self, d: dict, jump: bool = False) -> None:
        """Raises IntegrationError at the last good time if ``d`` diverged.  ``jump``:
        the step ended with a jump to another equilibrium at the same loads (a branch
        switch, analysis/branches.py), whose energy the loads supplied along the jump,
        unseen by the power: its state counts as supplied, as the first one does."""
        t_good = self.previous["time"]
        self._finite(d, t_good)
        h = d["time"] - self.previous["time"]
        self.supply += h * max(0.0, 0.5 * (d["load_power"] + self.previous["load_power"]))
        if self.first_step or jump:
            # a step load or a step of a prescribed end motion at t_0 supplies its energy
            # as an impulse the trapezoidal work cannot see: the first state counts as
            # supplied (an explicit instability grows by a bounded factor per step, x2.4
            # in docs/stability.md, so it is caught one step later)
            self.supply = max(self.supply, _energy(d))
            self.first_step = False
        if _energy(d) > self.FACTOR * self.supply + 1e-300:
            raise IntegrationError(
                f"the solution diverged: the stored energy {_energy(d):.3g} at t = "
                f"{d['time']:g} is more than {self.FACTOR:g} times what the initial state "
                f"and the loads supplied ({self.supply:.3g}); time.dt is probably above the "
                f"scheme's stability limit (stopped; results up to t = {t_good:g} are kept)",
                t_good)
        self.previous = d


def _energy(d: dict) -> float:
    return d["free_energy"] + d["kinetic_energy"]
