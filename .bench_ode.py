import time
from dolfin_rod.scenes import parse_scene, build
for n in (10**4, 10**5):
    sc = parse_scene(f"""[material]\nalpha=2.0\nmu_d=0.5\n[loads]\nend_torsion={{type="ramp", value=1.0, duration=0.5}}\n[time]\nt_end={n*1e-3}\ndt=1e-3\n""")
    sim = build(sc, "ode"); sim.start()
    t0 = time.perf_counter()
    for k in range(1, n+1):
        sim.advance((k-1)*1e-3, k*1e-3); sim.diagnostics(min(k*1e-3, n*1e-3))
    print(n, time.perf_counter()-t0)
