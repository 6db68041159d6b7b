"""
Solution curves along the friction and the load
===============================================

On :math:`\\Gamma_C` the static Coulomb problem is piecewise linear: in each contact state
(each node free, stuck or slipping along :math:`\\pm t`) it is one linear system. So its
solutions, followed along a parameter, form curves made of pieces, one state each, which
``path_case`` finds exactly, without a step size. Where pieces meet it reports *kinks* (a node
changes status), *folds* (the curve turns back) and *branch points* (the friction equals a
critical coefficient of the state: a continuum of solutions joins the curves there).

Two shipped examples: the one triangle along the friction (the paper's Fig. 2), and the unit
square pressed down, then sheared, at friction 0.5.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from critfric.files.pathfile import write_path
from critfric.multiplicity.path import path_case
from critfric.plots import figures

tmp = tempfile.TemporaryDirectory()

# %%
# The one triangle along the friction
# -----------------------------------
# ``cases/one_triangle.toml`` has the paper's load of section 4.1 and ``[path] parameter =
# "friction"``, ``range = [0, 3]``. Below :math:`3 - 4\nu = 1.8` the slip solution is the only
# one; at 1.8 a vertical branch joins it to the stuck solution, which exists from there on.

triangle = path_case("one-triangle")
print(triangle.counts())
branch = next(e for e in triangle.events if e.kind == "branch")
print(f"branch point at friction {branch.value!r}, the critical coefficient {branch.critical!r}")
plt.figure(figures(write_path(triangle, Path(tmp.name) / "triangle_path.h5"))["diagram"])

# %%
# The unit square pressed, then sheared
# -------------------------------------
# ``cases/unit_square.toml``: the top pressed down by 0.01 (the load L0), then moved along
# :math:`+x` by t x 0.02 (the load L1) for t from 0 to 1, at friction 0.5. The diagram shows
# the tangential displacement of the node that moves most, the status of every contact node
# along the way, and each piece's margin (its state's critical coefficient over the
# friction).

square = path_case("unit-square")
print(square.counts(), f"{square.n_contact} contact nodes, {square.seconds:.2f} s")
first = square.events[0]
print(f"first kink at t = {first.value:.3f}: node {first.nodes}")
plt.figure(figures(write_path(square, Path(tmp.name) / "square_path.h5"))["diagram"])

# %%
# The check: the branch point is at 1.8 to rounding; the square's response is one curve
# with no fold and no branch point, every state at least 7.9 times the friction away from
# losing uniqueness (or with no positive critical coefficient at all).

assert abs(branch.value - 1.8) < 1e-12 and abs(branch.critical - 1.8) < 1e-12
counts = square.counts()
assert counts["curves"] == 1 and counts["folds"] == 0 and counts["branches"] == 0
margins = [p.margin for c in square.curves for p in c.pieces if p.margin is not None]
assert min(margins) > 7.9
tmp.cleanup()
