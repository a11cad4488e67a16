"""The seed paper's parameter values, in one place (SI units).

Moses, Murphy, Kutzer & Armand, IEEE/ASME Trans. Mechatronics 20(6), 2015.
Every default that reproduces the paper (springs, friction model, statics,
the diagnosis baseline's starting point) reads these names.
"""

from __future__ import annotations

__all__ = [
    "DAMPING", "DUAL_RATE_K1", "DUAL_RATE_K2", "DUAL_RATE_THRESH",
    "FRICTION_K_LIN", "FRICTION_K_MID", "FRICTION_K_STOP", "FRICTION_THETA_MID",
    "FRICTION_THETA_STOP", "MU_D", "MU_S", "V_THR",
]

# Dual-rate flexure spring (Sec. III, Fig. 7) [N m/rad], [rad]
DUAL_RATE_K1 = 0.36
DUAL_RATE_K2 = 10.0
DUAL_RATE_THRESH = 0.135

# Friction-model spring (Sec. IV-B, Fig. 17) [N m/rad], [rad]. The paper gives
# no number for the mid-range rate: 0.25 is the documented default, a fitted
# parameter.
FRICTION_K_LIN = 0.4829
FRICTION_K_MID = 0.25
FRICTION_K_STOP = 10.0
FRICTION_THETA_MID = 0.07
FRICTION_THETA_STOP = 0.14

# Friction simulator (Sec. IV-B)
MU_D = 0.29          # sliding friction coefficient [-]
MU_S = 0.30          # static friction coefficient [-]
DAMPING = 0.03       # first-order damping b [N m s/rad]
V_THR = 5e-5         # stick speed threshold [m/s]
