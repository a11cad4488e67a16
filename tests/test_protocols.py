"""Bend/unbend protocols like the paper's experiments (Sec. IV, Fig. 11)."""
import numpy as np
import pytest

from notchfit.physics.protocols import BendProtocol, bend_unbend, paper_protocols


def test_fig11_default_protocol_shape():
    t, tl, tr, ids = bend_unbend()
    assert len(t) == 38 and np.allclose(np.diff(t), 5.0) and t[0] == 0.0
    assert list(ids) == list(range(1, 39))
    assert (tr == 0.45).all()                      # counter-tension on the right cable
    k = int(np.argmax(tl))
    assert k == 18 and tl[k] == 25.0               # 19 samples up incl. start and peak (regime I has 18 steps)
    assert (np.diff(tl[:k + 1]) > 0).all() and (np.diff(tl[k:]) < 0).all()
    assert tl[0] == tl[-1] == 0.45                 # starts and ends straight


def test_right_pull_mirrors_the_cables():
    a = bend_unbend(30.0, 1.5, pull="left")
    b = bend_unbend(30.0, 1.5, pull="right")
    assert np.array_equal(a.tension_left, b.tension_right) and np.array_equal(a.tension_right, b.tension_left)
    assert isinstance(b, BendProtocol) and b.tension_right.max() == 30.0


def test_same_grid_up_and_down():
    t, tl, tr, _ = bend_unbend(20.0, 0.2, n_up=11, n_down=10, interval=4.0, start=1.0, t0=2.0)
    assert np.allclose(tl[:11], tl[10:][::-1]) and t[0] == 2.0 and t[-1] == 2.0 + 4.0 * 20
    assert tl[0] == 1.0 and (tr == 0.2).all()


def test_paper_suite_names_and_pairs():
    suite = paper_protocols()
    assert sorted(suite) == ["L020", "L045", "L150", "R020", "R045", "R150"]
    assert suite["L150"].tension_left.max() == 32.0 and (suite["L150"].tension_right == 1.5).all()
    assert suite["R020"].tension_right.max() == 20.0


@pytest.mark.parametrize("kw,match", [
    (dict(peak=0.3, counter=0.45), "peak"), (dict(counter=-1.0), ">= 0"), (dict(pull="up"), "pull"),
    (dict(interval=0.0), "interval"), (dict(n_up=1), "n_up"), (dict(peak=float("nan")), "finite"),
])
def test_bad_arguments(kw, match):
    with pytest.raises(ValueError, match=match):
        bend_unbend(**kw)
    with pytest.raises(ValueError, match="pair"):
        paper_protocols(counters=(0.2,), peaks=(20.0, 25.0))
