"""The estimation core under ``identify`` and ``diagnose``: parameter specs, observations, least squares."""

from .specs import (BASELINE, BASELINE_MU_EXCESS, CAPSTAN_MU, MATERIAL, MATERIAL_BASELINE, ParamSpec, StudyScales,
                    baseline_specs)

__all__ = ["BASELINE", "BASELINE_MU_EXCESS", "CAPSTAN_MU", "MATERIAL", "MATERIAL_BASELINE", "ParamSpec",
           "StudyScales", "baseline_specs"]
