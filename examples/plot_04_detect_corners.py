"""
Detect the notch corners on a rendered image
============================================

A tube bent at 0.1 rad per joint is rendered through a synthetic camera
(0.05 mm per pixel, blur, noise, uneven light, a textured background:
:func:`notchfit.vision.render.render_manipulator`), and
:func:`notchfit.vision.detection.detect_notches` finds its 58 numbered corners.
The rendering returns the true points, so the detector's error is measured
here; ``docs/robustness.md`` gives it over many images and conditions.
"""

import matplotlib.pyplot as plt
import numpy as np

from notchfit.vision.detection import detect_notches
from notchfit.figures.detection import detection_overlay
from notchfit.physics.geometry import default_geometry
from notchfit.vision.render import camera_for_shapes, render_manipulator

geom = default_geometry()
rng = np.random.default_rng(2015)
theta = np.full(geom.n_joints, 0.10) + rng.normal(0.0, 0.002, geom.n_joints)   # [rad]
camera, planes = camera_for_shapes([theta], geom, mm_per_px=0.05, phi=0.4)
render = render_manipulator(theta, geom, camera, plane=planes[0], rng=rng)

det = detect_notches(render.image, camera, geom)
error = np.linalg.norm(det.points - render.points_plane, axis=1)          # [m]
print(f"image {render.image.shape[1]} x {render.image.shape[0]} px, status {det.image_status}")
print(f"corner error: rms {np.sqrt(np.nanmean(error ** 2)) * 1e3:.4f} mm, "
      f"max {np.nanmax(error) * 1e3:.4f} mm over {np.isfinite(error).sum()} corners")

overlay = detection_overlay(render.image, det, 0, size=900)                # BGR, cropped to the tube
pixels = camera.plane_to_pixel(det.points)                                 # (58, 2) [px]
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9.6, 4.8), gridspec_kw={"width_ratios": [1, 1]})
ax1.imshow(overlay[..., ::-1])
ax1.set_axis_off()
ax1.set_title("the detected corners, coloured by status")

near_tip = np.arange(24, 36)                                               # points 25-36, around the tip
ax2.imshow(render.image, cmap="gray")
ax2.plot(*pixels[near_tip].T, "+", color="tab:green", ms=10, mew=1.5)
for i in near_tip:
    ax2.annotate(str(i + 1), pixels[i], textcoords="offset points", xytext=(6, 4), color="tab:red", fontsize=9)
lo, hi = pixels[near_tip].min(axis=0) - 25, pixels[near_tip].max(axis=0) + 25
ax2.set_xlim(lo[0], hi[0])
ax2.set_ylim(hi[1], lo[1])
ax2.set_axis_off()
ax2.set_title("near the tip: corners numbered as in the data files")
fig.tight_layout()
plt.show()
