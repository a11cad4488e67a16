"""The parameters ``notchfit identify`` can fit: bounds and starts from physics, the defaults.

Every fitted parameter is a :class:`notchfit.analysis.estimation.ParamSpec` (bounds,
start, log scale, probe values for the multi-start search). The seed tube's
(``spring_law = "rates"``) are the diagnosis baseline's: ``k_lin``, ``k_mid`` and
``μ_d`` (docs/models.md, "The baseline of the diagnosis"). A real tube's
material law (``spring_law = "material"``, :func:`notchfit.physics.springs.material_spring`)
has the material of superelastic nitinol:

* ``E_lin`` — the austenite modulus, 30–80 GPa in the literature (Duerig,
  Pelton & Stöckel 1999; manufacturers' sheets 41–75 GPa); bounds 15–150 GPa
  leave room for cut depths a few per cent off the drawing (the thin wall's
  ``I`` goes with its thickness cubed), start 50 GPa;
* ``E_se`` — the slope of the moment past the transformation onset, where the
  transformed zone spreads through the wall: a few GPa; bounds 0.2–30 GPa;
* ``strain_lower`` — the outer-fibre strain of the transformation onset,
  1–2 % in tension (onset stress ~400–500 MPa over E_lin); bounds 0.4–4 %;
* ``μ_d`` — tendon on the cut edges (capstan law): ~0.05–0.3 for a steel or
  polymer tendon on nitinol; bounds 0–0.8, start 0.1.

* ``strain_ratio`` — the plateau's onset strain in compression over that in tension: superelastic
  nitinol transforms later in compression (1.2–1.5; Orgéas & Favier 1998, Gall et al. 1999), so a
  notch whose cut face (compressed) lies farther from the neutral axis than its back (stretched)
  starts its plateau later than one threshold on its most strained fibre says; bounds 0.7–2.5
  (below 1 leaves the optimiser room around the symmetric law: with the bound at 1 it stalled there),
  start 1 (the symmetric law); identified by default where some notch's geometry lets it act
  (:func:`default_free`).

Positive moduli and the strain threshold are fitted in log space. ``μ_s`` is
tied to ``μ_d`` plus the base model's excess (0.01, the paper's).

Per tube and per notch (real tubes):

* ``rest_angle`` — the rest angles, within ``±REST_RANGE`` of the geometry
  file's (and inside the slot's closure), tied by a Gaussian prior to the angles
  the tube's own trials measured at zero force, with their standard error (the
  geometry file's, with ``REST_SIGMA_GEOMETRY``, when no trial starts at rest):
  cutting and heat treatment leave a few degrees of pre-curve that a geometry
  file rarely knows to a tenth of a degree, but a rest angle is a measurement,
  not a free bias that absorbs what the shared model misses;
* ``slot_depth`` — the effective cut depth, within ``±DEPTH_RANGE`` of the
  drawing, with a Gaussian prior of the geometry's ``slot_depth_tolerance_mm``,
  else ``DEPTH_TOLERANCE`` (a cutting and measuring tolerance of ~10–20 µm): the wall left by a deep one-sided cut is
  ~0.2 mm thick and its stiffness goes with its thickness cubed, so 10 µm off
  is ~15 % off in a notch's stiffness, more than the angle noise of a
  measurement. The material stays shared by every notch and tube.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..causes import REGISTRY
from ..estimation.specs import BASELINE, CAPSTAN_MU, MATERIAL, ParamSpec
from ...physics.friction_params import PARAM_KEYS, FrictionParams, default_params

__all__ = ["DEPTH", "DEPTH_COMMON", "DEPTH_RANGE", "DEPTH_TOLERANCE", "MATERIAL",
           "REST", "REST_RANGE", "REST_SIGMA_GEOMETRY", "REST_SIGMA_MIN", "SPECS", "TUBE_FREE", "base_model", "default_free", "parse_free", "specs_for"]

#: The name of the per-tube, per-joint rest angles in ``--free``.
REST = "rest_angle"
#: Rest angles are fitted within this distance of the geometry file's [rad] (~11°).
REST_RANGE = 0.2
#: Prior σ of a rest angle that no trial measured at zero force: the geometry file's value [rad] (1°).
REST_SIGMA_GEOMETRY = 0.0175
#: The smallest prior σ of a rest angle [rad] (0.05°): a rest angle is never known better than this.
REST_SIGMA_MIN = 8.7e-4
#: The name of the per-tube, per-notch cut depths in ``--free``.
DEPTH = "slot_depth"
#: Cut depths are fitted within this distance of the geometry file's [m] ...
DEPTH_RANGE = 60e-6
#: ... with a zero-mean Gaussian prior of this standard deviation [m] (the cutting tolerance), unless the
#: geometry file states its own (``slot_depth_tolerance_mm``) ...
DEPTH_TOLERANCE = 15e-6
#: ... and the mean of a tube's offsets held near 0 [m]: a depth error common to a tube's
#: notches scales its stiffness like the material does, so it is left to the shared material.
DEPTH_COMMON = 2e-6
#: ``strain_ratio`` is identified by default when a notch's cut face lies this many times farther from the
#: neutral axis than its back (shallower cuts); elsewhere the onset is the back fibre's either way.
ASYMMETRY_MIN_RATIO = 1.05
#: Names of the per-tube unknowns in ``--free``, with their spellings.
TUBE_FREE = {REST: REST, "rest_angle_rad": REST, DEPTH: DEPTH, "slot_depth_offset": DEPTH,
             "slot_depth_offset_m": DEPTH}

#: Every scalar parameter identify may fit, by FrictionParams field name.
SPECS = {
    **{s.name: s for s in BASELINE},
    **{s.name: s for s in MATERIAL},
    "k_stop": ParamSpec("k_stop", 0.5, 100.0, 10.0, log=True),
    "theta_mid": ParamSpec("theta_mid", 0.005, 0.5, 0.07, log=True),
    "theta_stop": ParamSpec("theta_stop", 0.01, 1.0, 0.14, log=True),
    "stop_ratio": ParamSpec("stop_ratio", 2.0, 500.0, 20.7, log=True),
    # the tension–compression asymmetry of the plateau's onset (compression over tension, 1.2-1.5 for
    # superelastic nitinol): probes on both sides of the symmetric law
    "strain_ratio": ParamSpec("strain_ratio", 0.7, 2.5, 1.0, log=True),
    **{s.name: s for c in REGISTRY.values() if c.identifiable for s in c.params},
}


#: The spring law a parameter acts through (the others act on every tube).
_LAW_OF = {**{k: "rates" for k in ("k_lin", "k_mid", "k_stop", "theta_mid", "theta_stop")},
           **{k: "material" for k in ("E_lin", "E_se", "strain_lower", "stop_ratio", "strain_ratio", DEPTH)}}


def parse_free(names) -> tuple[str, ...]:
    """``--free`` names (field names or model-file keys, e.g. ``E_lin`` or ``E_lin_Pa``) as field names.

    Raises
    ------
    ValueError
        An unknown name, or one given twice.
    """
    by_key = {v: k for k, v in PARAM_KEYS.items() if k not in ("rest_angle", "slot_depth_offset")}
    out = []
    for raw in names:
        name = raw.strip()
        field = TUBE_FREE.get(name, by_key.get(name, name))
        if field not in SPECS and field not in (REST, DEPTH):
            known = ", ".join(sorted(SPECS)) + f", {REST}, {DEPTH}"
            raise ValueError(f"--free {name!r}: not a parameter identify can fit (known: {known})")
        if field in out:
            raise ValueError(f"--free names {field} twice")
        out.append(field)
    if not out:
        raise ValueError("--free needs at least one parameter")
    return tuple(out)


def default_free(models, geoms) -> tuple[str, ...]:
    """The parameters identified by default, by the physics of the study's tubes.

    The material law's ``E_lin``, ``E_se``, ``strain_lower`` when a tube uses it (and its
    tension–compression asymmetry ``strain_ratio`` when a notch's cut face lies 5 % or more
    farther from the neutral axis than its back: leave-one-tube-out 1.10x -> 0.98x the true
    model's error on a synthetic stock with that asymmetry, docs/models.md),
    the rates law's ``k_lin``, ``k_mid`` when one does (the diagnosis baseline),
    ``μ_d`` always, and for real tubes (a section backbone) each notch's rest
    angle and, with the material law, its cut depth (module docstring).
    """
    laws = {m.spring_law for m in models}
    free = []
    if "material" in laws:
        free += [s.name for s in MATERIAL]
    if "rates" in laws:
        free += ["k_lin", "k_mid"]
    free.append("mu_d")
    real = [m for m, g in zip(models, geoms) if g.backbone == "section"]
    if "material" in laws and any(g.backbone == "section" and _cut_governs(g) for g in geoms):
        free.insert(free.index("mu_d"), "strain_ratio")
    if real:
        free.append(REST)
    if any(m.spring_law == "material" for m in real):
        free.append(DEPTH)
    return tuple(free)


def _cut_governs(geom, *, ratio: float = ASYMMETRY_MIN_RATIO) -> bool:
    """Whether a notch of ``geom`` leaves its cut face at least ``ratio`` times farther from the neutral axis
    than its back (where the plateau's onset in compression, ``strain_ratio``, can act)."""
    if geom.inner_radius is None:
        return False
    sec = geom.section
    return bool(np.any(sec.cut_fibre >= ratio * sec.back_fibre))


def base_model(geom) -> FrictionParams:
    """The model identify starts from without ``--model``: :func:`notchfit.physics.friction.default_params`
    (for a real tube the material law at the damping time
    :data:`notchfit.physics.friction.QUASI_STATIC_DAMPING_TIME`)."""
    return default_params(geom)


def specs_for(free, models, *, start: FrictionParams | None = None) -> tuple[ParamSpec, ...]:
    """The specs of the scalar free parameters (the per-tube ``rest_angle``, ``slot_depth`` left out), in order.

    ``μ_d`` starts at the capstan value (0.1) when every tube has the capstan
    law, else at the paper's 0.29. ``start`` (a ``--model`` file) moves each
    start to its value, clipped into the bounds.

    Raises
    ------
    ValueError
        A parameter of a spring law no tube uses (it would have no effect).
    """
    capstan = all(m.friction_law == "capstan" for m in models)
    laws = {m.spring_law for m in models}
    out = []
    for name in free:
        need = _LAW_OF.get(name)
        if need is not None and need not in laws:
            raise ValueError(f"--free {name}: no tube of this study uses spring_law = {need!r} "
                             f"(they use {', '.join(sorted(laws))}), so {name} has no effect")
        if name in (REST, DEPTH):
            continue
        spec = CAPSTAN_MU if (name == "mu_d" and capstan) else SPECS[name]
        if start is not None:
            v = min(max(float(getattr(start, name)), spec.lower), spec.upper)
            spec = dataclasses.replace(spec, start=v)
        out.append(spec)
    return tuple(out)
