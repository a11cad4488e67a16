"""Reliability (issue 16), determinism: the same inputs and seed give byte-identical CSV and JSON
outputs, run serially or with worker processes (``--jobs 2``). The run records differ only in the
wall-clock ``time`` they note.
"""

from __future__ import annotations

import json

import pytest

from reliability_helpers import make_study, run_main, snapshot


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    return make_study(tmp_path_factory.mktemp("rel_det") / "study", n_experiments=3)


def _outputs(folder) -> dict:
    """CSV and JSON outputs; JSON without the wall-clock ``time`` of the run record."""
    out = {}
    for rel, data in snapshot(folder).items():
        if rel.endswith(".json"):
            d = json.loads(data)
            d.pop("time", None)
            out[rel] = json.dumps(d, sort_keys=True)
        elif rel.endswith(".csv") or rel.endswith(".toml"):
            out[rel] = data
    return out


@pytest.mark.parametrize("command,extra", [("fit", ["--models", "cc,linear"]), ("simulate", [])])
def test_serial_and_parallel_runs_are_byte_identical(command, extra, study, tmp_path, capsys):
    runs = {}
    for label, jobs in (("serial", "1"), ("again", "1"), ("jobs2", "2")):
        out = tmp_path / label
        rc = run_main([command, study, "--out", out, "--no-figures", "--jobs", jobs, *extra], capsys)[0]
        assert rc == 0
        runs[label] = _outputs(out)
    assert len(runs["serial"]) >= 4
    assert runs["serial"] == runs["again"] == runs["jobs2"]


@pytest.mark.parametrize("narrow", [
    pytest.param(["--causes", "joint_hysteresis,calibration_error", "--max-folds", "2"], id="two-candidates"),
    pytest.param([], id="every-candidate", marks=pytest.mark.slow)])
def test_diagnose_is_byte_identical_serial_and_parallel(study, tmp_path, capsys, narrow):
    """The default job tries two candidates on two folds (six calibrations to share between two workers);
    the slow job every candidate on every fold."""
    runs = {}
    for label, jobs in (("serial", "1"), ("jobs2", "2")):
        out = tmp_path / label
        assert run_main(["diagnose", study, "--out", out, "--no-figures", "--jobs", jobs, "--seed", "3", *narrow],
                        capsys)[0] == 0
        runs[label] = _outputs(out)
    assert set(runs["serial"]) == {"diagnosis.json", "extended_model.toml"}
    assert runs["serial"] == runs["jobs2"]
