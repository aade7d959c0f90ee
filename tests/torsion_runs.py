"""Small drivers shared by the torsion tests (a run returns the diagnostics history)."""


from __future__ import annotations

from mpi4py import MPI

from dolfin_rod import TimeStepper
from dolfin_rod.torsion.model import TorsionModel, TorsionParameters


def run(params: TorsionParameters, t_end: float, dt: float, scheme: str = "bdf2",
        comm=MPI.COMM_WORLD, every_step=True, **model_kwargs) -> list[dict]:
    model = TorsionModel(params, comm=comm, **model_kwargs)
    model.set_initial_state()
    history: list[dict] = []
    stepper = TimeStepper(model.problem, scheme)
    stepper.run(0.0, t_end, dt, observer=lambda t, s: history.append(model.diagnostics(t)))
    return history


def series(history: list[dict], key: str):
    import numpy as np
    return np.array([h[key] for h in history])
