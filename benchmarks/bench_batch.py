"""Batch detection at lab scale: peak memory and images per second against the number of images.

A study of N images (hard links to a few renders of the lab's wrist in a chuck, JPEG as a camera
writes them, 2.3 MP = 1920x1200 or 16 MP = 4928x3264 at the same field of view) goes through
``notchfit detect`` as a user runs it (a subprocess), with ``--jobs 1``, ``--jobs 2`` and on a local
Dask cluster (``distributed.LocalCluster``: a scheduler and two single-threaded worker processes on
127.0.0.1, started fresh for each run in a helper process, with notchfit's recommended
configuration ``notchfit.batch.DASK_CONFIG``; mode ``dask-defaults``: Dask's own). For each run:

- peak RSS: the sum of the resident set sizes of every process of the run (the command, its
  worker processes, and for Dask the cluster's processes), sampled every 50 ms with psutil; pages
  shared between forked processes are counted once per process (an upper bound); the peaks of
  the command's processes and of the cluster's are also given apart;
- images per second: the command's own final line (the batch's images over its wall time,
  without the start-up of Python and the study scan), and the whole command's wall time;
- CPU per image: the CPU time (user + system) of every process of the run over the images,
  against the reference's CPU per image: what the run costs besides the detections, whatever
  else the shared machine runs (on idle cores, the batch / reference time ratio it predicts);
- the reference in the same run: one image's detection time in this process (``detect_one``, the
  mean over the renders of the best of 2) times the count divided by the workers.

Targets (issue 30): peak RSS within 10 % from 200 to 2,000 images; batch time within 10 % of the
reference. The machine's load average is printed with every row: on a shared machine the
figures move with it.

Run:  python benchmarks/bench_batch.py [--sizes 2.3,16] [--counts 200,2000] [--modes jobs1,jobs2,dask,dask-defaults]
                                       [--renders 3] [--workdir DIR]
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import psutil

ROOT = Path(__file__).resolve().parent.parent
#: image sizes (W, H) and scales [px/mm]: the lab's 16 MP camera at 130 px/mm and a 2.3 MP one
#: with the same field of view
SIZES = {"2.3": ((1920, 1200), 130.0 * 1920 / 4928), "16": ((4928, 3264), 130.0)}
WORKERS = {"jobs1": 1, "jobs2": 2, "dask": 2, "dask-defaults": 2}
#: a local cluster: notchfit's recommended configuration (notchfit.batch.DASK_CONFIG), or Dask's defaults
_CLUSTER = """
import sys
import dask
from distributed import LocalCluster
from notchfit.batch import DASK_CONFIG
with dask.config.set(DASK_CONFIG if sys.argv[1] == "dask" else {}), \\
        LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                     dashboard_address=None) as cluster:
    print(cluster.scheduler_address, flush=True)
    sys.stdin.read()
"""


def renders(folder: Path, size: str, n: int) -> list[Path]:
    """``n`` JPEG renders (wrist in a chuck, camera tone curve, blur) and camera.yml in ``folder``."""
    from notchfit import io
    from notchfit.vision.render.scenes import Scene, render_scene, scene_camera

    geom = io.load_geometry(io.datasets_dir() / "geometry" / "wrist_asymmetric.toml")
    (wh, px_per_mm) = SIZES[size]
    paths = [folder / f"render{k}.jpg" for k in range(n)]
    if all(p.is_file() for p in paths):
        return paths
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(30)
    for k, p in enumerate(paths):
        th = np.array([0.2, 0.25, 0.3, 0.3, 0.25]) * (0.6 + 0.4 * k / max(n - 1, 1))
        cam, plane = scene_camera(th, geom, image_size=wh, mm_per_px=1 / px_per_mm, angle_deg=90, base_at=0.05)
        r = render_scene(th, geom, cam, plane=plane, rng=rng,
                         scene=Scene(holder="chuck", holder_half_width=4e-3, gamma=2.2, blur_sigma=2.0))
        io.write_image(p, r.image, jpeg_quality=95)
        io.write_camera(cam, folder / "camera.yml")
    return paths


def study(root: Path, size: str, count: int, n_renders: int) -> Path:
    """An experiment of ``count`` samples whose images are hard links to the renders."""
    from notchfit import io

    src = renders(root / f"renders_{size}", size, n_renders)
    exp = root / f"study_{size}_{count}" / "exp"
    if (exp / "samples.csv").is_file():
        return exp
    (exp / "images").mkdir(parents=True)
    for s in range(1, count + 1):
        os.link(src[(s - 1) % len(src)], exp / "images" / f"{s:04d}.jpg")
    pd.DataFrame({"sample": range(1, count + 1), "time_s": np.arange(1.0, count + 1), "tension_right_N": 0.5,
                  "image": [f"images/{s:04d}.jpg" for s in range(1, count + 1)]}).to_csv(exp / "samples.csv",
                                                                                         index=False)
    shutil.copyfile(src[0].parent / "camera.yml", exp / "camera.yml")
    geom = io.datasets_dir() / "geometry" / "wrist_asymmetric.toml"
    (exp / "experiment.toml").write_text(f'name = "exp"\ngeometry = "{geom}"\ncalibration = "camera.yml"\n'
                                         'base = "top"\nimage_gamma = 2.2\n')
    return exp


def single_image_s(exp: Path, n_renders: int) -> tuple[float, float]:
    """One image's detection in this process: wall and CPU time [s], each the mean over the renders of
    the best of 2."""
    from notchfit import io
    from notchfit.commands.detect import detect_one

    e = io.read_experiment(exp)
    best, cpu = [], []
    for img in e.image_paths[:n_renders]:
        item = {"image": img, "calibration": e.calibration_path, "geometry": e.geometry, "base": e.base,
                "mirror": e.mirror, "sample": 1, "overlay": "overlays/0001.jpg", "full_overlay": False,
                "tone_gamma": e.image_gamma}
        ts, cs = [], []
        for _ in range(2):
            t0, c0 = time.perf_counter(), time.process_time()
            detect_one(item)
            ts.append(time.perf_counter() - t0)
            cs.append(time.process_time() - c0)
        best.append(min(ts))
        cpu.append(min(cs))
    return float(np.mean(best)), float(np.mean(cpu))


class PeakRSS:
    """The peak over time of the summed RSS of ``roots`` and all their descendants [bytes]
    (``peak``), each root's own peak with its descendants (``peaks``), and the CPU time their
    processes used since the start [s] (``cpu_s``; each process as last seen: a process that ends
    loses at most ``every_s`` of it)."""

    def __init__(self, roots, every_s: float = 0.05):
        self.roots, self.every_s, self.peak = roots, every_s, 0
        self.peaks = [0] * len(roots)
        self._cpu0: dict = {}
        self._cpu: dict = {}
        self._started = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self._stop.is_set():
            total = 0
            for k, root in enumerate(self.roots):
                try:
                    procs = [root, *root.children(recursive=True)]
                except psutil.Error:
                    continue
                tree = 0
                for p in procs:
                    try:
                        tree += p.memory_info().rss
                        t = p.cpu_times()
                        self._cpu[p.pid] = t.user + t.system
                        self._cpu0.setdefault(p.pid, 0.0 if self._started else self._cpu[p.pid])
                    except psutil.Error:
                        pass
                self.peaks[k] = max(self.peaks[k], tree)
                total += tree
            self.peak = max(self.peak, total)
            self._started = True           # processes seen after the first pass count from their start
            self._stop.wait(self.every_s)

    @property
    def cpu_s(self) -> float:
        return sum(v - self._cpu0.get(k, 0.0) for k, v in self._cpu.items())

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def run_detect(exp: Path, out: Path, mode: str) -> dict:
    """One ``notchfit detect`` run: wall time, the batch's images/s, the peak RSS of its processes."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cluster = None
    argv = [sys.executable, "-m", "notchfit.cli", "detect", str(exp), "--out", str(out)]
    if mode.startswith("dask"):
        cluster = subprocess.Popen([sys.executable, "-c", _CLUSTER, mode], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                   stderr=subprocess.DEVNULL, text=True, env=env)
        argv += ["--scheduler", cluster.stdout.readline().strip()]
    else:
        argv += ["--jobs", str(WORKERS[mode])]
    try:
        t0 = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
        roots = [psutil.Process(proc.pid)] + ([psutil.Process(cluster.pid)] if cluster else [])
        with PeakRSS(roots) as rss:
            stdout, _ = proc.communicate()
        wall = time.perf_counter() - t0
    finally:
        if cluster is not None:
            cluster.stdin.close()
            cluster.wait(timeout=60)
    m = re.search(r"in ([\d.]+) s, ([\d.]+) images/s", stdout)
    if proc.returncode != 0 or m is None:
        raise RuntimeError(f"detect exited {proc.returncode}: {stdout[-2000:]}")
    return {"wall_s": wall, "batch_s": float(m.group(1)), "images_per_s": float(m.group(2)),
            "cpu_s": rss.cpu_s, "peak_rss_mb": rss.peak / 2 ** 20, "command_mb": rss.peaks[0] / 2 ** 20,
            "cluster_mb": rss.peaks[1] / 2 ** 20 if cluster else 0.0}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2.3,16", help="image sizes in MP, of " + ", ".join(SIZES))
    ap.add_argument("--counts", default="200,2000", help="study sizes (images)")
    ap.add_argument("--modes", default="jobs1,jobs2,dask", help="of " + ", ".join(WORKERS))
    ap.add_argument("--renders", type=int, default=3, help="distinct renders the study's images link to")
    ap.add_argument("--workdir", type=Path, default=None, help="where the studies go (default: a temporary folder)")
    args = ap.parse_args()
    sizes, modes = args.sizes.split(","), args.modes.split(",")
    counts = [int(c) for c in args.counts.split(",")]
    root = args.workdir or Path(tempfile.mkdtemp(prefix="bench_batch_"))
    print(f"{os.cpu_count()} CPUs; load average at the start {os.getloadavg()[0]:.1f}; studies in {root}")
    rows, cpu_ref = [], {}
    for size in sizes:
        t1, c1 = single_image_s(study(root, size, counts[0], args.renders), args.renders)
        print(f"{size} MP: one image {t1:.3f} s ({c1:.3f} s CPU) in this process (detect_one)")
        cpu_ref[size] = c1
        for count in counts:
            exp = study(root, size, count, args.renders)
            for mode in modes:
                out = root / f"out_{size}_{count}_{mode}"
                shutil.rmtree(out, ignore_errors=True)
                r = run_detect(exp, out, mode)
                ref = t1 * count / WORKERS[mode]
                cpu = r["cpu_s"] / count
                rows.append({"MP": size, "images": count, "mode": mode, **r, "reference_s": ref,
                             "batch/reference": r["batch_s"] / ref, "cpu_per_image_s": cpu,
                             "cpu/reference": cpu / c1, "load": os.getloadavg()[0]})
                print(f"  {count:5d} images {mode:5s}: {r['images_per_s']:6.2f} images/s (batch {r['batch_s']:.1f} s, "
                      f"reference {ref:.1f} s, ratio {r['batch_s'] / ref:.2f}; command {r['wall_s']:.1f} s), "
                      f"CPU {cpu:.3f} s/image (/ reference {cpu / c1:.2f}), "
                      f"peak RSS {r['peak_rss_mb']:.0f} MB (command {r['command_mb']:.0f}, cluster {r['cluster_mb']:.0f}), load {os.getloadavg()[0]:.1f}", flush=True)
                shutil.rmtree(out, ignore_errors=True)
    df = pd.DataFrame(rows)
    print("\n" + df.to_string(index=False, float_format=lambda v: f"{v:.3g}"))
    if len(counts) > 1:
        print(f"\npeak RSS at {counts[-1]} images / at {counts[0]} (target: within 10 %):")
        for (size, mode), g in df.groupby(["MP", "mode"], sort=False):
            a, b = g[g.images == counts[0]].peak_rss_mb, g[g.images == counts[-1]].peak_rss_mb
            if len(a) and len(b):
                print(f"  {size} MP {mode}: {float(b.iloc[0]) / float(a.iloc[0]):.3f}")
        print(f"\nCPU per image from {counts[0]} to {counts[-1]} images (the run's fixed costs drop out), "
              "against the reference's:")
        for (size, mode), g in df.groupby(["MP", "mode"], sort=False):
            a, b = g[g.images == counts[0]].cpu_s, g[g.images == counts[-1]].cpu_s
            if len(a) and len(b):
                marginal = (float(b.iloc[0]) - float(a.iloc[0])) / (counts[-1] - counts[0])
                print(f"  {size} MP {mode}: {marginal:.3f} s, / reference {marginal / cpu_ref[size]:.2f}")


if __name__ == "__main__":
    main()
