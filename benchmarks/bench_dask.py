"""Where a Dask cluster's batch loses against a process pool, measured in CPU time per image.

The same detect items (``detect_one`` on a study of hard links to a few renders, 2.3 MP JPEG by
default: ``bench_batch.study``) run in one invocation:

- ``serial``: in this process, one after the other (the reference);
- ``pool``: :func:`notchfit.batch.run_batch` with ``jobs=2`` (a process pool of two forked workers);
- ``dask-defaults``: run_batch on a ``LocalCluster`` (scheduler in this process, two single-threaded
  worker processes) with Dask's default configuration, one image per task;
- ``dask-env``: the same with notchfit's worker environment (``DASK_WORKER_ENVIRON``: one malloc
  arena, large arrays kept in the heap), one image per task;
- ``dask-config``: with ``DASK_CONFIG`` (that environment, no statistical profiler), one image per task;
- ``dask``: ``DASK_CONFIG`` and a few images per task (``items_per_task``), as notchfit runs.

Every worker is warmed up first (the detector imported, its kernels compiled). For each: the wall
time per image, the CPU time (user + system) per image summed over this process and its children
(the workers; for Dask also the scheduler and client, which live in this process), of which the
thread that ran the detection (``time.thread_time`` in the task: the work itself) and the system
time; and ``CPU / reference``: what the same batch would take against the reference on two free
cores (its CPU per image over the serial run's). On a shared machine the wall times follow the
load; the CPU times much less (though a loaded machine's caches make every CPU second dearer).

Run:  python benchmarks/bench_dask.py [--images 64] [--size 2.3] [--modes serial,pool,dask-defaults,...]
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_batch import study  # noqa: E402

MODES = ("serial", "pool", "dask-defaults", "dask-env", "dask-config", "dask")


def timed_detect(item: dict) -> tuple:
    """``detect_one(item)`` and the CPU time of the thread that ran it [s]."""
    from notchfit.commands.detect import detect_one

    t0 = time.thread_time()
    value = detect_one(item)
    return value, time.thread_time() - t0


def _cpu() -> dict:
    """``{pid: (user + system, system)}`` [s] of this process and its live descendants, and under
    key 0 those of its ended children (a pool's workers end with its batch)."""
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = {0: (ended.ru_utime + ended.ru_stime, ended.ru_stime)}
    me = psutil.Process()
    for p in [me, *me.children(recursive=True)]:
        try:
            t = p.cpu_times()
            out[p.pid] = (t.user + t.system, t.system)
        except psutil.Error:
            pass
    return out


def _measure(run, items) -> dict:
    """Wall, CPU (all processes), system and in-task CPU per image [ms] of ``run(items)``."""
    c0, t0 = _cpu(), time.perf_counter()
    task_cpu = run(items)
    wall, c1 = time.perf_counter() - t0, _cpu()
    n = len(items)
    cpu = sum(v[0] - c0.get(k, (0, 0))[0] for k, v in c1.items())
    sys_ = sum(v[1] - c0.get(k, (0, 0))[1] for k, v in c1.items())
    here = c1[os.getpid()][0] - c0[os.getpid()][0]
    return {"wall_ms": 1e3 * wall / n, "cpu_ms": 1e3 * cpu / n, "task_ms": 1e3 * np.mean(task_cpu),
            "this_process_ms": 1e3 * here / n, "system_ms": 1e3 * sys_ / n}


def _serial(items):
    from notchfit.batch import run_batch

    run_batch(timed_detect, items[:2])            # warm up
    return _measure(lambda its: [r.value[1] for r in run_batch(timed_detect, its).items], items)


def _pool(items):
    from notchfit.batch import run_batch

    return _measure(lambda its: [r.value[1] for r in run_batch(timed_detect, its, jobs=2).items], items)


def _dask(items, config: dict, one_per_task: bool):
    import dask
    from distributed import Client, LocalCluster

    import notchfit.batch as batch

    per_task = batch.items_per_task
    if one_per_task:
        batch.items_per_task = lambda n, t, **k: 1
    try:
        with dask.config.set(config), LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                                   host="127.0.0.1", dashboard_address=None) as cluster, \
                Client(cluster) as client:
            batch.run_batch(timed_detect, items[:4], scheduler=client)           # warm up every worker
            return _measure(lambda its: [r.value[1] for r in batch.run_batch(timed_detect, its, scheduler=client).items],
                            items)
    finally:
        batch.items_per_task = per_task


def run_mode(mode: str, items) -> dict:
    from notchfit.batch import DASK_CONFIG, DASK_WORKER_ENVIRON

    if mode == "serial":
        return _serial(items)
    if mode == "pool":
        return _pool(items)
    configs = {"dask-defaults": {}, "dask-env": {"distributed.nanny.pre-spawn-environ": DASK_WORKER_ENVIRON},
               "dask-config": DASK_CONFIG, "dask": DASK_CONFIG}
    return _dask(items, configs[mode], one_per_task=mode != "dask")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=64)
    ap.add_argument("--size", default="2.3", help="image size in MP (2.3 or 16)")
    ap.add_argument("--modes", default=",".join(MODES), help="of " + ", ".join(MODES))
    ap.add_argument("--workdir", type=Path, default=None)
    args = ap.parse_args()
    from notchfit import io

    root = args.workdir or Path(tempfile.mkdtemp(prefix="bench_dask_"))
    e = io.read_experiment(study(root, args.size, args.images, 3))
    items = [{"image": img, "calibration": e.calibration_path, "geometry": e.geometry, "base": e.base,
              "mirror": e.mirror, "sample": int(s), "overlay": f"overlays/{int(s):04d}.jpg", "full_overlay": False,
              "tone_gamma": e.image_gamma} for s, img in zip(e.sample_ids, e.image_paths)]
    print(f"{os.cpu_count()} CPUs; {len(items)} images of {args.size} MP; per image, in ms:")
    ref = None
    for mode in args.modes.split(","):
        r = run_mode(mode, items)
        ref = r["cpu_ms"] if mode == "serial" else ref
        vs = f"; CPU / reference {r['cpu_ms'] / ref:.2f}" if ref else ""
        print(f"  {mode:13s} wall {r['wall_ms']:6.1f}, CPU {r['cpu_ms']:6.1f} (the detection's thread "
              f"{r['task_ms']:5.1f}, this process {r['this_process_ms']:5.1f}, system {r['system_ms']:5.1f}){vs}; "
              f"load {os.getloadavg()[0]:.1f}", flush=True)


if __name__ == "__main__":
    main()
