"""Where the data shipped with notchfit lives: ``datasets/`` and ``calibration/``.

Both folders sit at the top of the repository and travel inside the wheel as
``notchfit/datasets/`` and ``notchfit/calibration/`` (package data mapped in
``pyproject.toml``), so an installed notchfit finds them through
:mod:`importlib.resources`; a checkout (an editable install, or the source
folder on ``PYTHONPATH``) finds them beside the ``notchfit`` package folder.
``$NOTCHFIT_DATASETS`` and ``$NOTCHFIT_CALIBRATION`` override the locations.
"""

from __future__ import annotations

import importlib.resources
import os
from pathlib import Path

__all__ = ["calibration_dir", "datasets_dir"]

_CHECKOUT = Path(__file__).resolve().parents[2]


def _shipped_folder(name: str, env: str) -> Path:
    """``$env`` if set, else ``notchfit/<name>`` of an installed notchfit, else ``<checkout>/<name>``."""
    override = os.environ.get(env)
    if override:
        return Path(override)
    installed = importlib.resources.files("notchfit").joinpath(name)
    if isinstance(installed, Path) and installed.is_dir():
        return installed
    return _CHECKOUT / name


def datasets_dir() -> Path:
    """Folder of the shipped data: default geometry, recipes, reference values.

    Returns
    -------
    Path
        ``$NOTCHFIT_DATASETS`` if set, else the repository's ``datasets/``
        as installed with notchfit.

    Raises
    ------
    FileNotFoundError
        The folder is absent, with a hint.
    """
    path = _shipped_folder("datasets", "NOTCHFIT_DATASETS")
    if not path.is_dir():
        raise FileNotFoundError(
            f"notchfit data folder not found at {path}; reinstall notchfit (`pip install .`) "
            "or set NOTCHFIT_DATASETS"
        )
    return path


def calibration_dir() -> Path:
    """Folder of the shipped calibration-board definitions (the repository's ``calibration/``).

    ``$NOTCHFIT_CALIBRATION`` overrides it. The folder may be absent (then no
    board can be looked up by name).
    """
    return _shipped_folder("calibration", "NOTCHFIT_CALIBRATION")
