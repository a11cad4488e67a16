"""Compare the demo's outputs with a stored reference (refactors must not change results).

Runs ``notchfit demo --small --seed 0 --no-images`` into a temporary folder and
compares every CSV, JSON and TOML file it writes (study and results) with
``benchmarks/reference/demo-small-seed0/``: every reference file written again, same columns and keys,
numbers equal to ``--tol`` (absolute and relative, default 1e-9), strings equal.
Run logs (``*_run.json``: times, paths) are not compared; files the
reference does not have are listed (new outputs), not failed.

Seed 0 is the setting at which the code before the architecture refactor and
after it agree by construction (the noise floor used seed 0 whatever seed was
asked for). ``--update`` rewrites the reference from the current code.

Usage::

    python benchmarks/compare_demo.py            # exit 0 when everything agrees
    python benchmarks/compare_demo.py --update   # store a new reference
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

REFERENCE = Path(__file__).resolve().parent / "reference" / "demo-small-seed0"
KINDS = ("*.csv", "*.json", "*.toml")
#: keys whose values are paths or run metadata, not results
IGNORED_KEYS = {"extended_model_file", "figures", "input", "time", "python", "notchfit"}


def output_files(root: Path) -> list[Path]:
    """Result files under ``root`` (relative paths), run logs excluded."""
    out = []
    for pattern in KINDS:
        out += [p.relative_to(root) for p in root.rglob(pattern) if not p.name.endswith("_run.json")]
    return sorted(out)


def close(a: float, b: float, tol: float) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return abs(a - b) <= tol * max(1.0, abs(a), abs(b))


def compare_values(a, b, tol: float, where: str, problems: list[str]) -> None:
    """Recursive comparison of JSON/TOML values."""
    if isinstance(a, dict) and isinstance(b, dict):
        keys = (set(a) | set(b)) - IGNORED_KEYS
        for k in sorted(keys):
            if k not in a or k not in b:
                problems.append(f"{where}.{k}: only in {'reference' if k in a else 'new output'}")
            else:
                compare_values(a[k], b[k], tol, f"{where}.{k}", problems)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            problems.append(f"{where}: length {len(a)} != {len(b)}")
        for i, (x, y) in enumerate(zip(a, b)):
            compare_values(x, y, tol, f"{where}[{i}]", problems)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if not close(float(a), float(b), tol):
            problems.append(f"{where}: {a!r} != {b!r}")
    elif a != b:
        problems.append(f"{where}: {a!r} != {b!r}")


def compare_tables(ref: Path, new: Path, tol: float, problems: list[str]) -> None:
    a, b = pd.read_csv(ref), pd.read_csv(new)
    if list(a.columns) != list(b.columns) or len(a) != len(b):
        problems.append(f"{ref.name}: columns/rows {list(a.columns)}x{len(a)} != {list(b.columns)}x{len(b)}")
        return
    for col in a.columns:
        x, y = a[col], b[col]
        if pd.api.types.is_numeric_dtype(x) and pd.api.types.is_numeric_dtype(y):
            x, y = x.to_numpy(float), y.to_numpy(float)
            both_nan = np.isnan(x) & np.isnan(y)
            bad = ~both_nan & ~(np.abs(x - y) <= tol * np.maximum(1.0, np.maximum(np.abs(x), np.abs(y))))
            if bad.any():
                k = int(np.argmax(bad))
                problems.append(f"{ref}: column {col}: {int(bad.sum())} values differ (row {k}: {x[k]!r} != {y[k]!r})")
        elif not x.astype(str).equals(y.astype(str)):
            problems.append(f"{ref}: column {col}: strings differ")


def compare_trees(ref_root: Path, new_root: Path, tol: float) -> list[str]:
    problems: list[str] = []
    ref_files, new_files = output_files(ref_root), output_files(new_root)
    for missing in sorted(set(ref_files) - set(new_files)):
        problems.append(f"{missing}: not written any more")
    for rel in sorted(set(ref_files) & set(new_files)):
        ref, new = ref_root / rel, new_root / rel
        if rel.suffix == ".csv":
            compare_tables(ref, new, tol, problems)
        elif rel.suffix == ".json":
            compare_values(json.loads(ref.read_text()), json.loads(new.read_text()), tol, str(rel), problems)
        else:
            compare_values(tomllib.loads(ref.read_text()), tomllib.loads(new.read_text()), tol, str(rel), problems)
    return problems


def run_demo(out: Path) -> None:
    cmd = [sys.executable, "-m", "notchfit.cli", "demo", "--small", "--seed", "0", "--no-images",
           "--out", str(out), "--force"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tol", type=float, default=1e-9, help="absolute/relative tolerance (default 1e-9)")
    ap.add_argument("--update", action="store_true", help="store the current outputs as the reference")
    ap.add_argument("--outputs", type=Path, help="compare this existing demo folder instead of running the demo")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        out = args.outputs or Path(tmp) / "demo"
        if args.outputs is None:
            run_demo(out)
        if args.update:
            shutil.rmtree(REFERENCE, ignore_errors=True)
            for rel in output_files(out):
                (REFERENCE / rel).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(out / rel, REFERENCE / rel)
            print(f"reference updated: {len(output_files(REFERENCE))} files in {REFERENCE}")
            return 0
        problems = compare_trees(REFERENCE, out, args.tol)
        new = sorted(set(output_files(out)) - set(output_files(REFERENCE)))
    n = len(output_files(REFERENCE))
    for rel in new:
        print(f"new file (not in the reference, not compared): {rel}")
    if problems:
        print(f"{len(problems)} differences against {n} reference files:")
        for p in problems[:200]:
            print("  " + p)
        return 1
    print(f"all {n} reference files agree to {args.tol:g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
