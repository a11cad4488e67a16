"""The corrections model of ``notchfit review``: a detect run's corners, a person's corrections, conflicts.

One :class:`ReviewSession` serves every tab of the page. It holds, per
experiment, the detections (never changed) and the corrections, which are
written to ``review.csv`` beside ``detections.csv`` (atomically, after every
change). Two tabs may edit one study: the last write to a corner wins, the
writer is told when it replaced a change it had not seen, and the other tab
learns of it from :meth:`ReviewSession.changes_since`.
"""

from __future__ import annotations

import datetime
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import io
from ..units import DEG, MM
from .measure import hand_angles, live_fit
from .pixels import pixel_views

__all__ = ["ACTIONS", "ExperimentReview", "ReviewSession", "corner_counts"]

#: What a person can do to a corner (``restore`` puts back a saved state: undo).
ACTIONS = ("move", "place", "accept", "delete", "occlude", "revert", "restore")
_MISSING = ("missing", "deleted", "occluded")


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _f(v) -> float | None:
    """A number for JSON (None for NaN)."""
    v = float(v)
    return v if np.isfinite(v) else None


@dataclass
class ExperimentReview:
    """One experiment's detections and corrections.

    Attributes
    ----------
    exp : Experiment
    detections : Path
        The detect run's ``detections.csv``; ``review.csv`` is beside it.
    uv, xy_mm : ndarray (S, m, 2)
        Detected pixels and plane coordinates [mm] (NaN = none).
    sigma_mm : ndarray (S, m)
    status : ndarray (S, m) of str
        The detector's status, ``""`` where it wrote no row.
    views : list
        Per sample, the pixel <-> plane map (:func:`~notchfit.review.pixels.pixel_views`).
    rows : dict
        ``{(sample, point): review row}`` (the columns of ``review.csv``).
    versions : dict
        ``{(sample, point): n}``: how often the corner was changed in this session.
    """

    exp: object
    detections: Path
    uv: np.ndarray
    xy_mm: np.ndarray
    sigma_mm: np.ndarray
    status: np.ndarray
    views: list
    rows: dict = field(default_factory=dict)
    versions: dict = field(default_factory=dict)

    @property
    def review_path(self) -> Path:
        return io.review_path(self.detections)

    @classmethod
    def load(cls, exp, detections) -> "ExperimentReview":
        """Read ``detections`` (and ``review.csv`` beside it, when present) for ``exp``."""
        m = exp.geometry.n_points
        df = io.read_detections(detections, n_points=m, sample_ids=exp.sample_ids)
        index = {int(s): i for i, s in enumerate(exp.sample_ids)}
        S = exp.n_samples
        uv, xy = np.full((S, m, 2), np.nan), np.full((S, m, 2), np.nan)
        sig, status = np.full((S, m), np.nan), np.full((S, m), "", dtype=object)
        i, q = df["sample"].map(index).to_numpy(int), df["point"].to_numpy(int) - 1
        uv[i, q] = df[["u_px", "v_px"]].to_numpy(float)
        xy[i, q] = df[["x_mm", "y_mm"]].to_numpy(float)
        sig[i, q] = df["sigma_mm"].to_numpy(float)
        status[i, q] = df["status"].str.lower().to_numpy()
        camera = None
        if exp.calibration_path is not None and Path(exp.calibration_path).is_file():
            camera = io.read_camera(exp.calibration_path)
        rev = cls(exp, Path(detections), uv, xy, sig, status, pixel_views(camera, uv, xy))
        if rev.review_path.is_file():
            table = io.read_review(rev.review_path, n_points=m, sample_ids=exp.sample_ids)
            rev.rows = {(int(r["sample"]), int(r["point"])): r for r in table.to_dict("records")}
        return rev

    def index(self, sample: int) -> int:
        ids = [int(s) for s in self.exp.sample_ids]
        if int(sample) not in ids:
            raise KeyError(f"{self.exp.name} has no sample {sample}")
        return ids.index(int(sample))

    def corner(self, sample: int, point: int) -> dict:
        """The state of corner ``point`` (1-based) of ``sample`` as the page shows it."""
        i, q = self.index(sample), int(point) - 1
        row = self.rows.get((int(sample), int(point)))
        det = self.status[i, q] or "missing"
        if not np.isfinite(self.uv[i, q]).all() and det != "occluded":
            det = "missing"
        if row is None:
            u, v = self.uv[i, q]
            status, sigma = det, self.sigma_mm[i, q]
        else:
            u, v, status, sigma = row["u_px"], row["v_px"], row["status"], row["sigma_mm"]
        return {"point": int(point), "u": _f(u), "v": _f(v), "status": status, "detected": det,
                "corrected": row is not None, "sigma_mm": _f(sigma),
                "review": None if row is None else {k: (_f(x) if isinstance(x, float) else x)
                                                    for k, x in row.items()},
                "version": self.versions.get((int(sample), int(point)), 0)}

    def corners(self, sample: int) -> list[dict]:
        return [self.corner(sample, q) for q in range(1, self.exp.geometry.n_points + 1)]

    def plane_points(self, sample: int) -> tuple[np.ndarray, np.ndarray]:
        """The sample's corners as the fits see them: plane points (m, 2) [m] and sigma (m,) [m];
        a corner that is not ``ok`` or ``manual`` has NaN sigma (shown, not fitted)."""
        i = self.index(sample)
        pts, sig = self.xy_mm[i] * MM, np.where(self.status[i] == "ok", self.sigma_mm[i] * MM, np.nan)
        for (s, q), row in self.rows.items():
            if s == int(sample):
                if row["status"] == "manual":
                    pts[q - 1] = (row["x_mm"] * MM, row["y_mm"] * MM)
                    sig[q - 1] = row["sigma_mm"] * MM
                else:
                    pts[q - 1], sig[q - 1] = np.nan, np.nan
        return pts, sig

    def save(self) -> None:
        """Write ``review.csv`` (atomically), or remove it when no correction is left."""
        if self.rows:
            io.write_review(self.rows.values(), self.review_path)
        else:
            self.review_path.unlink(missing_ok=True)


def corner_counts(corners) -> dict:
    """``ok`` (detected ok or placed by hand), ``ambiguous``, ``missing`` (none, deleted, occluded), ``manual``."""
    st = [c["status"] for c in corners]
    return {"ok": sum(s in ("ok", "manual") for s in st), "ambiguous": st.count("ambiguous"),
            "missing": sum(s in _MISSING for s in st), "manual": st.count("manual")}


class ReviewSession:
    """Every experiment under review, the edits, and the log of changes the tabs poll.

    Parameters
    ----------
    experiments : sequence of ExperimentReview
    manual_sigma_px : float
        Uncertainty of a corner placed by hand [image pixels]; written in
        ``review.csv`` as ``sigma_mm`` (the pixel's size on the plane at that
        point) and used by the fits.
    """

    def __init__(self, experiments, *, manual_sigma_px: float = 1.0):
        self.experiments = list(experiments)
        self.manual_sigma_px = float(manual_sigma_px)
        self.lock = threading.RLock()
        self.log: list[dict] = []          # {"seq", "exp", "sample", "point", "client"}

    def get(self, exp: int) -> ExperimentReview:
        if not 0 <= int(exp) < len(self.experiments):
            raise KeyError(f"no experiment {exp}")
        return self.experiments[int(exp)]

    # ------------------------------------------------------------------ reading
    def overview(self) -> dict:
        """Every experiment and sample with the counts of its corners (the thumbnail strip)."""
        with self.lock:
            out = []
            for k, r in enumerate(self.experiments):
                samples = []
                for s, img in zip(r.exp.sample_ids, r.exp.image_paths or [None] * r.exp.n_samples):
                    samples.append({"sample": int(s), "image": img is not None,
                                    "counts": corner_counts(r.corners(int(s)))})
                out.append({"index": k, "name": r.exp.name, "n_points": r.exp.geometry.n_points,
                            "n_joints": r.exp.geometry.n_joints, "review": str(r.review_path),
                            "samples": samples})
            return {"experiments": out, "manual_sigma_px": self.manual_sigma_px, "seq": len(self.log)}

    def sample(self, exp: int, sample: int) -> dict:
        with self.lock:
            r = self.get(exp)
            corners = r.corners(sample)
            return {"exp": int(exp), "sample": int(sample), "corners": corners, "counts": corner_counts(corners)}

    def fit(self, exp: int, sample: int) -> dict:
        """The live free-θ fit of the sample (:func:`~notchfit.review.measure.live_fit`), with the
        fitted corners in image pixels (``predicted_px``: where a missing corner should be)."""
        with self.lock:
            r = self.get(exp)
            pts, sig = r.plane_points(sample)
            view = r.views[r.index(sample)]
        out = live_fit(pts, sig, r.exp.geometry, mirror=r.exp.mirror)
        pred = out.pop("predicted")
        out["predicted_px"] = (None if pred is None or view is None else
                               [[_f(a) for a in uv] for uv in view.plane_to_pixel(pred)])
        return out

    def angles(self, exp: int, sample: int) -> dict:
        """The angles by hand of the sample, with the cut-face lines in image pixels."""
        with self.lock:
            r = self.get(exp)
            pts, _ = r.plane_points(sample)
            view = r.views[r.index(sample)]
        res = hand_angles(pts, r.exp.geometry, mirror=r.exp.mirror)
        faces = []
        for pair in res["faces"]:
            if pair is None or view is None:
                faces.append(None)
                continue
            faces.append([view.plane_to_pixel(np.asarray(seg)).tolist() for seg in pair])
        return {"theta_deg": [_f(t / DEG) for t in res["theta"]], "faces": faces}

    def write_angles(self, exp: int) -> dict:
        """Write ``angles.csv`` of the experiment from its reviewed corners, beside ``review.csv``."""
        with self.lock:
            r = self.get(exp)
            points = [r.plane_points(int(s))[0] for s in r.exp.sample_ids]
        theta = np.stack([hand_angles(p, r.exp.geometry, mirror=r.exp.mirror)["theta"] for p in points])
        path = r.detections.parent / "angles.csv"
        io.write_table_atomic(io.angles_table(theta, r.exp.sample_ids), path)
        return {"path": str(path), "measured": int(np.isfinite(theta).sum()), "total": int(theta.size)}

    def changes_since(self, seq: int, client: str | None = None) -> dict:
        """The corners changed after ``seq`` by other tabs than ``client``, with their state now."""
        with self.lock:
            changed = [c for c in self.log[int(seq):] if c["client"] != client]
            out = [dict(c, corner=self.get(c["exp"]).corner(c["sample"], c["point"])) for c in changed]
            return {"seq": len(self.log), "changes": out}

    # ------------------------------------------------------------------ editing
    def edit(self, exp: int, sample: int, point: int, action: str, *, u=None, v=None, row=None,
             version=None, client: str | None = None) -> dict:
        """Apply one action to a corner, save ``review.csv``, and return the corner's new state.

        ``version`` is the corner's version the tab last saw: when another tab
        changed it since, the change still applies (the last write wins) and
        ``conflict`` says whose change it replaced.
        """
        if action not in ACTIONS:
            raise ValueError(f"unknown action {action!r} (one of {', '.join(ACTIONS)})")
        with self.lock:
            r = self.get(exp)
            key = (int(sample), int(point))
            i, q = r.index(sample), int(point) - 1
            if not 0 <= q < r.exp.geometry.n_points:
                raise KeyError(f"no point {point}")
            conflict = None
            now = r.versions.get(key, 0)
            if version is not None and int(version) != now:
                last = next((c for c in reversed(self.log) if (c["exp"], c["sample"], c["point"])
                             == (int(exp), *key)), None)
                if last is not None and last["client"] != client:
                    conflict = (f"corner {point} of sample {sample} had been changed in another tab; "
                                "your change replaced it (the last change wins)")
            old = r.rows.get(key)
            self._apply(r, i, key, action, u, v, row)
            try:
                r.save()
            except BaseException:
                # not saved: the corner stays as the file has it
                if old is None:
                    r.rows.pop(key, None)
                else:
                    r.rows[key] = old
                raise
            r.versions[key] = now + 1
            self.log.append({"seq": len(self.log) + 1, "exp": int(exp), "sample": key[0], "point": key[1],
                             "client": client})
            return {"corner": r.corner(*key), "conflict": conflict, "seq": len(self.log),
                    "counts": corner_counts(r.corners(sample))}

    def _apply(self, r: ExperimentReview, i: int, key, action, u, v, row) -> None:
        q = key[1] - 1
        prev = {"prev_u_px": r.uv[i, q, 0], "prev_v_px": r.uv[i, q, 1], "prev_x_mm": r.xy_mm[i, q, 0],
                "prev_y_mm": r.xy_mm[i, q, 1], "prev_status": r.status[i, q]}
        base = {"sample": key[0], "point": key[1], **prev, "time": _now()}
        if action == "revert" or (action == "restore" and not row):
            r.rows.pop(key, None)
        elif action == "restore":
            keep = {k: row.get(k) for k in ("u_px", "v_px", "x_mm", "y_mm", "sigma_mm")}
            keep = {k: (np.nan if x is None else float(x)) for k, x in keep.items()}
            status = row.get("status")
            if status not in io.REVIEW_STATUSES or (status == "manual" and not (
                    np.isfinite(list(keep.values())).all() and keep["sigma_mm"] > 0)):
                raise ValueError(f"cannot restore corner {key[1]} of sample {key[0]}: not a review row ({row})")
            r.rows[key] = {**base, **keep, "status": status}
        elif action in ("delete", "occlude"):
            r.rows[key] = {**base, "u_px": np.nan, "v_px": np.nan, "x_mm": np.nan, "y_mm": np.nan,
                           "sigma_mm": np.nan, "status": "deleted" if action == "delete" else "occluded"}
        elif action == "accept":
            # an ambiguous detection keeps its pixel (detections.csv leaves its plane point empty): the
            # person confirms it, with the detector's sigma where it gave one, else one pixel's
            if not np.isfinite(r.uv[i, q]).all():
                raise ValueError(f"corner {key[1]} of sample {key[0]} has no detected position to accept")
            r.rows[key] = {**base, **self._manual(r, i, r.uv[i, q]), "status": "manual"}
            if np.isfinite(r.sigma_mm[i, q]):
                r.rows[key]["sigma_mm"] = r.sigma_mm[i, q]
        else:
            uv = np.array([float(u), float(v)])
            if not np.isfinite(uv).all():
                raise ValueError("a corner's position needs finite u and v")
            r.rows[key] = {**base, **self._manual(r, i, uv), "status": "manual"}

    def _manual(self, r: ExperimentReview, i: int, uv) -> dict:
        """The columns of a corner put at pixel ``uv`` by hand: the pixel, its plane point [mm], its sigma."""
        uv = np.asarray(uv, float)
        xy = self._view(r, i).pixel_to_plane(uv) / MM
        return {"u_px": uv[0], "v_px": uv[1], "x_mm": xy[0], "y_mm": xy[1], "sigma_mm": self._pixel_sigma_mm(r, i, uv)}

    @staticmethod
    def _view(r: ExperimentReview, i: int):
        view = r.views[i]
        if view is None:
            raise ValueError(f"{r.exp.name}: no camera file and no detected corner: the pixel size is unknown, "
                             "a corner cannot be placed")
        return view

    def _pixel_sigma_mm(self, r: ExperimentReview, i: int, uv) -> float:
        """``manual_sigma_px`` image pixels on the plane at pixel ``uv`` [mm]."""
        view = self._view(r, i)
        return self.manual_sigma_px / view.plane_scale(view.pixel_to_plane(np.asarray(uv, float))) / MM
