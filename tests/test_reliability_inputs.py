"""Reliability (issue 16), bad inputs: exit 2, one stderr line naming the file and the problem, no
traceback, earlier outputs byte-identical — for every reader, path fault, value and encoding.

Each case mutates a copy of one experiment of a tiny synthetic study and runs the command that
reads the damaged file (``fit`` for the experiment files, ``simulate --model`` for a model file,
``calibrate`` for boards and images, ``detect`` for camera files, ``synth`` for recipes). The
output folder holds earlier results and the run is given ``--force``: a failing run must leave
them exactly as they were (no staging folder, no lock file left behind).
"""

from __future__ import annotations

import errno
import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from notchfit.vision.camera import CameraModel
from notchfit.io import datasets_dir, write_camera
from reliability_helpers import (assert_one_line_error, cli_env, copy_study, make_study, messages,
                                 prior_outputs, run_cli, run_main, snapshot)

FIT = ["fit", "{exp}", "--out", "{out}", "--models", "cc", "--no-figures", "--force"]


@pytest.fixture(scope="module")
def base_study(tmp_path_factory):
    return make_study(tmp_path_factory.mktemp("rel_inputs") / "study")


# ----------------------------------------------------------------------------- file edits
def _replace(path: Path, old: str, new: str) -> None:
    text = path.read_text(encoding="utf-8")
    assert old in text, (path, old)
    path.write_text(text.replace(old, new, 1), encoding="utf-8")


def _set_line(path: Path, line_no: int, text: str) -> None:
    lines = path.read_text(encoding="utf-8").splitlines()
    lines[line_no - 1] = text
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _geometry(exp: Path, **changes) -> None:
    """Give the experiment its own geometry file with ``changes`` (raw TOML values)."""
    text = (datasets_dir() / "geometry" / "default.toml").read_text()
    for k, v in changes.items():
        lines = [ln for ln in text.splitlines() if not ln.startswith(f"{k} ")]
        text = "\n".join(lines) + f"\n{k} = {v}\n"
    (exp / "geom.toml").write_text(text)
    _replace(exp / "experiment.toml", 'geometry = "default"', 'geometry = "geom.toml"')


def _last_line() -> int:
    """The line :func:`_geometry` writes its (one) change on: the last of the file."""
    return len((datasets_dir() / "geometry" / "default.toml").read_text().splitlines())


def _model(t: Path, e: Path, data) -> list:
    """Write the model file ``t/m.toml`` (text or bytes); the argv of ``simulate --model`` on it."""
    (t / "m.toml").write_bytes(data if isinstance(data, bytes) else data.encode())
    return ["simulate", e, "--out", t / "out", "--model", t / "m.toml", "--force", "--no-figures"]


def _samples_row(exp: Path, line_no: int, row: str) -> None:
    _set_line(exp / "samples.csv", line_no, row)


# (id, edit(exp, tmp) -> argv or None for FIT, needles of the one stderr line)
CASES = [
    # --- paths
    ("input-missing", lambda e, t: ["fit", t / "nope", "--out", t / "out", "--force"], ["nope", "not found"]),
    ("input-is-a-file", lambda e, t: ["fit", e / "samples.csv", "--out", t / "out", "--force"],
     ["samples.csv", "is a file"]),
    ("out-through-a-file", lambda e, t: ["fit", e, "--out", e / "samples.csv" / "x", "--force"],
     ["--out", "samples.csv"]),
    ("out-is-a-file", lambda e, t: ["fit", e, "--out", e / "samples.csv", "--force"], ["--out", "is a file"]),
    ("out-equals-input", lambda e, t: ["fit", e, "--out", e, "--force"], ["--out", "input folder"]),
    ("out-inside-input", lambda e, t: ["fit", e.parent, "--out", e.parent / "results", "--force"],
     ["--out", "inside the input folder"]),
    ("geometry-is-a-folder", lambda e, t: ((e / "geomdir").mkdir(), _replace(
        e / "experiment.toml", 'geometry = "default"', 'geometry = "geomdir"'))[1], ["experiment.toml", "geomdir",
                                                                                    "is a folder"]),
    ("samples-is-a-folder", lambda e, t: ((e / "samples.csv").unlink(), (e / "samples.csv").mkdir())[1],
     ["samples.csv", "is a folder"]),
    ("samples-missing", lambda e, t: (e / "samples.csv").unlink(), ["samples.csv", "not found"]),
    ("experiment-toml-missing", lambda e, t: (e / "experiment.toml").unlink(), ["no experiment.toml"]),
    # --- geometry values (checked by geometry_from_dict; the reader names the file)
    ("geometry-slot-sides-nested", lambda e, t: _geometry(e, slot_sides="[[1, -1]]"),
     ["geom.toml", "slot_sides must be"]),
    ("geometry-negative-radius", lambda e, t: _geometry(e, outer_radius_mm="-3.0"),
     ["geom.toml", "outer_radius_mm", "positive"]),
    ("geometry-slot-deeper-than-tube", lambda e, t: _geometry(e, slot_depth_mm="7.0"),
     ["geom.toml", f": line {_last_line()}: slot_depth must be smaller than the tube diameter"]),
    ("geometry-decimal-comma", lambda e, t: _geometry(e, p_mm="1,21"),
     ["geom.toml", f"line {_last_line()}", "decimal comma"]),
    ("geometry-nan", lambda e, t: _geometry(e, p_mm="nan"), ["geom.toml", "p_mm", "finite"]),
    ("geometry-inf", lambda e, t: _geometry(e, r_x_mm="inf"), ["geom.toml", "r_x_mm", "finite"]),
    ("geometry-huge-n-joints", lambda e, t: _geometry(e, n_joints="1000000000000"), ["geom.toml", "n_joints"]),
    ("geometry-bad-toml", lambda e, t: ((e / "geom.toml").write_text("n_joints = = 3\n"), _replace(
        e / "experiment.toml", 'geometry = "default"', 'geometry = "geom.toml"'))[1], ["geom.toml", "line 1"]),
    # --- experiment.toml
    ("toml-latin1", lambda e, t: (e / "experiment.toml").write_bytes(
        (e / "experiment.toml").read_bytes().replace(b"synthetic", b"synth\xe9tic")),
     ["experiment.toml", "line 2", "column", "UTF-8"]),
    ("toml-unknown-key", lambda e, t: _replace(e / "experiment.toml", "mirror", "mirorr"),
     ["experiment.toml", "mirorr"]),
    ("toml-syntax", lambda e, t: _replace(e / "experiment.toml", "mirror = false", "mirror = fals"),
     ["experiment.toml", "line 4", "bad TOML"]),
    ("toml-name-escapes-out", lambda e, t: _replace(e / "experiment.toml", 'name = "L045"', 'name = "../../x"'),
     ["experiment.toml", "name"]),
    ("toml-negative-sigma", lambda e, t: _replace(e / "experiment.toml", "point_mm = 0.02", "point_mm = -1"),
     ["experiment.toml", "point_mm"]),
    ("toml-nan-sigma", lambda e, t: _replace(e / "experiment.toml", "point_mm = 0.02", "point_mm = nan"),
     ["experiment.toml", "point_mm"]),
    ("toml-absurd-sigma", lambda e, t: _replace(e / "experiment.toml", "point_mm = 0.02", "point_mm = 1e300"),
     ["experiment.toml", "line 7", "point_mm must be a positive number below 1000"]),
    # --- samples.csv
    ("samples-nan-tension", lambda e, t: _samples_row(e, 3, "2,10.0,nan,0.5,0,0"),
     ["samples.csv", "line 3", "tension_left_N"]),
    ("samples-inf-time", lambda e, t: _samples_row(e, 3, "2,inf,1.0,0.5,0,0"), ["samples.csv", "line 3", "finite"]),
    ("samples-absurd-tension", lambda e, t: _samples_row(e, 3, "2,10.0,1e20,0.5,0,0"),
     ["samples.csv", "line 3", "out of range"]),
    ("samples-23-digit-id", lambda e, t: _samples_row(e, 2, "12345678901234567890123,5.0,1.0,0.5,0,0"),
     ["samples.csv", "line 2", "out of range"]),
    ("samples-decimal-comma", lambda e, t: _samples_row(e, 3, "2,10,0,1,5,0,5,0,0"),
     ["samples.csv", "line 3", "decimal comma"]),
    ("samples-quoted-decimal-comma", lambda e, t: _samples_row(e, 3, '2,10.0,"1,5",0.5,0,0'),
     ["samples.csv", "line 3", "decimal comma"]),
    ("samples-semicolons", lambda e, t: (e / "samples.csv").write_text(
        (e / "samples.csv").read_text().replace(",", ";")), ["samples.csv", "';'"]),
    ("samples-latin1", lambda e, t: (e / "samples.csv").write_bytes(
        (e / "samples.csv").read_bytes() + "9,99.0,1.0,0.5,0,0,\xb5\n".encode("latin-1")),
     ["samples.csv", "line 9", "UTF-8"]),
    ("samples-zero-bytes", lambda e, t: (e / "samples.csv").write_bytes(b""), ["samples.csv", "empty"]),
    ("samples-truncated", lambda e, t: (e / "samples.csv").write_bytes((e / "samples.csv").read_bytes()[:-9]),
     ["samples.csv", "line 8", "fields"]),
    ("samples-time-order", lambda e, t: _samples_row(e, 3, "2,1.0,1.0,0.5,0,0"), ["samples.csv", "line 3",
                                                                                   "time_s"]),
    ("samples-binary", lambda e, t: (e / "samples.csv").write_bytes(bytes(range(256)) * 4),
     ["samples.csv"]),
    ("samples-nul", lambda e, t: (e / "samples.csv").write_bytes(b"sample,time_s\n1,\x002\n"), ["samples.csv"]),
    # --- notch_points.csv
    ("points-absurd-x", lambda e, t: _set_line(e / "notch_points.csv", 2, "1,1,1e20,0.0"),
     ["notch_points.csv", "line 2", "out of range"]),
    ("points-23-digit-sample", lambda e, t: _set_line(e / "notch_points.csv", 2,
                                                      "12345678901234567890123,1,1.0,0.0"),
     ["notch_points.csv", "line 2", "out of range"]),
    ("points-id-out-of-range", lambda e, t: _set_line(e / "notch_points.csv", 2, "1,99,1.0,0.0"),
     ["notch_points.csv", "line 2", "99"]),
    ("points-inf", lambda e, t: _set_line(e / "notch_points.csv", 2, "1,1,-inf,0.0"),
     ["notch_points.csv", "line 2", "finite"]),
    ("points-header-only", lambda e, t: (e / "notch_points.csv").write_text("sample,point,x_mm,y_mm\n"),
     ["notch_points.csv", "--models cc"]),
    # --- model TOML (simulate --model)
    ("model-unknown-key", lambda e, t: ((t / "m.toml").write_text("k_foo = 1.0\n"),
                                        ["simulate", e, "--out", t / "out", "--model", t / "m.toml",
                                         "--force", "--no-figures"])[1], ["m.toml", "k_foo"]),
    ("model-huge-int", lambda e, t: ((t / "m.toml").write_text(f"mu_d = {10 ** 400}\n"),
                                     ["simulate", e, "--out", t / "out", "--model", t / "m.toml",
                                      "--force", "--no-figures"])[1], ["m.toml"]),
    ("model-is-a-folder", lambda e, t: ((t / "m.toml").mkdir(),
                                        ["simulate", e, "--out", t / "out", "--model", t / "m.toml",
                                         "--force", "--no-figures"])[1], ["m.toml", "is a folder"]),
    ("model-garbage", lambda e, t: ((t / "m.toml").write_bytes(b"\x00\xff\xfe garbage"),
                                    ["simulate", e, "--out", t / "out", "--model", t / "m.toml",
                                     "--force", "--no-figures"])[1], ["m.toml"]),
    ("model-string", lambda e, t: _model(t, e, 'mu_d = 0.2\nk_lin_Nm_per_rad = "abc"\n'),
     ["m.toml", "line 2", "k_lin_Nm_per_rad must be a number"]),
    ("model-boolean", lambda e, t: _model(t, e, "mu_d = true\n"), ["m.toml", "line 1", "mu_d must be a number"]),
    ("model-table", lambda e, t: _model(t, e, "[mu_d]\nx = 1\n"), ["m.toml", "line 1", "mu_d must be a number"]),
    ("model-nan", lambda e, t: _model(t, e, "mu_d = 0.2\nk_lin_Nm_per_rad = nan\n"),
     ["m.toml", "line 2", "k_lin must be finite"]),
    ("model-negative", lambda e, t: _model(t, e, "\n# stiffness\nk_lin_Nm_per_rad = -0.05\n"),
     ["m.toml", "line 3", "k_lin must be positive"]),
    ("model-mu-s-below-mu-d", lambda e, t: _model(t, e, "mu_d = 0.5\nmu_s = 0.3\n"),
     ["m.toml", "line 2", "mu_s must be >= mu_d"]),
    ("model-absurd-force", lambda e, t: _model(t, e, "mu_d = 0.2\ntip_force_x_N = 1e6\n"),
     ["m.toml", "line 2", "tip_force_x_N", "absurd"]),
    ("model-absurd-stiffness", lambda e, t: _model(t, e, "k_lin_Nm_per_rad = 1e300\n"),
     ["m.toml", "line 1", "absurd"]),
    ("model-absurd-time", lambda e, t: _model(t, e, "damping_time_s = 1e-30\n"),
     ["m.toml", "line 1", "damping_time_s", "absurd"]),
    ("model-decimal-comma", lambda e, t: _model(t, e, "mu_d = 0,2\n"), ["m.toml", "line 1", "decimal comma"]),
    ("model-latin1", lambda e, t: _model(t, e, "mu_d = 0.2 # r\xe9glage\n".encode("latin-1")),
     ["m.toml", "line 1", "UTF-8"]),
    # --- --points DIR (fit, simulate, diagnose): an explicit folder must be a detect run's
    ("points-dir-is-a-file", lambda e, t: ["fit", e, "--out", t / "out", "--force", "--points", e / "samples.csv"],
     ["--points", "samples.csv", "is a file"]),
    ("points-dir-missing", lambda e, t: ["simulate", e, "--out", t / "out", "--force", "--points", t / "nope"],
     ["--points", "nope", "not found"]),
    ("points-dir-without-detections", lambda e, t: ["diagnose", e.parent, "--out", t / "out", "--force",
                                                    "--points", e.parent], ["--points", "no detections.csv"]),
    # --- report
    ("report-folder-missing", lambda e, t: ["report", t / "nope"], ["nope", "output folder not found"]),
    # --- recipe (synth)
    ("recipe-bad-toml", lambda e, t: ((t / "r.toml").write_text("[[experiments]\n"),
                                      ["synth", t / "r.toml", "--out", t / "out", "--force"])[1],
     ["r.toml", "line 1"]),
    ("recipe-is-a-folder", lambda e, t: ((t / "r.toml").mkdir(), ["synth", t / "r.toml", "--out", t / "out"])[1],
     ["r.toml"]),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_keeps_earlier_outputs(case, base_study, tmp_path, capsys):
    _, edit, needles = case
    exp = copy_study(base_study, tmp_path / "study") / "L045"
    out = tmp_path / "out"
    before = prior_outputs(out)
    argv = edit(exp, tmp_path)
    argv = argv if isinstance(argv, list) else [a.format(exp=exp, out=out) for a in FIT]
    rc, _, err = run_main(argv, capsys)
    assert_one_line_error(rc, err, *needles)
    assert snapshot(out) == before


def test_permission_denied_names_the_file(base_study, tmp_path, capsys, monkeypatch):
    """An unreadable file (simulated: the tests may run as root, who reads anything)."""
    exp = copy_study(base_study, tmp_path / "study") / "L045"
    real = Path.read_bytes

    def read_bytes(self):
        if self.name == "samples.csv":
            raise PermissionError(errno.EACCES, "Permission denied", str(self))
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", read_bytes)
    rc, _, err = run_main(["fit", exp, "--out", tmp_path / "out", "--models", "cc", "--no-figures"], capsys)
    assert_one_line_error(rc, err, "samples.csv", "permission denied")


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files without permission")
def test_permission_denied_for_real(base_study, tmp_path, capsys):
    exp = copy_study(base_study, tmp_path / "study") / "L045"
    (exp / "notch_points.csv").chmod(0)
    rc, _, err = run_main(["fit", exp, "--out", tmp_path / "out", "--models", "cc", "--no-figures"], capsys)
    assert_one_line_error(rc, err, "notch_points.csv", "permission denied")


@pytest.mark.parametrize("variant", ["bom", "crlf", "bom+crlf"])
def test_bom_and_crlf_are_read(variant, base_study, tmp_path, capsys):
    """A byte-order mark and Windows line ends are valid (Excel exports): same fits as the plain files."""
    study = copy_study(base_study, tmp_path / "study")
    for f in ("samples.csv", "notch_points.csv", "experiment.toml"):
        p = study / "L045" / f
        data = p.read_bytes()
        if "crlf" in variant:
            data = data.replace(b"\n", b"\r\n")
        if "bom" in variant:
            data = b"\xef\xbb\xbf" + data
        p.write_bytes(data)
    args = ["--models", "cc", "--no-figures"]
    assert run_main(["fit", study / "L045", "--out", tmp_path / "a", *args], capsys)[0] == 0
    assert run_main(["fit", base_study / "L045", "--out", tmp_path / "b", *args], capsys)[0] == 0
    assert (tmp_path / "a" / "fits.csv").read_bytes() == (tmp_path / "b" / "fits.csv").read_bytes()


# ----------------------------------------------------------------------------- camera files, boards, images
def _camera(folder: Path) -> Path:
    return write_camera(CameraModel.synthetic(320, 240, mm_per_px=0.3), folder / "camera.yml")


def _image_experiment(exp: Path, images: dict) -> None:
    """Give ``exp`` images (sample -> bytes or array) and a camera file; drop its notch points."""
    (exp / "images").mkdir()
    rows = (exp / "samples.csv").read_text().splitlines()
    out = [rows[0] + ",image"]
    for k, row in enumerate(rows[1:], start=1):
        name = f"images/{k:04d}.png"
        img = images.get(k, np.zeros((240, 320), np.uint8))
        p = exp / name
        p.write_bytes(img) if isinstance(img, bytes) else cv2.imwrite(str(p), img)
        out.append(row + "," + name)
    (exp / "samples.csv").write_text("\n".join(out) + "\n")
    (exp / "notch_points.csv").unlink()
    _camera(exp)
    _replace(exp / "experiment.toml", "mirror = false", 'mirror = false\ncalibration = "camera.yml"')


CAMERA_CASES = [
    ("camera-garbage", b"\x00\x01garbage{{{", ["camera.yml", "FileStorage"]),
    ("camera-empty", b"", ["camera.yml"]),
    ("camera-missing-key", b"%YAML:1.0\n---\nimage_width: 320\n", ["camera.yml", "camera_matrix"]),
    ("camera-nan", None, ["camera.yml", "camera_matrix"]),
    ("camera-huge-size", None, ["camera.yml", "image_width"]),
]


@pytest.mark.parametrize("case", CAMERA_CASES, ids=[c[0] for c in CAMERA_CASES])
def test_bad_camera_file(case, base_study, tmp_path, capsys):
    name, data, needles = case
    exp = copy_study(base_study, tmp_path / "study") / "L045"
    _image_experiment(exp, {})
    cam = exp / "camera.yml"
    if name == "camera-nan":
        cam.write_text(cam.read_text().replace("data: [ 4000.", "data: [ .nan", 1))
    elif name == "camera-huge-size":
        cam.write_text(cam.read_text().replace("image_width: 320", "image_width: 1e300"))
    else:
        cam.write_bytes(data)
    out = tmp_path / "out"
    before = prior_outputs(out)
    rc, _, err = run_main(["detect", exp, "--out", out, "--force", "--no-overlays"], capsys)
    assert_one_line_error(rc, err, *needles)
    assert snapshot(out) == before


def _png_with_size(w: int, h: int) -> bytes:
    ok, buf = cv2.imencode(".png", np.zeros((4, 4), np.uint8))
    b = bytearray(buf.tobytes())
    b[16:24] = struct.pack(">II", w, h)
    b[29:33] = struct.pack(">I", zlib.crc32(bytes(b[12:29])) & 0xFFFFFFFF)
    return bytes(b)


BAD_IMAGES = {
    "zero-bytes": b"",
    "truncated": cv2.imencode(".png", np.full((240, 320), 128, np.uint8))[1].tobytes()[:200],
    "wrong-format": b"sample,time_s\n1,2\n",
    "huge-dimensions": _png_with_size(200_000, 200_000),
    "forged-size-under-cv-limit": _png_with_size(30_000, 30_000),
}


def test_bad_images_in_detect_are_listed_per_image(base_study, tmp_path, capsys):
    """detect isolates image failures: exit 1, each bad image listed with its file and reason."""
    exp = copy_study(base_study, tmp_path / "study") / "L045"
    _image_experiment(exp, dict(zip(range(1, 6), BAD_IMAGES.values())))
    rc, out, err = run_main(["detect", exp, "--out", tmp_path / "out", "--no-overlays"], capsys)
    assert rc == 1 and "Traceback" not in err
    failed = [ln for ln in out.splitlines() if "FAILED" in ln]
    assert len(failed) == 5, out
    for k, line in enumerate(failed, start=1):
        assert f"images/{k:04d}.png" in line and "InputFileError" not in line, line   # words, not class names
    assert "too large" in failed[3] and "too large" in failed[4]


def _forged(fmt: str, w: int, h: int) -> bytes:
    """A small image in format ``fmt`` whose header claims ``w x h`` pixels."""
    data = bytearray(cv2.imencode(fmt, np.zeros((40, 50), np.uint8))[1].tobytes())
    if fmt == ".bmp":
        data[18:26] = struct.pack("<ii", w, h)
    elif fmt == ".pgm":
        data = data.replace(b"50 40", f"{w} {h}".encode(), 1)
    else:                                       # TIFF: ImageWidth (256) and ImageLength (257) of IFD 0
        bo = "<" if data[:2] == b"II" else ">"
        ifd = struct.unpack(bo + "I", data[4:8])[0]
        for i in range(struct.unpack(bo + "H", data[ifd:ifd + 2])[0]):
            e = ifd + 2 + 12 * i
            tag, typ = struct.unpack(bo + "HH", data[e:e + 4])
            if tag in (256, 257):
                fmt_v = bo + ("H" if typ == 3 else "I")
                data[e + 8:e + 8 + struct.calcsize(fmt_v)] = struct.pack(fmt_v, w if tag == 256 else h)
    return bytes(data)


@pytest.mark.parametrize("fmt", [".tif", ".bmp", ".pgm"])
@pytest.mark.parametrize("side", [30_000, 60_000])
def test_forged_headers_of_other_formats_are_clean_errors(fmt, side, tmp_path):
    """Formats whose size notchfit does not read from the header itself (TIFF, BMP, PGM): OpenCV
    refuses a header above its own pixel limit, or finds the data missing before it allocates the
    image — an InputFileError naming the file either way, no memory exhausted."""
    from notchfit.io import InputFileError, load_image

    path = tmp_path / f"forged{fmt}"
    path.write_bytes(_forged(fmt, side, side))
    with pytest.raises(InputFileError, match=str(path)):
        load_image(path)


@pytest.mark.parametrize("kind", ["16-bit", "rgba", "rgb"])
def test_16_bit_and_rgba_images_are_processed(kind, base_study, tmp_path, capsys):
    """Images OpenCV decodes in other depths or channel counts: no traceback (processed or listed)."""
    exp = copy_study(base_study, tmp_path / "study") / "L045"
    base = np.full((240, 320), 200, np.uint8)
    img = {"16-bit": base.astype(np.uint16) * 257, "rgba": cv2.cvtColor(base, cv2.COLOR_GRAY2BGRA),
           "rgb": cv2.cvtColor(base, cv2.COLOR_GRAY2BGR)}[kind]
    _image_experiment(exp, {1: img, 2: img})
    rc, out, err = run_main(["detect", exp, "--out", tmp_path / "out", "--no-overlays"], capsys)
    assert rc in (0, 1) and "Traceback" not in err, (rc, out, err)
    said = messages(err)                     # only the images where no point was found (flat grey here)
    assert not said or ("gave no point at all" in said[0] and all(ln.startswith("  ") for ln in said[1:])), err


def test_calibrate_with_only_bad_images_and_bad_boards(tmp_path, capsys):
    paths = []
    for name, data in BAD_IMAGES.items():
        p = tmp_path / f"{name}.png"
        p.write_bytes(data)
        paths.append(p)
    rc, _, err = run_main(["calibrate", *paths, "--board", "charuco_small", "--out", tmp_path / "c.yml"], capsys)
    line = assert_one_line_error(rc, err, "no readable calibration image")
    assert all(p.name in line for p in paths)
    for text, needle in [("squares_x = 1e400\n", "board.toml"), ('type = "chessboard"\nsquares_x = 5\n'
                                                                 'squares_y = 1000000\nsquare_mm = 10\n',
                                                                 "squares_y"),
                         ('squares_x = 5\nsquares_y = 4\nsquare_mm = 10\nmarker_mm = 5\n'
                          'dictionary = "getPredefinedDictionary"\n', "dictionary"),
                         ("\xff", "board.toml")]:
        (tmp_path / "board.toml").write_bytes(text.encode("latin-1"))
        rc, _, err = run_main(["calibrate", paths[0], "--board", tmp_path / "board.toml",
                               "--out", tmp_path / "c.yml"], capsys)
        assert_one_line_error(rc, err, needle)
    rc, _, err = run_main(["calibrate", paths[0], "--board", "no_such_board", "--out", tmp_path / "c.yml"], capsys)
    assert_one_line_error(rc, err, "no_such_board", "charuco_small")


def test_bad_detections_file_names_it(base_study, tmp_path, capsys):
    """fit --points DIR with a corrupt detections.csv for an experiment without notch_points.csv."""
    exp = copy_study(base_study, tmp_path / "study") / "L045"
    _image_experiment(exp, {})
    (tmp_path / "det").mkdir()
    (tmp_path / "det" / "detections.csv").write_text("sample,point,x_mm\n1,1,2\n")
    rc, _, err = run_main(["fit", exp, "--out", tmp_path / "out", "--points", tmp_path / "det"], capsys)
    assert_one_line_error(rc, err, "detections.csv", "missing column")


# ----------------------------------------------------------------------------- the CLI's own faults
def test_unexpected_exception_is_one_line_and_debug_shows_the_traceback(base_study, tmp_path, capsys,
                                                                        monkeypatch):
    from notchfit.commands import fit

    def boom(*a, **k):
        raise TypeError("something nobody expected")

    monkeypatch.setattr(fit, "_fittable", boom)
    argv = ["fit", base_study, "--out", tmp_path / "out"]
    rc, _, err = run_main(argv, capsys)
    assert_one_line_error(rc, err, "unexpected TypeError", "something nobody expected", "--debug")
    rc, _, err = run_main(["--debug", *argv], capsys)
    assert rc == 2 and "Traceback" in err and "boom" in err
    rc, _, err = run_main([*argv, "--debug"], capsys)
    assert rc == 2 and "Traceback" in err
    monkeypatch.setenv("NOTCHFIT_DEBUG", "1")
    rc, _, err = run_main(argv, capsys)
    assert rc == 2 and "Traceback" in err


@pytest.mark.parametrize("argv,needles", [
    (["synth", "null", "--out", "{t}/s", "--samples", "0", "0"], ["--samples", "0 is below 1"]),
    (["synth", "null", "--out", "{t}/s", "--experiments", "0"], ["--experiments", "0 is below 1"]),
    (["synth", "null", "--out", "{t}/s", "--seed", "-5"], ["--seed", "-5 is below 0"]),
    (["fit", "{t}", "--out", "{t}/out", "--jobs", "-3"], ["--jobs", "-3 is below 0"]),
    (["fit", "{t}", "--out", "{t}/out", "--jobs", "100000"], ["--jobs", "100000 worker processes", "at most"]),
    (["diagnose", "{t}", "--out", "{t}/out", "--max-folds", "0"], ["--max-folds", "0 is below 1"]),
    (["diagnose", "{t}", "--out", "{t}/out", "--seed", "-1"], ["--seed", "-1 is below 0"]),
    (["demo", "--out", "{t}/demo", "--jobs", "-5"], ["--jobs", "-5 is below 0"]),
], ids=["synth-samples-0", "synth-experiments-0", "synth-seed-negative", "jobs-negative", "jobs-huge",
        "max-folds-0", "diagnose-seed-negative", "demo-jobs-negative"])
def test_counts_out_of_range_are_usage_errors(argv, needles, tmp_path, capsys):
    """Counts and seeds are checked when the options are parsed: one line, exit 2, before anything runs
    (``--samples 0 0`` was taken as "the recipe's counts"; a negative seed failed deep in numpy)."""
    with pytest.raises(SystemExit) as exc:
        run_main([a.format(t=tmp_path) for a in argv], capsys)
    assert_one_line_error(exc.value.code, capsys.readouterr().err, *needles)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_usage_error_is_one_line(capsys):
    rc = None
    with pytest.raises(SystemExit) as exc:
        run_main(["fit", "x", "--out", "o", "--jobs", "many"], capsys)
    rc = exc.value.code
    assert_one_line_error(rc, capsys.readouterr().err, "--jobs", "many")


def test_subprocess_errors_and_broken_pipe(base_study, tmp_path):
    """In a real process: a bad input is one line (exit 2); `figure --list | head -1` ends quietly."""
    res = run_cli(["fit", base_study / "L045", "--out", base_study / "L045" / "samples.csv" / "x"])
    assert_one_line_error(res.returncode, res.stderr, "samples.csv")
    pipe = subprocess.run(f"'{sys.executable}' -m notchfit.cli figure --list | head -1", shell=True,
                          capture_output=True, text=True, env=cli_env(), timeout=120)
    assert pipe.returncode == 0 and len(pipe.stdout.splitlines()) == 1
    assert pipe.stderr.strip() == "", pipe.stderr
