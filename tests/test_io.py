"""notchfit.io: experiment folders, studies and outputs (data-format.md)."""
import os

import numpy as np
import pandas as pd
import pytest

from notchfit import io
from notchfit.physics.notches import notch_points, to_plane


def _samples(S=5, image=False):
    df = pd.DataFrame({
        "sample": np.arange(1, S + 1),
        "time_s": 5.0 * np.arange(S) + 0.5,
        "tension_left_N": np.linspace(0.45, 20.25, S),
        "tension_right_N": np.full(S, 0.45),
        "displacement_left_mm": np.linspace(0, 1.3, S),
        "displacement_right_mm": [np.nan] * S,
    })
    if image:
        df["image"] = [f"images/{i:03d}.png" for i in range(1, S + 1)]
    return df


def _points(geom, S=5, rng=None):
    th = np.linspace(0, -0.1, S)[:, None] * np.ones(geom.n_joints)
    pts = to_plane(notch_points(th, geom), 0.012, -0.004, 0.3, mirror=True)
    pts[1, 7] = np.nan  # an occluded point
    return pts


def _write(tmp_path, geom, **kw):
    return io.write_experiment(tmp_path / "ct045", name="ct045", samples=_samples(),
                               points=_points(geom), mirror=True, description="a test",
                               point_sigma=2e-5, tension_sigma=0.11, **kw)


def test_round_trip_experiment(tmp_path, geom):
    folder = _write(tmp_path, geom)
    exp = io.read_experiment(folder)
    pd.testing.assert_frame_equal(exp.samples, _samples())
    assert exp.name == "ct045" and exp.mirror is True and exp.description == "a test"
    assert exp.point_sigma == pytest.approx(2e-5) and exp.tension_sigma == 0.11
    assert exp.geometry == geom and exp.calibration_path is None and exp.image_paths is None
    np.testing.assert_allclose(exp.points, _points(geom), rtol=1e-15, atol=1e-18)
    assert np.isnan(exp.points[1, 7]).all() and np.isfinite(exp.points[0]).all()
    np.testing.assert_array_equal(exp.sample_ids, np.arange(1, 6))
    np.testing.assert_allclose(exp.tension_left, _samples()["tension_left_N"])
    assert exp.n_samples == 5


def test_round_trip_points_frame(tmp_path, geom):
    df = io.points_table(_points(geom), np.arange(1, 6))
    assert len(df) == 5 * 58 - 1
    io.write_table_atomic(df, tmp_path / "notch_points.csv")
    back = io.read_points_table(tmp_path / "notch_points.csv", n_points=58)
    pd.testing.assert_frame_equal(back, df.reset_index(drop=True))


def test_round_trip_image_column(tmp_path, geom):
    folder = tmp_path / "e"
    (folder / "images").mkdir(parents=True)
    for i in range(1, 6):
        (folder / f"images/{i:03d}.png").write_bytes(b"x")
    (folder / "cam.yml").write_text("%YAML:1.0\n")
    io.write_experiment(folder, name="e", samples=_samples(image=True), calibration="cam.yml")
    exp = io.read_experiment(folder)
    pd.testing.assert_frame_equal(exp.samples, _samples(image=True))
    assert exp.points is None and exp.image_paths[2] == folder / "images/003.png"
    assert exp.calibration_path == folder / "cam.yml"


def test_write_refuses_existing_without_force(tmp_path, geom):
    _write(tmp_path, geom)
    with pytest.raises(FileExistsError, match="--force"):
        _write(tmp_path, geom)
    _write(tmp_path, geom, force=True)


def _edit(folder, name, old, new):
    p = folder / name
    txt = p.read_text()
    assert old in txt
    p.write_text(txt.replace(old, new, 1))


def _samples_lines(folder):
    return (folder / "samples.csv").read_text().splitlines()


def test_error_missing_column(tmp_path, geom):
    folder = _write(tmp_path, geom)
    _edit(folder, "samples.csv", "tension_right_N", "tension_rigth_N")
    with pytest.raises(ValueError, match=r"samples\.csv: line 1: missing column\(s\) tension_right_N"):
        io.read_experiment(folder)


def test_error_non_numeric(tmp_path, geom):
    folder = _write(tmp_path, geom)
    lines = _samples_lines(folder)
    f = lines[3].split(",")
    f[2] = "12,5"[:2] + "x"
    lines[3] = ",".join(f)
    (folder / "samples.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"samples\.csv: line 4: column tension_left_N: "
                                         r"non-numeric value '12x'"):
        io.read_experiment(folder)


def test_error_duplicate_sample(tmp_path, geom):
    folder = _write(tmp_path, geom)
    lines = _samples_lines(folder)
    lines[4] = "2" + lines[4][1:]
    (folder / "samples.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"samples\.csv: line 5: duplicate sample 2 \(first on line 3\)"):
        io.read_experiment(folder)


def test_error_non_monotonic_time(tmp_path, geom):
    folder = _write(tmp_path, geom)
    lines = _samples_lines(folder)
    f = lines[5].split(",")
    f[1] = "3.0"
    lines[5] = ",".join(f)
    (folder / "samples.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"samples\.csv: line 6: time_s 3 is not after 15\.5 \(line 5\)"):
        io.read_experiment(folder)


def test_error_point_out_of_range(tmp_path, geom):
    folder = _write(tmp_path, geom)
    lines = (folder / "notch_points.csv").read_text().splitlines()
    f = lines[9].split(",")
    f[1] = "59"
    lines[9] = ",".join(f)
    (folder / "notch_points.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"notch_points\.csv: line 10: point id 59 out of range 1\.\.58"):
        io.read_experiment(folder)


def test_error_point_duplicate_and_unknown_sample(tmp_path, geom):
    folder = _write(tmp_path, geom)
    lines = (folder / "notch_points.csv").read_text().splitlines()
    lines.append(lines[3])
    lines.append("99,1,0.0,0.0")
    (folder / "notch_points.csv").write_text("\n".join(lines) + "\n")
    n = len(lines)
    with pytest.raises(ValueError) as ei:
        io.read_experiment(folder)
    msg = str(ei.value)
    assert "notch_points.csv: 2 problems" in msg
    assert f"line {n - 1}: duplicate point 3 of sample 1 (first on line 4)" in msg
    assert f"line {n}: sample 99 is not in samples.csv" in msg


def test_error_image_missing(tmp_path, geom):
    folder = tmp_path / "e"
    (folder / "images").mkdir(parents=True)
    for i in (1, 2, 4, 5):
        (folder / f"images/{i:03d}.png").write_bytes(b"x")
    (folder / "cam.yml").write_text("%YAML:1.0\n")
    io.write_experiment(folder, name="e", samples=_samples(image=True), calibration="cam.yml")
    with pytest.raises(ValueError, match=r"samples\.csv: line 4: image missing: images/003\.png"):
        io.read_experiment(folder)
    exp = io.read_experiment(folder, missing_images="keep")  # a batch reports it per image
    assert not exp.image_paths[2].exists()


def test_error_bad_toml(tmp_path, geom):
    folder = _write(tmp_path, geom)
    _edit(folder, "experiment.toml", "mirror = true", "mirror = tru")
    with pytest.raises(ValueError, match=r"experiment\.toml: line 4: bad TOML"):
        io.read_experiment(folder)


def test_error_toml_bad_values(tmp_path, geom):
    folder = _write(tmp_path, geom)
    _edit(folder, "experiment.toml", "mirror = true", 'mirror = "yes"\nmirorr = true')
    _edit(folder, "experiment.toml", "point_mm = ", "point_mm = -")
    with pytest.raises(ValueError) as ei:
        io.read_experiment(folder)
    msg = str(ei.value)
    assert "experiment.toml: 3 problems" in msg
    assert "line 5: unknown key 'mirorr'" in msg
    assert "line 4: mirror must be true or false, got 'yes'" in msg
    assert "line 8: [uncertainty] point_mm must be a positive number" in msg


def test_error_no_points_no_images(tmp_path, geom):
    folder = _write(tmp_path, geom)
    os.remove(folder / "notch_points.csv")
    with pytest.raises(ValueError, match="no notch_points.csv, no angles.csv and no images"):
        io.read_experiment(folder)


def test_error_ragged_row(tmp_path, geom):
    folder = _write(tmp_path, geom)
    with open(folder / "samples.csv", "a") as fh:
        fh.write("9,99.0,1.0\n")
    with pytest.raises(ValueError, match=r"samples\.csv: line 7: 3 fields, the header has 6"):
        io.read_experiment(folder)


def test_read_study_sorted_and_single(tmp_path, geom):
    for name in ("ct200", "ct045"):
        io.write_experiment(tmp_path / "study" / name, name=name, samples=_samples(), points=_points(geom))
    (tmp_path / "study" / "truth.json").write_text("{}")
    exps = io.read_study(tmp_path / "study")
    assert [e.name for e in exps] == ["ct045", "ct200"]
    assert [e.name for e in io.read_study(tmp_path / "study" / "ct200")] == ["ct200"]
    with pytest.raises(ValueError, match="neither an experiment folder"):
        io.read_study(tmp_path)


def test_detections_to_points(tmp_path, geom):
    folder = _write(tmp_path, geom)
    exp = io.read_experiment(folder)
    df = io.points_table(exp.points, exp.sample_ids)
    df["u_px"], df["v_px"], df["sigma_mm"] = 1.0, 2.0, 0.01
    df["status"] = "ok"
    df.loc[5, "status"] = "low_contrast"
    io.write_table_atomic(df, tmp_path / "detections.csv")
    got = io.load_detected_points(exp, tmp_path / "detections.csv")
    want = exp.points.copy()
    want[0, 5] = np.nan
    np.testing.assert_allclose(got.points, want, rtol=1e-15, atol=1e-18)


def test_atomic_write_keeps_old_file_on_failure(tmp_path):
    p = tmp_path / "t.csv"
    io.write_table_atomic(pd.DataFrame({"a": [1, 2]}), p)

    class Boom(pd.DataFrame):
        def to_csv(self, *a, **k):
            with open(a[0], "w") as fh:
                fh.write("a\n1\n")  # half-written
            raise OSError("disk full")

    with pytest.raises(OSError):
        io.write_table_atomic(Boom({"a": [3]}), p)
    assert p.read_text() == "a\n1\n2\n"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["t.csv"]


def test_output_run_refuses_and_is_all_or_nothing(tmp_path):
    out = tmp_path / "out"
    with io.OutputRun(out, outputs=["fits.csv"]) as run:
        io.write_table_atomic(pd.DataFrame({"a": [1]}), run.path("fits.csv"))
        io.write_table_atomic(pd.DataFrame({"a": [1]}), run.path("ct045/fits.csv"))
    assert (out / "fits.csv").read_text() == "a\n1\n"
    with pytest.raises(FileExistsError, match="--force"):
        io.OutputRun(out, outputs=["fits.csv"])
    # another command's outputs in the same folder are not a clash
    with io.OutputRun(out, outputs=["simulation.csv"]) as run:
        io.write_table_atomic(pd.DataFrame({"s": [1]}), run.path("simulation.csv"))
    # a failing forced run leaves the old results untouched (crash mid-way)
    with pytest.raises(RuntimeError):
        with io.OutputRun(out, outputs=["fits.csv"], force=True) as run:
            io.write_table_atomic(pd.DataFrame({"a": [2]}), run.path("fits.csv"))
            raise RuntimeError("solver failed")
    assert (out / "fits.csv").read_text() == "a\n1\n"
    assert sorted(p.name for p in out.iterdir()) == ["ct045", "fits.csv", "simulation.csv"]
    with io.OutputRun(out, outputs=["fits.csv"], force=True) as run:
        io.write_table_atomic(pd.DataFrame({"a": [2]}), run.path("fits.csv"))
    assert (out / "fits.csv").read_text() == "a\n2\n"
    assert io.find_output(out, "fits.csv") == {"": out / "fits.csv", "ct045": out / "ct045/fits.csv"}


def test_prepare_output_dir_plain(tmp_path):
    out = io.prepare_output_dir(tmp_path / "o")
    (out / "x.txt").write_text("1")
    with pytest.raises(FileExistsError):
        io.prepare_output_dir(out)
    assert io.prepare_output_dir(out, force=True) == out


def test_json_and_toml_helpers(tmp_path):
    p = io.write_json_atomic({"a": np.float64(1.5), "b": np.arange(3), "c": float("nan")}, tmp_path / "x.json")
    assert io.read_json(p) == {"a": 1.5, "b": [0, 1, 2], "c": None}
    (tmp_path / "bad.json").write_text('{\n "a": 1,\n}')
    with pytest.raises(ValueError, match=r"bad\.json: line 3: bad JSON"):
        io.read_json(tmp_path / "bad.json")
    import tomllib
    d = {"s": 'q"\\\x7f', "f": 1e-7, "l": [1.0, 2.0], "t": {"x": True}, "a": [{"k": 1}, {"k": 2}]}
    assert tomllib.loads(io.toml_dumps(d)) == d
    nested = {"m": {"n": 1, "inner": {"x": 2.5, "deeper": {"y": "z"}}, "rows": [{"k": 1}]}, "top": 3}
    assert tomllib.loads(io.toml_dumps(nested)) == nested
    back = tomllib.loads(io.toml_dumps({"v": float("nan"), "w": -float("inf")}))
    assert np.isnan(back["v"]) and back["w"] == -np.inf


def test_output_run_whole_dirs_leaves_no_stale_files(tmp_path):
    out = tmp_path / "study"
    with io.OutputRun(out, outputs=["e1"], name="synth", whole_dirs=True) as run:
        (run.path("e1/notch_points.csv")).write_text("old")
        (run.path("e1/samples.csv")).write_text("old")
    with io.OutputRun(out, outputs=["e1"], force=True, name="synth", whole_dirs=True) as run:
        (run.path("e1/samples.csv")).write_text("new")
        (run.path("truth.json")).write_text("{}")
    assert sorted(p.name for p in (out / "e1").iterdir()) == ["samples.csv"]
    assert (out / "e1/samples.csv").read_text() == "new" and (out / "truth.json").is_file()
    assert sorted(p.name for p in out.iterdir()) == ["e1", "truth.json"]


def test_camera_io_is_re_exported():
    from notchfit.io import camera

    assert io.read_camera is camera.read_camera and io.write_camera is camera.write_camera
    with pytest.raises(AttributeError):
        io.no_such_reader


def test_load_toml_lines_and_errors(tmp_path):
    f = tmp_path / "x.toml"
    f.write_text('# head\nname = "a"\n\n[uncertainty]\npoint_mm = 0.02\n"tension_N" = 0.1\n\n'
                 '[outer.inner]\nk = 1\n[[runs]]\nk = 2\n')
    doc = io.load_toml(f)
    assert doc.data["uncertainty"] == {"point_mm": 0.02, "tension_N": 0.1}
    assert doc.line_of("name") == 2 and doc.line_of("uncertainty") == 4
    assert doc.line_of("uncertainty", "point_mm") == 5 and doc.line_of("uncertainty", "tension_N") == 6
    assert doc.line_of("outer", "inner", "k") == 9 and doc.line_of("runs", "k") == 11
    assert doc.line_of("point_mm") is None and doc.line_of("nothing") is None
    err = doc.error("point_mm is odd", "uncertainty", "point_mm")
    assert isinstance(err, io.TomlError) and str(err) == f"{f}: line 5: point_mm is odd"
    assert str(doc.error("whole file")) == f"{f}: whole file"
    f.write_text('a = 1\nb = [1, 2\nc = 3\n')
    with pytest.raises(io.TomlError, match=r"x\.toml: line 3: bad TOML: .* at column \d+; the file is not valid"):
        io.load_toml(f)
    with pytest.raises(io.TomlFileNotFoundError, match=r"none\.toml: recipe not found") as ei:
        io.load_toml(tmp_path / "none.toml", what="recipe")
    assert isinstance(ei.value, ValueError) and isinstance(ei.value, FileNotFoundError)


def test_every_toml_reader_raises_toml_error(tmp_path):
    from notchfit.studies.synth import load_recipe

    bad = tmp_path / "bad.toml"
    bad.write_text("x = = 1\n")
    readers = [io.load_geometry, io.load_params, io.load_fea_reference, io.load_board, load_recipe,
               io.read_experiment_toml]
    for reader in readers:
        with pytest.raises(io.TomlError, match=r"bad\.toml: line 1: bad TOML"):
            reader(bad)


def test_atomic_writers_use_normal_file_modes(tmp_path):
    mask = os.umask(0o022)
    try:
        paths = [io.write_text_atomic("x", tmp_path / "a.txt"),
                 io.write_json_atomic({"a": 1}, tmp_path / "b.json"),
                 io.write_table_atomic(pd.DataFrame({"a": [1]}), tmp_path / "c.csv"),
                 io.save_params(io.load_params(_params_file(tmp_path)), tmp_path / "m.toml")]
    finally:
        os.umask(mask)
    assert [p.stat().st_mode & 0o777 for p in paths] == [0o644] * 4
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())


def _params_file(tmp_path):
    f = tmp_path / "in.toml"
    f.write_text("mu_d = 0.2\n")
    return f


def test_physics_does_not_import_io_and_moved_names_say_where():
    """Physics imports no file I/O; the model-file names moved to notchfit.io say so clearly."""
    import subprocess
    import sys

    code = ("import sys, notchfit.physics.friction as f, notchfit.physics.geometry, notchfit.physics.statics\n"
            "assert 'notchfit.io' not in sys.modules, 'physics imported notchfit.io'\n"
            "import notchfit\n"
            "assert 'notchfit.io' not in sys.modules, 'import notchfit imported notchfit.io'\n"
            "try:\n"
            "    f.load_params\n"
            "except AttributeError as exc:\n"
            "    assert 'notchfit.io.load_params' in str(exc), exc\n"
            "else:\n"
            "    raise AssertionError('notchfit.physics.friction.load_params still imports')\n"
            "assert 'notchfit.io' not in sys.modules, 'the moved name imported notchfit.io'\n"
            "import notchfit.io as io\n"
            "assert notchfit.load_geometry is io.load_geometry\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_write_image_png_is_lossless_and_jpeg_is_small(tmp_path):
    """Study images round-trip exactly (they are measured again); overlays may be lossy but are small."""
    rng = np.random.default_rng(3)
    noisy = np.clip(160 + rng.normal(0, 3.2, (300, 400)), 0, 255).astype(np.uint8)     # a render's noise
    for png in ("noisy", "graphics"):
        p = io.write_image(tmp_path / f"{png}.png", noisy, png=png)
        assert np.array_equal(io.load_image(p), noisy)
    colour = np.dstack([noisy] * 3)
    j = io.write_image(tmp_path / "o.jpg", colour, jpeg_quality=85)
    back = io.load_image(j)
    assert back.shape == colour.shape and np.abs(back.astype(int) - colour).mean() < 3
    assert j.stat().st_size < (tmp_path / "noisy.png").stat().st_size
    # Huffman coding alone is the smaller PNG for noise-dominated pixels (docs/history.md)
    assert (tmp_path / "noisy.png").stat().st_size <= (tmp_path / "graphics.png").stat().st_size
    with pytest.raises(ValueError, match=r"\.tif"):
        io.write_image(tmp_path / "x.tif", noisy)
    assert not list(tmp_path.glob("*.tmp*"))
