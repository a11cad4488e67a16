"""Numba kernels of the friction simulator (Sec. IV-B); see :mod:`notchfit.physics.friction`.

Everything here works on plain float64 arrays. Parameters are packed in one
vector ``par`` (indices ``P_*`` below) and a per-joint table ``J`` (rows
``J_*``: spring rates, breaks and scale, damping, rest angle, the two tendons'
moment arms; :meth:`notchfit.physics.friction_params.FrictionParams.joint_table`).
Indices are 0-based: joint ``i`` is the paper's joint ``i + 1``; link ``i``
(``i = 0..n-2``) lies between joints ``i`` and ``i + 1`` (the paper's link
``i + 1``); the tension profile ``T[i]`` is the cable tension where it
crosses joint ``i`` (``T[0]`` = base tension).

Cable states: ``+1`` sliding toward the base, ``-1`` sliding toward the tip,
``0`` sticking (as in ``SimulationResult``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._hysteresis_kernels import (bouc_wen_step, hyst_direction, hyst_rate_torque, hyst_relax, hyst_relax_target,
                                  hyst_rest, hyst_state, hyst_stiffness, hyst_threshold, superelastic_torque,
                                  superelastic_update)
from ._spring_kernels import spring_angle, spring_mag, spring_piece, spring_torque  # noqa: F401 (re-exported)

# ---- packed parameter vector (the spring and damping entries hold joint 1's values; the
# kernels read every joint's own from the per-joint table ``J``)
(P_K1, P_K2, P_K3, P_TM, P_TS, P_MUD, P_MUS, P_B, P_VTHR, P_BETA, P_H, P_FX, P_FZ, P_RX,
 P_LAW, P_UNI, P_ARMU, P_HON, P_HY, P_BWZ, P_BWA, P_SEG) = range(22)
N_PAR = 22
# P_H, P_HON, P_HY: the joint-hysteresis family (threshold, onset, yield angle;
# :mod:`notchfit.physics._hysteresis_kernels`); P_BWZ, P_BWA, P_SEG: the generator's Bouc-Wen
# torque and stiffness and superelastic gap (reference solver only)
#: friction laws (``P_LAW``): the seed's per-link channel law, the capstan law of a lumen tendon
LAW_CHANNEL, LAW_CAPSTAN = 0, 1

# ---- per-joint table ``J`` (rows, one column per joint): unscaled spring rates and breaks
# (Fig. 17 form), stiffness scale, damping b_j [N m s/rad], rest angle θ0_j [rad], moment
# arms of the right and left tendons [m], and the straight-configuration vector (x, z) from
# joint j's pivot to joint j+1's (to the tool point for the last joint) [m], for tip loads
J_K1, J_K2, J_K3, J_TM, J_TS, J_S, J_B, J_TH0, J_AR, J_AL, J_DX, J_DZ = range(12)
N_J = 12

# relative slack on the stick test |ΔT| <= μ_s N (1 + slack): lets a link stick when N = 0
# (straight joints) or μ_s == μ_d, where the paper's strict |ΔT| < μ_s N can never hold
STICK_SLACK = 1e-9
LAND_SLACK = 1e-6


@njit(cache=True, inline="always")
def slide_next(T0, sa, sb, mu, state):
    """``T[j+1]`` of a sliding link from ``T[j+1] = T[j] ∓ μ (T[j+1] sb + T[j] sa)``.

    ``state = +1`` (toward the base): ``T[j+1] = T[j] (1 - μ sa)/(1 + μ sb)``;
    ``state = -1`` (toward the tip): ``T[j+1] = T[j] (1 + μ sa)/(1 - μ sb)``.
    ``sa = |sin θ_j|``, ``sb = |sin θ_{j+1}|``.
    """
    if state > 0:
        return T0 * (1.0 - mu * sa) / (1.0 + mu * sb)
    return T0 * (1.0 + mu * sa) / (1.0 - mu * sb)


@njit(cache=True, inline="always")
def slide_law(T0, sa, sb, mu, state, law):
    """``T[j+1]`` of a sliding link under either friction law.

    Channel law (:func:`slide_next`; ``sa``, ``sb`` = ``|sin θ|``). Capstan law
    (``sa``, ``sb`` = ``|θ|``, the wrap angles): the tendon wraps half of each
    joint's angle at each of the two cut edges between the gaps of joints
    ``j`` and ``j+1``, so ``T[j+1] = T[j] exp(∓μ (|θ_j| + |θ_{j+1}|)/2)``
    (Euler–Eytelwein capstan equation; ``state = +1`` toward the base).
    """
    if law == LAW_CHANNEL:
        return slide_next(T0, sa, sb, mu, state)
    if state > 0:
        return T0 * math.exp(-mu * 0.5 * (sa + sb))
    return T0 * math.exp(mu * 0.5 * (sa + sb))


@njit(cache=True, inline="always")
def stick_ok(Ta, Tb, sa, sb, fac, law):
    """A sliding link may stick: ``|T_b - T_a| <= fac N`` (channel) or
    ``T_a e^{-fac w} <= T_b <= T_a e^{fac w}``, ``w = (sa + sb)/2`` (capstan)."""
    if law == LAW_CHANNEL:
        N = Tb * sb + Ta * sa
        return abs(Tb - Ta) <= fac * N
    w = 0.5 * (sa + sb)
    return Ta * math.exp(-fac * w) <= Tb <= Ta * math.exp(fac * w)


@njit(cache=True, inline="always")
def slip_dir(Ta, Tb, sa, sb, mus, law):
    """A sticking link breaks away: +1 toward the base, -1 toward the tip, 0 it holds
    (``|ΔT| > μ_s N``, channel; ``T_b`` outside ``T_a e^{±μ_s w}``, capstan)."""
    if law == LAW_CHANNEL:
        dT = Tb - Ta
        N = Tb * sb + Ta * sa
        if -dT > mus * N:
            return 1
        if dT > mus * N:
            return -1
        return 0
    w = 0.5 * (sa + sb)
    if Tb < Ta * math.exp(-mus * w):
        return 1
    if Tb > Ta * math.exp(mus * w):
        return -1
    return 0


@njit(cache=True, inline="always")
def stick_margin(Ta, Tb, sa, sb, mus, law):
    """Distance of a sticking link from break-away [N] (< 0: it slips)."""
    if law == LAW_CHANNEL:
        N = Tb * sb + Ta * sa
        return mus * N - abs(Tb - Ta)
    w = 0.5 * (sa + sb)
    return min(Tb - Ta * math.exp(-mus * w), Ta * math.exp(mus * w) - Tb)


@njit(cache=True, inline="always")
def wrap_measure(th, law):
    """``|sin θ|`` (channel law's normal-force factor) or ``|θ|`` (capstan wrap angle)."""
    if law == LAW_CHANNEL:
        return abs(math.sin(th))
    return abs(th)


@njit(cache=True)
def tip_torques(theta, dx, dz, fx, fz, out):
    """``J_X(θ)^T (f_x, f_z, 0)`` (Eqs. 18-20) into ``out`` [N m], for any pivot chain.

    ``(d_x, d_z)_i`` is the straight-configuration vector from joint ``i``'s pivot
    to the next (to the tool point for the last joint), turned by ``φ_i = Σ_{l≤i} θ_l``
    (``R_y``: ``(d_x cos φ + d_z sin φ, -d_x sin φ + d_z cos φ)``); the lever
    ``L_k = Σ_{i≥k} R(φ_i) d_i`` from joint ``k`` to the tool point gives
    ``τ_k = L_k,z f_x - L_k,x f_z``. On the seed tube (``d = (0, p)``) this is the
    paper's ``J_xk = p Σ_{i≥k} cos φ_i``, ``J_zk = -p Σ_{i≥k} sin φ_i``.
    """
    n = theta.shape[0]
    phi = 0.0
    cphi = np.empty(n)
    sphi = np.empty(n)
    for i in range(n):
        phi += theta[i]
        cphi[i] = math.cos(phi)
        sphi[i] = math.sin(phi)
    uniform = True                      # the seed's chain: the paper's sums, bit for bit
    for i in range(n):
        if dx[i] != 0.0 or dz[i] != dz[0]:
            uniform = False
            break
    lx = 0.0
    lz = 0.0
    for i in range(n - 1, -1, -1):
        if uniform:
            lx += sphi[i]
            lz += cphi[i]
            out[i] = dz[0] * lz * fx - dz[0] * lx * fz
        else:
            lx += dx[i] * cphi[i] + dz[i] * sphi[i]
            lz += dz[i] * cphi[i] - dx[i] * sphi[i]
            out[i] = lz * fx - lx * fz


@njit(cache=True, inline="always")
def band_update(tb, tm, ebeta, embeta):
    """Play operator of the proximal capstan band on ``log T`` (multiplicative bounds)."""
    lo = tm * embeta
    hi = tm * ebeta
    if tb < lo:
        return lo
    if tb > hi:
        return hi
    return tb


@njit(cache=True)
def _hysteretic_states(th, thd, dt, J, h, hon, ke, stop_on, hS, bw_on, bwa, bwz, bwz_t, se_on, seg, xi):
    """Advance the joints' hysteretic states by one Euler increment ``dt θ̇`` (reference solver)."""
    for i in range(th.shape[0]):
        dev = th[i] - J[J_TH0, i]
        dx = dt * thd[i]
        if stop_on:
            r = hyst_threshold(abs(dev), h, hon)
            hS[i] = min(max(hS[i] + ke * dx, -r), r)
        if bw_on:
            bwz_t[i] = bouc_wen_step(bwz_t[i], dx, bwa, bwz)
        if se_on:
            xi[i] = superelastic_update(dev, xi[i], seg, J[J_K1, i], J[J_K2, i], J[J_K3, i], J[J_TM, i],
                                        J[J_TS, i], J[J_S, i])


@njit(cache=True)
def reference_kernel(t_s, TLm, TRm, par, J, dt_max, ramp_time, settle_time):
    """The paper's four-step algorithm, explicit Euler (Sec. IV-B).

    Input protocol: before ``t_s[0]`` the model starts at rest (θ = 0, zero
    tension, all sticking) at ``t_s[0] - settle_time``; in every interval
    ``[t_{k-1}, t_k]`` the measured tensions move linearly from sample
    ``k-1`` to sample ``k`` during the first ``min(ramp_time, interval)``
    seconds and are held until ``t_k`` (``ramp_time <= 0``: a step).
    The step in each interval is ``interval / ceil(interval / dt_max)`` and
    the input used for the step from ``t`` to ``t + dt`` is its value at
    ``t + dt``.

    Per joint (the table ``J``): spring rates and breaks, scale, damping,
    rest angle ``θ0_j`` (the spring acts on ``θ_j - θ0_j``; the start is at
    rest, ``θ = θ0``) and the tendons' moment arms (drive
    ``a_R,j T_R[j] - a_L,j T_L[j]``; cable speed through link ``j``
    ``v_c[j] = s_c Σ_{k>j} a_c,k θ̇_k``). ``par[P_LAW]`` selects the channel or
    the capstan law (:func:`slide_law`). Joint hysteresis: the play or stop of
    :mod:`notchfit.physics._hysteresis_kernels` (the stop's state advanced by each
    Euler increment), and the generator's Bouc-Wen torque and superelastic
    flexure (explicit in the same increments).

    Returns per sample: θ (S, n), tension profiles L, R (S, n), base tensions
    after the band L, R (S,), the last slip direction of each link during
    the interval L, R (S, n-1) int8, and the number of steps taken.
    """
    S = t_s.shape[0]
    n = J.shape[1]
    mud, mus, vthr = par[P_MUD], par[P_MUS], par[P_VTHR]
    beta, h, fx, fz, rx = par[P_BETA], par[P_H], par[P_FX], par[P_FZ], par[P_RX]
    law = int(par[P_LAW])
    armu = par[P_ARMU] != 0.0
    ebeta = math.exp(beta)
    embeta = math.exp(-beta)
    use_tip = fx != 0.0 or fz != 0.0
    stick_fac = mus * (1.0 + STICK_SLACK)
    hon = par[P_HON]
    ke = hyst_stiffness(h, hon, par[P_HY])
    stop_on = h > 0.0 and ke < math.inf
    bwz, bwa, seg = par[P_BWZ], par[P_BWA], par[P_SEG]
    bw_on = bwz > 0.0 and bwa > 0.0
    se_on = seg > 0.0

    th = J[J_TH0].copy()
    thd = np.zeros(n)
    TL = np.zeros(n)
    TR = np.zeros(n)
    sL = np.zeros(max(n - 1, 0), np.int8)
    sR = np.zeros(max(n - 1, 0), np.int8)
    lastL = np.zeros(max(n - 1, 0), np.int8)
    lastR = np.zeros(max(n - 1, 0), np.int8)
    sinabs = np.zeros(n)
    tip = np.zeros(n)
    hS = np.zeros(n)       # the stop's torque
    bwz_t = np.zeros(n)    # Bouc-Wen torque
    xi = np.zeros(n)       # superelastic martensite fraction (signed)
    tbL = 0.0
    tbR = 0.0

    o_th = np.empty((S, n))
    o_TL = np.empty((S, n))
    o_TR = np.empty((S, n))
    o_bL = np.empty(S)
    o_bR = np.empty(S)
    o_sL = np.empty((S, max(n - 1, 0)), np.int8)
    o_sR = np.empty((S, max(n - 1, 0)), np.int8)
    nsteps_total = 0

    for k in range(S):
        if k == 0:
            t0 = t_s[0] - settle_time
            aL, aR = 0.0, 0.0
        else:
            t0 = t_s[k - 1]
            aL, aR = TLm[k - 1], TRm[k - 1]
        interval = t_s[k] - t0
        bL, bR = TLm[k], TRm[k]
        nst = int(math.ceil(interval / dt_max - 1e-9))
        if nst < 1:
            nst = 1
        dt = interval / nst
        ramp = min(ramp_time, interval)
        for i in range(n - 1):
            lastL[i] = 0
            lastR[i] = 0
        for it in range(nst):
            # ---- input at the end of the step (linear ramp, then hold)
            if ramp <= 0.0:
                frac = 1.0
            else:
                frac = (it + 1) * dt / ramp
                if frac > 1.0:
                    frac = 1.0
            mL = aL + (bL - aL) * frac
            mR = aR + (bR - aR) * frac
            if beta > 0.0:
                if k == 0 and it == 0:
                    tbL, tbR = mL, mR
                tbL = band_update(tbL, mL, ebeta, embeta)
                tbR = band_update(tbR, mR, ebeta, embeta)
            else:
                tbL, tbR = mL, mR
            # ---- Step 1: tension propagation, base to tip
            for i in range(n):
                sinabs[i] = wrap_measure(th[i], law)
            TL[0] = tbL
            TR[0] = tbR
            for i in range(n - 1):
                if sL[i] != 0:
                    TL[i + 1] = slide_law(TL[i], sinabs[i], sinabs[i + 1], mud, sL[i], law)
                if sR[i] != 0:
                    TR[i + 1] = slide_law(TR[i], sinabs[i], sinabs[i + 1], mud, sR[i], law)
            # ---- Step 2: first-order dynamics
            if use_tip:
                tip_torques(th, J[J_DX], J[J_DZ], fx, fz, tip)
            for i in range(n):
                if armu:
                    x = rx * (TR[i] - TL[i])
                else:
                    x = J[J_AR, i] * TR[i] - J[J_AL, i] * TL[i]
                dev = th[i] - J[J_TH0, i]
                if se_on:
                    x -= superelastic_torque(dev, xi[i], J[J_K1, i], J[J_K2, i], J[J_K3, i],
                                             J[J_TM, i], J[J_TS, i], J[J_S, i])
                else:
                    x -= spring_torque(dev, J[J_K1, i], J[J_K2, i], J[J_K3, i],
                                       J[J_TM, i], J[J_TS, i], J[J_S, i])
                if bw_on:
                    x -= bwz_t[i]
                if use_tip:
                    x += tip[i]
                if h > 0.0:
                    x = hyst_rate_torque(x, dev, hS[i], ke, h, hon)
                thd[i] = x / J[J_B, i]
            # ---- Step 3 + Step 4: cable speeds and the stick/slip state machine
            ssum = 0.0
            ssumL = 0.0
            for i in range(n - 2, -1, -1):
                if armu:
                    ssum += thd[i + 1]
                    vR = rx * ssum
                    vL = -vR
                else:
                    ssum += J[J_AR, i + 1] * thd[i + 1]
                    ssumL += J[J_AL, i + 1] * thd[i + 1]
                    vR = ssum
                    vL = -ssumL
                # right cable
                if sR[i] != 0:
                    if abs(vR) < vthr and stick_ok(TR[i], TR[i + 1], sinabs[i], sinabs[i + 1], stick_fac, law):
                        sR[i] = 0
                else:
                    sR[i] = slip_dir(TR[i], TR[i + 1], sinabs[i], sinabs[i + 1], mus, law)
                # left cable
                if sL[i] != 0:
                    if abs(vL) < vthr and stick_ok(TL[i], TL[i + 1], sinabs[i], sinabs[i + 1], stick_fac, law):
                        sL[i] = 0
                else:
                    sL[i] = slip_dir(TL[i], TL[i + 1], sinabs[i], sinabs[i + 1], mus, law)
                if sL[i] != 0:
                    lastL[i] = sL[i]
                if sR[i] != 0:
                    lastR[i] = sR[i]
            # ---- explicit Euler update (and the hysteretic states over the same increments)
            for i in range(n):
                th[i] += dt * thd[i]
            if stop_on or bw_on or se_on:
                _hysteretic_states(th, thd, dt, J, h, hon, ke, stop_on, hS, bw_on, bwa, bwz, bwz_t,
                                   se_on, seg, xi)
        nsteps_total += nst
        for i in range(n):
            o_th[k, i] = th[i]
            o_TL[k, i] = TL[i]
            o_TR[k, i] = TR[i]
        o_bL[k] = tbL
        o_bR[k] = tbR
        for i in range(n - 1):
            o_sL[k, i] = lastL[i]
            o_sR[k, i] = lastR[i]
    return o_th, o_TL, o_TR, o_bL, o_bR, o_sL, o_sR, nsteps_total


# --------------------------------------------------------------------------
# fast solver
# --------------------------------------------------------------------------
@njit(cache=True)
def relax(th0, y, b, h, k1, k2, k3, tm, ts, s):
    """Exact ``θ(h)`` of ``b dθ/dt = y - τ(θ)`` from ``θ(0) = th0`` (τ piecewise linear).

    Within one spring segment the motion is an exponential toward that
    segment's virtual equilibrium; segment boundaries are crossed at their
    exact times. Unconditionally stable (the hard stop's b/k = 3 ms is no
    limit on the step).
    """
    target = spring_angle(y, k1, k2, k3, tm, ts, s)
    th = th0
    t = h
    for _ in range(8):
        if th == target:
            return th
        d = 1.0 if target > th else -1.0
        x = abs(th)
        sgn = 1.0 if (th > 0.0 or (th == 0.0 and d > 0.0)) else -1.0
        if d == sgn:  # moving away from 0
            if x < tm:
                k, bnd = k1, tm
            elif x < ts:
                k, bnd = k2, ts
            else:
                k, bnd = k3, -1.0
        else:
            if x > ts:
                k, bnd = k3, ts
            elif x > tm:
                k, bnd = k2, tm
            else:
                k, bnd = k1, 0.0
        k *= s
        thv = th + (y - spring_torque(th, k1, k2, k3, tm, ts, s)) / k
        if bnd < 0.0:
            return thv + (th - thv) * math.exp(-k * t / b)
        bth = sgn * bnd
        if (thv - bth) * d <= 0.0:
            return thv + (th - thv) * math.exp(-k * t / b)
        tb = b / k * math.log((th - thv) / (bth - thv))
        if tb >= t:
            return thv + (th - thv) * math.exp(-k * t / b)
        t -= tb
        th = bth
    return th


@njit(cache=True, inline="always")
def drive_target(F, tq, hyst):
    """Target torque of the (dead-zone) joint dynamics, or NaN if the joint holds.

    ``b θ̇ = F - τ`` without hysteresis; with a play-operator hysteresis
    ``h``: ``b θ̇ = F - τ ∓ h`` outside the band ``|F - τ| <= h``, 0 inside.
    """
    if hyst <= 0.0:
        return F
    x = F - tq
    if x > hyst:
        return F - hyst
    if x < -hyst:
        return F + hyst
    return math.nan


# rows of the per-configuration table of the fast solver
G_SIN, G_TIP, G_TAU, G_FB, G_FT, G_IB, G_IT = range(7)


@njit(cache=True)
def _geometry_terms(th, par, J, G):
    """Everything that depends on θ alone, for the passes at a frozen configuration.

    Rows of ``G`` (7, n): ``s_j`` (:func:`wrap_measure`), tip-load torque,
    spring torque ``τ_j(θ_j - θ0_j)``, and the factors of the slide law:
    channel ``1 - μ_d s``, ``1 + μ_d s``, ``1/(1 + μ_d s)``, ``1/(1 - μ_d s)``
    (``s = |sin θ_j|``); capstan ``e^{-μ_d s/2}``, ``e^{μ_d s/2}`` (twice each,
    ``s = |θ_j|``), so that both laws propagate as ``T[j+1] = T[j] F_j I_{j+1}``.
    """
    n = th.shape[0]
    mud = par[P_MUD]
    for i in range(n):
        G[G_TAU, i] = spring_torque(th[i] - J[J_TH0, i], J[J_K1, i], J[J_K2, i], J[J_K3, i],
                                    J[J_TM, i], J[J_TS, i], J[J_S, i])
        G[G_TIP, i] = 0.0
    if par[P_LAW] == LAW_CHANNEL:
        for i in range(n):
            sa = abs(math.sin(th[i]))
            G[G_SIN, i] = sa
            fb = 1.0 - mud * sa
            ft = 1.0 + mud * sa
            d = 1.0 / (fb * ft)
            G[G_FB, i] = fb
            G[G_FT, i] = ft
            G[G_IB, i] = fb * d
            G[G_IT, i] = ft * d
    else:
        for i in range(n):
            sa = abs(th[i])
            G[G_SIN, i] = sa
            fb = math.exp(-0.5 * mud * sa)
            ft = math.exp(0.5 * mud * sa)
            G[G_FB, i] = fb
            G[G_FT, i] = ft
            G[G_IB, i] = fb
            G[G_IT, i] = ft
    if par[P_FX] != 0.0 or par[P_FZ] != 0.0:
        tip_torques(th, J[J_DX], J[J_DZ], par[P_FX], par[P_FZ], G[G_TIP])


@njit(cache=True)
def _forces(TL, TR, sL, sR, tbL, tbR, par, J, ibd, G, F, thd, v, vL, th, hS):
    """Steps 1-3 at a configuration ``th`` (its table ``G``, the stops' torques ``hS``):
    tension propagation, drive torques ``F``, rates, cable speeds. ``v[i]``, ``vL[i]``: the
    right and left cables' speeds through link ``i`` (``ibd`` = ``1/b_j``)."""
    n = TL.shape[0]
    hyst, rx = par[P_H], par[P_RX]
    hon = par[P_HON]
    ke = hyst_stiffness(hyst, hon, par[P_HY])
    armu = par[P_ARMU] != 0.0
    TL[0] = tbL
    TR[0] = tbR
    for i in range(n - 1):
        if sL[i] > 0:
            TL[i + 1] = TL[i] * G[G_FB, i] * G[G_IB, i + 1]
        elif sL[i] < 0:
            TL[i + 1] = TL[i] * G[G_FT, i] * G[G_IT, i + 1]
        if sR[i] > 0:
            TR[i + 1] = TR[i] * G[G_FB, i] * G[G_IB, i + 1]
        elif sR[i] < 0:
            TR[i + 1] = TR[i] * G[G_FT, i] * G[G_IT, i + 1]
    if armu:
        for i in range(n):
            F[i] = rx * (TR[i] - TL[i]) + G[G_TIP, i]
    else:
        for i in range(n):
            F[i] = J[J_AR, i] * TR[i] - J[J_AL, i] * TL[i] + G[G_TIP, i]
    for i in range(n):
        x = F[i] - G[G_TAU, i]
        if hyst > 0.0:
            x = hyst_rate_torque(x, th[i] - J[J_TH0, i], hS[i], ke, hyst, hon)
        thd[i] = x * ibd[i]
    ssum = 0.0
    ssumL = 0.0
    if armu:
        for i in range(n - 2, -1, -1):
            ssum += thd[i + 1]
            v[i] = rx * ssum
            vL[i] = -v[i]
    else:
        for i in range(n - 2, -1, -1):
            ssum += J[J_AR, i + 1] * thd[i + 1]
            ssumL += J[J_AL, i + 1] * thd[i + 1]
            v[i] = ssum
            vL[i] = -ssumL


@njit(cache=True)
def _state_machine(TL, TR, sL, sR, sinabs, v, vLs, mus, vthr, law, lastL, lastR, flags,
                   phiL, phiR, TLp, TRp):
    """Step 4 (the paper's rules, as in :func:`reference_kernel`).

    ``flags[0]`` = some link went from sticking to sliding, ``flags[1]`` =
    some link is sliding afterwards, ``flags[2]`` = a frozen tension was
    corrected. A link that sticks with ``phi[i] >= 0`` (its speed crossed
    ``v_thr`` at the fraction ``phi`` of the last step) freezes the tension
    it had then, ``Tp + phi (T - Tp)``, instead of the one at the step's end.
    """
    m = sL.shape[0]
    stick_fac = mus * (1.0 + STICK_SLACK)
    slipped = 0
    anyslide = 0
    corrected = 0
    for i in range(m):
        vR = v[i]
        vL = vLs[i]
        if sR[i] != 0:
            if abs(vR) < vthr and stick_ok(TR[i], TR[i + 1], sinabs[i], sinabs[i + 1], stick_fac, law):
                sR[i] = 0
                if phiR[i] >= 0.0:
                    TR[i + 1] = TRp[i + 1] + phiR[i] * (TR[i + 1] - TRp[i + 1])
                    corrected = 1
        else:
            sR[i] = slip_dir(TR[i], TR[i + 1], sinabs[i], sinabs[i + 1], mus, law)
            if sR[i] != 0:
                slipped = 1
        if sL[i] != 0:
            if abs(vL) < vthr and stick_ok(TL[i], TL[i + 1], sinabs[i], sinabs[i + 1], stick_fac, law):
                sL[i] = 0
                if phiL[i] >= 0.0:
                    TL[i + 1] = TLp[i + 1] + phiL[i] * (TL[i + 1] - TLp[i + 1])
                    corrected = 1
        else:
            sL[i] = slip_dir(TL[i], TL[i + 1], sinabs[i], sinabs[i + 1], mus, law)
            if sL[i] != 0:
                slipped = 1
        if sL[i] != 0:
            lastL[i] = sL[i]
            anyslide = 1
        if sR[i] != 0:
            lastR[i] = sR[i]
            anyslide = 1
        phiL[i] = -1.0
        phiR[i] = -1.0
    flags[0] = slipped
    flags[1] = anyslide
    flags[2] = corrected


@njit(cache=True)
def _advance(th, F, tau, h, par, J, out, hS, hS_out):
    """Every joint by the exact relaxation over ``h`` with its drive ``F`` held.

    The spring acts on ``θ - θ0`` (the rest angle). Fast path: when the
    target lies on the same piece of the spring law as ``θ`` the motion is
    one exponential, ``θ* + (θ - θ*) e^{-k h/b}`` (with ``par[P_UNI]`` — every
    joint with the same law and damping — the three decay factors are shared
    by all joints of unit scale); otherwise :func:`relax` crosses the breaks
    at their exact times. A hysteresis with an onset or a yield angle moves by
    :func:`notchfit.physics._hysteresis_kernels.hyst_relax` (its stops' torques
    ``hS`` -> ``hS_out``); otherwise the stops hold no state.
    """
    n = th.shape[0]
    hyst = par[P_H]
    if hyst > 0.0 and (par[P_HON] > 0.0 or par[P_HY] > 0.0):
        _advance_hyst(th, F, tau, h, par, J, out, hS, hS_out)
        return
    for i in range(n):
        hS_out[i] = hS[i]
    if par[P_UNI] != 0.0:
        _advance_uniform(th, F, tau, h, hyst, J, out)
        return
    for i in range(n):
        k1, k2, k3, tm, ts = J[J_K1, i], J[J_K2, i], J[J_K3, i], J[J_TM, i], J[J_TS, i]
        s, bd, th0 = J[J_S, i], J[J_B, i], J[J_TH0, i]
        y = drive_target(F[i], tau[i], hyst)
        if math.isnan(y):
            out[i] = th[i]
            continue
        x = spring_angle(y, k1, k2, k3, tm, ts, s)
        target = th0 + x
        dev = th[i] - th0
        seg = spring_piece(dev, tm, ts)
        if seg == spring_piece(x, tm, ts):
            a = abs(seg)
            kk = k1 if a == 0 else (k2 if a == 1 else k3)
            e = math.exp(-kk * s * h / bd)
            out[i] = target + (th[i] - target) * e
        else:
            out[i] = th0 + relax(dev, y, bd, h, k1, k2, k3, tm, ts, s)


@njit(cache=True)
def _advance_hyst(th, F, tau, h, par, J, out, hS, hS_out):
    """:func:`_advance` with the hysteresis family's stops (exact piecewise-exponential relaxation:
    one exponential when the motion stays on one piece of the law, with the decay factors shared by
    the joints of unit scale when every joint has the same law, else the piece-by-piece walk)."""
    hyst, hon = par[P_H], par[P_HON]
    ke = hyst_stiffness(hyst, hon, par[P_HY])
    uni = par[P_UNI] != 0.0
    e = np.empty(3)
    if uni:
        e[0] = math.exp(-J[J_K1, 0] * h / J[J_B, 0])
        e[1] = math.exp(-J[J_K2, 0] * h / J[J_B, 0])
        e[2] = math.exp(-J[J_K3, 0] * h / J[J_B, 0])
    for i in range(th.shape[0]):
        th0 = J[J_TH0, i]
        x0 = th[i] - th0
        d = hyst_direction(F[i] - tau[i], x0, hS[i], ke, hyst, hon)
        if d == 0:
            out[i] = th[i]
            hS_out[i] = hS[i]
            continue
        k1, k2, k3, tm, ts, s, bd = J[J_K1, i], J[J_K2, i], J[J_K3, i], J[J_TM, i], J[J_TS, i], J[J_S, i], J[J_B, i]
        xs, K, piece = hyst_relax_target(x0, hS[i], F[i], d, ke, hyst, hon, k1, k2, k3, tm, ts, s)
        if K > 0.0:
            f = e[piece] if (uni and s == 1.0 and piece >= 0) else math.exp(-K * h / bd)
            x1 = xs + (x0 - xs) * f
        else:
            x1 = hyst_relax(x0, hS[i], F[i], bd, h, d, ke, hyst, hon, k1, k2, k3, tm, ts, s)
        out[i] = th0 + x1
        hS_out[i] = hyst_state(x1, x0, hS[i], d, ke, hyst, hon)


@njit(cache=True)
def _advance_uniform(th, F, tau, h, hyst, J, out):
    """:func:`_advance` when every joint has the same law and damping (the seed tube):
    the three decay factors are computed once and shared by the joints of unit scale."""
    n = th.shape[0]
    k1, k2, k3, tm, ts, bd = J[J_K1, 0], J[J_K2, 0], J[J_K3, 0], J[J_TM, 0], J[J_TS, 0], J[J_B, 0]
    e1 = math.exp(-k1 * h / bd)
    e2 = math.exp(-k2 * h / bd)
    e3 = math.exp(-k3 * h / bd)
    for i in range(n):
        s = J[J_S, i]
        th0 = J[J_TH0, i]
        y = drive_target(F[i], tau[i], hyst)
        if math.isnan(y):
            out[i] = th[i]
            continue
        x = spring_angle(y, k1, k2, k3, tm, ts, s)
        dev = th[i] - th0
        seg = spring_piece(dev, tm, ts)
        if seg == spring_piece(x, tm, ts):
            a = abs(seg)
            if s == 1.0:
                e = e1 if a == 0 else (e2 if a == 1 else e3)
            else:
                kk = k1 if a == 0 else (k2 if a == 1 else k3)
                e = math.exp(-kk * s * h / bd)
            target = th0 + x
            out[i] = target + (th[i] - target) * e
        else:
            out[i] = th0 + relax(dev, y, bd, h, k1, k2, k3, tm, ts, s)


@njit(cache=True)
def _margins(T, st, sinabs, v, mus, vthr, law, g):
    """Event functions per link: sticking -> :func:`stick_margin` (``μ_s N - |ΔT|``
    for the channel law; slips when < 0); sliding -> ``|v| - v_thr`` (sticks when < 0)."""
    n = T.shape[0]
    for i in range(n - 1):
        if st[i] == 0:
            g[i] = stick_margin(T[i], T[i + 1], sinabs[i], sinabs[i + 1], mus, law)
        else:
            g[i] = abs(v[i]) - vthr


@njit(cache=True, inline="always")
def _cross_fraction(v0, v1, vthr):
    """Fraction of a step at which a speed decaying from ``v0`` to ``v1`` (> 0) crosses
    ``vthr``, interpolating ``log v`` (exact for an exponential decay)."""
    if v1 > 0.0 and v0 > v1:
        return math.log(v0 / vthr) / math.log(v0 / v1)
    return (v0 - vthr) / (v0 - v1)


@njit(cache=True)
def _settle(th, TL, TR, par, J, out, work, tol, maxiter, hS, hS_out):
    """Rest state with every link sticking (all tensions frozen).

    Per joint ``τ(θ) = F`` (or the play operator ``θ ∈ [τ⁻¹(F - h), τ⁻¹(F + h)]``
    nearest to the current ``θ``; with an onset or a yield angle the first rest
    point of :func:`notchfit.physics._hysteresis_kernels.hyst_rest`, the stops' torques
    ``hS`` -> ``hS_out``); the tip-load torques depend on the whole
    configuration and are iterated to a fixed point (``tol`` [rad], ``maxiter``).
    """
    n = th.shape[0]
    hyst, fx, fz, rx = par[P_H], par[P_FX], par[P_FZ], par[P_RX]
    hon = par[P_HON]
    ke = hyst_stiffness(hyst, hon, par[P_HY])
    family = hyst > 0.0 and (hon > 0.0 or par[P_HY] > 0.0)
    armu = par[P_ARMU] != 0.0
    use_tip = fx != 0.0 or fz != 0.0
    for i in range(n):
        out[i] = th[i]
        work[i] = 0.0
        hS_out[i] = hS[i]
    for it in range(maxiter):
        if use_tip:
            tip_torques(out, J[J_DX], J[J_DZ], fx, fz, work)
        delta = 0.0
        for i in range(n):
            if armu:
                F = rx * (TR[i] - TL[i]) + work[i]
            else:
                F = J[J_AR, i] * TR[i] - J[J_AL, i] * TL[i] + work[i]
            k1, k2, k3, tm, ts, s, th0 = (J[J_K1, i], J[J_K2, i], J[J_K3, i], J[J_TM, i], J[J_TS, i],
                                          J[J_S, i], J[J_TH0, i])
            if family:
                x0 = th[i] - th0
                d = hyst_direction(F - spring_torque(x0, k1, k2, k3, tm, ts, s), x0, hS[i], ke, hyst, hon)
                new = th[i]
                if d != 0:
                    x1, K, _ = hyst_relax_target(x0, hS[i], F, d, ke, hyst, hon, k1, k2, k3, tm, ts, s)
                    if not K > 0.0:
                        x1 = hyst_rest(x0, hS[i], F, d, ke, hyst, hon, k1, k2, k3, tm, ts, s)
                    new = th0 + x1
                    hS_out[i] = hyst_state(x1, x0, hS[i], d, ke, hyst, hon)
            elif hyst > 0.0:
                lo = th0 + spring_angle(F - hyst, k1, k2, k3, tm, ts, s)
                hi = th0 + spring_angle(F + hyst, k1, k2, k3, tm, ts, s)
                new = min(max(th[i], lo), hi)
            else:
                new = th0 + spring_angle(F, k1, k2, k3, tm, ts, s)
            delta = max(delta, abs(new - out[i]))
            out[i] = new
        if not use_tip or delta <= tol:
            return it + 1
    return maxiter


@njit(cache=True)
def fast_kernel(t_s, TLm, TRm, par, J, ramp_time, settle_time, h_min, h_max, growth,
                max_events, max_micro, settle_tol, settle_maxiter, land_sticks, dth_max, order):
    """Same model and input protocol as :func:`reference_kernel`, in large exact steps.

    The whole history from the initial rest state (θ = θ0, zero tension, every
    link sticking, ``settle_time`` before the first sample): :func:`fast_intervals`
    from that state.
    """
    n = J.shape[1]
    m = max(n - 1, 0)
    th = J[J_TH0].copy()
    return fast_intervals(t_s, TLm, TRm, t_s[0] - settle_time, 0.0, 0.0, True, th, np.zeros(n), np.zeros(n),
                          np.zeros(m, np.int8), np.zeros(m, np.int8), np.zeros(2), np.zeros(n), par, J, ramp_time,
                          h_min, h_max, growth, max_events, max_micro, settle_tol, settle_maxiter, land_sticks, dth_max,
                          order)


@njit(cache=True)
def fast_intervals(t_s, TLm, TRm, t_prev, prev_left, prev_right, first, th, TL, TR, sL, sR, band, hS, par, J,
                   ramp_time, h_min, h_max, growth, max_events, max_micro, settle_tol, settle_maxiter,
                   land_sticks, dth_max, order):
    """The fast solver from a given state over the intervals ending at the samples ``t_s``.

    The state — joint angles ``th``, tension profiles ``TL``, ``TR`` (n), the
    links' stick/slip states ``sL``, ``sR`` (n-1, int8), the base tensions
    after the proximal band ``band`` (2: left, right) and the hysteresis
    stops' torques ``hS`` (n; the play holds none) — is read and updated in
    place, so that consecutive calls continue one history exactly (the
    real-time predictor, :class:`notchfit.physics.predictor.Predictor`). The first
    interval starts at ``t_prev`` with the measured tensions ``prev_left``,
    ``prev_right``; ``first``: it is the history's first (the band starts at
    the first input).

    * Steps 1-4 are the reference's, in the reference's order (tensions from
      the previous states, then the state machine), so a slip front advances
      one link per pass as in the reference. Right after a link slips, the
      passes are repeated with θ frozen until no link slips any more: the
      reference's dt -> 0 limit of its front (its front takes n dt).
    * Between passes every joint moves by the exact solution of
      ``b θ̇ = F - τ(θ)`` with its drive ``F`` held over the step
      (piecewise exponential: stable for any step, exact once all tensions
      are frozen); the coupling through sliding tensions is explicit
      (``order = 1``) or corrected with the drive's mean over the step
      (``order = 2``). The step grows geometrically from ``h_min`` after each
      change of the input; while a link slides it is at most ``h_max`` and no
      joint may move more than ``dth_max`` [rad] in it.
    * Events inside a step (a sticking link reaching ``|ΔT| = μ_s N``, a
      sliding link's speed falling to ``v_thr``) are located by linear
      interpolation of their margins between the step's ends, and the step
      is shortened to land on the first (at most ``max_events`` times per
      interval; then events act at step ends). ``max_micro`` caps the frozen
      passes per interval (chattering stick-slip as joints straighten).
      With ``land_sticks = False`` a speed event does not shorten the step;
      the link freezes the tension it had at the interpolated crossing.
    * Once every link sticks and the input is held, the rest state is solved
      in closed form (:func:`_settle`) unless a sticking link would slip there
      (``settle_tol < 0`` disables this shortcut, for tests).
    """

    S = t_s.shape[0]
    n = J.shape[1]
    m = max(n - 1, 0)
    mus, vthr, beta = par[P_MUS], par[P_VTHR], par[P_BETA]
    law = int(par[P_LAW])
    ibd = 1.0 / J[J_B]
    h_micro_min = 1e-6
    use_tip = par[P_FX] != 0.0 or par[P_FZ] != 0.0
    ebeta = math.exp(beta)
    embeta = math.exp(-beta)

    lastL = np.zeros(m, np.int8)
    lastR = np.zeros(m, np.int8)
    G = np.zeros((7, n))
    F = np.zeros(n)
    thd = np.zeros(n)
    v = np.zeros(m)
    vL = np.zeros(m)
    gL = np.zeros(m)
    gR = np.zeros(m)
    flags = np.zeros(3, np.int64)
    phiL = np.full(m, -1.0)
    phiR = np.full(m, -1.0)
    TLp = np.zeros(n)
    TRp = np.zeros(n)
    # trial state
    th_e = np.zeros(n)
    hS_e = np.zeros(n)
    hS_s = np.zeros(n)
    TL_e = np.zeros(n)
    TR_e = np.zeros(n)
    G_e = np.zeros((7, n))
    sin_s = np.zeros(n)
    F_e = np.zeros(n)
    Fa = np.zeros(n)
    thd_e = np.zeros(n)
    v_e = np.zeros(m)
    vL_e = np.zeros(m)
    gL_e = np.zeros(m)
    gR_e = np.zeros(m)
    work = np.zeros(n)
    tbL = band[0]
    tbR = band[1]

    o_th = np.empty((S, n))
    o_TL = np.empty((S, n))
    o_TR = np.empty((S, n))
    o_bL = np.empty(S)
    o_bR = np.empty(S)
    o_sL = np.empty((S, m), np.int8)
    o_sR = np.empty((S, m), np.int8)
    nsteps_total = 0

    for k in range(S):
        if k == 0:
            t0 = t_prev
            aL, aR = prev_left, prev_right
        else:
            t0 = t_s[k - 1]
            aL, aR = TLm[k - 1], TRm[k - 1]
        interval = t_s[k] - t0
        bL, bR = TLm[k], TRm[k]
        ramp = max(min(ramp_time, interval), 0.0)
        for i in range(m):
            lastL[i] = 0
            lastR[i] = 0
        t = 0.0
        hnom = h_min
        nev = 0
        nmicro = 0
        fresh = False  # the arrays hold Steps 1-3 at the current state and input
        while t < interval:
            in_ramp = ramp > 0.0 and t < ramp
            # ---- input (measured tension at the end of the step) and the proximal band
            if in_ramp:
                h = min(hnom, h_max, ramp / 50.0, ramp - t)
                frac = (t + h) / ramp
            else:
                h = min(hnom, interval - t)
                frac = 1.0
            mL = aL + (bL - aL) * frac
            mR = aR + (bR - aR) * frac
            if beta > 0.0:
                if first and k == 0 and t == 0.0:
                    tbL, tbR = mL, mR
                tbL = band_update(tbL, mL, ebeta, embeta)
                tbR = band_update(tbR, mR, ebeta, embeta)
            else:
                tbL, tbR = mL, mR
            # ---- Steps 1-3
            if not fresh:
                _geometry_terms(th, par, J, G)
                _forces(TL, TR, sL, sR, tbL, tbR, par, J, ibd, G, F, thd, v, vL, th, hS)
            # ---- Step 4, repeated with θ frozen while links keep slipping
            _state_machine(TL, TR, sL, sR, G[G_SIN], v, vL, mus, vthr, law, lastL, lastR, flags,
                           phiL, phiR, TLp, TRp)
            while flags[0] == 1 and nmicro < max_micro:
                nmicro += 1
                nsteps_total += 1
                _forces(TL, TR, sL, sR, tbL, tbR, par, J, ibd, G, F, thd, v, vL, th, hS)
                _state_machine(TL, TR, sL, sR, G[G_SIN], v, vL, mus, vthr, law, lastL, lastR, flags,
                               phiL, phiR, TLp, TRp)
            if flags[0] == 1 or flags[2] == 1:
                # cap reached (slipped links take their law) or frozen tensions corrected
                _forces(TL, TR, sL, sR, tbL, tbR, par, J, ibd, G, F, thd, v, vL, th, hS)
            # ---- rest state in closed form once everything sticks
            if not in_ramp and flags[1] == 0 and settle_tol >= 0.0:
                _settle(th, TL, TR, par, J, th_e, work, settle_tol, settle_maxiter, hS, hS_s)
                ok = True
                for i in range(n):
                    sin_s[i] = wrap_measure(th_e[i], law)
                for i in range(m):
                    if slip_dir(TL[i], TL[i + 1], sin_s[i], sin_s[i + 1], mus, law) != 0:
                        ok = False
                    if slip_dir(TR[i], TR[i + 1], sin_s[i], sin_s[i + 1], mus, law) != 0:
                        ok = False
                if ok:
                    for i in range(n):
                        th[i] = th_e[i]
                        hS[i] = hS_s[i]
                    nsteps_total += 1
                    break
            # ---- trial step, event location (h_max bounds the step while a link
            # slides: the explicit tension coupling; with every tension frozen
            # the relaxation is exact (up to the weak tip-load coupling, a
            # contraction) and the step may grow on)
            if flags[1] == 1:
                h = min(h, h_max)
                rmax = 0.0
                for i in range(n):
                    rmax = max(rmax, abs(thd[i]))
                if rmax * h > dth_max:
                    h = max(dth_max / rmax, h_micro_min)
            _advance(th, F, G[G_TAU], h, par, J, th_e, hS, hS_e)
            fresh = False
            if not in_ramp:
                for i in range(n):
                    TL_e[i] = TL[i]
                    TR_e[i] = TR[i]
                _geometry_terms(th_e, par, J, G_e)
                _forces(TL_e, TR_e, sL, sR, tbL, tbR, par, J, ibd, G_e, F_e, thd_e, v_e, vL_e, th_e, hS_e)
                correct = order == 2 and (flags[1] == 1 or use_tip)
                if correct:
                    # corrector: the drive's mean over the step (trapezoid), then re-evaluate
                    for i in range(n):
                        Fa[i] = 0.5 * (F[i] + F_e[i])
                    _advance(th, Fa, G[G_TAU], h, par, J, th_e, hS, hS_e)
                    for i in range(n):
                        TL_e[i] = TL[i]
                        TR_e[i] = TR[i]
                    _geometry_terms(th_e, par, J, G_e)
                    _forces(TL_e, TR_e, sL, sR, tbL, tbR, par, J, ibd, G_e, F_e, thd_e, v_e, vL_e, th_e, hS_e)
                phi = 1.0
                if nev < max_events:
                    _margins(TL, sL, G[G_SIN], vL, mus, vthr, law, gL)
                    _margins(TR, sR, G[G_SIN], v, mus, vthr, law, gR)
                    _margins(TL_e, sL, G_e[G_SIN], vL_e, mus, vthr, law, gL_e)
                    _margins(TR_e, sR, G_e[G_SIN], v_e, mus, vthr, law, gR_e)
                    # sticking -> sliding events: shorten the step to land on the first;
                    # sliding -> sticking: remember where v crossed v_thr (frozen tension)
                    for i in range(m):
                        if gL_e[i] < 0.0 and gL[i] > 0.0:
                            if sL[i] == 0 or land_sticks:
                                phi = min(phi, gL[i] / (gL[i] - gL_e[i]))
                            else:
                                phiL[i] = _cross_fraction(gL[i] + vthr, gL_e[i] + vthr, vthr)
                        if gR_e[i] < 0.0 and gR[i] > 0.0:
                            if sR[i] == 0 or land_sticks:
                                phi = min(phi, gR[i] / (gR[i] - gR_e[i]))
                            else:
                                phiR[i] = _cross_fraction(gR[i] + vthr, gR_e[i] + vthr, vthr)
                if phi < 1.0:
                    nev += 1
                    h = h * phi * (1.0 + LAND_SLACK)
                    if correct:
                        for i in range(n):
                            Fa[i] = F[i] + 0.5 * phi * (F_e[i] - F[i])
                        _advance(th, Fa, G[G_TAU], h, par, J, th_e, hS, hS_e)
                    else:
                        _advance(th, F, G[G_TAU], h, par, J, th_e, hS, hS_e)
                    for i in range(m):
                        phiL[i] = -1.0
                        phiR[i] = -1.0
                else:
                    fresh = True
                    for i in range(n):
                        TLp[i] = TL[i]
                        TRp[i] = TR[i]
            for i in range(n):
                th[i] = th_e[i]
                hS[i] = hS_e[i]
            if fresh:
                for i in range(n):
                    TL[i] = TL_e[i]
                    TR[i] = TR_e[i]
                    F[i] = F_e[i]
                    thd[i] = thd_e[i]
                    for r in range(7):
                        G[r, i] = G_e[r, i]
                for i in range(m):
                    v[i] = v_e[i]
                    vL[i] = vL_e[i]
            t += h
            nsteps_total += 1
            if h >= hnom:
                hnom = hnom * growth
        for i in range(n):
            o_th[k, i] = th[i]
            o_TL[k, i] = TL[i]
            o_TR[k, i] = TR[i]
        o_bL[k] = tbL
        o_bR[k] = tbR
        for i in range(m):
            o_sL[k, i] = lastL[i]
            o_sR[k, i] = lastR[i]
    band[0] = tbL
    band[1] = tbR
    return o_th, o_TL, o_TR, o_bL, o_bR, o_sL, o_sR, nsteps_total
