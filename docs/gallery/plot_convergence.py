"""
An h -> 0 limit and its error bar
=================================

A critical coefficient computed on a mesh of size :math:`h` is a discrete value
:math:`\\mu_h`; the continuous problem has its limit as :math:`h \\to 0`. A sweep over three
sizes or more fits

.. math:: \\mu_h = \\mu_0 + C h^p

to the four finest sizes (weighted towards the finer ones), with the order :math:`p`
observed, and gives :math:`\\mu_0` with an error estimate built from the extrapolation
correction, the change of the limit without the finest size and the scatter of the fit. Here
is the unit square at :math:`\\nu = 0.3` (the paper's Fig. 5) with three elements, against
the reference value 1.94471145 (known to 3e-8 from much finer, radially graded meshes:
``make validate``).
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import critfric
from critfric.plots import figures
from critfric.sweep import make_grid, run_sweep

REFERENCE = 1.94471145

# %%
# The sweep
# ---------
# Four sizes that halve, three elements. With three sizes or more a sweep grades its meshes
# at the singular points (size 0.05 h at the ends of Gamma_C) and nests them.

case = critfric.load_case("unit-square")
grid = make_grid(case, nu="0.3", size="0.2,0.1,0.05,0.025", element="P1,P2,Q2")
tmp = tempfile.TemporaryDirectory()
sweep = run_sweep(case, grid, output=Path(tmp.name) / "fig5.h5", jobs=1)

for lim in sweep.limits:
    if lim.family == "positive":
        print(f"{lim.element}: limit {lim.limit:.9f} +- {lim.error:.1e} (order {lim.order:.2f}),"
              f" reference - limit = {REFERENCE - lim.limit:+.1e}")

# %%
# Values, limits and error bars
# -----------------------------
# Left: the computed values against h, each element's limit as a dashed line and its error
# estimate as a band. Right: each limit with its error bar, zoomed around the reference.

limits = {lim.element: lim for lim in sweep.limits if lim.family == "positive"}
fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2))
for k, element in enumerate(grid.element):
    rows = [r for r in sweep.rows if r["element"] == element]
    h = np.array([r["size"] for r in rows])
    values = np.array([r["positive"][0] for r in rows])
    line, = left.plot(h, values, marker="o", label=f"{element}")
    lim = limits[element]
    left.axhline(lim.limit, color=line.get_color(), ls="--", lw=1)
    left.axhspan(lim.limit - lim.error, lim.limit + lim.error, color=line.get_color(), alpha=0.15)
    right.errorbar([k], [lim.limit - REFERENCE], yerr=[lim.error], fmt="o", capsize=6,
                   color=line.get_color())
left.set_xscale("log")
left.set_xticks(grid.size, [f"{s:g}" for s in grid.size])
left.minorticks_off()
left.invert_xaxis()
left.set_xlabel("mesh size h")
left.set_ylabel(r"lowest positive eigenvalue $\mu_h$")
left.set_title(r"unit square, $\nu = 0.3$: values and $h \to 0$ limits")
left.legend()
right.axhline(0, color="0.3", lw=1)
right.set_yscale("symlog", linthresh=1e-7)
right.set_xticks(range(len(grid.element)), grid.element)
right.set_xlim(-0.5, len(grid.element) - 0.5)
right.set_ylabel("limit - reference (symlog)")
right.set_title("each limit with its error bar")
for ax in (left, right):
    ax.grid(True, alpha=0.3)
fig.tight_layout()

# %%
# critfric's own figure of the same file (``critfric plot fig5.h5`` writes it as
# ``fig5_convergence.png``): the distance to the limit on log-log axes, with the observed
# orders. ``plt.figure(fig)`` hands the Figure to pyplot to show it.

plt.figure(figures(sweep.path)["convergence"])

# %%
# The check: every limit is converged and contains the reference within its error bar.

for lim in limits.values():
    assert lim.status == "ok", lim
    assert abs(lim.limit - REFERENCE) <= lim.error + 3e-8, lim
tmp.cleanup()
