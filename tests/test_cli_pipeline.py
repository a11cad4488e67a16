"""The pipeline commands (synth, fit, simulate, report) and the README quick start."""
import re
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _readme_test_command():
    text = (ROOT / "README.md").read_text()
    quick = re.search(r"^## Quick start\n(.*?)(?=^## )", text, re.S | re.M)
    assert quick, "README.md has no '## Quick start' section"
    blocks = re.findall(r"```(?:bash|sh|console)?\n(.*?)```", quick.group(1), re.S)
    cmds = [ln.strip() for b in blocks for ln in b.splitlines() if "pytest" in ln and not ln.startswith("#")]
    assert len(cmds) == 1, f"expected one test command in the quick start, found {cmds}"
    return cmds[0]


def _ci_test_command():
    lines = [ln.strip() for ln in (ROOT / ".ci" / "run").read_text().splitlines()
             if ln.strip() and not ln.strip().startswith("#")]
    cmds = [ln for ln in lines if "pytest" in ln and not ln.startswith(("echo", "if", "rc="))]
    assert len(cmds) == 1, f"expected one pytest command in .ci/run, found {cmds}"
    return cmds[0]


def test_readme_quick_start_is_what_ci_runs():
    readme, ci = _readme_test_command(), _ci_test_command()
    assert shlex.split(readme) == shlex.split(ci), (readme, ci)
    assert shlex.split(ci)[-3:] == ["python", "-m", "pytest"]
