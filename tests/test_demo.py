"""`notchfit demo` end to end (issue 7 item 6), at the small size."""
import re

from notchfit.cli import main


def test_demo_runs_end_to_end_and_report_has_every_section(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--small", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    lines = [ln for ln in text.splitlines() if ln.startswith(("fit errors", "cause:", "gain:"))]
    assert len(lines) == 3, text
    assert "cause: proximal_friction" in text
    gain = float(re.search(r"\(([\d.]+) % lower\)", text).group(1))
    assert gain >= 30
    html = (out / "results" / "report.html").read_text()
    for section in ("Summary", "Calibration quality", "Detection", "Shape-fit errors",
                    "Simulation vs measurement", "Diagnosis"):
        assert f"<h2>{section}" in html
    # self-contained: figures embedded, nothing fetched from elsewhere
    assert html.count("data:image/png;base64") >= 5
    assert not re.search(r'(src|href)\s*=\s*["\']?(https?:|//|file:)', html)
    # refuses to overwrite an earlier demo without --force
    assert main(["demo", "--small", "--out", str(out)]) == 2
