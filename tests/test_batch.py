"""notchfit.batch: parallel items with failure isolation, progress and a summary."""
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from notchfit.batch import run_batch
from notchfit.io import image_info, load_image


@pytest.fixture
def images(tmp_path, rng):
    paths = []
    for i in range(5):
        img = (rng.random((40, 60)) * 255).astype(np.uint8)
        p = tmp_path / f"img{i}.png"
        assert cv2.imwrite(str(p), img)
        paths.append(p)
    paths[1].write_bytes(rng.integers(0, 256, 500, dtype=np.uint8).tobytes())  # corrupt
    paths[3] = tmp_path / "gone.png"                                           # missing
    return paths


def _check_image_batch(res, paths):
    assert [r.key for r in res.items] == [p.name for p in paths]
    assert res.n_ok == 3 and [r.ok for r in res.items] == [True, False, True, False, True]
    assert res.items[0].value["width"] == 60 and res.items[4].value["height"] == 40
    # the readers' one error type (notchfit.io.InputFileError; a missing file is InputFileNotFoundError)
    assert res.items[1].error.startswith("InputFileError: corrupt or unreadable image")
    assert res.items[3].error.startswith("InputFileNotFoundError: image missing")
    s = res.summary("detect")
    assert s.startswith("detect: 3 of 5 ok")
    assert "img1.png: InputFileError: corrupt" in s and "gone.png: InputFileNotFoundError: image missing" in s


@pytest.mark.parametrize("jobs", [1, 2])
def test_corrupt_and_missing_image_reported_rest_finish(images, jobs):
    res = run_batch(image_info, images, keys=[p.name for p in images], jobs=jobs, desc="images")
    _check_image_batch(res, images)
    with pytest.raises(RuntimeError, match="2 failed"):
        res.raise_on_failure()


def test_load_image_reasons(images):
    assert load_image(images[0]).shape == (40, 60)
    with pytest.raises(ValueError, match="corrupt"):
        load_image(images[1])
    with pytest.raises(FileNotFoundError, match="image missing"):
        load_image(images[3])


def _square_or_die(x):
    if x == 3:
        os._exit(7)  # a native crash in a worker
    return x * x


def test_dead_worker_blames_only_its_item():
    res = run_batch(_square_or_die, range(6), jobs=2)
    assert [r.ok for r in res.items] == [True, True, True, False, True, True]
    assert res.values()[:3] == [0, 1, 4] and res.values()[5] == 25
    assert "worker process died" in res.items[3].error


def test_dask_local_cluster(images):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        res = run_batch(image_info, images, keys=[p.name for p in images],
                        scheduler=cluster.scheduler_address)
    _check_image_batch(res, images)


def test_workers_start_after_the_parent_used_native_thread_pools():
    """Regression: worker initialisation after this process ran OpenCV's and BLAS's thread
    pools (as `notchfit demo` does before diagnose) must not hang in a forked child. Run in a
    subprocess with a time limit so that a hang fails instead of blocking the suite."""
    import subprocess
    import sys

    script = (
        "import cv2, numpy as np\n"
        "from notchfit.batch import run_batch\n"
        "img = np.random.default_rng(0).random((1200, 1920)).astype(np.float32)\n"
        "cv2.GaussianBlur(img, (0, 0), 3.0); np.linalg.svd(np.ones((400, 400)))\n"
        "res = run_batch(np.sum, [np.ones(3)] * 4, jobs=2)\n"
        "assert all(r.ok for r in res.items), res.summary('t')\n"
        "from concurrent.futures import ProcessPoolExecutor\n"
        "from notchfit.batch import single_threaded_worker\n"
        "with ProcessPoolExecutor(2, initializer=single_threaded_worker) as ex:  # as notchfit.analysis.diagnosis\n"
        "    assert list(ex.map(abs, [-1, -2])) == [1, 2]\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_progress_is_one_line_per_batch_when_piped(capsys):
    """Not a terminal (pytest captures stderr): one line naming the stage and its size, no bar."""
    res = run_batch(abs, [-1, -2, -3], desc="square")
    assert res.values() == [1, 2, 3]
    err = capsys.readouterr().err
    assert err == "square: 3 items ...\n"
    run_batch(abs, [-1], desc="quiet", progress=False)
    run_batch(abs, [-1])                                   # no stage name: nothing to say
    assert capsys.readouterr().err == ""


def test_progress_steps_when_piped(capsys):
    from notchfit.progress import Steps

    with Steps("diagnose") as step:
        step("calibrating the baseline")
        step("fitting 6 candidate extensions")
    assert capsys.readouterr().err.splitlines() == ["diagnose: calibrating the baseline ...",
                                                     "diagnose: fitting 6 candidate extensions ..."]


def test_progress_starts_no_thread():
    """A thread in the parent would make the worker processes start by spawn, not fork (batch._mp_context)."""
    import threading

    from notchfit.progress import Steps, bar

    before = threading.active_count()
    with bar(2, "x", enabled=True) as b:
        b.update(2)
    with Steps("y", enabled=True) as step:
        step("one")
    assert threading.active_count() == before


def test_dead_scheduler_is_reported_within_the_connect_timeout():
    """A scheduler address where nothing answers fails in seconds (Dask's own default waits 30 s).

    Run in a subprocess: the Dask client that never connected leaves its event-loop thread running,
    and a thread in this process would make every later ``jobs=2`` test spawn its workers instead of
    forking them (notchfit.batch._mp_context)."""
    import subprocess
    import sys

    pytest.importorskip("distributed")
    code = ("import re, time\n"
            "from notchfit.batch import run_batch\n"
            "t0 = time.perf_counter()\n"
            "try:\n"
            "    run_batch(abs, [-1, -2], scheduler='tcp://127.0.0.1:9', connect_timeout=2.0)\n"
            "except ValueError as exc:\n"
            "    assert re.search(r'tcp://127\\.0\\.0\\.1:9 \\(no answer within 2 s\\)', str(exc)), exc\n"
            "else:\n"
            "    raise AssertionError('no error')\n"
            "print(time.perf_counter() - t0)\n")
    root = Path(__file__).resolve().parent.parent
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=root,
                         env=dict(os.environ, PYTHONPATH=str(root)))
    assert res.returncode == 0, res.stderr[-2000:]
    assert float(res.stdout.split()[-1]) < 25.0          # the bound is the timeout, not a speed claim


@pytest.mark.parametrize("jobs", [1, 2])
def test_on_result_streams_each_item_and_keeps_no_value(jobs):
    """on_result sees every item once, as it finishes, with its value; the BatchResult keeps the
    outcomes only (memory flat in the number of items). An exception in the callback stops the run."""
    seen = {}
    res = run_batch(_square_or_die, [0, 1, 2, 4, 5], jobs=jobs, on_result=lambda i, r: seen.setdefault(i, r))
    assert sorted(seen) == [0, 1, 2, 3, 4] and [seen[i].value for i in range(5)] == [0, 1, 4, 16, 25]
    assert res.n_ok == 5 and res.values() == [None] * 5

    def full(i, r):
        raise OSError(28, "No space left on device")
    with pytest.raises(OSError, match="No space"):
        run_batch(abs, [-1, -2, -3], jobs=jobs, on_result=full)


def test_dask_streams_with_a_bounded_window(images):
    """On a cluster at most two items per worker thread are in flight, and results reach on_result."""
    distributed = pytest.importorskip("distributed")
    seen, on_scheduler = [], []
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        def record(i, r):
            seen.append((i, r.ok))
            on_scheduler.append(len(cluster.scheduler.tasks))
        res = run_batch(image_info, images * 3, scheduler=cluster.scheduler_address, on_result=record)
    assert sorted(seen)[:5] == [(0, True), (1, False), (2, True), (3, False), (4, True)]
    assert len(seen) == 15 and max(on_scheduler) <= 2
    assert res.n_ok == 9 and res.values() == [None] * 15


def test_piped_progress_gives_the_rate_and_the_time_left(capsys, monkeypatch):
    """Piped, a counted stage says every `every_s` seconds how far it is, its rate and the time left."""
    import notchfit.progress as progress

    clock = iter([0.0, 10.0, 20.0, 30.0])
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    with progress.bar(4, "detect", unit="images", every_s=5.0) as b:
        b.update(1)
        b.update(1)
        b.update(2)                                          # the end: no line
    assert capsys.readouterr().err.splitlines() == [
        "detect: 4 images ...", "detect: 1 of 4 images, 0.1 images/s, about 30 s left ...",
        "detect: 2 of 4 images, 0.1 images/s, about 20 s left ..."]
    assert progress.duration(3725) == "1 h 02 min" and progress.duration(185) == "3 min 05 s"


def test_items_per_task_spreads_the_cost_of_a_dask_task():
    """A few items per Dask task, every worker thread still gets at least four tasks, never more than `most`."""
    from notchfit.batch import items_per_task

    assert items_per_task(5, 2) == 1 and items_per_task(15, 1) == 3
    assert items_per_task(200, 2) == 8 and items_per_task(2000, 2, most=4) == 4
    for n, t in [(1, 1), (7, 2), (33, 4), (100, 3)]:
        k = items_per_task(n, t)
        assert k >= 1 and (k == 1 or n // k >= 4 * t)
