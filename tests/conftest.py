import numpy as np
import pytest

from notchfit.physics.geometry import Geometry, default_geometry


@pytest.fixture
def geom() -> Geometry:
    return default_geometry()


@pytest.fixture
def geom5() -> Geometry:
    """A 5-joint tube with a non-alternating slot layout."""
    return Geometry(n_joints=5, slot_sides=(1, 1, -1, 1, -1), name="five")


@pytest.fixture
def rng():
    return np.random.default_rng(20151103)
