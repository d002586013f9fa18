"""What became of an operator request: ``status.request`` carries its ``seq``, ``applied`` or ``refused`` and
what is in force or why not; a refused one raises ``operator.request_refused`` (info) until 10 s after the
last refusal. Before, a refused "auto_position" left the operator with the mode unchanged and no reason
anywhere but the black-box record."""

from __future__ import annotations

from dpbase.requests import SetpointRequest
from dpcontrol.bench import bench_config
from dpcontrol.runtime.step import REQUEST_REFUSED_HOLD_S, DpController, Mode
from dpcontrol.service.daemon import status_payload
from interfaces.zenoh import schemas


def test_a_refused_request_is_reported_with_its_seq_and_reason_then_cleared() -> None:
    controller = DpController(bench_config())
    assert controller.last_request is None
    status = schemas.parse_message("status", status_payload(controller, controller.alarms, 0.0, 1))
    assert not isinstance(status, schemas.Rejected) and status["request"] is None  # absent before the first

    # no position or heading reference yet: DP cannot engage
    controller.step(1.0, requests=[SetpointRequest(t_s=1.0, seq=4711, mode="auto_position")])
    outcome = controller.last_request
    assert outcome is not None and (outcome.seq, outcome.t_s, outcome.outcome) == (4711, 1.0, "refused")
    assert outcome.detail.startswith("auto_position refused: no estimate yet")
    assert outcome.detail.endswith("mode standby, no set-point yet")
    assert controller.mode is Mode.STANDBY
    assert controller.alarms.is_active("operator.request_refused")

    status = schemas.parse_message("status", status_payload(controller, controller.alarms, 1.0, 2))
    assert not isinstance(status, schemas.Rejected)
    assert status["request"] == {"seq": 4711, "t_s": 1.0, "outcome": "refused", "detail": outcome.detail,
                                 "role": None, "identity": None}  # (unauthenticated: none known)
    alarm = next(a for a in status["alarms"] if a["code"] == "operator.request_refused")
    assert alarm["active"] and alarm["severity"] == "info" and alarm["text"].startswith("auto_position refused")

    # a set-point alone is applied (and the refusal clears 10 s after it was raised)
    controller.step(2.0, requests=[SetpointRequest(t_s=2.0, seq=4712, north_m=5.0, east_m=-1.0)])
    outcome = controller.last_request
    assert (outcome.seq, outcome.outcome) == (4712, "applied")
    assert outcome.detail == "mode standby, set-point 5.00 m N, -1.00 m E, heading 0.0°"
    controller.step(1.0 + REQUEST_REFUSED_HOLD_S)
    assert controller.alarms.is_active("operator.request_refused")
    controller.step(1.1 + REQUEST_REFUSED_HOLD_S)
    assert not controller.alarms.is_active("operator.request_refused")
    assert controller.last_request.seq == 4712  # kept until the next request


def test_the_operator_resets_a_latched_thruster_failure() -> None:
    """A thruster failure judged from the drive's feedback is latched (out of the allocation, and kept across a
    restart through the persisted state) until the operator clears it: ``reset_thruster`` in a request."""
    controller = DpController(bench_config())
    name = controller.thrusters[0].name
    controller.monitor.load_state_dict({"latched": [name]})  # as a restart finds it in the persisted state
    controller.step(1.0)
    assert controller.monitor.is_latched(name) and not controller.monitor.available[0]

    controller.step(1.1, requests=[SetpointRequest(t_s=1.1, seq=7, reset_thruster=name)])
    outcome = controller.last_request
    assert (outcome.seq, outcome.outcome) == (7, "applied")
    assert outcome.detail == f"mode standby, no set-point yet; {name} reset"
    assert not controller.monitor.is_latched(name) and controller.monitor.available[0]

    controller.step(1.2, requests=[SetpointRequest(t_s=1.2, seq=8, reset_thruster=name)])
    assert controller.last_request.detail.endswith(f"{name} reset (no failure was latched)")
    controller.step(1.3, requests=[SetpointRequest(t_s=1.3, seq=9, reset_thruster="stern_jet")])
    outcome = controller.last_request
    assert (outcome.seq, outcome.outcome) == (9, "refused")
    assert outcome.detail.startswith("reset_thruster 'stern_jet': no such thruster (")


def test_a_reset_request_is_valid_alone_and_travels_in_the_setpoint_message() -> None:
    request = schemas.parse_setpoint(schemas.setpoint_payload(t_s=1.0, seq=3, reset_thruster="bow_tunnel_1"))
    assert isinstance(request, SetpointRequest) and request.reset_thruster == "bow_tunnel_1"
    assert not request.changes_pose and request.mode is None
    rejected = schemas.parse_setpoint(b'{"schema": "dpcontrol.setpoint/1", "t_s": 1, "seq": 3, '
                                      b'"reset_thruster": "bow tunnel"}')
    assert isinstance(rejected, schemas.Rejected) and "reset_thruster" in rejected.detail


def test_requests_taken_in_one_cycle_each_get_their_own_answer() -> None:
    """Two consoles (the bridge and the shore) may send in the same cycle. Each request is answered under its own
    ``seq`` (``status.requests``, the last second's): a refused mode is the refusal of the request that asked for
    it, not of a set-point beside it, and a request whose mode a later one replaced says so. Before, the status
    named the last request alone: the other sender waited for its answer until its time-out."""
    controller = DpController(bench_config())
    name = controller.thrusters[0].name
    controller.step(1.0, requests=[
        SetpointRequest(t_s=1.0, seq=11, mode="auto_position"),  # no estimate yet: refused
        SetpointRequest(t_s=1.0, seq=12, north_m=3.0, east_m=4.0),
        SetpointRequest(t_s=1.0, seq=13, reset_thruster="stern_jet"),  # no such thruster: refused
        SetpointRequest(t_s=1.0, seq=14, reset_thruster=name)])
    answers = {outcome.seq: outcome for outcome in controller.requests_since(1.0)}
    assert list(answers) == [11, 12, 13, 14]
    in_force = "mode standby, set-point 3.00 m N, 4.00 m E, heading 0.0°"
    assert answers[11].outcome == "refused"
    assert answers[11].detail == f"auto_position refused: no estimate yet (position and heading references needed); " \
                                 f"{in_force}"
    assert (answers[12].outcome, answers[12].detail) == ("applied", in_force)
    assert answers[13].outcome == "refused" and answers[13].detail.startswith("reset_thruster 'stern_jet': no such")
    assert answers[14].outcome == "applied"
    assert answers[14].detail == f"{in_force}; {name} reset (no failure was latched)"
    assert controller.last_request == answers[14]
    # the alarm names every refusal of the cycle
    alarm = next(a for a in controller.alarms.active() if a.code == "operator.request_refused")
    assert "auto_position refused" in alarm.text and "stern_jet" in alarm.text

    status = schemas.parse_message("status", status_payload(controller, controller.alarms, 1.0, 2))
    assert not isinstance(status, schemas.Rejected)
    assert [(r["seq"], r["outcome"]) for r in status["requests"]] == [(11, "refused"), (12, "applied"),
                                                                      (13, "refused"), (14, "applied")]
    assert status["request"]["seq"] == 14

    # a mode replaced by a later request of the same cycle: both applied, the first says by what
    controller.step(1.1, requests=[SetpointRequest(t_s=1.1, seq=21, mode="auto_heading"),
                                   SetpointRequest(t_s=1.1, seq=22, mode="standby")])
    first, second = controller.requests_since(1.1)
    assert (first.seq, first.outcome, second.seq, second.outcome) == (21, "applied", 22, "applied")
    assert first.detail.endswith("; mode standby requested after it in the same cycle (seq 22)")
    assert not second.detail.endswith(")") and controller.mode is Mode.STANDBY

    # the status lists the last second's requests only, and omits the list when there are none
    status = schemas.parse_message("status", status_payload(controller, controller.alarms, 2.05, 3))
    assert [r["seq"] for r in status["requests"]] == [21, 22]
    status = schemas.parse_message("status", status_payload(controller, controller.alarms, 2.2, 4))
    assert status["requests"] is None and status["request"]["seq"] == 22
    assert b'"requests"' not in status_payload(controller, controller.alarms, 2.2, 5)


def test_an_auto_engage_refusal_is_no_requests_refusal() -> None:
    """``loop.auto_engage_s`` asks for DP without an operator request: a refusal then answers no request (and the
    index of the last step's mode request is not reused)."""
    controller = DpController(bench_config())
    controller.step(1.0, requests=[SetpointRequest(t_s=1.0, seq=5, mode="standby")])
    controller.request_mode("auto_position")  # as the auto-engage does, with no request this step
    controller.step(1.1)
    assert controller.last_request is not None and controller.last_request.seq == 5
    assert controller.last_request.outcome == "applied"
    assert controller.out.rejected_requests and controller.out.rejected_requests[0].startswith("auto_position refused")


def test_the_operator_accepts_a_reference_through_the_request_path() -> None:
    """``accept_reference`` travels the same way as every operator request: the payload of ``dpcontrol setpoint
    --accept-reference NAME`` parsed by the daemon's parser, the hub told (its own test: tests/unit/test_hub.py),
    the answer naming what was done — or refused for a name that is no reference."""
    payload = schemas.setpoint_payload(t_s=1.0, seq=8, accept_reference="gnss1")
    request = schemas.parse_setpoint(payload)
    assert isinstance(request, SetpointRequest) and request.accept_reference == "gnss1"
    controller = DpController(bench_config())
    controller.step(1.0, requests=[request])
    outcome = controller.last_request
    assert (outcome.seq, outcome.outcome) == (8, "applied")
    assert "reference gnss1 accepted as the truth" in outcome.detail
    controller.step(1.1, requests=[SetpointRequest(t_s=1.1, seq=9, accept_reference="gnss9")])
    outcome = controller.last_request
    assert (outcome.seq, outcome.outcome) == (9, "refused")
    assert "accept_reference 'gnss9': no such reference (gnss1, gyro1)" in outcome.detail
