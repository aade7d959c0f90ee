# %% [markdown]
# # Your first rod, from Python
#
# `first_rod.ipynb` and its script twin `first_rod.py` hold the same cells
# (tests/test_notebook.py runs the notebook's cells and compares the two).  From the
# repository root: `./rodenv python3 examples/notebooks/first_rod.py`, or open the
# notebook in Jupyter (where you have it; it finds scenes/ from the root or from here).
#
# A scene is a TOML file; `dolfin_rod.run` runs it (as `dolfin-rod run` does) and returns
# the results.  Here: the bundled soft cantilever, clamped at one end and released under
# gravity while its natural curvature creeps (scenes/gravity_cantilever.toml), made short
# and coarse so that it runs in seconds.

# %%
from pathlib import Path

import numpy as np

import dolfin_rod

scenes = next(p for p in (Path("scenes"), Path("../../scenes")) if p.is_dir())
result = dolfin_rod.run(scenes / "gravity_cantilever.toml",
                        {"time.t_end": 0.2, "geometry.n_cells": 8},   # {"table.key": value}
                        out="first_rod_notebook", overwrite=True, quiet=True)
print(result.status, "in", result.folder)

# %% [markdown]
# ## The time series
#
# `result.series` holds every column of timeseries.csv (one value per step): loads, tip
# position and rotation, reactions, energies, the power-balance residual.

# %%
t = np.array(result.series["time"])
tip = np.array([result.series[f"tip_position_{c}"] for c in "xyz"]).T
print(f"{len(t)} rows; tip at t = {t[-1]:g}: {tip[-1]} (moved {tip[-1] - tip[0]})")
print("columns:", ", ".join(sorted(result.series))[:300], "...")

# %% [markdown]
# ## Fields along the rod
#
# `rod.pvd` (any ParaView; `rod.bp` for ParaView >= 5.13) holds the deformed centre line
# and the fields at the output times; `dolfin_rod.read_pvd` reads it back as arrays.

# %%
steps = dolfin_rod.read_pvd(result.folder / "rod.pvd")
last = steps[-1]
s = last["point"]["s"]
print(f"{len(steps)} steps of fields; at t = {last['time']:g} the centre line ends at "
      f"{last['points'][np.argmax(s)]}")
print("natural curvature u_d per cell:", np.round(last["cell"]["u_d"][:, 1], 3))

# %% [markdown]
# ## Pictures
#
# The run drew histories.png (what the scene is about), animation.gif and snapshots.png.
# `result.plot(...)` draws them again, here with the panels and columns you name.

# %%
files = result.plot(["tip_deflection", "reaction_force_start_z"])
print("drew", [f.name for f in files])
try:                                   # in Jupyter: show the figure
    from IPython.display import Image, display
    display(Image(filename=str(files[0])))
except ImportError:
    pass

# %% [markdown]
# ## Change a parameter, check against a hand formula
#
# Any key of a scene can be changed the same way (docs/scenes.md lists them).  The bundled
# sprung cantilever (scenes/sprung_cantilever.toml: a steel strip 1 m long, pinned to a wall
# on a rotational spring k, a tip force F ramped to 5 N, quasi-static) with the spring twice
# as stiff: for small deflections the tip moves F L^3 / (3 E I) + F L^2 / k.

# %%
k = 400.0                                          # N m / rad (the scene has 200)
sprung = dolfin_rod.run(scenes / "sprung_cantilever.toml",
                        {"boundary.start_spring": {"rotational": k}},
                        out="first_rod_sprung", overwrite=True, quiet=True)
E, b, h, L, F = 2.1e11, 0.04, 0.005, 1.0, 5.0     # the scene's numbers (SI)
hand = F * L**3 / (3 * E * b * h**3 / 12) + F * L**2 / k
computed = sprung.series["tip_position_x"][-1] - sprung.series["tip_position_x"][0]
print(f"tip deflection {computed:.5f} m; small-deflection formula {hand:.5f} m")
