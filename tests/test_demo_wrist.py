"""`notchfit demo --tube wrist` end to end (issue 18 item 4), at the small size.

Two synthetic nitinol wrists of one stock (recipe wrist_stock: notch angles, loading-only
trials, 0.5 deg angle noise) through fit (angle-space shape models), identify and simulate
with the identified model. Marked slow: ~13 s of CPU (the identification refits 9 times).
"""
import json
import re

import pandas as pd
import pytest

from notchfit.cli import main


@pytest.mark.slow
def test_wrist_demo_identifies_and_simulates(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--tube", "wrist", "--small", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    res = out / "results"
    data = json.loads((res / "identify.json").read_text())
    assert data["metric"] == "deg" and set(data["tubes"]) == {"wrist_asymmetric", "wrist_tip_first"}
    # each trial predicted by a model that never saw it: about the 0.5 deg angle noise
    assert data["heldout_rms"] < 0.75
    # the identified material is printed beside the hidden truth
    line = next(ln for ln in text.splitlines() if ln.startswith("identified:"))
    for found, truth in re.findall(r"E_lin_Pa ([\d.e+]+) .*?\(truth ([\d.e+]+)\)", line):
        assert abs(float(found) / float(truth) - 1) < 0.1
    cmp = pd.read_csv(res / "A1" / "simulation_vs_angles.csv")
    assert cmp["rms_deg"].mean() < 1.0 and (res / "A1" / "angle_fits.csv").is_file()
    page = (res / "report.html").read_text()                    # the demo writes its report
    assert "wrist_tip_first" in page and "could not build" not in page and f"report: {res / 'report.html'}" in text
    assert main(["demo", "--tube", "wrist", "--small", "--out", str(out)]) == 2       # no overwrite without --force
