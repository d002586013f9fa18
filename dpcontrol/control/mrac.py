"""MRAC-augmented PD controller (seed 003 eqs. (15)–(25)), one SISO loop per DOF.

Per DOF (surge, sway, yaw) in the vessel-parallel frame, seed 003 writes the plant and the
reference model as

    m ÿ + c ẏ = u                                   (16)   (K = 0: no mooring)
    m_M ÿ_M + c_M ẏ_M + k_M y_M = u_c               (15)

with β₀ = k_M/m_M = ω_M², β₁ = c_M/m_M = 2ζω_M (natural period 200 s and ζ = 1 by default). The
reference model is driven by the guidance, ``u_c = k_M η_d`` (so ``y_M`` follows the guidance with
the dynamics the adaptive loop makes the vessel match). With ``e = y − y_M``

    z = ÿ_M − β₁ ė − β₀ e                           (17)
    u = â₂ z + â₁ ẏ,      v = [z, ẏ]ᵀ,  â = [â₂, â₁]ᵀ          (18)
    ë + β₁ ė + β₀ e = vᵀ ã / m                      (19)
    ẋ = A x + b vᵀã/m,   A = [[0, 1], [−β₀, −β₁]],  b = [0, 1]ᵀ,  x = [e, ė]ᵀ       (20)
    GA + AᵀG = −Q_C,     â̇ = −Γ v bᵀ G x            (20)–(21)

so that ``â₂ → m`` (mass incl. added mass) and ``â₁ → c`` (damping) under persistent excitation,
and the law keeps the PD structure of eq. (25): ``u = −â₂β₁ ė − â₂β₀ e + â₂ ÿ_M + â₁ ẏ`` — a PD
with gains ``P = â₂β₀``, ``D = â₂β₁`` retuned on line. The errors are rotated into body axes
with the estimated heading (``e_b = Rᵀ(ψ̂)(η̂ − y_M)``), the bias estimated by the wave filter is
compensated as in the commercial PD (``τ = u − b̂``, seed 003 Fig. 5) and the optional wind
feed-forward adds ``−τ̂_wind`` (seed 002 eq. (35)). ``G`` is solved once with
:func:`scipy.linalg.solve_continuous_lyapunov`.

Robustness for a real sea
-------------------------
Residual wave-frequency motion and estimator noise in ``e`` and ``ė`` make the regressor ``z``
(which itself contains ``−β₁ė − β₀e``) correlated with the error signal ``bᵀGx``: the product
``z·bᵀGx`` has the negative mean ``−g₁₂(β₀⟨e²⟩ + …  + (g₂₂/g₁₂)β₁⟨ė²⟩)`` and the pure law (21)
makes the mass estimate drift upwards without bound — the classical parameter drift of adaptive
control (in the single-DOF tanker case with 0.25 m of WF surge motion the pure law takes â₂
from 1× to 3× the true mass in 12 h of station keeping). This implementation uses

* the **reference-model regressor** (default, ``regressor: reference``): the law adapts with
  ``v_M = [ÿ_M, ẏ_M]ᵀ`` of the noise-free reference model instead of ``v = [z, ẏ]ᵀ``,
  ``â̇ = −Γ v_M bᵀG x`` — the "desired compensation" adaptation law of Sadegh & Horowitz (1990).
  ``v − v_M = [−β₁ė − β₀e, ė]`` is of the order of the tracking error, so the law is the same where
  the MRAC tracks, but the regressor no longer carries the estimator's noise and the correlation
  above is gone. On the plant (3-DOF tanker, lockstep, 3 h of seed 003's schedule) the plant
  regressor took â₂ to +55 % of the true mass, the reference regressor keeps it within ±10 %.
  ``regressor: plant`` gives seed 003's eq. (21);
* **excitation gating**: ``â₂`` adapts only while the reference model accelerates,
  ``|ÿ_M| > a_min`` (and ``â₁`` only while ``|ẏ_M| > v_min``), measured on the noise-free
  reference model: the information about the mass is in the reference acceleration, and while
  the reference rests the only thing to "learn" is noise;
* a **dead zone** on the normalised error signal ``s̄ = bᵀGx / g₁₂ = e + (g₂₂/g₁₂) ė`` [m or
  rad]: no adaptation while ``|s̄| ≤ d`` and ``s̄ − d·sign(s̄)`` outside (continuous). ``d = d₀`` (fixed, 0.02 % of
  L) or, with ``dead_zone_noise_factor`` k > 0 (the default with ``reference: guidance`` on a vessel of constant
  mass), sized from the disturbance as robust adaptive control prescribes (Ioannou & Sun, *Robust Adaptive
  Control*, §8.5.4):
  ``d = max(d₀, k·s̄_rms + |w − w̄|/P)``, ``s̄_rms`` the RMS of s̄ measured once the reference has rested a
  reference-model period (the error is then all weather: waves, estimator noise, the force the bias estimate has
  not taken up), k = 3, and ``|w − w̄|/P`` the change of the compensated weather force ``w = b̂ + τ̂_wind`` over
  the last period through the PD's stiffness ``P = â₂β₀`` — the error the bias estimate's lag leaves while a
  turn swings a current or wind force across the hull (:func:`~dpcontrol.control.kernels.dead_zone_width`).
  The supply vessel's station-keeping error in a sea is tenths of a metre (0.23 m rms, 0.56 m at the start of a
  move, in 13.6 m/s of wind and 0.7 m/s of current); the fixed d₀ (1.5 cm for her) let the law take it for
  inertia the moment the reference accelerated and run the estimate onto its bound within 13 s; in a turn in
  0.7 m/s of current the bias estimate changes by 40–50 kN within a minute and its lag leaves her 1.3–2.5 m
  behind the reference. With seed 003's reference model (the tanker) it is off by default: in the loading
  tanker's excerpt (``tests/closed_loop/test_seed003.py``) the bias estimate also takes up her inertia error and
  the measured dead zone slows the learning of the 2.4× mass error past seed 003's 0.5 m (0.53 m in the third
  correction with the rest term alone, k = 3);
* **projection** of ``â₂`` onto ``[0.3, 5] × m_nominal`` and of ``â₁`` onto
  ``[0, max(20 c_nominal, m_nominal β₁)]`` (physical bounds: a vessel neither loses 70 % of
  its mass nor quintuples it), so that whatever drift is left stays bounded. Where â₁ adapts
  (Γ₂₂ > 0) its bound is also ``ĉ_min + κ β₁ â₂`` (κ = ``damping_bound_kappa``, 0.9): the frozen loop
  of eq. (23), ``m ÿ + (c + â₂β₁ − â₁) ẏ + â₂β₀ y = (â₂/m_M) u_c``, then keeps the damping
  ``c + â₂β₁ − â₁ ≥ (1 − κ) β₁ â₂ > 0`` for every admissible estimate and every true ``c ≥ ĉ_min`` (the
  static bound alone allowed â₁ = m_nom β₁ with â₂ = 0.3 m_nom: ``c − 0.7 m_nom β₁ < 0``, unstable).

Coupling
--------
Seed 003 writes one SISO plant (16) per DOF. The hull is not diagonal: ``M ν̇ + C(ν)ν + Dν = τ`` (seed 002
eqs. (1)–(10)) couples sway and yaw through M₂₃ and D₂₃, D₃₂, and the body-frame acceleration of a reference
that turns is not ``Rᵀÿ_M`` but ``ν̇_M = Rᵀÿ_M − S(r_M)ν_M``. The per-DOF law then meets, in each DOF, a force
it does not model that correlates with the reference acceleration of a move that changes position and heading
together, and takes it for inertia (measured with ``benchmarks/mrac_estimate_bias.py``, perfect state, no
weather, 24 moves of 0.08 L and 10°: the supply vessel's sway and yaw estimates +22 %, +23 %, CyberShip II's
yaw +11 %; single-DOF moves leave them at 1.000). What the nominal model knows goes into a known part, what is
adapted stays per DOF (``coupling``, default all four of)

* ``rotation``: the regressor and z of eq. (17) use ν̇_M = Rᵀÿ_M − S(r_M)ν_M, ν_M = Rᵀẏ_M, r_M = ẏ_M,ψ;
* ``inertia``: ``Σ_{j≠i} M_ij z_j`` — eq. (25) becomes the PD ``P = M̂β₀``, ``D = M̂β₁`` with the matrix
  ``M̂ = diag(â₂) + M_off``;
* ``coriolis``: ``C(ν_M)ν_M`` of the nominal M (the (M₁₁ − M₂₂)uv Munk moment, −M₂₂vr, M₁₁ur);
* ``damping``: ``Σ_{j≠i} D_ij ν_j``, the off-diagonal linear damping.

With them the error dynamics are ``M (ë + β₁ė + β₀e) = diag(v) ã`` and, the β's being the same in every DOF,
``V = xᵀ(M ⊗ G)x + ãᵀΓ⁻¹ã`` gives ``V̇ = −xᵀ(M ⊗ Q_C)x`` for the per-DOF law (21) unchanged: seed 003's
proof and structure carry over. On a diagonal hull moving one DOF at a time (seed 003's tanker) every term is
zero. The same benchmark with them: every estimate of every vessel within 0.1 % except the tanker's sway
(−6.1 %, as in a sway-only move: the quadratic sway drag, which the linear design model lacks; the optional
``drag`` term ``d_i|ν_M,i|ν_M,i`` removes it in still water, but in a current the drag acts on the unknown
ν − ν_c, so it is not in the default). ``coupling: []`` gives seed 003's diagonal law.

The actuators' lag
------------------
The desired-compensation law assumes that the force commanded is the force the vessel gets. The thrusters deliver
it through their drives' first-order response ``τ_a = τ/(1 + T_u s)`` (``time_constant_s`` of each thruster: 2 s on
the supply vessel), so the feed-forward ``â₂ÿ_M`` arrives as ``â₂(ÿ_M − T_u y⃛_M + O(T_u²))``: the error dynamics
(19) become ``m(ë + β₁ė + β₀e) = (â₂ − m)ÿ_M − â₂T_u y⃛_M + …``, and the error the jerk term drives through
``1/(s² + β₁s + β₀)`` correlates with ÿ_M, which the law (21) takes for inertia (measured in docs/campaigns.md,
"The actuators' lag"). With ``actuator_time_constant_s`` the feed-forward is led by the lag's inverse on the
reference, ``z = ÿ_M + T_u y⃛_M − β₁ė − β₀e`` with
``y⃛_M = β₀(η̇_d − ẏ_M) − β₁ÿ_M`` [m/s³, rad/s³], the derivative of model (15) (exact: no signal is
differentiated), so that the force delivered is ``â₂ÿ_M`` to first order in ``T_u ω_M`` and the error equation
is again (19), with the lag acting only on the PD terms of the tracking error, which are of the order of ``e``: the
regressor ``v_M = [ÿ_M, ẏ_M]`` and the law (21) are unchanged. Model reference control cancels the plant's known,
stable dynamics so that the closed loop matches the reference model (Ioannou & Sun, *Robust Adaptive Control*,
ch. 6); the actuators' lag is such a known part, and the reference being smooth with its derivative known, its
inverse is realisable on the feed-forward. ``actuator_time_constant_s: thrusters`` takes ``T_u`` per DOF as the
mean of the thrusters' time constants weighted by the force each gives in the DOF (:func:`actuator_time_constants`):
what the vessel configuration gives, nothing tuned. Not with ``reference: guidance`` (the guidance gives no jerk; its
acceleration saturates without a jerk limit) nor a step-driven model (its acceleration jumps), and not the
thrust-rate limits, the azimuths' slewing or the wave filter's estimate. Off by default (T_u = 0, seed 003's law):
in the full loop the lag's upward bias is the smaller part of what the law takes for inertia and partly offsets
the rest (the loading tanker's estimate, until now slightly high, ends lower with the lead; docs/campaigns.md).

Gating and a dead zone rather than σ-modification are the default because the operation the
controller is made for — loading a shuttle tanker, seed 003 — changes the mass by 2.66× while the
excitation comes in bursts (a set-point correction every 30 min): leakage would pull the estimate
back towards the *ballast* mass between bursts (a bias growing with the loading), whereas gating
and the dead zone simply hold the last estimate when there is nothing to learn from.
σ-modification (``â̇ = … − σΓ(â − â_nominal)``, integrated exactly) is available
(``leakage_per_s``) for vessels whose parameters do not change. Adaptation is also frozen in a
DOF whose last command the allocator could not deliver (the error is then caused by saturation,
not by a wrong mass).

The adaptive law is integrated with the error signals held over the sample (zero-order hold),
which is the exact integral of (21) for piecewise-constant signals, followed by the projection;
the reference model (15) is discretised exactly for each step's ``dt`` (the matrix exponential in closed
form, :func:`~dpcontrol.control.kernels.reference_transition`: the daemon's measured period changes every
cycle).

The entry glide: after an entry into DP (default design: ``entry_rest_s`` = one reference-model period)
nothing is learnt until the reference model has rested that long without a break. The bumpless entry
starts the reference at the vessel's velocity, and the reference then decelerates the drift the weather gave her, so the
reference acceleration of the glide points against the weather's force, which the bias estimate has not
yet taken up, and the error it sees is that force: the law takes it for inertia. Measured in the seed
scenarios with the glide learnt from: CyberShip II's surge mass at 5× within 10 s of engaging, the supply
vessel's sway mass at 2.8× in 10 s.

Damping: â₁ is not adapted by default in the runtime configuration (``Γ₂₂ = 0``, configurable). At
DP speeds the damping hardly shows in a set-point move (seed 003 Fig. 11: "an oscillatory
behavior was found in damping estimation ... damping effect in surge motion is extremely small"),
and on the plant the current drag, which depends on the speed through the water, drove â₁ to its
lower bound and the mass estimate, which shares the error signal, 30 % high.

Reference excitation: in the runtime the MRAC reference model is driven by the guidance
(:class:`~dpcontrol.guidance.reference_model.ReferenceModel`, third order with speed and acceleration
limits), not by seed 003's raw set-point steps, and a move excites it far less (tanker, 20 m:
max ÿ_M = 1.8·10⁻³ instead of β₀ℓ = 2·10⁻² m/s²). :func:`default_mrac_config` therefore scales Γ by
the excitation energy of a typical move through the vessel's default guidance
(:func:`reference_excitation`) and sets the gating thresholds from that move;
``step_driven=True`` keeps the step design (the single-DOF study of
:mod:`sim_plant.bench.offloading_case`).

In the runtime (:mod:`dpcontrol.runtime.step`) an adapting MRAC also hands its mass estimate to the
DP wave filter between moves (:class:`~dpcontrol.runtime.estimators.MassAdaptiveEstimator`): a filter
on the ballast model misleads the adaptation as the tanker fills. :attr:`MracController.excited`
tells when the gate is closed.

Adaptation gains: at the frequencies a step excites (around ω_M) the error filter
``1/(s² + β₁s + β₀)`` puts ``ė`` in phase with ``z``, and ``g₂₂ ≈ q_e/(2β₀β₁)`` dominates
``bᵀGx``; averaging ``z²`` over the ≈ 3/ω_M a reference step of ``ℓ`` metres takes
(``⟨z²⟩ ≈ β₀²ℓ²/12``) gives the convergence rate ``λ ≈ Γ₁₁ q_e ℓ² / (96 ζ m)`` for â₂ and
likewise ``Γ₂₂ q_e ℓ² / (96 ζ m β₀)`` for â₁. :func:`adaptation_gains` inverts this for a time
constant ``T_a``: ``Γ₁₁ = 96 ζ m_nom / (q_e ℓ² T_a)``, ``Γ₂₂ = β₀ Γ₁₁``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import expm, solve_continuous_lyapunov

from dpbase.frames import ssa
from dpbase.schema import ConfigError, Section, check_vector
from dpcontrol.allocation.geometry import ThrusterGeometry
from dpcontrol.control.base import (
    ADAPTATION_STATES,
    ALL_DOFS,
    ControlOutput,
    check_dt,
    checked_state_inputs,
    floats3,
    kernel_arguments,
)
from dpcontrol.control.kernels import (
    C_A1_HI,
    C_A1_LO,
    C_A1_NOMINAL,
    C_A2_HI,
    C_A2_LO,
    C_A2_NOMINAL,
    C_ACCEL,
    C_BETA0,
    C_BETA1,
    C_COUPLING,
    C_DAMPING,
    C_DEAD_ZONE,
    C_DRAG,
    C_ENTRY_REST,
    C_FLAGS,
    C_G12,
    C_G_RATIO,
    C_GAMMA_C,
    C_GAMMA_M,
    C_GUIDED,
    C_INTEGRAL,
    C_LEAD,
    C_MASS,
    C_NOISE_FACTOR,
    C_NOISE_TIME,
    C_OMEGA,
    C_ROWS,
    C_TRACKING,
    C_VELOCITY,
    C_ZETA,
    COUPLE_CORIOLIS,
    COUPLE_DAMPING,
    COUPLE_DRAG,
    COUPLE_INERTIA,
    COUPLE_ROTATION,
    ERROR_INPUT,
    MASS_CHANGED,
    OUT_ERROR,
    OUT_PARAMETERS,
    OUT_REFERENCE_MODEL,
    OUT_SIZE,
    OUT_TAU,
    OUT_VELOCITY_ERROR,
    S_A1,
    S_A2,
    S_ACHIEVED,
    S_COMMAND,
    S_DUTY,
    S_FLAGS,
    S_INTEGRAL,
    S_NOISE,
    S_REST,
    S_ROWS,
    S_Y_M,
    S_YD_M,
    damping_ceiling,
    mrac_step,
)
from dpcontrol.control.pid import INTEGRAL_ACTIONS, default_natural_period_s
from dpcontrol.guidance.reference_model import Reference, ReferenceModel, ReferenceModelConfig, default_reference_config
from dpcontrol.models.vessels import VesselData

PARAMETER_NAMES: tuple[str, ...] = ("mass_surge_kg", "mass_sway_kg", "inertia_yaw_kgm2",
                                    "damping_surge_nspm", "damping_sway_nspm", "damping_yaw_nmsprad")
REGRESSORS: tuple[str, ...] = ("reference", "plant")
#: What y_M is: ``guidance`` the guidance's reference itself (one reference, what the operator sees), ``model``
#: seed 003's second-order model (15) driven by it.
REFERENCES: tuple[str, ...] = ("guidance", "model")
#: Reference-model outputs added to :attr:`ControlOutput.parameters` by :meth:`MracController.step`: the
#: state ``y_M`` of eq. (15) in NED at the step's time (the pose the vessel is made to track).
REFERENCE_MODEL_NAMES: tuple[str, ...] = ("ref_model_north_m", "ref_model_east_m", "ref_model_heading_rad")
#: The known coupling terms of the nominal model the law can add to its per-DOF structure (:class:`MracConfig`
#: ``coupling``; :func:`dpcontrol.control.kernels._known_coupling`): the off-diagonal inertia M_ij z_j, the rotation
#: term −S(r_M)ν_M of the reference's body-frame acceleration, the Coriolis and centripetal force C(ν_M)ν_M and the
#: off-diagonal damping D_ij ν_j (the default: all four), and the optional quadratic drag d_i|ν_M,i|ν_M,i at the
#: reference's velocity (``drag``: right in still water only).
COUPLINGS: tuple[str, ...] = ("inertia", "rotation", "coriolis", "damping", "drag")
DEFAULT_COUPLING: tuple[str, ...] = ("inertia", "rotation", "coriolis", "damping")
_COUPLING_BITS = {"inertia": COUPLE_INERTIA, "rotation": COUPLE_ROTATION, "coriolis": COUPLE_CORIOLIS,
                  "damping": COUPLE_DAMPING, "drag": COUPLE_DRAG}
Triple = tuple[float, float, float]


def _triple(name: str, value: Any, *, positive: bool = True, allow_zero: bool = False) -> Triple:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = (value, value, value)
    out = tuple(float(v) for v in value)
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    if positive and not all(v > 0.0 or (allow_zero and v == 0.0) for v in out):
        raise ValueError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return out  # type: ignore[return-value]


@dataclass(frozen=True)
class MracConfig:
    """Parameters of :class:`MracController` (per DOF: surge, sway, yaw).

    Attributes
    ----------
    mass_nominal : 3 floats
        Initial/nominal ``â₂`` = M_ii incl. added mass [kg, kg, kg·m²].
    damping_nominal : 3 floats
        Initial/nominal ``â₁`` = D_ii [N·s/m, N·s/m, N·m·s/rad] (>= 0).
    adaptation_gain_mass, adaptation_gain_damping : 3 floats
        Γ₁₁, Γ₂₂ per DOF (>= 0; 0 disables adaptation of that parameter).
    natural_period_s, relative_damping : 3 floats
        Reference model (15): ``ω_M = 2π/T``, ζ; β₀ = ω_M², β₁ = 2ζω_M (seed 003: 200 s, 1.0).
    lyapunov_q : 2 floats
        ``Q_C = diag(q_e, q_ė)`` of eq. (20) (seed 003 uses a multiple of the identity).
    dead_zone : 3 floats
        d₀ on ``s̄ = e + (g₂₂/g₁₂)ė`` [m, m, rad] (>= 0): the least dead zone.
    dead_zone_noise_factor : float
        k of the measured dead zone ``d = max(d₀, k·s̄_rms + |w − w̄|/P)``, ``s̄_rms`` the RMS of s̄ once the
        reference has rested one reference-model period, ``|w − w̄|/P`` the change of the weather force compensated
        over that period through the PD's stiffness (>= 0; 0: the fixed d₀ alone;
        :func:`dpcontrol.control.kernels.dead_zone_width`). Not for a vessel whose mass changes: a wrong mass
        shows in both measures too (the bias estimate takes up the inertia error of a move, a too-soft PD lets
        the weather move her more at rest), and the dead zone then holds the estimate back — 0 for a loading
        tanker on the guided reference (docs/campaigns.md).
    accel_threshold : 3 floats
        ``a_min``: â₂ adapts only while ``|ÿ_M| > a_min`` [m/s², m/s², rad/s²] (>= 0).
    velocity_threshold : 3 floats
        ``v_min``: â₁ adapts only while ``|ẏ_M| > v_min`` [m/s, m/s, rad/s] (>= 0).
    mass_bounds_factor, damping_bounds_factor : 2 floats
        Projection bounds of ``â₂`` relative to ``mass_nominal`` and the upper bound of ``â₁``
        relative to ``damping_nominal`` (lower bound 0; upper at least ``m_nom β₁``).
    leakage_per_s : float
        σ of the σ-modification (0 = off) [1/s].
    regressor : {"reference", "plant"}
        Regressor of the adaptive law: ``"reference"`` (default) ``v_M = [ÿ_M, ẏ_M]ᵀ`` of the noise-free
        reference model (desired-compensation law), ``"plant"`` seed 003's ``v = [z, ẏ]ᵀ`` of eq. (21); see
        the module docstring.
    adapt : bool
        False freezes the parameters at the nominal values: the fixed-gain PD of seed 003 eq. (25)
        (config ``control: {kind: mrac, adapt: false}``, the comparison case of seed 003 Fig. 13).
    entry_rest_s : float
        After each entry into DP (:meth:`MracController.reset`) nothing is learnt until the reference model
        has rested (gate closed) this long [s] (>= 0; 0 = learn at once; the default design: one
        reference-model period). See "The entry glide" in the module docstring.
    reference : {"model", "guidance"}
        What the reference y_M of eq. (17) is: ``"model"`` seed 003's second-order model (15) (``natural_period_s``,
        ``relative_damping``) driven by the guidance's η_d, ``"guidance"`` the guidance's η_d, η̇_d, η̈_d
        themselves (one reference: the pose the operator sees, no second lag; β₀, β₁ then set only the error
        dynamics (19)). The configuration's default is ``"guidance"`` (docs/campaigns.md, "One reference");
        this dataclass's and :func:`default_mrac_config`'s is seed 003's ``"model"``.
    mass_coupling : 3 floats
        The nominal off-diagonal inertia (M₁₂, M₁₃, M₂₃) [kg, kg·m, kg·m] (M symmetric; the plant symmetrises
        M_A): known, not adapted (default 0; :func:`default_mrac_config` takes the vessel's).
    damping_coupling : 6 floats
        The nominal off-diagonal linear damping (D₁₂, D₁₃, D₂₁, D₂₃, D₃₁, D₃₂) [N·s, N·s, N·s/m·m, N·s, N·s,
        N·s] (default 0; :func:`default_mrac_config` takes the vessel's).
    coupling : tuple of str
        Which known terms of the nominal model the law adds (subset of :data:`COUPLINGS`, default
        :data:`DEFAULT_COUPLING`; ``()`` is seed 003's diagonal law). See the module docstring, "Coupling".
    quadratic_damping : 3 floats
        d of the optional ``drag`` term [N·s²/m², N·s²/m², N·m·s²] (>= 0; :func:`default_mrac_config` takes
        the vessel's).
    damping_bound_kappa : float
        κ of the joint bound ``â₁ ≤ ĉ_min + κ β₁ â₂`` where â₁ adapts (0 <= κ < 1; 0: the static bound only;
        :func:`dpcontrol.control.kernels.damping_ceiling`).
    actuator_time_constant_s : 3 floats
        T_u per DOF [s] (>= 0): the first-order lag ``1/(1 + T_u s)`` between the command and the force the
        thrusters deliver, which the feed-forward leads by ``T_u y⃛_M`` (see the module docstring, "The actuators'
        lag"; with ``reference: model`` only, not for a step-driven model, whose acceleration jumps; default 0: no
        lead, seed 003's law; ``thrusters`` in the configuration: :func:`actuator_time_constants`).
    integral_action : {"bias_feedforward", "integrator"}
        Where the law's integral action comes from: ``"bias_feedforward"`` (seed 003: the wave filter's bias
        estimate compensated, ``τ = u − b̂``), ``"integrator"`` an integral force ``τ̇_I = −K_I e``,
        ``K_I = integral_ratio · ω_M · â₂β₀`` (the PID's rule, a decade below ω_M, retuned with the PD's
        stiffness), compensated instead of b̂, with conditional integration as anti-windup
        (:func:`dpcontrol.control.kernels.mrac_step`). The configuration's default is the integrator with an
        estimator that estimates no bias (``kalman_bucy``), the bias feed-forward otherwise.
    integral_ratio : float
        K_I over the PD's stiffness times ω_M [-] (> 0; default 0.1, as the PID's pole placement).
    """

    mass_nominal: Triple
    damping_nominal: Triple
    adaptation_gain_mass: Triple
    adaptation_gain_damping: Triple
    natural_period_s: Triple = (200.0, 200.0, 200.0)
    relative_damping: Triple = (1.0, 1.0, 1.0)
    lyapunov_q: tuple[float, float] = (1.0, 1.0)
    dead_zone: Triple = (0.0, 0.0, 0.0)
    dead_zone_noise_factor: float = 0.0
    accel_threshold: Triple = (0.0, 0.0, 0.0)
    velocity_threshold: Triple = (0.0, 0.0, 0.0)
    mass_bounds_factor: tuple[float, float] = (0.3, 5.0)
    damping_bounds_factor: tuple[float, float] = (0.0, 20.0)
    leakage_per_s: float = 0.0
    adapt: bool = True
    regressor: str = "reference"
    entry_rest_s: float = 0.0
    reference: str = "model"
    mass_coupling: Triple = (0.0, 0.0, 0.0)
    damping_coupling: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    coupling: tuple[str, ...] = DEFAULT_COUPLING
    damping_bound_kappa: float = 0.9
    quadratic_damping: Triple = (0.0, 0.0, 0.0)
    actuator_time_constant_s: Triple = (0.0, 0.0, 0.0)
    integral_action: str = "bias_feedforward"
    integral_ratio: float = 0.1

    def __post_init__(self) -> None:
        object.__setattr__(self, "mass_nominal", _triple("mass_nominal", self.mass_nominal))
        object.__setattr__(self, "damping_nominal", _triple("damping_nominal", self.damping_nominal, allow_zero=True))
        for name in ("adaptation_gain_mass", "adaptation_gain_damping", "dead_zone", "accel_threshold",
                     "velocity_threshold", "actuator_time_constant_s"):
            object.__setattr__(self, name, _triple(name, getattr(self, name), allow_zero=True))
        for name in ("natural_period_s", "relative_damping"):
            object.__setattr__(self, name, _triple(name, getattr(self, name)))
        q = tuple(float(v) for v in self.lyapunov_q)
        if len(q) != 2 or not all(math.isfinite(v) and v > 0.0 for v in q):
            raise ValueError(f"lyapunov_q must be 2 numbers > 0, got {self.lyapunov_q!r}")
        object.__setattr__(self, "lyapunov_q", q)
        lo, hi = (float(v) for v in self.mass_bounds_factor)
        if not (0.0 < lo <= 1.0 <= hi and math.isfinite(hi)):
            raise ValueError(f"mass_bounds_factor must satisfy 0 < low <= 1 <= high, got {self.mass_bounds_factor!r}")
        object.__setattr__(self, "mass_bounds_factor", (lo, hi))
        dlo, dhi = (float(v) for v in self.damping_bounds_factor)
        if not (0.0 <= dlo <= 1.0 <= dhi and math.isfinite(dhi)):
            raise ValueError(f"damping_bounds_factor must satisfy 0 <= low <= 1 <= high, got "
                             f"{self.damping_bounds_factor!r}")
        object.__setattr__(self, "damping_bounds_factor", (dlo, dhi))
        if not (math.isfinite(self.entry_rest_s) and self.entry_rest_s >= 0.0):
            raise ValueError(f"entry_rest_s must be finite and >= 0, got {self.entry_rest_s!r}")
        if not (math.isfinite(self.dead_zone_noise_factor) and self.dead_zone_noise_factor >= 0.0):
            raise ValueError(f"dead_zone_noise_factor must be finite and >= 0, got {self.dead_zone_noise_factor!r}")
        if not (math.isfinite(self.leakage_per_s) and self.leakage_per_s >= 0.0):
            raise ValueError(f"leakage_per_s must be finite and >= 0, got {self.leakage_per_s!r}")
        if not isinstance(self.adapt, bool):
            raise ValueError(f"adapt must be true or false, got {self.adapt!r}")
        if self.regressor not in REGRESSORS:
            raise ValueError(f"regressor must be one of {REGRESSORS}, got {self.regressor!r}")
        if self.reference not in REFERENCES:
            raise ValueError(f"reference must be one of {REFERENCES}, got {self.reference!r}")
        if self.integral_action not in INTEGRAL_ACTIONS:
            raise ValueError(f"integral_action must be one of {INTEGRAL_ACTIONS}, got {self.integral_action!r}")
        if not (math.isfinite(self.integral_ratio) and self.integral_ratio > 0.0):
            raise ValueError(f"integral_ratio must be finite and > 0, got {self.integral_ratio!r}")
        object.__setattr__(self, "mass_coupling", _triple("mass_coupling", self.mass_coupling, positive=False))
        object.__setattr__(self, "quadratic_damping", _triple("quadratic_damping", self.quadratic_damping,
                                                              allow_zero=True))
        damping = tuple(float(v) for v in self.damping_coupling)
        if len(damping) != 6 or not all(math.isfinite(v) for v in damping):
            raise ValueError(f"damping_coupling must be 6 finite numbers, got {self.damping_coupling!r}")
        object.__setattr__(self, "damping_coupling", damping)
        if isinstance(self.coupling, str) or not all(name in COUPLINGS for name in self.coupling):
            raise ValueError(f"coupling must be a list of {COUPLINGS}, got {self.coupling!r}")
        object.__setattr__(self, "coupling", tuple(name for name in COUPLINGS if name in self.coupling))
        if not (0.0 <= self.damping_bound_kappa < 1.0):
            raise ValueError(f"damping_bound_kappa must be >= 0 and < 1, got {self.damping_bound_kappa!r}")
        m = self.mass_matrix
        if np.any(np.linalg.eigvalsh(m) <= 0.0):
            raise ValueError(f"mass_nominal with mass_coupling must be a positive definite M, got {m.tolist()}")

    @property
    def mass_matrix(self) -> np.ndarray:
        """The nominal M: ``mass_nominal`` on the diagonal, ``mass_coupling`` off it [kg, kg·m, kg·m²]."""
        (m11, m22, m33), (m12, m13, m23) = self.mass_nominal, self.mass_coupling
        return np.array([[m11, m12, m13], [m12, m22, m23], [m13, m23, m33]])

    @property
    def damping_off_diagonal(self) -> np.ndarray:
        """The nominal D with a zero diagonal (``damping_coupling``) [N·s/m, N·s, N·m·s/rad]."""
        d12, d13, d21, d23, d31, d32 = self.damping_coupling
        return np.array([[0.0, d12, d13], [d21, 0.0, d23], [d31, d32, 0.0]])

    @property
    def beta0(self) -> np.ndarray:
        """β₀ = k_M/m_M = ω_M² per DOF [1/s²]."""
        return np.array([(2.0 * math.pi / t) ** 2 for t in self.natural_period_s])

    @property
    def beta1(self) -> np.ndarray:
        """β₁ = c_M/m_M = 2ζω_M per DOF [1/s]."""
        return np.array([2.0 * z * 2.0 * math.pi / t for z, t in zip(self.relative_damping,
                                                                         self.natural_period_s, strict=True)])


def adaptation_gains(mass_nominal: Sequence[float], natural_period_s: Sequence[float],
                     relative_damping: Sequence[float], excitation: Sequence[float], *,
                     adaptation_time_constant_s: float, lyapunov_q: tuple[float, float] = (1.0, 1.0),
                     excitation_energy: Sequence[float] | None = None) -> tuple[Triple, Triple]:
    """Default Γ₁₁, Γ₂₂ per DOF from an adaptation time constant (see the module docstring).

    Parameters
    ----------
    mass_nominal : 3 floats
        Nominal masses [kg, kg, kg·m²].
    natural_period_s : 3 floats
        Reference-model periods [s].
    relative_damping : 3 floats
        Reference-model ζ.
    excitation : 3 floats
        Typical reference excursion ℓ [m, m, rad].
    adaptation_time_constant_s : float
        T_a [s], for a reference model driven by a step of ℓ.
    excitation_energy : 3 floats, optional
        ``∫ ÿ_M² dt`` of the typical move as the reference model actually sees it [m²/s³, rad²/s³]
        (:func:`reference_excitation`). A step of ℓ gives ``ℓ² ω_M³ / 4`` (ζ = 1); a smoother input
        (the guidance in front of the MRAC) gives less, and Γ is raised by the ratio so that one move
        teaches the estimate as much as one step would (the learning per move is ∝ Γ ∫ z² dt).
    """
    gm = []
    gc = []
    energies = excitation_energy if excitation_energy is not None else (None, None, None)
    for m, t, zeta, ell, energy in zip(mass_nominal, natural_period_s, relative_damping, excitation, energies,
                                       strict=True):
        omega = 2.0 * math.pi / t
        beta0 = omega**2
        base = 96.0 * zeta * m / (adaptation_time_constant_s * lyapunov_q[0] * ell * ell)
        if energy is not None:
            base *= ell * ell * omega**3 / 4.0 / energy
        gm.append(base)
        gc.append(base * beta0)
    return (gm[0], gm[1], gm[2]), (gc[0], gc[1], gc[2])


@dataclass(frozen=True)
class ReferenceExcitation:
    """What the MRAC reference model does during a typical move (per DOF: surge, sway, yaw).

    Attributes
    ----------
    energy : 3 floats
        ``∫ ÿ_M² dt`` [m²/s³, m²/s³, rad²/s³].
    peak_accel : 3 floats
        ``max |ÿ_M|`` [m/s², m/s², rad/s²].
    peak_velocity : 3 floats
        ``max |ẏ_M|`` [m/s, m/s, rad/s].
    """

    energy: Triple
    peak_accel: Triple
    peak_velocity: Triple


@functools.lru_cache(maxsize=32)
def reference_excitation(guidance: ReferenceModelConfig, natural_period_s: Triple, relative_damping: Triple,
                         excitation: Triple, guided: bool = False) -> ReferenceExcitation:
    """The MRAC reference model (15) driven by the guidance's answer to a set-point step of ℓ.

    The runtime drives the MRAC reference model with the output of the guidance
    (:class:`~dpcontrol.guidance.reference_model.ReferenceModel`: third order, speed and acceleration
    limits), not with the raw set-point steps of seed 003: the cascade is smoother and its ÿ_M far
    smaller (for the shuttle tanker and a 20 m move 1.8·10⁻³ m/s² instead of β₀ℓ = 2·10⁻² m/s²).
    Gains and gating thresholds designed for a step would then adapt ≈ 100× too slowly (seed 003's
    mass estimate would not keep up with the loading). Simulated once per configuration (cached):
    north and heading moved together (independent channels; sway is surge's mirror image). ``guided``: y_M is
    the guidance's reference itself (``reference: guidance``), whose own acceleration and speed count.
    """
    model = ReferenceModel(guidance)
    model.reset(np.zeros(3))
    dofs = (0, 2)  # surge (north at ψ = 0) and yaw; sway = surge by symmetry
    period = max(*natural_period_s, *guidance.natural_period_s)
    dt = min(*natural_period_s, *guidance.natural_period_s) / 100.0
    steps = math.ceil(10.0 * period / dt)
    phi = {}
    for i in dofs:
        beta0 = (2.0 * math.pi / natural_period_s[i]) ** 2
        beta1 = 2.0 * relative_damping[i] * 2.0 * math.pi / natural_period_s[i]
        a = np.array([[0.0, 1.0, 0.0], [-beta0, -beta1, beta0], [0.0, 0.0, 0.0]])
        phi[i] = (expm(a * dt), beta0, beta1)
    target = np.array([excitation[0], 0.0, excitation[2]])
    energy = [0.0, 0.0, 0.0]
    peak_a = [0.0, 0.0, 0.0]
    peak_v = [0.0, 0.0, 0.0]
    state = {i: np.zeros(3) for i in dofs}  # [y_M, ẏ_M, r] per DOF
    for _ in range(steps):
        reference = model.step(dt, target)
        r = reference.eta_d_ned
        for i in dofs:
            x = state[i]
            e, beta0, beta1 = phi[i]
            if guided:
                x[1] = reference.eta_dot_d_ned[i]
                accel = float(reference.eta_ddot_d_ned[i])
            else:
                x[2] = r[i]
                accel = beta0 * (x[2] - x[0]) - beta1 * x[1]
            energy[i] += accel * accel * dt
            peak_a[i] = max(peak_a[i], abs(accel))
            peak_v[i] = max(peak_v[i], abs(x[1]))
            if not guided:
                state[i] = e @ x
    return ReferenceExcitation(energy=(energy[0], energy[0], energy[2]), peak_accel=(peak_a[0], peak_a[0], peak_a[2]),
                               peak_velocity=(peak_v[0], peak_v[0], peak_v[2]))


# Default tuning (see default_mrac_config): excitation ℓ = 0.08 L in surge/sway (≈ the 20 m
# corrections of seed 003 for the 260 m tanker) and 10° in yaw, passed through the vessel's default
# guidance; T_a = 0.1 natural periods for a step-driven model (the estimate settles within one
# set-point correction) and 0.3 through the guidance (on the plant one correction's information is
# noisy — estimator noise, wave drift — and averaging over ≈ 3 corrections halves the scatter of
# the estimate while the 12 h loading changes the mass by only 4 % per correction); dead zone
# 0.02 % of L (5 cm for the tanker) and 0.05° in yaw — above the LF-estimate noise the wave filter
# leaves; gating thresholds 5 % of the peak reference-model acceleration and velocity of that move.
_EXCITATION_PER_LENGTH = 0.08
_EXCITATION_YAW_RAD = math.radians(10.0)
_ADAPTATION_PERIODS = 0.1
_ADAPTATION_PERIODS_GUIDED = 0.3
_DEAD_ZONE_PER_LENGTH = 2e-4
_DEAD_ZONE_YAW_RAD = math.radians(0.05)
# k of the measured dead zone (kernels.dead_zone_width): three standard deviations of the error the weather causes
# at rest, a bound a Gaussian disturbance error exceeds with a probability of 0.3 %
_DEAD_ZONE_NOISE_FACTOR = 3.0
#: The built-in vessels whose mass changes in operation (seed 003's shuttle tanker loads 2.66×): the default
#: ``mass_changes`` of the MRAC's configuration (the daemon's configuration also for a vessel ``base:``d on one).
LOADING_VESSELS: tuple[str, ...] = ("shuttle_tanker", "shuttle_tanker_full")
_GATING_FRACTION = 0.05
_ENTRY_REST_PERIODS = 1.0  # rest after an entry into DP before anything is learnt, in reference-model periods
# How long a DOF reads "adapting" after its gate last opened (MracController.adaptation_states), in reference-model
# periods, and at least _ADAPTING_HOLD_MIN_S. Within one move the gate closes while ÿ_M passes through zero
# (|ÿ_M| below the gate): measured for the typical move (0.08 L) through the default guidance, 0.033 T_M — 6.5 s
# of the tanker's 350 s move (T_M = 200 s), 4.3 s for the supply vessel. 0.05 T_M bridges that, so a move reads
# "adapting" from its start to its end and "frozen" follows within 0.05 T_M of its end (10 s for the tanker). The
# floor keeps a short burst on a small vessel (CyberShip II: T_M = 17 s, gap 0.5 s) on screen for a few of the
# displays' redraws.
_ADAPTING_HOLD_PERIODS = 0.05
_ADAPTING_HOLD_MIN_S = 2.0


def default_mrac_config(vessel: VesselData, natural_period_s: float | None = None,
                        guidance: ReferenceModelConfig | None = None, *, step_driven: bool = False,
                        reference: str = "model", mass_changes: bool | None = None) -> MracConfig:
    """MRAC defaults for a vessel: nominal parameters from diag(M), diag(D), seed 003 reference model.

    The reference-model period is 200 s for the shuttle tankers (seed 003) and the Froude-scaled
    150 s × √(L/100 m) otherwise (as :func:`dpcontrol.control.pid.default_natural_period_s`);
    ζ = 1; Γ from :func:`adaptation_gains` with the constants above and the excitation of a typical
    move through ``guidance`` (default: the vessel's :func:`default_reference_config`), see
    :func:`reference_excitation`. ``step_driven``: the reference model is driven by the raw set-point
    steps, as in seed 003's single-DOF study (:mod:`sim_plant.bench.offloading_case`), not by a guidance.
    ``reference``: see :class:`MracConfig` (``guidance``: Γ and the gating from the guidance's own move, and the
    measured dead zone unless ``mass_changes``). ``mass_changes``: the vessel's mass changes in operation (cargo):
    the dead zone stays the fixed d₀, since a wrong mass inflates the error the measured one is sized from
    (default: the vessel is one of :data:`LOADING_VESSELS`).
    """
    if mass_changes is None:
        mass_changes = vessel.name in LOADING_VESSELS
    period = float(natural_period_s) if natural_period_s is not None else default_natural_period_s(vessel)
    periods = (period, period, period)
    mass = tuple(float(v) for v in np.diag(vessel.mass_matrix))
    damping = tuple(max(float(v), 0.0) for v in np.diag(vessel.damping_matrix))
    m_sym = 0.5 * (vessel.mass_matrix + vessel.mass_matrix.T)
    d = vessel.damping_matrix
    length = vessel.length_m
    excitation = (_EXCITATION_PER_LENGTH * length, _EXCITATION_PER_LENGTH * length, _EXCITATION_YAW_RAD)
    zetas = (1.0, 1.0, 1.0)
    if step_driven:
        # a step of ℓ: ÿ_M peaks at β₀ℓ, ẏ_M at ω_M ℓ/e (ζ = 1); Γ as designed for it
        omega = 2.0 * math.pi / period
        gain_m, gain_c = adaptation_gains(mass, periods, zetas, excitation,
                                          adaptation_time_constant_s=_ADAPTATION_PERIODS * period)
        accel = tuple(_GATING_FRACTION * omega**2 * ell for ell in excitation)
        velocity = tuple(_GATING_FRACTION * omega * ell / math.e for ell in excitation)
    else:
        moves = reference_excitation(guidance if guidance is not None else default_reference_config(vessel),
                                     periods, zetas, excitation, guided=reference == "guidance")
        gain_m, _ = adaptation_gains(mass, periods, zetas, excitation,
                                     adaptation_time_constant_s=_ADAPTATION_PERIODS_GUIDED * period,
                                     excitation_energy=moves.energy)
        gain_c = (0.0, 0.0, 0.0)  # damping not adapted by default (see the module docstring)
        accel = tuple(_GATING_FRACTION * a for a in moves.peak_accel)
        velocity = tuple(_GATING_FRACTION * v for v in moves.peak_velocity)
    return MracConfig(
        mass_nominal=mass,  # type: ignore[arg-type]
        damping_nominal=damping,  # type: ignore[arg-type]
        adaptation_gain_mass=gain_m,
        adaptation_gain_damping=gain_c,
        natural_period_s=periods,
        relative_damping=zetas,
        dead_zone=(_DEAD_ZONE_PER_LENGTH * length, _DEAD_ZONE_PER_LENGTH * length, _DEAD_ZONE_YAW_RAD),
        dead_zone_noise_factor=(_DEAD_ZONE_NOISE_FACTOR if reference == "guidance" and not step_driven
                                and not mass_changes else 0.0),
        accel_threshold=accel,  # type: ignore[arg-type]
        velocity_threshold=velocity,  # type: ignore[arg-type]
        entry_rest_s=0.0 if step_driven else _ENTRY_REST_PERIODS * period,
        reference="model" if step_driven else reference,
        mass_coupling=(float(m_sym[0, 1]), float(m_sym[0, 2]), float(m_sym[1, 2])),
        damping_coupling=(float(d[0, 1]), float(d[0, 2]), float(d[1, 0]), float(d[1, 2]), float(d[2, 0]),
                          float(d[2, 1])),
        quadratic_damping=tuple(max(float(v), 0.0) for v in vessel.quadratic_damping),  # type: ignore[arg-type]
    )


def actuator_time_constants(vessel: VesselData) -> Triple:
    """T_u per DOF (surge, sway, yaw) [s]: the thrusters' first-order time constants (``time_constant_s``) averaged
    with the force each can give in the DOF as weight.

    The weight of a thruster in DOF i is ``Σ_k |B_ik| T_max`` over its extended-thrust variables k (the
    configuration matrix of :class:`~dpcontrol.allocation.geometry.ThrusterGeometry`: an azimuth counts in surge,
    sway and yaw, a tunnel in sway and yaw), so a DOF the thrusters of one kind serve takes their time constant —
    the supply vessel 2 s in every DOF, the shuttle tanker's surge (main propeller 5 s, azimuth 3 s) 4.7 s. 0 in a
    DOF no thruster acts in.
    """
    geometry = ThrusterGeometry.build(vessel.thrusters)
    scale = geometry.scale_n[geometry.variable_thruster]
    tau = np.array([spec.time_constant_s for spec in geometry.specs])[geometry.variable_thruster]
    weight = np.abs(geometry.B) * scale
    total = weight.sum(axis=1)
    lead = [float((weight[i] @ tau) / total[i]) if total[i] > 0.0 else 0.0 for i in range(3)]
    return (lead[0], lead[1], lead[2])


def mrac_config_from_mapping(value: object, vessel: VesselData, path: str = "control") -> MracConfig:
    """Validate a ``control: {kind: mrac, ...}`` mapping over :func:`default_mrac_config`.

    Keys (optional): ``natural_period_s`` (number), ``relative_damping``, ``mass_nominal``,
    ``damping_nominal``, ``adaptation_gain_mass``, ``adaptation_gain_damping``, ``dead_zone``,
    ``accel_threshold``, ``velocity_threshold`` (number or 3 numbers; yaw in rad), ``lyapunov_q``
    (2), ``mass_bounds_factor`` (2), ``damping_bounds_factor`` (2), ``leakage_per_s``, ``entry_rest_s``, ``regressor``
    (``reference`` | ``plant``), ``reference`` (``guidance`` | ``model``, see :class:`MracConfig`; default
    ``guidance``: one reference, the guidance's, as the operator sees it), ``mass_changes`` (bool: the vessel's
    mass changes in operation, default for :data:`LOADING_VESSELS`; see :func:`default_mrac_config`), ``adapt``
    (bool, default true; false = the fixed PD of seed 003 eq. (25) at ``mass_nominal``),
    ``actuator_time_constant_s`` (number or 3 numbers >= 0 [s], or ``thrusters``: :func:`actuator_time_constants`;
    default 0), ``integral_action`` (``bias_feedforward`` | ``integrator``), ``integral_ratio`` (number > 0).
    """
    section = Section.of(value, path)
    section.string("kind", "mrac", choices=("mrac",))
    period = section.raw("natural_period_s", None)
    if period is not None:
        period = section.number("natural_period_s", minimum=0.0, exclusive_minimum=True)
    reference = section.string("reference", "guidance", choices=REFERENCES)
    mass_changes = section.boolean("mass_changes", vessel.name in LOADING_VESSELS)
    base = default_mrac_config(vessel, period, reference=reference, mass_changes=mass_changes)
    kwargs: dict[str, Any] = {}
    for key, length in (("relative_damping", 3), ("mass_nominal", 3), ("damping_nominal", 3),
                        ("adaptation_gain_mass", 3), ("adaptation_gain_damping", 3), ("dead_zone", 3),
                        ("accel_threshold", 3), ("velocity_threshold", 3),
                        ("lyapunov_q", 2), ("mass_bounds_factor", 2), ("damping_bounds_factor", 2)):
        raw = section.raw(key, None)
        if raw is None:
            continue
        if isinstance(raw, (int, float)) and not isinstance(raw, bool):
            raw = [raw] * length
        kwargs[key] = tuple(float(v) for v in check_vector(raw, f"{section.path}.{key}", length))
    kwargs["leakage_per_s"] = section.number("leakage_per_s", 0.0, minimum=0.0)
    kwargs["dead_zone_noise_factor"] = section.number("dead_zone_noise_factor", base.dead_zone_noise_factor,
                                                      minimum=0.0)
    kwargs["entry_rest_s"] = section.number("entry_rest_s", base.entry_rest_s, minimum=0.0)
    kwargs["adapt"] = section.boolean("adapt", True)
    kwargs["integral_action"] = section.string("integral_action", base.integral_action, choices=INTEGRAL_ACTIONS)
    kwargs["integral_ratio"] = section.number("integral_ratio", base.integral_ratio, minimum=0.0,
                                              exclusive_minimum=True)
    kwargs["regressor"] = section.string("regressor", "reference", choices=REGRESSORS)
    coupling = section.raw("coupling", None)
    if isinstance(coupling, bool):
        kwargs["coupling"] = DEFAULT_COUPLING if coupling else ()
    elif coupling is not None:
        if not isinstance(coupling, (list, tuple)) or not all(name in COUPLINGS for name in coupling):
            raise ConfigError(f"{section.path}.coupling", f"true, false or a list of {', '.join(COUPLINGS)}",
                              coupling)
        kwargs["coupling"] = tuple(coupling)
    for key, length in (("mass_coupling", 3), ("damping_coupling", 6), ("quadratic_damping", 3)):
        raw = section.raw(key, None)
        if raw is not None:
            kwargs[key] = tuple(float(v) for v in check_vector(raw, f"{section.path}.{key}", length))
    kwargs["damping_bound_kappa"] = section.number("damping_bound_kappa", base.damping_bound_kappa, minimum=0.0)
    lag = section.raw("actuator_time_constant_s", None)
    if lag == "thrusters":
        kwargs["actuator_time_constant_s"] = actuator_time_constants(vessel)
    elif lag is not None:
        if isinstance(lag, (int, float)) and not isinstance(lag, bool):
            lag = [lag] * 3
        if isinstance(lag, str):
            raise ConfigError(f"{section.path}.actuator_time_constant_s", "thrusters, a number or 3 numbers >= 0 [s]",
                              lag)
        kwargs["actuator_time_constant_s"] = tuple(
            float(v) for v in check_vector(lag, f"{section.path}.actuator_time_constant_s", 3))
    try:
        config = MracConfig(**{**base.__dict__, **kwargs})
    except ValueError as error:
        raise ConfigError(section.path, "valid MRAC parameters", str(error)) from None
    section.finish()
    return config


class MracController:
    """MRAC-augmented PD (seed 003) for surge, sway and yaw; implements ``PositionController``.

    Parameters
    ----------
    config : MracConfig
        Nominal parameters, reference model, adaptation gains and robustness settings.
    adapt : bool, optional
        Overrides ``config.adapt``. False freezes the parameters: the controller is then the
        fixed-gain PD of seed 003 eq. (25) at ``mass_nominal`` (the comparison case of seed 003
        Fig. 13).

    Notes
    -----
    One step is one compiled call (:func:`dpcontrol.control.kernels.mrac_step`) on the constants and
    the state held here in two small arrays (layouts in :mod:`dpcontrol.control.kernels`): three SISO
    loops of scalar arithmetic, which as Python floats cost ≈ 30 µs per step.
    """

    rudder_steering = False  # a DP controller: a force in every DOF (see PositionController)

    def __init__(self, config: MracConfig, adapt: bool | None = None) -> None:
        self._config = config
        self._adapt = config.adapt if adapt is None else bool(adapt)
        beta0 = [float(v) for v in config.beta0]
        beta1 = [float(v) for v in config.beta1]
        self._beta0 = beta0
        self._beta1 = beta1
        q = np.diag(config.lyapunov_q)
        self._g12 = [0.0, 0.0, 0.0]
        self._g22 = [0.0, 0.0, 0.0]
        for i in range(3):
            A = np.array([[0.0, 1.0], [-beta0[i], -beta1[i]]])
            # G A + Aᵀ G = −Q_C (eq. (20)); scipy solves a X + X aᴴ = q, so a = Aᵀ, q = −Q_C
            G = solve_continuous_lyapunov(A.T, -q)
            self._g12[i] = float(G[0, 1])
            self._g22[i] = float(G[1, 1])
        m_nom = list(config.mass_nominal)
        c_nom = list(config.damping_nominal)
        lo, hi = config.mass_bounds_factor
        dlo, dhi = config.damping_bounds_factor
        const = np.zeros((C_ROWS, 3))
        const[C_BETA0] = beta0
        const[C_BETA1] = beta1
        const[C_G12] = self._g12
        const[C_G_RATIO] = [g22 / g12 for g12, g22 in zip(self._g12, self._g22, strict=True)]
        const[C_GAMMA_M] = config.adaptation_gain_mass
        const[C_GAMMA_C] = config.adaptation_gain_damping
        const[C_DEAD_ZONE] = config.dead_zone
        const[C_ACCEL] = config.accel_threshold
        const[C_VELOCITY] = config.velocity_threshold
        const[C_A2_LO] = [lo * m for m in m_nom]
        const[C_A2_HI] = [hi * m for m in m_nom]
        const[C_A1_LO] = [dlo * c for c in c_nom]
        const[C_A1_HI] = [max(dhi * c, m * b1) for c, m, b1 in zip(c_nom, m_nom, beta1, strict=True)]
        const[C_A2_NOMINAL] = m_nom
        const[C_A1_NOMINAL] = c_nom
        const[C_OMEGA] = [2.0 * math.pi / t for t in config.natural_period_s]
        const[C_ZETA] = config.relative_damping
        const[C_FLAGS] = (config.leakage_per_s, float(self._adapt), float(config.regressor == "reference"))
        const[C_ENTRY_REST] = config.entry_rest_s
        const[C_GUIDED, 0] = float(config.reference == "guidance")
        const[C_MASS:C_MASS + 3] = config.mass_matrix
        const[C_DAMPING:C_DAMPING + 3] = config.damping_off_diagonal
        const[C_COUPLING, 0] = float(sum(_COUPLING_BITS[name] for name in config.coupling))
        const[C_COUPLING, 1] = config.damping_bound_kappa
        const[C_DRAG] = config.quadratic_damping
        const[C_NOISE_FACTOR] = config.dead_zone_noise_factor
        const[C_NOISE_TIME] = config.natural_period_s
        const[C_LEAD] = config.actuator_time_constant_s
        if config.integral_action == "integrator":
            const[C_INTEGRAL] = [config.integral_ratio * 2.0 * math.pi / t for t in config.natural_period_s]
            # T_t = √(T_i T_d) (Åström & Hägglund's rule, as the PID's): T_i = 1/κ_I, T_d = β₁/β₀
            const[C_TRACKING] = [math.sqrt(k * b0 / b1) for k, b0, b1 in zip(const[C_INTEGRAL].tolist(), beta0,
                                                                               beta1, strict=True)]
        self._const = const
        self._state = np.zeros((S_ROWS, 3))
        self._state[S_A2] = m_nom
        self._state[S_A1] = c_nom
        self._excited = 0  # bit i: the reference model excited DOF i's mass adaptation at the last step
        self._suspended = False  # the supervision stopped the adaptation (suspend_adaptation)
        # for adaptation_states: the time stepped since construction [s] (the sum of the steps' dt: no clock in the
        # core), when each DOF's gate last opened on it, and how long a DOF reads "adapting" after that [s]
        self._clock_s = 0.0
        self._excited_at_s = [-math.inf, -math.inf, -math.inf]
        self._adapting_hold_s = tuple(max(_ADAPTING_HOLD_PERIODS * t, _ADAPTING_HOLD_MIN_S)
                                      for t in config.natural_period_s)
        self._mass_low = tuple(const[C_A2_LO].tolist())  # the projection bounds as floats (_set_mass)
        self._mass_high = tuple(const[C_A2_HI].tolist())
        self._set_mass(m_nom[0], m_nom[1], m_nom[2])  # â₂ as floats (mass_hat_floats), updated when it changes
        self._zero3 = np.zeros(3)  # b̂ and τ̂_wind when not given

    @property
    def config(self) -> MracConfig:
        return self._config

    @property
    def mass_adaptation(self) -> MracController:
        """The controller itself: its mass estimate is what a supervisor watches (see ``PositionController``)."""
        return self

    @property
    def mass_nominal(self) -> tuple[float, float, float]:
        """The nominal masses ``a₂(0)`` [kg, kg, kg·m²] (the configuration's)."""
        m = self._config.mass_nominal
        return (float(m[0]), float(m[1]), float(m[2]))

    @property
    def adapting(self) -> bool:
        """Whether the parameters adapt (False: the fixed PD of seed 003 eq. (25))."""
        return self._adapt

    @property
    def excited(self) -> tuple[bool, bool, bool]:
        """Per DOF: the reference model excited the mass adaptation at the last step (gate open)."""
        bits = self._excited
        return (bits & 1 != 0, bits & 2 != 0, bits & 4 != 0)  # (MASS_CHANGED is bit 3)

    @property
    def adapting_hold_s(self) -> tuple[float, float, float]:
        """How long after its gate last opened a DOF still reads ``adapting`` [s] (see :meth:`adaptation_states`)."""
        hold = self._adapting_hold_s
        return (hold[0], hold[1], hold[2])

    def adaptation_states(self) -> tuple[str, str, str]:
        """Per DOF (surge, sway, yaw): what its mass estimate is doing, one of :data:`ADAPTATION_STATES`.

        ``off`` when configured not to adapt (``adapt: false``), ``suspended`` after :meth:`suspend_adaptation`
        (all DOFs: the supervision stops the whole law), else ``adapting`` while the reference model excited the
        DOF (gate open: the law moves the estimate unless the error is inside the dead zone) within the last
        :attr:`adapting_hold_s`, ``frozen`` otherwise (nothing to learn from: the estimate is held). Computed
        when asked (a display's rate), from what :meth:`step` keeps at the cost of one addition per step.
        """
        adapting, frozen, suspended, off = ADAPTATION_STATES
        if not self._adapt:
            state = suspended if self._suspended else off
            return (state, state, state)
        now = self._clock_s
        at = self._excited_at_s
        hold = self._adapting_hold_s
        return (adapting if now - at[0] <= hold[0] else frozen, adapting if now - at[1] <= hold[1] else frozen,
                adapting if now - at[2] <= hold[2] else frozen)

    @property
    def mass_hat(self) -> np.ndarray:
        """Estimated masses ``â₂`` [kg, kg, kg·m²] (new array)."""
        return self._state[S_A2].copy()

    @property
    def mass_hat_floats(self) -> tuple[float, float, float]:
        """``â₂`` as Python floats (no array: for a per-step check whether it changed)."""
        return self._mass

    @property
    def damping_hat(self) -> np.ndarray:
        """Estimated damping ``â₁`` [N·s/m, N·s/m, N·m·s/rad] (new array)."""
        return self._state[S_A1].copy()

    @property
    def reference_model_state_ned(self) -> tuple[np.ndarray, np.ndarray]:
        """``(y_M, ẏ_M)`` of the reference model in NED (new arrays)."""
        return self._state[S_Y_M].copy(), self._state[S_YD_M].copy()

    def parameters(self) -> dict[str, float]:
        """Parameter estimates keyed by :data:`PARAMETER_NAMES`."""
        return dict(zip(PARAMETER_NAMES, self._state[S_A2:S_A1 + 1].ravel().tolist(), strict=True))

    def equivalent_pd_gains(self) -> tuple[np.ndarray, np.ndarray]:
        """Seed 003 eq. (25): ``P = â₂β₀``, ``D = â₂β₁`` per DOF (acting on ``e`` and ``ė``) [N/m, N·s/m; N·m/rad,
        N·m·s/rad]. With the ``inertia`` coupling the law's PD is the matrix ``M̂β₀``, ``M̂β₁`` with
        ``M̂ = diag(â₂) + M_off`` (:attr:`MracConfig.mass_matrix` off the diagonal); these are its diagonal."""
        a2 = self._state[S_A2].tolist()
        return (np.array([a * b for a, b in zip(a2, self._beta0, strict=True)]),
                np.array([a * b for a, b in zip(a2, self._beta1, strict=True)]))

    def step(self, dt_s: float, eta_hat_ned: np.ndarray, nu_hat_b: np.ndarray, bias_hat_b: np.ndarray | None,
             reference: Reference, *, dof_enabled: Sequence[bool] = ALL_DOFS,
             tau_wind_ff_b: np.ndarray | None = None) -> ControlOutput:
        """One control period (arguments as :meth:`dpcontrol.control.pid.PidController.step`).

        The reference model is initialised at the estimate on the first step after
        construction or :meth:`reset` (bumpless), is driven by ``reference.eta_d_ned`` and advanced
        by ``dt_s`` after the control is computed. ``bias_hat_b`` (None = 0) is compensated.
        ``parameters`` of the output holds the estimates (:data:`PARAMETER_NAMES`) and the
        reference-model pose ``y_M`` at this step (:data:`REFERENCE_MODEL_NAMES`), the pose the
        tracking error ``e = y − y_M`` of eq. (17) is measured against.
        """
        dt = check_dt(dt_s)
        out = np.empty(OUT_SIZE)
        # the runtime's arguments go straight to the kernel, which checks that the vectors are finite: the two
        # DOF masks it passes (valid by construction) and float64 vectors (anything else: TypeError)
        mask, bias, wind = kernel_arguments(dof_enabled, bias_hat_b, tau_wind_ff_b, self._zero3)
        result = ERROR_INPUT
        if mask >= 0:
            try:
                result = mrac_step(dt, eta_hat_ned, nu_hat_b, bias, wind, reference.eta_d_ned, reference.eta_dot_d_ned,
                                   reference.eta_ddot_d_ned, mask, self._const, self._state, out)
            except TypeError:
                result = ERROR_INPUT
        if result < 0:  # the arguments checked in order and converted: the first invalid one raises ValueError
            eta, nu, mask, bias, wind = checked_state_inputs(
                eta_hat_ned, nu_hat_b, dof_enabled, bias_hat_b=bias_hat_b, tau_wind_ff_b=tau_wind_ff_b,
                zero3=self._zero3)
            r = np.array(floats3("reference.eta_d_ned", reference.eta_d_ned))
            rd = np.array(floats3("reference.eta_dot_d_ned", reference.eta_dot_d_ned))
            rdd = np.array(floats3("reference.eta_ddot_d_ned", reference.eta_ddot_d_ned))
            result = mrac_step(dt, eta, nu, bias, wind, r, rd, rdd, mask, self._const, self._state, out)
        self._excited = result
        self._clock_s = now = self._clock_s + dt
        if result & 7:  # a gate open (bits 1, 2, 4; MASS_CHANGED is 8): when, for adaptation_states
            at = self._excited_at_s
            for i in range(3):
                if result >> i & 1:
                    at[i] = now
        values = out.tolist()
        m0, m1, m2, c0, c1, c2, north, east, heading = values[OUT_PARAMETERS:]
        if result & MASS_CHANGED:
            self._set_mass(m0, m1, m2)
        # keys: PARAMETER_NAMES, REFERENCE_MODEL_NAMES (a dict display and positional fields: dict(zip(...)) and
        # keywords cost three times as much)
        parameters = {"mass_surge_kg": m0, "mass_sway_kg": m1, "inertia_yaw_kgm2": m2, "damping_surge_nspm": c0,
                      "damping_sway_nspm": c1, "damping_yaw_nmsprad": c2, "ref_model_north_m": north,
                      "ref_model_east_m": east, "ref_model_heading_rad": heading}
        return ControlOutput(out[OUT_TAU:OUT_TAU + 3], out[OUT_ERROR:OUT_ERROR + 3],
                             out[OUT_VELOCITY_ERROR:OUT_VELOCITY_ERROR + 3], parameters,
                             tracked_ned=out[OUT_REFERENCE_MODEL:OUT_REFERENCE_MODEL + 3])

    def mass_at_bound(self) -> int | None:
        """The first DOF (0 surge, 1 sway, 2 yaw) whose ``â₂`` sits on a projection bound, else None.

        A bound is a physical limit (``mass_bounds_factor`` × ``mass_nominal``: a vessel neither loses 70 % of
        its inertia nor quintuples it), so an estimate held there is no longer learning the vessel but
        something the law mistakes for inertia: measured on CyberShip II and the supply vessel, whose
        closed loops (wave filter, bias compensation, thrusters) carry errors that correlate with the reference
        acceleration, the estimates went from bound to bound and the heading was lost (110° and 54°).
        :meth:`dpcontrol.runtime.step.DpController.step` then calls :meth:`suspend_adaptation`.
        """
        return self._bound_dof

    def _set_mass(self, m0: float, m1: float, m2: float) -> None:
        """â₂ as floats, and which DOF sits on a projection bound (judged when â₂ changes, not every step)."""
        self._mass = (m0, m1, m2)
        self._bound_dof: int | None = None
        for i, (mass, low, high) in enumerate(zip(self._mass, self._mass_low, self._mass_high, strict=True)):
            if mass <= low or mass >= high:
                self._bound_dof = i
                break

    def suspend_adaptation(self) -> None:
        """Stop adapting and return to the nominal parameters: the fixed PD of seed 003 eq. (25).

        The supervision's answer to :meth:`mass_at_bound`. Not part of :meth:`state_dict`: a restarted
        controller adapts again (from the estimates saved, the nominal ones after a suspension).
        """
        self._adapt = False
        self._suspended = True
        self._const[C_FLAGS, 1] = 0.0
        self._excited = 0
        self.reset_parameters()

    def notify_achieved(self, tau_achieved_b: np.ndarray) -> None:
        """The force the allocator could deliver for the last command (freezes adaptation if short)."""
        self._state[S_ACHIEVED] = floats3("tau_achieved_b", tau_achieved_b)
        self._state[S_FLAGS, 1] = 1.0

    def reset(self) -> None:
        """Re-initialise the reference model at the next estimate (bumpless); parameters are kept."""
        state = self._state
        state[S_FLAGS, 0] = 0.0
        state[S_COMMAND] = 0.0
        state[S_FLAGS, 1] = 0.0
        state[S_REST] = 0.0  # the entry's glide teaches nothing: learn after entry_rest_s of rest
        state[S_FLAGS, 2] = 0.0  # the weather force's mean starts again at the next step's
        state[S_INTEGRAL] = 0.0  # the integral force starts from zero at each entry, as the PID's
        state[S_DUTY] = 0.0
        self._excited_at_s[:] = (-math.inf, -math.inf, -math.inf)  # a new entry has learnt nothing yet

    def reset_parameters(self) -> None:
        """Parameter estimates back to the nominal values."""
        self._state[S_A2] = self._const[C_A2_NOMINAL]
        self._state[S_A1] = self._const[C_A1_NOMINAL]
        m0, m1, m2 = self._state[S_A2].tolist()
        self._set_mass(m0, m1, m2)

    def state_dict(self) -> dict[str, Any]:
        """JSON-able state: parameter estimates, reference model, saturation memory, integral force."""
        state = self._state
        return {
            "mass_hat": state[S_A2].tolist(),
            "damping_hat": state[S_A1].tolist(),
            "initialised": bool(state[S_FLAGS, 0]),
            "y_m_n": state[S_Y_M].tolist(),
            "y_dot_m_n": state[S_YD_M].tolist(),
            "last_command_b": state[S_COMMAND].tolist(),
            "last_achieved_b": state[S_ACHIEVED].tolist() if state[S_FLAGS, 1] else None,
            "rest_s": state[S_REST].tolist(),
            "dead_zone_mean_square": state[S_NOISE].tolist(),
            "integral_force_b": state[S_INTEGRAL].tolist(),
            "saturation_duty": state[S_DUTY].tolist(),
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output (validated first; estimates are projected onto the bounds)."""
        try:
            a2 = floats3("mass_hat", state["mass_hat"])
            a1 = floats3("damping_hat", state["damping_hat"])
            y_m = floats3("y_m_n", state["y_m_n"])
            yd_m = floats3("y_dot_m_n", state["y_dot_m_n"])
            command = floats3("last_command_b", state["last_command_b"])
            achieved_raw = state.get("last_achieved_b")
            achieved = None if achieved_raw is None else floats3("last_achieved_b", achieved_raw)
            initialised = bool(state["initialised"])
            # rest since the entry (absent from the states saved before 2026-12-03: a full rest, as they learnt)
            rest = floats3("rest_s", state.get("rest_s", [self._config.entry_rest_s] * 3))
            if min(rest) < 0.0:
                raise ValueError(f"rest_s must be >= 0, got {list(rest)}")
            # the error's mean square at rest (absent from older states: not measured yet, the fixed dead zone)
            noise = floats3("dead_zone_mean_square", state.get("dead_zone_mean_square", [0.0] * 3))
            if min(noise) < 0.0:
                raise ValueError(f"dead_zone_mean_square must be >= 0, got {list(noise)}")
            # the integral force (absent from the states saved before 2026-12-08: none)
            integral = floats3("integral_force_b", state.get("integral_force_b", [0.0] * 3))
            duty = floats3("saturation_duty", state.get("saturation_duty", [0.0] * 3))
            if max(abs(v) for v in duty) > 1.0:
                raise ValueError(f"saturation_duty must be within [-1, 1], got {list(duty)}")
        except (KeyError, TypeError, ValueError) as error:
            raise ValueError(f"invalid MRAC state: {error}") from None
        const = self._const
        lo2, hi2, lo1 = (const[row].tolist() for row in (C_A2_LO, C_A2_HI, C_A1_LO))
        ours = self._state
        m0, m1, m2 = (min(max(a2[i], lo2[i]), hi2[i]) for i in range(3))
        ours[S_A2] = (m0, m1, m2)
        self._set_mass(m0, m1, m2)
        ours[S_A1] = [min(max(a1[i], lo1[i]), damping_ceiling(const, i, (m0, m1, m2)[i])) for i in range(3)]
        ours[S_Y_M] = (y_m[0], y_m[1], ssa(y_m[2]))
        ours[S_YD_M] = yd_m
        ours[S_COMMAND] = command
        ours[S_ACHIEVED] = (0.0, 0.0, 0.0) if achieved is None else achieved
        ours[S_FLAGS, 1] = float(achieved is not None)
        ours[S_FLAGS, 0] = float(initialised)
        ours[S_REST] = rest
        ours[S_NOISE] = noise
        ours[S_INTEGRAL] = integral
        ours[S_DUTY] = duty

