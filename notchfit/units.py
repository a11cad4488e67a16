"""Unit constants: the one place that converts between SI and file/CLI units.

Inside notchfit every quantity is SI (m, N, rad, s, N m, Pa). Files and the
command line carry unit suffixes (``x_mm``, ``tension_N``, ``theta_deg``);
readers multiply by these constants on the way in, writers divide on the way
out::

    x = x_mm * MM          # mm -> m
    x_mm = x / MM          # m -> mm
    theta = theta_deg * DEG
"""

from __future__ import annotations

import math

__all__ = ["DEG", "MM", "UNIT_SIZE"]

#: One millimetre in metres.
MM = 1e-3
#: One degree in radians.
DEG = math.pi / 180.0
#: The units of measurement errors in files, by their suffix: their size in SI [m or rad].
UNIT_SIZE = {"mm": MM, "deg": DEG}
