"""
Diagnose a hidden effect
========================

A small synthetic study (4 bend–unbend tests, notch points with 0.02 mm
noise) hides one effect the paper's model lacks: friction between the load
cell and the manipulator's base (``proximal_friction``, a capstan band of
``β = 0.1``). :func:`notchfit.analysis.diagnosis.diagnose` calibrates the paper's
model on some tests, predicts the held-out ones, fits six physical
extensions, and names a cause only when it beats the baseline on held-out
data by more than the measurement noise.

The diagnosis takes about 100 s on 2 cores, too long for a page build, so
this page shows a **cached result**: ``examples/data/diagnosis_small.json``,
written by this script's own ``summarize`` when it runs with
``NOTCHFIT_DOCS_DIAGNOSE=1``. The figure and the printed lines are drawn from
that file.
"""

import json
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

try:
    HERE = Path(__file__).resolve().parent
except NameError:                                     # the site's build runs it from its folder
    HERE = Path.cwd()
CACHE = HERE / "data" / "diagnosis_small.json"
MM = 1e3


def summarize(diag) -> dict:
    """What the figure shows, from a :class:`notchfit.analysis.diagnosis.Diagnosis` [mm]."""
    return {
        "cause": diag.cause,
        "causes": list(diag.causes),
        "noise_floor_mm": diag.noise_rms * MM,
        "baseline_heldout_mm": diag.gain.baseline * MM,
        "extended_heldout_mm": diag.gain.extended * MM,
        "candidates": {c.cause: {"heldout_mm": c.heldout_rms * MM, "z": c.z, "significant": bool(c.significant)}
                       for c in diag.candidates},
        "per_regime": {k: [g.baseline * MM, g.extended * MM] for k, g in diag.per_regime.items()},
    }


if os.environ.get("NOTCHFIT_DOCS_DIAGNOSE") == "1":   # run the diagnosis and refresh the cache
    from notchfit import io
    from notchfit.analysis.diagnosis import diagnose
    from notchfit.studies.synth import generate_study, load_recipe

    folder = Path(tempfile.mkdtemp()) / "study"
    recipe = load_recipe("proximal_friction").scaled(n_experiments=4, n_up=8, n_down=10)
    generate_study(recipe, folder, seed=7)
    diag = diagnose(io.read_study(folder), seed=7, max_folds=4)
    CACHE.write_text(json.dumps(summarize(diag), indent=1) + "\n")

result = json.loads(CACHE.read_text())
print(f"cause named: {result['cause']}")
print(f"held-out rms: baseline {result['baseline_heldout_mm']:.3f} mm -> extended "
      f"{result['extended_heldout_mm']:.3f} mm (noise floor {result['noise_floor_mm']:.3f} mm)")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9.6, 4.4), gridspec_kw={"width_ratios": [3, 2]})
names = sorted(result["candidates"], key=lambda c: result["candidates"][c]["heldout_mm"])
values = [result["candidates"][c]["heldout_mm"] for c in names]
colors = ["tab:green" if result["candidates"][c]["significant"] else "tab:gray" for c in names]
ax1.barh(names, values, color=colors)
ax1.axvline(result["baseline_heldout_mm"], color="k", lw=1, label="calibrated baseline")
ax1.axvline(result["noise_floor_mm"], color="tab:red", lw=1, ls="--", label="noise floor")
ax1.invert_yaxis()
ax1.set_xlabel("held-out notch-point rms [mm]")
ax1.set_title("each extension, held out (green: a significant gain)")
ax1.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)

regimes = list(result["per_regime"])
x = np.arange(len(regimes))
before, after = np.array([result["per_regime"][r] for r in regimes]).T
ax2.bar(x - 0.2, before, 0.4, label="baseline")
ax2.bar(x + 0.2, after, 0.4, label=f"with {result['cause']}")
ax2.axhline(result["noise_floor_mm"], color="tab:red", lw=1, ls="--")
ax2.set_xticks(x, [f"regime {r}" for r in regimes])
ax2.set_ylabel("held-out rms [mm]")
ax2.set_title("where the baseline missed")
ax2.legend(fontsize=8)
fig.tight_layout()
plt.show()
