"""Sub-commands of the ``notchfit`` CLI, one module each (see :mod:`notchfit.cli`)."""
