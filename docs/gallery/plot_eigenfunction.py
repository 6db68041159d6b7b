"""
An eigenfunction and its contact forces on Gamma_C (Figs. 8 and 9)
===================================================================

At a critical coefficient :math:`\\alpha` the eigenproblem (3.2) has a solution
:math:`(\\Phi, X, Y)`: a displacement :math:`\\Phi` of the body with normal and tangential
contact forces :math:`X, Y` on :math:`\\Gamma_C` such that

.. math:: K \\Phi = B_n X + B_t Y, \\qquad \\Phi_n = 0 \\text{ and }
          Y = \\alpha \\gamma X \\text{ on } \\Gamma_C,

with :math:`\\gamma = +1` for slip along :math:`+t`. Section 5.3 of the paper builds from it a
whole branch of solutions of the static problem. Here is the eigenfunction of the inclined
body (Fig. 8), its von Mises stress (Fig. 9), and what it does on :math:`\\Gamma_C`.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import critfric
from critfric.plots import figures

# %%
# Solve and write the result file
# -------------------------------
# ``solve_case`` returns a ``Result``; ``write_result`` writes the HDF5 file that
# ``critfric plot`` and ``critfric export`` read.

result = critfric.solve_case("inclined-body", overrides={"mesh.size": 0.05})
print(result)
tmp = tempfile.TemporaryDirectory()
path = critfric.write_result(result, Path(tmp.name) / "inclined_body.h5")
figs = figures(path)

# %%
# Fig. 8: the body moved by Phi (scaled to 10% of its size), :math:`\Gamma_C` in red.

plt.figure(figs["deformed"])

# %%
# Fig. 9: the von Mises stress of Phi (max :math:`|\Phi| = 1`, E = 1). The stress is singular
# at the ends of :math:`\Gamma_C`; the colour scale stops at the 99th percentile.

plt.figure(figs["von_mises"])

# %%
# On Gamma_C
# ----------
# ``result.modes[0]`` is the lowest positive mode: ``phi`` at every node (x, y), and the
# nodal contact forces ``theta_n``, ``theta_t`` (X and Y) at the contact nodes, which
# ``result.contact_nodes`` lists in the order of t. With the outward normal n = (0, -1), the
# tangent is t = (1, 0).

mode = result.modes[0]
nodes = result.contact_nodes
normal = result.normal
tangent = np.array([-normal[1], normal[0]])
x = result.mesh.points[nodes] @ tangent
phi = mode["phi"][nodes] / np.abs(mode["phi"]).max()
X, Y = mode["theta_n"], mode["theta_t"]
scale = np.abs(X).max()

fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
top.plot(x, phi @ tangent, "o-", ms=3, label=r"$\Phi_t$")
top.plot(x, phi @ normal, "s-", ms=3, label=r"$\Phi_n$ (zero: the node stays in contact)")
top.set_ylabel(r"$\Phi$ on $\Gamma_C$ (max $|\Phi| = 1$)")
bottom.plot(x, X / scale, "o-", ms=3, label=r"$X$ (normal force)")
bottom.plot(x, Y / scale, "s-", ms=3, label=rf"$Y = \alpha X$, $\alpha$ = {mode['alpha']:.5f}")
bottom.set_ylabel("nodal contact force (max |X| = 1)")
bottom.set_xlabel(r"position along $\Gamma_C$ (x)")
top.set_title(f"inclined body, P1, h = {result.h:.3g}: the lowest positive mode on Gamma_C")
for ax in (top, bottom):
    ax.axhline(0, color="0.5", lw=0.8)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
fig.tight_layout()

# %%
# The check: the mode satisfies the conditions on Gamma_C, and the coefficient is the paper's
# (about 0.585 at nu = 0.3; 0.5867 on this coarse mesh).

assert np.abs(phi @ normal).max() < 1e-10
assert np.allclose(Y, mode["alpha"] * X, atol=1e-12 * scale)
assert abs(result.critical - 0.5867) < 1e-3
tmp.cleanup()
