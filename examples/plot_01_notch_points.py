"""
Project the notch points
========================

The 58 numbered notch points of the default tube (27 joints, Sec. IV-A of
Moses et al. 2015) at three shapes: straight, constant curvature, and the
linear shape ``θ_j = a + b j`` whose base joints bend more than its tip. The
projector :func:`notchfit.physics.notches.notch_points` maps joint angles [rad] to
points (x, z) [m] in the manipulator frame; ``docs/geometry.md`` numbers
them.
"""

import matplotlib.pyplot as plt
import numpy as np

from notchfit.physics.geometry import default_geometry
from notchfit.physics.notches import notch_points

geom = default_geometry()
j = np.arange(1, geom.n_joints + 1)
shapes = {
    "straight": np.zeros(geom.n_joints),
    "constant curvature, θ = 0.08 rad": np.full(geom.n_joints, 0.08),
    "linear, θ_j = 0.11 − 0.003 j": 0.11 - 0.003 * j,
}

fig, ax = plt.subplots(figsize=(6.4, 5.0))
for label, theta in shapes.items():
    points = notch_points(theta, geom)                 # (58, 2) [m]
    ax.plot(points[:, 0] * 1e3, points[:, 1] * 1e3, ".", ms=4, label=label)
    tip = points[28:30].mean(axis=0) * 1e3             # points 29 and 30: the tip corners
    print(f"{label:36s} tip at x = {tip[0]:7.2f} mm, z = {tip[1]:6.2f} mm")

# number some points of the last shape as the files do (from 1, anticlockwise from the base's left corner)
for i in (0, 1, 10, 28, 29, 48):
    ax.annotate(str(i + 1), points[i] * 1e3, textcoords="offset points", xytext=(4, -8), fontsize=7)
ax.set_aspect("equal")
ax.set_xlabel("x [mm]")
ax.set_ylabel("z [mm]")
ax.set_title(f"The {len(points)} notch points of the default tube")
ax.legend(loc="upper left", fontsize=8)
plt.show()
