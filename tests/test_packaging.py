"""The package stands alone: every package and every shipped data file is in the wheel's configuration."""
import tomllib
from pathlib import Path

import pytest

from notchfit.io import calibration_dir, datasets_dir, load_board, load_geometry

ROOT = Path(__file__).resolve().parents[1]


def _setuptools_config() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_every_package_is_listed():
    cfg = _setuptools_config()
    listed = set(cfg["packages"])
    code = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "notchfit").rglob("__init__.py")}
    assert code <= listed, f"add to pyproject.toml [tool.setuptools] packages: {sorted(code - listed)}"
    data = {"notchfit.datasets", "notchfit.calibration"}
    for top in ("datasets", "calibration"):
        data |= {".".join(("notchfit", top) + p.relative_to(ROOT / top).parts)
                 for p in (ROOT / top).rglob("*") if p.is_dir() and p.name != "__pycache__"}
    assert listed == code | data
    assert cfg["package-dir"] == {"notchfit.datasets": "datasets", "notchfit.calibration": "calibration"}


def test_every_shipped_file_is_package_data():
    cfg = _setuptools_config()
    patterns = cfg["package-data"]
    shipped = sorted(p for d in ("datasets", "calibration") for p in (ROOT / d).rglob("*")
                     if p.is_file() and "__pycache__" not in p.parts)
    for p in shipped:
        rel = p.relative_to(ROOT)
        package = ".".join(("notchfit",) + rel.parent.parts)
        assert any(p.match(pat) for pat in patterns.get(package, [])), f"{rel} is not package data"


def test_shipped_folders_and_overrides(tmp_path, monkeypatch):
    assert (datasets_dir() / "geometry" / "default.toml").is_file()
    assert (calibration_dir() / "charuco_a4.toml").is_file()
    assert len(list((calibration_dir() / "samples" / "charuco_a4").glob("*.jpg"))) == 6   # README calibrate
    monkeypatch.setenv("NOTCHFIT_DATASETS", str(tmp_path))
    assert datasets_dir() == tmp_path
    with pytest.raises(FileNotFoundError, match="default.toml"):
        load_geometry("default")
    monkeypatch.setenv("NOTCHFIT_CALIBRATION", str(tmp_path))
    with pytest.raises(FileNotFoundError, match="shipped boards: none"):
        load_board("charuco_a4")
