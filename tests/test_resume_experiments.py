"""``fit --resume`` and ``simulate --resume``: a run stopped after some experiments continues with the
others only, and writes what an uninterrupted run writes (issue 30).

The study: 4 synthetic experiments (a fraction of a second each). The run is killed at a known
point: a subprocess whose ``ResumableRun.keep`` sends itself SIGKILL once two experiments are kept
(nothing of the process runs after it, as after a power cut).
"""

import shutil
import subprocess
import sys

import pandas as pd
import pytest
from reliability_helpers import assert_one_line_error, cli_env, run_main, snapshot

from notchfit import io
from notchfit.studies.synth import generate_study, load_recipe

COMMANDS = ["fit", "simulate"]
RUN_RECORD = {"fit": "fit_run.json", "simulate": "simulate_run.json"}
_KILL_AFTER_TWO = """
import os, signal, sys
from notchfit.io import resume
keep = resume.ResumableRun.keep
def keep_then_die(self, *a, **k):
    keep(self, *a, **k)
    if len(self.records) == 2:
        os.kill(os.getpid(), signal.SIGKILL)
resume.ResumableRun.keep = keep_then_die
from notchfit.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """``(study folder, {command: its uninterrupted run's output folder})``."""
    root = tmp_path_factory.mktemp("resume_exp")
    d = root / "study"
    generate_study(load_recipe("proximal_friction").scaled(n_experiments=4, n_up=3, n_down=3), d, seed=4)
    refs = {}
    for cmd in COMMANDS:
        refs[cmd] = root / f"ref_{cmd}"
        assert _main([cmd, d, "--out", refs[cmd], "--no-figures"]) == 0
    return d, refs


def _main(argv):
    from notchfit.cli import main

    return main([str(a) for a in argv])


def _records(out, cmd):
    return sorted((out / f".notchfit-resume-{cmd}" / "items").glob("*.json"))


def _killed_after_two(cmd, folder, out, *extra):
    """The command run in a subprocess that SIGKILLs itself once two experiments are kept; its worker
    processes (``--jobs 2``) end with it (else they would hold its pipes open: a timeout here)."""
    p = subprocess.run([sys.executable, "-c", _KILL_AFTER_TWO, cmd, str(folder), "--out", str(out), "--no-figures",
                        *map(str, extra)], env=cli_env(), capture_output=True, text=True, timeout=120)
    assert p.returncode == -9, (p.returncode, p.stdout, p.stderr)
    assert len(_records(out, cmd)) == 2
    assert not [q for q in out.iterdir() if not q.name.startswith(".")]      # OUT itself unchanged: empty


def _resumed(stdout):
    line = next(ln for ln in stdout.splitlines() if "resuming the interrupted run" in ln)
    return int(line.split(": ")[1].split(" of ")[0]), int(line.split(", ")[1].split(" to run")[0])


def _assert_same_outputs(out, ref, cmd):
    """Every table byte-identical to the uninterrupted run's; the run records alike but for the time."""
    got, want = snapshot(out), snapshot(ref)
    rec = RUN_RECORD[cmd]
    assert sorted(got) == sorted(want)
    assert {k: v for k, v in got.items() if k != rec} == {k: v for k, v in want.items() if k != rec}
    a, b = io.read_json(out / rec), io.read_json(ref / rec)
    for k in ("time", "input"):
        a.pop(k), b.pop(k)
    assert a == b


@pytest.mark.parametrize("cmd", COMMANDS)
@pytest.mark.parametrize("jobs", [1, 2])
def test_killed_run_resumes_to_the_uninterrupted_result(cmd, jobs, study, tmp_path, capsys):
    """SIGKILL after two of four experiments, then --resume: the other two only are run, and the
    outputs equal those of a run never stopped."""
    folder, refs = study
    out = tmp_path / "out"
    _killed_after_two(cmd, folder, out, "--jobs", jobs)
    rc, stdout, _ = run_main([cmd, folder, "--out", out, "--resume", "--jobs", jobs, "--no-figures"], capsys)
    assert rc == 0 and _resumed(stdout) == (2, 2)
    _assert_same_outputs(out, refs[cmd], cmd)


def _interrupted_after(n, cmd, folder, out, monkeypatch, capsys, *extra):
    """The command run here, Ctrl-C once ``n`` experiments are kept: exit 130, ``n`` records."""
    from notchfit.io import resume

    keep = resume.ResumableRun.keep

    def keep_then_interrupt(self, *a, **k):
        keep(self, *a, **k)
        if len(self.records) == n:
            raise KeyboardInterrupt
    with monkeypatch.context() as m:
        m.setattr(resume.ResumableRun, "keep", keep_then_interrupt)
        rc, _, err = run_main([cmd, folder, "--out", out, "--no-figures", *extra], capsys)
    assert rc == 130 and f"{n} of 4 experiments finished are kept in {out}" in err, err
    assert len(_records(out, cmd)) == n
    return [io.read_json(p)["key"] for p in _records(out, cmd)]


@pytest.mark.parametrize("cmd", COMMANDS)
def test_changed_data_and_changed_options_are_run_again(cmd, study, tmp_path, capsys, monkeypatch):
    """An experiment whose points changed since it was kept is run again; so is every experiment when
    the command's options change."""
    folder = shutil.copytree(study[0], tmp_path / "study")
    kept = _interrupted_after(2, cmd, folder, tmp_path / "a", monkeypatch, capsys)
    pts = folder / kept[0] / "notch_points.csv"
    df = pd.read_csv(pts)
    df.loc[0, "x_mm"] += 0.01
    df.to_csv(pts, index=False)
    rc, stdout, _ = run_main([cmd, folder, "--out", tmp_path / "a", "--resume", "--no-figures"], capsys)
    assert rc == 0 and _resumed(stdout) == (1, 3)
    _interrupted_after(2, cmd, folder, tmp_path / "b", monkeypatch, capsys)
    changed = ["--models", "cc"] if cmd == "fit" else ["--param", "mu_d=0.2"]
    rc, stdout, _ = run_main([cmd, folder, "--out", tmp_path / "b", "--resume", *changed, "--no-figures"], capsys)
    assert rc == 0 and _resumed(stdout) == (0, 4)


@pytest.mark.parametrize("cmd", COMMANDS)
def test_ctrl_c_keeps_the_finished_experiments(cmd, study, tmp_path, capsys, monkeypatch):
    """Ctrl-C after an experiment is kept: exit 130, the line says how many are kept, OUT holds nothing
    else, and --resume finishes the run as an uninterrupted one."""
    folder, refs = study
    out = tmp_path / "out"
    _interrupted_after(1, cmd, folder, out, monkeypatch, capsys)
    assert [p.name for p in out.iterdir()] == [f".notchfit-resume-{cmd}"]
    rc, stdout, _ = run_main([cmd, folder, "--out", out, "--resume", "--no-figures"], capsys)
    assert rc == 0 and _resumed(stdout) == (1, 3)
    _assert_same_outputs(out, refs[cmd], cmd)


@pytest.mark.parametrize("cmd", COMMANDS)
def test_resume_refused_where_no_run_of_the_command_was_interrupted(cmd, study, tmp_path, capsys, monkeypatch):
    """--resume on a missing folder, a finished run's folder, or another command's interrupted run; a
    plain run over an interrupted run: exit 2, one line, nothing changed."""
    folder, refs = study
    rc, _, err = run_main([cmd, folder, "--out", tmp_path / "none", "--resume"], capsys)
    assert_one_line_error(rc, err, "no such folder", f"no interrupted {cmd} run")
    assert not (tmp_path / "none").exists()
    before = snapshot(refs[cmd])
    rc, _, err = run_main([cmd, folder, "--out", refs[cmd], "--resume"], capsys)
    assert_one_line_error(rc, err, f"its {cmd} run finished", "nothing to resume")
    assert snapshot(refs[cmd]) == before
    other, out, mine = "simulate" if cmd == "fit" else "fit", tmp_path / "out", tmp_path / "mine"
    _interrupted_after(2, other, folder, out, monkeypatch, capsys)
    _interrupted_after(2, cmd, folder, mine, monkeypatch, capsys)
    kept, kept_mine = snapshot(out), snapshot(mine)
    rc, _, err = run_main([cmd, folder, "--out", out, "--resume"], capsys)
    assert_one_line_error(rc, err, f"holds no interrupted {cmd} run")
    rc, _, err = run_main([cmd, folder, "--out", mine], capsys)
    assert_one_line_error(rc, err, "interrupted", "--resume")
    assert snapshot(out) == kept and snapshot(mine) == kept_mine
