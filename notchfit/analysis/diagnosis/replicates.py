"""Lack of fit first: the held-out error against the trials' own scatter.

Where trials repeat (one tube driven through the same tensions, in the same
direction of loading, in several trials), the trial-to-trial scatter is an
error no model can remove; the classical decomposition into pure error and lack
of fit (:mod:`notchfit.analysis.lack_of_fit`, Draper & Smith 1998, Sec. 2.1)
tests whether the model misses something beyond it. The diagnosis applies it to
held-out predictions (no parameter fitted to the predicted trial: ``n_params = 0``),
so that ``unexplained`` means a significant lack of fit that no candidate removes;
a baseline within the scatter of repeated trials is ``none`` even where the
noise floor (the load-cell noise pushed through the model) is smaller than that
scatter.

A significant lack of fit must also be material (:func:`lack_of_fit_material`):
larger, per measured point or angle, than the excess over the noise floor that
the decision's ``none`` rule tolerates (``none_tol`` times the floor). With
hundreds of replicated values a lack of fit of a few micrometres is significant;
where it is that small, the held-out excess over the floor lies in the
trials' scatter or in samples no other trial repeats. Such a sample is where
one held-out error can outweigh all the others: on the steep start of a
superelastic plateau the load-cell noise alone moves a wrist's tip tenfold
(``wrist_asymmetric`` as notch points, seed 1: the true model errs by 0.22 mm at
the first unloading step of the middle trial), and so does any error of the
plateau's stress that the other trials leave (a fold fitted on the lightest and
the heaviest trial, which cross the plateau's start in one or two samples each,
put it 8 % low and erred by 0.42 mm there, with μ_d fitted or held at zero),
while the replicated samples showed a lack of fit of 0.005 mm against a floor of
0.026 mm.

Replicates are samples of different trials of one tube, pulled by the same
tendon against the same counter-tension in the same direction of loading, whose
pulled tensions agree within ``tol_sigma`` times the load cells' σ (within the
load-cell noise the inputs cannot be told apart).
Their tensions still differ a little, and on a steep part of the curve so do their
true shapes; the decomposition is therefore made on the residuals (measured minus
predicted): the pure error is the scatter of a group's residuals, which the
model's own prediction of those small differences does not inflate, and the lack
of fit is the groups' mean residuals (near replicates, Draper & Smith 1998, Sec. 2.1).
"""

from __future__ import annotations

import numpy as np

from ...physics.notches import from_plane
from ...units import DEG, MM
from ..lack_of_fit import LackOfFit, lack_of_fit_table, loading_direction, replicate_groups

__all__ = ["heldout_lack_of_fit", "lack_of_fit_first", "lack_of_fit_material", "lack_of_fit_mse"]


def _responses(p, values) -> np.ndarray:
    """One experiment's values (S, k): joint angles, or notch points in the manipulator frame (each trial
    registered by its own plane transform, so that the trials' points compare), NaN where not measured."""
    S = p.time.size
    v = np.asarray(values, dtype=float)
    if p.metric == "points":
        T = p.transform
        v = np.where(p.valid[..., None], from_plane(v, T.tx, T.ty, T.phi, T.mirror), np.nan)
    else:
        v = np.where(p.valid, v, np.nan)
    return v.reshape(S, -1)


def _counter_classes(preps, tol: float) -> list:
    """A label per experiment: experiments whose counter-tensions [N] agree within ``tol`` (chained in
    sorted order) share it."""
    c = np.array([float(p.counter_tension) for p in preps])
    order = np.argsort(c, kind="stable")
    labels, k = np.empty(c.size, int), 0
    for j, i in enumerate(order):
        if j and c[i] - c[order[j - 1]] > tol:
            k += 1
        labels[i] = k
    return labels.tolist()


def _stack(preps, predicted: dict, tol: float):
    """Measured and predicted responses (N, k) of every sample (NaN where not measured or where a tube has
    fewer notches), the trial, condition and pulled tension of each."""
    ys = [_responses(p, p.measured) for p in preps]
    yh = [_responses(p, predicted[i]) for i, p in enumerate(preps)]
    k = max(y.shape[1] for y in ys)
    pad = lambda a: np.pad(a, ((0, 0), (0, k - a.shape[1])), constant_values=np.nan)  # noqa: E731
    trial, cond, force = [], [], []
    for p, counter in zip(preps, _counter_classes(preps, tol)):
        t = np.asarray(p.pulled_tension, dtype=float)
        trial += [p.name] * t.size
        cond += [f"{p.tube}/{p.pulled}/{counter}/{d}" for d in loading_direction(t, tol=p.tension_sigma)]
        force.append(t)
    return (np.vstack([pad(y) for y in ys]), np.vstack([pad(y) for y in yh]), np.array(trial), np.array(cond),
            np.concatenate(force))


def heldout_lack_of_fit(preps, predicted: dict, *, tol_sigma: float = 3.0, alpha: float = 0.05,
                        n_ranges: int = 3) -> LackOfFit:
    """Pure error and lack of fit of held-out predictions, in the metric's file unit (degrees or mm).

    Parameters
    ----------
    preps : sequence of Observations
    predicted : dict
        Experiment index -> held-out predicted measurements (:attr:`HeldOut.predicted`).
    tol_sigma : float
        Replicate tensions agree within this many load-cell σ (module docstring).
    alpha : float
        Significance level of the lack-of-fit test.
    n_ranges : int
        Force ranges of the table.

    Returns
    -------
    LackOfFit
        Per response: a joint angle (joint ``j`` of every tube), or a notch point's coordinate in the
        manipulator frame.
    """
    sigma = max(float(np.max([p.tension_sigma for p in preps])), 1e-9)
    y, yhat, trial, cond, force = _stack(preps, predicted, tol_sigma * sigma)
    resid = y - yhat
    groups = replicate_groups(trial, cond, force, tol=tol_sigma * sigma)
    angles = preps[0].metric == "angles"
    return lack_of_fit_table(resid, np.where(np.isfinite(resid), 0.0, np.nan), groups, force, n_params=0, unit="deg" if angles else "mm",
                             scale=1.0 / (DEG if angles else MM), n_ranges=n_ranges, alpha=alpha,
                             response_labels=None if angles else
                             [f"notch {j // 2 + 1} {'xz'[j % 2]}" for j in range(y.shape[1])])


def lack_of_fit_mse(lof: LackOfFit, point_factor: float) -> float:
    """The lack of fit beyond the trials' scatter as a mean squared error per measured point or angle
    [m² or rad²]: ``point_factor`` (2 for a point's two coordinates, 1 for an angle) times the square of
    its rms per response value (reported in the file unit, mm or degrees)."""
    unit = MM if lof.unit == "mm" else DEG
    return point_factor * (lof.overall.lack_of_fit_rms * unit) ** 2


def lack_of_fit_material(lof: LackOfFit, noise: float, point_factor: float, *, none_tol: float = 0.5) -> bool:
    """Whether a held-out lack of fit shows a model error: significant at the table's level against the
    trials' scatter, and larger than ``none_tol`` times the noise floor (module docstring).

    Parameters
    ----------
    lof : LackOfFit
        Of the held-out baseline (:func:`heldout_lack_of_fit`), with replicates.
    noise : float
        The noise floor [m² or rad²] (mean squared error of a perfect model per point or angle).
    point_factor : float
        2 for notch points, 1 for joint angles (``Observations.point_factor``).
    none_tol : float
        The excess over the floor the decision's ``none`` rule tolerates, as a fraction of the floor.
    """
    return lof.overall.significant(lof.alpha) and lack_of_fit_mse(lof, point_factor) > none_tol * noise


def lack_of_fit_first(cause: str, lof: LackOfFit, noise: float, point_factor: float, *,
                      none_tol: float = 0.5) -> str:
    """The verdict with the trials' scatter: ``unexplained`` becomes ``none`` where trials repeat and the
    held-out lack of fit beyond their scatter is not material (:func:`lack_of_fit_material`)."""
    if cause == "unexplained" and lof.has_replicates and not lack_of_fit_material(lof, noise, point_factor,
                                                                                   none_tol=none_tol):
        return "none"
    return cause
