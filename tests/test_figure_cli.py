"""`notchfit figure`: discovery of figure modules, data + PNG output, no silent overwrite."""
import sys
import textwrap

import numpy as np
import pandas as pd
import pytest

from notchfit.physics import cables as C
from notchfit.cli import main
from notchfit.figures import discover

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
MINE = {"fig3", "fig5", "fig6", "fig7", "fig8", "fig_fea"}


def test_discover_finds_the_paper_figures():
    figs = discover()
    assert MINE <= set(figs)
    assert all(callable(f) for f in figs.values())


def _fake_package(tmp_path, monkeypatch, name, modules):
    pkg = tmp_path / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for mod, src in modules.items():
        (pkg / f"{mod}.py").write_text(textwrap.dedent(src))
    monkeypatch.syspath_prepend(str(tmp_path))
    for key in [k for k in sys.modules if k == name or k.startswith(name + ".")]:
        monkeypatch.delitem(sys.modules, key)
    return name


def test_discover_merges_modules_and_skips_those_without_figures(tmp_path, monkeypatch):
    name = _fake_package(tmp_path, monkeypatch, "nf_figs_ok", {
        "a": "FIGURES = {'x': lambda out_dir, **kw: []}",
        "b": "FIGURES = {'y': lambda out_dir, **kw: []}",
        "helpers": "VALUE = 1",
        "_private": "raise RuntimeError('never imported')",
    })
    assert set(discover(name)) == {"x", "y"}


def test_discover_duplicate_name_is_an_error(tmp_path, monkeypatch):
    name = _fake_package(tmp_path, monkeypatch, "nf_figs_dup", {
        "a": "FIGURES = {'fig3': lambda out_dir, **kw: []}",
        "b": "FIGURES = {'fig3': lambda out_dir, **kw: []}",
    })
    with pytest.raises(ValueError, match="fig3.*twice"):
        discover(name)


def test_discover_broken_module_is_named(tmp_path, monkeypatch):
    name = _fake_package(tmp_path, monkeypatch, "nf_figs_bad", {"broken": "import not_a_module_xyz"})
    with pytest.raises(ImportError, match="nf_figs_bad.broken"):
        discover(name)


def test_cli_list(capsys):
    """Every figure, in natural order (fig3 before fig11), described in plain text (no reST markup)."""
    assert main(["figure", "--list"]) == 0
    out = capsys.readouterr().out
    for name in MINE:
        assert name in out
    names = [ln.split()[0] for ln in out.splitlines()]
    assert names.index("fig3") < names.index("fig8") < names.index("fig11") < names.index("fig19")
    assert "``" not in out and ":func:" not in out and "`" not in out
    assert "error L_Ri - L_RSi of the simplified segment length" in out


def test_natural_key_and_plain_text():
    from notchfit.commands.figure import plain_text
    from notchfit.figures import natural_key

    assert sorted(["fig11", "fig3", "hysteresis", "fig_fea", "fig19"], key=natural_key) == \
        ["fig3", "fig11", "fig19", "fig_fea", "hysteresis"]
    assert plain_text("see :func:`notchfit.x` and ``a + b`` or `c`") == "see notchfit.x and a + b or c"


def test_cli_all_names_every_figure_and_keeps_existing_files(tmp_path, capsys):
    """`figure all` = every listed figure; with every file present nothing is redrawn (exit 0)."""
    names = list(discover())
    for n in names:
        (tmp_path / f"{n}.png").write_bytes(PNG_MAGIC)
    assert main(["figure", "all", "--out", str(tmp_path)]) == 0
    kept = [ln.split(":")[0] for ln in capsys.readouterr().out.splitlines() if ": kept " in ln]
    assert kept == names
    assert main(["figure", "all", "fig99", "--out", str(tmp_path)]) == 2
    assert "available: all, fig3" in capsys.readouterr().err


def test_cli_writes_data_and_png_and_refuses_overwrite(tmp_path, capsys):
    out = tmp_path / "figs"
    assert main(["figure", "fig3", "fig5", "fig6", "fig7", "fig_fea", "--out", str(out)]) == 0
    for name in ("fig3", "fig5", "fig6", "fig7", "fig_fea"):
        assert (out / f"{name}.png").read_bytes()[:8] == PNG_MAGIC
        assert (out / f"{name}.csv").stat().st_size > 0
    # Fig. 3 data are the cable model's numbers (µm)
    df = pd.read_csv(out / "fig3.csv")
    assert list(df.columns) == ["theta_i_rad", "theta_ip1_rad", "error_um"]
    assert df.theta_i_rad.min() == pytest.approx(-0.14) and df.theta_ip1_rad.max() == pytest.approx(0.14)
    from notchfit.physics.geometry import default_geometry
    g = default_geometry()
    row = df.iloc[1234]
    expect = (C.segment_length(row.theta_i_rad, row.theta_ip1_rad, g)
              - C.segment_length_simple(row.theta_i_rad, row.theta_ip1_rad, g)) * 1e6
    assert row.error_um == pytest.approx(expect, rel=1e-6, abs=1e-9)
    df6 = pd.read_csv(out / "fig6.csv")
    assert df6.length_um.min() == pytest.approx(810 - 2 * 0.14 * 2500, abs=1e-6)   # Fig. 6 range
    # existing files are kept (README "Paper figures"): said, exit 0, the file untouched; --force redraws
    before = (out / "fig7.png").stat().st_mtime_ns
    capsys.readouterr()
    assert main(["figure", "fig7", "--out", str(out)]) == 0
    assert f"fig7: kept {out / 'fig7.csv'}, {out / 'fig7.png'} (exist; --force" in capsys.readouterr().out
    assert (out / "fig7.png").stat().st_mtime_ns == before
    assert main(["figure", "fig7", "--out", str(out), "--force"]) == 0
    assert (out / "fig7.png").stat().st_mtime_ns > before


def test_cli_input_errors(tmp_path, capsys):
    assert main(["figure", "fig99", "--out", str(tmp_path)]) == 2
    assert "unknown figure" in capsys.readouterr().err
    assert main(["figure", "--out", str(tmp_path)]) == 2
    f = tmp_path / "afile"
    f.write_text("x")
    assert main(["figure", "fig7", "--out", str(f)]) == 2


def test_fig8_data(tmp_path):
    """Fig. 8 writes both equilibria; they differ (see test_statics.test_fig8_path_dependence)."""
    paths = discover()["fig8"](tmp_path)
    assert {p.name for p in paths} == {"fig8.csv", "fig8_history.csv", "fig8.png"}
    df = pd.read_csv(tmp_path / "fig8.csv")
    a = df[df.solution == "A"].theta_rad.dropna().to_numpy()
    b = df[df.solution == "B"].theta_rad.dropna().to_numpy()
    assert a.size == b.size == 27
    assert np.abs(a - b).max() == pytest.approx(0.273, abs=0.002)
    h = pd.read_csv(tmp_path / "fig8_history.csv")
    assert h.time_s.iloc[-1] == pytest.approx(6.0)
    assert h.tip_phi_rad_A.iloc[-1] == pytest.approx(a.sum(), abs=1e-6)
