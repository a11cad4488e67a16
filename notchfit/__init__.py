"""notchfit: models, image processing and diagnosis for notched-tube continuum manipulators.

After Moses, Murphy, Kutzer & Armand, "Modeling cable and guide channel
interaction in a high-strength cable-driven continuum manipulator",
IEEE/ASME Trans. Mechatronics 20(6), 2015.

The package's folders are its layers (docs/architecture.md), each importing
only from those below it: the primitives at the top of the package (units,
validation, paper, polygon, imaging, progress, batch); :mod:`notchfit.physics`
(geometry, kinematics, notches, shapes, cables, springs, statics, friction,
the predictor); :mod:`notchfit.vision` (camera, render, detection, the
camera-plane warp); :mod:`notchfit.analysis` (fitting, comparison, the
estimation core, identify, diagnosis, the cause records); :mod:`notchfit.io`;
:mod:`notchfit.studies` (synthetic studies and their recipes);
:mod:`notchfit.figures`, :mod:`notchfit.report` and :mod:`notchfit.review`;
and the command line, :mod:`notchfit.cli` and :mod:`notchfit.commands`. The
module names of earlier releases (``notchfit.friction``) still import the same
modules, with a warning that names the new home.
"""

from . import _moved
from ._version import __version__
from .physics.geometry import Geometry, default_geometry

__all__ = ["Geometry", "default_geometry", "load_geometry", "__version__"]

_moved.install()


def __getattr__(name):
    """``notchfit.load_geometry``: :func:`notchfit.io.load_geometry`, resolved on first use."""
    if name == "load_geometry":
        # notchfit.io imports pandas and OpenCV; `import notchfit` stays light without them
        from .io import load_geometry

        return load_geometry
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
