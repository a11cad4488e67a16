"""Which parameters do the data determine? A verdict from the Fisher information.

A least-squares fit with Jacobian ``J`` (residuals divided by their σ) has
Fisher information ``F = Jᵀ J`` and, near its optimum, covariance ``F⁻¹``
(Bates & Watts, *Nonlinear Regression Analysis and Its Applications*, 1988,
Sec. 2.3). A parameter the data do not pin down shows in two ways: its
standard error is large against the range it could take, and it lies along
a direction in which ``F`` is nearly singular (Raue et al., "Structural and
practical identifiability analysis of partially observed dynamical models by
exploiting the profile likelihood", Bioinformatics 25(15), 2009, call these
*practically non-identifiable*). Such a number must not be printed as
"0.117 ± 4.8": it is fixed at its prior and reported as undetermined.

:func:`assess` works on the Jacobian in the parameters' own scales (the width
of their physical bounds), so that a modulus in Pa and a friction coefficient
compare; it returns an :class:`Identifiability` with one verdict per parameter
that prints its own summary.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Identifiability", "ParameterVerdict", "assess"]

#: verdicts, from best to worst
DETERMINED, WEAK, UNDETERMINED = "determined", "weakly determined", "not determined"


@dataclass(frozen=True)
class ParameterVerdict:
    """What the data say about one parameter.

    Attributes
    ----------
    name : str
    value : float
        The fitted value [its unit].
    se : float
        Standard error from the Fisher information (inf where it is singular) [its unit].
    scale : float
        The range it could take (its bounds' width) [its unit].
    relative_se : float
        ``se / scale``: 1 means the data allow anything within the bounds.
    null_weight : float
        Share (0-1) of the parameter in the near-null directions of the information:
        1 when the data cannot tell it from a combination of the others.
    verdict : str
        ``"determined"``, ``"weakly determined"`` or ``"not determined"``.
    """

    name: str
    value: float
    se: float
    scale: float
    relative_se: float
    null_weight: float
    verdict: str

    @property
    def determined(self) -> bool:
        return self.verdict != UNDETERMINED


@dataclass(frozen=True)
class Identifiability:
    """The verdict on every parameter of a fit, and the information's conditioning.

    Attributes
    ----------
    parameters : tuple of ParameterVerdict
    condition : float
        Condition number of the scaled Fisher information (inf when singular).
    """

    parameters: tuple[ParameterVerdict, ...]
    condition: float

    def undetermined(self) -> list[str]:
        """Names of the parameters the data do not determine (to be fixed at their priors)."""
        return [p.name for p in self.parameters if not p.determined]

    def __getitem__(self, name: str) -> ParameterVerdict:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def summary(self) -> str:
        """One line per parameter: value ± SE where determined, the verdict otherwise."""
        lines = [f"Identifiability (condition number of the scaled information {self.condition:.3g})"]
        for p in self.parameters:
            if p.determined:
                lines.append(f"  {p.name:>20} = {p.value:.4g} ± {p.se:.2g}  ({p.verdict})")
            else:
                spread = ("unbounded" if not np.isfinite(p.relative_se)
                          else f"{p.relative_se:.0%} of its range")
                lines.append(f"  {p.name:>20}: not determined by these data (SE {spread}); fixed at its prior")
        return "\n".join(lines)

    def as_dict(self) -> dict:
        return {"condition": self.condition,
                "parameters": {p.name: {"verdict": p.verdict, "se": p.se, "relative_se": p.relative_se,
                                        "null_weight": p.null_weight} for p in self.parameters}}


def assess(jacobian, names, values, scales, *, weak_se: float = 0.1, max_se: float = 0.5,
           null_ratio: float = 1e-10, null_weight_max: float = 0.25) -> Identifiability:
    """Identifiability of each parameter from the Jacobian of the weighted residuals.

    Parameters
    ----------
    jacobian : array_like (N, p)
        ``∂r/∂x`` of the residuals divided by their σ (dimensionless), one column per parameter.
    names : sequence of str (p,)
    values : array_like (p,)
        Fitted values [their units].
    scales : array_like (p,)
        The range each parameter could take (its bounds' width, > 0) [its unit].
    weak_se : float
        ``se / scale`` above which a parameter is only weakly determined.
    max_se : float
        ``se / scale`` above which it is not determined (the data leave half its range open).
    null_ratio : float
        An eigenvalue of the scaled information below ``null_ratio`` times the largest marks a
        near-null direction (1e-10: beyond what double-precision finite differences resolve).
    null_weight_max : float
        A parameter whose squared share in the near-null directions exceeds this is not determined
        (two parameters seen only as their sum share one such direction half and half).

    Returns
    -------
    Identifiability
    """
    J = np.asarray(jacobian, dtype=float)
    x = np.asarray(values, dtype=float)
    s = np.asarray(scales, dtype=float)
    if J.ndim != 2 or J.shape[1] != len(names) or x.shape != (len(names),) or s.shape != (len(names),):
        raise ValueError(f"jacobian (N, p), names, values and scales must agree; got {J.shape}, "
                         f"{len(names)}, {x.shape}, {s.shape}")
    if not np.all(s > 0):
        raise ValueError("scales must be > 0")
    Js = J * s                                          # derivatives per unit of each range
    Js = np.where(np.isfinite(Js), Js, 0.0)
    _, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    top = sv[0] if sv.size and sv[0] > 0 else 0.0
    # the information is sv², so a singular value ratio of sqrt(null_ratio) is an information ratio of null_ratio
    null = sv <= np.sqrt(null_ratio) * top if top > 0 else np.ones_like(sv, dtype=bool)
    cond = float(sv[0] ** 2 / sv[-1] ** 2) if top > 0 and sv[-1] > 0 else float("inf")
    weight = np.sum(Vt[null] ** 2, axis=0) if null.any() else np.zeros(len(names))
    keep = ~null
    cov_scaled = (Vt[keep].T / sv[keep] ** 2) @ Vt[keep] if keep.any() else np.zeros((len(names),) * 2)
    rel = np.sqrt(np.clip(np.diag(cov_scaled), 0.0, None))
    rel = np.where(weight > null_weight_max, np.inf, rel)       # its spread along a null direction is unbounded
    out = []
    for i, n in enumerate(names):
        if weight[i] > null_weight_max or rel[i] > max_se:
            verdict = UNDETERMINED
        elif rel[i] > weak_se:
            verdict = WEAK
        else:
            verdict = DETERMINED
        out.append(ParameterVerdict(str(n), float(x[i]), float(rel[i] * s[i]), float(s[i]), float(rel[i]),
                                    float(weight[i]), verdict))
    return Identifiability(tuple(out), cond)
