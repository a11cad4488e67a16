"""notchfit: models, image processing and diagnosis for notched-tube continuum manipulators.

After Moses, Murphy, Kutzer & Armand, "Modeling cable and guide channel
interaction in a high-strength cable-driven continuum manipulator",
IEEE/ASME Trans. Mechatronics 20(6), 2015.

Modules are named for their concept (geometry, kinematics, notches, cables,
springs, statics, friction, fitting, camera, detection, render, io, synth,
diagnosis, report); the command-line pipeline is assembled in
:mod:`notchfit.cli` and :mod:`notchfit.commands`.
"""

from ._version import __version__
from .geometry import Geometry, default_geometry

__all__ = ["Geometry", "default_geometry", "load_geometry", "__version__"]


def __getattr__(name):
    """``notchfit.load_geometry``: :func:`notchfit.io.load_geometry`, resolved on first use."""
    if name == "load_geometry":
        # notchfit.io imports pandas and OpenCV; `import notchfit` stays light without them
        from .io import load_geometry

        return load_geometry
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
