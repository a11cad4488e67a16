"""Numba kernels of the joint-hysteresis laws (cause ``joint_hysteresis``).

**The candidate family** (both solvers; fitted by the diagnosis). Each joint
carries a hysteretic torque ``S`` in parallel with its spring,
``b θ̇ = F - τ(x) - S`` with ``x = θ - θ0`` its deflection. ``S`` is a stop
operator — Prandtl's elastic-perfectly-plastic element, a spring ``k_e`` in
series with a slider of threshold ``r`` (Brokate & Sprekels, *Hysteresis and
Phase Transitions*, Springer 1996, Ch. 2; Krasnosel'skii & Pokrovskii,
*Systems with Hysteresis*, 1989) — whose threshold depends on the deflection,
as in the generalized play of Al Janaideh, Rakheja & Su (IEEE/ASME TMECH 16(4),
2011)::

    S <- clip(S + k_e dx, -r(|x|), r(|x|)),
    r(a) = h                                          (onset θ_h = 0)
    r(a) = h clip((a - (1 - ρ) θ_h) / (ρ θ_h), 0, 1)  (θ_h > 0), ρ = HYST_RAMP

Three parameters reach the three shapes of the hysteresis family:

* ``h`` alone (``θ_h = θ_y = 0``, ``k_e -> ∞``): the constant-width play,
  ``F ∈ [τ(x) - h, τ(x) + h]`` at rest — a joint holds until the torque on it
  changes by ``2h`` (the seed's ``hysteresis_torque``, unchanged bit for bit);
* ``θ_y = h / k_e > 0``: elastic-plastic loops with the spring's finite
  hardening. After a reversal the joint unloads elastically (tangent
  ``τ' + k_e``) over ``2 θ_y``, twice the virgin curve's elastic range
  (Masing's rule, Masing 1926), then follows the opposite branch. A single
  stop in parallel with a spring is the one-element Prandtl-Ishlinskii (Iwan
  1966) model;
* ``θ_h > 0``: the width grows from zero below ``(1 - ρ) θ_h`` to ``2h``
  beyond ``θ_h``: flag-shaped loops confined to large deflections (the plateau
  of a superelastic flexure) with no residual bend at zero load.

The stop is kept consistent with its moving threshold by ``k_e >= |r'|``
(``θ_y`` is at most ``ρ θ_h``): then the stop's output after any monotone
motion from ``(x0, S0)`` is ``clip(S0 + k_e (x - x0), -r, r)`` in closed form,
so that the fast solver's exact relaxation (:func:`hyst_relax`) and rest state
(:func:`hyst_rest`) agree with the reference solver's small steps. Along a
monotone motion the total torque ``τ(x) + S`` is piecewise linear; its kinks
are the spring's breaks, the threshold's and the point where the stop starts
to slip, crossed at their exact times.

**Laws of the hidden-effect generator** (reference solver only; no analysis
fits them, so a diagnosis cannot win by reproducing them):

* Bouc-Wen (Bouc 1967; Wen, J. Eng. Mech. Div. ASCE 102, 1976), ``n = 1``,
  ``β = γ``: a torque ``z`` with ``dz = dx (A - (β sgn(dx z) + γ)|z|)``,
  ``β = γ = A / (2 z_u)``: smooth elastic-plastic loops, ultimate torque
  ``z_u``, elastic unloading at stiffness ``A`` (:func:`bouc_wen_step`);
* a two-branch superelastic flexure (phase-fraction kinetics after Auricchio,
  Taylor & Lubliner, CMAME 146, 1997, linear hardening): the spring's plateau
  is a transformation of fraction ``ξ``; it advances at the loading plateau
  (the Fig. 17 law itself) and reverses ``gap`` lower; between them the joint
  is elastic (:func:`superelastic_torque`, :func:`superelastic_update`).
"""

from __future__ import annotations

import math

from numba import njit

from ._spring_kernels import spring_piece, spring_torque

#: Fraction of the onset over which the threshold of the stop grows (ρ).
HYST_RAMP = 0.5
#: Segments of a piecewise-linear law crossed in one relaxation or rest solve.
MAX_SEGMENTS = 32
#: A segment with no break ahead is linear to this distance [rad].
_FAR = 1.0
#: Breaks closer than this are the current point [rad].
_TOUCH = 1e-14


@njit(cache=True, inline="always")
def hyst_threshold(a, h, on):
    """Threshold ``r(a)`` [N m] at deflection magnitude ``a``: ``h`` when ``on <= 0``."""
    if on <= 0.0:
        return h
    lo = (1.0 - HYST_RAMP) * on
    if a <= lo:
        return 0.0
    if a >= on:
        return h
    return h * (a - lo) / (HYST_RAMP * on)


@njit(cache=True, inline="always")
def hyst_stiffness(h, on, y):
    """Elastic stiffness ``k_e = h / θ_y`` of the stop [N m/rad]; ``inf`` (the play) for ``θ_y <= 0``.

    ``θ_y`` is limited to ``ρ θ_h`` so that ``k_e`` is at least the threshold's slope.
    """
    if y <= 0.0 or h <= 0.0:
        return math.inf
    if on > 0.0 and y > HYST_RAMP * on:
        y = HYST_RAMP * on
    return h / y


@njit(cache=True, inline="always")
def hyst_rate_torque(q, x, S, ke, h, on):
    """``b θ̇`` from ``q = F - τ(x)``: the play's dead zone ``|q| <= r(|x|)``, or ``q - S`` (stop)."""
    if ke == math.inf:
        r = hyst_threshold(abs(x), h, on)
        if q > r:
            return q - r
        if q < -r:
            return q + r
        return 0.0
    return q - S


@njit(cache=True, inline="always")
def hyst_direction(q, x, S, ke, h, on):
    """Direction of motion (+1, -1) or 0 (the joint holds) for ``q = F - τ(x)``."""
    v = hyst_rate_torque(q, x, S, ke, h, on)
    if v > 0.0:
        return 1
    if v < 0.0:
        return -1
    return 0


@njit(cache=True, inline="always")
def hyst_branch(x, x0, S0, d, ke, h, on):
    """Hysteretic torque at ``x`` reached monotonically (direction ``d``) from ``(x0, S0)``."""
    r = hyst_threshold(abs(x), h, on)
    if ke == math.inf:
        return d * r
    u = S0 + ke * (x - x0)
    if u > r:
        return r
    if u < -r:
        return -r
    return u


@njit(cache=True, inline="always")
def hyst_state(x, x0, S0, d, ke, h, on):
    """The stop's state after moving to ``x`` (0 for the play, which has none)."""
    if ke == math.inf:
        return 0.0
    return hyst_branch(x, x0, S0, d, ke, h, on)


@njit(cache=True, inline="always")
def _law(x, x0, S0, d, ke, h, on, k1, k2, k3, tm, ts, s):
    """Total torque ``τ(x) + S`` along the monotone motion [N m]."""
    return spring_torque(x, k1, k2, k3, tm, ts, s) + hyst_branch(x, x0, S0, d, ke, h, on)


@njit(cache=True)
def _next_break(x, x0, S0, d, ke, h, on, tm, ts):
    """Distance from ``x`` in direction ``d`` to the law's next kink (``inf`` if none) [rad]."""
    best = math.inf
    for b in (tm, -tm, ts, -ts):
        dist = d * (b - x)
        if _TOUCH < dist < best:
            best = dist
    if on > 0.0:
        lo = (1.0 - HYST_RAMP) * on
        for b in (lo, -lo, on, -on):
            dist = d * (b - x)
            if _TOUCH < dist < best:
                best = dist
    if ke < math.inf:
        # where the elastic stop reaches its threshold and starts to slip
        phi0 = d * (S0 + ke * (x - x0)) - hyst_threshold(abs(x), h, on)
        if phi0 < 0.0:
            span = best if best < _FAR else _FAR
            x1 = x + d * span
            phi1 = d * (S0 + ke * (x1 - x0)) - hyst_threshold(abs(x1), h, on)
            if phi1 > 0.0:
                sat = span * (-phi0) / (phi1 - phi0)
                if sat > _TOUCH:   # a slip point closer than that: the stop slips here already
                    best = sat
    return best


@njit(cache=True)
def hyst_relax(x0, S0, F, bd, t, d, ke, h, on, k1, k2, k3, tm, ts, s):
    """Exact ``x(t)`` of ``bd ẋ = F - τ(x) - S`` moving in direction ``d`` from ``(x0, S0)``, ``F`` held.

    Within one linear piece of the law the motion is an exponential toward
    that piece's virtual equilibrium (or away from it on a falling piece);
    pieces are crossed at their exact times (as :func:`notchfit.physics._friction_kernels.relax`).
    """
    x = x0
    for _ in range(MAX_SEGMENTS):
        g = _law(x, x0, S0, d, ke, h, on, k1, k2, k3, tm, ts, s)
        rem = F - g
        if d * rem <= 0.0:
            return x
        nb = _next_break(x, x0, S0, d, ke, h, on, tm, ts)
        span = nb if nb < _FAR else _FAR
        xm = x + d * 0.5 * span
        k = (_law(xm, x0, S0, d, ke, h, on, k1, k2, k3, tm, ts, s) - g) / (xm - x)
        xb = x + d * nb
        if abs(k) > 1e-12:
            xv = x + rem / k
            if nb == math.inf or (k > 0.0 and d * (xb - xv) >= 0.0):
                return xv + (x - xv) * math.exp(-k * t / bd)
            tb = bd / k * math.log((x - xv) / (xb - xv))
            if tb >= t:
                return xv + (x - xv) * math.exp(-k * t / bd)
        else:
            rate = rem / bd
            if nb == math.inf:
                return x + rate * t
            tb = nb / abs(rate)
            if tb >= t:
                return x + rate * t
        t -= tb
        x = xb
    return x


@njit(cache=True, inline="always")
def _threshold_piece(x, on):
    """Piece of the threshold holding ``x``: 0 where it is 0 (inside ``(1 - ρ) θ_h``), ±1 on the ramp,
    ±2 where it is ``h`` (beyond ``θ_h``; sign of ``x``); always 2 without an onset."""
    if on <= 0.0:
        return 2
    a = abs(x)
    if a <= (1.0 - HYST_RAMP) * on:
        return 0
    sg = 1 if x > 0.0 else -1
    return sg if a < on else 2 * sg


@njit(cache=True)
def hyst_relax_target(x0, S0, F, d, ke, h, on, k1, k2, k3, tm, ts, s):
    """The one-exponential case of :func:`hyst_relax`: ``(x*, K, piece)`` when the motion from ``x0``
    toward the virtual equilibrium ``x*`` of the law's linear piece at ``x0`` (slope ``K``) stays on
    that piece — the spring's piece and the threshold's, the stop slipping or the play — so that
    ``x(t) = x* + (x0 - x*) e^{-K t / b}``; ``piece`` is the spring's (0/1/2: ``K = s k1, s k2, s k3``)
    when the threshold is constant there, else -1. ``(NaN, 0, -1)`` when the motion crosses pieces."""
    r0 = hyst_threshold(abs(x0), h, on)
    if ke < math.inf and S0 * d < r0:
        return math.nan, 0.0, -1                     # the stop is elastic: several pieces
    sp = spring_piece(x0, tm, ts)
    tp = _threshold_piece(x0, on)
    a = abs(sp)
    K = s * (k1 if a == 0 else (k2 if a == 1 else k3))
    ramp = tp == 1 or tp == -1
    if ramp:
        K += d * tp * h / (HYST_RAMP * on)
    if K <= 0.0:
        return math.nan, 0.0, -1
    xs = x0 + (F - spring_torque(x0, k1, k2, k3, tm, ts, s) - d * r0) / K
    if spring_piece(xs, tm, ts) != sp or _threshold_piece(xs, on) != tp:
        return math.nan, 0.0, -1
    return xs, K, (-1 if ramp else a)


@njit(cache=True)
def hyst_rest(x0, S0, F, d, ke, h, on, k1, k2, k3, tm, ts, s):
    """First rest point ``τ(x) + S(x) = F`` in direction ``d`` from ``(x0, S0)`` (the relaxation's limit)."""
    x = x0
    for _ in range(MAX_SEGMENTS):
        g = _law(x, x0, S0, d, ke, h, on, k1, k2, k3, tm, ts, s)
        rem = F - g
        if d * rem <= 0.0:
            return x
        nb = _next_break(x, x0, S0, d, ke, h, on, tm, ts)
        span = nb if nb < _FAR else _FAR
        x1 = x + d * span
        g1 = _law(x1, x0, S0, d, ke, h, on, k1, k2, k3, tm, ts, s)
        if d * (F - g1) <= 0.0:
            return x + (x1 - x) * rem / (g1 - g)
        if nb == math.inf and d * (g1 - g) > 0.0:
            return x + (x1 - x) * rem / (g1 - g)
        x = x1
    return x


# ----------------------------------------------------------------------------- generator laws
@njit(cache=True, inline="always")
def bouc_wen_step(z, dx, A, zu):
    """Bouc-Wen torque after a deflection increment ``dx`` (``n = 1``, ``β = γ = A / (2 z_u)``) [N m]."""
    if A <= 0.0 or zu <= 0.0:
        return 0.0
    beta = A / (2.0 * zu)
    p = dx * z
    sg = 1.0 if p > 0.0 else (-1.0 if p < 0.0 else 0.0)
    return z + dx * (A - beta * (sg + 1.0) * abs(z))


@njit(cache=True, inline="always")
def superelastic_torque(x, xi, k1, k2, k3, tm, ts, s):
    """Two-branch superelastic flexure ``τ(x, ξ) = s (k1 (x - x_L ξ) + (k3 - k1)(|x| - ts)_+ sgn x)`` [N m].

    ``x_L = (ts - tm)(1 - k2/k1)`` makes the loading branch the Fig. 17 law:
    the plateau (rate ``k2`` from ``tm`` to ``ts``) is the transformation of
    ``ξ`` from 0 to 1 (signed with the bending direction); the stop is the slot
    closing (``k3``).
    """
    xl = (ts - tm) * (1.0 - k2 / k1)
    a = abs(x)
    extra = (k3 - k1) * (a - ts) if a > ts else 0.0
    sg = 1.0 if x >= 0.0 else -1.0
    return s * (k1 * (x - xl * xi) + sg * extra)


@njit(cache=True, inline="always")
def superelastic_update(x, xi, gap, k1, k2, k3, tm, ts, s):
    """Signed martensite fraction after the joint moved to ``x`` (rate independent).

    Forward transformation where the elastic torque reaches the loading plateau
    ``s (k1 tm + k2 (ts - tm) |ξ|)``, reverse where it falls ``gap`` below it
    (``gap`` is limited to ``0.9 s k1 tm``, so the reverse transformation ends
    before the joint straightens: no residual bend at zero load).
    """
    sg = 1.0 if x >= 0.0 else -1.0
    a = abs(xi) if xi * sg >= 0.0 else 0.0
    g = min(gap, 0.9 * s * k1 * tm) / s
    ax = abs(x)
    extra = (k3 - k1) * (ax - ts) if ax > ts else 0.0
    den = k1 * (ts - tm)
    te = k1 * (ax - (ts - tm) * (1.0 - k2 / k1) * a) + extra
    tf = k1 * tm + k2 * (ts - tm) * a
    if te > tf:
        a = max(a, min((k1 * ax + extra - k1 * tm) / den, 1.0))
    elif te < tf - g:
        a = min(a, max((k1 * ax + extra - k1 * tm + g) / den, 0.0))
    return sg * a
