import sys
import threading
from concurrent.futures import ThreadPoolExecutor

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


@pytest.fixture(autouse=True)
def _no_dask_thread_left_behind():
    """After a test that ran a Dask cluster in this process, stop the thread Dask keeps for its lifetime.

    ``notchfit.batch`` forks worker processes only when the process runs no other
    thread (else it spawns them, each importing the package again). Dask's
    ``distributed.utils._offload_executor`` keeps one thread alive once used, so
    without this every ``--jobs 2`` run after the first Dask test would take the
    spawn path a user's command line never takes. The executor is replaced by a
    fresh one, which starts its thread again only when Dask is next used.
    """
    yield
    if "distributed" not in sys.modules or not any(t.name.startswith("Dask-Offload") for t in threading.enumerate()):
        return
    utils = sys.modules.get("distributed.utils")
    old = getattr(utils, "_offload_executor", None)
    if old is None:                 # another Dask version: nothing known to replace
        return
    utils._offload_executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="Dask-Offload")
    old.shutdown(wait=True)
