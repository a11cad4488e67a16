"""The attainable floor of a synthetic study (the generating model's own error) and the warp centre's aim
point, for the camera-plane correction of a tilted bending plane (notchfit.vision.warp)."""
import dataclasses
import math

import numpy as np

from notchfit.analysis.diagnosis.calibration import _aim_point, attainable_mse
from notchfit.analysis.estimation.observations import observe_study
from notchfit.analysis.estimation.problem import measure_registered
from notchfit.analysis.fitting.results import PlaneTransform
from notchfit.io import read_study
from notchfit.studies.synth import load_recipe, synthesize, write_study


def _study(tmp_path, **noise):
    """A reduced tilted-plane study (fast truth solver, as the diagnosis's simulator) and its truth."""
    r = load_recipe("calibration_tilt").replace(**noise).scaled(n_experiments=4, n_up=5, n_down=5)
    st = synthesize(r, seed=3, method="fast")
    write_study(st, tmp_path / "study")
    return st, observe_study(read_study(tmp_path / "study"), "points")


def _floor(st, preps) -> float:
    mse = [attainable_mse(p, st.params, transform=PlaneTransform(e.plane["tx"], e.plane["ty"], e.plane["phi"],
                                                                 e.plane["mirror"]), warp=st.warp)
           for p, e in zip(preps, st.experiments)]
    return math.sqrt(float(np.nanmean(np.concatenate(mse))))


def test_without_load_cell_noise_the_generating_model_leaves_the_point_noise(tmp_path):
    """Exact tensions: the true model through the true tilted-plane homography reproduces the noiseless points,
    so its rms is the point noise's, sqrt(2) sigma per point (two coordinates; sample_mse, Sec. IV-A) within
    the sampling error of a few hundred points."""
    sigma = 0.02e-3
    st, preps = _study(tmp_path, tension_sigma_N=0.0, point_sigma_mm=sigma * 1e3)
    floor = _floor(st, preps)
    assert abs(floor / (math.sqrt(2.0) * sigma) - 1.0) < 0.1
    # without the tilt the same model misses by the perspective term (|ω| r²/D: about 0.1 mm here)
    flat = dict(st.warp, tilt=(0.0, 0.0))
    mse = [attainable_mse(p, st.params, transform=PlaneTransform(e.plane["tx"], e.plane["ty"], e.plane["phi"]),
                          warp=flat) for p, e in zip(preps, st.experiments)]
    assert math.sqrt(float(np.nanmean(np.concatenate(mse)))) > 3.0 * floor


def test_the_load_cell_noise_raises_the_floor_above_the_point_noise(tmp_path):
    """With the recipe's 0.11 N load cells the measured tensions drive the simulator off the truth: the floor
    is several times the point noise (the noise floor's second term dominates, estimation.noise)."""
    st, preps = _study(tmp_path)
    assert _floor(st, preps) > 2.0 * math.sqrt(2.0) * 0.02e-3


def test_the_aim_point_does_not_lean_with_the_bending(tmp_path):
    """The warp centre's aim point is the straight tube's notch points (Eqs. 1-3 at θ = 0) under each
    registration: the same whatever the tube did, where the measured points' centroid leans toward the side
    the tube was pulled to (left pulls alone: millimetres off)."""
    st, preps = _study(tmp_path, tension_sigma_N=0.0)
    left = [p for p, e in zip(preps, st.experiments) if e.pull == "left"]
    aim = _aim_point(left)
    straight = np.stack([measure_registered(p, np.zeros((1, p.geom.n_joints)))[0] for p in left])
    np.testing.assert_allclose(aim, straight.mean(axis=(0, 1)), atol=1e-15)
    # the same registrations with the tube held straight: same aim point, while the centroid moves
    held = [dataclasses.replace(p, measured=s) for p, s in
            zip(left, [np.broadcast_to(q, p.measured.shape).copy() for p, q in zip(left, straight)])]
    np.testing.assert_allclose(_aim_point(held), aim, atol=1e-15)

    def centroid(ps):
        return np.nanmean(np.concatenate([p.measured[p.valid] for p in ps]), axis=0)

    assert np.linalg.norm(centroid(left) - centroid(held)) > 2e-3
