"""``dpcontrol setpoint``: the operator's request to a running controller, and its answer.

One request on ``dp/<vessel>/setpoint`` (``dpcontrol.setpoint/1``): a mode, an absolute position
and/or heading, a relative move or turn, or the reset of a thruster's latched failure. The request
is validated here with the daemon's own parser (:func:`interfaces.zenoh.schemas.parse_setpoint`), so
a malformed one never leaves the console. It is sent only when the vessel's controller is alive on
the network, with a random ``seq``; the command then waits for the controller's status to name that
``seq`` (``status.requests``, the requests taken in the last second, or ``status.request``, the last:
applied or refused, what is in force or why not) and prints it.

Exit codes: 0 applied; 1 refused, no controller, no answer within ``--timeout``, or the zenoh
session could not be opened; 2 invalid request or arguments (nothing sent).

Degrees appear here only: this is an edge (a human types them).
"""

from __future__ import annotations

import argparse
import json
import secrets
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TextIO

from dpcontrol.arguments import add_zenoh_arguments, finite_number, positive_number
from interfaces.messages import Rejected
from interfaces.zenoh.keys import validate_vessel_id
from interfaces.zenoh.node import LatestSlot, Received, ZenohNode
from interfaces.zenoh.schemas import MODES, parse_message, parse_setpoint, setpoint_payload
from interfaces.zenoh.security import ZenohSecurity
from interfaces.zenoh.session_config import LOCAL_DAEMON_CONNECT, ZenohConfig, ZenohOpenError, tool_config

#: Longest wait for the controller's answer by default [s]: a controller answers in the next cycle
#: (100 ms at 10 Hz); the rest is for zenoh to connect and discover on a loaded computer.
DEFAULT_TIMEOUT_S = 5.0
#: Request numbers are drawn below 2**53 so that any JSON reader (doubles included) keeps them exact.
_SEQ_LIMIT = 2**53

EXIT_APPLIED = 0
EXIT_NOT_APPLIED = 1
EXIT_USAGE = 2

#: command-line option → ``dpcontrol.setpoint/1`` field
_FIELDS: tuple[tuple[str, str], ...] = (
    ("mode", "mode"), ("north", "north_m"), ("east", "east_m"), ("heading", "heading_deg"),
    ("move_north", "move_north_m"), ("move_east", "move_east_m"), ("move_surge", "move_surge_m"),
    ("move_sway", "move_sway_m"), ("turn", "turn_deg"), ("reset_thruster", "reset_thruster"),
    ("accept_reference", "accept_reference"))


@dataclass(frozen=True, slots=True)
class Answer:
    """What came of one request.

    Attributes
    ----------
    outcome : str
        ``applied`` or ``refused`` (the controller's answer), ``no_controller``, ``no_answer``,
        ``controller_lost`` or ``not_sent``.
    detail : str
        The controller's words (what is in force, or why not), or what went wrong here.
    seq : int
        The request's sequence number.
    controller_t_s : float or None
        The controller's time of the step that took the request [s] (its monotonic clock).
    role, identity : str or None
        The role and identity (certificate common name) the controller took the request under (``None`` on an
        unauthenticated network).
    """

    outcome: str
    detail: str
    seq: int
    controller_t_s: float | None = None
    role: str | None = None
    identity: str | None = None

    @property
    def exit_code(self) -> int:
        return EXIT_APPLIED if self.outcome == "applied" else EXIT_NOT_APPLIED


def request_fields(args: argparse.Namespace) -> dict[str, Any]:
    """The ``dpcontrol.setpoint/1`` fields the options give (options not given are left out)."""
    return {field: getattr(args, option) for option, field in _FIELDS if getattr(args, option) is not None}


def _answer_to(seq: int, status: Mapping[str, Any] | None) -> Answer | None:
    """This request's answer in a status: among the requests taken in the last second (``requests``: another
    console's request in the same cycle is not ours), else the last one taken (``request``)."""
    if status is None:
        return None
    candidates = [*(status.get("requests") or ()), status.get("request")]
    for request in candidates:
        if isinstance(request, Mapping) and request.get("seq") == seq:
            return Answer(str(request.get("outcome")), str(request.get("detail", "")), seq, request.get("t_s"),
                          request.get("role"), request.get("identity"))
    return None


def _rejected_alarm(status: Mapping[str, Any] | None) -> str | None:
    """The controller's ``operator.setpoint_rejected`` alarm text, if active (its parser refused a request)."""
    for alarm in (status or {}).get("alarms", ()):
        if alarm.get("code") == "operator.setpoint_rejected" and alarm.get("active"):
            return str(alarm.get("text"))
    return None


def check_request(fields: Mapping[str, Any]) -> str | None:
    """Why the daemon would refuse a request with these ``dpcontrol.setpoint/1`` fields (its own parser,
    :func:`interfaces.zenoh.schemas.parse_setpoint`, run here), or ``None`` when it would take it. Every
    operator tool (``dpcontrol setpoint``, ``dpcontrol console``) checks with it before sending."""
    try:
        payload = setpoint_payload(t_s=time.time(), seq=0, **fields)
    except (TypeError, ValueError) as error:  # a field the schema does not have, a value it cannot encode
        return f"invalid request: {error}"
    checked = parse_setpoint(payload)
    return f"invalid request ({checked.reason}): {checked.detail}" if isinstance(checked, Rejected) else None


def send_request(node: ZenohNode, fields: Mapping[str, Any], *, timeout_s: float,
                 clock: Callable[[], float] = time.monotonic, seq: int | None = None) -> Answer:
    """Send one operator request to the vessel's controller and wait for its answer.

    Parameters
    ----------
    node : ZenohNode
        An open session on the vessel's keys (not the controller's own).
    fields : mapping
        ``dpcontrol.setpoint/1`` fields (``mode``, ``north_m`` … ``turn_deg``), already validated.
    timeout_s : float
        Longest wait in all [s]: for the controller's liveliness token, for its setpoint subscriber to
        match, and for the status naming this request.
    clock : callable
        Monotonic clock [s].
    seq : int, optional
        The request's sequence number (default: random below 2**53; the controller's status names it).

    Returns
    -------
    Answer
    """
    seq = secrets.randbelow(_SEQ_LIMIT - 1) + 1 if seq is None else seq
    deadline = clock() + timeout_s
    arrived = threading.Event()
    keys = node.keys
    controller = node.watch_alive("controller", on_change=lambda _present, _t: arrived.set())
    status_slot: LatestSlot[Received[Any]] = LatestSlot(on_put=arrived.set)
    statuses = node.subscribe("status", status_slot, parse=lambda payload: parse_message("status", payload))
    publisher = node.publisher("setpoint")
    if not controller.wait_for(True, max(0.0, deadline - clock())):
        return Answer("no_controller", f"no controller alive for vessel '{keys.vessel}' ({keys.alive('controller')}) "
                      f"within {timeout_s:g} s", seq)
    if not publisher.wait_matched(max(0.0, deadline - clock())):
        return Answer("no_controller", f"the controller of '{keys.vessel}' is alive but does not subscribe "
                      f"{keys.topic('setpoint')} (within {timeout_s:g} s)", seq)
    # (Unix time: the envelope's t_s is the sender's time; the controller answers in its own clock)
    if not publisher.put(setpoint_payload(t_s=time.time(), seq=seq, **fields)):
        return Answer("not_sent", f"zenoh refused to publish on {keys.topic('setpoint')}", seq)
    while True:
        latest = statuses.sink.latest()
        status = None if latest is None else latest.message
        answer = _answer_to(seq, status)
        if answer is not None:
            return answer
        if not controller.present:
            return Answer("controller_lost", f"the controller of '{keys.vessel}' went away before answering", seq)
        remaining = deadline - clock()
        if remaining <= 0.0:
            why = _rejected_alarm(status)
            detail = f"no answer from the controller of '{keys.vessel}' within {timeout_s:g} s"
            if why is not None:
                detail += f" (its alarm: {why})"
            elif status is None:
                detail += f" (no status heard on {keys.topic('status')})"
            return Answer("no_answer", detail, seq)
        arrived.wait(remaining)
        arrived.clear()


def _print(answer: Answer, vessel: str, as_json: bool, out: TextIO, err: TextIO) -> None:
    if as_json:
        out.write(json.dumps({"vessel": vessel, "seq": answer.seq, "outcome": answer.outcome,
                              "detail": answer.detail, "controller_t_s": answer.controller_t_s,
                              "role": answer.role, "identity": answer.identity}) + "\n")
        return
    by = f" (taken from {answer.role} '{answer.identity}')" if answer.identity else ""
    if answer.outcome == "applied":
        out.write(f"{vessel}: applied: {answer.detail}{by}\n")
    elif answer.outcome == "refused":
        err.write(f"dpcontrol setpoint: {vessel}: refused: {answer.detail}{by}\n")
    else:
        err.write(f"dpcontrol setpoint: {answer.detail}\n")


def run_setpoint(vessel: str, fields: Mapping[str, Any], *, connect: Sequence[str] = LOCAL_DAEMON_CONNECT,
                 listen: Sequence[str] = (), timeout_s: float = DEFAULT_TIMEOUT_S, as_json: bool = False,
                 out: TextIO | None = None, err: TextIO | None = None, security: ZenohSecurity | None = None) -> int:
    """Validate, send and report one request (the ``dpcontrol setpoint`` command); returns the exit code.
    ``security``: this tool's TLS identity (a console's) on a secured vessel network."""
    out = out or sys.stdout
    err = err or sys.stderr
    try:
        validate_vessel_id(vessel)
        config = ZenohConfig(listen=tuple(listen), connect=tuple(connect), security=security)
    except ValueError as error:
        err.write(f"dpcontrol setpoint: {error}\n")
        return EXIT_USAGE
    invalid = check_request(fields)
    if invalid is not None:
        err.write(f"dpcontrol setpoint: {invalid}; nothing sent\n")
        return EXIT_USAGE
    try:
        node = ZenohNode(config, vessel)
    except ZenohOpenError as error:
        err.write(f"dpcontrol setpoint: {error}\n")
        return EXIT_NOT_APPLIED
    try:
        answer = send_request(node, fields, timeout_s=timeout_s)
    finally:
        node.close()
    if answer.outcome in ("no_controller", "no_answer"):
        where = ", ".join([*(f"connecting to {e}" for e in connect), *(f"listening on {e}" for e in listen)])
        secured = "" if security is None else (f"; on a secured network, does '{security.expected_name}' hold the "
                                                 "console role in its zenoh.identities?")
        answer = Answer(answer.outcome, f"{answer.detail} ({where or 'no endpoints'}): is `dpcontrol run` up, "
                        f"with this vessel_id, and is the endpoint its zenoh.listen{secured}?", answer.seq)
    _print(answer, vessel, as_json, out, err)
    return answer.exit_code


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``setpoint`` options to an argparse (sub)parser."""
    add_zenoh_arguments(parser)
    parser.add_argument("--mode", choices=MODES, help="operating mode to enter")
    where = parser.add_argument_group("absolute set-point (NED from the datum; north and east together)")
    where.add_argument("--north", type=finite_number, metavar="M", help="north [m]")
    where.add_argument("--east", type=finite_number, metavar="M", help="east [m]")
    where.add_argument("--heading", type=finite_number, metavar="DEG", help="heading [deg, clockwise from north]")
    moves = parser.add_argument_group("relative to the set-point in force")
    moves.add_argument("--move-north", type=finite_number, metavar="M", help="move north [m]")
    moves.add_argument("--move-east", type=finite_number, metavar="M", help="move east [m]")
    moves.add_argument("--move-surge", type=finite_number, metavar="M",
                       help="move ahead along the set-point heading [m]")
    moves.add_argument("--move-sway", type=finite_number, metavar="M", help="move to starboard [m]")
    moves.add_argument("--turn", type=finite_number, metavar="DEG", help="turn [deg, clockwise positive]")
    parser.add_argument("--reset-thruster", metavar="NAME",
                        help="clear a thruster's latched failure (the drive is repaired): it rejoins the allocation "
                             "unless its drive reports not ready")
    parser.add_argument("--accept-reference", metavar="NAME",
                        help="take a lone position or heading reference that the prediction test rejects (it "
                             "jumped) as the truth now: the estimator is re-initialised on it")
    parser.add_argument("--timeout", type=positive_number, default=DEFAULT_TIMEOUT_S, metavar="SECONDS",
                        help=f"longest wait for the controller's answer (default {DEFAULT_TIMEOUT_S:g})")
    parser.add_argument("--json", action="store_true", help="print the answer as one JSON object")


def run_from_args(args: argparse.Namespace) -> int:
    """Run :func:`run_setpoint` from parsed :func:`add_arguments` options."""
    try:
        config = tool_config(args)
    except ValueError as error:
        print(f"dpcontrol setpoint: {error}", file=sys.stderr)
        return EXIT_USAGE
    return run_setpoint(args.vessel, request_fields(args), connect=config.connect, listen=config.listen,
                        timeout_s=args.timeout, as_json=args.json, security=config.security)
