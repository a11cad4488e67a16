"""`notchfit diagnose` options: --points (with --detections as its old name), --jobs, --scheduler, --seed."""
from pathlib import Path

from notchfit.cli import build_parser


def _args(*extra):
    return build_parser().parse_args(["diagnose", "study", "--out", "res", *extra])


def test_points_option_and_its_alias():
    assert _args("--points", "det").points == Path("det")
    assert _args("--detections", "det").points == Path("det")
    assert _args().points is None          # then detections are looked for in --out


def test_parallel_and_seed_options():
    a = _args("--jobs", "2", "--scheduler", "tcp://127.0.0.1:8786", "--seed", "4")
    assert (a.jobs, a.scheduler, a.seed) == (2, "tcp://127.0.0.1:8786", 4)
    a = _args()
    assert (a.jobs, a.scheduler, a.seed) == (1, None, 0)


# ----------------------------------------------------------------------------- options through the CLI
#: what these option tests need (no verdict is checked): three experiments with short ramps
TINY = dict(n_experiments=3, n_up=4, n_down=5)


def _small_study(tmp_path, recipe="null", seed=1):
    from notchfit.studies.synth import generate_study, load_recipe

    study = tmp_path / "study"
    generate_study(load_recipe(recipe).scaled(**TINY), study, seed=seed)
    return study


def test_metric_angles_without_angles_is_one_line_error(tmp_path, capsys):
    """--metric angles on a study measured as notch points only: exit 2, one line naming the
    experiments and the missing file, nothing written."""
    from notchfit.cli import main

    study = _small_study(tmp_path)
    out = tmp_path / "out"
    assert main(["diagnose", str(study), "--out", str(out), "--metric", "angles", "--no-figures"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error" in ln]
    assert len(err) == 1 and "angles.csv" in err[0] and "L045" in err[0]
    assert not (out / "diagnosis.json").exists()


def test_assume_step_and_one_cause(tmp_path):
    """--assume-step takes a step where experiment.toml gives no [protocol] (said as "assumed",
    no estimate); --one-cause writes at most one cause; --noise-floor-only judges the baseline against
    the noise alone (no fold prediction band in the floor)."""
    import json

    from notchfit.cli import main

    study = _small_study(tmp_path)
    out = tmp_path / "out"
    assert main(["diagnose", str(study), "--out", str(out), "--assume-step", "--one-cause", "--no-figures",
                 "--max-folds", "2", "--causes", "proximal_friction,external_load", "--noise-floor-only"]) == 0
    d = json.loads((out / "diagnosis.json").read_text())
    assert d["fold_band_rms_mm"] == 0.0 and d["floor_rms_mm"] == d["noise_rms_mm"]
    assert set(d["protocol"]["source"].values()) == {"assumed"}
    assert set(d["protocol"]["ramp_time_s"].values()) == {0.0}
    assert "a step was assumed" in d["protocol"]["text"]
    assert len(d["causes"]) <= 1
