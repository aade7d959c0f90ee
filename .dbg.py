import sys; sys.path.insert(0, "tests")
from test_scenes import _case, _run
sc = _case("relaxation_ramp_cn", time__ode_solution="scheme")
from dolfin_rod.scenes import build
for model in ("ode", "torsion"):
    sim = build(sc, model); sim.start()
    for k in range(1, 4):
        sim.advance((k-1)*0.01, k*0.01)
        d = sim.diagnostics(k*0.01)
        print(model, k, d["end_rotation"], d["end_rotation_rate"], d["mean_natural_twist"], d["dissipation_rate"], getattr(sim, "history_ok", None) if model=="ode" else sim.stepper.history_ok)
