"""The commands' edges (issue 29 item 4): Ctrl-C anywhere in ``demo`` stops all of it, checks before
work, nothing left behind by a failed command, messages in words, ``python -m notchfit``.

Each test states what a user would see: the exit code, the one message line, what is on disk
afterwards. The real SIGINT sweep over every stage of ``notchfit demo --small`` runs the demo
six times and is marked slow; the fast tests interrupt the demo in process, inside a step.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import types

import pytest

from notchfit import io
from notchfit.batch import run_batch
from notchfit.commands import _common, _resumable, demo, fit, simulate
from reliability_helpers import (ROOT, assert_one_line_error, cli_env, copy_study, make_study, run_main,
                                 snapshot)


@pytest.fixture(scope="module")
def study2(tmp_path_factory):
    return make_study(tmp_path_factory.mktemp("edges") / "study", n_experiments=2)


# ----------------------------------------------------------------------------- Ctrl-C in the demo
def _fast_demo(monkeypatch, *, interrupt_in: str | None):
    """The demo with its study written in a blink and, optionally, the named step interrupted."""
    def small_study(study_dir, **kw):
        study_dir.mkdir(parents=True)
        (study_dir / "truth.json").write_text("{}")
        return types.SimpleNamespace(cause="null"), False

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(demo, "demo_study", small_study)
    monkeypatch.setattr(fit, "run", interrupted if interrupt_in == "fit" else lambda args: 0)
    monkeypatch.setattr(simulate, "run", lambda args: 0)
    monkeypatch.setattr(demo, "diagnose", lambda *a, **k: interrupted(None))


@pytest.mark.parametrize("step", ["fit", "diagnose"])
def test_ctrl_c_inside_a_demo_step_stops_the_whole_demo(step, tmp_path, capsys, monkeypatch):
    """Ctrl-C inside a step run through ``call`` (fit) or in process (diagnose): exit 130 with one line,
    no later step runs, and the new demo folder is gone (a plain rerun is not refused)."""
    _fast_demo(monkeypatch, interrupt_in=step)
    later = []
    monkeypatch.setattr(demo, "build_report", lambda *a, **k: later.append("report"))
    out = tmp_path / "new" / "demo"
    rc, stdout, err = run_main(["demo", "--small", "--out", out], capsys)
    assert rc == 130, (stdout, err)
    assert [ln for ln in err.splitlines() if ln.startswith("notchfit demo:")] == [
        "notchfit demo: interrupted (SIGINT); the outputs of this run were discarded, earlier outputs are "
        "unchanged"]
    assert later == []
    if step == "fit":
        assert "] simulate" not in stdout
    assert not (tmp_path / "new").exists()


def _earlier_demo(out):
    (out / "results").mkdir(parents=True)
    (out / "results" / "report.html").write_text("<!DOCTYPE html> the earlier demo")
    (out / "notes.txt").write_text("the user's own file, beside the demo")


def test_ctrl_c_keeps_the_earlier_demo(tmp_path, capsys, monkeypatch):
    """``demo --force`` over an earlier demo, interrupted: the earlier demo and the user's own file
    are byte-identical and nothing of the run is left."""
    out = tmp_path / "demo"
    _earlier_demo(out)
    before = snapshot(out)
    _fast_demo(monkeypatch, interrupt_in="fit")
    rc, _, _ = run_main(["demo", "--small", "--out", out, "--force"], capsys)
    assert rc == 130
    assert snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo"]


def test_force_replaces_only_the_demo(tmp_path, capsys, monkeypatch):
    """``demo --force`` that finishes: the earlier demo's study and results are replaced, the user's
    own file in the folder is kept, nothing of the earlier demo is left aside."""
    out = tmp_path / "demo"
    _earlier_demo(out)
    _fast_demo(monkeypatch, interrupt_in=None)
    monkeypatch.setattr(demo, "diagnose", lambda *a, **k: None)
    monkeypatch.setattr(demo, "build_report", lambda *a, **k: out / "results" / "report.html")
    monkeypatch.setattr(demo, "summary_lines", lambda *a: [])
    rc, stdout, err = run_main(["demo", "--small", "--out", out, "--force"], capsys)
    assert rc == 0, stdout + err
    assert sorted(snapshot(out)) == ["notes.txt", "study/truth.json"]


def test_call_raises_an_interruption_and_reports_an_error(tmp_path, capsys):
    """``call`` (how the demo runs a step): an error is one line and exit 2, an interruption is raised."""
    def command(exc):
        def run(args):
            raise exc
        return types.SimpleNamespace(NAME="x", HELP="x", add_arguments=lambda p: None, run=run)

    assert _common.call(command(ValueError("x.csv: line 3: bad value")), []) == 2
    assert capsys.readouterr().err == "notchfit x: error: x.csv: line 3: bad value\n"
    with pytest.raises(KeyboardInterrupt):
        _common.call(command(KeyboardInterrupt()), [])


def _start(argv):
    """``python -m notchfit.cli argv`` with its stdout lines collected as they come."""
    proc = subprocess.Popen([sys.executable, "-m", "notchfit.cli", *map(str, argv)], env=cli_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    errors: list[str] = []
    readers = [threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True),
               threading.Thread(target=lambda: errors.extend(proc.stderr), daemon=True)]
    for r in readers:
        r.start()
    return proc, lines, errors, readers


def _interrupt_at(stage: str, out, *extra, timeout: float = 600):
    """Run ``demo --small``, send SIGINT when its stage line ``[ t s] <stage>`` appears; returns
    (exit code, stdout lines, stderr lines)."""
    proc, lines, errors, readers = _start(["demo", "--small", "--out", out, "--jobs", "1", *extra])
    t0 = time.monotonic()
    while not any(ln.split("] ", 1)[-1].startswith(stage) for ln in lines if ln.startswith("[")):
        assert proc.poll() is None, f"finished before {stage}: {lines} {errors}"
        assert time.monotonic() - t0 < timeout, lines
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=120)
    for r in readers:
        r.join(timeout=10)
    return proc.returncode, lines, errors


STAGES = ("synth", "fit", "simulate", "diagnose", "report")


@pytest.mark.slow
def test_demo_interrupted_at_every_stage_then_rerun(tmp_path):
    """SIGINT at each stage of the small demo: exit 130, one line, nothing left; then a plain rerun
    into the same folder succeeds, and an interrupted ``--force`` rerun keeps that demo byte for byte."""
    out = tmp_path / "demo"
    for stage in STAGES:
        rc, lines, errors = _interrupt_at(stage, out)
        assert rc == 130, (stage, lines, errors)
        text = "".join(errors)
        assert "Traceback" not in text and "interrupted (SIGINT)" in text, (stage, text)
        assert not out.exists(), (stage, list(out.rglob("*")))
        assert sorted(p.name for p in tmp_path.iterdir()) == [], stage
    done = subprocess.run([sys.executable, "-m", "notchfit.cli", "demo", "--small", "--out", str(out),
                           "--jobs", "1"], env=cli_env(), capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (out / "results" / "report.html").is_file()
    before = snapshot(out)
    rc, _, _ = _interrupt_at("diagnose", out, "--force")
    assert rc == 130
    assert snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo"]


# ----------------------------------------------------------------------------- checks before work
@pytest.mark.parametrize("command,record", [("fit", "fit_run.json"), ("simulate", "simulate_run.json"),
                                            ("identify", "identify_run.json"),
                                            ("diagnose", "diagnosis.json")])
def test_existing_output_refused_before_anything_is_read(command, record, study2, tmp_path, capsys):
    """An earlier run's record in --out: exit 2 naming it and --force, nothing printed or read
    (the study is not even there), the folder unchanged."""
    out = tmp_path / "out"
    out.mkdir()
    (out / record).write_text("{}")
    before = snapshot(out)
    rc, stdout, err = run_main([command, tmp_path / "no-study-here", "--out", out], capsys)
    assert stdout == ""
    assert_one_line_error(rc, err, f"--out {out}", record, "--force")
    assert snapshot(out) == before


def test_locked_output_refused_before_anything_is_read(study2, tmp_path, capsys):
    """A live run's lock in --out: exit 2 naming its pid, before the study is read or anything printed."""
    out = tmp_path / "out"
    out.mkdir()
    (out / io.LOCK_NAME).write_text(f"{os.getpid()} {__import__('socket').gethostname()}\n")
    rc, stdout, err = run_main(["fit", tmp_path / "no-study-here", "--out", out], capsys)
    assert stdout == ""
    assert_one_line_error(rc, err, "another notchfit run", f"pid {os.getpid()}")


def test_report_names_only_options_it_has(study2, tmp_path, capsys):
    """``report`` has no --out: its refusals (an existing report, a locked folder) do not suggest one."""
    out = tmp_path / "out"
    rc, _, _ = run_main(["fit", study2, "--out", out, "--models", "cc", "--no-figures"], capsys)
    assert rc == 0
    rc, _, _ = run_main(["report", out], capsys)
    assert rc == 0
    rc, stdout, err = run_main(["report", out], capsys)
    assert stdout == ""
    line = assert_one_line_error(rc, err, "report.html", "--force")
    assert "--out" not in line
    (out / io.LOCK_NAME).write_text(f"{os.getpid()} {__import__('socket').gethostname()}\n")
    rc, _, err = run_main(["report", out, "--force"], capsys)
    line = assert_one_line_error(rc, err, "another notchfit run")
    assert "--out" not in line


# ----------------------------------------------------------------------------- nothing left behind
def test_failed_command_leaves_no_empty_folder(study2, tmp_path, capsys, monkeypatch):
    """fit fails after its output run made --out (a new folder two levels deep): exit 2, and neither
    that folder nor its new parent is left; an existing parent stays."""
    def broken(*a, **k):
        raise ValueError("a worker could not start")

    monkeypatch.setattr(_resumable, "run_batch", broken)    # fit's item loop (resumable)
    out = tmp_path / "new" / "out"
    rc, _, err = run_main(["fit", study2, "--out", out, "--models", "cc", "--no-figures"], capsys)
    assert_one_line_error(rc, err, "a worker could not start")
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    # a folder that existed before the run is kept, empty as it was
    out.mkdir(parents=True)
    rc, _, _ = run_main(["fit", study2, "--out", out, "--models", "cc", "--no-figures"], capsys)
    assert rc == 2 and out.is_dir() and list(out.iterdir()) == []


# ----------------------------------------------------------------------------- messages in words
def _missing(path):
    raise io.InputFileNotFoundError(f"{path}: CSV file not found", path=path)


def test_failures_are_listed_in_words(tmp_path, capsys):
    """A batch item that failed on a missing file is listed by what is wrong, not by the error's class."""
    res = run_batch(_missing, [tmp_path / "L045" / "samples.csv"], keys=["L045"], jobs=1)
    _common.list_failures({r.key: r.error for r in res.failures})
    out = capsys.readouterr().out
    assert out == f"  FAILED L045: {tmp_path / 'L045' / 'samples.csv'}: CSV file not found\n"
    # an unexpected error keeps its type (it is a bug report)
    assert _common.in_words("KeyError: 'x'") == "KeyError: 'x'"


def test_a_missing_file_in_a_study_is_said_in_words(study2, tmp_path, capsys):
    study = copy_study(study2, tmp_path / "study")
    (study / "L045" / "samples.csv").unlink()
    rc, stdout, err = run_main(["fit", study, "--out", tmp_path / "out", "--models", "cc", "--no-figures"],
                               capsys)
    assert rc == 1
    assert "Error" not in stdout + err, stdout + err
    assert "samples.csv" in stdout


# ----------------------------------------------------------------------------- python -m notchfit
def test_python_m_notchfit(tmp_path):
    done = subprocess.run([sys.executable, "-m", "notchfit", "--version"], env=cli_env(), cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.startswith("notchfit "), done
    assert (ROOT / "notchfit" / "py.typed").is_file()
