"""Run a benchmark script on two checkouts, alternately, and print their outputs side by side.

"Before and after" timings of a refactor measured in one session on one machine:
each round runs the benchmark once in each checkout (A then B, then B then A in the
next round, so that a drift of the machine's load does not favour one), each in a
fresh interpreter whose ``PYTHONPATH`` is that checkout, with the benchmark script
of that checkout. Make a read-only checkout of the old version with
``git worktree add --detach /tmp/before main``.

Usage::

    python benchmarks/compare_versions.py BEFORE_DIR AFTER_DIR bench_identify.py [--rounds 2] [-- ARGS...]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path


def run(checkout: Path, script: str, args: list[str]) -> tuple[float, str]:
    """Wall time [s] and output of one run of ``benchmarks/<script>`` in ``checkout``."""
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, str(checkout / "benchmarks" / script), *args], cwd=checkout, env=env,
                       capture_output=True, text=True)
    dt = time.perf_counter() - t0
    out = p.stdout + (f"\n[exit {p.returncode}]\n{p.stderr[-2000:]}" if p.returncode else "")
    return dt, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("script")
    ap.add_argument("--rounds", type=int, default=2)
    argv = list(sys.argv[1:] if argv is None else argv)
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    a = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    trees = {"before": a.before.resolve(), "after": a.after.resolve()}
    totals = {k: [] for k in trees}
    for r in range(a.rounds):
        order = list(trees) if r % 2 == 0 else list(reversed(trees))
        for name in order:
            dt, out = run(trees[name], a.script, extra)
            totals[name].append(dt)
            print(f"===== round {r + 1}, {name} ({trees[name]}): {dt:.1f} s wall for the whole script")
            print(out.rstrip(), flush=True)
    for name, ts in totals.items():
        print(f"{name}: script wall times " + ", ".join(f"{t:.1f}" for t in ts) + " s")
    b, c = min(totals["before"]), min(totals["after"])
    print(f"best of {a.rounds}: after/before = {c / b:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
