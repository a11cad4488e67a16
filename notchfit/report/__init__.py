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
``diagnosis``      ``diagnosis.json``: each named cause, candidates, signatures,
                   the baseline's and the extension's parameters, figures
``files``          links to every per-experiment figure and the raw outputs
=================  ==========================================================

One convention throughout: ``a``, joint and tip angles in rad, ``b`` in rad
per joint, signed in the manipulator frame (CONVENTIONS.md); lengths in mm.
The diagnosis's own CSV of older versions (tip angle toward the pulled
cable) is converted. The study folder is the one given with ``study=``, or
the ``input`` recorded in a ``*_run.json`` provenance file.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

from .. import io as nio
from .._version import __version__
from ..cables import pulled_side
from .page import CSS, esc, na, num, rel
from .sections import (causes_of, detection_section, diagnosis_section, files_section, fit_section,
                              fit_summary, glance_section, simulation_section, study_section, unit_of)

__all__ = ["SECTIONS", "Inputs", "build_report", "find_study", "summary_lines"]

SECTIONS = (
    ("summary", "At a glance"),
    ("study", "Study"),
    ("detection", "Camera and detection"),
    ("fit", "Shape fits (Figs. 12–15)"),
    ("simulation", "Simulation vs measurement (Figs. 18–19)"),
    ("diagnosis", "Diagnosis"),
    ("files", "Files"),
)


# ----------------------------------------------------------------------------- study
def find_study(out_dir) -> Path | None:
    """The study folder recorded by ``fit``/``simulate``/``diagnose`` provenance files, if any."""
    out_dir = Path(out_dir)
    for p in sorted(out_dir.glob("*_run.json")):
        try:
            d = nio.read_json(p)
        except (ValueError, OSError):
            continue
        inp = d.get("input")
        if inp and Path(inp).is_dir():
            return Path(inp)
    return None


class Inputs:
    """What the report reads, once: the output folder, the study and its experiments, the run records.

    Attributes
    ----------
    out : Path
    study_path : Path or None
    exps : list of Experiment, or None
    why : str
        Why ``exps`` is None.
    pulled : dict
        ``{experiment: +1 right | -1 left}`` (:func:`notchfit.cables.pulled_side`).
    truth : dict or None
        ``truth.json`` of a synthetic study (the hidden effect).
    runs : dict
        ``{command: record}`` of the ``*_run.json`` files.
    diagnosis : dict or None
    diagnosis_error : str or None
    """

    def __init__(self, out_dir: Path, study=None):
        self.out = out_dir
        self.study_path = Path(study) if study is not None else find_study(out_dir)
        self.exps, self.why = None, "no study folder known (give --study STUDY)"
        if self.study_path is not None:
            try:
                self.exps = nio.read_study(self.study_path, missing_images="keep")
            except (ValueError, FileNotFoundError) as exc:
                self.why = f"cannot read the study: {exc}"
        self.by_name = {e.name: e for e in self.exps or []}
        self.pulled = {e.name: pulled_side(e.tension_left, e.tension_right) for e in self.exps or []}
        self.truth = self._json(self.study_path / "truth.json") if self.study_path else None
        self.runs = {}
        for p in sorted(out_dir.glob("*_run.json")):
            rec = self._json(p)
            if rec:
                self.runs[rec.get("command", p.stem[:-4])] = rec
        self.diagnosis, self.diagnosis_error = None, None
        if (out_dir / "diagnosis.json").is_file():
            try:
                self.diagnosis = nio.read_diagnosis(out_dir / "diagnosis.json")
            except ValueError as exc:
                self.diagnosis_error = str(exc)
        self._once: dict = {}

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


# ----------------------------------------------------------------------------- summary lines
def summary_lines(out_dir) -> list[str]:
    """Three lines: fit errors, the named cause(s), the measured gain (what is available)."""
    out_dir = Path(out_dir)
    st = fit_summary(out_dir)
    if st is None:
        lines = ["fit errors: not available (no fits.csv)"]
    else:
        txt = "; ".join(f"{r.model} {num(r.rms_mm)} mm rms (max {num(r.max_mm)} mm)" for r in st.itertuples())
        lines = [f"fit errors over {int(st['samples'].iloc[0])} samples: {txt}"]
    path = out_dir / "diagnosis.json"
    if not path.is_file():
        return lines + ["cause: not available (no diagnosis.json)", "gain: not available (no diagnosis.json)"]
    try:
        d = nio.read_diagnosis(path)
    except ValueError as exc:
        return lines + [f"cause: not available ({exc})", "gain: not available"]
    b, g, u = d.get("baseline") or {}, d.get("gain") or {}, unit_of(d)
    lines.append(f"cause: {', '.join(causes_of(d))} (calibrated baseline held-out rms "
                 f"{num(b.get(f'heldout_rms_{u}'))} {u})")
    lines.append(f"gain: held-out rms {num(g.get('baseline'))} -> {num(g.get('extended'))} {u} "
                 f"({num(g.get('reduction_pct'), 3)} % lower)")
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


def _sections(inp: Inputs, progress=None) -> dict:
    """Every section's HTML; one that fails says why and the others are built."""
    builders = {"summary": glance_section, "study": study_section, "detection": detection_section,
                "fit": fit_section, "simulation": simulation_section, "diagnosis": diagnosis_section,
                "files": files_section}
    body = {}
    for key, _ in SECTIONS:
        if progress is not None:
            progress(key)
        try:
            body[key] = builders[key](inp)
        except Exception as exc:  # noqa: BLE001 - one broken input must not lose the report
            body[key] = na(f"could not build this section: {type(exc).__name__}: {exc}")
    return body


def _header(inp: Inputs, title: str) -> str:
    now = _dt.datetime.now().strftime("%Y-%m-%d %H:%M")
    where = f"study <code>{esc(inp.rel(inp.study_path))}</code>, " if inp.study_path else ""
    nav = "".join(f'<a href="#{k}">{esc(t)}</a>' for k, t in SECTIONS)
    return (f"<h1>{esc(title)}</h1><p class=\"meta\">notchfit {__version__} · {now} · {where}"
            f"results: this folder</p><nav>{nav}</nav>\n")


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
    body = _sections(inp, progress)
    title = title or f"notchfit report: {inp.study_path.name if inp.study_path else out_dir.name}"
    secs = "\n".join(f'<section id="{k}"><h2>{esc(t)}</h2>\n{body[k]}\n</section>' for k, t in SECTIONS)
    doc = (f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
           f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
           f"<title>{esc(title)}</title><style>{CSS}</style></head><body>\n"
           f"{_header(inp, title)}{secs}\n</body></html>\n")
    return nio.write_text_atomic(doc, target)

