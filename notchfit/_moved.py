"""The module names of earlier releases, kept importable after the layer folders came.

notchfit's modules now live in folders named for their layer (``physics``,
``vision``, ``analysis``, ``studies``; docs/architecture.md). The old dotted
names (``notchfit.friction``, ``notchfit.detection.refine``, ...) still import
the same module objects, with a :class:`FutureWarning` that names the new home,
so scripts written for earlier releases keep working while they are updated.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

#: old top-level name under ``notchfit`` -> its new dotted path under ``notchfit``
MOVED = {
    "geometry": "physics.geometry", "kinematics": "physics.kinematics", "notches": "physics.notches",
    "cables": "physics.cables", "springs": "physics.springs", "statics": "physics.statics",
    "friction": "physics.friction", "friction_params": "physics.friction_params",
    "_friction_kernels": "physics._friction_kernels", "_spring_kernels": "physics._spring_kernels",
    "_hysteresis_kernels": "physics._hysteresis_kernels", "section": "physics.section",
    "predictor": "physics.predictor", "protocols": "physics.protocols", "shapes": "physics.shapes",
    "camera": "vision.camera", "render": "vision.render", "detection": "vision.detection", "warp": "vision.warp",
    "fitting": "analysis.fitting", "comparison": "analysis.comparison",
    "estimation": "analysis.estimation", "identify": "analysis.identify", "diagnosis": "analysis.diagnosis",
    "causes": "analysis.causes",
    "lack_of_fit": "analysis.lack_of_fit",
    "synth": "studies.synth", "recipes": "studies.recipes",
}


def new_name(fullname: str) -> str:
    """``notchfit.<old>[.rest]`` -> ``notchfit.<layer>.<old>[.rest]``; other names unchanged."""
    head, _, rest = fullname.partition(".")
    if head != "notchfit" or not rest:
        return fullname
    first, _, tail = rest.partition(".")
    if first not in MOVED:
        return fullname
    return f"notchfit.{MOVED[first]}" + (f".{tail}" if tail else "")


class _Alias(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds an old name and loads it as the module of its new name (the same object)."""

    def find_spec(self, fullname, path=None, target=None):
        new = new_name(fullname)
        if new == fullname or importlib.util.find_spec(new) is None:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None     # a placeholder; exec_module puts the real module in its place

    def exec_module(self, module):
        new = new_name(module.__name__)
        warnings.warn(f"{module.__name__} is now {new}: the old name still imports it, "
                      "but scripts should use the new one", FutureWarning, stacklevel=2)
        sys.modules[module.__name__] = importlib.import_module(new)


def install() -> None:
    """Put the old names' finder first (once): an old name must never find a stale file of its own."""
    if not any(isinstance(f, _Alias) for f in sys.meta_path):
        sys.meta_path.insert(0, _Alias())
