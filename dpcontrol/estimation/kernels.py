"""Compiled per-step kernels of the MMAE bank, its band likelihood and the Bayes weights.

Each kernel is the arithmetic of one stage of :class:`~dpcontrol.estimation.wave_filter.BankWaveFilter`
or :class:`~dpcontrol.estimation.weighting.BandLikelihood`, written as loops over the bank (see
:mod:`dpbase.jit` for why: 8 models × 15 states are too small for numpy's per-call cost). The classes
keep the configuration, validation, persistence and the decisions made once per step in Python; a
step is four kernel calls.

Notation (as the classes): N models, n states per model (15 with wave states, 9 without), the state
``x`` of every model in vessel-parallel coordinates about the frame heading ψ_f (seed 002 eq. (14)),
the measurement matrix H (3, n), innovations ``ε_i = y_p − H x̄_i`` (seed 002 eq. (51)), weights p_i
(seed 000 eq. (16)).
"""

from __future__ import annotations

import math

import numpy as np

from dpbase.frames import ssa_compiled as ssa
from dpbase.jit import UniTuple, f8, f8_1d, f8_2d, f8_3d, i8, kernel, void

TWO_PI = 2.0 * math.pi
NO_INDEX = -1   # an index argument for a block the model does not have (no wave states)

# Pattern bits of dpcontrol.estimation.kalman.pattern_code: north 1, east 2, heading 4
_POSITION_BITS = 3
_HEADING_BIT = 4

# Columns of band_update's per-group statistics array (2, len(GROUP_FIELDS)): its state (the first six,
# persisted), then constants
GROUP_FIELDS = ("weight_sum", "wf_mean", "wf_weight", "wf_time_s", "wf_energy", "wf_share",
                "noise", "prior", "scale_time_s", "share_time_s", "lf_excess_limit", "dt_s")
(G_WEIGHT_SUM, G_WF_MEAN, G_WF_WEIGHT, G_WF_TIME, G_WF_ENERGY, G_WF_SHARE,
 G_NOISE, G_PRIOR, G_SCALE_TIME, G_SHARE_TIME, G_LF_EXCESS_LIMIT, G_DT) = range(len(GROUP_FIELDS))


@kernel(UniTuple(f8, 3)(f8_2d, f8_2d, i8))
def model_measurement(x: np.ndarray, H: np.ndarray, i: int) -> tuple[float, float, float]:
    """``H x_i`` of model i: its predicted measurement (vessel-parallel) [m, m, rad]; x (N, n), H (3, n)."""
    y0 = y1 = y2 = 0.0
    for j in range(x.shape[1]):
        xj = x[i, j]
        y0 += H[0, j] * xj
        y1 += H[1, j] * xj
        y2 += H[2, j] * xj
    return y0, y1, y2


@kernel(void(f8_2d, f8_2d, f8_1d, f8_2d, f8, f8, f8_1d, f8_1d))
def bank_predicted_measurement(x: np.ndarray, H: np.ndarray, p: np.ndarray, S9: np.ndarray, c: float, s: float,
                               mean_ned: np.ndarray, var_ned: np.ndarray) -> None:
    """The bank's predicted measurement and innovation variance in NED (seed 000 eq. (16) for the mean).

    With the models' predictions ŷ_i = H x̄_i (vessel-parallel), m = Σ p_i ŷ_i, the spread
    C = Σ p_i (ŷ_i − m)(ŷ_i − m)ᵀ and S̄ = Σ p_i S_i, the mixture's innovation covariance is S̄ + C; its NED
    diagonal is diag(R (S̄ + C) Rᵀ) with R = R(ψ_f) on the north/east block.

    Parameters
    ----------
    x : (N, n) prior states; H : (3, n); p : (N,) weights; S9 : (N, 9) innovation covariances S_i (row-major)
    c, s : cos ψ_f, sin ψ_f
    mean_ned : (3,) out — ŷ in NED [m, m, rad], heading wrapped
    var_ned : (3,) out — innovation variance diagonal in NED [m², m², rad²]
    """
    N = x.shape[0]
    m0 = m1 = m2 = 0.0
    for i in range(N):
        y0, y1, y2 = model_measurement(x, H, i)
        m0 += p[i] * y0
        m1 += p[i] * y1
        m2 += p[i] * y2
    c00 = c01 = c11 = c22 = 0.0
    s00 = s01 = s10 = s11 = s22 = 0.0
    for i in range(N):
        y0, y1, y2 = model_measurement(x, H, i)   # (recomputed: cheaper than a work array's dispatch)
        d0, d1, d2 = y0 - m0, y1 - m1, y2 - m2
        w = p[i]
        c00 += w * d0 * d0
        c01 += w * d0 * d1
        c11 += w * d1 * d1
        c22 += w * d2 * d2
        s00 += w * S9[i, 0]
        s01 += w * S9[i, 1]
        s10 += w * S9[i, 3]
        s11 += w * S9[i, 4]
        s22 += w * S9[i, 8]
    a00, a11, a22, cross = s00 + c00, s11 + c11, s22 + c22, s01 + s10 + 2.0 * c01
    var_ned[0] = c * c * a00 - c * s * cross + s * s * a11
    var_ned[1] = s * s * a00 + c * s * cross + c * c * a11
    var_ned[2] = a22
    mean_ned[0] = c * m0 - s * m1
    mean_ned[1] = s * m0 + c * m1
    mean_ned[2] = ssa(m2)


@kernel(f8(i8, f8_1d, f8, i8, i8, i8, i8, i8, f8_2d, f8_2d, f8_3d, f8_1d, f8_2d, f8_2d, f8_1d))
def bank_correct(code: int, y_ned: np.ndarray, psi_frame: float, heading: int, wf0: int, rot_start: int,
                 rot_blocks: int, flags: int, x: np.ndarray, H: np.ndarray, K: np.ndarray, p: np.ndarray,
                 x_post: np.ndarray, eps: np.ndarray, residual: np.ndarray) -> float:
    """Frame update and correction of every model with its steady-state gain (seed 002 eq. (51)).

    1. Frame heading ψ_f ← the measured heading, else the predicted total heading Σ p_i (ψ_i + ψ_w,i).
       Moving the frame by Δψ rotates every vessel-parallel vector of every model, ``v ← v·R(Δψ)``
       (rows ``rot_start + 3b``, ``+ 1`` for the ``rot_blocks`` 3-blocks), so the NED estimate is unchanged
       (seed 001: the ψ̇S terms in discrete form).
    2. ``y_p = [Rᵀ(ψ_f)(north, east), ψ]``, ``ε_i = y_p − H x̄_i`` on the measured channels (0 elsewhere);
       the yaw innovations are wrapped by whole turns, all models by the same turn count (their headings
       differ by far less than π).
    3. ``x̂_i = x̄_i + K_i ε_i``.
    4. The WF-share residual ``y − η̂_LF`` of the band likelihood: Σ p_i (ξ2_i + ε_i) (when ``flags`` & 1
       and the model has WF states).

    Parameters
    ----------
    code : int
        Measurement pattern (north 1, east 2, heading 4; 0: nothing measured — predict only).
    y_ned : (3,) measurement [m, m, rad] in NED (read on the measured channels only)
    psi_frame : float
        Frame heading before this step [rad].
    heading, wf0 : int
        Index of ψ in the state; first index of ξ2 (``NO_INDEX`` without wave states).
    rot_start, rot_blocks : int
        First index and number of the 3-blocks that turn with the frame.
    flags : int
        1: compute ``residual``.
    x : (N, n) prior states (rotated in place); H : (3, n); K : (N, n, 3) gains of the pattern; p : (N,)
    x_post : (N, n) out — corrected states (= x̄ when nothing is measured)
    eps : (N, 3) out — innovations, vessel-parallel, 0 on unmeasured channels
    residual : (3,) out — see 4.

    Returns
    -------
    float
        The new frame heading ψ_f [rad].
    """
    N, n = x.shape
    # 1. frame heading
    if code & _HEADING_BIT:
        psi_new = ssa(y_ned[2])
    else:
        total = 0.0
        for i in range(N):
            total += p[i] * x[i, heading]
        if wf0 != NO_INDEX:
            wf_total = 0.0
            for i in range(N):
                wf_total += p[i] * x[i, wf0 + 2]
            total += wf_total
        psi_new = ssa(total)
    dpsi = ssa(psi_new - psi_frame)
    if dpsi != 0.0:
        c = math.cos(dpsi)
        s = math.sin(dpsi)
        for i in range(N):
            for b in range(rot_blocks):
                k = rot_start + 3 * b
                a0 = x[i, k]
                a1 = x[i, k + 1]
                x[i, k] = a0 * c + a1 * s
                x[i, k + 1] = -a0 * s + a1 * c
    if code == 0:
        for i in range(N):
            for j in range(n):
                x_post[i, j] = x[i, j]
            eps[i, 0] = eps[i, 1] = eps[i, 2] = 0.0
        residual[0] = residual[1] = residual[2] = 0.0
        return psi_new
    # 2. innovations
    c = math.cos(psi_new)
    s = math.sin(psi_new)
    use_pos = (code & _POSITION_BITS) == _POSITION_BITS
    use_psi = (code & _HEADING_BIT) != 0
    yp0 = c * y_ned[0] + s * y_ned[1] if use_pos else 0.0
    yp1 = -s * y_ned[0] + c * y_ned[1] if use_pos else 0.0
    yp2 = y_ned[2] if use_psi else 0.0
    wrap = 0.0
    for i in range(N):
        y0, y1, y2 = model_measurement(x, H, i)
        if i == 0 and use_psi:
            raw = yp2 - y2
            wrap = ssa(raw) - raw
        eps[i, 0] = yp0 - y0 if use_pos else 0.0
        eps[i, 1] = yp1 - y1 if use_pos else 0.0
        eps[i, 2] = (yp2 - y2) + wrap if use_psi else 0.0
    # 3. correction
    for i in range(N):
        e0, e1, e2 = eps[i, 0], eps[i, 1], eps[i, 2]
        for j in range(n):
            x_post[i, j] = x[i, j] + (K[i, j, 0] * e0 + K[i, j, 1] * e1 + K[i, j, 2] * e2)
    # 4. residual for the WF share
    residual[0] = residual[1] = residual[2] = 0.0
    if (flags & 1) and wf0 != NO_INDEX:
        for i in range(N):
            w = p[i]
            residual[0] += w * (x[i, wf0] + eps[i, 0])
            residual[1] += w * (x[i, wf0 + 1] + eps[i, 1])
            residual[2] += w * (x[i, wf0 + 2] + eps[i, 2])
    return psi_new


@kernel(f8(f8_2d, f8_2d, f8_1d, f8_2d, f8, i8, i8, i8, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d, f8_1d))
def bank_outputs(x_post: np.ndarray, eps: np.ndarray, p: np.ndarray, P_post_diag: np.ndarray, psi_frame: float,
                 eta0: int, wf0: int, lf_start: int, omegas: np.ndarray, x_hat: np.ndarray, eta_hat_ned: np.ndarray,
                 lf_tail: np.ndarray, eta_wf_hat_ned: np.ndarray, covariance_diag: np.ndarray,
                 innovation_ned: np.ndarray) -> float:
    """The blended estimate and its outputs (seed 000 eq. (16); the mixture covariance diagonal).

    ``x̂ = Σ p_i x̂_i``; the heading states of every model are shifted by whole turns so that x̂'s heading
    stays near (−π, π] (the blend never averages across ±π). Outputs in NED: LF pose (heading wrapped),
    bias and ν (vessel-parallel/body, copied as they are), WF motion, ``Σ p_i (P_i + (x̂_i − x̂)²)`` and the
    weighted innovation ``Σ p_i ε_i``.

    Parameters
    ----------
    x_post : (N, n) corrected states (heading shifted in place); eps : (N, 3); p : (N,)
    P_post_diag : (N, n) posterior covariance diagonals of the pattern used
    psi_frame : float, frame heading [rad]
    eta0, wf0, lf_start : int
        Index of ηp, of ξ2 (``NO_INDEX`` without wave states) and of the 6 LF states [bias, ν].
    omegas : (N,) model peak frequencies [rad/s]
    x_hat, eta_hat_ned, lf_tail, eta_wf_hat_ned, covariance_diag, innovation_ned : out — (n,), (3,), (6,), (3,),
        (n,), (3,)

    Returns
    -------
    float
        Σ p_i ω_i [rad/s] (the weighted peak frequency of an MMAE bank).
    """
    N, n = x_post.shape
    heading = eta0 + 2
    for j in range(n):
        total = 0.0
        for i in range(N):
            total += p[i] * x_post[i, j]
        x_hat[j] = total
    turns = round(x_hat[heading] / TWO_PI)
    if turns != 0:
        shift = turns * TWO_PI
        for i in range(N):
            x_post[i, heading] -= shift
        x_hat[heading] -= shift
    c = math.cos(psi_frame)
    s = math.sin(psi_frame)
    xp, yp = x_hat[eta0], x_hat[eta0 + 1]
    eta_hat_ned[0] = c * xp - s * yp
    eta_hat_ned[1] = s * xp + c * yp
    eta_hat_ned[2] = ssa(x_hat[heading])
    for j in range(6):
        lf_tail[j] = x_hat[lf_start + j]
    if wf0 != NO_INDEX:
        wx, wy = x_hat[wf0], x_hat[wf0 + 1]
        eta_wf_hat_ned[0] = c * wx - s * wy
        eta_wf_hat_ned[1] = s * wx + c * wy
        eta_wf_hat_ned[2] = x_hat[wf0 + 2]
    for j in range(n):
        total = 0.0
        for i in range(N):
            d = x_post[i, j] - x_hat[j]
            total += p[i] * (d * d + P_post_diag[i, j])
        covariance_diag[j] = total
    e0 = e1 = e2 = 0.0
    omega_hat = 0.0
    for i in range(N):
        e0 += p[i] * eps[i, 0]
        e1 += p[i] * eps[i, 1]
        e2 += p[i] * eps[i, 2]
        omega_hat += p[i] * omegas[i]
    innovation_ned[0] = c * e0 - s * e1
    innovation_ned[1] = s * e0 + c * e1
    innovation_ned[2] = e2
    return omega_hat


@kernel(void(f8_2d, f8_3d, f8_2d, f8_1d, f8_2d))
def bank_predict(x_post: np.ndarray, Phi: np.ndarray, Gamma: np.ndarray, tau_b: np.ndarray, x: np.ndarray) -> None:
    """One-step prediction of every model with the delivered force (seed 002 eq. (52)):
    ``x̄_i ← Φ_i x̂_i + Γ τ``. x_post (N, n), Phi (N, n, n), Gamma (n, 3), tau_b (3,) [N, N, N·m], x (N, n) out."""
    N, n = x_post.shape
    t0, t1, t2 = tau_b[0], tau_b[1], tau_b[2]
    for j in range(n):
        forced = Gamma[j, 0] * t0 + Gamma[j, 1] * t1 + Gamma[j, 2] * t2
        for i in range(N):
            total = 0.0
            for k in range(n):
                total += Phi[i, j, k] * x_post[i, k]
            x[i, j] = total + forced


@kernel(void(f8_1d, f8_1d, f8_1d, f8, f8))
def bayes_step(log_w: np.ndarray, p: np.ndarray, log_likelihood: np.ndarray, forgetting: float,
               log_floor: float) -> None:
    """Discrete Bayesian weight update with forgetting, in the log domain, in place.

    ``ln w_i(k) = α ln w_i(k−1) + ln L_i(k)`` (Anderson & Moore 1979, ch. 10.1; α = 1 is pure Bayes),
    shifted so the largest is 0 and floored at ``ln(floor)`` relative to it; ``p = w / Σ w``. (Re-exported
    by :mod:`dpcontrol.estimation.weighting`, whose docstring explains the floor and the forgetting.)

    Parameters
    ----------
    log_w : ndarray, shape (N,)
        Unnormalised log-weights (max 0); overwritten.
    p : ndarray, shape (N,)
        Overwritten with the normalised weights.
    log_likelihood : ndarray, shape (N,)
        ``log β_i − m_i`` of this sample.
    forgetting : float
        α in (0, 1].
    log_floor : float
        ln of the relative floor (``-inf`` disables).
    """
    N = log_w.shape[0]
    top = -np.inf
    for i in range(N):
        log_w[i] = forgetting * log_w[i] + log_likelihood[i]
        top = max(top, log_w[i])
    total = 0.0
    for i in range(N):
        value = max(log_w[i] - top, log_floor)
        log_w[i] = value
        p[i] = math.exp(value)
        total += p[i]
    for i in range(N):
        p[i] /= total


@kernel(f8(f8_2d, f8_1d, f8, i8, i8, f8_3d, f8_3d, f8_2d, f8_3d, f8_3d, f8_2d, f8_2d, f8_2d, f8_1d, f8_1d,
           f8_1d))
def band_update(eps: np.ndarray, residual: np.ndarray, heading_scale_m: float, gap_position: int, gap_heading: int,
                state: np.ndarray, CAt: np.ndarray, DB: np.ndarray, yz: np.ndarray, means: np.ndarray,
                group: np.ndarray, prefilter: np.ndarray, energy_band: np.ndarray, gate: np.ndarray,
                coef: np.ndarray, log_l: np.ndarray) -> float:
    """One period of :class:`~dpcontrol.estimation.weighting.BandLikelihood` (see its docstring).

    Rows 0..N−1 are the bank's innovations, row N the residual ``y − η̂_LF``; channels north, east, heading
    (as ψ·L/2). Each row/channel advances its band-pass + low-pass prefilters (state-space form
    ``[y | z'] = z [Cᵀ | Aᵀ] + x [D | Bᵀ]``); the group energies (position: north² + east², heading) update
    their short-window means; per measured group g the WF share λ_g, the LF-validity gate γ_g and the
    tempering κ_g = B_g h_g/π give ``log L_i = Σ_g −½ λ_g γ_g κ_g ẽ²_{g,i} / s_g``.

    Parameters
    ----------
    eps : (N, 3) innovations, vessel-parallel [m, m, rad]; residual : (3,) [m, m, rad]
    heading_scale_m : float, L/2 [m]
    gap_position, gap_heading : int
        Control periods since each group's last sample (0: not measured now).
    state : (N+1, 3, s) prefilter states (a channel's advance only while its group is measured)
    CAt : (3, s, 2+s); DB : (3, 2+s) — the per-channel stacks for these gaps
    yz : (N+1, 3, 2+s) work
    means : (N+1, 2, 2) short-window means [group, (band, low)], in place
    group : (2, 12) per-group statistics, in place — rows of :data:`GROUP_FIELDS`
    prefilter : (2, 3) per group at its gap: band noise gain, white ratio, band width [rad/s]
    energy_band : (N+1, 2) work: this period's band energies
    gate : (2,) out — γ_g (0 for a group with no evidence); coef : (2,) work; log_l : (N,) out

    Returns
    -------
    float
        max_g γ_g when some group gave evidence, else −1 (``log_l`` is then 0).
    """
    rows = state.shape[0]
    N = rows - 1
    s_count = state.shape[2]
    gaps = (gap_position, gap_heading)
    dt = group[0, G_DT]
    for r in range(rows):
        for ch in range(3):
            value = eps[r, ch] if r < N else residual[ch]
            if ch == 2:
                value *= heading_scale_m
            for k in range(2 + s_count):
                total = 0.0
                for m in range(s_count):
                    total += state[r, ch, m] * CAt[ch, m, k]
                yz[r, ch, k] = total + value * DB[ch, k]
            if gaps[1 if ch == 2 else 0] > 0:
                for m in range(s_count):
                    state[r, ch, m] = yz[r, ch, 2 + m]
    # group energies (band, low), their short-window means; an unmeasured group keeps its means
    for g in range(2):
        gap = gaps[g]
        a = math.exp(-gap * dt / group[g, G_SCALE_TIME]) if gap else 1.0
        group[g, G_WEIGHT_SUM] = a * group[g, G_WEIGHT_SUM] + (1.0 - a)
        for r in range(rows):
            for k in range(2):
                # position: north² + east²; heading: (ψ·L/2)²
                energy = yz[r, 0, k] * yz[r, 0, k] + yz[r, 1, k] * yz[r, 1, k] if g == 0 else yz[r, 2, k] * yz[r, 2, k]
                if k == 0:
                    energy_band[r, g] = energy
                means[r, g, k] = means[r, g, k] * a + energy * (1.0 - a)
    used = False
    for g in range(2):
        coef[g] = 0.0
        gap = gaps[g]
        if not gap:
            continue
        # WF share: the band energy of the residual over share_time_s, noise floor removed (warm-up
        # from the design expectation)
        a = math.exp(-gap * dt / group[g, G_SHARE_TIME])
        group[g, G_WF_MEAN] = a * group[g, G_WF_MEAN] + (1.0 - a) * energy_band[N, g]
        group[g, G_WF_WEIGHT] = a * group[g, G_WF_WEIGHT] + (1.0 - a)
        measured = group[g, G_WF_MEAN] / group[g, G_WF_WEIGHT] - group[g, G_NOISE] * prefilter[g, 0]
        warm = 1.0 - math.exp(-group[g, G_WF_TIME] / group[g, G_SCALE_TIME])
        group[g, G_WF_TIME] += gap * dt
        group[g, G_WF_ENERGY] = warm * max(measured, 0.0) + (1.0 - warm) * group[g, G_PRIOR]
        total = group[0, G_WF_ENERGY] + group[1, G_WF_ENERGY]
        if total > 0.0:
            group[0, G_WF_SHARE] = group[0, G_WF_ENERGY] / total
            group[1, G_WF_SHARE] = group[1, G_WF_ENERGY] / total
        weight = group[g, G_WEIGHT_SUM]
        smallest = np.inf
        band_total = 0.0
        low_total = 0.0
        for r in range(N):
            smallest = min(smallest, means[r, g, 0])
            band_total += means[r, g, 0]
            low_total += means[r, g, 1]
        scale = smallest / weight
        lam = group[g, G_WF_SHARE]
        if not (scale > 0.0 and band_total > 0.0 and lam > 0.0):
            gate[g] = 0.0
            continue
        excess = low_total / band_total / prefilter[g, 1]
        limit = group[g, G_LF_EXCESS_LIMIT]
        gate_g = weight * min(1.0, limit / excess) if excess > 0.0 else weight
        gate[g] = gate_g
        kappa = prefilter[g, 2] * gap * dt / math.pi
        coef[g] = -0.5 * lam * gate_g * kappa / scale
        used = True
    if not used:
        for r in range(N):
            log_l[r] = 0.0
        return -1.0
    for r in range(N):
        log_l[r] = energy_band[r, 0] * coef[0] + energy_band[r, 1] * coef[1]
    return max(gate[0], gate[1])

