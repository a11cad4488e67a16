"""Recipes of synthetic studies (``datasets/recipes/*.toml``): what a study holds and how it is drawn.

A recipe describes a study the way a lab would run it (several paper-like
bend/unbend tests, Sec. IV, Fig. 11) and the hidden truth that produced it:
the ranges of the base model parameters, the hidden effects (none, one or
several cause ids of docs/data-formats.md, each with the fields of one of
its laws, :data:`EFFECT_LAWS`, and their sizes), the measurement noise, the
plane transform, what is measured (notch points, joint angles or both) and
the protocol of every experiment (the drive's ramp time and whether
experiment.toml records it). :func:`load_recipe` reads one (shipped by name,
or a TOML path); :mod:`notchfit.studies.synth` draws and writes the study.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..analysis.causes import REGISTRY
from ..physics.friction import FrictionParams
from ..io import TomlError, datasets_dir, load_toml
from ..paper import FRICTION_K_LIN, FRICTION_K_MID, MU_D, MU_S
from ..physics.protocols import bend_unbend

__all__ = [
    "CAUSES",
    "EFFECT_ALIASES",
    "EFFECT_FIELDS",
    "EFFECT_LAWS",
    "OBSERVATIONS",
    "PAPER_VALUES",
    "TENSION_RESOLUTION",
    "ProtocolSpec",
    "Recipe",
    "bend_unbend_protocol",
    "combine_recipes",
    "list_recipes",
    "load_recipe",
    "recipe_from_dict",
]

#: Cause ids of docs/data-formats.md and the recipe/truth fields of each law that can produce the
#: effect (the first is the cause's default): :attr:`notchfit.analysis.causes.Cause.laws`.
EFFECT_LAWS = {"none": ((),), **{c.id: c.laws for c in REGISTRY.values()}}
#: Each cause's default law's fields.
EFFECT_FIELDS = {c: laws[0] for c, laws in EFFECT_LAWS.items()}
CAUSES = tuple(c for c in EFFECT_FIELDS if c != "none")
#: Effect fields that are :class:`notchfit.physics.friction.FrictionParams` fields of the truth.
_MODEL_EFFECTS = tuple(dict.fromkeys(k for laws in EFFECT_LAWS.values() for law in laws for k in law
                                    if k in {f.name for f in dataclasses.fields(FrictionParams)}))
_BASE_FIELDS = ("k_lin", "k_mid", "mu_d", "E_lin", "E_se", "strain_lower")
#: Old names of effect fields, still read (recipe files and :meth:`Recipe.replace`).
EFFECT_ALIASES = {"static_excess": "mu_s_excess"}
#: The paper's values of the drawn base parameters (Sec. IV-B, docs/models.md).
PAPER_VALUES = {"k_lin": FRICTION_K_LIN, "k_mid": FRICTION_K_MID, "mu_d": MU_D}
#: What drawn base parameters are kept away from: the paper's values, notchfit's material defaults.
_REFERENCE_VALUES = {**PAPER_VALUES, **{k: getattr(FrictionParams(), k) for k in ("E_lin", "E_se", "strain_lower")}}
#: The paper's μ_s − μ_d (0.30 − 0.29), rounded off the float subtraction's last bits.
_PAPER_MU_S_EXCESS = round(MU_S - MU_D, 12)
#: What a synthetic experiment measures: notch points, joint angles (``angles.csv``), or both.
OBSERVATIONS = ("points", "angles", "both")
#: Resolution of the tensions in ``samples.csv`` [N] (four decimals): the drive's set-points are
#: drawn on this grid, so that the file holds the true tensions exactly when the load cells are
#: noise-free and a simulation from the file reproduces the truth to solver precision.
TENSION_RESOLUTION = 1e-4


# ----------------------------------------------------------------------------- recipe
@dataclass(frozen=True)
class ProtocolSpec:
    """One bend/unbend test (Sec. IV, Fig. 11).

    Attributes
    ----------
    name : str
    pull : {"left", "right"}
        The cable ramped up and down.
    counter_N : float
        Constant tension on the other cable, also the start and end tension of
        the pulled one [N].
    peak_N : float or (lo, hi)
        Peak tension of the pulled cable [N] (a range is drawn per experiment).
    n_up, n_down : int
        Samples on the loading and the unloading ramp (n_up + n_down + 1 in all);
        ``n_down = 0``: a loading-only trial.
    dt_s : float
        Time between samples [s].
    geometry : str, optional
        This experiment's geometry (a tube of the same stock), in place of the
        recipe's: a shipped geometry name or a path.
    """

    name: str
    pull: str
    counter_N: float
    peak_N: float | tuple = (20.0, 32.0)
    n_up: int = 18
    n_down: int = 22
    dt_s: float = 5.0
    geometry: str | None = None

    def __post_init__(self):
        if self.pull not in ("left", "right"):
            raise ValueError(f"experiment {self.name!r}: pull must be 'left' or 'right', got {self.pull!r}")
        if not (self.counter_N >= 0):
            raise ValueError(f"experiment {self.name!r}: counter_N must be >= 0")
        if self.n_up < 1 or self.n_down < 0:
            raise ValueError(f"experiment {self.name!r}: n_up must be >= 1 and n_down >= 0 (0: loading only)")
        if not self.dt_s > 0:
            raise ValueError(f"experiment {self.name!r}: dt_s must be > 0")


@dataclass(frozen=True)
class Recipe:
    """A synthetic study (see the module docstring and ``datasets/recipes/``).

    Ranges are ``(lo, hi)`` tuples drawn uniformly; a range with ``lo == hi``
    is a fixed value.
    """

    name: str
    description: str = ""
    seed: int = 0
    geometry: str = "default"
    cause: str = "none"
    base: dict = field(default_factory=lambda: {"k_lin": (0.40, 0.58), "k_mid": (0.18, 0.32),
                                                 "mu_d": (0.22, 0.36)})
    min_rel_offset: float = 0.05
    fixed: dict = field(default_factory=dict)
    effect: dict = field(default_factory=dict)
    random_sign: tuple = ()
    warp_center_mm: tuple = ((-3.0, 3.0), (8.0, 20.0))
    warp_radius_mm: float = 10.0
    warp_distance_mm: float = 250.0
    point_sigma_mm: float = 0.02
    tension_sigma_N: float = 0.11
    displacement_step_mm: float = 0.0079
    missing_points: float = 0.0
    plane_tx_mm: tuple = (-5.0, 5.0)
    plane_ty_mm: tuple = (-5.0, 5.0)
    plane_phi_deg: tuple = (-20.0, 20.0)
    mirror: bool = False
    experiments: tuple = ()
    images: bool = False
    image_options: dict = field(default_factory=dict)
    observe: str = "points"
    angle_sigma_deg: float = 0.5
    ramp_time_s: float = 0.0
    record_protocol: bool = False

    @property
    def causes(self) -> tuple:
        """The hidden causes (empty for ``"none"``)."""
        c = (self.cause,) if isinstance(self.cause, str) else tuple(self.cause)
        return tuple(x for x in c if x != "none")

    @property
    def effect_order(self) -> tuple:
        """The effect fields in the order they are drawn: each cause's law, in cause order."""
        return tuple(k for c in self.causes for k in _law_of(c, self.effect))

    def replace(self, **changes) -> "Recipe":
        """A copy with fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def scaled(self, *, n_experiments: int | None = None, n_up: int | None = None,
               n_down: int | None = None) -> "Recipe":
        """A smaller study: the first ``n_experiments`` (alternating pull directions kept
        by taking them in recipe order) with fewer samples per ramp."""
        exps = list(self.experiments)
        if n_experiments is not None:
            exps = exps[:n_experiments]
        exps = [dataclasses.replace(e, n_up=e.n_up if n_up is None else n_up,
                                    n_down=e.n_down if n_down is None else n_down) for e in exps]
        return self.replace(experiments=tuple(exps))

    def __post_init__(self):
        object.__setattr__(self, "effect", {EFFECT_ALIASES.get(k, k): v for k, v in self.effect.items()})
        object.__setattr__(self, "random_sign", tuple(EFFECT_ALIASES.get(k, k) for k in self.random_sign))
        if not isinstance(self.cause, str):
            object.__setattr__(self, "cause", tuple(self.cause) if len(self.cause) != 1 else self.cause[0])
        _check_causes(self)
        allowed = self.effect_order
        for k in self.random_sign:
            if k not in allowed:
                raise ValueError(f"recipe {self.name!r}: random_sign names {k!r}, not an effect field")
        for d, what in ((self.base, "base"), (self.effect, "effect")):
            object.__setattr__(self, what, {k: _range(v, f"{what}.{k}") for k, v in d.items()})
        for k in self.base:
            if k not in _BASE_FIELDS:
                raise ValueError(f"recipe {self.name!r}: base ranges are for {', '.join(_BASE_FIELDS)}, "
                                 f"got {k!r}")
        for f in ("plane_tx_mm", "plane_ty_mm", "plane_phi_deg"):
            object.__setattr__(self, f, _range(getattr(self, f), f))
        object.__setattr__(self, "warp_center_mm",
                           tuple(_range(r, "warp center") for r in self.warp_center_mm))
        if not (math.isfinite(self.warp_distance_mm) and self.warp_distance_mm > 0):
            raise ValueError(f"recipe {self.name!r}: the camera's distance_mm must be a number > 0")
        if not self.experiments:
            raise ValueError(f"recipe {self.name!r}: no experiments")
        names = [e.name for e in self.experiments]
        if len(set(names)) != len(names):
            raise ValueError(f"recipe {self.name!r}: experiment names must be unique")
        if self.point_sigma_mm < 0 or self.tension_sigma_N < 0:
            raise ValueError(f"recipe {self.name!r}: noise levels must be >= 0")
        if not 0 <= self.missing_points < 1:
            raise ValueError(f"recipe {self.name!r}: missing_points must be in [0, 1)")
        if self.observe not in OBSERVATIONS:
            raise ValueError(f"recipe {self.name!r}: observe must be one of {', '.join(OBSERVATIONS)}, "
                             f"got {self.observe!r}")
        if not (self.angle_sigma_deg >= 0 and math.isfinite(self.angle_sigma_deg)):
            raise ValueError(f"recipe {self.name!r}: angle noise must be a finite number >= 0")
        if self.images and any(e.geometry not in (None, self.geometry) for e in self.experiments):
            raise ValueError(f"recipe {self.name!r}: rendered images need one geometry for the whole study")
        if not (math.isfinite(self.ramp_time_s) and self.ramp_time_s >= 0):
            raise ValueError(f"recipe {self.name!r}: [protocol] ramp_time_s must be a number >= 0")
        if self.observe == "angles" and (self.images or "calibration_error" in self.causes):
            raise ValueError(f"recipe {self.name!r}: rendered images and a calibration error act on notch "
                             "points: they need observe = 'points' or 'both'")


def _law_of(cause: str, effect: dict) -> tuple:
    """The fields of the law of ``cause`` that ``effect`` gives (the largest that fits), or ()."""
    fits = [law for law in EFFECT_LAWS[cause] if set(law) <= set(effect)]
    return max(fits, key=len) if fits else ()


def _check_causes(r: Recipe) -> None:
    """The causes are known ids, each at most once, and the effect fields are exactly one law of each."""
    names = (r.cause,) if isinstance(r.cause, str) else r.cause
    bad = [c for c in names if c not in EFFECT_LAWS]
    if bad or not names or (len(names) > 1 and "none" in names) or len(set(names)) != len(names):
        raise ValueError(f"recipe {r.name!r}: cause must be one of {', '.join(EFFECT_LAWS)} or a list of "
                         f"distinct causes, got {r.cause!r}")
    used = set()
    for c in r.causes:
        law = _law_of(c, r.effect)
        if not law:
            alts = " or ".join("+".join(a) for a in EFFECT_LAWS[c])
            raise ValueError(f"recipe {r.name!r}: cause {c!r} needs effect range(s) {alts}")
        used |= set(law)
    extra = [k for k in r.effect if k not in used]
    if extra:
        raise ValueError(f"recipe {r.name!r}: effect field(s) {', '.join(extra)} do not belong to "
                         f"cause {r.cause!r} (expected {', '.join(sorted(used)) or 'none'})")


def combine_recipes(*recipes: Recipe, name: str | None = None) -> Recipe:
    """A study hiding every effect of ``recipes`` at once (each a one-cause recipe).

    The first recipe gives the study (base ranges, noise, plane, experiments,
    protocol); the others add their causes, effect ranges, random signs and
    (calibration_error) the warp's centre, radius and camera distance.
    """
    first = recipes[0]
    causes, effect, signs = [], {}, []
    warp = {}
    for r in recipes:
        causes += list(r.causes)
        effect.update(r.effect)
        signs += list(r.random_sign)
        if "calibration_error" in r.causes:
            warp = {"warp_center_mm": r.warp_center_mm, "warp_radius_mm": r.warp_radius_mm,
                    "warp_distance_mm": r.warp_distance_mm}
    return first.replace(name=name or "+".join(r.name for r in recipes), cause=tuple(causes), effect=effect,
                         random_sign=tuple(signs), description="; ".join(r.description for r in recipes), **warp)


def _range(v, what) -> tuple:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return (float(v), float(v))
    try:
        lo, hi = (float(x) for x in v)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected a number or a [lo, hi] range, got {v!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ValueError(f"{what}: expected finite lo <= hi, got {v!r}")
    return (lo, hi)


_RECIPE_KEYS = {"name", "description", "seed", "geometry", "cause", "causes", "base", "min_rel_offset", "fixed",
                "effect", "noise", "plane", "protocol", "experiments", "images", "observe"}


def recipe_from_dict(d: dict, origin: str = "<recipe>") -> Recipe:
    """Build a :class:`Recipe` from the TOML layout of ``datasets/recipes/``."""
    unknown = sorted(set(d) - _RECIPE_KEYS)
    if unknown:
        raise ValueError(f"{origin}: unknown key(s) {', '.join(unknown)} "
                         f"(known: {', '.join(sorted(_RECIPE_KEYS))})")
    kw = {k: d[k] for k in ("name", "description", "seed", "geometry", "cause", "min_rel_offset", "observe")
          if k in d}
    if "causes" in d:
        if "cause" in d:
            raise ValueError(f"{origin}: give cause or causes, not both")
        kw["cause"] = d["causes"]
    kw.setdefault("name", Path(origin).stem)
    if "base" in d:
        kw["base"] = dict(d["base"])
    if "fixed" in d:
        kw["fixed"] = dict(d["fixed"])
    eff = dict(d.get("effect", {}))
    kw["random_sign"] = tuple(eff.pop("random_sign", ()))
    c = eff.pop("center_mm", None)
    if c is not None:
        kw["warp_center_mm"] = tuple(c)
    r = eff.pop("radius_mm", None)
    if r is not None:
        kw["warp_radius_mm"] = float(r)
    dist = eff.pop("distance_mm", None)
    if dist is not None:
        kw["warp_distance_mm"] = float(dist)
    kw["effect"] = eff
    noise = dict(d.get("noise", {}))
    for src, dst in (("point_mm", "point_sigma_mm"), ("tension_N", "tension_sigma_N"),
                     ("displacement_step_mm", "displacement_step_mm"), ("missing_points", "missing_points"),
                     ("angle_deg", "angle_sigma_deg")):
        if src in noise:
            kw[dst] = float(noise.pop(src))
    if noise:
        raise ValueError(f"{origin}: unknown [noise] key(s) {', '.join(noise)}")
    plane = dict(d.get("plane", {}))
    for src in ("tx_mm", "ty_mm", "phi_deg"):
        if src in plane:
            kw[f"plane_{src}"] = plane.pop(src)
    if "mirror" in plane:
        kw["mirror"] = bool(plane.pop("mirror"))
    if plane:
        raise ValueError(f"{origin}: unknown [plane] key(s) {', '.join(plane)}")
    proto = dict(d.get("protocol", {}))
    if "ramp_time_s" in proto:
        kw["ramp_time_s"] = float(proto.pop("ramp_time_s"))
    if "record" in proto:
        kw["record_protocol"] = bool(proto.pop("record"))
    pkeys = {"peak_N", "n_up", "n_down", "dt_s", "counter_N", "pull"}
    bad = set(proto) - pkeys
    if bad:
        raise ValueError(f"{origin}: unknown [protocol] key(s) {', '.join(sorted(bad))}")
    exps = []
    for i, e in enumerate(d.get("experiments", [])):
        spec = {**proto, **e}
        bad = set(spec) - pkeys - {"name", "geometry"}
        if bad:
            raise ValueError(f"{origin}: experiment {i + 1}: unknown key(s) {', '.join(sorted(bad))}")
        if "name" not in spec or "pull" not in spec or "counter_N" not in spec:
            raise ValueError(f"{origin}: experiment {i + 1} needs name, pull and counter_N")
        pk = spec.get("peak_N", (20.0, 32.0))
        spec["peak_N"] = _range(pk, f"experiment {spec['name']} peak_N")
        exps.append(ProtocolSpec(**spec))
    kw["experiments"] = tuple(exps)
    img = dict(d.get("images", {}))
    kw["images"] = bool(img.pop("render", False))
    kw["image_options"] = img
    try:
        return Recipe(**kw)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{origin}: {exc}") from None


def list_recipes() -> list[str]:
    """Names of the recipes shipped in ``datasets/recipes/``."""
    return sorted(p.stem for p in (datasets_dir() / "recipes").glob("*.toml"))


def load_recipe(source) -> Recipe:
    """A recipe from a TOML path, or a shipped recipe by name (``"paper8"``, ``"proximal_friction"``).

    Raises
    ------
    FileNotFoundError
        No such file and no shipped recipe of that name (the message lists them).
    TomlError
        Bad TOML (with its line) or a recipe problem, naming the file.
    """
    p = Path(source)
    if not p.is_file():
        cand = datasets_dir() / "recipes" / f"{source}.toml"
        if cand.is_file():
            p = cand
        else:
            raise FileNotFoundError(f"{source}: recipe not found (a TOML path, or one of "
                                    f"{', '.join(list_recipes())})")
    doc = load_toml(p, what="recipe")
    try:
        return recipe_from_dict(doc.data, origin=str(p))
    except ValueError as exc:
        raise TomlError(str(exc)) from None


# ----------------------------------------------------------------------------- protocol
def bend_unbend_protocol(pull: str, counter_N: float, peak_N: float, n_up: int, n_down: int,
                         dt_s: float = 5.0):
    """Tension history of one bend/unbend test (Fig. 11), via :func:`notchfit.physics.protocols.bend_unbend`.

    The pulled cable starts at the counter-tension, is ramped in ``n_up``
    equal steps to ``peak_N`` and back down in ``n_down`` equal steps; the
    other cable holds ``counter_N``. Samples are ``dt_s`` apart, starting at
    ``t = dt_s`` (the manipulator starts at rest, untensioned, at t = 0).

    Returns
    -------
    time : ndarray (S,) [s]
    tension_left, tension_right : ndarray (S,) [N]
        With ``S = n_up + n_down + 1``.
    """
    # protocols counts the loading samples including start and peak: n_up steps = n_up + 1 samples
    p = bend_unbend(peak_N, counter_N, pull=pull, n_up=n_up + 1, n_down=n_down, interval=dt_s, t0=dt_s)
    return p.time, p.tension_left, p.tension_right


def _protocol(spec: ProtocolSpec, peak: float):
    """The test's true tensions, on the file's grid (:data:`TENSION_RESOLUTION`)."""
    time, tl, tr = bend_unbend_protocol(spec.pull, spec.counter_N, peak, spec.n_up, spec.n_down, spec.dt_s)
    return time, _on_file_grid(tl), _on_file_grid(tr)


def _on_file_grid(tension) -> np.ndarray:
    """Tensions rounded to the four decimals of ``samples.csv`` (:data:`TENSION_RESOLUTION`)."""
    return np.round(np.asarray(tension, dtype=float), 4)
