"""One way through the commands: where fit, simulate and diagnose find measured points (issue 17).

The order is the experiment's own files, then the detect run named by
``--points``, then the ``--out`` folder (notchfit.io.find_points); each
command says which it used, and one that cannot compare says how to fix it.
"""
import shutil

import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.cli import main
from notchfit.studies.synth import generate_study, load_recipe


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("points") / "study"
    generate_study(load_recipe("proximal_friction").scaled(n_experiments=2, n_up=4, n_down=4), d, seed=2)
    return d


def _detections(exp, shift_mm: float = 0.0):
    """A detect run's detections.csv for ``exp`` (its own points, shifted by ``shift_mm`` in x)."""
    t = io.points_table(exp.points, exp.sample_ids)
    t["x_mm"] += shift_mm
    return t.assign(u_px=1.0, v_px=1.0, sigma_mm=0.01, status="ok")


def _without_own_points(study, dest):
    """A copy of ``study`` as a study of images is: one (blank) image per sample, no notch_points.csv."""
    shutil.copytree(study, dest)
    for e in io.read_study(dest):
        (e.path / "notch_points.csv").unlink()
        (e.path / "images").mkdir()
        names = [f"images/{s:04d}.png" for s in e.sample_ids]
        for n in names:
            io.write_image(e.path / n, np.full((8, 8), 128, np.uint8))
        samples = pd.read_csv(e.path / "samples.csv").assign(image=names)
        samples.to_csv(e.path / "samples.csv", index=False)
    return dest


def test_find_points_order_own_then_points_then_out(study, tmp_path):
    exps = io.read_study(study)
    bare = io.read_study(_without_own_points(study, tmp_path / "bare"), missing_images="keep")
    det_a, det_b = tmp_path / "detect_a", tmp_path / "detect_b"
    for e in exps:
        io.write_table_atomic(_detections(e, 1.0), det_a / e.name / "detections.csv")
        io.write_table_atomic(_detections(e, 2.0), det_b / e.name / "detections.csv")
    # own files first, whatever the folders hold
    own = io.find_points(exps, [("--points", det_a), ("--out", det_b)])
    assert {w for w, _ in own.sources.values()} == {"own"} and not own.problems
    # then --points, then --out
    got = io.find_points(bare, [("--points", det_a), ("--out", det_b)])
    assert {w for w, _ in got.sources.values()} == {"--points"}
    np.testing.assert_allclose(got.experiments[0].points, exps[0].points + [1e-3, 0.0], atol=1e-12)
    (det_a / exps[1].name / "detections.csv").unlink()
    got = io.find_points(bare, [("--points", det_a), ("--out", det_b)])
    assert got.sources[exps[1].name][0] == "--out"
    np.testing.assert_allclose(got.experiments[1].points, exps[1].points + [2e-3, 0.0], atol=1e-12)
    # nowhere: the reason names every folder searched
    none = io.find_points(bare, [("--points", None), ("--out", tmp_path / "empty")])
    assert not none.experiments and "empty (--out)" in none.problems[exps[0].name]
    # a detections.csv that is found but broken is that experiment's problem, not skipped for --out
    (det_a / exps[0].name / "detections.csv").write_text("sample,point\n1,1\n")
    got = io.find_points(bare, [("--points", det_a), ("--out", det_b)])
    assert "missing column" in got.problems[exps[0].name]


def test_fit_simulate_diagnose_say_where_points_came_from(study, tmp_path, capsys):
    bare = _without_own_points(study, tmp_path / "bare")
    out = tmp_path / "out"
    for e in io.read_study(study):
        io.write_table_atomic(_detections(e), out / e.name / "detections.csv")
    assert main(["fit", str(bare), "--out", str(out), "--models", "linear", "--no-figures"]) == 0
    text = capsys.readouterr().out
    assert "fit: points of L045, L150 from detections.csv in" in text and "(--out)" in text
    assert main(["simulate", str(bare), "--out", str(out), "--no-figures"]) == 0
    assert "simulate: points of L045, L150 from detections.csv" in capsys.readouterr().out
    assert main(["fit", str(study), "--out", str(tmp_path / "own"), "--models", "linear", "--no-figures"]) == 0
    assert "fit: points of L045, L150 from their own notch_points.csv" in capsys.readouterr().out


def test_a_command_that_cannot_compare_says_how_to_fix_it(study, tmp_path, capsys):
    bare = _without_own_points(study, tmp_path / "bare")
    assert main(["simulate", str(bare), "--out", str(tmp_path / "sim"), "--no-figures"]) == 0
    text = capsys.readouterr().out
    assert "no measured points or angles for L045, L150: simulated without a comparison" in text
    assert "run `notchfit detect STUDY --out DIR` first" in text
    assert not (tmp_path / "sim" / "L045" / "simulation_vs_measured.csv").exists()
    for argv in (["fit", "--models", "linear"], ["diagnose"]):
        assert main([argv[0], str(bare), "--out", str(tmp_path / argv[0]), *argv[1:]]) == 2
        err = capsys.readouterr().err
        assert "no notch_points.csv, no angles.csv and no detections.csv" in err and "--points DIR" in err, err
