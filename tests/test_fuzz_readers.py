"""Reliability (issue 16), fuzzing: every reader, fed random bytes and mutations of a valid file,
either returns or raises the documented error type — :class:`notchfit.io.InputFileError` (a
ValueError) whose message is one line naming the file. Nothing else may escape (no TypeError,
OverflowError, UnicodeDecodeError, cv2.error, KeyError, RecursionError, ...).

Hypothesis runs derandomized (a fixed seed per test): ``FUZZ_EXAMPLES`` cases per reader and
strategy in the default job, ``FUZZ_EXAMPLES_SLOW`` with ``-m slow``. ``-s`` prints the counts
of cases tried and of clean errors per reader (docs/reliability.md quotes them).
"""

from __future__ import annotations

import collections
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from notchfit import io
from notchfit.vision.camera import CameraModel
from notchfit.studies.synth import load_recipe
from reliability_helpers import make_study

FUZZ_EXAMPLES = 200
FUZZ_EXAMPLES_SLOW = 3000

#: Tokens that break readers: special floats, huge numbers, separators, encodings, structure.
TOKENS = [b"", b"nan", b"inf", b"-inf", b"1e400", b"1e20", b"-1e308", b"12345678901234567890123", b"1,5",
          b"\xff", b"\xe9", b"\xef\xbb\xbf", b"\r\n", b"\n", b",", b";", b'"', b"'", b"=", b"[", b"]", b"[[",
          b"]]", b"{", b"}", b"\x00", b"-1", b"0", b"true", b"1e-400", b"0x10", b"\t", b"#", b"!!opencv-matrix",
          b"data: [", b"rows: 99999999", b"[[" * 600, b"9" * 400, b"\\u0000", b"..", b"/"]

COUNTS: dict = collections.defaultdict(lambda: [0, 0])     # reader -> [cases, clean errors]


# ----------------------------------------------------------------------------- valid seed files
def _seeds(folder: Path) -> dict:
    study = make_study(folder / "study", n_experiments=1, n_up=2, n_down=2)
    exp = study / "L045"
    cam = io.write_camera(CameraModel.synthetic(320, 240), folder / "camera.yml").read_bytes()
    png = cv2.imencode(".png", (np.arange(48 * 64) % 251).astype(np.uint8).reshape(48, 64))[1].tobytes()
    jpg = cv2.imencode(".jpg", (np.arange(48 * 64) % 251).astype(np.uint8).reshape(48, 64))[1].tobytes()
    rgb = (np.arange(48 * 64 * 3) % 251).astype(np.uint8).reshape(48, 64, 3)
    tif, bmp = (cv2.imencode(ext, rgb)[1].tobytes() for ext in (".tif", ".bmp"))
    return {
        "experiment.toml": (exp / "experiment.toml").read_bytes(),
        "samples.csv": (exp / "samples.csv").read_bytes(),
        "notch_points.csv": (exp / "notch_points.csv").read_bytes()[:3000],
        "geometry.toml": (io.datasets_dir() / "geometry" / "default.toml").read_bytes(),
        "model.toml": b"k_lin_Nm_per_rad = 0.05\nmu_d = 0.2\n[metadata]\ncause = \"none\"\n",
        "board.toml": (io.calibration_dir() / "charuco_small.toml").read_bytes(),
        "recipe.toml": (io.datasets_dir() / "recipes" / "null.toml").read_bytes(),
        "fea.toml": (io.datasets_dir() / "reference" / "fea_sec3d.toml").read_bytes(),
        "detections.csv": b"sample,point,x_mm,y_mm,u_px,v_px,sigma_mm,status\n1,1,0.5,1.5,10,20,0.01,ok\n"
                          b"1,2,,,,,,occluded\n2,1,0.25,-1.5,11,21,0.02,ambiguous\n",
        "fits.csv": b"sample,model,a,b,base_x_mm,base_y_mm,base_phi_rad,rms_mm,max_mm,n_points,message\n"
                    b"1,cc,0.01,0,0.1,0.2,0.003,0.02,0.05,58,converged\n2,linear,0.02,0.001,0,0,0,0.01,0.03,58,\n",
        "pointwise.csv": b"sample,model,point,err_mm\n1,cc,1,0.01\n1,cc,2,nan\n",
        "simulation.csv": b"sample,regime,a,b,theta_1,theta_2\n1,I,0.01,0.0,0.01,0.01\n",
        "diagnosis.json": b'{"experiments": ["L045"], "baseline": {"k_lin": 0.05}, "discrepancies": [], '
                          b'"candidates": [], "cause": "none", "explanation": "", "gain": {"baseline": 1.0}}\n',
        "camera.yml": cam,
        "image.png": png,
        "image.jpg": jpg,
        "image.tif": tif,
        "image.bmp": bmp,
    }


@pytest.fixture(scope="module")
def seeds():
    folder = Path(tempfile.mkdtemp(prefix="notchfit-fuzz-"))
    yield folder, _seeds(folder)
    for name, (n, clean) in sorted(COUNTS.items()):
        print(f"fuzz {name:18s} {n:6d} cases, {clean:6d} clean errors, 0 other exceptions")


def _read_board(p):
    return io.load_board(p)


READERS = {
    "experiment.toml": io.read_experiment_toml,
    "samples.csv": io.read_samples,
    "notch_points.csv": lambda p: io.read_points_table(p, n_points=58, sample_ids=range(1, 6)),
    "geometry.toml": io.load_geometry,
    "model.toml": io.load_params,
    "board.toml": _read_board,
    "recipe.toml": load_recipe,
    "fea.toml": io.load_fea_reference,
    "detections.csv": lambda p: io.read_detections(p, n_points=58, sample_ids=[1, 2]),
    "fits.csv": io.read_fits,
    "pointwise.csv": io.read_pointwise,
    "simulation.csv": io.read_simulation,
    "diagnosis.json": io.read_diagnosis,
    "camera.yml": io.read_camera,
    "image.png": io.load_image,
    "image.jpg": io.load_image,
    "image.tif": io.load_image,
    "image.bmp": io.load_image,
}


# ----------------------------------------------------------------------------- strategies
@st.composite
def mutated(draw, seed: bytes) -> bytes:
    """``seed`` with 1-4 edits: a token inserted or written over a span, a span deleted, a line
    doubled, or the file cut short."""
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["insert", "replace", "delete", "double_line", "truncate", "flip"]))
        i = draw(st.integers(0, len(data)))
        j = min(len(data), i + draw(st.integers(0, 12)))
        tok = draw(st.sampled_from(TOKENS) | st.binary(max_size=8))
        if op == "insert":
            data[i:i] = tok
        elif op == "replace":
            data[i:j] = tok
        elif op == "delete":
            del data[i:j]
        elif op == "truncate":
            del data[i:]
        elif op == "flip" and i < len(data):
            data[i] ^= 1 << draw(st.integers(0, 7))
        elif op == "double_line":
            start = data.rfind(b"\n", 0, i) + 1
            end = data.find(b"\n", i)
            end = len(data) if end < 0 else end + 1
            data[start:start] = data[start:end]
    return bytes(data)


def _check(name: str, folder: Path, data: bytes) -> None:
    """Write ``data`` as file ``name`` and read it: a result or a one-line InputFileError naming it."""
    path = folder / "fuzz" / name
    path.parent.mkdir(exist_ok=True)
    path.write_bytes(data)
    COUNTS[name][0] += 1
    try:
        READERS[name](path)
    except io.InputFileError as exc:
        COUNTS[name][1] += 1
        msg = str(exc)
        assert "\n" not in msg, msg
        assert str(path) in msg or path.name in msg, msg


def _fuzz_settings(n: int):
    return settings(max_examples=n, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


def _random_bytes(seeds, name, data):
    folder, valid = seeds
    head = valid[name][:data.draw(st.integers(0, 16))]        # a valid signature, sometimes
    _check(name, folder, head + data.draw(st.binary(max_size=600)))


def _mutations(seeds, name, data):
    folder, valid = seeds
    _check(name, folder, data.draw(mutated(valid[name])))


@pytest.mark.parametrize("name", list(READERS))
@_fuzz_settings(FUZZ_EXAMPLES)
@given(data=st.data())
def test_random_bytes(seeds, name, data):
    _random_bytes(seeds, name, data)


@pytest.mark.parametrize("name", list(READERS))
@_fuzz_settings(FUZZ_EXAMPLES)
@given(data=st.data())
def test_mutations_of_valid_files(seeds, name, data):
    _mutations(seeds, name, data)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(READERS))
@_fuzz_settings(FUZZ_EXAMPLES_SLOW)
@given(data=st.data())
def test_random_bytes_many(seeds, name, data):
    _random_bytes(seeds, name, data)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(READERS))
@_fuzz_settings(FUZZ_EXAMPLES_SLOW)
@given(data=st.data())
def test_mutations_of_valid_files_many(seeds, name, data):
    _mutations(seeds, name, data)


def test_valid_seeds_are_read(seeds):
    """The seeds themselves are valid: the mutations start from files the readers accept."""
    folder, valid = seeds
    for name in READERS:
        path = folder / "valid" / name
        path.parent.mkdir(exist_ok=True)
        path.write_bytes(valid[name])
        READERS[name](path)
