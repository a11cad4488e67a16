"""``detect --resume``: an interrupted, killed or disk-full run continued with only the missing images
(issue 30), and an image with no point at all listed with exit code 1 (issue 29).

The study: 8 samples, each its own file (copies of 4 renders of 1190 x 712 px, about 0.15 s each),
so that a run lasts a few seconds and can be stopped mid-way.
"""

import errno
import shutil
import signal
import subprocess
import sys
import time

import cv2
import numpy as np
import pandas as pd
import pytest
from reliability_helpers import assert_one_line_error, cli_env, messages, run_main, snapshot

from notchfit import io
from notchfit.commands import detect as detect_cmd
from notchfit.io import resume as resume_mod
from notchfit.vision.render import camera_for_shapes, render_manipulator

N_SAMPLES = 8
RESUME_DIR = ".notchfit-resume-detect"


def _write_experiment(folder, images, geom_name="default"):
    """An experiment folder whose sample s is ``images[s-1]`` (arrays written as PNG)."""
    (folder / "images").mkdir(parents=True)
    rows = []
    for s, img in enumerate(images, start=1):
        cv2.imwrite(str(folder / "images" / f"{s:04d}.png"), img)
        rows.append({"sample": s, "time_s": float(s), "tension_left_N": 1.0, "tension_right_N": 0.5,
                     "image": f"images/{s:04d}.png"})
    pd.DataFrame(rows).to_csv(folder / "samples.csv", index=False)
    (folder / "experiment.toml").write_text(f'name = "exp"\ngeometry = "{geom_name}"\nmirror = false\n'
                                            'calibration = "camera.yml"\n')
    return folder


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """``(experiment folder, reference output folder)``: the experiment and its uninterrupted detect run."""
    from notchfit.physics.geometry import default_geometry

    geom = default_geometry()
    root = tmp_path_factory.mktemp("resume")
    thetas = [np.full(geom.n_joints, 0.012 * k) for k in range(4)]
    cam, planes = camera_for_shapes(thetas, geom, mm_per_px=0.04, phi=0.4)
    rng = np.random.default_rng(30)
    renders = [render_manipulator(th, geom, cam, plane=planes[0], rng=rng).image for th in thetas]
    folder = root / "exp"
    _write_experiment(folder, [renders[k % 4] for k in range(N_SAMPLES)])
    io.write_camera(cam, folder / "camera.yml")
    ref = root / "ref"
    assert io_main(["detect", folder, "--out", ref]) == 0
    return folder, ref


def io_main(argv):
    from notchfit.cli import main

    return main([str(a) for a in argv])


def _copy(study, tmp_path):
    folder = shutil.copytree(study[0], tmp_path / "exp")
    return folder, study[1]


def _records(out):
    return sorted((out / RESUME_DIR / "items").glob("*.json"))


def _start(argv):
    return subprocess.Popen([sys.executable, "-m", "notchfit.cli", *map(str, argv)], env=cli_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _stop_midway(proc, out, sig, at_least=2, timeout=120):
    """Send ``sig`` once ``at_least`` images are kept and the run is still going; returns (stdout, stderr)."""
    t0 = time.monotonic()
    while len(_records(out)) < at_least:
        assert proc.poll() is None, f"finished before {at_least} images were kept: {proc.communicate()}"
        assert time.monotonic() - t0 < timeout
        time.sleep(0.02)
    proc.send_signal(sig)
    return proc.communicate(timeout=60)


def _assert_same_outputs(out, ref):
    """detections.csv and every overlay byte-identical to the uninterrupted run's; the run records alike
    but for the time and the count of kept images; no working folder or lock left."""
    assert (out / "detections.csv").read_bytes() == (ref / "detections.csv").read_bytes()
    assert snapshot(out / "overlays") == snapshot(ref / "overlays")
    got, want = io.read_json(out / "detect_run.json"), io.read_json(ref / "detect_run.json")
    for k in ("time", "kept_from_interrupted_run", "input"):
        got.pop(k), want.pop(k)
    assert got == want
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]


def _resumed(stdout):
    """(kept, to detect) as the resumed run says them."""
    line = next(ln for ln in stdout.splitlines() if "resuming the interrupted run" in ln)
    kept = int(line.split(": ")[1].split(" of ")[0])
    return kept, int(line.split(", ")[1].split(" to detect")[0])


@pytest.mark.parametrize("sig,jobs", [(signal.SIGKILL, 1), (signal.SIGINT, 2)], ids=["sigkill", "sigint-jobs2"])
def test_stopped_run_resumes_to_the_uninterrupted_result(sig, jobs, study, tmp_path, capsys):
    """SIGKILL (nothing runs after it: as a power cut) or Ctrl-C mid-run, then --resume: only the
    missing images are detected and detections.csv, the overlays and the run record equal those of a
    run never stopped."""
    folder, ref = _copy(study, tmp_path)
    out = tmp_path / "out"
    stdout, stderr = _stop_midway(_start(["detect", folder, "--out", out, "--jobs", jobs]), out, sig)
    n_kept = len(_records(out))
    assert 2 <= n_kept < N_SAMPLES and not (out / "detections.csv").exists()
    if sig == signal.SIGINT:
        said = messages(stderr)
        assert len(said) == 1 and "interrupted (SIGINT)" in said[0] and "--resume" in said[0], stderr
        assert f"{n_kept} of {N_SAMPLES} images finished are kept" in said[0]
        assert not (out / io.LOCK_NAME).exists()
    rc, stdout, _ = run_main(["detect", folder, "--out", out, "--resume", "--jobs", jobs], capsys)
    assert rc == 0
    kept, todo = _resumed(stdout)
    assert kept >= n_kept - 1 and kept + todo == N_SAMPLES      # SIGKILL may cut the last record short
    _assert_same_outputs(out, ref)


def _interrupt_after(monkeypatch, n, exc=KeyboardInterrupt):
    """detect's worker function raises ``exc`` at its ``n+1``-th call (in-process run: --jobs 1)."""
    real, calls = detect_cmd.detect_one, []

    def one(item):
        calls.append(item["sample"])
        if len(calls) > n:
            raise exc()
        return real(item)
    monkeypatch.setattr(detect_cmd, "detect_one", one)
    return calls


def test_changed_image_and_changed_options_are_done_again(study, tmp_path, capsys, monkeypatch):
    """An image replaced after it was done is detected again (content hash); a run resumed with other
    options (no overlays) does every image again and leaves no overlay of the earlier options."""
    folder, ref = _copy(study, tmp_path)
    out = tmp_path / "out"
    with monkeypatch.context() as m:
        _interrupt_after(m, 4)
        rc, _, err = run_main(["detect", folder, "--out", out], capsys)
    assert rc == 130 and "4 of 8 images finished are kept" in err
    # a plain rerun is refused (it would throw the kept images away): --resume or --force
    rc, _, err = run_main(["detect", folder, "--out", out], capsys)
    assert_one_line_error(rc, err, "interrupted detect run", "--resume", "--force")
    shutil.copyfile(folder / "images" / "0003.png", folder / "images" / "0001.png")   # sample 1 now shows shape 3
    rc, stdout, _ = run_main(["detect", folder, "--out", out, "--resume"], capsys)
    assert rc == 0 and _resumed(stdout) == (3, 5)
    det, want = pd.read_csv(out / "detections.csv"), pd.read_csv(ref / "detections.csv")
    cols = ["point", "x_mm", "y_mm", "u_px", "v_px", "sigma_mm", "status"]
    pd.testing.assert_frame_equal(det[det["sample"] == 1][cols].reset_index(drop=True),
                                  want[want["sample"] == 3][cols].reset_index(drop=True))
    pd.testing.assert_frame_equal(det[det["sample"] != 1].reset_index(drop=True),
                                  want[want["sample"] != 1].reset_index(drop=True))
    # options: the same interrupted state, resumed with --no-overlays
    out2 = tmp_path / "out2"
    with monkeypatch.context() as m:
        _interrupt_after(m, 3)
        assert run_main(["detect", folder, "--out", out2], capsys)[0] == 130
    rc, stdout, _ = run_main(["detect", folder, "--out", out2, "--resume", "--no-overlays"], capsys)
    assert rc == 0 and _resumed(stdout) == (0, 8) and not (out2 / "overlays").exists()
    assert (out2 / "detections.csv").read_bytes() == (out / "detections.csv").read_bytes()


def test_full_disk_mid_run_keeps_the_finished_images_and_resumes(study, tmp_path, capsys, monkeypatch):
    """ENOSPC while keeping the 4th image: exit 2, one line saying the disk is full and what is kept;
    after space is freed --resume finishes and equals the uninterrupted run."""
    folder, ref = _copy(study, tmp_path)
    out = tmp_path / "out"
    real, writes = resume_mod.write_bytes_synced, []

    def full_disk(path, data):
        writes.append(path)
        if len(writes) > 3 * 3:                     # overlay, table, record per image
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return real(path, data)
    with monkeypatch.context() as m:
        m.setattr(resume_mod, "write_bytes_synced", full_disk)
        rc, _, err = run_main(["detect", folder, "--out", out], capsys)
    line = assert_one_line_error(rc, err, "no space left", "3 of 8 images finished are kept", "--resume")
    assert "nothing of this run was kept" not in line
    rc, stdout, _ = run_main(["detect", folder, "--out", out, "--resume"], capsys)
    assert rc == 0 and _resumed(stdout) == (3, 5)
    _assert_same_outputs(out, ref)


def test_resume_refused_where_no_run_was_interrupted(study, tmp_path, capsys):
    """--resume on a missing folder, a finished run's folder, another folder, or an interrupted run of
    another input: exit 2, one line, nothing created or changed."""
    folder, ref = _copy(study, tmp_path)
    rc, _, err = run_main(["detect", folder, "--out", tmp_path / "none", "--resume"], capsys)
    assert_one_line_error(rc, err, "no such folder", "no interrupted detect run")
    assert not (tmp_path / "none").exists()
    before = snapshot(ref)
    rc, _, err = run_main(["detect", folder, "--out", ref, "--resume"], capsys)
    assert_one_line_error(rc, err, "its detect run finished", "nothing to resume")
    assert snapshot(ref) == before
    other = tmp_path / "other"
    (other / "L045").mkdir(parents=True)
    (other / "L045" / "fits.csv").write_text("earlier fits\n")
    rc, _, err = run_main(["detect", folder, "--out", other, "--resume"], capsys)
    assert_one_line_error(rc, err, "holds no interrupted detect run")
    assert snapshot(other) == {"L045/fits.csv": b"earlier fits\n"}
    # an interrupted run of this experiment, resumed with another input folder
    out = tmp_path / "out"
    (out / RESUME_DIR / "items").mkdir(parents=True)
    io.write_json_atomic({"command": "detect", "input": str(folder.resolve()), "force": False},
                         out / RESUME_DIR / "run.json")
    kept = snapshot(out)
    rc, _, err = run_main(["detect", study[0], "--out", out, "--resume"], capsys)
    assert_one_line_error(rc, err, "worked on", str(folder.resolve()))
    assert snapshot(out) == kept


def test_resumable_run_drops_cut_short_and_stray_files(tmp_path):
    """A record whose file is shorter than recorded (a crash before the data reached the disk) is
    dropped, as are temporary files a kill left; a record with the same options and input is kept."""
    src = tmp_path / "in"
    src.mkdir()
    for k in range(3):
        (src / f"{k}.txt").write_text(f"input {k}")
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt), io.ResumableRun(out, name="t", input_path=src) as run:
        for k in range(3):
            run.keep(f"item {k}", input_sha256=io.file_sha256(src / f"{k}.txt"), options_sha256="o",
                     value={"k": k}, stage_files={f"x/{k}.bin": b"data" * (k + 1)}, own_files={".csv": b"1,2\n"})
        raise KeyboardInterrupt
    stage = out / ".notchfit-resume-t" / "stage"
    (stage / "x" / "1.bin").write_bytes(b"da")                          # cut short
    (stage / "x" / ".2.bin.tmp123").write_bytes(b"half")                 # a temporary file left by a kill
    (src / "2.txt").write_text("input 2, changed")
    with io.ResumableRun(out, name="t", input_path=src, resume=True) as run:
        wanted = {f"item {k}": (src / f"{k}.txt", "o") for k in range(3)}
        assert run.reconcile(wanted) == {"item 0"}
        assert sorted(p.name for p in stage.rglob("*") if p.is_file()) == ["0.bin"]
    assert (out / "x" / "0.bin").read_bytes() == b"data" and not (out / ".notchfit-resume-t").exists()


def test_image_with_no_point_exits_1_and_is_listed(study, tmp_path, capsys):
    """A blank image among good ones: its rows are NaN, the others are detected; exit 1 and the image
    listed on stderr with its file name."""
    folder = study[0]
    images = [cv2.imread(str(folder / "images" / f"{s:04d}.png"), cv2.IMREAD_UNCHANGED) for s in (1, 2)]
    blank = np.full_like(images[0], 128)
    exp = _write_experiment(tmp_path / "exp", [images[0], blank, images[1]])
    shutil.copyfile(folder / "camera.yml", exp / "camera.yml")
    out = tmp_path / "out"
    rc, stdout, err = run_main(["detect", exp, "--out", out, "--no-overlays"], capsys)
    assert rc == 1
    said = messages(err)
    assert "1 of 3 images gave no point at all" in said[0] and "sample 2: 0002.png" in said[1], err
    df = pd.read_csv(out / "detections.csv")
    assert df[df["sample"] == 2][["x_mm", "y_mm"]].isna().all().all()
    assert (df[df["sample"] != 2]["status"] == "ok").all()
    assert io.read_json(out / "detect_run.json")["no_point"] == ["sample 2"]


def test_failed_detect_leaves_nothing_behind(tmp_path, capsys):
    """An input error after the output folder was locked (the camera file is missing): exit 2, one
    line, and the folders the run created are gone again."""
    exp = _write_experiment(tmp_path / "exp", [np.full((40, 60), 128, np.uint8)])
    out = tmp_path / "new" / "out"
    rc, _, err = run_main(["detect", exp, "--out", out], capsys)
    assert_one_line_error(rc, err, "camera.yml")
    assert not (tmp_path / "new").exists()


def test_existing_outputs_and_the_lock_are_checked_before_the_study_is_read(tmp_path, capsys):
    """Earlier detections without --force, or a live run's lock: exit 2 before anything is read or said
    (this study would make detect say it has no camera file, and fail on its broken samples.csv)."""
    exp = _write_experiment(tmp_path / "exp", [np.full((40, 60), 128, np.uint8)])
    (exp / "experiment.toml").write_text('name = "exp"\ngeometry = "default"\n')
    (exp / "samples.csv").write_text("sample,time_s\n1,x\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "detect_run.json").write_text("{}\n")
    rc, stdout, err = run_main(["detect", exp, "--out", out], capsys)
    assert_one_line_error(rc, err, "already holds outputs", "detect_run.json", "--force")
    assert stdout == ""
    (out / "detect_run.json").unlink()
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (out / io.LOCK_NAME).write_text(f"{holder.pid} {__import__('socket').gethostname()}\n")
        rc, stdout, err = run_main(["detect", exp, "--out", out], capsys)
        assert_one_line_error(rc, err, "another notchfit run", f"pid {holder.pid}")
        assert stdout == ""
    finally:
        holder.kill()
        holder.wait()


def test_stopped_while_writing_the_tables_resumes_without_detecting_again(study, tmp_path, capsys, monkeypatch):
    """Every image done, then stopped while the tables are assembled: --resume detects nothing and
    writes the outputs of the uninterrupted run."""
    folder, ref = _copy(study, tmp_path)
    out = tmp_path / "out"
    real = detect_cmd._assemble

    def stop(*a, **k):
        raise KeyboardInterrupt
    with monkeypatch.context() as m:
        m.setattr(detect_cmd, "_assemble", stop)
        rc, _, err = run_main(["detect", folder, "--out", out], capsys)
    assert rc == 130 and f"{N_SAMPLES} of {N_SAMPLES} images finished are kept" in err
    assert detect_cmd._assemble is real
    rc, stdout, _ = run_main(["detect", folder, "--out", out, "--resume"], capsys)
    assert rc == 0 and _resumed(stdout) == (N_SAMPLES, 0) and "images/s" not in stdout
    _assert_same_outputs(out, ref)
