"""Shared by the tests/test_reliability_*.py files: a tiny study, CLI runners, snapshots.

Not a test module (no ``test_`` prefix); imported by name (pytest puts tests/ on sys.path).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from notchfit.cli import main
from notchfit.studies.synth import generate_study, load_recipe

ROOT = Path(__file__).resolve().parent.parent


def make_study(folder: Path, *, n_experiments: int = 2, n_up: int = 3, n_down: int = 3, seed: int = 1) -> Path:
    """A small synthetic study (recipe ``null``) written to ``folder``."""
    generate_study(load_recipe("null").scaled(n_experiments=n_experiments, n_up=n_up, n_down=n_down),
                   folder, seed=seed)
    return folder


def copy_study(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def run_main(argv, capsys) -> tuple[int, str, str]:
    """``notchfit argv`` in this process: (exit code, stdout, stderr)."""
    rc = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def cli_env(**extra) -> dict:
    """The environment of a subprocess CLI run on this checkout's code."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("NOTCHFIT_DEBUG", None)
    env.update(extra)
    return env


def run_cli(argv, *, timeout: float = 300, **env) -> subprocess.CompletedProcess:
    """``python -m notchfit.cli argv`` in a subprocess (text output captured)."""
    return subprocess.run([sys.executable, "-m", "notchfit.cli", *[str(a) for a in argv]],
                          capture_output=True, text=True, timeout=timeout, env=cli_env(**env), cwd=ROOT)


def snapshot(folder: Path) -> dict:
    """``{relative path: bytes}`` of every file under ``folder`` (hidden ones included)."""
    folder = Path(folder)
    if not folder.exists():
        return {}
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def prior_outputs(out: Path) -> dict:
    """An output folder holding earlier results (fit outputs of experiments L045 and L150); its snapshot."""
    for name in ("L045", "L150"):
        (out / name).mkdir(parents=True, exist_ok=True)
        (out / name / "fits.csv").write_bytes(f"earlier fits of {name}\n".encode())
        (out / name / "simulation.csv").write_bytes(f"earlier simulation of {name}\n".encode())
    (out / "diagnosis.json").write_bytes(b'{"earlier": true}\n')
    return snapshot(out)


def messages(err: str) -> list[str]:
    """The stderr lines that are not progress lines (notchfit.progress: those end with " ...")."""
    return [ln for ln in err.splitlines() if ln.strip() and not ln.endswith(" ...")]


def assert_one_line_error(rc: int, err: str, *needles: str, code: int = 2) -> str:
    """Exit ``code``, exactly one stderr line besides the progress lines of the stages that ran
    (notchfit.progress: they end with " ..."), no traceback, every needle in that line; returns it."""
    lines = messages(err)
    assert rc == code, (rc, err)
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    for n in needles:
        assert str(n) in lines[0], (n, lines[0])
    return lines[0]
