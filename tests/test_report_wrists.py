"""The report of a study measured as joint angles with two tubes, and `diagnose` on several tubes (issue 27).

One reduced study of the shipped recipe ``wrist_stock`` (two nitinol wrists of
5 and 4 notches, loading-only trials, 5 samples per ramp) runs through fit,
identify (no held-out refits, one start), simulate with the identified model, diagnose (two folds, one candidate)
and report; the tests read what each step wrote.
"""

from __future__ import annotations

import functools
import re
import subprocess

import pytest

from notchfit import io, report
from notchfit.cli import main
from notchfit.studies.synth import generate_study, load_recipe

from browser_helpers import chromium_path, no_browser
from test_report import glance_text, noise_floors, numbers_without_unit, sections, tables


@pytest.fixture(scope="module")
def wrist_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("wrists")
    study, out = base / "study", base / "out"
    generate_study(load_recipe("wrist_stock").scaled(n_up=5), study, seed=3)
    assert main(["fit", str(study), "--out", str(out), "--models", "cc,linear", "--no-figures"]) == 0
    assert main(["identify", str(study), "--out", str(out), "--starts", "1", "--no-heldout"]) == 0
    assert main(["simulate", str(study), "--model", str(out / "model.toml"), "--out", str(out)]) == 0
    rc = main(["diagnose", str(study), "--out", str(out), "--assume-step", "--max-folds", "2",
               "--causes", "stiffness_gradient", "--one-cause"])
    html = report.build_report(out).read_text()
    return study, out, rc, html


#: What a page must never show: a section that failed, a Python exception's name, a traceback.
ERROR_TEXT = re.compile(r"could not build|[A-Z]\w*Error\b|Traceback|no fits\.csv")


def error_text(html) -> list[str]:
    return ERROR_TEXT.findall(re.sub(r"<[^>]+>", " ", html))


def test_multi_tube_diagnose_writes_its_figures(wrist_run):
    """diagnose on two tubes of 5 and 4 notches draws every figure: the errors by joint per tube."""
    _, out, rc, _ = wrist_run
    assert rc == 0
    d = io.read_json(out / "diagnosis.json")
    assert set(d["figures"]) >= {"diagnosis_candidates.png", "diagnosis_loops.png", "diagnosis_residuals.png"}
    joints = io.read_diagnosis_csv(out / "diagnosis_joint_errors.csv")
    assert joints.groupby("tube")["joint"].max().to_dict() == {"wrist_asymmetric": 5, "wrist_tip_first": 4}


def test_angle_study_report_reads_right(wrist_run):
    """No raw error, fit found in angle_fits.csv, identify's results shown, degrees throughout, no signature
    of unloading for trials that never unload."""
    _, _, _, html = wrist_run
    secs = sections(html)
    assert error_text(html) == []
    assert "not available" not in secs["fit"] and "not available" not in secs["simulation"]
    assert "not available" not in secs["identify"] and "E_lin = " in secs["identify"]
    headers = [c for body in secs.values() for t in tables(body) for c in t.columns]
    assert not [c for c in headers if re.search(r"\brad\b", c)], headers         # degrees throughout an angle study
    assert "degrees per joint" in secs["summary"]
    assert not re.search(r"\d rad\b", re.sub(r"<[^>]+>", "", html)), "a value in rad on an angle study's page"
    for sig in ("unloading_hold", "b_unloading_error", "residual_bend", "loop_area_ratio"):
        assert sig not in secs["diagnosis"]


def test_two_tube_study_described_as_two_tubes(wrist_run):
    """The study section and the first section name both tubes with their own geometry; identify's table
    has a row per tube."""
    _, _, _, html = wrist_run
    secs = sections(html)
    geo = tables(secs["study"])[0]
    assert list(geo["tube"]) == ["wrist_asymmetric", "wrist_tip_first"] and list(geo["joints"]) == ["5", "4"]
    assert "2 tubes" in secs["summary"]
    tubes = [t for t in tables(secs["identify"]) if "tube" in t.columns][0]
    assert list(tubes["tube"]) == ["wrist_asymmetric", "wrist_tip_first"]


def test_first_section_numbers_have_units_and_one_noise_floor(wrist_run):
    """Every number of the first section carries its unit; the noise floor is one number (issue 29)."""
    _, _, _, html = wrist_run
    text = glance_text(html)
    assert text.index("Model misses") < text.index("Cause")
    assert numbers_without_unit(text) == []
    assert len(noise_floors(html)) == 1


# ----------------------------------------------------------------------------- in a real browser
CHROMIUM = chromium_path()


def needs_chromium(test):
    """Run ``test`` in a real browser; without one, skip (or fail where one is required: CI)."""
    @functools.wraps(test)
    def wrapper(*args, **kwargs):
        if CHROMIUM is None:
            no_browser("no Chromium: the report is not checked in a real browser (apt-get install chromium)")
        return test(*args, **kwargs)
    return wrapper


def load_in_chromium(page, workdir):
    """The report as headless Chromium lays it out: its DOM text and a screenshot (PNG bytes)."""
    args = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-sync",
            "--disable-background-networking", "--disable-component-update", f"--user-data-dir={workdir / 'profile'}",
            "--window-size=1400,3000"]
    url = page.resolve().as_uri()
    dom = subprocess.run([*args, "--dump-dom", url], capture_output=True, text=True, timeout=120).stdout
    shot = workdir / "shot.png"
    subprocess.run([*args, f"--screenshot={shot}", url], capture_output=True, timeout=120)
    return dom, shot.read_bytes() if shot.is_file() else b""


def check_in_browser(page, workdir):
    dom, png = load_in_chromium(page, workdir)
    assert "<section id=\"summary\">" in dom and "Model misses" in dom
    assert error_text(dom) == []
    assert png.startswith(b"\x89PNG") and len(png) > 50_000          # a laid-out page, not a blank one


@needs_chromium
def test_angle_and_two_tube_report_in_a_browser(wrist_run, tmp_path):
    """The report of a two-tube study measured as joint angles, loaded in headless Chromium: no error text."""
    _, out, _, _ = wrist_run
    check_in_browser(out / "report.html", tmp_path)
