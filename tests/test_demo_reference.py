"""The small demo (seed 0) reproduces the stored reference outputs to 1e-9.

A guard for refactors: `benchmarks/compare_demo.py` runs `notchfit demo --small
--seed 0 --no-images` and compares every CSV, JSON and TOML file it writes with
`benchmarks/reference/demo-small-seed0/` (regenerate with `--update` when a
change of results is intended, and say why in the commit).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest


SCRIPT = Path(__file__).resolve().parent.parent / "benchmarks" / "compare_demo.py"


def _module():
    spec = importlib.util.spec_from_file_location("compare_demo", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_comparison_detects_a_changed_number(tmp_path):
    mod = _module()
    ref = tmp_path / "ref"
    new = tmp_path / "new"
    for root, value in ((ref, 0.1), (new, 0.1 + 1e-6)):
        (root / "results").mkdir(parents=True)
        (root / "results" / "fits.csv").write_text(f"sample,a\n1,{value!r}\n")
        (root / "results" / "diagnosis.json").write_text('{"gain": {"extended": 1.0}, "time": "x"}')
    problems = mod.compare_trees(ref, new, 1e-9)
    assert len(problems) == 1 and "column a" in problems[0]
    assert mod.compare_trees(ref, ref, 1e-9) == []


@pytest.mark.slow
def test_small_demo_reproduces_the_reference(tmp_path):
    mod = _module()
    out = tmp_path / "demo"
    mod.run_demo(out)
    problems = mod.compare_trees(mod.REFERENCE, out, 1e-9)
    assert problems == [], "\n".join(problems[:20])
