"""Zenoh payload schemas: builders ⇄ validating parsers, rejection reasons, junk never raises."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dpbase.frames import ssa
from interfaces.messages import Rejected
from interfaces.zenoh import schemas as sc
from interfaces.zenoh.keys import VesselKeys, validate_vessel_id

FAST = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _setpoint(**fields: object) -> bytes:
    return json.dumps({"schema": "dpcontrol.setpoint/1", "t_s": 1.0, "seq": 0, **fields}).encode()


def _reason(result: object) -> str:
    assert isinstance(result, Rejected), f"expected a rejection, got {result!r}"
    assert result.reason in sc.REJECT_REASONS
    assert result.detail
    return result.reason


# ------------------------------------------------------------------------------------------------
# Round trips: what the daemon/plant builds, the other side parses back exactly
# ------------------------------------------------------------------------------------------------

def test_command_round_trip_wraps_angles_and_keeps_values() -> None:
    rng = np.random.default_rng(1)
    thrust = rng.uniform(-2e5, 2e5, 4)
    azimuth = rng.uniform(-10.0, 10.0, 4)
    names = ["bow1", "bow2", "stern_az", "main"]
    payload = sc.command_payload(t_s=12.5, seq=7, mode="auto_position", names=names, thrust_n=thrust,
                                 azimuth_rad=azimuth, enabled=[True, False, True, True])
    msg = sc.parse_command(payload, thruster_names=set(names))
    assert isinstance(msg, sc.CommandMessage)
    assert (msg.t_s, msg.seq, msg.mode) == (12.5, 7, "auto_position")
    assert [t.name for t in msg.thrusters] == names
    np.testing.assert_array_equal([t.thrust_n for t in msg.thrusters], thrust)
    np.testing.assert_allclose([t.azimuth_rad for t in msg.thrusters], [ssa(a) for a in azimuth], atol=1e-12)
    assert all(-math.pi < t.azimuth_rad <= math.pi for t in msg.thrusters)
    assert [t.enabled for t in msg.thrusters] == [True, False, True, True]


def test_command_builder_refuses_nan_and_bad_mode() -> None:
    with pytest.raises(ValueError, match="non-finite"):
        sc.command_payload(t_s=0, seq=0, mode="standby", names=["a"], thrust_n=[math.nan], azimuth_rad=[0.0])
    with pytest.raises(ValueError, match="mode"):
        sc.command_payload(t_s=0, seq=0, mode="drift", names=["a"], thrust_n=[0.0], azimuth_rad=[0.0])
    with pytest.raises(ValueError, match="names"):
        sc.command_payload(t_s=0, seq=0, mode="standby", names=["a", "b"], thrust_n=[0.0], azimuth_rad=[0.0])


def test_command_parser_rejects_unknown_and_duplicate_thrusters() -> None:
    payload = sc.command_payload(t_s=0, seq=0, mode="standby", names=["a", "x"], thrust_n=[0, 0],
                                 azimuth_rad=[0, 0])
    assert _reason(sc.parse_command(payload, thruster_names={"a", "b"})) == "unknown_thruster"
    twice = json.loads(payload)
    twice["thrusters"][1]["name"] = "a"
    assert _reason(sc.parse_command(json.dumps(twice).encode())) == "duplicate"


@given(thrust=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=1, max_size=8),
       ready=st.data())
@FAST
def test_feedback_round_trip_turns_non_finite_into_none(thrust: list[float], ready: st.DataObject) -> None:
    n = len(thrust)
    names = [f"t{i}" for i in range(n)]
    flags = ready.draw(st.lists(st.booleans(), min_size=n, max_size=n))
    azimuth = np.linspace(-3.0, 3.0, n)
    payload = sc.feedback_payload(t_s=3.0, seq=1, names=names, thrust_n=thrust, azimuth_rad=azimuth, ready=flags)
    msg = sc.parse_feedback(payload)
    in_range = all(not math.isfinite(f) or abs(f) <= 1e8 for f in thrust)
    if not in_range:
        assert _reason(msg) == "out_of_range"
        return
    assert isinstance(msg, sc.FeedbackMessage)
    for entry, f, r in zip(msg.thrusters, thrust, flags, strict=True):
        assert entry.thrust_n == (f if math.isfinite(f) else None)
        assert entry.ready is r


def test_estimate_round_trip_with_missing_values() -> None:
    payload = sc.estimate_payload(t_s=1.0, seq=2, estimator="mmae", eta_ned=[10.0, -4.0, 7.0],
                                  nu_b=[0.1, math.nan, 0.01], bias=[1e3, 2e3, -3e4], bias_frame="body",
                                  eta_wf_ned=None, covariance_diag=[1.0, math.inf, 0.5])
    assert b"NaN" not in payload and b"Infinity" not in payload
    msg = sc.parse_message("estimate", payload)
    assert isinstance(msg, dict)
    assert msg["pose_n"] == {"north_m": 10.0, "east_m": -4.0, "heading_rad": pytest.approx(ssa(7.0))}
    assert msg["velocity_b"]["sway_mps"] is None
    assert msg["bias"]["frame"] == "body"
    assert msg["wave_n"] is None
    assert msg["covariance_diag"] == [1.0, None, 0.5]


def test_control_payload_computes_shortfall_and_nulls_mrac() -> None:
    tau = np.array([1e4, -2e4, 3e5])
    achieved = np.array([9e3, -2e4, 1e5])
    msg = sc.parse_message("control", sc.control_payload(t_s=0.0, seq=0, controller="pid", tau_b=tau,
                                                         tau_achieved_b=achieved, setpoint_ned=[1, 2, 0.5]))
    assert isinstance(msg, dict)
    short = msg["shortfall_b"]
    np.testing.assert_allclose([short["x_n"], short["y_n"], short["n_nm"]], tau - achieved)
    assert msg["mrac"] is None and msg["reference"] is None
    with_mrac = sc.parse_message("control", sc.control_payload(
        t_s=0.0, seq=1, controller="mrac", tau_b=tau, reference_ned=[0, 0, 0.1], reference_nu_b=[0.2, 0, 0],
        mrac_mass=[6e6, 7e6, 4e9], mrac_damping=None))
    assert isinstance(with_mrac, dict)
    assert with_mrac["mrac"]["mass"]["yaw_kgm2"] == 4e9
    assert with_mrac["mrac"]["damping"]["surge_kgps"] is None
    assert with_mrac["reference"]["surge_mps"] == 0.2


def test_control_mrac_carries_nominal_ratio_and_state_per_dof() -> None:
    """The MRAC's masses against nominal and what each does (``mrac.nominal``, ``ratio``, ``state``): built,
    parsed back, absent from an older daemon's payload (still valid), and checked."""
    payload = sc.control_payload(t_s=1.0, seq=2, controller="mrac", tau_b=[1.0, 2.0, 3.0],
                                 mrac_mass=[7.0e6, 7.0e6, np.nan], mrac_damping=[1e5, 2e5, 3e8],
                                 mrac_nominal=[6.25e6, 7.0e6, 4.0e9], mrac_state=("adapting", "frozen", "suspended"))
    mrac = sc.parse_message("control", payload)["mrac"]
    assert mrac["nominal"] == {"surge_kg": 6.25e6, "sway_kg": 7.0e6, "yaw_kgm2": 4.0e9}
    assert mrac["ratio"] == {"surge": 1.12, "sway": 1.0, "yaw": None}  # (no estimate: no ratio)
    assert mrac["state"] == {"surge": "adapting", "sway": "frozen", "yaw": "suspended"}
    older = json.loads(payload)
    for key in ("nominal", "ratio", "state"):
        del older["mrac"][key]
    parsed = sc.parse_message("control", json.dumps(older).encode())
    assert parsed["mrac"]["state"] is None and parsed["mrac"]["mass"]["surge_kg"] == 7.0e6
    for field, dof, wrong, reason in (("state", "sway", "learning", "bad_value"), ("state", "yaw", None, "wrong_type"),
                                      ("ratio", "surge", -1.0, "out_of_range"), ("ratio", "sway", "1.1", "wrong_type"),
                                      ("nominal", "surge_kg", -5.0, "out_of_range")):
        bad = json.loads(payload)
        bad["mrac"][field][dof] = wrong
        assert _reason(sc.parse_message("control", json.dumps(bad).encode())) == reason, (field, wrong)
    bad = json.loads(payload)
    del bad["mrac"]["state"]["yaw"]
    assert _reason(sc.parse_message("control", json.dumps(bad).encode())) == "missing_field"
    bad = json.loads(payload)
    bad["mrac"]["state"]["heave"] = "off"
    assert _reason(sc.parse_message("control", json.dumps(bad).encode())) == "unknown_field"


def test_status_adaptation_summary_is_optional_and_checked() -> None:
    payload = sc.status_payload(t_s=5.0, seq=3, mode="auto_position",
                                adaptation=sc.AdaptationSummary(("adapting", "off", "frozen"), (1.12, 1.0, math.inf)))
    summary = sc.parse_message("status", payload)["adaptation"]
    assert summary == {"state": {"surge": "adapting", "sway": "off", "yaw": "frozen"},
                       "ratio": {"surge": 1.12, "sway": 1.0, "yaw": None}}
    assert sc.parse_message("status", sc.status_payload(t_s=5.0, seq=3, mode="standby"))["adaptation"] is None
    for wrong, reason in (({"surge": "adapting", "sway": "off", "yaw": "melting"}, "bad_value"),
                          ("adapting", "wrong_type")):
        bad = json.loads(payload)
        bad["adaptation"]["state"] = wrong
        assert _reason(sc.parse_message("status", json.dumps(bad).encode())) == reason


def test_status_round_trip() -> None:
    payload = sc.status_payload(
        t_s=5.0, seq=3, mode="auto_position",
        sensors=[sc.SensorHealth("gnss1", "gnss", "ok", 0.1, 0.5), sc.SensorHealth("gyro1", "gyro", "frozen", None)],
        alarms=[sc.Alarm("GYRO_FROZEN", "alarm", "gyro1 frozen for 3 s", 2.0, True)],
        cycle=sc.CycleTiming(0.1, 140.0, 180.0, 0), thrusters=[sc.ThrusterAvailability("bow", False, "trip")])
    msg = sc.parse_message("status", payload)
    assert isinstance(msg, dict)
    assert [s["state"] for s in msg["sensors"]] == ["ok", "frozen"]
    assert msg["sensors"][1]["age_s"] is None
    assert msg["alarms"][0]["active"] is True
    assert msg["cycle"]["missed_deadlines"] == 0
    assert msg["cycle"]["host_steal_percent"] is None  # not known: null
    bad = json.loads(payload)
    bad["sensors"][0]["state"] = "great"
    assert _reason(sc.parse_message("status", json.dumps(bad).encode())) == "bad_value"


def test_status_cycle_host_steal_is_optional_and_a_percentage() -> None:
    payload = sc.status_payload(t_s=5.0, seq=3, mode="auto_position", cycle=sc.CycleTiming(0.1, 140.0, 180.0, 0, 1.25))
    assert sc.parse_message("status", payload)["cycle"]["host_steal_percent"] == 1.25
    older = json.loads(payload)
    del older["cycle"]["host_steal_percent"]  # a daemon from before the field: still valid
    assert sc.parse_message("status", json.dumps(older).encode())["cycle"]["host_steal_percent"] is None
    for wrong, reason in ((-0.5, "out_of_range"), (100.5, "out_of_range"), ("1 %", "wrong_type")):
        bad = json.loads(payload)
        bad["cycle"]["host_steal_percent"] = wrong
        assert _reason(sc.parse_message("status", json.dumps(bad).encode())) == reason


def test_config_payload_round_trip_and_refusals() -> None:
    msg = sc.parse_message("config", sc.config_payload(t_s=0, seq=0, config={"gains": np.eye(2), "n": (1, 2)}))
    assert isinstance(msg, dict)
    assert msg["config"] == {"gains": [[1.0, 0.0], [0.0, 1.0]], "n": [1, 2]}
    with pytest.raises(ValueError):
        sc.config_payload(t_s=0, seq=0, config={"x": math.nan})
    with pytest.raises(ValueError):
        sc.config_payload(t_s=0, seq=0, config={"x": object()})


# ------------------------------------------------------------------------------------------------
# MMAE and the sea-state table (seed 001 Table I)
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize(("omega", "expected"), [
    (0.93, "calm"), (0.7901, "calm"), (0.79, "moderate"), (0.70, "moderate"), (0.6701, "moderate"),
    (0.67, "high"), (0.50, "high"), (0.45, "high"), (0.4499, "outside_table"), (None, None), (math.nan, None)])
def test_seed001_sea_state_boundaries(omega: float | None, expected: str | None) -> None:
    assert sc.SEA_STATES_SEED001.classify(omega) == expected


def test_sea_state_table_is_a_parameter() -> None:
    table = sc.SeaStateTable(bands=(("swell_free", 1.0), ("swell", 0.3)), below="long_swell")
    payload = sc.mmae_payload(t_s=0, seq=0, omegas_rad_s=[0.4, 0.8], weights=[0.5, 0.5], omega_hat_rad_s=0.6,
                              sea_states=table)
    msg = sc.parse_message("mmae", payload)
    assert isinstance(msg, dict)
    assert msg["sea_state"] == "swell"
    assert table.classify(0.2) == "long_swell"
    with pytest.raises(ValueError):
        sc.SeaStateTable(bands=(("a", 0.5), ("b", 0.6)))
    with pytest.raises(ValueError):
        sc.SeaStateTable(bands=(("a", 0.5),), below="a")


def test_mmae_parser_checks_lengths_and_weight_sum() -> None:
    good = sc.mmae_payload(t_s=0, seq=0, omegas_rad_s=[0.56, 0.73, 0.80], weights=[0.2, 0.5, 0.3],
                           omega_hat_rad_s=0.7)
    msg = sc.parse_message("mmae", good)
    assert isinstance(msg, dict) and msg["sea_state"] == "moderate"
    data = json.loads(good)
    data["weights"] = [0.5, 0.5]
    assert _reason(sc.parse_message("mmae", json.dumps(data).encode())) == "length_mismatch"
    data["weights"] = [0.5, 0.5, 0.5]
    assert _reason(sc.parse_message("mmae", json.dumps(data).encode())) == "out_of_range"


# ------------------------------------------------------------------------------------------------
# Setpoints: accepted forms and every rejection reason
# ------------------------------------------------------------------------------------------------

def test_setpoint_forms() -> None:
    absolute = sc.parse_setpoint(_setpoint(north_m=10.0, east_m=-5.0, heading_deg=270.0, mode="auto_position"))
    assert isinstance(absolute, sc.SetpointRequest)
    assert absolute.heading_rad == pytest.approx(-math.pi / 2)
    assert absolute.resolve(0.0, 0.0, 0.3) == pytest.approx((10.0, -5.0, -math.pi / 2))
    mode_only = sc.parse_setpoint(_setpoint(mode="standby"))
    assert isinstance(mode_only, sc.SetpointRequest) and not mode_only.changes_pose
    # A move "ahead" at heading 90° (east) is a move east; a turn wraps with ssa.
    relative = sc.parse_setpoint(_setpoint(move_surge_m=10.0, move_sway_m=2.0, turn_deg=100.0))
    assert isinstance(relative, sc.SetpointRequest)
    north, east, heading = relative.resolve(1.0, 1.0, math.radians(90.0))
    assert (north, east) == pytest.approx((1.0 - 2.0, 1.0 + 10.0))
    assert heading == pytest.approx(ssa(math.radians(190.0)))
    ned = sc.parse_setpoint(sc.setpoint_payload(t_s=0, seq=1, move_north_m=-3.0, heading_rad=0.5))
    assert isinstance(ned, sc.SetpointRequest)
    assert ned.resolve(5.0, 6.0, 0.0) == pytest.approx((2.0, 6.0, 0.5))


@pytest.mark.parametrize(("payload", "reason"), [
    (b"", "not_json"),
    (b"\xff\xfe", "not_utf8"),
    (b"[1, 2]", "not_object"),
    (b'{"t_s": 0, "seq": 0}', "missing_field"),
    (b'{"schema": 5, "t_s": 0, "seq": 0, "mode": "standby"}', "wrong_type"),
    (b'{"schema": "dpcontrol.status/1", "t_s": 0, "seq": 0, "mode": "standby"}', "wrong_schema"),
    (b'{"schema": "dpcontrol.setpoint/2", "t_s": 0, "seq": 0, "mode": "standby"}', "unsupported_version"),
    (b'{"schema": "dpcontrol.setpoint/1", "seq": 0, "mode": "standby"}', "missing_field"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "mode": "standby"}', "missing_field"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": -1, "mode": "standby"}', "out_of_range"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 1.5, "mode": "standby"}', "wrong_type"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": NaN, "east_m": 0}', "not_finite"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": 1e999, "east_m": 0}', "not_finite"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": -Infinity, "east_m": 0}', "not_finite"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": true, "east_m": 0}', "wrong_type"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": "1", "east_m": 0}', "wrong_type"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "heading_degs": 10}', "unknown_field"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "mode": "standby", "mode": "auto_position"}',
     "duplicate_field"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "mode": "drift"}', "bad_value"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0}', "empty"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": 5}', "incomplete"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "heading_deg": 5, "heading_rad": 0.1}', "conflict"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "turn_deg": 5, "turn_rad": 0.1}', "conflict"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "heading_deg": 5, "turn_deg": 1}', "conflict"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": 1, "east_m": 1, "move_north_m": 1}',
     "conflict"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "north_m": 20000, "east_m": 0}', "out_of_range"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "move_surge_m": 5000}', "out_of_range"),
    (b'{"schema": "dpcontrol.setpoint/1", "t_s": 0, "seq": 0, "heading_deg": 400}', "out_of_range"),
    (b"[" * 3000 + b"]" * 3000, "too_long"),
    (b"[" * 2000 + b"]" * 2000, "too_deep"),
])
def test_setpoint_rejections(payload: bytes, reason: str) -> None:
    result = sc.parse_setpoint(payload)
    assert _reason(result) == reason
    assert result.raw == payload[:256]


def test_setpoint_limits_are_parameters() -> None:
    payload = _setpoint(north_m=50.0, east_m=0.0)
    assert isinstance(sc.parse_setpoint(payload), sc.SetpointRequest)
    assert _reason(sc.parse_setpoint(payload, limits=sc.SetpointLimits(max_offset_m=20.0))) == "out_of_range"


def test_parsers_accept_str_and_reject_non_bytes() -> None:
    assert isinstance(sc.parse_setpoint(_setpoint(mode="standby").decode()), sc.SetpointRequest)
    assert _reason(sc.parse_setpoint(12345)) == "wrong_type"  # type: ignore[arg-type]
    assert _reason(sc.parse_message("nonsense", b"{}")) == "wrong_schema"


# ------------------------------------------------------------------------------------------------
# Junk: never an exception, always a known reason; whatever passes is sane
# ------------------------------------------------------------------------------------------------

_SETPOINT_KEYS = ["schema", "t_s", "seq", "mode", "north_m", "east_m", "heading_deg", "heading_rad",
                  "move_north_m", "move_east_m", "move_surge_m", "move_sway_m", "turn_deg", "turn_rad", "junk"]
_JSON_LEAF = (st.none() | st.booleans() | st.integers(min_value=-(10**30), max_value=10**30)
              | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=12)
              | st.sampled_from(["dpcontrol.setpoint/1", "dpcontrol.thrusters.feedback/1", "standby",
                                 "auto_position", "bow"]))
_JSON = st.recursive(_JSON_LEAF, lambda inner: st.lists(inner, max_size=4)
                     | st.dictionaries(st.text(max_size=8), inner, max_size=4), max_leaves=12)


@given(st.binary(max_size=512))
@FAST
def test_random_bytes_are_rejected_cleanly(data: bytes) -> None:
    for parse in (sc.parse_setpoint, sc.parse_feedback, sc.parse_command):
        result = parse(data)
        if isinstance(result, Rejected):
            assert result.reason in sc.REJECT_REASONS


@given(st.dictionaries(st.sampled_from(_SETPOINT_KEYS), _JSON, max_size=8), st.booleans())
@FAST
def test_junk_setpoints_never_raise_and_passes_are_sane(fields: dict, with_envelope: bool) -> None:
    if with_envelope:
        fields = {"schema": "dpcontrol.setpoint/1", "t_s": 0.0, "seq": 1, **fields}
    payload = json.dumps(fields, allow_nan=True).encode()
    result = sc.parse_setpoint(payload)
    if isinstance(result, Rejected):
        assert result.reason in sc.REJECT_REASONS
        return
    values = [result.north_m, result.east_m, result.heading_rad, result.move_north_m, result.move_east_m,
              result.move_surge_m, result.move_sway_m, result.turn_rad]
    assert all(v is None or (isinstance(v, float) and math.isfinite(v)) for v in values)
    assert result.heading_rad is None or -math.pi < result.heading_rad <= math.pi
    assert result.mode is not None or result.changes_pose
    target = result.resolve(0.0, 0.0, 0.0)
    assert all(math.isfinite(v) for v in target)


_FEEDBACK_ITEM = st.dictionaries(st.sampled_from(["name", "thrust_n", "azimuth_rad", "ready", "rpm"]), _JSON,
                                 max_size=5)


@given(st.lists(_FEEDBACK_ITEM, max_size=5), st.sampled_from(["thrusters", "thruster"]))
@FAST
def test_junk_feedback_never_raises_and_passes_are_sane(items: list, key: str) -> None:
    payload = json.dumps({"schema": "dpcontrol.thrusters.feedback/1", "t_s": 1.0, "seq": 0, key: items},
                         allow_nan=True).encode()
    result = sc.parse_feedback(payload, thruster_names={"bow", "stern"})
    if isinstance(result, Rejected):
        assert result.reason in sc.REJECT_REASONS
        return
    assert result.thrusters
    for entry in result.thrusters:
        assert entry.name in {"bow", "stern"}
        assert entry.thrust_n is None or math.isfinite(entry.thrust_n)
        assert entry.azimuth_rad is None or -math.pi < entry.azimuth_rad <= math.pi
        assert isinstance(entry.ready, bool)


def test_one_field_mutations_of_a_valid_feedback() -> None:
    valid = json.loads(sc.feedback_payload(t_s=1, seq=0, names=["bow"], thrust_n=[1e3], azimuth_rad=[0.1],
                                           ready=[True]))
    junk = [None, True, "x", math.nan, math.inf, 1e300, [], {}, -1]
    for field in ("thrust_n", "azimuth_rad", "ready", "name"):
        for value in junk:
            mutated = json.loads(json.dumps(valid))
            mutated["thrusters"][0][field] = value
            result = sc.parse_feedback(json.dumps(mutated, allow_nan=True).encode())
            # Measured values may be null (unknown) or an in-range number; ready only a boolean;
            # a name only an identifier string.
            acceptable = ((field in ("thrust_n", "azimuth_rad") and (value is None or value == -1))
                          or (field == "ready" and value is True) or (field == "name" and value == "x"))
            if acceptable:
                assert isinstance(result, sc.FeedbackMessage)
            else:
                assert isinstance(result, Rejected), (field, value)
                assert result.reason in sc.REJECT_REASONS
                assert field in result.detail or result.reason == "not_finite"


# ------------------------------------------------------------------------------------------------
# Keys
# ------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("vessel", ["cybership2", "supply-1", "blue_lady", "A"])
def test_valid_vessel_ids_make_keys(vessel: str) -> None:
    keys = VesselKeys(vessel)
    assert keys.topic("command") == f"dp/{vessel}/thrusters/command"
    assert keys.topic("feedback") == f"dp/{vessel}/thrusters/feedback"
    assert keys.config == f"dp/{vessel}/config"
    assert keys.alive("plant") == f"dp/{vessel}/alive/plant"


@pytest.mark.parametrize("vessel", ["", "a/b", "a*", "**", "$x", "a b", "a?", "a#", "-lead", "x" * 65, None, 3])
def test_invalid_vessel_ids_are_refused(vessel: object) -> None:
    with pytest.raises(ValueError, match="vessel id"):
        validate_vessel_id(vessel)


@given(st.text(min_size=1, max_size=10))
@FAST
def test_vessel_ids_with_key_metacharacters_never_pass(text: str) -> None:
    try:
        validate_vessel_id(text)
    except ValueError:
        return
    assert not any(c in text for c in "/*$?# \t\n")


def test_unknown_topic_and_role_are_refused() -> None:
    keys = VesselKeys("v")
    with pytest.raises(ValueError, match="topic"):
        keys.topic("thrusters")
    with pytest.raises(ValueError, match="role"):
        keys.alive("operator")


def test_fast_encoder_and_stdlib_fallback_write_the_same_json() -> None:
    rng = np.random.default_rng(7)
    payloads = [
        sc.estimate_payload(t_s=1e9 + 0.1, seq=2**40, estimator="kf", eta_ned=rng.normal(size=3) * 1e5,
                            nu_b=rng.normal(size=3) * 1e-7, bias=[1e-300, -0.0, 5e15], covariance_diag=[1e-20, 3.0]),
        sc.mmae_payload(t_s=0.0, seq=0, omegas_rad_s=np.linspace(0.3, 1.35, 8), weights=np.full(8, 0.125),
                        omega_hat_rad_s=None),
        sc.status_payload(t_s=1.0, seq=1, mode="auto_position",
                          sensors=[sc.SensorHealth("gnss1", "gnss", "ok", 0.1, 1.0, "ünïcode ✓")]),
    ]
    for payload in payloads:
        obj = json.loads(payload)
        assert json.loads(sc._encode_stdlib(obj)) == obj
        assert json.loads(sc._encode(obj)) == obj


def test_setpoint_null_fields_mean_not_given() -> None:
    request = sc.parse_setpoint(_setpoint(north_m=None, east_m=None, heading_deg=45.0, mode=None, turn_rad=None))
    assert isinstance(request, sc.SetpointRequest)
    assert (request.north_m, request.mode, request.turn_rad) == (None, None, None)
    assert request.heading_rad == pytest.approx(math.pi / 4)
    assert _reason(sc.parse_setpoint(_setpoint(north_m=None, east_m=None))) == "empty"
