"""
The friction model and its hysteresis loops
===========================================

The cable-friction simulator of Sec. IV-B driven by a bend–unbend test (the
left cable pulled from 0.45 N to 25 N and back,
:func:`notchfit.physics.protocols.bend_unbend`). Friction between the cable and its
guide channels makes the unloading branch differ from the loading one: the
loop of tension against tip angle (the sum of the joint angles) changes
with the dynamic friction coefficient ``μ_d``, and a larger ``μ_d`` bends the
tube less at the same tension. The right panel shows the regimes of
the paper (I loading, II holding, III releasing) along the test for the
paper's ``μ_d = 0.29``.
"""

import matplotlib.pyplot as plt
import numpy as np

from notchfit.physics.friction import FrictionParams, simulate
from notchfit.polygon import polygon_area
from notchfit.physics.protocols import bend_unbend

test = bend_unbend(25.0, 0.45, pull="left")
results = {mu: simulate(test.time, test.tension_left, test.tension_right, FrictionParams(mu_d=mu))
           for mu in (0.0, 0.1, 0.29)}

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9.6, 4.0))
for mu, r in results.items():
    load = r.input_left - r.input_right                # [N]
    tip = -r.tip_angle                                 # toward the pulled (left) side [rad]
    area = polygon_area(load, tip)
    print(f"μ_d = {mu:4.2f}: loop area {area:.3f} N rad, peak tip angle {tip.max():.3f} rad")
    ax1.plot(tip, load, ".-", ms=3, lw=1, label=f"μ_d = {mu:g} (area {area:.2f} N rad)")
ax1.set_xlabel("tip angle toward the pulled side [rad]")
ax1.set_ylabel("tension difference [N]")
ax1.set_title("tension against tip angle")
ax1.legend(fontsize=8)

r = results[0.29]
colors = {"I": "tab:red", "II": "tab:gray", "III": "tab:blue"}
for regime, color in colors.items():
    on = r.regime == regime
    ax2.plot(r.time[on], -r.a[on], "o", ms=4, color=color, label=f"regime {regime}")
ax2.plot(r.time, -r.a, "-", lw=0.8, color="k")
ax2.set_xlabel("time [s]")
ax2.set_ylabel("−a of θ_j = a + b j [rad]")
ax2.set_title("the paper's regimes, μ_d = 0.29")
ax2.legend(fontsize=8)
fig.tight_layout()
plt.show()
