"""
Flutter and divergence of the sliding square
============================================

The static critical coefficient says when the static problem loses uniqueness. Steady
sliding can fail earlier. Small motions :math:`u = \\phi e^{st}` about the sliding state solve

.. math:: (s^2 M + K)\\,\\phi = (B_n + f B_t)\\,X, \\qquad \\phi_n = 0 \\text{ on } \\Gamma_C,

with :math:`f` the signed friction coefficient. At :math:`f = 0` every :math:`s` is imaginary
(the free vibrations). As :math:`|f|` grows, either a frequency reaches 0 (*divergence*, at
exactly the static critical coefficient) or two frequencies meet and split into a growing and
a decaying oscillation (*flutter*, mode coupling). ``stability_case`` follows the lowest
frequency pairs along :math:`f` and finds the first coalescence by Newton's method.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import critfric
from critfric.files.stabilityfile import write_stability
from critfric.plots import figures
from critfric.stability import stability_case

# %%
# The analysis
# ------------
# The unit square (P1, h = 0.05, nu = 0.3), 10 frequency pairs followed each way.

result = stability_case("unit-square", overrides={"mesh.size": 0.05})
print(result)
print("frequencies at f = 0:", np.round(result.frequencies[:6], 4))
for side in ("positive", "negative"):
    print(f"{side}: flutter at {result.flutter[side]:+.6f}, divergence at "
          f"{result.divergence[side]:+.6f}; first: {result.first(side)}")
omega = np.sqrt(result.flutter_kappa["positive"])
print(f"flutter frequency {omega:.4f}, between omega_4 and omega_5")

# %%
# The root locus
# --------------
# ``critfric stability --plot`` draws it from the stability file: the frequency
# :math:`|\mathrm{Im}\, s|` and the growth rate :math:`\mathrm{Re}\, s` of each branch against
# the friction, flutter onsets circled, divergence dashed.

tmp = tempfile.TemporaryDirectory()
path = write_stability(result, Path(tmp.name) / "square_stability.h5")
plt.figure(figures(path)["locus"])

# %%
# The static analysis alone
# -------------------------
# The static coefficient of the same mesh is the divergence threshold: 30 times the flutter
# threshold. Close natural frequencies (omega_4 and omega_5 differ by 0.6%), not the static
# coefficient, limit the friction that steady sliding of this square tolerates.

static = critfric.solve_case("unit-square", overrides={"mesh.size": 0.05})
print(f"static critical coefficient {static.critical:.6f}, "
      f"{static.critical / result.flutter['positive']:.1f} x the flutter threshold")

# %%
# The check: divergence is the static coefficient, flutter comes first, at the coalescence of
# the 4th and 5th frequencies.

assert abs(result.divergence["positive"] - static.critical) < 1e-10
assert result.first("positive") == "flutter" and 0.06 < result.flutter["positive"] < 0.07
assert result.frequencies[3] < omega < result.frequencies[4]
tmp.cleanup()
