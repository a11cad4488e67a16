"""The pipeline commands (synth, fit, simulate, report) and the README quick start."""
import re
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _readme_test_command():
    text = (ROOT / "README.md").read_text()
    quick = re.search(r"^## Quick start\n(.*?)(?=^## )", text, re.S | re.M)
    assert quick, "README.md has no '## Quick start' section"
    blocks = re.findall(r"```(?:bash|sh|console)?\n(.*?)```", quick.group(1), re.S)
    cmds = [ln.strip() for b in blocks for ln in b.splitlines() if "pytest" in ln and not ln.startswith("#")]
    assert len(cmds) == 1, f"expected one test command in the quick start, found {cmds}"
    return cmds[0]


def _ci_test_command():
    lines = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()
             if ln.strip() and not ln.strip().startswith("#")]
    cmds = [ln for ln in lines if "pytest" in ln and not ln.startswith(("echo", "if", "rc="))]
    assert len(cmds) == 1, f"expected one pytest command in .ci/run, found {cmds}"
    return cmds[0]


def test_readme_quick_start_is_what_ci_runs():
    readme, ci = _readme_test_command(), _ci_test_command()
    assert shlex.split(readme) == shlex.split(ci), (readme, ci)
    assert shlex.split(ci)[-3:] == ["python", "-m", "pytest"]


# --------------------------------------------------------------------------- fit / simulate on a study
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from notchfit import io  # noqa: E402
from notchfit.cli import main  # noqa: E402
from notchfit.studies.synth import generate_study, load_recipe  # noqa: E402


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    d = tmp_path_factory.mktemp("pipe") / "study"
    generate_study(load_recipe("stiffness_gradient").scaled(n_experiments=2, n_up=5, n_down=6), d, seed=1)
    return d


def test_fit_study_writes_data_format_outputs(study, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fit", str(study), "--out", str(out), "--models", "cc,linear", "--jobs", "2"]) == 0
    for name in ("L045", "L150"):
        fits = io.read_fits(out / name / "fits.csv")
        cols = list(fits.columns)
        assert cols[:4] == ["sample", "model", "a", "b"]
        assert cols.index("base_x_mm") < cols.index("rms_mm") < cols.index("n_points")
        assert set(fits["model"]) == {"cc", "linear"} and len(fits) == 2 * 12
        pw = io.read_pointwise(out / name / "pointwise.csv")
        assert list(pw.columns) == ["sample", "model", "point", "err_mm"] and pw["point"].max() == 58
        for fig in ("fig12_overlay.png", "fig13_pointwise.png", "fig15_shape_parameters.png"):
            assert (out / name / fig).stat().st_size > 1000
    # linear beats constant curvature on friction shapes (Sec. IV-A: 0.35 vs 3.36 mm max)
    f = io.read_fits(out / "L045" / "fits.csv")
    assert f[f.model == "linear"]["max_mm"].max() < f[f.model == "cc"]["max_mm"].max()
    assert io.read_json(out / "fit_run.json")["input"] == str(study.resolve())
    text = capsys.readouterr().out
    assert "fit: 2 of 2 experiments fitted" in text
    # nothing is overwritten without --force (exit 2, a message), and --force replaces
    assert main(["fit", str(study), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert main(["fit", str(study), "--out", str(out), "--force", "--models", "cc", "--no-figures"]) == 0
    assert set(io.read_fits(out / "L045" / "fits.csv")["model"]) == {"cc"}


def test_fit_usage_errors_exit_2(study, tmp_path, capsys):
    assert main(["fit", str(study), "--out", str(tmp_path / "o"), "--models", "cc,bogus"]) == 2
    assert "--models" in capsys.readouterr().err
    assert main(["fit", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o" / "fits.csv").exists()


def test_fit_one_bad_experiment_is_listed_others_finish(study, tmp_path, capsys):
    import shutil

    bad = tmp_path / "study"
    shutil.copytree(study, bad)
    (bad / "L150" / "notch_points.csv").write_text("sample,point,x_mm,y_mm\n")  # nothing measured
    out = tmp_path / "out"
    assert main(["fit", str(bad), "--out", str(out)]) == 1
    text = capsys.readouterr().out
    assert "fit: 1 of 2 experiments fitted" in text and "FAILED L150" in text
    assert (out / "L045" / "fits.csv").is_file() and not (out / "L150" / "fits.csv").exists()
    assert "L150" in io.read_json(out / "fit_run.json")["failures"]


def test_fit_uses_detections_when_there_are_no_points(study, tmp_path):
    """The detect -> fit hand-off: detections.csv (status ok) replaces notch_points.csv."""
    exp = io.read_experiment(study / "L045")
    folder = tmp_path / "img" / "L045"
    (folder / "images").mkdir(parents=True)
    for s in exp.sample_ids:
        (folder / f"images/{s:04d}.png").write_bytes(b"png")
    (tmp_path / "img" / "camera.yml").write_text("%YAML:1.0\n")
    io.write_experiment(folder, name="L045", samples=exp.samples.assign(
        image=[f"images/{s:04d}.png" for s in exp.sample_ids]), calibration="../camera.yml",
        mirror=exp.mirror)
    det = io.points_table(exp.points, exp.sample_ids)
    det["u_px"], det["v_px"], det["sigma_mm"], det["status"] = 0.0, 0.0, 0.02, "ok"
    io.write_table_atomic(det, tmp_path / "res" / "detections.csv")
    assert main(["fit", str(folder), "--out", str(tmp_path / "res"), "--no-figures"]) == 0
    a = io.read_fits(tmp_path / "res" / "fits.csv")
    assert main(["fit", str(study / "L045"), "--out", str(tmp_path / "ref"), "--no-figures"]) == 0
    b = io.read_fits(tmp_path / "ref" / "fits.csv")
    np.testing.assert_allclose(a["rms_mm"], b["rms_mm"], rtol=1e-6)


def test_fit_on_a_dask_cluster(study, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        assert main(["fit", str(study), "--out", str(tmp_path / "o"), "--no-figures",
                     "--scheduler", cluster.scheduler_address]) == 0
    assert (tmp_path / "o" / "L150" / "fits.csv").is_file()


def test_simulate_compares_with_the_points(study, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(study), "--out", str(out), "--param", "k_lin=0.45"]) == 0
    c = pd.read_csv(out / "L045" / "simulation_vs_measured.csv")
    assert {"a_meas", "b_meas", "a_sim", "b_sim", "point_rms_mm"} <= set(c.columns)
    # a left pull bends toward negative θ in both the measurement and the prediction
    assert c["a_meas"].min() < -0.05 and c["a_sim"].min() < -0.05
    for fig in ("fig18_joint_angles.png", "fig19_shape_parameters.png"):
        assert (out / "L150" / fig).stat().st_size > 1000
    assert io.read_json(out / "simulate_run.json")["params"]["k_lin"] == 0.45
    assert "prediction rms" in capsys.readouterr().out
    assert main(["simulate", str(study), "--out", str(out), "--param", "k_lin"]) == 2


def test_synth_scaled_and_listed(tmp_path, capsys):
    assert main(["synth", "--list"]) == 0
    listed = capsys.readouterr().out
    assert "paper8" in listed and "calibration_error" in listed
    assert main(["synth", "paper8", "--out", str(tmp_path / "s"), "--experiments", "2",
                 "--samples", "3", "4", "--seed", "9"]) == 0
    exps = io.read_study(tmp_path / "s")
    assert [e.name for e in exps] == ["L045", "L100"] and exps[0].n_samples == 8 and exps[0].mirror
    assert main(["synth", "calibration_error", "--images", "--out", str(tmp_path / "c")]) == 2
    assert main(["synth", "nope", "--out", str(tmp_path / "n")]) == 2


# ----------------------------------------------------------------------------- the CLI's structure
def test_commands_do_not_import_the_cli_and_help_stays_light():
    """No cycle: commands never import notchfit.cli; `notchfit --help` loads no command, cv2, matplotlib or dask."""
    import ast
    import subprocess
    import sys

    for path in (ROOT / "notchfit" / "commands").glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [f"{node.module or ''}.{a.name}" for a in node.names]
                assert not any(n.split(".")[-1] == "cli" or n == "notchfit.cli" for n in names), path.name
            elif isinstance(node, ast.Import):
                assert not any(a.name == "notchfit.cli" for a in node.names), path.name
    heavy = "('cv2', 'matplotlib', 'dask', 'distributed')"
    # every command's parser may load OpenCV (notchfit.io reads camera files and images
    # with it), none loads the plotting or cluster libraries
    plotting = "('matplotlib', 'dask', 'distributed')"
    code = ("import contextlib, io, sys; from notchfit.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit): main(['--help'])\n"
            "print(sorted(m for m in ('notchfit.commands.fit', 'scipy') + " + heavy + " if m in sys.modules))\n"
            "from notchfit.cli import build_parser; build_parser().format_help()\n"
            "print(sorted(m for m in " + plotting + " if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.split()
    # the listing imports no command; every command's parser still loads no slow optional library
    assert out == ["[]", "[]"]


def test_points_option_and_call_helper(study, tmp_path, capsys):
    """`--points` is the option for a detect run's folder in fit and simulate; `call` runs a
    command module as the CLI does (exit codes included) without importing notchfit.cli."""
    from notchfit.commands import fit, simulate
    from notchfit.commands._common import EXIT_INPUT_ERROR, add_command, call

    for mod in (fit, simulate):
        args = add_command(None, mod).parse_args([str(study), "--out", "o", "--points", "det"])
        assert args.points == Path("det")
    assert call(fit, [study, "--out", tmp_path / "o", "--models", "cc", "--no-figures"]) == 0
    assert call(fit, [study, "--out", tmp_path / "o", "--models", "cc"]) == EXIT_INPUT_ERROR
    assert "notchfit fit: error:" in capsys.readouterr().err
