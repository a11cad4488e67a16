"""One HTML report per study that reads at a glance (``notchfit report DIR``).

The page a researcher forwards to a colleague: the question and the answer
first (what was measured, the cause, the gain, what was assumed), one
statement of units and signs, then a section per step, each with the
parameters of every simulation it shows and one-sentence captions saying
what each figure shows and how to read it. Figures are drawn for the page
(:mod:`notchfit.figures.summary`, 100 dpi, legible at 100 % zoom) from the
tables the commands wrote, and embedded, so ``report.html`` opens alone; the
per-experiment figures and the raw files are linked (relative links: keep
the folder together). Sections, each present even when its input is absent
(then it says "not available: <why>"):

=================  ==========================================================
id                 content
=================  ==========================================================
``summary``        at a glance: question, measured, cause, gain, assumptions
``study``          the experiments (from the study folder, when known)
``detection``      the camera file and the detected corners (thumbnails)
``fit``            shape-fit errors per model (Figs. 12–15)
``simulation``     simulation vs measurement, with its parameters (Figs. 18–19)
``identify``       ``identify.json``: the identified model, its held-out errors, each tube
``diagnosis``      ``diagnosis.json``: each named cause, candidates, signatures,
                   the baseline's and the extension's parameters, figures
``files``          links to every per-experiment figure and the raw outputs
=================  ==========================================================

One convention throughout: ``a``, joint and tip angles in rad, ``b`` in rad
per joint (degrees and degrees per joint throughout a study measured as joint
angles), signed in the manipulator frame (CONVENTIONS.md); lengths in mm;
tensions in N with the digits the load cells resolve. The page is a typed form
(:mod:`notchfit.report.forms`) laid out by Jinja2 templates (``templates/``,
autoescaped); every result file is read through :mod:`notchfit.io`.
The diagnosis's own CSV of older versions (tip angle toward the pulled
cable) is converted. The study folder is the one given with ``study=``, or
the ``input`` recorded in a ``*_run.json`` provenance file.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

import numpy as np

from .. import io as nio
from .._version import __version__
from ..physics.cables import pulled_side
from ..analysis.estimation import tube_labels
from .diagnosis import diagnosis_section
from .forms import NotAvailable, Page, Section
from .page import num, rel, render_page
from .sections import detection_section, files_section, glance_section, study_section
from .steps import fit_section, fit_summary, identify_section, simulation_section

__all__ = ["SECTIONS", "Inputs", "build_report", "find_study", "summary_lines"]

SECTIONS = (
    ("summary", "At a glance"),
    ("study", "Study"),
    ("detection", "Camera and detection"),
    ("fit", "Shape fits (Figs. 12–15)"),
    ("simulation", "Simulation vs measurement (Figs. 18–19)"),
    ("identify", "Identified model"),
    ("diagnosis", "Diagnosis"),
    ("files", "Files"),
)


# ----------------------------------------------------------------------------- study
def find_study(out_dir) -> Path | None:
    """The study folder recorded by ``fit``/``simulate``/``diagnose`` provenance files, if any."""
    for rec in nio.read_run_records(out_dir).values():
        if rec.input and Path(rec.input).is_dir():
            return Path(rec.input)
    return None


def tension_decimals(exps, *, most: int = 6) -> int:
    """The decimals the load cells resolve: the fewest with which every tension of the study is written
    (0.1 mN steps: 4). Tensions are shown with these digits at most (:func:`notchfit.report.page.newton`)."""
    vals = np.concatenate([np.concatenate([np.ravel(e.tension_left), np.ravel(e.tension_right)]) for e in exps])
    vals = vals[np.isfinite(vals)]
    for k in range(most + 1):
        if np.all(np.abs(vals * 10**k - np.round(vals * 10**k)) < 1e-6):
            return k
    return most


def _unloads(e) -> bool:
    """Whether a test releases its pulled tension after the peak (by more than a tenth of the peak)."""
    t = np.nan_to_num(np.abs(np.asarray(e.tension_left, float) - np.asarray(e.tension_right, float)))
    k = int(np.argmax(t)) if t.size else 0
    return bool(t.size) and float(t[k:].min()) < 0.9 * float(t[k])


class Inputs:
    """What the report reads, once: the output folder, the study and its experiments, the result records.

    Attributes
    ----------
    out : Path
    study_path : Path or None
    exps : list of Experiment, or None
    why : str
        Why ``exps`` is None.
    pulled : dict
        ``{experiment: +1 right | -1 left}`` (:func:`notchfit.physics.cables.pulled_side`).
    truth : dict or None
        ``truth.json`` of a synthetic study (the hidden effect).
    runs : dict
        ``{command: notchfit.io.RunRecord}`` of the ``*_run.json`` files.
    diagnosis : notchfit.io.DiagnosisRecord or None
    identify : notchfit.io.IdentifyRecord or None
    angles : bool
        The study is measured as joint angles: degrees throughout the page.
    decimals : int
        The decimals the load cells resolve (:func:`tension_decimals`).
    unloads : bool
        Some test releases its tension (signatures of unloading can be shown).
    tubes : list of (label, geometry, experiment names)
    """

    def __init__(self, out_dir: Path, study=None):
        self.out = out_dir
        self.runs = nio.read_run_records(out_dir)
        self.study_path = Path(study) if study is not None else find_study(out_dir)
        self.exps, self.why = None, "no study folder known (give --study STUDY)"
        if self.study_path is not None:
            try:
                self.exps = nio.read_study(self.study_path, missing_images="keep")
            except (ValueError, FileNotFoundError) as exc:
                self.why = f"cannot read the study: {exc}"
        exps = self.exps or []
        self.by_name = {e.name: e for e in exps}
        self.pulled = {e.name: pulled_side(e.tension_left, e.tension_right) for e in exps}
        self.truth = self._json(self.study_path / "truth.json") if self.study_path else None
        self.diagnosis, self.diagnosis_error = self._record(nio.read_diagnosis_record, "diagnosis.json")
        self.identify, self.identify_error = self._record(nio.read_identify, "identify.json")
        self.angles = bool(exps) and all(e.points is None and not e.has_images and e.angles is not None
                                         for e in exps)
        if self.diagnosis is not None:
            self.angles = self.diagnosis.unit == "deg"
        self.decimals = tension_decimals(exps) if exps else 2
        self.unloads = any(_unloads(e) for e in exps) if exps else True
        self.tubes = _tubes(exps)
        self._once: dict = {}

    def _record(self, reader, name: str):
        path = self.out / name
        if not path.is_file():
            return None, None
        try:
            return reader(path), None
        except ValueError as exc:
            return None, str(exc)

    def once(self, fn, *args):
        """``fn(self, *args)``, computed on the first call only: the output tables that several
        sections use (detections, fit errors, the diagnosis's loops) are read once per report."""
        key = (fn, args)
        if key not in self._once:
            self._once[key] = fn(self, *args)
        return self._once[key]

    @staticmethod
    def _json(path: Path):
        try:
            return nio.read_json(path) if path.is_file() else None
        except (ValueError, OSError):
            return None

    def experiment(self, name: str):
        """The study's experiment ``name`` (``""``: the only one of a single-experiment run)."""
        if name in self.by_name:
            return self.by_name[name]
        return self.exps[0] if name == "" and self.exps and len(self.exps) == 1 else None

    def rel(self, path) -> str:
        return rel(path, self.out)


def _tubes(exps) -> list[tuple]:
    """``(label, geometry, [experiment names])`` per tube, labelled as ``identify`` labels tubes."""
    out: dict = {}
    for e, label in zip(exps, tube_labels([e.geometry for e in exps])):
        out.setdefault(label, (label, e.geometry, []))[2].append(e.name)
    return list(out.values())


# ----------------------------------------------------------------------------- summary lines
def summary_lines(out_dir) -> list[str]:
    """Three lines: fit errors, the named cause(s), the measured gain (what is available)."""
    out_dir = Path(out_dir)
    st = fit_summary(out_dir)
    if st is None:
        lines = ["fit errors: not available (no fits.csv or angle_fits.csv)"]
    else:
        u = st.unit
        txt = "; ".join(f"{r.model} {num(r.rms)} {u} rms (max {num(r.max)} {u})" for r in st.table.itertuples())
        lines = [f"fit errors over {int(st.table['samples'].iloc[0])} samples: {txt}"]
    path = out_dir / "diagnosis.json"
    if not path.is_file():
        return lines + ["cause: not available (no diagnosis.json)", "gain: not available (no diagnosis.json)"]
    try:
        d = nio.read_diagnosis_record(path)
    except ValueError as exc:
        return lines + [f"cause: not available ({exc})", "gain: not available"]
    u = d.unit
    lines.append(f"cause: {', '.join(d.named)} (calibrated baseline held-out rms {num(d.baseline.heldout_rms)} {u})")
    lines.append(f"gain: held-out rms {num(d.gain.baseline)} -> {num(d.gain.extended)} {u} "
                 f"({num(d.gain.reduction_pct, 3)} % lower)")
    return lines


# ----------------------------------------------------------------------------- build
def _refuse_input_folder(out_dir: Path) -> None:
    """An experiment or study folder is input data, not an output folder: refuse it with a hint."""
    try:
        subs = [p for p in out_dir.iterdir() if p.is_dir() and not p.name.startswith(".")]
    except OSError:
        subs = []
    if nio.is_experiment_dir(out_dir) or any(nio.is_experiment_dir(p) for p in subs):
        raise ValueError(f"{out_dir}: is an input study or experiment (it holds experiment.toml), not an "
                         "output folder; run `notchfit report OUT --study "
                         f"{out_dir}` on the --out folder of fit/simulate/diagnose")


def _sections(inp: Inputs, progress=None) -> list[Section]:
    """Every section's typed form; one that fails says why and the others are built."""
    builders = {"summary": glance_section, "study": study_section, "detection": detection_section,
                "fit": fit_section, "simulation": simulation_section, "identify": identify_section,
                "diagnosis": diagnosis_section, "files": files_section}
    out = []
    for key, title in SECTIONS:
        if progress is not None:
            progress(key)
        try:
            blocks = tuple(b for b in builders[key](inp) if b is not None)
        except Exception as exc:  # noqa: BLE001 - one broken input must not lose the report
            blocks = (NotAvailable(f"could not build this section ({exc})"),)
        out.append(Section(key, title, blocks))
    return out


def build_report(out_dir, *, study=None, title: str | None = None, filename: str = "report.html",
                 force: bool = False, progress=None) -> Path:
    """Write ``out_dir/report.html``.

    Parameters
    ----------
    out_dir : path
        The folder the pipeline commands wrote into.
    study : path, optional
        The study (or experiment) folder; default: from the provenance files.
    title : str, optional
    force : bool
        Replace an existing report.
    progress : callable, optional
        Called with each section's id as it is built.

    Returns
    -------
    Path
    """
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"{out_dir}: output folder not found")
    _refuse_input_folder(out_dir)
    target = out_dir / filename
    if target.exists() and not force:
        raise FileExistsError(f"{target}: exists; use --force to replace it")
    inp = Inputs(out_dir, study)
    sections = _sections(inp, progress)
    title = title or f"notchfit report: {inp.study_path.name if inp.study_path else out_dir.name}"
    page = Page(title=title, version=__version__, created=_dt.datetime.now().strftime("%Y-%m-%d %H:%M"),
                study=inp.rel(inp.study_path) if inp.study_path else "", sections=tuple(sections), angles=inp.angles)
    return nio.write_text_atomic(render_page(page), target)
