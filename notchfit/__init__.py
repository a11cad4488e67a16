"""notchfit: models, image processing and diagnosis for notched-tube continuum manipulators.

After Moses, Murphy, Kutzer & Armand, "Modeling cable and guide channel
interaction in a high-strength cable-driven continuum manipulator",
IEEE/ASME Trans. Mechatronics 20(6), 2015.

Modules are named for their concept (geometry, kinematics, notches, cables,
springs, statics, friction, fitting, camera, detection, render, io, synth,
diagnosis, report); the command-line pipeline is assembled in
:mod:`notchfit.cli` and :mod:`notchfit.commands`.
"""

from .geometry import Geometry, default_geometry, load_geometry

__version__ = "0.1.0"
__all__ = ["Geometry", "default_geometry", "load_geometry", "__version__"]
