"""notchfit.report: one self-contained HTML file per study."""
import json
import re

import cv2
import matplotlib
import numpy as np
import pandas as pd
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from notchfit import io, report  # noqa: E402

SECTION_IDS = [k for k, _ in report.SECTIONS]


def _sections(html):
    return {m.group(1): m.group(2) for m in re.finditer(r'<section id="(\w+)">(.*?)</section>', html, re.S)}


def _self_contained(html):
    srcs = re.findall(r'\ssrc="([^"]*)"', html)
    hrefs = re.findall(r'\shref="([^"]*)"', html)
    assert all(s.startswith("data:image/png;base64,") for s in srcs)
    assert all(h.startswith("#") for h in hrefs)
    assert "<link" not in html and "<script" not in html
    return len(srcs)


def test_empty_folder_every_section_says_why(tmp_path):
    p = report.build_report(tmp_path)
    html = p.read_text()
    secs = _sections(html)
    assert list(secs) == SECTION_IDS
    for k in ("study", "calibration", "detection", "fit", "simulation", "diagnosis"):
        assert "not available:" in secs[k], k
    assert "no diagnosis.json" in secs["diagnosis"] and "no fits.csv" in secs["fit"]
    assert _self_contained(html) == 0
    with pytest.raises(FileExistsError, match="--force"):
        report.build_report(tmp_path)


def _png(path):
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.plot([0, 1], [0, 1])
    fig.savefig(path)
    plt.close(fig)


@pytest.fixture
def full_run(tmp_path, geom):
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
    samples = pd.DataFrame({"sample": [1, 2, 3], "time_s": [5.0, 10, 15], "tension_left_N": [0.45, 10, 0.45],
                            "tension_right_N": [0.45] * 3, "image": [f"images/{s:04d}.png" for s in (1, 2, 3)]})
    io.write_experiment(exp, name="L045", samples=samples, calibration="../camera.yml")
    out = tmp_path / "out"
    (out / "L045").mkdir(parents=True)
    det = pd.DataFrame({"sample": np.repeat([1, 2, 3], 4), "point": np.tile([1, 2, 3, 4], 3),
                        "x_mm": 0.0, "y_mm": 0.0, "u_px": 10.0 + np.arange(12), "v_px": 20.0,
                        "sigma_mm": 0.01, "status": ["ok"] * 11 + ["low_contrast"]})
    io.write_table_atomic(det, out / "L045/detections.csv")
    fits = pd.DataFrame({"sample": [1, 2, 3, 1, 2, 3], "model": ["cc"] * 3 + ["linear"] * 3,
                         "a": 0.1, "b": 0.0, "base_x_mm": 1.0, "base_y_mm": 2.0, "base_phi_rad": 0.1,
                         "rms_mm": [0.5, 0.9, 0.4, 0.03, 0.04, 0.03], "max_mm": [1, 2, 1, .1, .1, .1],
                         "n_points": 58, "success": True})
    io.write_table_atomic(fits, out / "L045/fits.csv")
    _png(out / "L045/fig13_pointwise.png")
    sim = pd.DataFrame({"sample": [1, 2, 3], "regime": ["I", "I", "III"], "a": 0.1, "b": -0.001})
    io.write_table_atomic(sim, out / "L045/simulation.csv")
    io.write_table_atomic(pd.DataFrame({"sample": [1, 2, 3], "a_meas": 0.1, "b_meas": 0.0, "a_sim": 0.11,
                                        "b_sim": 0.0, "point_rms_mm": [0.2, 0.3, 0.1]}),
                          out / "L045/simulation_vs_measured.csv")
    _png(out / "L045/fig19_shape_parameters.png")
    diag = {"experiments": ["L045"], "baseline": {"model": "moses2015", "params": {"k_lin": 0.45},
                                                  "heldout_rms_mm": 0.31},
            "discrepancies": [{"signature": "unloading_hold", "value": 6.1, "unit": "N",
                               "text": "the measured shape holds 6.1 N longer <while> unloading"}],
            "candidates": [{"cause": "proximal_friction", "params": {"proximal_beta": 0.09}, "n_params": 1,
                            "train_rms_mm": 0.05, "heldout_rms_mm": 0.06, "aic": 10.0},
                           {"cause": "joint_hysteresis", "params": {"hysteresis_torque": 0.003},
                            "n_params": 1, "train_rms_mm": 0.2, "heldout_rms_mm": 0.25, "aic": 50.0}],
            "cause": "proximal_friction", "explanation": "The band explains the hold.",
            "gain": {"metric": "heldout_rms_mm", "baseline": 0.31, "extended": 0.06, "reduction_pct": 80.6}}
    io.write_json_atomic(diag, out / "diagnosis.json")
    _png(out / "diagnosis_loops.png")
    io.write_json_atomic({"command": "fit", "input": str(study)}, out / "fit_run.json")
    return out, study


def test_full_report_has_every_section(full_run):
    out, study = full_run
    html = report.build_report(out).read_text()
    secs = _sections(html)
    assert list(secs) == SECTION_IDS
    for k in SECTION_IDS:
        assert "not available" not in secs[k], (k, secs[k][:300])
    assert "L045" in secs["study"] and "camera.yml" in secs["calibration"] and "0.07" in secs["calibration"]
    assert "low_contrast" in secs["detection"] and "detected notch points" in secs["detection"]
    assert "fig13_pointwise.png" in secs["fit"] and "0.03" in secs["fit"]
    assert "fig19_shape_parameters.png" in secs["simulation"]
    d = secs["diagnosis"]
    assert "cause: proximal_friction" in d and "&lt;while&gt;" in d and "80.6" in d
    assert "joint_hysteresis" in d and "diagnosis_loops.png" in d
    n_img = _self_contained(html)
    assert n_img == 5  # 2 overlays + fig13 + fig19 + diagnosis
    lines = report.summary_lines(out)
    assert lines[0].startswith("fit errors over 3 samples: cc") and "linear 0.034 mm rms" in lines[0]
    assert lines[1].startswith("cause: proximal_friction") and "80.6 % lower" in lines[2]


def test_broken_input_is_reported_not_fatal(full_run):
    out, _ = full_run
    (out / "diagnosis.json").write_text(json.dumps({"cause": "x"}))
    (out / "L045/fits.csv").write_text("sample,model\n1,cc\n")
    secs = _sections(report.build_report(out, force=True).read_text())
    assert "not available" in secs["diagnosis"] and "missing key(s)" in secs["diagnosis"]
    assert "missing column(s)" in secs["fit"]


def test_report_command(full_run, capsys):
    from notchfit.cli import main

    out, study = full_run
    assert main(["report", str(out), "--study", str(study)]) == 0
    text = capsys.readouterr().out
    assert "cause: proximal_friction" in text and f"report: {out / 'report.html'}" in text
    assert main(["report", str(out)]) == 2            # exists, no --force
    assert "use --force" in capsys.readouterr().err
    assert main(["report", str(out / "nope")]) == 2
