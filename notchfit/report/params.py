"""Model parameters in words: symbol, value (± standard error) and unit, for every parameter statement."""

from __future__ import annotations

import math

from ..units import DEG
from .page import num

__all__ = ["PARAM_TEXT", "param_text", "params_text"]

#: Symbol and unit of each model parameter as shown, and the factor from the SI value in the result files
#: (lengths in mm, moduli in GPa); the keys of diagnosis.json and of identify.json (``E_lin_Pa``) both.
PARAM_TEXT = {"k_lin": ("k_lin", "N m/rad"), "k_mid": ("k_mid", "N m/rad"), "k_stop": ("k_stop", "N m/rad"),
              "theta_mid": ("θ_mid", "rad"), "theta_stop": ("θ_stop", "rad"), "mu_d": ("μ_d", ""),
              "mu_s": ("μ_s", ""), "b": ("damping b", "N m s/rad"), "v_thr": ("v_thr", "m/s"),
              "proximal_beta": ("β", ""), "hysteresis_torque": ("hysteresis torque", "N m"),
              "hysteresis_onset": ("hysteresis onset", "rad"), "hysteresis_yield": ("yield angle", "rad"),
              "E_lin": ("E_lin", "GPa", 1e-9), "E_se": ("E_se", "GPa", 1e-9),
              "E_lin_Pa": ("E_lin", "GPa", 1e-9), "E_se_Pa": ("E_se", "GPa", 1e-9),
              "strain_lower": ("ε_lower", ""), "damping_time": ("damping time", "s"),
              "tip_force_x": ("F_x", "N"), "tip_force_z": ("F_z", "N"), "stiffness_gradient": ("gradient", ""),
              "mu_s_minus_mu_d": ("μ_s − μ_d", ""), "mu_s_excess": ("μ_s − μ_d", ""),
              "scale_error": ("scale error", ""), "k_radial": ("radial k", ""),
              "warp_center_x": ("warp centre x", "mm", 1e3), "warp_center_y": ("warp centre y", "mm", 1e3),
              "plane_tilt_x": ("plane tilt ω_x", "°", 1 / DEG),
              "plane_tilt_y": ("plane tilt ω_y", "°", 1 / DEG)}


def _shown(name: str, angles: bool) -> tuple[str, str, float]:
    sym, unit, *factor = PARAM_TEXT.get(name, (name, ""))
    f = factor[0] if factor else 1.0
    if angles and unit.endswith("rad"):                     # degrees throughout an angle study
        unit, f = unit[:-3] + "deg", f * (1 / DEG if unit == "rad" else DEG)
    return sym, unit, f


def param_text(name: str, value, se=None, *, angles: bool = False) -> str:
    """``"sym = value ± se unit"`` (value with 4 significant digits, trailing zeros dropped)."""
    sym, unit, f = _shown(name, angles)
    txt = f"{sym} = {num(value * f, 4, trim=True)}"
    if se is not None and math.isfinite(se):
        txt += f" ± {num(se * f, 2)}"
    return txt + (f" {unit}" if unit else "")


def params_text(values: dict, se: dict | None = None, *, symbols_only: bool = False,
                angles: bool = False) -> list[str]:
    """Each numeric parameter as :func:`param_text` (or its symbol only)."""
    se = se or {}
    ok = [(k, v) for k, v in values.items() if isinstance(v, (int, float)) and not isinstance(v, bool)]
    if symbols_only:
        return [PARAM_TEXT.get(k, (k, ""))[0] for k, _ in ok]
    return [param_text(k, v, se.get(k), angles=angles) for k, v in ok]
