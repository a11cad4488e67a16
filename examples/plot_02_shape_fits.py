"""
Fit constant-curvature, linear and free shapes
==============================================

A synthetic bend–unbend test with known ground truth (regime I: the tube
bends with its base joints bent more than its tip; regime II: the curvature
evens out; regime III: it unbends), 0.02 mm point noise. Each sample is fitted
with three shape models (Sec. IV-A): constant curvature ``cc`` (one angle),
``linear`` (``θ_j = a + b j``) and ``free`` (one angle per joint). The plot
shows the pointwise error along the tube at the sample where the shape is
least like an arc (Figs. 13–14 of the paper), and the fitted ``b`` against
the truth (Fig. 15).
"""

import matplotlib.pyplot as plt
import numpy as np

from notchfit.figures.fitting import synthetic_bend_unbend
from notchfit.analysis.fitting import fit_experiment
from notchfit.physics.geometry import default_geometry

geom = default_geometry()
points, truth = synthetic_bend_unbend(geom)            # (S, 58, 2) [m] and the ground truth
fit = fit_experiment(points, geom, ("cc", "linear", "free"), mirror=truth["mirror"], sigma=truth["noise"])

s = int(np.argmax(np.abs(truth["b"])))                # the end of regime I: b at its largest
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9.6, 4.0))
for model in fit.models:
    err = fit.errors(model)                            # (S, 58) [m]
    rms = np.sqrt(np.mean(err ** 2)) * 1e3
    print(f"{model:7s} rms error over every sample {rms:.4f} mm")
    ax1.plot(err[s] * 1e3, ".-", ms=3, label=f"{model} (rms {rms:.3f} mm)")
ax1.set_xlabel("notch point")
ax1.set_ylabel("error [mm]")
ax1.set_yscale("log")
ax1.set_title(f"pointwise error, sample {s} (largest b)")
ax1.legend(fontsize=8)

a, b, se_a, se_b = fit.ab("linear")
ax2.errorbar(np.arange(len(b)), b * 1e3, yerr=2 * se_b * 1e3, fmt=".", label="fitted b ± 2 SE")
ax2.plot(truth["b"] * 1e3, "-", lw=1, label="truth")
ax2.set_xlabel("sample")
ax2.set_ylabel("b [mrad per joint]")
ax2.set_title("linear model: b over the test")
ax2.legend(fontsize=8)
fig.tight_layout()
plt.show()
