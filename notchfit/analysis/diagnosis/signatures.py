"""Discrepancy signatures: what the held-out baseline gets wrong, in numbers and words.

Error by regime, the extra tension the measured shape holds while
unloading, hysteresis-loop areas, ``b`` on each branch (``θ_j = a + b j``,
Sec. IV-A), the bend left at the end of unloading, residuals along the
backbone, the spatial pattern that no joint configuration explains (free-θ
fit residuals against the noise), the asymmetry between pull directions,
stalls on the upper loading ramp and the dependence on the counter-tension
(docs/diagnosis.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...polygon import polygon_area
from ...physics.shapes import line_fit
from ...units import DEG, MM
from .crossval import HeldOut
from .noise import pooled_rms
from .results import Signature

__all__ = ["loading_stalls", "signatures", "skipped_signatures"]


def _loop_area(T, phi) -> float:
    """Area of the hysteresis loop (pulled tension T [N], tip angle φ [rad]) closed back to its start [N rad]."""
    return polygon_area(T, phi)


def _release_tension(T, phi, regime, level: float = 0.5) -> float:
    """Pulled tension at which the tip angle has lost ``level`` of its unloading drop [N]."""
    k = int(np.argmax(T))
    seg_T, seg_phi = T[k:], phi[k:]
    if len(seg_T) < 2:
        return float("nan")
    drop = seg_phi[0] - np.min(seg_phi)
    if drop <= 0:
        return float("nan")
    target = seg_phi[0] - level * drop
    for s in range(1, len(seg_phi)):
        if seg_phi[s] <= target:
            f = (seg_phi[s - 1] - target) / max(seg_phi[s - 1] - seg_phi[s], 1e-15)
            return float(seg_T[s - 1] + f * (seg_T[s] - seg_T[s - 1]))
    return float("nan")


def loading_stalls(T, tip_measured, tip_predicted, *, min_step: float = 0.01, ratio: float = 0.3,
                   upper: float = 0.5) -> tuple[int, int]:
    """Loading steps on which the measured shape stalled where the model moved.

    A static friction coefficient well above the sliding one (Sec. IV-B
    Step 4) makes a cable break away only when a tension step exceeds
    ``(μ_s − μ_d) N``: with the large normal forces of the upper loading
    ramp some steps move nothing, the next ones catch up. Counted are the
    steps ``k-1 -> k`` with rising pulled tension above ``upper`` times its
    peak on which the predicted tip angle grows by more than ``min_step``
    [rad] (far above the measurement noise) and the measured one by less
    than ``ratio`` of that.

    Parameters
    ----------
    T : ndarray, shape (S,)
        Pulled tension [N].
    tip_measured, tip_predicted : ndarray, shape (S,)
        Tip angle toward the pulled side [rad].

    Returns
    -------
    n_stalled, n_steps : int
    """
    T, tm, tp = (np.asarray(a, dtype=float) for a in (T, tip_measured, tip_predicted))
    up = (np.diff(T) > 0) & (T[1:] > upper * np.nanmax(T))
    dm, dp = np.diff(tm)[up], np.diff(tp)[up]
    big = np.isfinite(dm) & (dp > min_step)
    return int(np.sum(dm[big] < ratio * dp[big])), int(np.sum(big))


@dataclass
class _Tally:
    """Per-experiment measures of the held-out baseline, pooled over experiments."""

    holds: list = field(default_factory=list)
    area_m: list = field(default_factory=list)
    area_p: list = field(default_factory=list)
    b_load: list = field(default_factory=list)
    b_unload: list = field(default_factory=list)
    bend: list = field(default_factory=list)
    back: list = field(default_factory=list)
    front: list = field(default_factory=list)
    asym: list = field(default_factory=list)
    n_stall: int = 0
    n_steps: int = 0
    pulls: set = field(default_factory=set)

    @property
    def both_directions(self) -> bool:
        """The study pulls both ways (the direction asymmetry is defined)."""
        return len(self.pulls) > 1

    def add(self, p, th_p: np.ndarray, stall_ratio: float) -> None:
        """Add experiment ``p`` (Prepared) with predicted joint angles ``th_p`` (S, n) [rad]."""
        self.pulls.add(p.pulled)
        tip_m = p.tip_angle
        tip_p = p.pulled * th_p.sum(axis=1)
        T = p.pulled_tension
        rm, rp = _release_tension(T, tip_m, p.regime), _release_tension(T, tip_p, p.regime)
        if np.isfinite(rm) and np.isfinite(rp):
            self.holds.append(rp - rm)
        self.area_m.append(_loop_area(T, tip_m))
        self.area_p.append(_loop_area(T, tip_p))
        ns, nt = loading_stalls(T, tip_m, tip_p, ratio=stall_ratio)
        self.n_stall, self.n_steps = self.n_stall + ns, self.n_steps + nt
        bp = p.pulled * line_fit(th_p)[1]
        bm = p.pulled * p.b
        load = p.regime == "I"
        if load.any():
            self.b_load.append(np.nanmean(bm[load] - bp[load]))
        if (~load).any():
            self.b_unload.append(np.nanmean(bm[~load] - bp[~load]))
        self.bend.append(tip_m[-1] - tip_p[-1])
        dth = p.pulled * (p.theta_free - th_p)
        third = max(p.geom.n_joints // 3, 1)
        self.back.append(np.nanmean(dth[:, :third]))
        self.front.append(np.nanmean(dth[:, -third:]))
        self.asym.append(np.nanmean(p.theta_free.sum(axis=1) - th_p.sum(axis=1)))


def _regime_signatures(preps, mse, noise: float) -> list[Signature]:
    out = []
    angles = preps[0].metric == "angles"
    for reg in ("I", "II", "III"):
        r = pooled_rms(mse, [p.regime == reg for p in preps])
        if np.isfinite(r):
            if angles:
                out.append(Signature(f"heldout_rms_regime_{reg}", r / DEG, "deg",
                                     f"held-out baseline joint-angle rms in regime {reg} is {r / DEG:.3f}° "
                                     f"(noise floor {math.sqrt(noise) / DEG:.3f}°)"))
            else:
                out.append(Signature(f"heldout_rms_regime_{reg}", r, "m",
                                     f"held-out baseline notch-point rms in regime {reg} is {r / MM:.3f} mm "
                                     f"(noise floor {math.sqrt(noise) / MM:.3f} mm)"))
    return out


def _hold_and_stall_signatures(t: _Tally, stall_ratio: float) -> list[Signature]:
    out = []
    if t.holds:
        v = float(np.mean(t.holds))
        word = "longer" if v > 0 else "shorter"
        out.append(Signature("unloading_hold", v, "N",
                             f"the measured shape holds {abs(v):.2f} N {word} while unloading than the "
                             "baseline predicts (tension at half release, measured vs predicted)"))
    if t.n_steps:
        out.append(Signature("loading_stalls", t.n_stall / t.n_steps, "-",
                             f"on {t.n_stall} of {t.n_steps} steps of the upper loading ramp the measured "
                             f"shape moved less than {100 * stall_ratio:.0f}% of the baseline's prediction "
                             "(a cable that stuck where the model slides)"))
    am, ap = float(np.mean(t.area_m)), float(np.mean(t.area_p))
    ratio = am / ap if ap > 0 else float("inf")
    out.append(Signature("loop_area_ratio", ratio, "-",
                         f"hysteresis loop (pulled tension vs tip angle) is {am:.3f} N rad measured vs "
                         f"{ap:.3f} N rad predicted (ratio {ratio:.2f})"))
    return out


def _shape_signatures(t: _Tally) -> list[Signature]:
    out = []
    for name, vals, what in (("b_loading_error", t.b_load, "loading"),
                             ("b_unloading_error", t.b_unload, "unloading")):
        if vals:
            v = float(np.mean(vals))
            out.append(Signature(name, v, "rad",
                                 f"on the {what} branch the measured b (θ_j = a + b j, toward the pulled "
                                 f"side) differs from the baseline's by {v:+.5f} rad per joint"))
    v = float(np.mean(t.bend))
    out.append(Signature("residual_bend", v, "rad",
                         f"after unloading the measured tip angle exceeds the predicted by {v:+.4f} rad "
                         "(toward the pulled side)"))
    vb, vf = float(np.mean(t.back)), float(np.mean(t.front))
    out.append(Signature("backbone_residual", vb - vf, "rad",
                         f"joint-angle error (measured − baseline) is {vb:+.4f} rad on the base third and "
                         f"{vf:+.4f} rad on the tip third"))
    if t.both_directions:
        v = float(np.mean(t.asym))
        out.append(Signature("direction_asymmetry", v, "rad",
                             f"the tip-angle error has mean {v:+.4f} rad in the manipulator frame over both pull "
                             "directions (a mirror-symmetric model error averages out; a steady load does not)"))
    return out


def _study_signatures(preps, mse) -> list[Signature]:
    """The spatial pattern of the free-θ residuals (notch points) and the dependence on the counter-tension."""
    out = []
    if preps[0].metric == "points":
        free_ms = np.nanmean(np.concatenate([np.sum(p.free_residuals**2, -1)[p.valid] for p in preps]))
        point_noise = np.mean([2 * p.sigma**2 for p in preps])
        v = float(math.sqrt(free_ms / point_noise))
        out.append(Signature("spatial_pattern", v, "-",
                             f"free-θ fits leave a residual {v:.2f}× the noise level: "
                             + ("a pattern across the image that no joint configuration explains" if v > 1.3
                                else "no pattern beyond noise")))
    cts = [p.counter_tension for p in preps]
    ers = [math.sqrt(np.nanmean(m)) for m in mse]
    if len(set(np.round(cts, 6))) > 1:
        c = float(np.corrcoef(cts, ers)[0, 1])
        out.append(Signature("counter_tension_dependence", c, "-",
                             f"held-out error correlates with counter-tension at r = {c:+.2f}"))
    return out


def skipped_signatures(preps) -> dict:
    """``{signature: reason}`` for the signatures this study cannot show."""
    out = {}
    if preps[0].metric == "angles":
        out["spatial_pattern"] = ("needs notch points: the residual of free-θ fits across the image; the "
                                  "experiments are measured as joint angles")
    if len({p.pulled for p in preps}) < 2:
        out["direction_asymmetry"] = ("needs both pull directions: every experiment pulls the same way "
                                      "(e.g. a one-tendon wrist)")
    return out


def signatures(preps, base: HeldOut, noise: float, *, stall_ratio: float = 0.3) -> list[Signature]:
    """Discrepancy signatures of the held-out baseline.

    Parameters
    ----------
    preps : sequence of Prepared
    base : HeldOut
        The baseline's held-out predictions.
    noise : float
        Mean squared point error a perfect model would leave [m²]
        (:func:`notchfit.analysis.estimation.noise_floor`).
    stall_ratio : float
        Passed to :func:`loading_stalls`.

    Returns
    -------
    list of Signature
    """
    mse = base.sample_mse(preps)
    tally = _Tally()
    for i, p in enumerate(preps):
        tally.add(p, base.theta[i], stall_ratio)
    return (_regime_signatures(preps, mse, noise) + _hold_and_stall_signatures(tally, stall_ratio)
            + _shape_signatures(tally) + _study_signatures(preps, mse))
