"""Single-reference fail-safe runs: one GNSS and one gyro (DP class 1, or any vessel whose other references
failed), one sensor fault, a sea with current; what the controller did about it.

Used by the acceptance tests (``tests/closed_loop/test_failsafe_single_reference.py``) and the randomized
campaign (``benchmarks/failsafe_campaign.py``). A case is a plain mapping (:func:`case_scenario` turns it into a
scenario mapping of the ``sim-plant`` scenario format), so that a campaign engine can take the same cases as a
spec later: vessel, sea, fault kind, start, duration, seed.

Vessels: the supply vessel (full scale) and CyberShip II (a 1:70 model, seed 000). A case is stated at full
scale; on CyberShip II it is Froude-scaled (length 1/70, speed and time 1/√70): the 3 m bound is 43 mm, a 10 m
jump 143 mm, a 40 s freeze 4.8 s of model time — the same event for a vessel 70 times smaller, whose dynamics
run √70 times faster (a 40 s freeze on the model would be 5.5 min at full scale). ``Case.duration_scale``
overrides it (1.0: model time as given). The heading bound is not scaled (angles are not).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from dpbase.frames import ssa_array
from sim_plant.bench.lockstep import ProbedRun
from sim_plant.bench.run import build_simulation
from sim_plant.scenario import parse_scenario

SCALE_CS2 = 70.0  # CyberShip II's model scale (seed 000)
ENGAGE_S = 20.0  # DP engages once the estimator has settled (lockstep auto-engage; Froude-scaled on the model)

# Per vessel: the scenario fragment and the bounds [m], [deg]. Full-scale seas of the supply vessel's fault
# catalogue (sim_plant/scenarios/faults: Hs 1.0 m, 0.15 m/s current, 6 m/s wind); CyberShip II's the seed 000
# sea (Hs 0.08 m model = 5.6 m full scale is a storm; here Hs 0.04 m at 1.2 rad/s, the demo's moderate sea)
# with a 0.03 m/s model current (0.25 m/s full scale).
VESSELS: dict[str, dict[str, Any]] = {
    "supply": {
        "datum": {"lat_deg": 60.35, "lon_deg": 2.75},
        # as shipped (deploy/config/supply.yaml): the PID with the wave filter's bias fed forward, seed 001's bank;
        # the noise of the bench's receiver and gyro (what the sensors' sigma_m / sigma_deg would give). Not her
        # fallback.position_loss hold_heading: a single-reference case dead-reckons past the 60 s limit
        # (alarm position.dead_reckoning_limit) so that what the dead reckoning does stays measured
        "controller": {"estimator": {"kind": "mmae", "omegas_rad_s": [0.56, 0.73, 0.80], "dead_reckoning_bias": "mean",
                                     "position_noise_std_m": 0.3, "heading_noise_std_rad": 8.7e-4},
                       "control": {"kind": "pid", "integral_action": "bias_feedforward"}},
        "sea": {"hs_m": 1.0, "omega_peak_rad_s": 0.79},
        "current_mps": 0.15, "wind_mps": 6.0,
        "gnss": {"rate_hz": 5, "noise_m": 0.3}, "gyro": {"rate_hz": 10, "noise_deg": 0.05},
        "rot": {"rate_hz": 10, "noise_degps": 0.01, "bias_degps": 0.03},
        "position_bound_m": 3.0, "heading_bound_deg": 3.0, "jump_m": 10.0, "time_scale": 1.0,
    },
    "cybership2": {
        "datum": {"lat_deg": 63.4305, "lon_deg": 10.3951},
        "controller": {"estimator": {"kind": "mmae", "omegas_rad_s": [0.3, 0.45, 0.6, 0.75, 0.9, 1.05, 1.2, 1.35],
                                     "position_noise_std_m": 0.01, "heading_noise_std_rad": 1.0e-4,
                                     "wf_position_std_m": 0.3},
                       "control": {"kind": "pid"},
                       # the hub's distances and detection times Froude-scaled (length 1/70, time 1/√70): the
                       # 4 m jump floor and 3 m median limit of a ship are 57 mm and 43 mm on the model, its 5 s
                       # freeze window 0.6 s, its 10 s / 180 s rejection times 1.2 s / 21.5 s, its rate check's 30 s
                       # window and 10 s return 3.6 s / 1.2 s, its velocity check's 1 m floor 14 mm, 30 s window
                       # 3.6 s, 2 s low-pass 0.24 s and 5 s return 0.6 s, its 3 s noise window 0.36 s (the hub keeps
                       # 15 samples at least: 1.5 s at 10 Hz), its 5 s readmission and 20 s blend 0.6 s / 2.4 s
                       "hub": {"jump_min_m": 4.0 / SCALE_CS2, "median_limit_m": 3.0 / SCALE_CS2,
                               "rot_check_window_s": 30.0 / math.sqrt(SCALE_CS2),
                               "rot_check_return_s": 10.0 / math.sqrt(SCALE_CS2),
                               "velocity_check_min_m": 1.0 / SCALE_CS2,
                               "velocity_check_window_s": 30.0 / math.sqrt(SCALE_CS2),
                               "velocity_check_filter_s": 2.0 / math.sqrt(SCALE_CS2),
                               "velocity_check_return_s": 5.0 / math.sqrt(SCALE_CS2),
                               "noise_window_s": 3.0 / math.sqrt(SCALE_CS2),
                               "readmit_s": 5.0 / math.sqrt(SCALE_CS2),
                               "switch_blend_s": 20.0 / math.sqrt(SCALE_CS2),
                               "freeze_window_s": 5.0 / math.sqrt(SCALE_CS2),
                               "reject_persist_s": 10.0 / math.sqrt(SCALE_CS2),
                               "single_reference_accept_s": 180.0 / math.sqrt(SCALE_CS2)},
                       "deviation": {"position_warning_m": 0.2, "position_alarm_m": 0.3},
                       # DP engaged after the lockstep runs' 20 s Froude-scaled (2.4 s): 20 s of model time is 167 s of
                       # a ship drifting in standby (0.45 m, 31 m full scale, in the campaign's current), still being
                       # made good when the measurement starts
                       "loop": {"auto_engage_s": ENGAGE_S / math.sqrt(SCALE_CS2)}},
        "sea": {"hs_m": 0.04, "omega_peak_rad_s": 1.2},
        "current_mps": 0.03, "wind_mps": 0.0,
        # (the receiver's velocity noise Froude-scaled with its position noise: 0.02 m/s full scale)
        "gnss": {"rate_hz": 10, "noise_m": 0.01, "velocity_noise_mps": 0.02 / math.sqrt(SCALE_CS2)},
        "gyro": {"rate_hz": 10, "noise_deg": 0.0057},
        # the same rate gyro as the ship's (a device is not scaled)
        "rot": {"rate_hz": 10, "noise_degps": 0.01, "bias_degps": 0.03},
        "position_bound_m": 3.0 / SCALE_CS2, "heading_bound_deg": 3.0, "jump_m": 10.0 / SCALE_CS2,
        "time_scale": 1.0 / math.sqrt(SCALE_CS2),
    },
}


@dataclass(frozen=True)
class Case:
    """One run: ``vessel`` (a key of :data:`VESSELS`), ``fault`` (a plant fault kind on gnss1, gyro1 or rot1),
    ``start_s``/``duration_s`` of the fault, the sea's direction [deg] and Hs factor, the current's direction
    [deg], and the plant's ``seed``."""

    vessel: str
    fault: str
    start_s: float
    duration_s: float
    seed: int = 1
    sea_direction_deg: float = 30.0
    hs_factor: float = 1.0
    current_direction_deg: float = 210.0
    after_s: float = 120.0  # run on after the fault ends [s]
    duration_scale: float | None = None  # fault duration factor; None: the vessel's Froude time scale
    controller: dict[str, Any] | None = None  # controller sections merged over the vessel's (e.g. {"hub": {...}})
    rate_of_turn: bool = False  # a rate-of-turn sensor rot1 (independent of the gyro) besides gnss1 and gyro1
    noise_factor: float = 10.0  # ``gnss_noise``: the factor on the receiver's white noise [-]

    @property
    def fault_duration_s(self) -> float:
        """The injected fault's duration on this vessel [s] (:attr:`duration_s` × the time scale)."""
        scale = VESSELS[self.vessel]["time_scale"] if self.duration_scale is None else self.duration_scale
        return self.duration_s * scale

    def _controller(self, base: dict[str, Any]) -> dict[str, Any]:
        return base if not self.controller else _merged(base, self.controller)

    def scenario(self) -> dict[str, Any]:
        """The scenario mapping (``sim-plant`` scenario format) of this case."""
        v = VESSELS[self.vessel]
        duration = self.fault_duration_s
        fault: dict[str, Any] = {"t_s": self.start_s, "kind": self.fault, "duration_s": duration,
                                 "sensor": {"gyro": "gyro1", "rot_": "rot1"}.get(self.fault[:4], "gnss1")}
        if self.fault == "gnss_jump":
            fault.update(offset_m=v["jump_m"], direction_deg=45.0)
        elif self.fault == "gnss_drift":
            fault.update(rate_mps=v["jump_m"] / duration, direction_deg=45.0)
        elif self.fault == "gnss_noise":
            fault.update(factor=self.noise_factor)
        elif self.fault == "gyro_offset":
            fault.update(offset_deg=10.0)
        elif self.fault in ("gyro_drift", "rot_offset"):
            # 0.2 °/s at full scale; Froude-scaled like the duration (an angle is not scaled, a time is: the model
            # drifts the same angle in the scaled time)
            fault.update(rate_degps=0.2 * self.duration_s / duration)
        sea = v["sea"]
        scenario: dict[str, Any] = {
            "name": f"failsafe-{self.vessel}-{self.fault}-{self.seed}",
            "vessel": self.vessel, "duration_s": self.start_s + duration + self.after_s, "seed": self.seed,
            "datum": v["datum"], "controller": self._controller(v["controller"]),
            "sea_states": [{"t_s": 0, "spectrum": "jonswap", "hs_m": sea["hs_m"] * self.hs_factor,
                            "omega_peak_rad_s": sea["omega_peak_rad_s"], "gamma": 3.3,
                            "direction_deg": self.sea_direction_deg}],
            "current": {"speed_mps": v["current_mps"], "direction_deg": self.current_direction_deg},
            "setpoints": [{"t_s": 0, "north_m": 0, "east_m": 0, "heading_deg": 0}],
            "sensors": [{"name": "gnss1", "kind": "gnss", "protocol": "nmea0183", **v["gnss"]},
                        {"name": "gyro1", "kind": "gyro", "protocol": "nmea0183", **v["gyro"]}],
            "faults": [fault],
        }
        if self.rate_of_turn:
            scenario["sensors"].append({"name": "rot1", "kind": "rot", "protocol": "nmea0183", **v["rot"]})
        if v["wind_mps"]:
            scenario["wind"] = {"speed_mps": v["wind_mps"], "direction_deg": self.sea_direction_deg}
        return scenario


def _merged(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """``base`` with the sections of ``over`` merged in (one level deep)."""
    out = dict(base)
    for key, value in over.items():
        out[key] = {**out[key], **value} if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


@dataclass(frozen=True)
class Outcome:
    """What a run did: the largest true LF position / heading distance from the set-point from ``settled_s`` on
    [m], [deg]; the mode at the end and whether it was ever other than ``auto_position`` after the
    engagement; how long after the fault ended the mode was ``auto_position`` again (0: never left) [s]; the
    alarms raised (codes, in order of first raise)."""

    max_position_m: float
    max_heading_deg: float
    final_mode: str
    left_dp: bool
    back_after_s: float
    alarms: tuple[str, ...]

    def within(self, case: Case) -> bool:
        v = VESSELS[case.vessel]
        return self.max_position_m <= v["position_bound_m"] and self.max_heading_deg <= v["heading_bound_deg"]


def true_distances(run: ProbedRun) -> tuple[np.ndarray, np.ndarray]:
    """The true LF position's distance from the set-point (the origin) [m] and the heading's [deg], per sample."""
    position = np.hypot(run.col("north_m"), run.col("east_m"))
    heading = np.degrees(np.abs(ssa_array(run.col("heading_rad"))))
    return position, heading


def run_case(case: Case, settled_s: float = 60.0) -> tuple[ProbedRun, Outcome]:
    """Run ``case`` in lockstep and measure it against the operator's set-point (not the reference model's
    output, which is undefined in standby: a vessel drifting in standby must count)."""
    run = ProbedRun.run(build_simulation(parse_scenario(case.scenario(), file=f"<{case.vessel} {case.fault}>")))
    t = run.t_s
    window = t >= settled_s - 1e-9
    position, heading = true_distances(run)
    changes = run.result.mode_changes
    engaged = [c for c in changes if c[2] == "auto_position"]
    first_engaged = engaged[0][0] if engaged else math.inf
    left = [c for c in changes if c[0] > first_engaged and c[1] == "auto_position"]
    end = case.start_s + case.fault_duration_s
    final_mode = changes[-1][2] if changes else "standby"
    back = 0.0
    if left:
        returns = [c[0] for c in changes if c[0] > left[-1][0] - 1e-9 and c[2] == "auto_position"]
        back = (returns[-1] - end) if returns and final_mode == "auto_position" else math.inf
    codes: list[str] = []
    for event in run.result.alarm_events:
        if event.raised and event.code not in codes:
            codes.append(event.code)
    return run, Outcome(float(np.nanmax(position[window])), float(np.nanmax(heading[window])), final_mode,
                        bool(left), max(back, 0.0), tuple(codes))
