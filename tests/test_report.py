"""notchfit.report: one HTML report per study that reads at a glance (issue 17)."""
import json
import re
from html.parser import HTMLParser

import cv2
import numpy as np
import pandas as pd
import pytest

from notchfit import io, report

SECTION_IDS = [k for k, _ in report.SECTIONS]


def sections(html):
    return {m.group(1): m.group(2) for m in re.finditer(r'<section id="(\w+)">(.*?)</section>', html, re.S)}


class _Tables(HTMLParser):
    """Every <table> as (header, rows) of cell texts."""

    def __init__(self):
        super().__init__()
        self.tables, self._cell, self._row = [], None, None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr" and self.tables:
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.tables[-1].append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def tables(html) -> list[pd.DataFrame]:
    """The tables of an HTML fragment, header row as columns."""
    p = _Tables()
    p.feed(html)
    return [pd.DataFrame(t[1:], columns=t[0]) for t in p.tables if len(t) > 1]


def page_links(html):
    srcs = re.findall(r'\ssrc="([^"]*)"', html)
    hrefs = re.findall(r'\shref="([^"]*)"', html)
    return srcs, hrefs


def check_self_standing(html):
    """Figures embedded; links only inside the page or relative to the report's folder; no raw dump."""
    srcs, hrefs = page_links(html)
    assert all(s.startswith("data:image/png;base64,") for s in srcs)
    assert not [h for h in hrefs if re.match(r"(https?:|//|file:|/)", h)], hrefs
    assert "<link" not in html and "<script" not in html and "<pre>" not in html
    return len(srcs)


#: A number in running text: a decimal, a power of ten, or a percentage's digits.
NUMBER = re.compile(r"(?<![\w.×⁻])[-+−]?\d+\.\d+(?:×10[⁻⁰¹²³⁴⁵⁶⁷⁸⁹]+)?")
#: What may follow a measured number: its unit (or ×, %, a ratio's "×").
UNIT = re.compile(r"(–[-+−]?[\d.]+)?\s?(mm|°|deg|N m/rad|N m s/rad|N m|N|rad|s|px|%|×|GPa|m/s|µm)(?![a-zA-Z])")


def glance_text(html) -> str:
    body = sections(html)["summary"]
    body = body[:body.index('<p class="conv">')] if '<p class="conv">' in body else body
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", "", body)).replace("&#39;", "'")


def numbers_without_unit(text) -> list[str]:
    """Every decimal number of ``text`` not followed by a unit (symbols such as β = 0.104 are parameters
    given with their symbol: a unitless coefficient is allowed after ``=``)."""
    bad = []
    for m in NUMBER.finditer(text):
        after = text[m.end():]
        before = text[max(0, m.start() - 3):m.start()]
        if not UNIT.match(after) and "=" not in before:
            bad.append(text[max(0, m.start() - 40):m.end() + 10])
    return bad


def noise_floors(html) -> set[str]:
    text = re.sub(r"<[^>]+>", "", html)
    return set(re.findall(r"noise floor,? (?:of )?([\d.]+)", text))


def test_empty_folder_every_section_says_why(tmp_path):
    html = report.build_report(tmp_path).read_text()
    secs = sections(html)
    assert list(secs) == SECTION_IDS
    for k in ("study", "detection", "fit", "simulation", "diagnosis"):
        assert "not available:" in secs[k], k
    assert "no diagnosis.json" in secs["diagnosis"] and "no fits.csv" in secs["fit"]
    assert check_self_standing(html) == 0
    with pytest.raises(FileExistsError, match="--force"):
        report.build_report(tmp_path)


def write_full_run(tmp_path):
    """A study of one left-pulled experiment with images, and every output file, written by hand."""
    study = tmp_path / "study"
    exp = study / "L045"
    (exp / "images").mkdir(parents=True)
    S = 3
    for s in range(1, S + 1):
        cv2.imwrite(str(exp / f"images/{s:04d}.png"), np.full((60, 80), 40 * s, np.uint8))
    fs = cv2.FileStorage(str(study / "camera.yml"), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", np.array([[2000.0, 0, 40], [0, 2000.0, 30], [0, 0, 1]]))
    fs.write("distortion_coefficients", np.zeros((1, 5)))
    fs.write("image_width", 80)
    fs.write("image_height", 60)
    fs.write("avg_reprojection_error", 0.07)
    fs.write("plane_rvec", np.zeros((3, 1)))
    fs.write("plane_tvec", np.array([[0.0], [0.0], [150.0]]))
    fs.release()
    T = [0.45, 10, 0.45]
    samples = pd.DataFrame({"sample": [1, 2, 3], "time_s": [5.0, 10, 15], "tension_left_N": T,
                            "tension_right_N": [0.45] * 3, "image": [f"images/{s:04d}.png" for s in (1, 2, 3)]})
    io.write_experiment(exp, name="L045", samples=samples, calibration="../camera.yml")
    out = tmp_path / "out"
    (out / "L045").mkdir(parents=True)
    det = pd.DataFrame({"sample": np.repeat([1, 2, 3], 4), "point": np.tile([1, 2, 3, 4], 3),
                        "x_mm": 0.0, "y_mm": 0.0, "u_px": 10.0 + np.arange(12), "v_px": 20.0 + np.arange(12) % 3,
                        "sigma_mm": 0.01, "status": ["ok"] * 11 + ["ambiguous"]})
    io.write_table_atomic(det, out / "L045/detections.csv")
    fits = pd.DataFrame({"sample": [1, 2, 3, 1, 2, 3], "model": ["cc"] * 3 + ["linear"] * 3,
                         "a": [0.0, -0.1, 0.0, 0.0, -0.12, -0.01], "b": [0, 0, 0, 0, 0.004, 0.0],
                         "base_x_mm": 1.0, "base_y_mm": 2.0, "base_phi_rad": 0.1,
                         "rms_mm": [0.5, 0.9, 0.4, 0.03, 0.04, 0.03], "max_mm": [1, 2, 1, .1, .1, .1],
                         "n_points": 58, "success": True})
    io.write_table_atomic(fits, out / "L045/fits.csv")
    io.write_table_atomic(pd.DataFrame({"sample": np.repeat([1, 2, 3], 2), "model": "linear",
                                        "point": np.tile([1, 2], 3), "err_mm": 0.03}), out / "L045/pointwise.csv")
    (out / "L045/fig13_pointwise.png").write_bytes(b"\x89PNG fake")
    sim = pd.DataFrame({"sample": [1, 2, 3], "regime": ["I", "I", "III"], "a": -0.1, "b": 0.003})
    io.write_table_atomic(sim, out / "L045/simulation.csv")
    io.write_table_atomic(pd.DataFrame({"sample": [1, 2, 3], "tension_left_N": T, "tension_right_N": 0.45,
                                        "regime": ["I", "I", "III"], "a_meas": [0.0, -0.12, -0.01],
                                        "b_meas": [0.0, 0.004, 0.0], "a_sim": [0.0, -0.13, 0.0],
                                        "b_sim": [0.0, 0.003, 0.0], "point_rms_mm": [0.2, 0.3, 0.1]}),
                          out / "L045/simulation_vs_measured.csv")
    diag = {"experiments": ["L045"],
            "baseline": {"model": "moses2015", "params": {"k_lin": 0.45, "k_mid": 0.2, "mu_d": 0.3},
                         "se": {"k_lin": 0.01, "k_mid": 0.02, "mu_d": 0.01},
                         "fixed": {"mu_s_minus_mu_d": 0.01, "b": 0.03, "v_thr": 5e-5}, "heldout_rms_mm": 0.31},
            "noise_rms_mm": 0.05,
            "discrepancies": [{"signature": "unloading_hold", "value": 6.1, "unit": "N",
                               "text": "the measured shape holds 6.1 N longer <while> unloading"}],
            "candidates": [{"cause": "proximal_friction", "params": {"proximal_beta": 0.09}, "n_params": 1,
                            "train_rms_mm": 0.05, "heldout_rms_mm": 0.06, "aic": 10.0, "z": 9.0,
                            "excess_removed": 0.97, "significant": True},
                           {"cause": "joint_hysteresis", "params": {"hysteresis_torque": 0.003},
                            "n_params": 1, "train_rms_mm": 0.2, "heldout_rms_mm": 0.25, "aic": 50.0}],
            "cause": "proximal_friction", "explanation": "The band explains the hold <while> unloading.",
            "extended_model": {"cause": "proximal_friction", "params": {"k_lin": 0.46, "proximal_beta": 0.1}},
            "gain": {"metric": "heldout_rms_mm", "baseline": 0.31, "extended": 0.06, "reduction_pct": 80.6},
            "extended_model_file": "extended_model.toml"}
    io.write_json_atomic(diag, out / "diagnosis.json")
    # a diagnosis_loops.csv of the earlier layout: signed toward the pulled (left) cable, no pulled_cable
    io.write_table_atomic(pd.DataFrame({"experiment": "L045", "sample": [0, 1, 2] * 2,
                                        "tension_pulled_N": T * 2, "series": ["measured"] * 3 + ["baseline"] * 3,
                                        "tip_angle_rad": [0.0, 1.5, 0.1, 0.0, 1.4, 0.0],
                                        "b_rad": [0.0, -0.004, 0.0, 0.0, -0.003, 0.0]}), out / "diagnosis_loops.csv")
    io.write_json_atomic({"command": "fit", "input": str(study)}, out / "fit_run.json")
    io.write_json_atomic({"command": "simulate", "input": str(study), "params": {
        "k_lin": 0.4829, "k_mid": 0.25, "k_stop": 10.0, "theta_mid": 0.07, "theta_stop": 0.14, "mu_d": 0.29,
        "mu_s": 0.3, "b": 0.03, "v_thr": 5e-05, "proximal_beta": 0.0, "hysteresis_torque": 0.0,
        "tip_force_x": 0.0, "tip_force_z": 0.0, "stiffness_gradient": 0.0}, "model_file": None},
        out / "simulate_run.json")
    return out, study


@pytest.fixture
def full_run(tmp_path):
    """:func:`write_full_run` for a test that changes the outputs."""
    return write_full_run(tmp_path)


@pytest.fixture(scope="module")
def full_page(tmp_path_factory):
    """:func:`write_full_run` and its report, built once for the tests that only read them."""
    out, study = write_full_run(tmp_path_factory.mktemp("full_page"))
    return out, study, report.build_report(out).read_text()


def test_full_report_reads_at_a_glance(full_page):
    out, study, html = full_page
    secs = sections(html)
    assert list(secs) == SECTION_IDS
    for k in SECTION_IDS:
        if k != "identify":                 # a points study diagnosed, not identified
            assert "not available" not in secs[k], (k, secs[k][:300])
    assert "no identify.json" in secs["identify"]
    glance = secs["summary"]
    for row in ("Question", "Measured", "Cause", "Gain", "Assumed"):
        assert f"<th>{row}</th>" in glance
    assert "proximal friction" in glance and "80.6" not in glance and "81 % lower" in glance
    assert "Units and signs in every section" in glance and "rad per joint" in glance
    # relative paths only: the study is ../study, no absolute path of this machine anywhere
    assert "../study" in html and str(out) not in html and str(study) not in html
    assert "ambiguous" in secs["detection"] and "camera.yml" in secs["detection"] and "0.070 px" in secs["detection"]
    assert re.search(r'href="L045/fig13_pointwise.png"', secs["files"])
    d = secs["diagnosis"]
    assert "Cause 1: proximal friction" in d and "&lt;while&gt;" in d and 'href="diagnosis.json"' in d
    assert "joint_hysteresis" in d and "The band explains the hold" in d
    # the signature's value with the 0.01 N the tensions resolve, its meaning in words
    assert "extra tension the measured shape holds while unloading" in d and "6.10 N" in d
    assert check_self_standing(html) >= 2
    lines = report.summary_lines(out)
    assert lines[0].startswith("fit errors over 3 samples: cc") and "linear 0.0337 mm rms" in lines[0]
    assert lines[1].startswith("cause: proximal_friction") and "80.6 % lower" in lines[2]


def test_every_simulation_states_its_parameters(full_page, full_run):
    """The simulation section names the paper's defaults (or the model file) with their values; the
    diagnosis names the calibrated baseline and the extended model with theirs (issue 17)."""
    out, _ = full_run
    secs = sections(full_page[2])
    sim = re.search(r'<p class="params">(.*?)</p>', secs["simulation"], re.S).group(1)
    assert "paper's default values" in sim and "k_lin = 0.4829 N m/rad" in sim and "μ_d = 0.29" in sim
    diag = re.search(r'<p class="params">(.*?)</p>', secs["diagnosis"], re.S).group(1)
    assert "calibrated" in diag and "k_lin = 0.45 ± 0.01" in diag and "μ_s − μ_d = 0.01" in diag
    assert "Extended (proximal friction" in diag and "β = 0.1" in diag
    # a model file: named instead of "defaults"
    rec = io.read_json(out / "simulate_run.json")
    io.write_json_atomic({**rec, "model_file": "ext/extended_model.toml",
                          "params": {**rec["params"], "proximal_beta": 0.1}}, out / "simulate_run.json")
    sim = re.search(r'<p class="params">(.*?)</p>', sections(report.build_report(out, force=True).read_text())
                    ["simulation"], re.S).group(1)
    assert "model file <code>ext/extended_model.toml</code>" in sim and "extension β = 0.1" in sim
    # --param overrides: named with their values
    io.write_json_atomic({**rec, "param_overrides": ["mu_d=0.25"], "params": {**rec["params"], "mu_d": 0.25}},
                         out / "simulate_run.json")
    sim = re.search(r'<p class="params">(.*?)</p>', sections(report.build_report(out, force=True).read_text())
                    ["simulation"], re.S).group(1)
    assert "--param mu_d=0.25" in sim and "μ_d = 0.25" in sim and "default values" not in sim


def b_signs(html) -> dict:
    """``{(section, column): {experiment: sign}}`` of every "b at peak" column of the report's tables."""
    found = {}
    for key, body in sections(html).items():
        for t in tables(body):
            for col in [c for c in t.columns if c.startswith("b at peak")]:
                vals = {r["experiment"]: np.sign(float(r[col])) for _, r in t.iterrows() if r[col] not in ("", "–")}
                found[(key, col)] = vals
    return found


def test_one_sign_convention_for_b(full_page):
    """The same experiment's measured b has the same sign in every section, the manipulator frame's: a
    left pull bends toward −x (a < 0) with b > 0 here, also from a diagnosis CSV of the older layout
    that was signed toward the pulled cable."""
    found = b_signs(full_page[2])
    measured = {k: v for k, v in found.items() if "measured" in k[1] or k[0] == "fit"}
    assert {k[0] for k in measured} == {"fit", "simulation", "diagnosis"}, found
    assert all(v == {"L045": 1.0} for v in measured.values()), measured


def test_diagnosis_loops_over_causes(full_run):
    """diagnosis.json with "causes" (several named): a part per cause, in order; the glance names all."""
    out, _ = full_run
    d = io.read_json(out / "diagnosis.json")
    io.write_json_atomic({**d, "causes": ["proximal_friction", "joint_hysteresis"]}, out / "diagnosis.json")
    secs = sections(report.build_report(out, force=True).read_text())
    i1, i2 = secs["diagnosis"].index("Cause 1: proximal friction"), secs["diagnosis"].index("Cause 2: joint hysteresis")
    assert i1 < i2
    assert "joint hysteresis</b>" in secs["summary"]
    assert report.summary_lines(out)[1].startswith("cause: proximal_friction, joint_hysteresis")


def test_broken_input_is_reported_not_fatal(full_run):
    out, _ = full_run
    (out / "diagnosis.json").write_text(json.dumps({"cause": "x"}))
    (out / "L045/fits.csv").write_text("sample,model\n1,cc\n")
    secs = sections(report.build_report(out, force=True).read_text())
    assert "not available" in secs["diagnosis"] and "missing key(s)" in secs["diagnosis"]
    assert "not available" in secs["fit"]


def test_report_command(full_run, capsys):
    from notchfit.cli import main

    out, study = full_run
    assert main(["report", str(out), "--study", str(study)]) == 0
    text = capsys.readouterr().out
    assert "cause: proximal_friction" in text and f"report: {out / 'report.html'}" in text
    assert main(["report", str(out)]) == 2            # exists, no --force
    assert "use --force" in capsys.readouterr().err
    assert main(["report", str(out / "nope")]) == 2


def test_numbers_with_sensible_digits():
    from notchfit.report.page import num, pct

    assert [num(0.6471040669823731), num(27.66), num(0.004990, 2, sign=True), num(-0.128, sign=True)] == \
        ["0.647", "27.7", "+0.0050", "-0.128"]
    assert num(5e-05, 4, trim=True) == "5×10⁻⁵" and num(0.01, 4, trim=True) == "0.01" and num(None) == "–"
    assert pct(81.6071) == "82 %" and pct(5.31) == "5.3 %" and pct(float("nan")) == "–"


def test_first_section_numbers_have_units_and_one_noise_floor(full_page):
    """The first line says what the model misses before the cause; every number of the first section
    carries its unit; the noise floor is one number on the whole page (issue 29)."""
    html = full_page[2]
    text = glance_text(html)
    assert text.index("Model misses") < text.index("Cause")
    assert "misses the held-out notch points by 0.310 mm rms, 6.2× the noise floor" in text
    assert numbers_without_unit(text) == []
    assert noise_floors(html) == {"0.0500"}
