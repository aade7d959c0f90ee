"""dolfin_rod as a solver of other programs: cosseratbench.py registers it with
cosseratbench, the open benchmark of Cosserat rod simulators (entry point
``cosseratbench.solvers``, extra ``[bench]``)."""
