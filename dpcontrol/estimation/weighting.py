"""Model-probability weights of the MMAE wave filter (seed 000 eq. (18), seed 001 eq. (42)).

Two weight generators over a bank of N models, both fed with per-model log-likelihoods ``log L_i``:

* :func:`dwsg_step` — the dynamic weighting signal generator (DWSG) of seed 000 eq. (18)::

      ṗ_i = −λ (1 − L_i / Σ_j p_j L_j) p_i

  integrated *exactly* over one sample period with the likelihoods held (zero-order hold). With
  the substitution ``dτ = λ dt / Σ_j p_j L_j`` the DWSG becomes the replicator equation
  ``dp_i/dτ = p_i (L_i − Σ_j p_j L_j)``, whose solution is ``p_i(τ) ∝ p_i(0) e^{L_i τ}``; the new
  time τ follows from ``ln Σ_j p_j(0) e^{L_j τ} = λ dt`` (``d ln Z/dτ = Σ p L``), a scalar convex
  equation solved by Newton's method (monotone from the tangent start). The step keeps the weights
  on the simplex for any λ·dt, so no stability limit on the gain.
* :func:`bayes_step` — the discrete Bayesian recursion (Anderson & Moore 1979, ch. 10.1)
  ``p_i(k) ∝ p_i(k−1)^α L_i(k)`` with exponential forgetting ``α = exp(−dt / T_f)`` of past
  log-likelihoods (α = 1: pure Bayes), kept in the log domain (no underflow, no log per step).

and two ways to compute ``log L_i`` from the innovations ``ε_i`` of the bank (chosen by
``WaveFilterConfig.likelihood_scale``):

* per sample, ``log L_i = −½ εᵢᵀ S̄⁻¹ εᵢ`` with one fixed common S̄ (``"common"``), or seed 000's
  ``−½ ln det S_i − ½ εᵢᵀ S_i⁻¹ εᵢ`` (``"own"``) — the textbook forms, right when the plant *is* the
  design model (the unit tests on design-model data);
* :class:`BandLikelihood` (``"band"``, the default) — the form that works in closed loop on a real
  plant, see below.

Why the per-sample forms fail in closed loop (measured on cs2-seed000, see the tests and the
closed-loop report): the innovations of the bank on the nonlinear plant are 3–10× larger than the
S the filters were designed with (unmodelled LF dynamics, thruster lag, a sea that is not the
design model, mis-set noise intensities), and they are strongly coloured. ``−½ ε²/S̄`` then differs
between models by tens of nats *per sample* (median spread 91 nats in the old cs2-seed000 sea), so
each sample overturns the last: the weights chatter between models every second. And the
differences that remain come mostly from outside the wave band — white sensor noise and the
JONSWAP tail far above the peak (which favour the highest ω0), LF model mismatch while the filters
converge or the vessel manoeuvres (which favours the lowest ω0, whose WF states absorb it) — not
from how well each model explains the wave motion.

:class:`BandLikelihood` therefore compares the models only on what distinguishes them, at a
statistically honest rate:

1. **Prediction-error prefilter** (Ljung 1999, *System Identification*, §14.4: a prefilter on the
   prediction errors weights the model fit in frequency): each innovation channel passes a 2nd-order
   Butterworth band-pass over the band the bank's seas occupy, ``[ω_1/2, 1.5·ω_N]`` by default (the
   sea of the lowest model starts at ≈ 0.8·ω_1, a JONSWAP at the top model holds its energy up to
   ≈ 1.5·ω_N).
2. **Local whitening per channel group** (position; heading): the band-passed energies are divided
   by a slowly varying common scale, the smallest short-window (``likelihood_time_s``) band energy
   of the bank. The likelihood is then invariant to the absolute innovation level: mis-set noise
   intensities, a bigger sea or a transient do not change how much one sample can say.
3. **Tempering by the number of independent samples**: band-limited innovations carry about
   ``B·h/π`` independent samples per sample of period h (Nyquist, B = band width in rad/s), so each
   sample's log-likelihood is scaled by that factor instead of counting every correlated sample as
   new evidence — the cause of the chatter.
4. **LF-validity gate**: a correct LF model leaves no systematic low-frequency innovation; when the
   energy below the band exceeds ``lf_excess_limit`` times what white innovations would put there
   (filter convergence after a start, DP engagement, bias changes), the in-band innovations are
   contaminated by that LF mismatch and the group's evidence is scaled down in proportion. The same
   factor holds the weights while the statistics warm up after a start or a pose reset.
5. **Channel groups weighted by their WF motion**: position and heading (the latter as the
   displacement ``ψ·L/2`` of the hull ends, the plant's dominant-DOF rule) enter in proportion to the
   share of the wave-frequency motion measured in each (band-passed ``y − η̂_LF`` minus the sensor
   noise floor), so a DOF the waves hardly move (CyberShip II's yaw in long waves: share < 0.1 %)
   cannot outvote the one they do, and the heading — often the cleanest channel on a full-scale ship
   (the supply vessel's calm sea: 0.13° of WF yaw against a 0.05° gyro, 9 cm of WF surge against a
   0.3 m DGPS) — counts when the waves yaw the vessel.

Why weights must not lock (docs/design.md §5, seed 001 Fig. 3): both generators drive the weight of a
model that is worse *now* towards zero geometrically; once it underflows, no later evidence can
raise it (0 × anything = 0), so after a sea-state change the bank stays on the old model. Two
remedies, both applied:

* a **floor** relative to the leading model, ``p_i ≥ p_min · max_j p_j`` (then renormalised): the
  log-odds of any model against the leader are bounded by ``ln(1/p_min)``;
* **forgetting** (Bayes form): the log-odds are an exponentially weighted sum of recent
  log-likelihood ratios with memory T_f, so they stay proportional to the evidence of the last
  T_f seconds. That keeps the weights *soft* when neighbouring models are nearly as good and bounds
  the switching time to a fraction of T_f. With the band likelihood the memory runs on *evidence*
  time (``α^γ`` per sample, γ the gate): a period the gate rejects neither adds nor forgets evidence.

Why the Bayes form is the default (``WaveFilterConfig.weighting``): the DWSG is driven by the
*instantaneous* likelihood ratio, ``d ln p_i/dt = λ (L_i/Σ p_j L_j − 1)``, linear in ``L`` — where
neighbouring models differ by a few per cent a small λ makes the weights sluggish and a large λ
makes them follow the noise. The Bayes form sums log-likelihoods, so its log-odds grow with the
accumulated evidence.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.signal import butter, sosfilt

from dpcontrol.estimation.kernels import GROUP_FIELDS, band_update, bayes_step

__all__ = ["BandLikelihood", "apply_floor", "bayes_step", "dwsg_step"]

_NEWTON_ITERATIONS = 8
_NEWTON_TOLERANCE = 1e-12


def apply_floor(p: np.ndarray, floor: float) -> None:
    """In place: ``p_i ← max(p_i, floor · max_j p_j)``, then normalise to the simplex.

    The floor is relative to the leading model, so it bounds every log-odds against the leader by
    ``ln(1/floor)`` whatever N is.
    """
    if floor > 0.0:
        np.maximum(p, floor * float(p.max()), out=p)
    p /= p.sum()


def dwsg_step(p: np.ndarray, log_likelihood: np.ndarray, *, rate_per_s: float, dt_s: float,
              floor: float, work: np.ndarray | None = None) -> None:
    """Exact one-period solution of the DWSG (seed 000 eq. (18)), in place on ``p``.

    Parameters
    ----------
    p : ndarray, shape (N,)
        Weights p_i(t) on the simplex; overwritten with p_i(t + dt).
    log_likelihood : ndarray, shape (N,)
        ``log β_i − m_i`` held over the period (any common offset cancels).
    rate_per_s : float
        λ [1/s].
    dt_s : float
        Period [s].
    floor : float
        Relative floor of :func:`apply_floor` (0 disables).
    work : ndarray, shape (N,), optional
        Scratch array (avoids allocation in the control loop).
    """
    ell = np.empty_like(p) if work is None else work
    # ℓ_i = L_i / Σ_j p_j L_j, scaled so the mean under p is 1 (the DWSG is invariant to scaling L).
    np.subtract(log_likelihood, log_likelihood.max(), out=ell)
    np.exp(ell, out=ell)
    mean = float(p @ ell)
    if not mean > 0.0 or not math.isfinite(mean):
        return
    ell /= mean
    target = rate_per_s * dt_s
    ell_max = float(ell.max())
    # Newton on g(τ) = ln Σ p_j e^{ℓ_j τ} − λdt; g(0) = −λdt, g'(0) = 1, g convex increasing, so the
    # first iterate is τ = λdt and the following ones decrease monotonically to the root.
    tau = target
    for _ in range(_NEWTON_ITERATIONS):
        z = p * np.exp((ell - ell_max) * tau)
        z_sum = float(z.sum())
        g = math.log(z_sum) + ell_max * tau - target
        slope = float(z @ ell) / z_sum
        step = g / slope
        tau -= step
        if abs(step) <= _NEWTON_TOLERANCE * max(tau, 1e-300):
            break
    np.multiply(ell, tau, out=ell)
    ell -= ell.max()
    np.exp(ell, out=ell)
    p *= ell
    apply_floor(p, floor)


# ------------------------------------------------------------------------------------------------
# Band-limited, locally whitened, tempered likelihood (see the module docstring).

_GROUPS = 2                # 0: position (north, east), 1: heading (as ψ·L/2)
_CHANNEL_GROUP = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])   # (channel, group) membership
_MAX_GAP = 64              # a group silent for more control periods than this restarts its prefilters


def _sos_noise_gain(sos: np.ndarray, settle_samples: int) -> float:
    """Σ h[n]² of a digital filter in SOS form: its power gain for white noise (by the impulse response)."""
    impulse = np.zeros(settle_samples)
    impulse[0] = 1.0
    return float(np.sum(sosfilt(sos, impulse) ** 2))


def _cascade_state_space(sos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(A, B, C, D) of a cascade of biquads, each in direct form II transposed.

    One section ``y = b0 x + z1; z1' = b1 x − a1 y + z2; z2' = b2 x − a2 y`` is
    ``z' = [[−a1, 1], [−a2, 0]] z + [b1 − a1 b0, b2 − a2 b0] x``, ``y = z1 + b0 x``; the cascade feeds each
    output to the next section (block lower-triangular A). The same arithmetic as ``sosfilt``, written
    as one linear map so that a whole bank of channels advances in one pass (``kernels.band_update``).
    """
    n_sec = sos.shape[0]
    n = 2 * n_sec
    A = np.zeros((n, n))
    B = np.zeros(n)
    C = np.zeros(n)
    D = 1.0
    for k in range(n_sec):
        b0, b1, b2, _, a1, a2 = sos[k]
        i = 2 * k
        # input of section k = C·z + D·x of the cascade so far
        A[i, :] += (b1 - a1 * b0) * C
        A[i + 1, :] += (b2 - a2 * b0) * C
        A[i, i] += -a1
        A[i, i + 1] += 1.0
        A[i + 1, i] += -a2
        B[i] = (b1 - a1 * b0) * D
        B[i + 1] = (b2 - a2 * b0) * D
        C = b0 * C
        C[i] += 1.0
        D = b0 * D
    return A, B, C, D


class _Prefilter:
    """Band-pass and below-band low-pass prefilters of one channel at one sample period.

    Coefficients from ``scipy.signal.butter``; the two filters run in parallel as one state-space system
    (outputs: band, low) so the whole bank advances in one pass per period.
    """

    __slots__ = ("A", "B", "C", "D", "band_noise_gain", "band_width_rad_s", "white_ratio")

    def __init__(self, band_rad_s: tuple[float, float], period_s: float, order: int) -> None:
        nyquist = math.pi / period_s
        lo, hi = band_rad_s
        hi = min(hi, 0.9 * nyquist)
        if not lo < hi:
            raise ValueError(f"likelihood band [{lo:g}, {hi:g}] rad/s is empty at a sample period of {period_s:g} s")
        fs = 2.0 * math.pi / period_s          # angular sampling frequency: band edges in rad/s
        band_sos = butter(order, [lo, hi], btype="bandpass", fs=fs, output="sos")
        low_sos = butter(order, lo, btype="lowpass", fs=fs, output="sos")
        self.band_width_rad_s = hi - lo
        settle = int(min(200_000, max(2_000, 60.0 * fs / lo)))
        self.band_noise_gain = _sos_noise_gain(band_sos, settle)
        # what white innovations would put below the band relative to inside it
        self.white_ratio = _sos_noise_gain(low_sos, settle) / self.band_noise_gain
        ab, bb, cb, db = _cascade_state_space(band_sos)
        al, bl, cl, dl = _cascade_state_space(low_sos)
        nb, nl = ab.shape[0], al.shape[0]
        self.A = np.zeros((nb + nl, nb + nl))
        self.A[:nb, :nb] = ab
        self.A[nb:, nb:] = al
        self.B = np.concatenate([bb, bl])
        self.C = np.zeros((2, nb + nl))
        self.C[0, :nb] = cb
        self.C[1, nb:] = cl
        self.D = np.array([db, dl])


class BandLikelihood:
    """Per-sample log-likelihoods of the bank from band-limited, locally whitened innovations.

    See the module docstring for the five ingredients. Per sample of a channel group g (position:
    north and east together; heading) with period h_g, the log-likelihood of model i is::

        log L_i += −½ · λ_g · γ_g · (B_g h_g / π) · ẽ²_{g,i} / s_g

    with ẽ the prefiltered innovations (heading scaled to metres by L/2), s_g the smallest short-window
    band energy of the bank, B_g h_g/π the independent samples per sample, γ_g ∈ [0, 1] the
    LF-validity gate times the warm-up factor, and λ_g the group's share of the WF motion. The WF
    motion of a group is estimated from the data, not from the filters' WF states (those absorb
    sensor noise in proportion to the tuning): the energy of the band-passed residual
    ``y − η̂_LF`` (WF motion + noise) over ``share_time_s``, minus the noise floor ``R·(band noise
    gain)``; until data arrive the design expectation ``prior_wf_energy`` stands in.

    Everything is batched: the N innovation rows and the residual row of the three channels advance
    through their prefilters in one compiled kernel (:func:`~dpcontrol.estimation.kernels.band_update`),
    the statistics are (rows, groups, 2) arrays;
    a group that is not measured this period keeps its states (decay 1, gain 0).

    Parameters
    ----------
    n_models : int
    sample_time_s : float
        Control period dt [s]; a group sampled every m periods is filtered at h = m·dt.
    band_rad_s : (float, float)
        Prefilter pass band [rad/s].
    scale_time_s : float
        Time constant of the short-window statistics (whitening scale, gate, warm-up) [s].
    lf_excess_limit : float
        Largest low-frequency innovation energy, relative to white innovations, that still counts
        as full evidence (``inf`` disables the gate).
    length_m : float
        Vessel length L: heading innovations count as the displacement ``ψ·L/2`` [m].
    noise_var : sequence of 3 float
        Measurement noise variance per sample, north/east/heading [m², m², rad²].
    prior_wf_energy : sequence of 2 float
        Expected WF motion energy of the position group (both axes) and of the heading group
        (as ``ψ·L/2``) [m²], used until the data take over.
    share_time_s : float
        Time constant of the WF motion estimate [s].
    order : int
        Butterworth order of the prefilters.
    """

    def __init__(self, n_models: int, *, sample_time_s: float, band_rad_s: Sequence[float], scale_time_s: float,
                 lf_excess_limit: float, length_m: float, noise_var: Sequence[float] | np.ndarray,
                 prior_wf_energy: Sequence[float], share_time_s: float, order: int = 2) -> None:
        lo, hi = float(band_rad_s[0]), float(band_rad_s[1])
        if not 0.0 < lo < hi:
            raise ValueError(f"likelihood band must satisfy 0 < low < high, got [{lo}, {hi}] rad/s")
        self.band_rad_s = (lo, hi)
        self.n_models = int(n_models)
        self.dt_s = float(sample_time_s)
        self.scale_time_s = float(scale_time_s)
        self.share_time_s = float(share_time_s)
        self.lf_excess_limit = float(lf_excess_limit)
        self.order = int(order)
        self.heading_scale_m = 0.5 * float(length_m)
        noise = [float(v) for v in noise_var]
        # noise variance of a group's residual, summed over its channels (heading in metres)
        self._noise = (noise[0] + noise[1], noise[2] * self.heading_scale_m**2)
        self._prior = (float(prior_wf_energy[0]), float(prior_wf_energy[1]))
        self._filters: dict[int, _Prefilter] = {}
        self._stacks: dict[tuple[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        n_state = self._prefilter(1).A.shape[0]           # also checks the band at the control period
        rows = self.n_models + 1                           # the bank's innovations + the residual row
        self.state = np.zeros((rows, 3, n_state))           # prefilter states per row and channel
        # [y | z'] = z [Cᵀ | Aᵀ] + x [D | Bᵀ]: outputs (band, low) then the next states, per row and channel
        self._yz = np.zeros((rows, 3, 2 + n_state))
        self._energy_band = np.zeros((rows, _GROUPS))       # this period's band energy per row and group
        self.means = np.zeros((rows, _GROUPS, 2))           # short-window EWMA numerators (band, low)
        # per-group statistics and constants, one row per group (columns: kernels.GROUP_FIELDS)
        self._group = np.zeros((_GROUPS, len(GROUP_FIELDS)))
        column = {name: k for k, name in enumerate(GROUP_FIELDS)}
        self._group[:, column["noise"]] = self._noise
        self._group[:, column["prior"]] = self._prior
        self._group[:, column["scale_time_s"]] = self.scale_time_s
        self._group[:, column["share_time_s"]] = self.share_time_s
        self._group[:, column["lf_excess_limit"]] = self.lf_excess_limit
        self._group[:, column["dt_s"]] = self.dt_s
        # views of the statistics' columns (read/write through them)
        self.weight_sum = self._group[:, column["weight_sum"]]   # EWMA weight sums (warm-up 1 − e^{−t/T_s})
        self.wf_mean = self._group[:, column["wf_mean"]]         # EWMA numerator of the residual band energy
        self.wf_weight = self._group[:, column["wf_weight"]]
        self.wf_time_s = self._group[:, column["wf_time_s"]]     # data time behind it
        self.wf_energy = self._group[:, column["wf_energy"]]
        self.wf_share = self._group[:, column["wf_share"]]
        self.wf_energy[:] = self._prior
        self.wf_share[:] = self.wf_energy / max(float(self.wf_energy.sum()), 1e-300)
        self.steps_since = [0, 0]
        self.gate = np.zeros(_GROUPS)                       # last γ_g (diagnostics)
        self.gate_max = 0.0                                 # max_g γ_g of the last update that had evidence
        self.log_l = np.zeros(self.n_models)
        self._coef = np.zeros(_GROUPS)

    # -- configuration ----------------------------------------------------------------------------
    def _prefilter(self, gap: int) -> _Prefilter:
        pre = self._filters.get(gap)
        if pre is None:
            pre = self._filters[gap] = _Prefilter(self.band_rad_s, gap * self.dt_s, self.order)
        return pre

    def _stack(self, gaps: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-channel ``[Cᵀ | Aᵀ]`` (3, s, 2 + s) and ``[D | Bᵀ]`` (3, 2 + s) stacks — outputs and next
        states in one product — and per group (2, 3) the band noise gain, white ratio and band width of its
        prefilter, for the groups' gaps (0: not measured)."""
        stack = self._stacks.get(gaps)
        if stack is None:
            pres = [self._prefilter(max(gaps[g], 1)) for g in (0, 0, 1)]
            CAt = np.ascontiguousarray(np.stack([np.concatenate([p.C.T, p.A.T], axis=1) for p in pres]))
            DB = np.ascontiguousarray(np.stack([np.concatenate([p.D, p.B]) for p in pres]))
            params = np.array([[p.band_noise_gain, p.white_ratio, p.band_width_rad_s]
                               for p in (self._prefilter(max(gaps[g], 1)) for g in range(_GROUPS))])
            stack = self._stacks[gaps] = (CAt, DB, params)
        return stack

    def restart(self) -> None:
        """Forget prefilter states and short-window statistics (after a pose reset); the weights and the
        WF share estimate (a property of the sea) are kept by the caller / here."""
        self.state[...] = 0.0
        self.means[...] = 0.0
        self.weight_sum[:] = 0.0
        self.steps_since = [0, 0]
        self.gate[:] = 0.0

    # -- one period -------------------------------------------------------------------------------
    def update(self, eps: np.ndarray, position: bool, heading: bool, residual: np.ndarray) -> bool:
        """Filter this period's innovations and fill :attr:`log_l` (N,); False when there is no evidence.

        Parameters
        ----------
        eps : ndarray, shape (N, 3)
            Innovations of the bank, vessel-parallel [m, m, rad] (zero where not measured).
        position, heading : bool
            Which channel groups were measured this period.
        residual : ndarray, shape (3,)
            Measurement minus the blended LF pose estimate, vessel-parallel [m, m, rad] (WF motion +
            noise), for the WF share λ_g.
        """
        measured = (position, heading)
        since = self.steps_since
        gaps = [0, 0]
        for g in range(_GROUPS):
            since[g] += 1
            if measured[g]:
                gap = since[g]
                since[g] = 0
                if gap > _MAX_GAP:          # a long silence: restart the group's filters
                    self.state[:, _CHANNEL_GROUP[:, g] > 0] = 0.0
                    self.means[:, g] = 0.0
                    self.weight_sum[g] = 0.0
                    gap = 1
                gaps[g] = gap
        if gaps[0] == 0 and gaps[1] == 0:
            self.log_l[:] = 0.0
            return False
        CAt, DB, params = self._stack((gaps[0], gaps[1]))
        gate_max = band_update(eps, residual, self.heading_scale_m, gaps[0], gaps[1], self.state, CAt, DB, self._yz,
                               self.means, self._group, params, self._energy_band, self.gate, self._coef, self.log_l)
        if gate_max < 0.0:
            return False
        self.gate_max = gate_max
        return True

    # -- persistence (a restart must not lose the evidence statistics: bumpless weights) ----------
    _ARRAYS = ("state", "means", "gate")
    _SCALARS = ("weight_sum", "wf_mean", "wf_weight", "wf_time_s", "wf_energy", "steps_since")

    def state_dict(self) -> dict[str, Any]:
        """JSON-able statistics and prefilter states."""
        out: dict[str, Any] = {"band_rad_s": list(self.band_rad_s)}
        for name in self._ARRAYS:
            out[name] = getattr(self, name).tolist()
        for name in self._SCALARS:
            value = getattr(self, name)
            out[name] = value.tolist() if isinstance(value, np.ndarray) else list(value)
        return out

    def load_state_dict(self, state: Any) -> None:
        """Restore :meth:`state_dict`; ValueError (nothing changed) if it does not fit this bank."""
        if not isinstance(state, dict):
            raise ValueError("likelihood state: expected a mapping")
        band: Any = state.get("band_rad_s")  # (None or any JSON value: judged below)
        try:
            band_ok = len(band) == 2 and np.allclose(np.asarray(band, dtype=float), self.band_rad_s,
                                                     rtol=1e-12, atol=0.0)
        except (TypeError, ValueError):
            band_ok = False
        if not band_ok:
            raise ValueError("likelihood state: band_rad_s differs from the configured band")
        staged: dict[str, Any] = {}
        for name in (*self._ARRAYS, *self._SCALARS):
            current = getattr(self, name)
            shape = current.shape if isinstance(current, np.ndarray) else (len(current),)
            try:
                value = np.array(state.get(name), dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"likelihood state: {name} is not numeric") from None
            if value.shape != shape or not np.all(np.isfinite(value)) or (name in self._SCALARS
                                                                           and np.any(value < 0.0)):
                raise ValueError(f"likelihood state: {name} must be finite (>= 0 for counters) with shape {shape}")
            staged[name] = value
        for name in self._ARRAYS:
            getattr(self, name)[...] = staged[name]
        for name in self._SCALARS:
            if name == "steps_since":
                self.steps_since = [int(v) for v in staged[name].tolist()]
            else:
                getattr(self, name)[:] = staged[name]     # the views of the statistics array
        total = float(self.wf_energy.sum())
        self.wf_share[:] = self.wf_energy / total if total > 0.0 else 0.5
