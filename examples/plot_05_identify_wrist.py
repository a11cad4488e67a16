"""
Identify a wrist stock from notch angles
========================================

Two nitinol wrists cut from one tube stock (a 5-notch asymmetric wrist and a
4-notch, pre-curved, tip-first wrist: ``datasets/geometry/wrist_*.toml``),
three loading trials each, the angle of every notch measured with 0.5° noise:
the synthetic study of ``notchfit demo --tube wrist``, at a smaller size.
:func:`notchfit.analysis.identify.identify` fits what the wrists share (the material's
``E_lin``, ``E_se``, ``strain_lower``, the tension-compression ratio
``strain_ratio`` of the asymmetric notches, and the tendon's friction ``μ_d``) and
each wrist's rest angles and cut depths; the plot compares the measured
angles of each wrist's first trial with the identified model. The hidden
truth is printed beside the identified values.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from notchfit import io
from notchfit.physics.friction import FrictionParams, simulate_angles
from notchfit.analysis.identify import identify
from notchfit.studies.synth import generate_study, load_recipe

folder = Path(tempfile.mkdtemp()) / "study"
generate_study(load_recipe("wrist_stock").scaled(n_up=8), folder, seed=7)
experiments = io.read_study(folder)
result = identify(experiments, heldout=False)         # held-out refits take longer: `notchfit identify`

truth = io.read_json(folder / "truth.json")["params"]
for name in result.free:
    # a parameter the generator's model does not set is at the model's default (strain_ratio 1: symmetric)
    true = truth.get(name, getattr(FrictionParams(), name))
    print(f"{name:13s} {result.values[name]:.4g} ± {result.se[name]:.2g}   (truth {true:.4g})")
print(f"training rms {result.train_rms:.2f} {result.metric}")

fig, axes = plt.subplots(1, 2, figsize=(9.6, 4.0), sharey=True)
for ax, tube in zip(axes, result.tubes.values()):
    exp = next(e for e in experiments if e.name == tube.experiments[0])
    s = exp.samples
    tension = s["tension_right_N"].to_numpy()
    model = simulate_angles(s["time_s"].to_numpy(), None, tension, tube.model, exp.geometry)
    for j in range(exp.geometry.n_joints):
        line, = ax.plot(tension, np.degrees(exp.angles[:, j]), "o", ms=4)
        ax.plot(tension, np.degrees(model[:, j]), "-", color=line.get_color(), lw=1)
    ax.set_title(f"{tube.name}: trial {exp.name}")
    ax.set_xlabel("tendon tension [N]")
axes[0].set_ylabel("notch angle [deg]")
fig.suptitle("each notch (one colour per notch): dots measured, lines the identified model", fontsize=10)
fig.tight_layout()
plt.show()
