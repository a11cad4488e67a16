"""Every command example of the README runs as written on the demo's study (issue 17).

The README says its examples run from the repository's folder once
`notchfit demo` has written its study, in the order shown, with new paths
under `out/`. Here the "repository's folder" is a temporary folder holding
the demo's study (`notchfit-demo/study`, written by the demo's own study
function at the small size, with images) and the shipped `calibration/`
(a link to the repository's); each command runs verbatim through the shell
(globs included), `notchfit` being this checkout's command line. The long
ones (diagnose and what needs its result, synth, demo, drawing figures) are
marked slow; a test runs the earlier fast commands first when they have not
run yet, so that each can be run alone. The fast examples of the default job run on
a reduced study of the demo (2 experiments of 4 + 4 samples, with images): what they check,
that each example runs as written, needs no more; the slow ones, and the fast ones
they run first, use the demo's small study itself.
"""
from __future__ import annotations

import os
import re
import shlex
import stat
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def readme_commands(text: str | None = None) -> list[str]:
    """The README's command examples, in order: inline code spans and code-block lines that start with
    ``notchfit SUBCOMMAND`` and give it at least one argument (a bare ``notchfit diagnose`` names a
    command in prose, it is not an example)."""
    text = (ROOT / "README.md").read_text() if text is None else text
    text = re.sub(r"```[^\n]*\n(.*?)```", lambda m: "".join(f"`{ln}`" for ln in m.group(1).splitlines()),
                  text, flags=re.S)
    found = []
    for span in re.findall(r"`([^`]+)`", text):
        cmd = " ".join(span.split())
        words = shlex.split(cmd)
        if len(words) >= 3 and words[0] == "notchfit" and cmd not in found:
            found.append(cmd)
    return found


def is_slow(cmd: str) -> bool:
    """Minutes rather than seconds (or needs the diagnosis's result); drawing figures is tested elsewhere."""
    words = shlex.split(cmd)
    return (words[1] in ("diagnose", "identify", "synth", "demo") or "--model" in words
            or (words[1] == "figure" and "--list" not in words))


COMMANDS = readme_commands()


def test_the_readme_has_the_examples_it_promises():
    subs = [shlex.split(c)[1] for c in COMMANDS]
    for sub in ("calibrate", "detect", "fit", "simulate", "diagnose", "report", "synth", "figure"):
        assert sub in subs, (sub, COMMANDS)
    fast = [c for c in COMMANDS if not is_slow(c)]
    assert {shlex.split(c)[1] for c in fast} >= {"calibrate", "detect", "fit", "simulate", "report", "figure"}
    assert any("--points" in c for c in COMMANDS)           # the one option for a detect run's points
    assert readme_commands("a `notchfit diagnose` b `notchfit fit s\n --out o` ```bash\nnotchfit x y\n```") == \
        ["notchfit fit s --out o", "notchfit x y"]


def test_quick_start_has_two_set_up_and_run_commands():
    quick = re.search(r"^## Quick start\n(.*?)(?=^## )", (ROOT / "README.md").read_text(), re.S | re.M).group(1)
    blocks = re.findall(r"```(?:bash|sh|console)?\n(.*?)```", quick, re.S)
    lines = [ln.strip() for b in blocks for ln in b.splitlines() if ln.strip() and not ln.startswith("#")]
    assert lines == ['pip install -e . && notchfit demo', 'pip install -e ".[test]" && python -m pytest']


#: (experiments, samples loading, samples unloading) of the default job's reduced demo study
REDUCED = (2, 4, 4)


def make_workspace(ws: Path) -> dict:
    """The repository's folder ``ws`` as the README's examples see it, after `notchfit demo` wrote its study."""
    from notchfit.commands.demo import demo_study

    demo_study(ws / "notchfit-demo" / "study", small=True, images=True, jobs=2)
    (ws / "calibration").symlink_to(ROOT / "calibration", target_is_directory=True)
    bin_dir = ws / ".bin"
    bin_dir.mkdir()
    shim = bin_dir / "notchfit"
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m notchfit.cli "$@"\n')
    shim.chmod(shim.stat().st_mode | stat.S_IEXEC)
    env = dict(os.environ, PYTHONPATH=str(ROOT), PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    env.pop("NOTCHFIT_DEBUG", None)
    return {"dir": ws, "env": env, "done": set()}


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    """The README's folder with the demo's small study (the slow examples need its size)."""
    return make_workspace(tmp_path_factory.mktemp("readme"))


@pytest.fixture(scope="module")
def reduced_workspace(tmp_path_factory):
    """The README's folder with the demo's study reduced to ``REDUCED`` (the fast examples)."""
    from notchfit.commands import demo

    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(demo.SIZES, "small", REDUCED)
        return make_workspace(tmp_path_factory.mktemp("readme_reduced"))


def _run(ws: dict, cmd: str) -> subprocess.CompletedProcess:
    res = subprocess.run(cmd, shell=True, cwd=ws["dir"], env=ws["env"], capture_output=True, text=True,
                         timeout=1800)
    ws["done"].add(cmd)
    return res


@pytest.mark.parametrize("index", [pytest.param(i, marks=[pytest.mark.slow] if is_slow(c) else [],
                                                id=" ".join(shlex.split(c)[1:3]))
                                   for i, c in enumerate(COMMANDS)])
def test_readme_command_runs_as_written(request, index):
    workspace = request.getfixturevalue("workspace" if is_slow(COMMANDS[index]) else "reduced_workspace")
    for earlier in COMMANDS[:index]:
        if earlier not in workspace["done"] and not is_slow(earlier):
            res = _run(workspace, earlier)
            assert res.returncode == 0, (earlier, res.stdout[-2000:], res.stderr[-2000:])
    cmd = COMMANDS[index]
    res = _run(workspace, cmd)
    assert res.returncode == 0, (cmd, res.stdout[-3000:], res.stderr[-3000:])
    assert "Traceback" not in res.stderr, res.stderr[-3000:]
