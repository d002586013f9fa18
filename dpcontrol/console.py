"""``dpcontrol console``: the operator's station in a web browser, served from this process, fed live over Zenoh.

One page (``console_page.html`` beside this module: plain HTML, CSS and JavaScript, no build step) shows what
a DP operator's station shows — the vessel outline at its estimated pose on a local north-east plot with the
set-point, the reference and the position history; heading; a thrust vector per thruster with its
utilisation; the MMAE weights and the estimated sea state; the MRAC estimates; sensor health per reference;
alarms with their age, clock time and acknowledgement; the worst-case (consequence) state; cycle timing.

The page gets a snapshot of everything over a WebSocket at up to 10 Hz. Operator actions (mode, set-point,
move, turn, thruster reset) are posted to ``/api/request`` and go through exactly the request path of
``dpcontrol setpoint`` (:mod:`dpcontrol.setpoint`): the same validation, then
:func:`dpcontrol.setpoint.send_request` over a session of its own, and the controller's answer is returned to
the page. The console is read-only unless started with ``--allow-actions``, and binds to 127.0.0.1 unless
told otherwise (``--http``): it has no login of its own, so on a vessel network it is reached through an SSH
tunnel or a reverse proxy that authenticates (docs/console.md).

Web framework: Starlette on uvicorn. Starlette is a small, well-kept ASGI toolkit with WebSockets, routing
and a threadpool for the blocking Zenoh request built in; uvicorn is its standard server and runs inside
this process (no separate web server to install on the vessel). aiohttp would do as well; Starlette was
chosen for its plain request/response objects and its TestClient, and because FastAPI (the common choice
for such a console) is built on it should the console grow an API.

Alarm acknowledgement belongs to this console (the daemon has no acknowledgement key): an acknowledged
alarm stays listed but stops flashing for every browser of this console, until it is raised again.
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import contextlib
import functools
import json
import logging
import math
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import orjson

from dpcontrol.arguments import add_zenoh_arguments, positive_number
from dpcontrol.models.vessels import vessel_from_config
from dpcontrol.setpoint import DEFAULT_TIMEOUT_S, check_request, send_request
from interfaces.zenoh.keys import ROLES, validate_vessel_id
from interfaces.zenoh.node import LatestSlot, Received, TopicSubscriber, ZenohNode
from interfaces.zenoh.schemas import MODES, parse_message
from interfaces.zenoh.security import is_loopback_host
from interfaces.zenoh.session_config import LOCAL_DAEMON_CONNECT, ZenohConfig, ZenohOpenError, tool_config

log = logging.getLogger(__name__)

#: Topics the console shows.
CONSOLE_TOPICS: tuple[str, ...] = ("estimate", "mmae", "control", "status", "command", "feedback")
#: Where the page is served when no ``--http`` is given: this machine only.
DEFAULT_HTTP = "127.0.0.1:8470"
#: The snapshot rate of the page [Hz] (the daemon publishes at its loop rate, 10 Hz by default).
PUSH_HZ = 10.0
#: Position history kept for the trail: one point per TRAIL_PERIOD_S, the last TRAIL_POINTS of them.
TRAIL_PERIOD_S = 0.5
TRAIL_POINTS = 3600
#: The request fields the page may send, with their kind (the ``dpcontrol.setpoint/1`` fields that
#: ``dpcontrol setpoint``'s options give; degrees, as an operator types them).
REQUEST_FIELDS: Mapping[str, str] = {
    "mode": "text", "north_m": "number", "east_m": "number", "heading_deg": "number", "move_north_m": "number",
    "move_east_m": "number", "move_surge_m": "number", "move_sway_m": "number", "turn_deg": "number",
    "reset_thruster": "text", "accept_reference": "text"}


def parse_http_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (IPv6 as ``[::1]:PORT``) → ``(host, port)``.

    Raises
    ------
    ValueError
        Not of that form, or the port out of 1–65535.
    """
    host, sep, port_text = text.rpartition(":")
    if not sep or not host:
        raise ValueError(f"--http {text!r}: expected HOST:PORT, e.g. {DEFAULT_HTTP}")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"--http {text!r}: the port must be a number") from None
    if not 0 < port < 65536:
        raise ValueError(f"--http {text!r}: the port must be within 1-65535")
    return host, port


def vessel_geometry(config: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """The outline and thruster layout the plot draws, from the daemon's running configuration (its
    ``dp/<vessel>/config`` reply): length and beam [m], and per thruster its kind, body position [m],
    fixed force direction [rad] and thrust range [N]. ``None`` when the configuration names no vessel that
    :func:`dpcontrol.models.vessels.vessel_from_config` knows."""
    if not isinstance(config, Mapping) or "vessel" not in config:
        return None
    try:
        vessel = vessel_from_config(config["vessel"])
    except Exception as error:  # (any invalid vessel entry: the daemon itself validated it; draw no outline)
        log.warning("console: the daemon's vessel entry gives no outline: %s", error)
        return None
    return {"name": vessel.name, "length_m": vessel.length_m, "beam_m": vessel.beam_m,
            "thrusters": [{"name": t.name, "kind": t.kind, "x_m": t.x_m, "y_m": t.y_m, "angle_rad": t.angle_rad,
                           "max_thrust_n": t.max_thrust_n, "min_thrust_n": t.min_thrust_n}
                          for t in vessel.thrusters]}


def request_fields_from_json(data: Any) -> dict[str, Any]:
    """The ``dpcontrol.setpoint/1`` fields of a request posted by the page.

    Only :data:`REQUEST_FIELDS` are taken, numbers as finite numbers, texts as texts; empty entries (a form
    field left blank) are left out. What the daemon would refuse beyond that is refused by
    :func:`dpcontrol.setpoint.check_request`, as for ``dpcontrol setpoint``.

    Raises
    ------
    ValueError
        Not an object, an unknown field, a number that is not one, or nothing asked.
    """
    if not isinstance(data, Mapping):
        raise ValueError("expected a JSON object of request fields")
    fields: dict[str, Any] = {}
    for key, value in data.items():
        kind = REQUEST_FIELDS.get(key)
        if kind is None:
            raise ValueError(f"unknown field {key!r} (known: {', '.join(REQUEST_FIELDS)})")
        if value is None or value == "":
            continue
        if kind == "number":
            if isinstance(value, bool) or not isinstance(value, (int, float, str)):
                raise ValueError(f"{key}: expected a number, got {value!r}")
            try:
                number = float(value)
            except ValueError:
                raise ValueError(f"{key}: expected a number, got {value!r}") from None
            if not math.isfinite(number):
                raise ValueError(f"{key}: expected a finite number, got {value!r}")
            fields[key] = number
        else:
            if not isinstance(value, str):
                raise ValueError(f"{key}: expected text, got {value!r}")
            fields[key] = value
    if not fields:
        raise ValueError("nothing asked: give a mode, a set-point, a move, a turn or a thruster to reset")
    return fields


class ConsoleFeed:
    """The Zenoh side of the console: one validating subscriber per topic, two liveliness watchers, the
    position trail, the alarm acknowledgements and the daemon's configuration (for the vessel outline).

    Thread-safe: Zenoh delivers on its own threads; the web server reads :meth:`snapshot` from its loop.
    """

    def __init__(self, node: ZenohNode, vessel: str, clock: Callable[[], float] = time.monotonic,
                 wall_clock: Callable[[], float] = time.time) -> None:
        self.node = node
        self.vessel = vessel
        self.clock = clock
        self.wall_clock = wall_clock
        self.subscribers: dict[str, TopicSubscriber[LatestSlot[Received[Any]]]] = {
            topic: node.subscribe(topic, LatestSlot(), parse=functools.partial(parse_message, topic))
            for topic in CONSOLE_TOPICS}
        self.watchers = {role: node.watch_alive(role) for role in ROLES}
        self._lock = threading.Lock()
        self._trail: collections.deque[tuple[float, float, float]] = collections.deque(maxlen=TRAIL_POINTS)
        self._trail_last_rx = -math.inf
        self._acknowledged: set[tuple[str, float | None]] = set()
        self._geometry: dict[str, Any] | None = None
        self._config_asked_at = -math.inf

    # -- the daemon's configuration (asked again every 10 s until it answers) --------------------------
    def geometry(self) -> dict[str, Any] | None:
        with self._lock:
            if self._geometry is not None or self.clock() - self._config_asked_at < 10.0:
                return self._geometry
            self._config_asked_at = self.clock()
        reply = self.node.query_config(2.0)
        geometry = vessel_geometry(reply.get("config", {}).get("config")) if isinstance(reply, dict) else None
        with self._lock:
            self._geometry = geometry
        return geometry

    # -- trail ----------------------------------------------------------------------------------------
    def _update_trail(self, estimate: Any) -> None:
        if estimate is None or estimate.rx_t_s - self._trail_last_rx < TRAIL_PERIOD_S:
            return
        pose = estimate.message.get("pose_n") or {}
        north, east = pose.get("north_m"), pose.get("east_m")
        if isinstance(north, (int, float)) and isinstance(east, (int, float)):
            self._trail.append((round(self.wall_clock() - (self.clock() - estimate.rx_t_s), 2), north, east))
            self._trail_last_rx = estimate.rx_t_s

    def trail(self) -> list[tuple[float, float, float]]:
        with self._lock:
            return list(self._trail)

    # -- alarm acknowledgement (this console's) --------------------------------------------------------
    def acknowledge(self, code: str, since_t_s: float | None) -> None:
        with self._lock:
            self._acknowledged.add((code, since_t_s))

    def _acknowledged_now(self, status: Mapping[str, Any] | None) -> list[list[Any]]:
        """The acknowledgements of alarms still listed (a raise again is a new ``since_t_s``: unacknowledged)."""
        listed = {(a.get("code"), a.get("since_t_s")) for a in (status or {}).get("alarms", ())}
        self._acknowledged &= listed
        return [list(item) for item in sorted(self._acknowledged, key=str)]

    # -- snapshot ---------------------------------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """Everything the page draws: each topic's newest message and age, liveliness, trail tip, acks."""
        now = self.clock()
        topics: dict[str, Any] = {}
        latest_estimate = None
        for topic, subscriber in self.subscribers.items():
            latest = subscriber.sink.latest()
            if topic == "estimate":
                latest_estimate = latest
            topics[topic] = None if latest is None else {"message": latest.message,
                                                         "age_s": round(max(0.0, now - latest.rx_t_s), 3),
                                                         "rejected": subscriber.stats.rejected}
        with self._lock:
            self._update_trail(latest_estimate)
            status = topics["status"]["message"] if topics["status"] else None
            acknowledged = self._acknowledged_now(status)
            tip = self._trail[-1] if self._trail else None
        alive = {}
        for role, watcher in self.watchers.items():
            state = watcher.state
            alive[role] = {"present": state.present, "seen": state.seen, "losses": state.losses}
        return {"vessel": self.vessel, "wall_s": self.wall_clock(), "topics": topics, "alive": alive,
                "peers": len(self.node.peers()), "acknowledged": acknowledged, "trail_tip": tip}


def load_capability(path: str | Path) -> dict[str, Any]:
    """The DP capability polar of ``sim-plant capability`` (its ``capability.json``) for the console's page.

    Returns
    -------
    dict
        ``{"level", "vessel", "current_mps", "directions_deg", "cases": [{"case", "max_wind_mps"}]}``:
        directions relative to the bow [deg], clockwise; the largest mean wind held from each [m/s], one list
        per case (intact, and each failure case the file holds).

    Raises
    ------
    ValueError
        The file cannot be read, is not JSON, or is not a capability file (the message says what is wrong).
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"--capability {path}: {error}") from None

    def numbers(value: Any, what: str, length: int | None = None) -> list[float]:
        if not isinstance(value, list) or not value or (length is not None and len(value) != length) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
            raise ValueError(f"--capability {path}: {what}: expected {length or 'some'} finite numbers")
        return [float(v) for v in value]

    if not isinstance(data, dict):
        raise ValueError(f"--capability {path}: expected the capability.json of sim-plant capability")
    directions = numbers(data.get("directions_deg"), "directions_deg")
    raw_cases = data.get("cases") or [{"case": "intact", "max_wind_mps": data.get("max_wind_mps")}]
    if not isinstance(raw_cases, list):
        raise ValueError(f"--capability {path}: cases: expected a list")
    cases = [{"case": str(case.get("case", f"case {i}")),
              "max_wind_mps": numbers(case.get("max_wind_mps"), f"cases[{i}].max_wind_mps", len(directions))}
             for i, case in enumerate(raw_cases) if isinstance(case, dict)]
    if not cases:
        raise ValueError(f"--capability {path}: no case to draw")
    return {"level": data.get("level"), "vessel": str(data.get("vessel", "")), "current_mps": data.get("current_mps"),
            "directions_deg": directions, "cases": cases}


def build_app(feed: ConsoleFeed, *, session_config: ZenohConfig, allow_actions: bool,
              timeout_s: float = DEFAULT_TIMEOUT_S, capability: Mapping[str, Any] | None = None) -> Any:
    """The Starlette application: ``/`` (the page), ``/api/info``, ``/api/trail``, ``/ws`` (snapshots),
    ``/api/ack`` and, with ``allow_actions``, ``/api/request``."""
    from starlette.applications import Starlette  # noqa: PLC0415 - web stack only for the console
    from starlette.concurrency import run_in_threadpool  # noqa: PLC0415
    from starlette.requests import Request  # noqa: PLC0415
    from starlette.responses import HTMLResponse, Response  # noqa: PLC0415
    from starlette.routing import Route, WebSocketRoute  # noqa: PLC0415
    from starlette.websockets import WebSocket, WebSocketDisconnect  # noqa: PLC0415

    page = (resources.files("dpcontrol") / "console_page.html").read_text(encoding="utf-8")
    vessel = feed.vessel

    def json_response(data: Any, status_code: int = 200) -> Response:
        return Response(orjson.dumps(data, option=orjson.OPT_SERIALIZE_NUMPY), status_code=status_code,
                        media_type="application/json")

    async def index(_request: Request) -> HTMLResponse:
        return HTMLResponse(page, headers={"Cache-Control": "no-store"})

    async def info(_request: Request) -> Response:
        geometry = await run_in_threadpool(feed.geometry)
        return json_response({"vessel": vessel, "allow_actions": allow_actions, "modes": list(MODES),
                              "geometry": geometry, "fields": dict(REQUEST_FIELDS), "capability": capability})

    async def trail(_request: Request) -> Response:
        return json_response(feed.trail())

    async def acknowledge(request: Request) -> Response:
        try:
            data = await request.json()
            code, since = data["code"], data.get("since_t_s")
            if not isinstance(code, str) or not (since is None or isinstance(since, (int, float))):
                raise ValueError
        except (ValueError, KeyError, TypeError):
            return json_response({"error": "expected {code, since_t_s}"}, 400)
        feed.acknowledge(code, since)
        return json_response({"acknowledged": [code, since]})

    async def operator_request(request: Request) -> Response:
        if not allow_actions:  # (the page shows no actions then; this answers anybody who posts anyway)
            return json_response({"outcome": "not_sent", "detail": "this console is read-only: start it with "
                                  "--allow-actions to send operator requests"}, 403)
        try:
            fields = request_fields_from_json(await request.json())
        except ValueError as error:
            return json_response({"outcome": "invalid", "detail": f"{error}; nothing sent"}, 400)
        invalid = check_request(fields)  # the daemon's own parser, as dpcontrol setpoint checks
        if invalid is not None:
            return json_response({"outcome": "invalid", "detail": f"{invalid}; nothing sent"}, 400)
        answer = await run_in_threadpool(_send, session_config, vessel, fields, timeout_s)
        return json_response({"outcome": answer.outcome, "detail": answer.detail, "seq": answer.seq,
                              "fields": fields}, 200 if answer.outcome in ("applied", "refused") else 502)

    async def stream(websocket: WebSocket) -> None:
        await websocket.accept()
        period = 1.0 / PUSH_HZ
        try:
            while True:
                await websocket.send_bytes(orjson.dumps(feed.snapshot(), option=orjson.OPT_SERIALIZE_NUMPY))
                await asyncio.sleep(period)
        except (WebSocketDisconnect, RuntimeError):  # the page went away (closed, reloaded)
            return

    routes = [Route("/", index), Route("/api/info", info), Route("/api/trail", trail),
              Route("/api/ack", acknowledge, methods=["POST"]),
              Route("/api/request", operator_request, methods=["POST"]), WebSocketRoute("/ws", stream)]
    return Starlette(routes=routes)


def _send(session_config: ZenohConfig, vessel: str, fields: Mapping[str, Any], timeout_s: float) -> Any:
    """One request over a session of its own, as ``dpcontrol setpoint`` sends it (:func:`send_request`)."""
    from dpcontrol.setpoint import Answer  # noqa: PLC0415

    try:
        node = ZenohNode(session_config, vessel)
    except ZenohOpenError as error:
        return Answer("not_sent", str(error), 0)
    try:
        return send_request(node, fields, timeout_s=timeout_s)
    finally:
        node.close()


def run_console(vessel: str, session_config: ZenohConfig, *, http: str = DEFAULT_HTTP,
                allow_actions: bool = False, timeout_s: float = DEFAULT_TIMEOUT_S,
                started: Callable[[str], None] | None = None, capability: Mapping[str, Any] | None = None) -> int:
    """Serve the console for ``vessel`` until interrupted.

    Parameters
    ----------
    vessel : str
        Vessel ID (``dp/<vessel>/…``).
    session_config : ZenohConfig
        The Zenoh session of the feed and of each operator request (as ``dpcontrol monitor`` and
        ``dpcontrol setpoint`` build it from ``--connect``/``--listen``).
    http : str
        ``HOST:PORT`` to serve the page on (default 127.0.0.1:8470; port 0: any free port).
    allow_actions : bool
        Serve the operator actions (read-only otherwise).
    timeout_s : float
        Longest wait for the controller's answer to a request [s].
    started : callable, optional
        Called with the page's URL once the server listens.
    capability : mapping, optional
        The vessel's DP capability polar (:func:`load_capability`), drawn with the live mean load.

    Returns
    -------
    int
        0 after a clean stop (Ctrl-C, SIGTERM); 1 if the Zenoh session or the web server could not be started;
        2 for invalid arguments.
    """
    try:
        validate_vessel_id(vessel)
        host, port = parse_http_address(http)
    except ValueError as error:
        print(f"dpcontrol console: {error}", file=sys.stderr)
        return 2
    try:
        import uvicorn  # noqa: PLC0415
    except ImportError as error:  # (a dependency of the project; an incomplete install)
        print(f"dpcontrol console: the web server is not installed ({error})", file=sys.stderr)
        return 1
    if not is_loopback_host(host):
        log.warning("console served on %s, beyond this machine: it has no login of its own; put it behind an "
                    "authenticating proxy or reach it through an SSH tunnel (docs/console.md)%s", host,
                    "; operator actions are ENABLED" if allow_actions else "")
    # bound here, not by uvicorn: a port in use is one clear line (uvicorn would exit from inside its loop)
    listener = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
    try:
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((host, port))
    except OSError as error:
        listener.close()
        print(f"dpcontrol console: cannot serve on {http}: {error.strerror or error}", file=sys.stderr)
        return 1
    try:
        node = ZenohNode(session_config, vessel)
    except ZenohOpenError as error:
        listener.close()
        print(f"dpcontrol console: {error}", file=sys.stderr)
        return 1
    try:
        feed = ConsoleFeed(node, vessel)
        app = build_app(feed, session_config=session_config, allow_actions=allow_actions, timeout_s=timeout_s,
                        capability=capability)
        server = uvicorn.Server(uvicorn.Config(app, host=host, port=port, log_level="warning", lifespan="off",
                                               ws="auto"))

        async def serve() -> None:
            task = asyncio.create_task(server.serve(sockets=[listener]))
            while not server.started and not task.done():
                await asyncio.sleep(0.05)
            if server.started:
                bound = server.servers[0].sockets[0].getsockname()
                where = f"[{bound[0]}]" if ":" in bound[0] else bound[0]
                url = f"http://{where}:{bound[1]}/"
                print(f"dpcontrol console: vessel {vessel} at {url} "
                      f"({'operator actions enabled' if allow_actions else 'read-only'})", flush=True)
                if started is not None:
                    started(url)
            await task

        # uvicorn stops gracefully on SIGINT/SIGTERM, then raises the signal again under the handlers it found:
        # SIGTERM (systemd, a test) ends here as a clean stop, SIGINT as the KeyboardInterrupt suppressed below
        main_thread = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGTERM, lambda _signum, _frame: None) if main_thread else None
        try:
            with contextlib.suppress(KeyboardInterrupt):
                asyncio.run(serve())
        finally:
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)
        return 0 if server.started else 1
    finally:
        node.close()
        listener.close()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``console`` options to an argparse (sub)parser."""
    add_zenoh_arguments(parser)
    parser.add_argument("--http", default=DEFAULT_HTTP, metavar="HOST:PORT",
                        help=f"where to serve the page (default {DEFAULT_HTTP}: this machine only; the console has "
                             "no login: beyond this machine, put it behind an authenticating proxy)")
    parser.add_argument("--allow-actions", action="store_true",
                        help="serve the operator actions (mode, set-point, move, turn, thruster reset); "
                             "read-only without it")
    parser.add_argument("--timeout", type=positive_number, default=DEFAULT_TIMEOUT_S, metavar="SECONDS",
                        help=f"longest wait for the controller's answer to an action (default {DEFAULT_TIMEOUT_S:g})")
    parser.add_argument("--capability", metavar="FILE",
                        help="the vessel's capability.json (sim-plant capability): its polar is drawn, with the "
                             "direction of the mean load the thrusters are holding now")


def session_config_from_args(args: argparse.Namespace) -> ZenohConfig:
    """The Zenoh session of the console (its live feed and every action), built from ``--connect``/``--listen``
    and the TLS options exactly as ``dpcontrol monitor`` and ``dpcontrol setpoint`` build theirs: on a secured
    vessel network the console is a ``console`` (or, read-only, a ``monitor``) identity like any other tool."""
    return tool_config(args, LOCAL_DAEMON_CONNECT)


def run_from_args(args: argparse.Namespace) -> int:
    """Run :func:`run_console` from parsed :func:`add_arguments` options."""
    try:
        config = session_config_from_args(args)
        capability = None if args.capability is None else load_capability(args.capability)
    except ValueError as error:
        print(f"dpcontrol console: {error}", file=sys.stderr)
        return 2
    return run_console(args.vessel, config, http=args.http, allow_actions=args.allow_actions, timeout_s=args.timeout,
                       capability=capability)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m dpcontrol.console --vessel ID``."""
    parser = argparse.ArgumentParser(prog="dpcontrol console", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run_from_args(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
