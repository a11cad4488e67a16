"""Reliability (issue 16), faults of a run: nothing skipped in silence, Ctrl-C and SIGTERM, two runs
into one --out, a full disk. Each test asserts the exit code, the one message line (naming the
file or folder), and that earlier outputs are byte-identical afterwards (data lost: none).
"""

from __future__ import annotations

import argparse
import errno
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import psutil
import pytest

from notchfit import io
from notchfit.commands import diagnose
from notchfit.io import interrupts, outputs
from notchfit.studies.synth import generate_study, load_recipe
from reliability_helpers import (assert_one_line_error, cli_env, copy_study, make_study, messages,
                                 prior_outputs, run_main, snapshot)


@pytest.fixture(scope="module")
def study3(tmp_path_factory):
    return make_study(tmp_path_factory.mktemp("rel_faults") / "study", n_experiments=3)


# ----------------------------------------------------------------------------- nothing skipped in silence
def test_invalid_study_subfolders_are_listed_and_exit_1(study3, tmp_path, capsys):
    study = copy_study(study3, tmp_path / "study")
    (study / "L150" / "experiment.toml").unlink()                       # lost its metadata
    (study / "L300" / "samples.csv").write_text("sample,time_s\n")       # broken
    (study / "calibration").mkdir()                                     # not an experiment: ignored
    (study / "calibration" / "camera.yml").write_text("%YAML:1.0\n")
    for argv in (["fit", "--models", "cc", "--no-figures"], ["simulate", "--no-figures"]):
        rc, out, err = run_main([argv[0], study, "--out", tmp_path / argv[0], *argv[1:]], capsys)
        assert rc == 1 and messages(err) == [], (out, err)         # progress lines only
        assert "1 of 3 experiments" in out
        failed = [ln for ln in out.splitlines() if "FAILED" in ln]
        assert any("L150" in ln and "no experiment.toml" in ln for ln in failed), out
        assert any("L300" in ln and "samples.csv" in ln and "missing column" in ln for ln in failed), out
        assert not any("calibration" in ln for ln in failed)
    record = io.read_json(tmp_path / "fit" / "fit_run.json")
    assert set(record["failures"]) == {"L150", "L300"}
    # diagnose goes on without them and lists them (checked on its input step: the run itself is long)
    parser = argparse.ArgumentParser()
    diagnose.add_arguments(parser)
    exps, unread = diagnose._experiments(parser.parse_args([str(study), "--out", str(tmp_path / "d")]))
    assert [e.name for e in exps] == ["L045"] and set(unread) == {"L150", "L300"}
    # nothing at all readable: exit 2, one line listing why
    (study / "L045" / "notch_points.csv").write_text("garbage")
    rc, _, err = run_main(["fit", study, "--out", tmp_path / "none"], capsys)
    assert_one_line_error(rc, err, "no experiment can be read", "L045", "L150", "L300")


def test_header_only_points_name_the_experiment_file_and_the_models_asked_for(study3, tmp_path, capsys):
    study = copy_study(study3, tmp_path / "study")
    (study / "L045" / "notch_points.csv").write_text("sample,point,x_mm,y_mm\n")
    rc, out, err = run_main(["fit", study, "--out", tmp_path / "o", "--models", "cc", "--no-figures"], capsys)
    line = next(ln for ln in out.splitlines() if "FAILED L045" in ln)
    assert rc == 1 and "L045/notch_points.csv" in line and "--models cc" in line and "free" not in line
    rc, _, err = run_main(["diagnose", study, "--out", tmp_path / "d"], capsys)
    assert_one_line_error(rc, err, "L045", "notch_points.csv", "the diagnosis")


def test_report_refuses_an_input_study(study3, tmp_path, capsys):
    before = snapshot(study3)
    for folder in (study3, study3 / "L045"):
        rc, _, err = run_main(["report", folder], capsys)
        assert_one_line_error(rc, err, str(folder), "input study", "--study")
    assert snapshot(study3) == before


def test_report_refuses_folders_inside_or_holding_input_data(study3, tmp_path, capsys):
    """A folder inside an experiment, inside the --study, or another study: refused, nothing written
    (no report, no lock, no staging folder)."""
    other = copy_study(study3, tmp_path / "other")
    inside = other / "L045" / "results"
    inside.mkdir()
    before = snapshot(other)
    for argv, needle in (([inside], "L045 above it holds experiment.toml"),
                         ([other / "results", "--study", other], "inside the input folder"),
                         ([other, "--study", study3], "its sub-folder L045 holds experiment.toml")):
        rc, _, err = run_main(["report", *argv], capsys)
        assert_one_line_error(rc, err, str(argv[0]), needle)
    assert snapshot(other) == before and not (other / "results").exists()


def test_report_takes_the_output_lock(study3, tmp_path, capsys):
    """report into a folder another live run writes into: exit 2 naming its pid, nothing written;
    then a report is written and the lock released."""
    out = tmp_path / "out"
    rc, _, _ = run_main(["fit", study3, "--out", out, "--models", "cc", "--no-figures"], capsys)
    assert rc == 0
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / ".notchfit-lock").write_text(f"{holder.pid} {socket.gethostname()}\n")
        before = snapshot(out)
        rc, _, err = run_main(["report", out], capsys)
        assert_one_line_error(rc, err, str(out), "another notchfit run", f"pid {holder.pid}")
        assert snapshot(out) == before
    finally:
        holder.kill()
        holder.wait()
    rc, stdout, _ = run_main(["report", out], capsys)
    assert rc == 0 and f"report: {out / 'report.html'}" in stdout
    assert (out / "report.html").read_bytes().startswith(b"<!DOCTYPE html>")
    assert not [p for p in out.iterdir() if p.name.startswith(".")]     # lock and staging folder gone
    rc, _, err = run_main(["report", out], capsys)                     # no --force: the report is kept
    assert_one_line_error(rc, err, "report.html", "--force")


# ----------------------------------------------------------------------------- Ctrl-C and SIGTERM
def _start(argv):
    proc = subprocess.Popen([sys.executable, "-m", "notchfit.cli", *map(str, argv)], env=cli_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True)
    reader.start()
    return proc, lines, reader


def _wait_for(lines, text, proc, timeout=120):
    t0 = time.monotonic()
    while not any(text in ln for ln in lines):
        assert proc.poll() is None, f"finished before '{text}': {lines}"
        assert time.monotonic() - t0 < timeout, lines
        time.sleep(0.05)


@pytest.mark.parametrize("sig,jobs", [(signal.SIGINT, 2), (signal.SIGTERM, 2), (signal.SIGINT, 1)],
                         ids=["sigint-jobs2", "sigterm-jobs2", "sigint-serial-numba"])
def test_interrupted_diagnose(sig, jobs, study3, tmp_path, capsys):
    """Signal mid-run: exit 128+sig, one message line, no worker left, earlier outputs byte-identical.
    While it runs, a second run into the same --out is refused by the lock (exit 2)."""
    out = tmp_path / "out"
    before = prior_outputs(out)
    proc, lines, reader = _start(["diagnose", study3, "--out", out, "--force", "--no-figures",
                                  "--jobs", jobs])
    _wait_for(lines, "calibrating the baseline", proc)
    rc, _, err = run_main(["fit", study3, "--out", out, "--models", "cc", "--no-figures"], capsys)
    assert_one_line_error(rc, err, str(out), "another notchfit run", f"pid {proc.pid}")
    time.sleep(0.5)
    children = psutil.Process(proc.pid).children(recursive=True)
    assert len(children) == (jobs if jobs > 1 else 0)
    proc.send_signal(sig)
    proc.wait(timeout=60)
    reader.join(timeout=10)
    assert proc.returncode == 128 + sig
    text = "".join(lines)
    assert "Traceback" not in text and "Error" not in text, text
    errors = [ln for ln in lines if not ln.startswith("diagnose: ")]
    assert len(errors) == 1 and f"interrupted ({signal.Signals(sig).name})" in errors[0], text
    gone = psutil.wait_procs(children, timeout=10)[1]
    assert not gone, f"orphan workers: {gone}"
    assert snapshot(out) == before           # no staging folder, no lock file, earlier outputs whole


@pytest.fixture(scope="module")
def image_study(tmp_path_factory):
    """A rendered study (recipe null, 9 images of 1568 x 1455 px) whose samples.csv names the images
    again and again (54 samples): detect then runs for many seconds on 2 workers."""
    study = tmp_path_factory.mktemp("rel_detect") / "study"
    generate_study(load_recipe("null").scaled(n_experiments=1, n_up=4, n_down=4), study, seed=1, images=True)
    samples = study / "L045" / "samples.csv"
    header, *rows = samples.read_text().splitlines()
    lines = [header]
    for k in range(54):
        cells = rows[k % len(rows)].split(",")
        cells[0], cells[1] = str(k + 1), f"{5.0 * (k + 1):g}"
        lines.append(",".join(cells))
    samples.write_text("\n".join(lines) + "\n")
    return study


def _earlier_detect_outputs(out):
    before = prior_outputs(out)
    (out / "L045" / "detections.csv").write_bytes(b"earlier detections of L045\n")
    (out / "L045" / "overlays").mkdir()
    (out / "L045" / "overlays" / "0001.jpg").write_bytes(b"earlier overlay\n")
    (out / "detect_run.json").write_bytes(b'{"earlier": true}\n')
    assert snapshot(out) != before
    return snapshot(out)


def _wait_for_staged(out, pattern, proc, timeout=120):
    """Until the run has staged a file matching ``pattern`` (it is mid-way through its items)."""
    t0 = time.monotonic()
    while not list(out.glob(f".notchfit-stage-*/{pattern}")) + list(out.glob(f".notchfit-resume-*/stage/{pattern}")):
        assert proc.poll() is None, f"finished before staging {pattern}"
        assert time.monotonic() - t0 < timeout
        time.sleep(0.05)


def _assert_interrupted(proc, lines, reader, sig, children, out, before):
    """Exit 128+sig, one line, no orphan; earlier outputs byte-identical, no lock left; the images
    finished before the signal are kept for --resume (the line says so), nothing else is added."""
    proc.wait(timeout=60)
    reader.join(timeout=10)
    assert proc.returncode == 128 + sig, lines
    text = "".join(lines)
    said = messages(text)                    # besides the progress lines of the stages that ran
    assert "Traceback" not in text and "Error" not in text, text
    assert len(said) == 1 and f"interrupted ({signal.Signals(sig).name})" in said[0], text
    gone = psutil.wait_procs(children, timeout=10)[1]
    assert not gone, f"orphan workers: {gone}"
    now = snapshot(out)
    kept = {k for k in now if k.startswith(".notchfit-resume-detect/")}
    assert {k: v for k, v in now.items() if k not in kept} == before       # no lock, earlier outputs whole
    assert not kept or ("finished are kept" in said[0] and "--resume" in said[0]), said
    return now


@pytest.mark.parametrize("sig,jobs", [(signal.SIGINT, 2), (signal.SIGTERM, 2), (signal.SIGINT, 1)],
                         ids=["sigint-jobs2", "sigterm-jobs2", "sigint-serial"])
def test_interrupted_detect(sig, jobs, image_study, tmp_path):
    """Ctrl-C / SIGTERM once detect has written its first overlays: exit 130/143, one stderr line,
    no traceback, both workers gone, the earlier detections, overlays and run record byte-identical."""
    out = tmp_path / "out"
    before = _earlier_detect_outputs(out)
    proc, lines, reader = _start(["detect", image_study, "--out", out, "--force", "--jobs", jobs])
    _wait_for_staged(out, "L045/overlays/*.jpg", proc)
    children = psutil.Process(proc.pid).children(recursive=True)
    assert len(children) == (jobs if jobs > 1 else 0)
    proc.send_signal(sig)
    _assert_interrupted(proc, lines, reader, sig, children, out, before)


def test_interrupted_detect_on_a_dask_cluster(image_study, tmp_path):
    """Ctrl-C of a --scheduler run: exit 130, one line; the run's tasks are cancelled on the cluster
    (none left on the scheduler), the cluster itself keeps running, and a task that was executing
    when the run stopped writes nothing into --out afterwards (earlier outputs byte-identical, the
    images kept for --resume as they were when the run stopped)."""
    distributed = pytest.importorskip("distributed")
    out = tmp_path / "out"
    before = _earlier_detect_outputs(out)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        proc, lines, reader = _start(["detect", image_study, "--out", out, "--force",
                                      "--scheduler", cluster.scheduler_address])
        _wait_for_staged(out, "L045/overlays/*.jpg", proc)
        assert not psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGINT)
        after = _assert_interrupted(proc, lines, reader, signal.SIGINT, [], out, before)
        t0 = time.monotonic()
        while client.run_on_scheduler(lambda dask_scheduler: len(dask_scheduler.tasks)):
            assert time.monotonic() - t0 < 30, "tasks of the interrupted run left on the scheduler"
            time.sleep(0.1)
        while any(client.run(lambda dask_worker: len(dask_worker.state.executing)).values()):
            assert time.monotonic() - t0 < 30, "a task of the interrupted run still executing"
            time.sleep(0.1)
        assert client.submit(sum, [1, 2]).result(timeout=30) == 3
    assert snapshot(out) == after


def test_interrupt_during_the_final_moves_is_held_until_they_are_done(tmp_path, monkeypatch):
    """SIGINT while OutputRun replaces earlier results: all files are moved, then Interrupted is raised."""
    out = tmp_path / "out"
    prior_outputs(out)
    real_replace = os.replace
    sent = []

    def replace(src, dst):
        if not sent and ".notchfit-stage-" in str(src) and ".notchfit-stage-" not in str(dst):
            sent.append(dst)
            os.kill(os.getpid(), signal.SIGINT)        # arrives in the middle of the loop of moves
        return real_replace(src, dst)

    with interrupts.handle_interrupts():
        monkeypatch.setattr(outputs.os, "replace", replace)
        with pytest.raises(interrupts.Interrupted):
            with io.OutputRun(out, force=True) as run:
                for name in ("L045", "L150"):
                    io.write_text_atomic(f"new fits of {name}\n", run.path(f"{name}/fits.csv"))
                    io.write_text_atomic(f"new simulation of {name}\n", run.path(f"{name}/simulation.csv"))
        monkeypatch.undo()
    assert sent
    after = snapshot(out)
    assert after["L045/fits.csv"] == b"new fits of L045\n" and after["L150/simulation.csv"] == \
        b"new simulation of L150\n"
    assert after["diagnosis.json"] == b'{"earlier": true}\n'
    assert not [k for k in after if k.startswith(".")]


# ----------------------------------------------------------------------------- the lock of an output folder
def test_lock_of_a_live_process_refuses_a_stale_one_is_removed(study3, tmp_path, capsys):
    out = tmp_path / "out"
    before = prior_outputs(out)
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / ".notchfit-lock").write_text(f"{holder.pid} {socket.gethostname()}\n")
        before = snapshot(out)
        rc, _, err = run_main(["fit", study3, "--out", out, "--force", "--models", "cc", "--no-figures"], capsys)
        assert_one_line_error(rc, err, str(out), f"pid {holder.pid}")
        assert snapshot(out) == before
    finally:
        holder.kill()
        holder.wait()
    rc, _, _ = run_main(["fit", study3, "--out", out, "--force", "--models", "cc", "--no-figures"], capsys)
    assert rc == 0 and not (out / ".notchfit-lock").exists()
    assert (out / "L045" / "fits.csv").read_bytes() != before["L045/fits.csv"]


# ----------------------------------------------------------------------------- a full disk
@pytest.mark.parametrize("nth", [1, 3])
def test_full_disk_exits_2_and_keeps_earlier_outputs(nth, study3, tmp_path, capsys, monkeypatch):
    """ENOSPC injected in the atomic writer on its nth file (after half of it is written)."""
    out = tmp_path / "out"
    before = prior_outputs(out)
    real = outputs.atomic_write
    calls = []

    def atomic_write(path, writer, *, suffix=".tmp"):
        calls.append(path)

        def half_then_full(tmp):
            writer(tmp)
            if len(calls) == nth:
                with open(tmp, "r+b") as fh:
                    fh.truncate(os.path.getsize(tmp) // 2)
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp))
        return real(path, half_then_full, suffix=suffix)

    monkeypatch.setattr(outputs, "atomic_write", atomic_write)
    rc, _, err = run_main(["fit", study3, "--out", out, "--force", "--models", "cc", "--no-figures"], capsys)
    assert_one_line_error(rc, err, "no space left")
    # the earlier outputs are untouched; what the run finished is kept apart for --resume
    after = snapshot(out)
    assert {k: v for k, v in after.items() if not k.startswith(".notchfit-resume-fit/")} == before
