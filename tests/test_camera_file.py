"""Camera files (docs/data-formats.md "Camera file (YAML)"): notchfit's own parser of the OpenCV
FileStorage YAML subset against OpenCV's reader and writer, its errors (file, line, key), and the
damaged file that made OpenCV's parser abort the process (issue 16, the slow fuzz job).

Files are exchanged both ways with ``cv2.FileStorage``: a file OpenCV writes is read by
``read_camera`` equal (bit for bit: FileStorage writes doubles with 17 significant digits), and a
file ``write_camera`` writes is read by OpenCV equal.
"""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from notchfit.vision.camera import DIST_LENGTHS, CameraModel
from notchfit.io import InputFileError, read_camera, write_camera
from notchfit.units import MM
from reliability_helpers import cli_env

#: The documented example of docs/data-formats.md (OpenCV 4's ``%YAML:1.0`` header).
DOC_EXAMPLE = """%YAML:1.0
---
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 4000., 0., 959.5, 0., 4000., 599.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.08, 0.05, 3.e-04, -2.e-04, 0. ]
image_width: 1920
image_height: 1200
avg_reprojection_error: 0.21
plane_rvec: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ 0.05, -0.03, -1.57 ]
plane_tvec: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ -5.2, 3.1, 120.0 ]
"""

#: The mutation of a camera file (written by write_camera for CameraModel.synthetic(320, 240),
#: OpenCV 5) on which cv2.FileStorage corrupted its heap and aborted the process
#: (``free(): invalid next size``): `cols` of plane_tvec became `co-1s`. Found by
#: ``pytest tests/test_fuzz_readers.py -m slow -k "mutations_of_valid_files_many and camera"``
#: (case 148 of the derandomized run).
CRASHING_FILE = b"""%YAML 1.2
---
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 4000., 0., 159.5, 0., 4000., 119.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.080000000000000002, 0.050000000000000003,
       0.00029999999999999997, -0.00020000000000000001, 0. ]
image_width: 320
image_height: 240
# avg_reprojection_error -1: not measured (a synthetic or hand-made camera)
avg_reprojection_error: -1.
plane_rvec: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ 0.068534997863347283, 0.013711175875220263,
       -1.5711451352270438 ]
plane_tvec: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ -7.3434046644369704e-16, 11.983554417054886,
       120.62803147491532 ]
""".replace(b"   cols: 1\n   dt: d\n   data: [ -7.34", b"   co-1s: 1\n   dt: d\n   data: [ -7.34")


def _opencv_write(path, fields: dict, comment: str | None = None):
    """Write ``fields`` (key -> number, string or array) with cv2.FileStorage, as OpenCV's sample does."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
    if comment:
        fs.writeComment(comment)
    for k, v in fields.items():
        fs.write(k, v)
    fs.release()
    return path


def _opencv_read(path, key):
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    node = fs.getNode(key)
    out = node.mat() if node.isMap() else node.real()
    fs.release()
    return out


def test_documented_example_read_equal_by_opencv_and_notchfit(tmp_path):
    path = tmp_path / "camera.yml"
    path.write_text(DOC_EXAMPLE)
    cam = read_camera(path)
    np.testing.assert_array_equal(cam.camera_matrix, _opencv_read(path, "camera_matrix"))
    np.testing.assert_array_equal(cam.dist_coeffs, _opencv_read(path, "distortion_coefficients").ravel())
    assert cam.image_size == (1920, 1200) and cam.rms == 0.21
    np.testing.assert_array_equal(cam.plane_rvec, [0.05, -0.03, -1.57])
    np.testing.assert_array_equal(cam.plane_tvec, np.array([-5.2, 3.1, 120.0]) * MM)


def test_file_written_by_opencv_with_the_sample_keys_and_extras_is_read_equal(tmp_path, rng):
    """OpenCV's calibration sample writes strings, counts, Nx1 errors, 2-channel point matrices and
    nested maps beside the keys notchfit reads: those are ignored, the keys read bit for bit."""
    K = np.array([[3987.123456789, 0.25, 955.5], [0, 4012.987654321, 601.25], [0, 0, 1]])
    d = rng.normal(0, 0.05, (8, 1))             # the sample writes 8x1 (rational model)
    rv, tv_mm = rng.normal(0, 1, (3, 1)), rng.normal(0, 50, (3, 1))
    pve = rng.uniform(0.1, 0.4, (7, 1))
    path = tmp_path / "camera.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
    fs.write("calibration_time", "Mon Nov 24 2025: 10:00 # not a comment \"quoted\"")
    fs.write("nframes", 7)
    fs.writeComment("flags: +fix_aspectRatio")
    for k, v in {"camera_matrix": K, "distortion_coefficients": d, "image_width": 1920, "image_height": 1200,
                 "avg_reprojection_error": 0.3125, "per_view_reprojection_errors": pve,
                 "image_points": rng.normal(0, 100, (7, 54, 2)).astype(np.float32).reshape(7, 54, 2),
                 "plane_rvec": rv, "plane_tvec": tv_mm, "board": "charuco_small"}.items():
        fs.write(k, v)
    fs.startWriteStruct("settings", cv2.FileNode_MAP)
    fs.write("square_size", 4.0)
    fs.startWriteStruct("views", cv2.FileNode_SEQ)
    fs.write("", 1.5)
    fs.write("", 2)
    fs.endWriteStruct()
    fs.endWriteStruct()
    fs.release()
    cam = read_camera(path)
    np.testing.assert_array_equal(cam.camera_matrix, K)
    np.testing.assert_array_equal(cam.dist_coeffs, d.ravel())
    np.testing.assert_array_equal(cam.plane_rvec, rv.ravel())
    np.testing.assert_array_equal(cam.plane_tvec, tv_mm.ravel() * MM)
    np.testing.assert_array_equal(cam.per_view_errors, pve.ravel())
    assert cam.image_size == (1920, 1200) and cam.rms == 0.3125


def test_write_camera_output_is_read_equal_by_opencv(tmp_path):
    cam = CameraModel.synthetic(640, 480).replace(rms=0.1234, std_intrinsics=np.arange(1, 10) * 0.01,
                                                  per_view_errors=np.array([0.11, 0.22, 0.33]), plane_rms=0.05)
    path = write_camera(cam, tmp_path / "camera.yml", extra={"board": "charuco_small", "views_used": 3})
    np.testing.assert_array_equal(_opencv_read(path, "camera_matrix"), cam.camera_matrix)
    np.testing.assert_array_equal(_opencv_read(path, "distortion_coefficients"), cam.dist_coeffs.reshape(1, -1))
    np.testing.assert_array_equal(_opencv_read(path, "plane_rvec"), cam.plane_rvec.reshape(3, 1))
    np.testing.assert_allclose(_opencv_read(path, "plane_tvec"), (cam.plane_tvec / MM).reshape(3, 1), rtol=1e-15)
    np.testing.assert_array_equal(_opencv_read(path, "intrinsics_std_dev").ravel(), cam.std_intrinsics)
    np.testing.assert_array_equal(_opencv_read(path, "per_view_reprojection_errors").ravel(), cam.per_view_errors)
    assert (_opencv_read(path, "image_width"), _opencv_read(path, "image_height")) == (640, 480)
    assert _opencv_read(path, "avg_reprojection_error") == 0.1234
    assert _opencv_read(path, "plane_reprojection_error") == 0.05
    back = read_camera(path)
    np.testing.assert_array_equal(back.camera_matrix, cam.camera_matrix)
    np.testing.assert_array_equal(back.plane_tvec, (np.asarray(cam.plane_tvec) / MM).reshape(3) * MM)
    assert back.rms == 0.1234 and back.plane_rms == 0.05
    np.testing.assert_array_equal(back.std_intrinsics, cam.std_intrinsics)


_finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False, allow_subnormal=True)


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(fx=st.floats(1e-3, 1e7), fy=st.floats(1e-3, 1e7), skew=_finite, cx=_finite, cy=_finite,
       dist=st.sampled_from(DIST_LENGTHS).flatmap(lambda n: st.lists(_finite, min_size=n, max_size=n)),
       size=st.tuples(st.integers(1, 1_000_000), st.integers(1, 1_000_000)),
       plane=st.lists(_finite, min_size=6, max_size=6), column=st.booleans())
def test_any_camera_opencv_writes_is_read_bit_for_bit(tmp_path_factory, fx, fy, skew, cx, cy, dist, size, plane,
                                                      column):
    """A round trip through OpenCV's writer over the whole value range: subnormal, huge, negative
    numbers, every distortion length, 1xN or Nx1 layouts."""
    path = tmp_path_factory.mktemp("cam") / "camera.yml"
    K = np.array([[fx, skew, cx], [0, fy, cy], [0, 0, 1]])
    d = np.array(dist).reshape((-1, 1) if column else (1, -1))
    _opencv_write(path, {"camera_matrix": K, "distortion_coefficients": d, "image_width": size[0],
                         "image_height": size[1], "plane_rvec": np.array(plane[:3]).reshape(3, 1),
                         "plane_tvec": np.array(plane[3:]).reshape(3, 1)}, comment="written by OpenCV")
    cam = read_camera(path)
    np.testing.assert_array_equal(cam.camera_matrix, K)
    np.testing.assert_array_equal(cam.dist_coeffs, d.ravel())
    np.testing.assert_array_equal(cam.plane_rvec, plane[:3])
    np.testing.assert_array_equal(cam.plane_tvec, np.array(plane[3:]) * MM)
    assert cam.image_size == size


def _edit(old: str, new: str) -> str:
    assert old in DOC_EXAMPLE, old
    return DOC_EXAMPLE.replace(old, new, 1)


@pytest.mark.parametrize("text,line,needle", [
    ("", None, "first line must be %YAML"),
    ("camera_matrix: 1\n", 1, "first line must be %YAML"),
    ("%YAML:2.0\n---\n", 1, "first line must be %YAML"),
    (_edit("   cols: 3\n", ""), 3, "camera_matrix: the matrix lacks cols"),
    (_edit("   cols: 3\n", "   co-1s: 3\n"), 5, "expected one of rows, cols, dt, data"),
    (_edit("   rows: 3\n   cols: 1\n   dt: d\n   data: [ -5.2", "   rows: 4\n   cols: 1\n   dt: d\n   data: [ -5.2"),
     25, "plane_tvec: data holds 3 values, rows x cols x channels = 4 x 1 x 1"),
    (_edit("rows: 3", "rows: 99999999999"), 4, "rows must be a positive integer"),
    (_edit("rows: 3", "rows: -3"), 4, "rows must be a positive integer"),
    (_edit("dt: d", "dt: q"), 6, "dt must be a number type"),
    (_edit("959.5", "1,5"), 7, "data holds 10 values"),
    (_edit("959.5", "nine"), 7, "camera_matrix: 'nine' is not a number"),
    (_edit("959.5", ".NaN"), 3, "camera_matrix: holds non-finite values"),
    (_edit("959.5", "1e400"), 3, "camera_matrix: holds non-finite values"),
    (_edit("0., 1. ]", "0., 1. "), 7, "not closed"),
    (_edit("1. ]\n", "1. ]]\n"), 7, "closing bracket"),
    (_edit("   rows: 3\n", "\trows: 3\n"), 4, "tab"),
    (_edit("image_height: 1200\n", "image_height: 1200\nimage_width: 1920\n"), 15, "'image_width' appears twice"),
    (_edit("image_width: 1920", "image_width: 1920.5"), 13, "image_width/image_height must be positive integers"),
    (_edit("image_width: 1920", "image_width: 1e300"), 13, "image_width/image_height must be positive integers"),
    (_edit("image_width: 1920", "image_width: .Inf"), 13, "image_width: must be a finite number"),
    (_edit("image_width: 1920", "image_width: 1920,0"), 13, "image_width: '1920,0' is not a number"),
    (_edit("image_width: 1920", "image_width: \"1920\""), 13, "is not a number"),
    (_edit("avg_reprojection_error: 0.21", "avg_reprojection_error:\n   - 0.21"), 15, "must be a number on its line"),
    (_edit("image_width: 1920\n", "image width 1920\n"), 13, "expected 'key: value'"),
    (_edit("plane_tvec: !!opencv-matrix", "plane_tvec: [ 1, 2 ]\nold_tvec: !!opencv-matrix"), 21,
     "plane_tvec: must be 3x1, got 2 values"),
    (_edit("plane_tvec:", "old_plane_tvec:"), 16, "plane_rvec and plane_tvec must be given together"),
    (_edit("image_width: 1920\n", ""), None, "missing key 'image_width'"),
    (_edit("dt: d\n   data: [ -0.08", "dt: d\n   data: [ -0.08, 1"), 12, "distortion_coefficients: data holds 6"),
    (_edit("rows: 1\n   cols: 5", "rows: 1\n   cols: 6"), 12, "data holds 5 values"),
    (_edit("4000., 0., 959.5, 0., 4000.", "-4000., 0., 959.5, 0., 4000."), None, "fx, fy > 0"),
])
def test_malformed_camera_file_names_file_line_and_key(tmp_path, text, line, needle):
    path = tmp_path / "camera.yml"
    path.write_text(text)
    with pytest.raises(InputFileError) as info:
        read_camera(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(str(path)), msg
    assert needle in msg, msg
    assert info.value.line == line, msg
    if line is not None:
        assert f": line {line}" in msg, msg


@pytest.mark.parametrize("change", ["crlf", "bom", "comments", "spread", "header_space", "document_end"])
def test_valid_variants_of_the_documented_file_are_read_equal(tmp_path, change):
    """Line endings, a byte-order mark, comments anywhere, a data list spread over lines with a
    trailing comma, OpenCV 5's ``%YAML 1.2`` header and ``...`` ending the document read the same."""
    text = DOC_EXAMPLE
    if change == "crlf":
        text = text.replace("\n", "\r\n")
    elif change == "bom":
        text = "\ufeff" + text
    elif change == "comments":
        text = text.replace("\n", "   # note [ with { brackets\n").replace("%YAML:1.0   # note [ with { brackets",
                                                                          "%YAML:1.0") + "# the end\n"
    elif change == "spread":
        text = text.replace("[ 4000., 0., 959.5,", "[ 4000.,\n  # a comment inside\n   0.,\n959.5,").replace(
            "0., 0., 1. ]", "0., 0., 1., ]")
    elif change == "header_space":
        text = text.replace("%YAML:1.0", "%YAML 1.2")
    elif change == "document_end":
        text = text + "...\nanything: [ after the end\n"
    path = tmp_path / "camera.yml"
    path.write_text(text, newline="")
    ref = tmp_path / "ref.yml"
    ref.write_text(DOC_EXAMPLE)
    a, b = read_camera(path), read_camera(ref)
    np.testing.assert_array_equal(a.camera_matrix, b.camera_matrix)
    np.testing.assert_array_equal(a.dist_coeffs, b.dist_coeffs)
    np.testing.assert_array_equal(a.plane_tvec, b.plane_tvec)
    assert (a.image_size, a.rms) == (b.image_size, b.rms)


def test_the_file_that_aborted_opencv_is_a_clean_error_in_a_subprocess(tmp_path):
    """Regression (issue 16): cv2.FileStorage aborted the whole process on this file in about half
    of the runs (heap corruption: ``free(): invalid next size``). Read 40 copies in a child process:
    a crash shows as this test failing, not as a dead pytest; each read is an InputFileError naming
    the file and line 26 (the damaged `cols`)."""
    paths = []
    for i in range(40):
        p = tmp_path / f"camera_{i:02d}.yml"
        p.write_bytes(CRASHING_FILE)
        paths.append(p)
    code = ("import sys\nfrom notchfit.io import InputFileError, read_camera\n"
            "for p in sys.argv[1:]:\n"
            "    try:\n        read_camera(p)\n        print('read', p)\n"
            "    except InputFileError as exc:\n        print(exc)\n")
    res = subprocess.run([sys.executable, "-c", code, *map(str, paths)], capture_output=True, text=True,
                         timeout=120, env=cli_env())
    assert res.returncode == 0, (res.returncode, res.stderr[-2000:])
    lines = res.stdout.splitlines()
    assert len(lines) == 40, res.stdout
    for p, ln in zip(paths, lines):
        assert ln == f"{p}: line 26: plane_tvec: expected one of rows, cols, dt, data, got 'co-1s: 1'", ln
