"""Pure error and lack of fit: does the model or the measurement limit the error?

Where trials repeat (the same tube driven through the same tensions several
times), the trial-to-trial scatter of the measurements is an error no model of
the tube can remove. The classical lack-of-fit decomposition of a regression
with replicates (Draper & Smith, *Applied Regression Analysis*, 3rd ed., 1998,
Sec. 2.1; NIST/SEMATECH e-Handbook of Statistical Methods, Sec. 4.4.4.3)
splits the residual sum of squares of a model's predictions ``ŷ`` into

* the **pure error** ``SS_pe = Σ_g Σ_{i∈g} (y_i − ȳ_g)²`` of the replicate
  groups ``g`` (``N − G`` degrees of freedom: the scatter; for near replicates,
  whose inputs differ within a tolerance, the deviations are taken of the
  residuals ``y_i − ŷ_i`` from their group mean, so that what the model
  predicts for the input's difference is not counted as scatter — for exact
  replicates the two are the same), and
* the **lack of fit** ``SS_lof = Σ_g n_g (ȳ_g − ŷ_g)²`` of the group means
  against the model (``G − p`` degrees of freedom),

and tests ``F = (SS_lof / df_lof) / (SS_pe / df_pe)`` against Fisher's F
distribution. A small p-value says the model misses something the scatter
cannot explain; a large one says the measurement limits the error.

Everything here works on plain arrays of one response per column (joint
angles [rad], or point coordinates [m]) with NaN for a missing observation,
so that ``identify``, ``fit`` and ``diagnose`` share it. The groups come from
:func:`replicate_groups`: samples of different trials of one tube whose
input tensions agree within a tolerance and that were taken in the same
direction of loading (loading and unloading differ by the hysteresis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from ..physics.cables import pulled_side
from ..physics.notches import notch_points
from ..units import DEG, MM

__all__ = ["LackOfFit", "LackOfFitRow", "Trial", "lack_of_fit", "lack_of_fit_summary", "lack_of_fit_table",
           "loading_direction", "replicate_groups", "shape_fit_lack_of_fit", "study_lack_of_fit"]


@dataclass(frozen=True)
class LackOfFitRow:
    """The decomposition for one set of responses (one notch, one force range, or all).

    Attributes
    ----------
    label : str
        What the row covers (``"all"``, ``"joint 3"``, ``"0.0-0.8 N"``, ...).
    n_obs : int
        Observations in replicate groups (groups of one observation carry no pure error and are left out).
    n_groups : int
        Replicate groups with two or more observations.
    df_pe, df_lof : int
        Degrees of freedom of the pure error (``n_obs − n_groups``) and of the lack of fit
        (``n_groups − n_params``, at least 1).
    pure_error_rms : float
        ``sqrt(SS_pe / df_pe)``: the trial-to-trial scatter of one observation [response unit].
    lack_of_fit_rms : float
        The model's error beyond the scatter: ``sqrt(max(0, mean_g((ȳ_g − ŷ_g)² − s²_pe / n_g)))``
        (the part of a group mean's error that its own scatter does not explain) [response unit].
    residual_rms : float
        rms of ``y − ŷ`` over the same observations [response unit].
    F : float
        The lack-of-fit statistic (NaN when the pure error is zero or undefined).
    p_value : float
        ``P(F_{df_lof, df_pe} ≥ F)`` (NaN where ``F`` is).
    """

    label: str
    n_obs: int
    n_groups: int
    df_pe: int
    df_lof: int
    pure_error_rms: float
    lack_of_fit_rms: float
    residual_rms: float
    F: float
    p_value: float

    def significant(self, alpha: float = 0.05) -> bool:
        """Whether the lack of fit is significant at level ``alpha``."""
        return bool(np.isfinite(self.p_value) and self.p_value < alpha)


@dataclass(frozen=True)
class LackOfFit:
    """Pure error and lack of fit of one model on one study, overall and per notch and force range.

    Attributes
    ----------
    overall : LackOfFitRow
        All responses pooled (each response a column with its own group means).
    by_response : tuple of LackOfFitRow
        One row per response column (per notch for joint angles).
    by_range : tuple of LackOfFitRow
        One row per force range (quantile bins of the pulled tension).
    unit : str
        Unit the rms figures are given in (``"deg"``, ``"mm"``); the numbers are
        in that unit (the caller converts before or passes ``scale``).
    alpha : float
        Significance level of :meth:`summary`'s verdicts.
    """

    overall: LackOfFitRow
    by_response: tuple[LackOfFitRow, ...]
    by_range: tuple[LackOfFitRow, ...]
    unit: str
    alpha: float = 0.05

    @property
    def has_replicates(self) -> bool:
        """Whether any replicate group exists (otherwise there is no pure error to compare with)."""
        return self.overall.n_groups > 0 and self.overall.df_pe > 0

    def verdict(self) -> str:
        """One sentence: does the model or the measurement limit the error?"""
        o = self.overall
        if not self.has_replicates:
            return "no repeated trials: the pure error (trial-to-trial scatter) cannot be measured"
        head = (f"trial-to-trial scatter {o.pure_error_rms:.3g} {self.unit}, "
                f"lack of fit beyond it {o.lack_of_fit_rms:.3g} {self.unit} "
                f"(F = {o.F:.3g} on {o.df_lof} and {o.df_pe} df, p = {o.p_value:.2g})")
        if o.significant(self.alpha):
            return head + ": the model, not the measurement, limits the error"
        return head + ": the model is within the measurement's scatter"

    def summary(self) -> str:
        """The decomposition as text: the verdict, then a line per notch and per force range."""
        lines = ["Lack of fit against the trials' scatter", "  " + self.verdict()]
        if not self.has_replicates:
            return "\n".join(lines)
        for title, rows in (("per response", self.by_response), ("per force range", self.by_range)):
            lines.append(f"  {title}:")
            for r in rows:
                mark = " *" if r.significant(self.alpha) else ""
                lines.append(f"    {r.label:>14}: scatter {r.pure_error_rms:.3g}, lack of fit "
                             f"{r.lack_of_fit_rms:.3g} {self.unit}, p = {r.p_value:.2g}{mark}")
        lines.append(f"  (* significant at {self.alpha:g})")
        return "\n".join(lines)

    def as_dict(self) -> dict:
        """A JSON-ready mapping (rows as dicts; NaN stays NaN for the writer to encode)."""
        def row(r: LackOfFitRow) -> dict:
            return {k: getattr(r, k) for k in LackOfFitRow.__dataclass_fields__}
        return {"unit": self.unit, "alpha": self.alpha, "verdict": self.verdict(),
                "overall": row(self.overall), "by_response": [row(r) for r in self.by_response],
                "by_range": [row(r) for r in self.by_range]}


def loading_direction(tension, *, tol: float = 0.0):
    """+1 where a sample's tension rose from the previous one, −1 where it fell, 0 at the first or a tie.

    Parameters
    ----------
    tension : array_like (S,) [N]
        One trial's pulled-tendon tension, in time order.
    tol : float [N]
        Changes within ±tol count as a tie (the load-cell noise).

    Returns
    -------
    ndarray (S,) int
    """
    t = np.asarray(tension, dtype=float)
    d = np.zeros(t.shape, dtype=int)
    step = np.diff(t)
    d[1:] = np.where(step > tol, 1, np.where(step < -tol, -1, 0))
    return d


def replicate_groups(trial, condition, tension, *, tol: float = 0.15, max_width: float | None = None):
    """Label samples that repeat one condition in different trials (replicates).

    Samples are replicates when they share ``condition`` (e.g. the tube and the
    direction of loading), come from different trials, and their tensions
    agree: within one condition the tensions are sorted and split where two
    neighbours differ by more than ``tol``, or where a group would grow wider
    than ``max_width``. A group with members from a single trial only is not
    a replicate group (label −1), nor is a single sample.

    Parameters
    ----------
    trial : array_like (N,)
        Trial (experiment) label of each sample.
    condition : array_like (N,)
        Condition label (hashable values); only samples of one condition can be replicates.
    tension : array_like (N,) [N]
        The input tension of each sample (the pulled tendon's).
    tol : float [N]
        Largest gap between neighbouring tensions within a group (default 0.15 N: three
        times the default load-cell σ of 0.05 N).
    max_width : float [N], optional
        Widest tension span of a group (default ``2 tol``), so that a slow ramp does not chain
        into one group.

    Returns
    -------
    ndarray (N,) int
        Group label ≥ 0 of each replicate, −1 for samples without a replicate.
    """
    trial = np.asarray(trial)
    cond = np.asarray(condition)
    t = np.asarray(tension, dtype=float)
    width = 2.0 * tol if max_width is None else float(max_width)
    labels = np.full(t.shape, -1, dtype=int)
    next_label = 0
    for c in dict.fromkeys(cond.tolist()):
        idx = np.flatnonzero((cond == c) & np.isfinite(t))
        idx = idx[np.argsort(t[idx], kind="stable")]
        start = 0
        for k in range(1, len(idx) + 1):
            if k < len(idx) and t[idx[k]] - t[idx[k - 1]] <= tol and t[idx[k]] - t[idx[start]] <= width:
                continue
            members = idx[start:k]
            if len(members) >= 2 and len(set(trial[members].tolist())) >= 2:
                labels[members] = next_label
                next_label += 1
            start = k
    return labels


def _row(label, y, yhat, groups, n_params) -> LackOfFitRow:
    """The decomposition of responses ``y`` (N, k) against ``yhat`` (N, k), groups (N,)."""
    ss_pe = ss_lof = ss_res = 0.0
    n_obs = n_groups = 0
    excess = []            # (ȳ_g − ŷ_g)² and s²/n_g pairs, for the lack-of-fit rms
    for col in range(y.shape[1]):
        ok = np.isfinite(y[:, col]) & np.isfinite(yhat[:, col]) & (groups >= 0)
        if not ok.any():
            continue
        g, yc, pc = groups[ok], y[ok, col], yhat[ok, col]
        uniq, inv, counts = np.unique(g, return_inverse=True, return_counts=True)
        keep = counts[inv] >= 2
        if not keep.any():
            continue
        g, yc, pc = inv[keep], yc[keep], pc[keep]
        uniq, inv, counts = np.unique(g, return_inverse=True, return_counts=True)
        ybar = np.bincount(inv, yc) / counts
        pbar = np.bincount(inv, pc) / counts
        # the scatter about the group's mean residual: replicates at slightly different inputs differ by
        # what the model predicts for them, which is not scatter (exact replicates: y − ȳ_g itself)
        rc = yc - pc
        ss_pe += float(np.sum((rc - (ybar - pbar)[inv]) ** 2))
        ss_lof += float(np.sum(counts * (ybar - pbar) ** 2))
        ss_res += float(np.sum((yc - pc) ** 2))
        n_obs += len(yc)
        n_groups += len(uniq)
        excess.append(((ybar - pbar) ** 2, counts))
    df_pe = n_obs - n_groups
    df_lof = max(n_groups - n_params, 1)
    nan = float("nan")
    if n_groups == 0 or df_pe <= 0:
        return LackOfFitRow(label, n_obs, n_groups, max(df_pe, 0), df_lof, nan, nan,
                            float(np.sqrt(ss_res / n_obs)) if n_obs else nan, nan, nan)
    s2 = ss_pe / df_pe
    d2 = np.concatenate([e for e, _ in excess])
    n_g = np.concatenate([c for _, c in excess])
    lof_rms = float(np.sqrt(max(0.0, float(np.mean(d2 - s2 / n_g)))))
    if s2 > 0:
        F = (ss_lof / df_lof) / s2
        p = float(stats.f.sf(F, df_lof, df_pe))
    else:
        F = p = nan
    return LackOfFitRow(label, n_obs, n_groups, df_pe, df_lof, float(np.sqrt(s2)), lof_rms,
                        float(np.sqrt(ss_res / n_obs)), float(F), p)


def lack_of_fit(measured, predicted, groups, *, n_params: int = 0, scale: float = 1.0,
                label: str = "all") -> LackOfFitRow:
    """The pure-error / lack-of-fit decomposition of one set of responses.

    Parameters
    ----------
    measured, predicted : array_like (N,) or (N, k)
        Observations and the model's predictions of them (NaN = missing); each
        column is one response with its own group means.
    groups : array_like (N,) int
        Replicate group of each row (:func:`replicate_groups`; −1 = no replicate).
    n_params : int
        Parameters the model fitted to these data (0 for held-out predictions);
        ``df_lof = G − n_params``.
    scale : float
        Multiplies every rms figure (e.g. ``1/DEG`` for radians reported in degrees).
    label : str
        The row's label.

    Returns
    -------
    LackOfFitRow
    """
    y = np.asarray(measured, dtype=float) * scale
    yhat = np.asarray(predicted, dtype=float) * scale
    if y.ndim == 1:
        y, yhat = y[:, None], yhat[:, None]
    if y.shape != yhat.shape:
        raise ValueError(f"measured {y.shape} and predicted {yhat.shape} differ in shape")
    g = np.asarray(groups, dtype=int)
    if g.shape != (y.shape[0],):
        raise ValueError(f"groups must have shape ({y.shape[0]},), got {g.shape}")
    return _row(label, y, yhat, g, n_params)


def lack_of_fit_table(measured, predicted, groups, force, *, n_params: int = 0, unit: str = "",
                      scale: float = 1.0, n_ranges: int = 3, response_labels=None,
                      alpha: float = 0.05) -> LackOfFit:
    """Pure error and lack of fit overall, per response (notch) and per force range.

    Parameters
    ----------
    measured, predicted : array_like (N, k)
        Observations and predictions, one column per response (e.g. joint angles [rad]).
    groups : array_like (N,) int
        Replicate groups (:func:`replicate_groups`).
    force : array_like (N,) [N]
        The pulled tension of each row; the force ranges are its quantile bins.
    n_params : int
        Parameters fitted to these data (0 for held-out predictions). Split evenly over
        the responses for the per-response rows (rounded up).
    unit : str
        Unit of the rms figures after ``scale`` (``"deg"``, ``"mm"``).
    scale : float
        Multiplies every rms figure.
    n_ranges : int
        Number of force ranges (quantile bins of ``force``; fewer where the tensions repeat).
    response_labels : sequence of str, optional
        Label of each response column (default ``"joint 1"``, ...); columns with the same label
        make one row (the two coordinates of a notch point).
    alpha : float
        Significance level of the verdicts.

    Returns
    -------
    LackOfFit
    """
    y = np.atleast_2d(np.asarray(measured, dtype=float).T).T
    yhat = np.atleast_2d(np.asarray(predicted, dtype=float).T).T
    g = np.asarray(groups, dtype=int)
    f = np.asarray(force, dtype=float)
    k = y.shape[1]
    names = list(response_labels) if response_labels is not None else [f"joint {j + 1}" for j in range(k)]
    overall = lack_of_fit(y, yhat, g, n_params=n_params, scale=scale)
    per_col = -(-n_params // k) if k else 0
    cols: dict = {}
    for j, name in enumerate(names):              # columns that share a label are one response (a point's x, y)
        cols.setdefault(name, []).append(j)
    by_resp = tuple(lack_of_fit(y[:, idx], yhat[:, idx], g, n_params=per_col * len(idx), scale=scale, label=name)
                    for name, idx in cols.items())
    finite = f[np.isfinite(f) & (g >= 0)]
    by_range: list[LackOfFitRow] = []
    if finite.size:
        edges = np.unique(np.quantile(finite, np.linspace(0.0, 1.0, n_ranges + 1)))
        # a replicate group belongs to the range of its mean tension, so no group is split
        mean_of = {lab: float(np.nanmean(f[g == lab])) for lab in np.unique(g[g >= 0])}
        group_force = np.array([mean_of.get(lab, np.nan) for lab in g])
        for lo, hi in zip(edges[:-1], edges[1:]):
            upper = group_force <= hi if hi == edges[-1] else group_force < hi
            inside = (g >= 0) & (group_force >= lo) & upper
            if not inside.any():
                continue
            by_range.append(lack_of_fit(y[inside], yhat[inside], g[inside], n_params=0, scale=scale,
                                        label=f"{lo:.2f}-{hi:.2f} N"))
    return LackOfFit(overall, by_resp, tuple(by_range), unit, alpha)


@dataclass(frozen=True)
class Trial:
    """One trial's responses for :func:`study_lack_of_fit`.

    Attributes
    ----------
    name : str
        The trial (experiment).
    tube : str
        Its tube: trials of one tube are compared; each tube gets its own table.
    measured, predicted : ndarray (S, k)
        Observations and the model's predictions, one column per response (NaN = missing).
    tension : ndarray (S,) [N]
        The pulled tendon's tension of each sample (the input the replicates share).
    """

    name: str
    tube: str
    measured: np.ndarray
    predicted: np.ndarray
    tension: np.ndarray


def study_lack_of_fit(trials, *, n_params: int = 0, params_per_group: int = 0, unit: str = "",
                      scale: float = 1.0, tol: float = 0.15, n_ranges: int = 3, response_labels=None,
                      alpha: float = 0.05) -> dict:
    """Pure error and lack of fit of a study, one :class:`LackOfFit` per tube.

    Replicates are samples of different trials of one tube taken in the same direction of loading
    (:func:`loading_direction`) at tensions within ``tol`` (:func:`replicate_groups`).

    Parameters
    ----------
    trials : iterable of Trial
    n_params : int
        Parameters fitted to a tube's data (shared and per-tube; 0 for held-out predictions).
    params_per_group : int
        Parameters fitted per replicate group in addition (a shape model fitted sample by sample).
    unit, scale, n_ranges, alpha :
        As :func:`lack_of_fit_table`.
    tol : float [N]
        Tension tolerance of a replicate (:func:`replicate_groups`).
    response_labels : sequence of str, optional
        Label of each response column (default ``"joint 1"``, ...).

    Returns
    -------
    dict
        Tube -> LackOfFit, in the order the tubes first appear.
    """
    by_tube: dict = {}
    for t in trials:
        by_tube.setdefault(t.tube, []).append(t)
    out = {}
    for tube, ts in by_tube.items():
        y = np.vstack([np.asarray(t.measured, float) for t in ts])
        yhat = np.vstack([np.asarray(t.predicted, float) for t in ts])
        force = np.concatenate([np.asarray(t.tension, float) for t in ts])
        trial = np.concatenate([np.full(len(t.tension), i) for i, t in enumerate(ts)])
        direction = np.concatenate([loading_direction(t.tension, tol=tol / 3.0) for t in ts])
        groups = replicate_groups(trial, direction, force, tol=tol)
        n_groups = int(np.unique(groups[groups >= 0]).size)
        out[tube] = lack_of_fit_table(y, yhat, groups, force, n_params=n_params + params_per_group * n_groups,
                                      unit=unit, scale=scale, n_ranges=n_ranges,
                                      response_labels=response_labels, alpha=alpha)
    return out


def lack_of_fit_summary(tables: dict) -> str:
    """The :meth:`LackOfFit.summary` of each tube of :func:`study_lack_of_fit`, titled by tube when several."""
    if len(tables) == 1:
        return next(iter(tables.values())).summary()
    return "\n".join(f"{tube}: " + lof.summary() for tube, lof in tables.items())


def shape_fit_lack_of_fit(items, models, *, tol: float = 0.15, n_ranges: int = 3, alpha: float = 0.05) -> dict:
    """Pure error and lack of fit of ``notchfit fit``'s shape models (Sec. IV-A), per model and tube.

    Each sample is fitted on its own, so every replicate group costs the model's ``k``
    parameters (``params_per_group``); the lack of fit is the shape the model cannot take
    (a constant curvature where the notches bend unevenly), against the trials' scatter.

    Parameters
    ----------
    items : iterable of (name, tube, tension_left, tension_right, result)
        One per experiment: its tensions (S,) [N] and its fit, an
        :class:`~notchfit.analysis.fitting.angles.AngleFit` (joint angles, degrees) or an
        :class:`~notchfit.analysis.fitting.results.ExperimentFit` (notch points in the plane, mm).
    models : sequence of str
    tol, n_ranges, alpha :
        As :func:`study_lack_of_fit`.

    Returns
    -------
    dict
        Model -> tube -> LackOfFit. A tube is compared in the kind of its first experiment; an
        experiment of the other kind is left out.
    """
    items = list(items)
    kind_of: dict = {}
    for name, tube, _, _, res in items:
        kind_of.setdefault(tube, hasattr(res, "measured"))
    out = {}
    for model in models:
        out[model] = {}
        for tube, angles in kind_of.items():
            trials, k, labels = [], 0, None
            for name, t, tl, tr, res in items:
                if t != tube or hasattr(res, "measured") != angles:
                    continue
                tension = tr if pulled_side(tl, tr) > 0 else tl
                if angles:
                    f = res.get(model)
                    meas, pred, k = res.measured, f.theta, f.params.shape[1]
                else:
                    theta = res.theta(model)
                    pred = res.transform.to_plane(notch_points(np.nan_to_num(theta), res.geom))
                    pred[~np.isfinite(theta).all(axis=1)] = np.nan
                    meas, k = res.points, res.params(model).shape[1]
                    labels = [f"point {i + 1}" for i in range(meas.shape[1]) for _ in "xy"]
                S = meas.shape[0]
                trials.append(Trial(name, tube, meas.reshape(S, -1), np.asarray(pred, float).reshape(S, -1),
                                    np.asarray(tension, float)))
            out[model].update(study_lack_of_fit(trials, params_per_group=k, unit="deg" if angles else "mm",
                                                scale=1.0 / (DEG if angles else MM), tol=tol, n_ranges=n_ranges,
                                                response_labels=labels, alpha=alpha))
    return out
