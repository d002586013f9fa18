"""Model-probability weights of the MMAE wave filter (seed 000 eq. (18), seed 001 eq. (42)).

Two weight generators over a bank of N models, both fed with per-model log-likelihoods
``log L_i = log β_i − m_i`` of the current innovations:

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

Why the Bayes form is the default (``WaveFilterConfig.weighting``): the DWSG is driven by the
*instantaneous* likelihood ratio, ``d ln p_i/dt = λ (L_i/Σ p_j L_j − 1)``, linear in ``L`` — on a real
sea, where neighbouring models differ by a few per cent in innovation energy and the per-sample
error measures fluctuate by far more, a small λ makes the weights sluggish (the 0.9 rad/s model of
seed 000 does not reach 0.9 in 300 s with λ = 1/s) and a large λ makes them follow the noise
(arithmetic, not geometric, averaging of fluctuating likelihoods). The Bayes form sums
log-likelihoods, so its log-odds grow with the accumulated evidence and are steady.

Why weights must not lock (DESIGN.md §5, seed 001 Fig. 3): both generators drive the weight of a
model that is worse *now* towards zero geometrically; once it underflows, no later evidence can
raise it (0 × anything = 0), so after a sea-state change the bank stays on the old model. Two
remedies, both applied:

* a **floor** relative to the leading model, ``p_i ≥ p_min · max_j p_j`` (then renormalised): the
  log-odds of any model against the leader are bounded by ``ln(1/p_min)``, so the time to switch
  after a change is bounded by the time the new evidence needs to overturn ``ln(1/p_min)`` nats
  (DWSG: about ``ln(1/p_min) / (λ Δm)`` with Δm the mean difference of the error measures),
  instead of growing without bound with the time spent in the previous sea state;
* **forgetting** (Bayes form): the log-odds are an exponentially weighted sum of recent
  log-likelihood ratios with memory T_f, so they stay proportional to the evidence of the last
  T_f seconds (bounded by ``max|Δ ln L| / (1 − α)``). That keeps the weights *soft* when
  neighbouring models are nearly as good and bounds the switching time to a fraction of T_f.

Defaults (T_f = 200 s, p_min = 10⁻⁶, measured in ``tests/unit/test_estimation_mmae.py``): on data
from the seed 000 design model the right model's weight passes 0.9 within 20–60 s and stays there
(T_f = 60 s lets it dip below 0.9 again in most runs); on seed 001's sea-state sequence every
switch completes within ≈ 200 s. The floor then mostly guards against underflow; the forgetting does
the unlocking.
"""

from __future__ import annotations

import math

import numpy as np

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


def bayes_step(log_w: np.ndarray, p: np.ndarray, log_likelihood: np.ndarray, *, forgetting: float,
               log_floor: float) -> None:
    """Discrete Bayesian weight update with forgetting, in the log domain, in place.

    ``ln w_i(k) = α ln w_i(k−1) + ln L_i(k)`` (Anderson & Moore; α = 1 is pure Bayes), shifted so the
    largest is 0 and floored at ``ln(floor)`` relative to it; ``p = w / Σ w``.

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
    log_w *= forgetting
    log_w += log_likelihood
    log_w -= log_w.max()
    np.maximum(log_w, log_floor, out=log_w)
    np.exp(log_w, out=p)
    p /= p.sum()
