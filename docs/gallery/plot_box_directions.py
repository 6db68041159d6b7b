"""
A 3D box: the critical coefficient over slip directions
=======================================================

In 3D each slipping contact node slips in a direction of the contact plane: at the angle
:math:`\\theta` from :math:`t_1` towards :math:`t_2 = n \\times t_1`. The box
:math:`[0, 1] \\times [0, 0.5] \\times [0, 1]`, clamped on top and resting on the plane
:math:`y = 0` (:math:`n = -e_y`, :math:`t_1 = e_x`, :math:`t_2 = e_z`), has one critical
coefficient per direction. Reversing the direction flips every eigenvalue,
:math:`\\alpha(\\theta + 180°) = -\\alpha(\\theta)`, so angles over 180 degrees give the whole
curve, and the *body's* coefficient is the least over all directions. Under the default
*rate* law the slip velocity follows the friction force; each eigenpair carries
:math:`r`, 0 when it is an exact static branch too.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

import critfric
from critfric.plots import figures
from critfric.sweep import make_grid, run_sweep

# %%
# One direction
# -------------
# The shipped ``box`` on a coarse P2 mesh, slipping along x: the eigenfunction on the contact
# plane (left) and the normal contact force (right).

case = critfric.load_case("box", overrides={"mesh.size": 0.25})
result = critfric.solve_case(case)
print(result, "r of the lowest:", result.r_of(result.positive[:1]))
tmp = tempfile.TemporaryDirectory()
path = critfric.write_result(result, Path(tmp.name) / "box.h5")
plt.figure(figures(path)["contact_positive_0"])

# %%
# Every direction
# ---------------
# Seven angles from 0 to 180 degrees on one mesh and one assembly; the sweep then brackets
# the least coefficient between the samples and locates it by Brent's method.

grid = make_grid(case, slip_angle="0:180:7")
sweep = run_sweep(case, grid, output=Path(tmp.name) / "angles.h5", jobs=1)
for row in sweep.rows:
    print(f"angle {row['slip_angle']:5.1f}: {row['positive'][0]:.6f} "
          f"(and {-row['negative'][0]:.6f} at {row['slip_angle'] + 180:.0f})")
(minimum,) = sweep.minima
print(f"the body's coefficient: {minimum['positive']:.7f} at {minimum['slip_angle']:.2f} degrees")
plt.figure(figures(sweep.path)["directions"])

# %%
# The check: slipping along an edge of the square base needs more friction than along a
# diagonal; the located minimum is below every sample; the 0 and 180 degree samples mirror
# each other.

rows = {row["slip_angle"]: row for row in sweep.rows}
samples = [row["positive"][0] for row in sweep.rows] + [-row["negative"][0] for row in sweep.rows]
assert minimum["positive"] <= min(samples)
assert rows[0.0]["positive"][0] > rows[60.0]["positive"][0]
assert abs(rows[180.0]["positive"][0] + rows[0.0]["negative"][0]) < 1e-9
tmp.cleanup()
