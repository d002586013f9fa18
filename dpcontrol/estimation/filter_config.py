"""Configuration of the DP wave filters: fields, validation and the default tuning rule.

:class:`WaveFilterConfig` is a frozen dataclass validated on construction (errors are
:class:`~dpbase.schema.ConfigError` naming the field). :meth:`WaveFilterConfig.from_options`
builds one from the runtime's ``estimator`` section (kind, grid, ζ and a mapping of options) and
reports errors with their key path (``estimator.weight_floor: expected a number in [0, 0.1], …``).

Default tuning rule (every number can be overridden)
----------------------------------------------------
All defaults scale with the vessel length L (``length_m``, or estimated from the surge mass as
``L ≈ (107·M11/ρ)^{1/3}``, i.e. block coefficient 0.7, L/B = 5, L/T = 15) and with the mass and
damping matrices, so one rule serves a 1.3 m model (CyberShip II) and a 260 m tanker:

* WF motion (seed 002 eq. (27)): standard deviation ``σ_wf = 0.01·L`` in surge/sway and 0.5° in
  yaw, the motion of a moderate sea. A model that expects less WF motion than the sea gives hands the excess
  to the LF estimate and the bias (docs/wave-filter.md); seed 002 estimates Q1 from data, and ``kind="pem"``
  does (seed 002 eqs. (46)–(50)), with this rule as the floor.
  ``wf_noise_rule = "equal_variance"`` (default): each model of the bank gets the intensity
  ``q1 = 4ζ·ω0·σ_wf²``, so every model expects the same WF motion variance and the models differ only in
  spectral shape — one of the two remedies for the MMAE trap of docs/design.md §5 (the other, the common error
  scale, is ``likelihood_scale``); on the seed 001 sea-state sequence it tracks the moderate sea more
  reliably than the alternative.
  ``"equal_intensity"`` (seed 000): one intensity ``q1 = 4ζ·ω_ref·σ_wf²`` for all models (σ_wf at the
  reference frequency ω_ref, geometric mean of the grid), so lower-frequency models expect more WF
  motion (variance ∝ 1/ω0).
* LF velocity noise w2 in surge/sway: a force white noise that alone would make the first-order velocity
  dynamics ``M_ii ν̇ + D_ii ν = w`` wander with standard deviation σ_ν: ``Q2_ii = 2·M_ii·D_ii·σ_ν²`` with
  ``σ_ν = 0.001·√(gL)`` [m/s] (``0.002·√(gL)`` without wave states, ``kind="raw"``, whose LF model must follow
  the wave motion too). Seed 002: "the entries of Q2 are taken as a fraction of the variance of the position
  measurement noises" — small; the LF velocity's wave-band content is what a PID's derivative action turns
  into thrust (docs/wave-filter.md).
* LF yaw noise w2_ψ, with wave states: set from the heading measurement noise so that the LF heading
  estimate has a chosen bandwidth ω_c (``lf_yaw_bandwidth_rad_s``, default ``0.5·√(g/L)``)::

      Q2_ψ = I_z²·ω_c⁴·R_ψ·Δt          [N²·m²·s]

  I_z = M33 (with added mass), R_ψ the heading variance per sample [rad²], Δt the sample time. Seed 002
  eq. (45) sets Q2 "as a fraction of the variance of the position measurement noises"; this fixes the
  fraction by the bandwidth it gives: the LF yaw model is nearly a double integrator ``I_z ψ̈ = w2_ψ``
  (the damping I_z/D33 and the bias are slower), whose steady-state Kalman filter with acceleration
  intensity ``q = Q2_ψ/I_z²`` [rad²/s³] and measurement density ``r = R_ψ·Δt`` [rad²·s] has the error poles
  ``ω_c·e^{±j3π/4}``, ``ω_c = (q/r)^{1/4}`` (the estimate's −3 dB point is ≈ 2.06·ω_c). ω_c is Froude scaled
  like every rate of the rule: 0.18 rad/s for the 76 m supply vessel, 3.7× the natural frequency of the
  default pole placement (``2π/(150 s·√(L/100 m))`` = 0.134·√(g/L), 0.100·√(g/L) for the tankers,
  :func:`~dpcontrol.control.pid.pole_placement_gains`), so above such a loop and under the wave band. The former
  rule (``σ_r = 0.002·√(g/L)``, ``Q2_ψ = 2·M33·D33·σ_r²``) gave ω_c = 0.5–1 rad/s at full scale (on the
  wave band: the heading's wave motion reached the yaw moment) and 10 rad/s on CyberShip II; it is kept
  when ``lf_yaw_rate_std_radps`` is given and for ``raw`` (no wave states: its LF model must follow the
  waves). A vessel whose yaw loop is faster than the rule's ω_c (CyberShip II with seed 000's gains,
  1.67 rad/s) needs ``lf_yaw_bandwidth_rad_s`` at a few times its loop (docs/wave-filter.md).
* Bias w3 (seed 002 eq. (33) / seed 001 eq. (35)): the slowly varying environmental force is
  expected to be of size ``σ_b = D̄·v_c`` with ``v_c = 0.02·√(gL)`` (a current of that speed; D̄ the
  mean of D11 and D22; yaw: ``D33·v_c/L``). Random walk: ``Q3 = σ_b²/T_drift`` (the bias can
  change by σ_b in ``bias_drift_time_s`` = ``360·√(L/g)`` in surge/sway — 1000 s for the 76 m supply
  vessel, Froude scaled like every time of the rule (128 s for CyberShip II): the time scale of mean current
  and wind changes — a bias that may move within 100 s follows the wave groups, and a PID with bias feed-forward
  passes that to the thrusters — and ``bias_yaw_drift_time_s`` = 100 s in yaw, whose mean wave and wind
  moment changes with every heading change); Markov with time constant T: ``Q3 = 2σ_b²/T``
  (stationary standard deviation σ_b). Surge and sway share one value so the model is invariant
  to the vessel-parallel rotation. Start-up learning: for ``bias_learning_s`` = ``15·√(L/g)`` after the filter
  starts with the bias at zero (42 s on the supply vessel), the steady-state kinds run the gains of
  ``bias_learning_factor`` = 10 × Q3, so that the force carrying a vessel in standby is learnt before DP is
  engaged (:meth:`WaveFilterConfig.bias_learning_time`; docs/fault-handling.md, "Entering DP while drifting").
* Measurement noise: ``σ_pos = 0.002·L`` (GNSS/DGNSS at full scale), heading 0.1° (gyro).
* Wave frequencies: the MMAE bank (seed 000's eight models, 0.3–1.35 rad/s), the single-model kinds' ω0
  (0.8 rad/s) and the PEM/RPEM ω0 range (0.2–2 rad/s) are full-scale seas' (seed 000 "from calm and glassy to
  very high and phenomenal"; seed 001 Table I, the sea states of a supply vessel, and its bank {0.56, 0.73, 0.80}
  rad/s). For a hull shorter than the reference ``L_ref = 76.2 m`` (seed 001's supply vessel) they are Froude
  scaled, ``ω·√(L_ref/L)`` (:func:`wave_frequency_scale`): such a hull is taken for a model meeting its basin's
  seas, Froude scaled like its own time scale (CyberShip II, L = 1.255 m: × 7.8, bank 2.3–10.5 rad/s; the Blue
  Lady, 13.75 m: × 2.35). A longer hull meets the reference's ocean: unchanged. A configuration's own grid,
  ω0 or range is kept; a small vessel at sea (not a model) must give its own.
* MMAE weights: discrete Bayes with forgetting time T_f = 600 s and a relative floor of 10⁻⁶, fed
  with the band-limited, locally whitened and tempered likelihood (``likelihood_scale="band"``):
  prefilter band ``[ω_1/2, 1.5·ω_N]``, short-window statistics over two periods of the lowest model
  (``4π/ω_1``), LF-validity limit 2 (see :mod:`~dpcontrol.estimation.weighting` for why, and
  ``tests/closed_loop`` for what they achieve on the plant). T_f = 600 s because the tempered evidence
  arrives at ≈ B/π independent samples per second: with 200 s the 0.9 rad/s model of cs2-seed000 held
  only 0.5–0.9 of the weight against 1.05 (they differ by ~10 % in band energy); with 600 s it holds
  > 0.9, and the seed 001 sea-state switches still take only 75–90 s.

``process_noise_intensity`` (9 numbers, ``diag(Q1, Q2, Q3)`` in the units of
:mod:`~dpcontrol.estimation.design_model`) overrides the rule, e.g. to reproduce seed 000 App. A.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from dpbase.schema import ConfigError, Section, check_number, join

KINDS = ("mmae", "kf", "rpem", "pem", "raw")
WF_FRAMES = ("body", "earth")
WF_NOISE_RULES = ("equal_intensity", "equal_variance")
WEIGHTINGS = ("dwsg", "bayes")
LIKELIHOOD_SCALES = ("band", "common", "own")
DEAD_RECKONING_BIAS = ("mean", "hold")
#: Length for which the default wave frequencies are stated [m]: the supply vessel of seed 001, whose sea states
#: (its Table I, peak ω0 0.45–0.85 rad/s) and bank {0.56, 0.73, 0.80} rad/s are full-scale ones.
REFERENCE_LENGTH_M = 76.2


def wave_frequency_scale(length_m: float) -> float:
    """Froude factor of the default wave frequencies for a vessel of length L [-].

    ``s = √(max(1, L_ref/L))`` with ``L_ref`` = :data:`REFERENCE_LENGTH_M`. A hull shorter than the reference is
    taken for a model of a full-scale vessel at the scale λ = L_ref/L: Froude similitude keeps ``ω²L/g``, so a
    sea met at full scale at ω meets the model at ``ω·√λ`` (wave lengths ``2πg/ω²`` scale with λ like the hull).
    A longer hull meets the same ocean as the reference (waves do not grow with the ship): s = 1.

    Parameters
    ----------
    length_m : float
        Vessel length L [m], > 0.

    Returns
    -------
    float
        ``s`` ≥ 1.
    """
    return math.sqrt(max(1.0, REFERENCE_LENGTH_M / length_m))


class LengthScaledGrid(tuple[float, ...]):
    """Wave frequencies stated at :data:`REFERENCE_LENGTH_M` [rad/s]; :class:`WaveFilterConfig` multiplies them
    by :func:`wave_frequency_scale` of its vessel. A plain tuple (a configuration's own grid) is kept as given."""

    __slots__ = ()

    def __format__(self, spec: str) -> str:
        values = ", ".join(f"{w:g}" for w in self)
        return f"[{values}] × √(max(1, {REFERENCE_LENGTH_M:g} m/L))"

    def __str__(self) -> str:
        return format(self, "")


class LengthScaledFrequency(float):
    """One wave frequency stated at :data:`REFERENCE_LENGTH_M` [rad/s], scaled like :class:`LengthScaledGrid`."""

    __slots__ = ()

    def __format__(self, spec: str) -> str:
        return f"{float(self):g} × √(max(1, {REFERENCE_LENGTH_M:g} m/L))"

    def __str__(self) -> str:
        return format(self, "")


#: MMAE bank of seed 000 (its sea states "from calm and glassy to very high and phenomenal", peak 0.25–1.4 rad/s,
#: full-scale), scaled to the vessel (:func:`wave_frequency_scale`) unless a configuration gives its own grid
DEFAULT_OMEGAS_RAD_S = LengthScaledGrid((0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35))
#: initial / fixed ω0 of the single-model kinds (kf, rpem, pem) when none is given, scaled the same way
DEFAULT_OMEGA0_RAD_S = LengthScaledFrequency(0.8)

_GRAVITY_MPS2 = 9.81
_RHO_KGPM3 = 1025.0


def _tuple_of(value: Any, length: int | None, where: str, *, positive: bool = False,
              nonnegative: bool = False) -> tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise ConfigError(where, f"a list of {length or 'some'} numbers", value)
    if length is not None and len(value) != length:
        raise ConfigError(where, f"a list of {length} numbers", value)
    out = []
    for i, item in enumerate(value):
        minimum = 0.0 if (positive or nonnegative) else None
        out.append(check_number(item, join(where, i), minimum=minimum, exclusive_minimum=positive))
    return tuple(out)


@dataclass(frozen=True, eq=False)
class WaveFilterConfig:
    """Everything a DP wave filter needs; see the module docstring for the tuning rule.

    Attributes
    ----------
    mass_matrix, damping_matrix : ndarray, shape (3, 3)
        M and D of the vessel (``VesselData.mass_matrix`` / ``damping_matrix``).
    sample_time_s : float
        Control period the filters are designed for [s].
    kind : {"mmae", "kf", "rpem", "pem", "raw"}
        Bank of steady-state filters / one filter at a fixed ω0 / RPEM adaptive-frequency filter /
        one filter whose wave model is re-identified in batches (seed 002 eqs. (46)–(50)) /
        LF model without wave states (wave filter off, seed 002 Fig. 7).
    omegas_rad_s : tuple of float
        mmae: the bank's peak frequencies; kf: one value; rpem, pem: the initial ω0; raw: ignored [rad/s].
        Default :data:`DEFAULT_OMEGAS_RAD_S` × :func:`wave_frequency_scale` (a :class:`LengthScaledGrid` is
        scaled to the vessel in ``__post_init__``; a plain tuple is kept).
    zeta : float
        WF relative damping ζ of every model [-].
    bias_time_constants_s : (Tx, Ty, Tψ) or None
        None: random-walk bias (seed 002 eq. (33)); else the Markov bias of seed 001 eq. (35)
        (Tx = Ty is required: the vessel-parallel rotation commutes with T only then, seed 001 eq. (27)).
    wf_frame : {"body", "earth"}
        WF states in body axes (seed 001 eq. (34), default: they do not turn with the heading) or
        earth axes (seed 002: rotated with the vessel-parallel states when the heading changes).
    length_m : float or None
        Vessel length for the default tuning [m] (None: estimated from M11).
    wf_position_std_m, wf_heading_std_rad : float or None
        Expected WF motion standard deviation [m], [rad] (None: 0.01·L, 0.5°).
    wf_reference_omega_rad_s : float or None
        ω_ref of the equal-intensity rule [rad/s] (None: geometric mean of ``omegas_rad_s``).
    wf_noise_rule : {"equal_variance", "equal_intensity"}
    lf_velocity_std_mps, lf_yaw_rate_std_radps : float or None
        σ_ν of the LF velocity noise rule [m/s], [rad/s]; a given ``lf_yaw_rate_std_radps`` replaces the
        bandwidth rule in yaw by ``Q2_ψ = 2·M33·D33·σ_r²``.
    lf_yaw_bandwidth_rad_s : float or None
        ω_c of the LF yaw noise rule ``Q2_ψ = I_z²·ω_c⁴·R_ψ·Δt`` [rad/s] (None: ``0.5·√(g/L)``); must lie
        at most π/(2Δt) (half the Nyquist frequency). Ignored for ``raw`` and when ``lf_yaw_rate_std_radps`` is given.
    bias_force_std_n, bias_moment_std_nm : float or None
        σ_b of the bias rule [N], [N·m].
    bias_drift_time_s, bias_yaw_drift_time_s : float
        T_drift of the random-walk bias rule in surge/sway (None: ``360·√(L/g)``) and in yaw [s].
    dead_reckoning_bias : {"mean", "hold"}
        The bias while its measurement is missing (dead reckoning on the model: surge/sway without a position, yaw
        without a heading): ``mean`` (default) relaxes it to its mean over the last ``bias_drift_time_s`` /
        ``bias_yaw_drift_time_s`` (the slowly varying wave drift and gusts it followed averaged out;
        :meth:`~dpcontrol.estimation.wave_filter.FrameFilter._dead_reckoning_bias`), ``hold`` keeps it as it was
        when the measurement was lost.
    bias_learning_s : float or None
        Start-up learning of the bias [s] (kinds mmae, kf steady-state and raw): for this long after the filter
        starts (or restarts from a fix, with the bias at zero) its gains are those of the design model whose bias
        intensity Q3 is ``bias_learning_factor`` times the rule's, then the rule's (None: ``15·√(L/g)``, 42 s
        for the 76 m supply vessel, 5.4 s for CyberShip II; off for ``raw``; 0: off). See
        :meth:`bias_learning_time`.
    bias_learning_factor : float
        Q3's factor during the start-up learning (≥ 1, default 10; 1: off) [-].
    process_noise_intensity : tuple of 9 float or None
        Explicit ``diag(Q1, Q2, Q3)``; overrides the four rules above.
    position_noise_std_m, heading_noise_std_rad : float or None
        Measurement noise per sample [m], [rad] (None: 0.002·L, 0.1°); the heading's at most π.
    weighting : {"bayes", "dwsg"}
        Discrete Bayes with forgetting (default), or the seed 000 eq. (18) DWSG (mmae); see
        :mod:`~dpcontrol.estimation.weighting` for why Bayes is the default.
    likelihood_scale : {"band", "common", "own"}
        ``band`` (default): band-limited, locally whitened, tempered likelihood with the LF-validity
        gate (:class:`~dpcontrol.estimation.weighting.BandLikelihood`, what works in closed loop on a
        real plant); ``common``: per-sample error measure with one fixed normalising covariance
        (minimum-energy criterion, seed 001 ref. [21]); ``own``: seed 000's ``β_i e^{−m_i}`` with each
        filter's innovation covariance S_i (prone to the docs/design.md §5 trap on real seas).
    likelihood_band_rad_s : (float, float) or None
        Prefilter pass band of the ``band`` likelihood [rad/s] (None: ``[ω_1/2, 1.5·ω_N]``).
    likelihood_time_s : float or None
        Time constant of its short-window statistics [s] (None: two periods of the lowest model, 4π/ω_1).
    lf_excess_limit : float
        LF-validity gate of the ``band`` likelihood: low-frequency innovation energy, relative to
        white innovations, above which evidence is scaled down (``inf``: no gate).
    dwsg_rate_per_s : float
        λ of the DWSG [1/s].
    forgetting_time_s : float
        T_f of the Bayes form [s] (α = exp(−dt/T_f)); ``math.inf`` for pure Bayes.
    weight_floor : float
        No weight falls below ``weight_floor`` × the largest weight (0 disables; see
        :mod:`~dpcontrol.estimation.weighting`).
    time_varying : bool
        kf: run the time-varying Joseph-form filter instead of the steady-state one.
    rpem_forgetting : float
        λ of seed 003 eqs. (11)–(12) (0.996 in the paper).
    rpem_omega_min_rad_s, rpem_omega_max_rad_s : float
        Projection range of the RPEM ω0 estimate and search range of PEM's [rad/s] (default 0.2 and 2.0 rad/s ×
        :func:`wave_frequency_scale`, the upper one at most π/(2Δt)).
    rpem_initial_variance : float or None
        Initial P of the RPEM recursion [(rad/s)²] (None: (0.3·ω0)²·(1 − λ_rpem)).
    pem_interval_s : float
        pem: time between batch identifications [s] (seed 002: 20 min, the sea's stationarity time).
    pem_window_s : float
        pem: length of the record each identification uses [s].
    pem_first_s : float
        pem: record length before the first identification [s] (until then the initial ω0, ζ).
    pem_identify_zeta : bool
        pem: identify ζ with ω0 (seed 002 eq. (48)); false keeps ``zeta`` (seed 002's alternative).
    pem_zeta_min, pem_zeta_max : float
        pem: search range of ζ [-].
    pem_wf_std_floor : float
        pem: the identified σ_wf is kept ≥ this fraction of the rule's σ_wf (a calm record must not switch the
        wave model off). The ω0 search range is ``[rpem_omega_min_rad_s, rpem_omega_max_rad_s]``.
    """

    mass_matrix: np.ndarray
    damping_matrix: np.ndarray
    sample_time_s: float
    kind: str = "mmae"
    omegas_rad_s: tuple[float, ...] = DEFAULT_OMEGAS_RAD_S
    zeta: float = 0.1
    bias_time_constants_s: tuple[float, float, float] | None = None
    wf_frame: str = "body"
    length_m: float | None = None
    wf_position_std_m: float | None = None
    wf_heading_std_rad: float | None = None
    wf_reference_omega_rad_s: float | None = None
    wf_noise_rule: str = "equal_variance"
    lf_velocity_std_mps: float | None = None
    lf_yaw_rate_std_radps: float | None = None
    lf_yaw_bandwidth_rad_s: float | None = None
    bias_force_std_n: float | None = None
    bias_moment_std_nm: float | None = None
    bias_drift_time_s: float | None = None
    bias_yaw_drift_time_s: float = 100.0
    dead_reckoning_bias: str = "mean"
    bias_learning_s: float | None = None
    bias_learning_factor: float = 10.0
    process_noise_intensity: tuple[float, ...] | None = None
    position_noise_std_m: float | None = None
    heading_noise_std_rad: float | None = None
    weighting: str = "bayes"
    likelihood_scale: str = "band"
    likelihood_band_rad_s: tuple[float, float] | None = None
    likelihood_time_s: float | None = None
    lf_excess_limit: float = 2.0
    dwsg_rate_per_s: float = 1.0
    forgetting_time_s: float = 600.0
    weight_floor: float = 1e-6
    time_varying: bool = False
    rpem_forgetting: float = 0.996
    rpem_omega_min_rad_s: float = LengthScaledFrequency(0.2)
    rpem_omega_max_rad_s: float = LengthScaledFrequency(2.0)
    rpem_initial_variance: float | None = None
    pem_interval_s: float = 1200.0
    pem_window_s: float = 1200.0
    pem_first_s: float = 300.0
    pem_identify_zeta: bool = True
    pem_zeta_min: float = 0.1
    pem_zeta_max: float = 0.5
    pem_wf_std_floor: float = 1.0

    def __post_init__(self) -> None:  # noqa: C901, PLR0912 - one check per wave-filter setting, each with its own message
        M = np.array(self.mass_matrix, dtype=float)
        D = np.array(self.damping_matrix, dtype=float)
        if M.shape != (3, 3) or not np.all(np.isfinite(M)):
            raise ConfigError("mass_matrix", "a finite 3x3 matrix", self.mass_matrix)
        if D.shape != (3, 3) or not np.all(np.isfinite(D)):
            raise ConfigError("damping_matrix", "a finite 3x3 matrix", self.damping_matrix)
        if np.any(np.linalg.eigvalsh(0.5 * (M + M.T)) <= 0.0):
            raise ConfigError("mass_matrix", "a positive definite matrix", M.tolist())
        if np.any(np.diag(D) <= 0.0):
            raise ConfigError("damping_matrix", "positive diagonal damping", D.tolist())
        M.setflags(write=False)
        D.setflags(write=False)
        object.__setattr__(self, "mass_matrix", M)
        object.__setattr__(self, "damping_matrix", D)
        check_number(self.sample_time_s, "sample_time_s", minimum=0.0, exclusive_minimum=True)
        if self.kind not in KINDS:
            raise ConfigError("kind", "one of " + ", ".join(KINDS), self.kind)
        self._scale_default_frequencies()
        omegas = _tuple_of(self.omegas_rad_s, None, "omegas_rad_s", positive=True)
        object.__setattr__(self, "omegas_rad_s", omegas)
        needed = {"mmae": 1, "kf": 1, "rpem": 1, "pem": 1, "raw": 0}[self.kind]
        if len(omegas) < needed or (self.kind in ("kf", "rpem", "pem") and len(omegas) != 1):
            raise ConfigError("omegas_rad_s", f"exactly one frequency for kind {self.kind}"
                              if self.kind in ("kf", "rpem", "pem") else "at least one frequency", list(omegas))
        if self.kind == "mmae" and len(set(omegas)) != len(omegas):
            raise ConfigError("omegas_rad_s", "distinct frequencies", list(omegas))
        check_number(self.zeta, "zeta", minimum=0.0, exclusive_minimum=True, maximum=1.0)
        if self.bias_time_constants_s is not None:
            T = _tuple_of(self.bias_time_constants_s, 3, "bias_time_constants_s", positive=True)
            if T[0] != T[1]:
                raise ConfigError("bias_time_constants_s", "Tx == Ty (seed 001 eq. (27): the vessel-parallel "
                                  "rotation commutes with T only then)", list(T))
            object.__setattr__(self, "bias_time_constants_s", T)
        for name, choices in (("wf_frame", WF_FRAMES), ("wf_noise_rule", WF_NOISE_RULES), ("weighting", WEIGHTINGS),
                              ("likelihood_scale", LIKELIHOOD_SCALES), ("dead_reckoning_bias", DEAD_RECKONING_BIAS)):
            if getattr(self, name) not in choices:
                raise ConfigError(name, "one of " + ", ".join(choices), getattr(self, name))
        for name in ("length_m", "wf_position_std_m", "wf_heading_std_rad", "wf_reference_omega_rad_s",
                     "lf_velocity_std_mps", "lf_yaw_rate_std_radps", "lf_yaw_bandwidth_rad_s", "bias_force_std_n",
                     "bias_moment_std_nm",
                     "position_noise_std_m", "heading_noise_std_rad", "rpem_initial_variance"):
            value = getattr(self, name)
            if value is not None:
                check_number(value, name, minimum=0.0, exclusive_minimum=True)
        # upper bounds: a heading noise beyond half a turn carries no heading (and the yaw rule scales Q2_ψ with
        # R_ψ: an absurd R_ψ would leave the Riccati equation unsolvable); ω_c·Δt ≤ π/2 as for the wave
        # frequencies, where the continuous-time rule still holds
        for name, maximum in (("heading_noise_std_rad", math.pi),
                              ("lf_yaw_bandwidth_rad_s", 0.5 * math.pi / float(self.sample_time_s))):
            if getattr(self, name) is not None:
                check_number(getattr(self, name), name, maximum=maximum)
        if self.bias_drift_time_s is not None:
            check_number(self.bias_drift_time_s, "bias_drift_time_s", minimum=0.0, exclusive_minimum=True)
        check_number(self.bias_yaw_drift_time_s, "bias_yaw_drift_time_s", minimum=0.0, exclusive_minimum=True)
        if self.bias_learning_s is not None:
            check_number(self.bias_learning_s, "bias_learning_s", minimum=0.0)
        check_number(self.bias_learning_factor, "bias_learning_factor", minimum=1.0)
        if self.process_noise_intensity is not None:
            object.__setattr__(self, "process_noise_intensity",
                               _tuple_of(self.process_noise_intensity, 9, "process_noise_intensity",
                                         nonnegative=True))
        if self.likelihood_band_rad_s is not None:
            band = _tuple_of(self.likelihood_band_rad_s, 2, "likelihood_band_rad_s", positive=True)
            if not band[0] < band[1]:
                raise ConfigError("likelihood_band_rad_s", "[low, high] with 0 < low < high [rad/s]", list(band))
            if band[1] >= math.pi / float(self.sample_time_s):
                raise ConfigError("likelihood_band_rad_s", f"a high edge below the Nyquist frequency "
                                  f"{math.pi / float(self.sample_time_s):g} rad/s", list(band))
            object.__setattr__(self, "likelihood_band_rad_s", band)
        if self.likelihood_time_s is not None:
            check_number(self.likelihood_time_s, "likelihood_time_s", minimum=0.0, exclusive_minimum=True)
        if not (isinstance(self.lf_excess_limit, (int, float)) and not isinstance(self.lf_excess_limit, bool)
                and self.lf_excess_limit > 0.0 and not math.isnan(self.lf_excess_limit)):
            raise ConfigError("lf_excess_limit", "a number > 0 (inf: no gate)", self.lf_excess_limit)
        check_number(self.dwsg_rate_per_s, "dwsg_rate_per_s", minimum=0.0, exclusive_minimum=True)
        if not (isinstance(self.forgetting_time_s, (int, float)) and not isinstance(self.forgetting_time_s, bool)
                and self.forgetting_time_s > 0.0 and not math.isnan(self.forgetting_time_s)):
            raise ConfigError("forgetting_time_s", "a number > 0 (inf: no forgetting)", self.forgetting_time_s)
        check_number(self.weight_floor, "weight_floor", minimum=0.0, maximum=0.1)
        if not isinstance(self.time_varying, bool):
            raise ConfigError("time_varying", "true or false", self.time_varying)
        check_number(self.rpem_forgetting, "rpem_forgetting", minimum=0.9, maximum=1.0)
        check_number(self.rpem_omega_min_rad_s, "rpem_omega_min_rad_s", minimum=0.0, exclusive_minimum=True)
        check_number(self.rpem_omega_max_rad_s, "rpem_omega_max_rad_s", minimum=self.rpem_omega_min_rad_s,
                     exclusive_minimum=True)
        if self.kind in ("rpem", "pem") and self.zeta >= 1.0:
            raise ConfigError("zeta", f"ζ < 1 for kind {self.kind} (underdamped WF model)", self.zeta)
        for name in ("pem_interval_s", "pem_window_s", "pem_first_s"):
            check_number(getattr(self, name), name, minimum=0.0, exclusive_minimum=True, maximum=86400.0)
        if not isinstance(self.pem_identify_zeta, bool):
            raise ConfigError("pem_identify_zeta", "true or false", self.pem_identify_zeta)
        check_number(self.pem_zeta_min, "pem_zeta_min", minimum=0.0, exclusive_minimum=True, maximum=0.9)
        check_number(self.pem_zeta_max, "pem_zeta_max", minimum=self.pem_zeta_min, exclusive_minimum=True,
                     maximum=0.95)
        check_number(self.pem_wf_std_floor, "pem_wf_std_floor", minimum=0.0, exclusive_minimum=True, maximum=1.0)
        if self.kind in ("pem", "rpem") and not self.rpem_omega_min_rad_s <= omegas[0] <= self.rpem_omega_max_rad_s:
            raise ConfigError("omegas_rad_s", f"an initial ω0 in [{self.rpem_omega_min_rad_s:g}, "
                              f"{self.rpem_omega_max_rad_s:g}] rad/s", omegas[0])

    def _scale_default_frequencies(self) -> None:
        """Replace the default wave frequencies (:class:`LengthScaledGrid`, :class:`LengthScaledFrequency`) by
        their values for this vessel, ``ω·√(max(1, L_ref/L))`` (:func:`wave_frequency_scale`); the default upper
        bound of the ω0 search is kept at π/(2Δt) (four samples a period, where the discretised model still
        holds). Given values are kept."""
        if self.length_m is not None:
            check_number(self.length_m, "length_m", minimum=0.0, exclusive_minimum=True)
        scale = wave_frequency_scale(self.length_scale_m)
        if isinstance(self.omegas_rad_s, LengthScaledGrid):
            object.__setattr__(self, "omegas_rad_s", tuple(scale * w for w in self.omegas_rad_s))
        if isinstance(self.rpem_omega_min_rad_s, LengthScaledFrequency):
            object.__setattr__(self, "rpem_omega_min_rad_s", scale * float(self.rpem_omega_min_rad_s))
        if isinstance(self.rpem_omega_max_rad_s, LengthScaledFrequency):
            highest = 0.5 * math.pi / float(self.sample_time_s)
            object.__setattr__(self, "rpem_omega_max_rad_s", min(scale * float(self.rpem_omega_max_rad_s), highest))

    # ----------------------------------------------------------------------------------------
    # Derived tuning (module docstring)
    @property
    def length_scale_m(self) -> float:
        """L for the default rule [m]: ``length_m`` or ``(107·M11/ρ)^{1/3}``."""
        if self.length_m is not None:
            return float(self.length_m)
        return float((107.0 * self.mass_matrix[0, 0] / _RHO_KGPM3) ** (1.0 / 3.0))

    @property
    def reference_omega_rad_s(self) -> float:
        """ω_ref of the equal-intensity WF rule [rad/s]."""
        if self.wf_reference_omega_rad_s is not None:
            return float(self.wf_reference_omega_rad_s)
        if not self.omegas_rad_s:
            return 0.8
        return float(np.exp(np.mean(np.log(self.omegas_rad_s))))

    def wf_std(self) -> np.ndarray:
        """Expected WF motion standard deviation (3,) [m, m, rad]."""
        pos = self.wf_position_std_m if self.wf_position_std_m is not None else 0.01 * self.length_scale_m
        yaw = self.wf_heading_std_rad if self.wf_heading_std_rad is not None else math.radians(0.5)
        return np.array([pos, pos, yaw])

    def wf_intensity(self, omega_rad_s: float) -> np.ndarray:
        """Q1 (3,) of the model at ω0 [m²/s, m²/s, rad²/s] (explicit or by ``wf_noise_rule``)."""
        if self.process_noise_intensity is not None:
            return np.array(self.process_noise_intensity[0:3])
        omega = omega_rad_s if self.wf_noise_rule == "equal_variance" else self.reference_omega_rad_s
        return 4.0 * self.zeta * omega * self.wf_std() ** 2

    def lf_yaw_bandwidth(self) -> float:
        """ω_c of the LF yaw noise rule [rad/s]: ``lf_yaw_bandwidth_rad_s`` or ``0.5·√(g/L)`` (Froude scaled)."""
        if self.lf_yaw_bandwidth_rad_s is not None:
            return float(self.lf_yaw_bandwidth_rad_s)
        return 0.5 * math.sqrt(_GRAVITY_MPS2 / self.length_scale_m)

    def force_intensity(self) -> np.ndarray:
        """Q2 (3,) [N²·s, N²·s, N²·m²·s] (module docstring).

        Surge/sway: ``2·M_ii·D_ii·σ_ν²``. Yaw with wave states: ``Q2_ψ = I_z²·ω_c⁴·R_ψ·Δt``, so that the
        steady-state LF heading filter, nearly a double integrator, has the error poles ``ω_c·e^{±j3π/4}``
        (Kalman–Bucy: ``ω_c = (q/r)^{1/4}`` for ``q = Q2_ψ/I_z²`` [rad²/s³], ``r = R_ψ·Δt`` [rad²·s]); seed 002
        eq. (45) takes Q2 as a fraction of the measurement noise variance, and ω_c sets the fraction. Yaw with
        ``lf_yaw_rate_std_radps`` given, or without wave states (``raw``): ``2·M33·D33·σ_r²``, σ_r defaulting
        to ``0.002·√(g/L)``.
        """
        if self.process_noise_intensity is not None:
            return np.array(self.process_noise_intensity[3:6])
        L = self.length_scale_m
        M = np.diag(self.mass_matrix)
        D = np.diag(self.damping_matrix)
        # without wave states (raw) the LF model must follow the wave motion too: the former, faster rule
        factor = 0.002 if self.kind == "raw" else 0.001
        v = self.lf_velocity_std_mps if self.lf_velocity_std_mps is not None else factor * math.sqrt(_GRAVITY_MPS2 * L)
        surge_sway = 2.0 * M[:2] * D[:2] * v**2
        if self.lf_yaw_rate_std_radps is not None or self.kind == "raw":
            r = (self.lf_yaw_rate_std_radps if self.lf_yaw_rate_std_radps is not None
                 else 0.002 * math.sqrt(_GRAVITY_MPS2 / L))
            yaw = 2.0 * M[2] * D[2] * r**2
        else:
            # The heading filter's bandwidth follows the gyro: a fixed σ_r made it 0.5–1 rad/s on a quiet
            # full-scale gyro (inside the wave band) and 10 rad/s on CyberShip II; tied to R_ψ it is ω_c on any.
            r_psi = float(self.measurement_covariance()[2, 2])
            yaw = M[2] ** 2 * self.lf_yaw_bandwidth() ** 4 * r_psi * self.sample_time_s
        return np.array([surge_sway[0], surge_sway[1], yaw])

    def bias_std(self) -> np.ndarray:
        """σ_b (3,) [N, N, N·m] of the bias rule."""
        L = self.length_scale_m
        v_c = 0.02 * math.sqrt(_GRAVITY_MPS2 * L)
        D = self.damping_matrix
        force = self.bias_force_std_n if self.bias_force_std_n is not None else 0.5 * (D[0, 0] + D[1, 1]) * v_c
        moment = self.bias_moment_std_nm if self.bias_moment_std_nm is not None else D[2, 2] * v_c / L
        return np.array([force, force, moment])

    def bias_drift_time(self) -> float:
        """T_drift of the surge/sway bias [s]: ``bias_drift_time_s`` or ``360·√(L/g)`` (Froude scaled)."""
        if self.bias_drift_time_s is not None:
            return float(self.bias_drift_time_s)
        return 360.0 * math.sqrt(self.length_scale_m / _GRAVITY_MPS2)

    def bias_learning_time(self) -> float:
        """T_learn of the start-up bias learning [s]: ``bias_learning_s`` or ``15·√(L/g)`` (Froude scaled, 42 s
        on the 76 m supply vessel: past a 20 s standby and the first 20 s of DP); 0 when off (``bias_learning_factor``
        1 too; by default for ``raw``).

        Why: a filter starts with the bias at zero and its steady-state covariance, the accuracy of a bias that
        has been tracked for many drift times, while the bias is unknown by the whole environmental force; its
        gains, made for a bias that changes by σ_b in ``bias_drift_time_s``, then take minutes to learn it (the
        supply vessel's sway bias at 38 % of the environment's after 20 s of standby in the failsafe campaign's
        `--seed 2` run 4, its position estimate 0.36 m behind the drifting vessel; docs/fault-handling.md). A
        time-varying Kalman filter started with the bias's prior variance has large gains at first; the
        steady-state bank approximates that with the gains of a Q3 ``bias_learning_factor`` times larger for
        T_learn, then its own.
        """
        if self.bias_learning_factor == 1.0:
            return 0.0
        if self.bias_learning_s is not None:
            return float(self.bias_learning_s)
        if self.kind == "raw":
            # without wave states the WF motion reaches the LF states: the larger gains pass it to the bias (a
            # drifting supply vessel's bias error 2–5× the steady gains' in the sea of
            # tests/unit/test_estimation_wave_filter.py)
            return 0.0
        return 15.0 * math.sqrt(self.length_scale_m / _GRAVITY_MPS2)

    def bias_intensity(self) -> np.ndarray:
        """Q3 (3,) [N²/s, N²/s, N²·m²/s]."""
        if self.process_noise_intensity is not None:
            return np.array(self.process_noise_intensity[6:9])
        if self.bias_time_constants_s is None:
            drift = self.bias_drift_time()
            return self.bias_std() ** 2 / np.array([drift, drift, self.bias_yaw_drift_time_s])
        return 2.0 * self.bias_std() ** 2 / np.asarray(self.bias_time_constants_s)

    def likelihood_band(self) -> tuple[float, float]:
        """Prefilter pass band of the ``band`` likelihood [rad/s]: explicit, or ``[ω_1/2, 1.5·ω_N]``.

        The sea of the lowest model starts at ≈ 0.8·ω_1 and a JONSWAP peaked at the top model keeps
        its energy up to ≈ 1.5·ω_N; the high edge is kept below 0.9 × the Nyquist frequency.
        """
        if self.likelihood_band_rad_s is not None:
            return (float(self.likelihood_band_rad_s[0]), float(self.likelihood_band_rad_s[1]))
        omegas = self.omegas_rad_s or (0.8,)
        nyquist = math.pi / self.sample_time_s
        return (0.5 * min(omegas), min(1.5 * max(omegas), 0.9 * nyquist))

    def likelihood_scale_time_s(self) -> float:
        """Short-window time constant of the ``band`` likelihood [s]: explicit, or 4π/ω_1."""
        if self.likelihood_time_s is not None:
            return float(self.likelihood_time_s)
        return 4.0 * math.pi / min(self.omegas_rad_s or (0.8,))

    def measurement_covariance(self) -> np.ndarray:
        """R (3, 3) per sample [m², m², rad²]."""
        pos = self.position_noise_std_m if self.position_noise_std_m is not None else 0.002 * self.length_scale_m
        yaw = self.heading_noise_std_rad if self.heading_noise_std_rad is not None else math.radians(0.1)
        return np.diag([pos**2, pos**2, yaw**2])

    # ----------------------------------------------------------------------------------------
    @staticmethod
    def from_options(mass_matrix: np.ndarray, damping_matrix: np.ndarray, sample_time_s: float, *, kind: str,
                     omegas_rad_s: Sequence[float], zeta: float, options: Mapping[str, Any] | None = None,
                     length_m: float | None = None, path: str = "estimator",
                     section_keys: Iterable[str] = ()) -> WaveFilterConfig:
        """Build from the runtime's estimator settings; errors carry ``path`` + the key.

        Parameters
        ----------
        mass_matrix, damping_matrix : ndarray, shape (3, 3)
        sample_time_s : float
            Control period [s].
        kind : str
        omegas_rad_s : sequence of float
            [rad/s]; a :class:`LengthScaledGrid` (the default) is scaled to the vessel, anything else kept.
        zeta : float
        options : mapping, optional
            Any other field of this class by name (YAML scalars/lists); unknown keys are rejected.
        length_m : float, optional
            Vessel length for the default tuning (an ``options`` entry wins).
        path : str
            Key path of the section, for error messages.
        section_keys : iterable of str
            The section's keys the caller read itself (its frequency key, ``zeta``): listed with this class's
            fields when a typo is refused.

        Raises
        ------
        ConfigError
        """
        section = Section.of(options, path)
        known = {f.name for f in fields(WaveFilterConfig)} - {
            "mass_matrix", "damping_matrix", "sample_time_s", "kind", "omegas_rad_s", "zeta"}
        values: dict[str, Any] = {}
        if length_m is not None:
            values["length_m"] = length_m
        for key in list(section.data):
            if key in known:
                value = section.raw(key)
                if key in ("forgetting_time_s", "lf_excess_limit") and value in ("inf", ".inf"):
                    value = math.inf
                values[key] = tuple(value) if isinstance(value, list) else value
        # (only the keys present were read: a typo is told every key of the section, the caller's among them)
        section.finish(also_valid=known | set(section_keys))
        try:
            return WaveFilterConfig(mass_matrix=mass_matrix, damping_matrix=damping_matrix,
                                    sample_time_s=sample_time_s, kind=kind,
                                    omegas_rad_s=omegas_rad_s if isinstance(omegas_rad_s, LengthScaledGrid)
                                    else tuple(omegas_rad_s),
                                    zeta=zeta, **values)
        except ConfigError as error:
            raise ConfigError(join(path, error.path), error.expected, error.got, show_got=error.show_got) from None
