"""`notchfit diagnose --scheduler`: the (model × fold) calibrations on a Dask cluster give the
same diagnosis.json as the serial run, and --seed reaches the noise floor."""
import json
import math

import numpy as np
import pytest

from notchfit.cli import main
from notchfit.analysis.diagnosis import noise_floor, prepare_experiment
from notchfit.physics.friction import FrictionParams
from notchfit.io import read_study
from notchfit.studies.synth import generate_study, load_recipe

# as tests/test_diagnosis_hidden.py: 4 experiments, 9 + 11 samples each, two folds
SMALL = dict(n_experiments=4, n_up=8, n_down=10)
ARGS = ["--no-figures", "--max-folds", "2", "--causes", "proximal_friction", "--one-cause"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    path = tmp_path_factory.mktemp("sched") / "study"
    generate_study(load_recipe("proximal_friction").scaled(**SMALL), path, seed=3)
    return path


def _same(a, b, where="diagnosis.json"):
    """Equal structure and text; numbers equal to 1e-9."""
    if isinstance(a, dict):
        assert list(a) == list(b), where
        for k in a:
            _same(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{i}]")
    elif isinstance(a, float):
        assert math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-15), (where, a, b)
    else:
        assert a == b, (where, a, b)


def test_dask_cluster_gives_the_serial_diagnosis(study, tmp_path):
    distributed = pytest.importorskip("distributed")
    assert main(["diagnose", str(study), "--out", str(tmp_path / "serial"), "--jobs", "1", *ARGS]) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        rc = main(["diagnose", str(study), "--out", str(tmp_path / "dask"),
                   "--scheduler", cluster.scheduler_address, *ARGS])
    assert rc == 0
    serial = json.loads((tmp_path / "serial" / "diagnosis.json").read_text())
    dask = json.loads((tmp_path / "dask" / "diagnosis.json").read_text())
    _same(serial, dask)
    assert serial["cause"] == "proximal_friction" and serial["seed"] == 0


def test_seed_reaches_the_noise_floor(study):
    prep = prepare_experiment(read_study(study)[0])
    assert prep.tension_sigma > 0
    vals = FrictionParams().replace(k_lin=0.4829, k_mid=0.25, mu_d=0.29)
    f0 = noise_floor(prep, vals, seed=0)
    np.testing.assert_array_equal(f0, noise_floor(prep, vals, seed=0))
    assert not np.array_equal(f0, noise_floor(prep, vals, seed=1))
    assert np.all(f0 >= 2 * prep.sigma**2)
