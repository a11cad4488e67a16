"""The measured experiments of an identification: inputs, observations, tubes.

Each experiment is reduced once to what the least-squares problem needs
(:class:`Observed`): its geometry and tube label, the measured tension history
(load-cell readings clipped at zero), and its observations — measured joint
angles (metric ``"deg"``) or notch points registered in the plane (metric
``"mm"``, the diagnosis's registration: the free-θ fit of the points alone,
:func:`notchfit.diagnosis.prepare_experiment`). Experiments that share a
geometry are one *tube*: they share its rest angles; every tube of a study
shares the material parameters (tubes cut from one stock).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..diagnosis import prepare_experiment
from ..fitting.angles import DEFAULT_ANGLE_SIGMA
from ..friction import LOAD_CELL_SIGMA
from ..units import UNIT_SIZE

__all__ = ["METRICS", "Observed", "metric_unit", "observe_study", "study_metric", "tube_labels",
           "zero_tension_samples"]

#: What an identification compares: measured joint angles [deg], or notch points [mm].
METRICS = ("deg", "mm")


@dataclass(frozen=True, eq=False)
class Observed:
    """One experiment ready for identification (S samples, n joints, m points).

    Attributes
    ----------
    name : str
    tube : str
        Label of its geometry in the study (:func:`tube_labels`).
    geom : Geometry
    time, tension_left, tension_right : ndarray (S,) [s, N, N]
        The measured history (readings clipped at zero; zeros for a missing tendon).
    ramp_time : float [s]
        ``[protocol] ramp_time_s`` (0: a step).
    tension_sigma : float [N]
        Load-cell uncertainty (0.05 N when the experiment gives none).
    metric : {"deg", "mm"}
    angles : ndarray (S, n) [rad] or None
        Measured joint angles (NaN = not measured) — metric "deg".
    sigma : float
        Uncertainty of one observation [rad] or of one point coordinate [m] (weights).
    points, valid, transform :
        Measured plane-frame points (S, m, 2) [m], which are finite (S, m), and the
        registration (PlaneTransform) — metric "mm".
    shape_angles : ndarray (S, n) [rad]
        Measured joint angles, or the free-θ fit of the points: what the rest
        angles start from.
    """

    name: str
    tube: str
    geom: object
    time: np.ndarray = field(repr=False)
    tension_left: np.ndarray = field(repr=False)
    tension_right: np.ndarray = field(repr=False)
    ramp_time: float
    tension_sigma: float
    metric: str
    angles: np.ndarray | None = field(default=None, repr=False)
    sigma: float = DEFAULT_ANGLE_SIGMA
    points: np.ndarray | None = field(default=None, repr=False)
    valid: np.ndarray | None = field(default=None, repr=False)
    transform: object = None
    shape_angles: np.ndarray | None = field(default=None, repr=False)

    @property
    def n_values(self) -> int:
        """Measured angles, or measured points."""
        return int(np.isfinite(self.angles).sum()) if self.metric == "deg" else int(self.valid.sum())

    @property
    def tendon_tensions(self) -> tuple:
        """``(left, right)`` for :func:`notchfit.friction.simulate`: None for a tendon the tube lacks."""
        return (self.tension_left if "left" in self.geom.tendons else None,
                self.tension_right if "right" in self.geom.tendons else None)


def study_metric(exps) -> str:
    """``"deg"`` when every experiment has measured angles, ``"mm"`` when every one has points.

    Raises
    ------
    ValueError
        A study that mixes experiments with only angles and only points (one metric per identification).
    """
    if all(e.angles is not None for e in exps):
        return "deg"
    if all(e.points is not None for e in exps):
        return "mm"
    ang = [e.name for e in exps if e.points is None]
    pts = [e.name for e in exps if e.angles is None]
    raise ValueError(f"identify compares one kind of measurement per study: {', '.join(ang)} have only joint "
                     f"angles (angles.csv), {', '.join(pts)} only notch points; identify them apart")


def tube_labels(geoms) -> list[str]:
    """A label per geometry: its name, made unique (``name-2``, ...) among the distinct geometries."""
    label_of: dict = {}
    count: dict = {}
    for g in geoms:
        if g not in label_of:
            k = count[g.name] = count.get(g.name, 0) + 1
            label_of[g] = g.name if k == 1 else f"{g.name}-{k}"
    return [label_of[g] for g in geoms]


def _observed(exp, tube: str, metric: str) -> Observed:
    kw = dict(name=exp.name, tube=tube, geom=exp.geometry, time=np.asarray(exp.time, float),
              tension_left=np.asarray(exp.tension_left, float), tension_right=np.asarray(exp.tension_right, float),
              ramp_time=float(exp.ramp_time or 0.0),
              tension_sigma=float(exp.tension_sigma) if exp.tension_sigma else LOAD_CELL_SIGMA, metric=metric)
    if metric == "deg":
        ang = np.asarray(exp.angles, dtype=float)
        if not np.isfinite(ang).any():
            raise ValueError(f"{exp.path}: experiment {exp.name} has no measured angle in angles.csv")
        return Observed(**kw, angles=ang, sigma=float(exp.angle_sigma or DEFAULT_ANGLE_SIGMA), shape_angles=ang)
    prep = prepare_experiment(exp)
    return Observed(**kw, sigma=prep.sigma, points=prep.measured, valid=prep.valid, transform=prep.transform,
                    shape_angles=prep.theta_free)


def observe_study(exps) -> tuple[Observed, ...]:
    """Every experiment of a study as :class:`Observed` (one metric, :func:`study_metric`)."""
    exps = list(exps)
    if not exps:
        raise ValueError("identify needs at least one experiment")
    metric = study_metric(exps)
    tubes = tube_labels([e.geometry for e in exps])
    return tuple(_observed(e, t, metric) for e, t in zip(exps, tubes))


def zero_tension_samples(obs: Observed, *, n_sigma: float = 3.0) -> np.ndarray:
    """Indices of the samples taken at rest before the first load: every tendon within ``n_sigma σ_T`` of zero.

    Only samples before the first one above the threshold count: after a
    load, friction may hold a bend at zero tension.
    """
    thr = n_sigma * obs.tension_sigma
    low = (obs.tension_left <= thr) & (obs.tension_right <= thr)
    if low.all():
        return np.arange(low.size)
    return np.arange(int(np.argmin(low)))


def metric_unit(metric: str) -> float:
    """SI value of the metric's unit: :data:`~notchfit.units.DEG` [rad] or :data:`~notchfit.units.MM` [m]."""
    return UNIT_SIZE["deg" if metric == "deg" else "mm"]
