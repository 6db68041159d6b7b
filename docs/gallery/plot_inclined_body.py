"""
The inclined body over the Poisson ratio (Fig. 7)
=================================================

The parallelogram of section 5.2 of the paper: base :math:`L = 1` on :math:`\\Gamma_C`,
height :math:`H = 3`, its clamped top shifted by :math:`L' = 1` (:math:`H/L = H/L' = 3`),
every contact node slipping. It leans, so its critical coefficient is small: the paper finds
it "between 0.55 and 0.61", "commonly observed friction coefficients" (Fig. 7). A sweep over
nu and three mesh sizes gives the curve on each mesh and, for each nu, the :math:`h \\to 0`
limit.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import critfric
from critfric.plots import figures
from critfric.sweep import make_grid, run_sweep

# %%
# The sweep
# ---------
# 11 Poisson ratios from 0 to 0.5 (the last one moved to 0.499: nu = 0.5 is singular) on
# three sizes; one mesh and one assembly per size serve every nu.

case = critfric.load_case("inclined-body")
grid = make_grid(case, nu="0:0.5:11", size="0.2,0.1,0.05", element="P1")
print("\n".join(grid.notes))
tmp = tempfile.TemporaryDirectory()
sweep = run_sweep(case, grid, output=Path(tmp.name) / "fig7.h5", jobs=1)

limits = sorted((lim for lim in sweep.limits if lim.family == "positive"), key=lambda m: m.nu)
for lim in limits:
    print(f"nu = {lim.nu:5.3f}: {lim.limit:.6f} +- {lim.error:.1e}  {lim.status[:60]}")

# %%
# The figure
# ----------
# ``critfric.plots.figures`` returns the figures of a sweep file as matplotlib Figures (what
# ``critfric plot`` saves as PNG); ``plt.figure(fig)`` hands one to pyplot to show it. The
# "critical" figure has the positive family on the left and the negative one on the right.

fig = figures(sweep.path)["critical"]
left = fig.axes[0]
left.axhspan(0.55, 0.61, color="0.85", zorder=0, label="the paper: 0.55 to 0.61")
left.legend(fontsize=8)
plt.figure(fig)

# %%
# The check: up to nu = 0.45 every limit lies in the paper's range and the coefficient falls
# with nu. At nu = 0.499 the P1 values drift from mesh to mesh (linear triangles lock as the
# material becomes incompressible), so the sweep gives no limit there: a gap in the dashed
# curve, and a note in the figure.

converged = [lim for lim in limits if lim.nu <= 0.45]
values = np.array([lim.limit for lim in converged])
assert all(lim.status == "ok" for lim in converged)
assert np.all((values > 0.55) & (values < 0.62)) and np.all(np.diff(values) < 0)
assert limits[-1].nu == 0.499 and limits[-1].status.startswith("not converged")
tmp.cleanup()
