"""Run many independent items (samples, experiments, images) with failure isolation.

:func:`run_batch` calls ``func(item)`` for every item, in this process
(``jobs=1``), in a pool of worker processes (``jobs>1``), or on a Dask
distributed cluster (``scheduler="tcp://host:8786"``, needs the ``dask``
extra). One item failing (an exception, a corrupt image, even a worker
process that dies) never stops the others: its reason is recorded in the
:class:`BatchResult`, whose :meth:`~BatchResult.summary` lists every failure.
Progress (:mod:`notchfit.progress`): a tqdm bar on a terminal, one line
``"desc: N items ..."`` on stderr when it is not a terminal. A Dask scheduler
that does not answer is reported after ``connect_timeout`` seconds.

``func`` must be picklable (a module-level function) for ``jobs>1`` and for
Dask.

Interrupts: worker processes ignore SIGINT (Ctrl-C reaches the whole
process group; the parent decides) and die on SIGTERM. When the parent is
interrupted (``KeyboardInterrupt``, :class:`notchfit.io.interrupts.Interrupted`)
or fails, the pool's queued items are cancelled and its workers terminated
before the exception goes on, and a Dask run cancels its futures and closes
its client: no orphan process is left (docs/reliability.md). Image batches load their images with :func:`notchfit.io.load_image`, which turns a
missing or unreadable file into an exception with the reason.

Streaming: with ``on_result`` the parent hands each item's result to that
callback as soon as it arrives (in completion order) and keeps only its
outcome, not its value, so memory stays flat in the number of items
(``detect`` writes each image's detections to disk there, to resume an
interrupted run). At most two items per worker are in flight at a time in the
pool; on a Dask cluster two tasks per worker thread, each of a few items
(:func:`items_per_task`); Dask results are released as soon as they are read.

Example (the image helper's ``detect`` calls it the same way)::

    res = run_batch(detect_one, image_paths, keys=[p.name for p in image_paths], jobs=4)
    print(res.summary("detect"))
    good = [r.value for r in res.items if r.ok]
"""

from __future__ import annotations

import concurrent.futures as cf
import ctypes
import dataclasses
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from threadpoolctl import threadpool_limits

from .progress import bar as progress_bar

__all__ = ["BatchResult", "DASK_CONFIG", "DASK_WORKER_ENVIRON", "ItemResult", "items_per_task", "run_batch", "single_threaded_worker", "worker_init"]


#: Environment of the Dask worker processes that run notchfit's items (the nanny sets it before
#: a worker starts): glibc's malloc with one arena and large arrays (up to 32 MiB) kept in the
#: heap instead of fresh ``mmap`` pages each time (Dask's own default sets
#: ``MALLOC_TRIM_THRESHOLD_=65536``, which with the task running in a thread of its own arena
#: returns every freed image to the system and faults it in again, measured by
#: ``benchmarks/bench_dask.py``), one thread per native library.
DASK_WORKER_ENVIRON = {"MALLOC_ARENA_MAX": 1, "MALLOC_MMAP_THRESHOLD_": 32 * 2 ** 20,
                       "MALLOC_TRIM_THRESHOLD_": 256 * 2 ** 20, "OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1,
                       "OPENBLAS_NUM_THREADS": 1}
#: The Dask configuration recommended for a cluster that runs notchfit (``dask.config.set(DASK_CONFIG)``
#: before the cluster starts, or the same keys in a Dask YAML file: docs/reliability.md): the worker
#: environment above, and no statistical profiler (it samples the task's thread every 10 ms).
DASK_CONFIG = {"distributed.nanny.pre-spawn-environ": DASK_WORKER_ENVIRON,
               "distributed.worker.profile.enabled": False}


def single_threaded_worker(threads: int = 1) -> None:
    """Initializer of worker processes: native libraries use ``threads`` threads each.

    The work items here are small (a few hundred points, 27 joints): BLAS
    thread pools only add contention, and with several worker processes
    they oversubscribe the cores (``benchmarks/bench_diagnose.py`` measures
    both). Uses threadpoolctl; the limit holds for the life of the process.

    OpenCV's own pool is left alone: ``cv2.setNumThreads`` in a forked
    child whose parent already used that pool never returns.
    """
    threadpool_limits(limits=threads)


def _die_with_parent() -> None:
    """On Linux, this process gets SIGTERM when its parent ends, even by SIGKILL (``prctl``
    ``PR_SET_PDEATHSIG``): a pool's workers otherwise wait for work forever, each holding the
    pipes of the killed command open."""
    if not sys.platform.startswith("linux"):
        return
    parent = multiprocessing.parent_process()
    try:
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)      # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if parent is not None and os.getppid() != parent.pid:              # the parent ended before prctl
        os.kill(os.getpid(), signal.SIGTERM)


def worker_init() -> None:
    """Initializer of the pool's worker processes: Ctrl-C is the parent's to handle (ignored here),
    SIGTERM ends the worker (the default action, not a handler inherited through fork) and comes
    when the parent ends, however it ends (:func:`_die_with_parent`), one thread per native
    library (:func:`single_threaded_worker`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with_parent()
    single_threaded_worker()


def _stop_pool(pool: cf.ProcessPoolExecutor) -> None:
    """Cancel what is queued and terminate the workers now (the parent was interrupted or failed)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=5)
        if p.is_alive():
            p.kill()
            p.join(timeout=5)


@dataclass(frozen=True)
class ItemResult:
    """Outcome of one item.

    Attributes
    ----------
    key : str
        The item's label (experiment name, ``ct045/17``, an image file name).
    ok : bool
    value : object
        ``func(item)`` when ok, else None.
    error : str or None
        ``"ExceptionType: message"`` when the item failed.
    seconds : float
        Wall time of the call [s] (0 when the worker died).
    """

    key: str
    ok: bool
    value: Any = None
    error: str | None = None
    seconds: float = 0.0


@dataclass(frozen=True)
class BatchResult:
    """Results of :func:`run_batch`, in input order."""

    items: tuple
    seconds: float = 0.0

    @property
    def failures(self) -> list[ItemResult]:
        return [r for r in self.items if not r.ok]

    @property
    def n_ok(self) -> int:
        return sum(r.ok for r in self.items)

    def values(self) -> list:
        """Values in input order (None for failed items)."""
        return [r.value for r in self.items]

    def summary(self, what: str = "batch") -> str:
        """``"fit: 7 of 8 ok in 3.2 s; 1 failed:\\n  ct045: ValueError: ..."``."""
        n = len(self.items)
        s = f"{what}: {self.n_ok} of {n} ok in {self.seconds:.1f} s"
        if self.failures:
            s += f"; {len(self.failures)} failed:"
            for r in self.failures:
                s += f"\n  {r.key}: {r.error}"
        return s

    def raise_on_failure(self) -> None:
        """Raise RuntimeError with the summary if any item failed."""
        if self.failures:
            raise RuntimeError(self.summary())


def _describe(exc: BaseException) -> str:
    msg = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {msg[0] if msg else ''}".rstrip(": ") + \
        ("" if len(msg) <= 1 else " ...")


def _call(func, item):
    """Run one item; never raises (the worker side of failure isolation)."""
    t0 = time.perf_counter()
    try:
        return True, func(item), None, time.perf_counter() - t0
    except Exception as exc:  # noqa: BLE001 - isolation is the point
        return False, None, _describe(exc), time.perf_counter() - t0


def _progress(total, desc, progress, jobs: int = 1, unit: str = "items"):
    """The batch's bar (:func:`notchfit.progress.bar`); piped, its line names the processes."""
    label = desc if (desc is None or jobs <= 1) else f"{desc} ({jobs} processes)"
    return progress_bar(total, label, enabled=progress, unit=unit)


def _mp_context(start_method: str | None = None):
    """Start method for worker processes: ``start_method`` when given, else fork when this
    process runs no other thread, else spawn.

    fork is fastest; forking a process that runs other threads (a Dask
    client, tqdm's monitor, a native pool) can leave a lock held forever in
    the child."""
    if start_method is not None:
        return multiprocessing.get_context(start_method)
    if sys.platform.startswith("linux") and threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context("spawn")


def run_batch(func: Callable, items: Sequence, *, keys: Sequence[str] | None = None, jobs: int = 1,
              scheduler=None, desc: str | None = None, progress: bool | None = None,
              start_method: str | None = None, connect_timeout: float = 5.0,
              unit: str = "items", on_result: Callable[[int, ItemResult], None] | None = None) -> BatchResult:
    """Call ``func(item)`` for every item, isolating failures.

    Parameters
    ----------
    func : callable
        ``func(item) -> value``; module-level (picklable) when ``jobs > 1`` or
        with a scheduler.
    items : sequence
    keys : sequence of str, optional
        Labels for the summary (default: the item index).
    jobs : int
        Worker processes (1: run here; 0 or negative: one per CPU).
    scheduler : str or dask.distributed.Client, optional
        Address of a Dask distributed scheduler (``tcp://host:8786``) or a
        client: the items run on that cluster instead.
    desc : str, optional
        Progress-bar label.
    progress : bool, optional
        Force the bar on/off (default: a bar on a terminal, else one line
        when ``desc`` is given; :func:`notchfit.progress.bar`).
    start_method : str, optional
        ``multiprocessing`` start method of the worker processes (``"fork"``,
        ``"spawn"``, ``"forkserver"``); default: fork when this process runs
        no other thread, else spawn.
    unit : str
        What an item is, for the progress line (``"images"``, ``"experiments"``).
    connect_timeout : float
        Seconds to wait for a Dask scheduler to answer before the run fails
        with ``ValueError`` naming the address [s].
    on_result : callable, optional
        ``on_result(index, item_result)``, called in this process as each item
        finishes (completion order). The returned :class:`BatchResult` then
        holds every item's outcome without its value (``value`` None): the
        callback has consumed it. An exception it raises stops the run (the
        workers are stopped as on an interrupt) and goes on.

    Returns
    -------
    BatchResult
        One :class:`ItemResult` per item, in input order.
    """
    items = list(items)
    keys = [str(k) for k in (keys if keys is not None else range(1, len(items) + 1))]
    if len(keys) != len(items):
        raise ValueError(f"{len(keys)} keys for {len(items)} items")
    if jobs is None or jobs <= 0:
        jobs = os.cpu_count() or 1
    t0 = time.perf_counter()
    sink = _Results(keys, on_result)
    if scheduler is not None:
        _run_dask(func, items, scheduler, sink, desc, progress, connect_timeout, unit)
    elif jobs == 1 or len(items) <= 1:
        with _progress(len(items), desc, progress, unit=unit) as bar:
            for i, it in enumerate(items):
                sink.put(i, _call(func, it))
                bar.update(1)
    else:
        _run_pool(func, items, sink, min(jobs, len(items)), desc, progress, _mp_context(start_method), unit)
    return BatchResult(items=tuple(sink.items), seconds=time.perf_counter() - t0)


class _Results:
    """Where the runners put each item's outcome ``(ok, value, error, seconds)`` as it arrives."""

    def __init__(self, keys, on_result=None):
        self.keys = keys
        self.on_result = on_result
        self.items: list = [None] * len(keys)

    def put(self, i: int, outcome) -> None:
        ok, value, error, seconds = outcome
        r = ItemResult(key=self.keys[i], ok=ok, value=value, error=error, seconds=seconds)
        if self.on_result is not None:
            self.on_result(i, r)
            r = dataclasses.replace(r, value=None)
        self.items[i] = r


def _run_pool(func, items, sink, jobs, desc, progress, ctx, unit="items"):
    """Process pool with at most ``jobs`` items in flight, so a dead worker blames few items."""
    todo = list(range(len(items)))[::-1]
    with _progress(len(items), desc, progress, jobs, unit) as bar:
        while todo:
            pool = cf.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx, initializer=worker_init)
            inflight: dict = {}
            broken = False
            try:
                while todo or inflight:
                    while todo and len(inflight) < 2 * jobs:
                        i = todo.pop()
                        inflight[pool.submit(_call, func, items[i])] = i
                    done, _ = cf.wait(inflight, return_when=cf.FIRST_COMPLETED)
                    for f in done:
                        i = inflight.pop(f)
                        try:
                            outcome = f.result()
                        except BrokenProcessPool:
                            broken = True
                            inflight[f] = i
                            break
                        except Exception as exc:  # pickling errors and the like
                            outcome = (False, None, _describe(exc), 0.0)
                        sink.put(i, outcome)
                        bar.update(1)
                    if broken:
                        break
            except BaseException:
                _stop_pool(pool)
                raise
            finally:
                pool.shutdown(wait=True, cancel_futures=True)
            if broken:
                # re-run each item that was in flight alone to find the one that kills its worker
                for f, i in inflight.items():
                    if f.done() and not f.cancelled() and f.exception() is None:
                        sink.put(i, f.result())
                    else:
                        sink.put(i, _run_isolated(func, items[i], ctx))
                    bar.update(1)


def _run_isolated(func, item, ctx):
    with cf.ProcessPoolExecutor(max_workers=1, mp_context=ctx, initializer=worker_init) as pool:
        try:
            return pool.submit(_call, func, item).result()
        except BrokenProcessPool:
            return (False, None, "worker process died while processing this item "
                                 "(a crash in native code, or out of memory)", 0.0)
        except Exception as exc:
            return (False, None, _describe(exc), 0.0)
        except BaseException:
            _stop_pool(pool)
            raise


def _call_many(func, items):
    """Run several items in one task (each isolated as by :func:`_call`)."""
    return [_call(func, it) for it in items]


def items_per_task(n_items: int, n_threads: int, *, most: int = 8) -> int:
    """How many items one Dask task runs: ``n_items // (4 * n_threads)``, between 1 and ``most``.

    Each task costs the scheduler, the client and the worker's event loop
    CPU time besides the item itself (``benchmarks/bench_dask.py`` measures
    it), on the same cores as the items on a small machine; a few
    items per task spread it, while every worker thread still gets at least
    four tasks (the load stays balanced) and an interrupted run loses at most
    two tasks per worker thread.
    """
    return max(1, min(most, n_items // max(1, 4 * n_threads)))


def _run_dask(func, items, scheduler, sink, desc, progress, connect_timeout: float = 5.0, unit="items"):
    """The items on a Dask cluster, a few per task (:func:`items_per_task`), two tasks per worker
    thread in flight; each result released once read."""
    try:  # Dask is an optional extra, slow to import: only with a scheduler
        from distributed import Client, as_completed
    except ImportError:
        raise ValueError("--scheduler needs Dask distributed: pip install 'notchfit[dask]'") from None
    own = not isinstance(scheduler, Client)
    try:
        client = Client(scheduler, timeout=connect_timeout) if own else scheduler
    except Exception as exc:  # noqa: BLE001 - OSError/TimeoutError, or garbage from a non-Dask server
        raise ValueError(f"cannot connect to the Dask scheduler at {scheduler} (no answer within "
                         f"{connect_timeout:g} s): {_describe(exc)}") from None
    inflight: dict = {}            # future key -> (indices, future)
    try:
        threads = sum(client.nthreads().values())
        per_task = items_per_task(len(items), threads)
        todo = [list(range(i, min(i + per_task, len(items)))) for i in range(0, len(items), per_task)][::-1]
        running = as_completed()

        def submit():
            idx = todo.pop()
            f = client.submit(_call_many, func, [items[i] for i in idx], pure=False)
            inflight[f.key] = (idx, f)
            running.add(f)

        while todo and len(inflight) < max(2, 2 * threads):
            submit()
        with _progress(len(items), desc, progress, unit=unit) as bar:
            for f in running:
                idx, _ = inflight.pop(f.key)
                try:
                    outcomes = f.result()
                except Exception as exc:  # a worker lost, a task that could not be deserialised
                    outcomes = [(False, None, _describe(exc), 0.0)] * len(idx)
                f.release()
                for i, outcome in zip(idx, outcomes):
                    sink.put(i, outcome)
                    bar.update(1)
                if todo:
                    submit()
    except BaseException:
        try:                        # interrupted: nothing of this run keeps running on the cluster
            client.cancel([f for _, f in inflight.values()])
        except Exception:  # noqa: BLE001 - a lost scheduler: the original exception matters
            pass
        raise
    finally:
        if own:
            client.close()
