"""``dpcontrol monitor``: a live terminal view of one vessel over Zenoh.

Shows the pose estimate against the setpoint and reference, velocities, MMAE weights (a bar per
model) with the estimated sea state, controller forces and MRAC parameters, per-sensor health,
thruster commands and feedback, alarms, cycle timing, and whether the controller's and the
plant's liveliness tokens are present. It subscribes to ``dp/<vessel>/…`` as a zenoh peer that
listens nowhere; works with any subset of the keys (missing ones show "no data", old ones their
age).

Rendering is a pure function of the latest messages: :func:`render` takes a
:class:`MonitorState` and returns a rich renderable, so it is tested without a terminal.
:func:`run_monitor` wires zenoh, the state and ``rich.live.Live`` together.

Degrees appear here only: this is an edge (a human reads it).
"""

from __future__ import annotations

import argparse
import functools
import math
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from rich.bar import Bar
from rich.columns import Columns
from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from dpbase.frames import ssa
from dpcontrol.arguments import add_zenoh_arguments
from interfaces.zenoh.keys import ROLES, validate_vessel_id
from interfaces.zenoh.node import AliveState, LatestSlot, Received, TopicSubscriber, ZenohNode
from interfaces.zenoh.schemas import parse_message
from interfaces.zenoh.security import ZenohSecurity
from interfaces.zenoh.session_config import LOCAL_DAEMON_CONNECT, ZenohConfig, ZenohOpenError, tool_config

#: Topics the monitor shows (the operator's own setpoint requests are not displayed).
MONITOR_TOPICS: tuple[str, ...] = ("estimate", "mmae", "control", "status", "command", "feedback")
#: Where it connects when no ``--connect`` is given: a daemon on this machine.
DEFAULT_CONNECT = LOCAL_DAEMON_CONNECT

_NO_DATA = "no data"
_PANEL_WIDTH = 62
_DASH = "—"
_STATE_STYLE = {"ok": "green", "waiting": "dim", "isolated": "red", "stale": "yellow", "frozen": "red",
                "rejected": "red", "invalid": "red", "disconnected": "bold red"}
# what an MRAC mass estimate does (control.mrac.state): learning is the normal case, held for want of excitation
# too, stopped by the supervision is the alarm control.adaptation
_ADAPTATION_STYLE = {"adapting": "green", "frozen": "cyan", "suspended": "bold red", "off": "dim"}
_SEVERITY_STYLE = {"info": "cyan", "warning": "yellow", "alarm": "red", "critical": "bold white on red"}


@dataclass(frozen=True)
class TopicView:
    """What the monitor knows about one topic.

    Attributes
    ----------
    message : dict or None
        Newest validated payload (see :func:`interfaces.zenoh.schemas.parse_message`).
    rx_t_s : float or None
        Its receive time on the monitor's clock [s].
    received : int
        Valid messages so far.
    rejected : int
        Payloads refused by validation.
    last_rejection : str or None
        Reason and detail of the newest refusal.
    """

    message: Mapping[str, Any] | None = None
    rx_t_s: float | None = None
    received: int = 0
    rejected: int = 0
    last_rejection: str | None = None


@dataclass(frozen=True)
class MonitorState:
    """Everything :func:`render` draws: the latest message per topic and the liveliness states.

    Attributes
    ----------
    vessel : str
    now_s : float
        Monitor clock now [s] (ages are ``now_s - rx_t_s``).
    topics : mapping of str to TopicView
        Missing topics count as "no data".
    alive : mapping of str to AliveState or None
        ``controller`` / ``plant``; ``None`` when not watched.
    peers : int
        Zenoh peers connected.
    stale_after_s : float
        Age beyond which data is shown as stale [s].
    wall_s : float or None
        Wall-clock time (UNIX epoch) at ``now_s`` [s]: alarm times are shown as UTC clock times; ``None``
        shows ages only.
    """

    vessel: str
    now_s: float
    topics: Mapping[str, TopicView] = field(default_factory=dict)
    alive: Mapping[str, AliveState | None] = field(default_factory=dict)
    peers: int = 0
    stale_after_s: float = 2.0
    wall_s: float | None = None

    def view(self, topic: str) -> TopicView:
        return self.topics.get(topic) or TopicView()

    def message(self, topic: str) -> Mapping[str, Any] | None:
        return self.view(topic).message


# ---------------------------------------------------------------------------------------------
# Formatting helpers: tolerate anything (a missing key, a None, a wrong type) and show a dash
# ---------------------------------------------------------------------------------------------

def _get(data: Any, *path: str | int) -> Any:
    for key in path:
        if isinstance(key, int):
            if not isinstance(data, list) or not -len(data) <= key < len(data):
                return None
        elif not isinstance(data, Mapping):
            return None
        data = data[key] if isinstance(key, int) else data.get(key)
    return data


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        number = float(value)
    except OverflowError:  # an enormous integer
        return None
    return number if math.isfinite(number) else None


def _fmt(value: Any, spec: str = ".2f", scale: float = 1.0) -> str:
    number = _number(value)
    return _DASH if number is None else format(number * scale, spec)


def _deg(value: Any, spec: str = ".1f") -> str:
    number = _number(value)
    return _DASH if number is None else format(math.degrees(number), spec)


def _heading_deg(value: Any) -> str:
    """Heading as a compass bearing in [0, 360) degrees."""
    number = _number(value)
    return _DASH if number is None else f"{math.degrees(number) % 360.0:.1f}"


#: SI prefixes a force column may take, by magnitude (a 1:70 model's forces are newtons, a tanker's meganewtons).
_FORCE_PREFIXES: tuple[tuple[str, float], ...] = (("", 1.0), ("k", 1e3), ("M", 1e6))


def _force_unit(values: Sequence[Any], unit: str = "N") -> tuple[str, float, str]:
    """``(label, scale, spec)`` for one column of forces [N] (or moments [N·m]): the largest prefix that keeps
    the column's biggest magnitude at or above 1, and enough decimals for three significant digits there."""
    numbers = [abs(n) for n in map(_number, values) if n is not None]
    largest = max(numbers, default=0.0)
    prefix, scale = _FORCE_PREFIXES[0]
    for candidate, candidate_scale in _FORCE_PREFIXES:
        if largest >= candidate_scale:
            prefix, scale = candidate, candidate_scale
    scaled = largest / scale
    decimals = 2 if scaled < 10.0 else 1 if scaled < 100.0 else 0
    return prefix + unit, 1.0 / scale, f".{decimals}f"


def _text(value: Any, limit: int = 60) -> str:
    if value is None:
        return ""
    text = str(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _row(table: Table, *cells: RenderableType) -> None:
    """Add a row; plain strings become :class:`Text` so ``[m]`` or a payload's brackets are never markup."""
    table.add_row(*(Text(cell) if isinstance(cell, str) else cell for cell in cells))


def _col(table: Table, header: str = "", **kwargs: Any) -> None:
    table.add_column(Text(header), **kwargs)


def _age(state: MonitorState, topic: str) -> tuple[str, str]:
    """``(label, style)`` describing how old a topic's data is."""
    view = state.view(topic)
    if view.message is None or view.rx_t_s is None:
        return _NO_DATA, "dim"
    age = max(0.0, state.now_s - view.rx_t_s)
    if age > state.stale_after_s:
        return f"stale {age:.1f} s", "yellow"
    return f"{age:.1f} s", "green"


def _title(state: MonitorState, topic: str, name: str) -> Text:
    label, style = _age(state, topic)
    title = Text(name, style="bold")
    title.append(f" ({label})", style=style)
    return title


def _no_data(state: MonitorState, topic: str, name: str) -> Panel:
    return Panel(Text(_NO_DATA, style="dim"), title=_title(state, topic, name), title_align="left")


# ---------------------------------------------------------------------------------------------
# Panels
# ---------------------------------------------------------------------------------------------

def _alive_text(role: str, alive: AliveState | None) -> Text:
    if alive is None:
        return Text(f"{role}: ?", style="dim")
    if alive.present:
        return Text(f"{role} ● alive", style="green")
    if alive.seen:
        return Text(f"{role} ✖ LOST", style="bold white on red")
    return Text(f"{role} ○ not seen", style="yellow")


def _drives_seen(status: Any) -> AliveState | None:
    """The plant/drives' liveliness as the daemon reports it (``status.drives``), ``None`` when it does not."""
    drives = _get(status, "drives")
    present, seen = _get(drives, "present"), _get(drives, "seen")
    if not isinstance(present, bool) or not isinstance(seen, bool):
        return None
    return AliveState(present=present, seen=seen or present, since_t_s=None, losses=0)


def _header(state: MonitorState) -> Panel:
    status = state.message("status")
    command = state.message("command")
    mode = _get(status, "mode") or _get(command, "mode")
    line = Text()
    line.append(f"vessel {state.vessel}", style="bold")
    line.append("   mode ")
    line.append(_text(mode) or _NO_DATA, style="bold cyan" if mode else "dim")
    for role in ROLES:
        line.append("   ")
        # the plant as the daemon sees it (what matters is whether the controller hears the drives); this
        # session's own view only when the daemon does not say
        daemon_view = _drives_seen(status) if role == "plant" else None
        line.append_text(_alive_text(role, daemon_view or state.alive.get(role)))
        if role == "plant" and daemon_view is None and state.alive.get(role) is not None:
            line.append(" (monitor's view)", style="dim")
    line.append(f"   peers {state.peers}", style="green" if state.peers else "yellow")
    _request_line(line, status)
    return Panel(line, title="dpcontrol monitor", title_align="left")


def _request_line(line: Text, status: Any) -> None:
    """What became of the last operator request (``status.request``): its outcome, what is in force or why
    not, and how long ago in the controller's time; nothing before the first request."""
    request = _get(status, "request")
    if not isinstance(request, Mapping):
        return
    outcome = _text(_get(request, "outcome"), 16)
    line.append("\nlast request ")
    line.append(outcome or _DASH, style={"applied": "green", "refused": "bold red"}.get(outcome, "dim"))
    now, then = _number(_get(status, "t_s")), _number(_get(request, "t_s"))
    if now is not None and then is not None:
        line.append(f" {max(0.0, now - then):.0f} s ago", style="dim")
    line.append(f": {_text(_get(request, 'detail'), 160)}")


def _pose_panel(state: MonitorState) -> Panel:
    estimate = state.message("estimate")
    control = state.message("control")
    if estimate is None and control is None:
        return _no_data(state, "estimate", "Position")
    table = Table(box=None, pad_edge=False, expand=True)
    _col(table, "")
    for name in ("estimate", "setpoint", "reference", "error"):
        _col(table, name, justify="right")
    pose = _get(estimate, "pose_n")
    setpoint = _get(control, "setpoint")
    reference = _get(control, "reference")
    for key, label in (("north_m", "north [m]"), ("east_m", "east [m]")):
        est, sp = _number(_get(pose, key)), _number(_get(setpoint, key))
        error = None if est is None or sp is None else est - sp
        _row(table, label, _fmt(est), _fmt(sp), _fmt(_get(reference, key)), _fmt(error))
    est_psi, sp_psi = _number(_get(pose, "heading_rad")), _number(_get(setpoint, "heading_rad"))
    psi_error = None if est_psi is None or sp_psi is None else ssa(est_psi - sp_psi)
    _row(table, "heading [deg]", _heading_deg(est_psi), _heading_deg(sp_psi),
                  _heading_deg(_get(reference, "heading_rad")), _deg(psi_error))
    estimator = _get(estimate, "estimator")
    title = _title(state, "estimate", "Position" + (f" · {estimator}" if isinstance(estimator, str) else ""))
    return Panel(table, title=title, title_align="left")


def _motion_panel(state: MonitorState) -> Panel:
    estimate = state.message("estimate")
    if estimate is None:
        return _no_data(state, "estimate", "Velocity / bias / waves")
    table = Table(box=None, pad_edge=False, expand=True)
    _col(table, "")
    _col(table, "estimate", justify="right")
    _col(table, "reference", justify="right")
    velocity = _get(estimate, "velocity_b")
    reference = _get(state.message("control"), "reference")
    _row(table, "surge [m/s]", _fmt(_get(velocity, "surge_mps"), ".3f"), _fmt(_get(reference, "surge_mps"), ".3f"))
    _row(table, "sway [m/s]", _fmt(_get(velocity, "sway_mps"), ".3f"), _fmt(_get(reference, "sway_mps"), ".3f"))
    _row(table, "yaw rate [deg/s]", _deg(_get(velocity, "yaw_rate_radps"), ".2f"),
                  _deg(_get(reference, "yaw_rate_radps"), ".2f"))
    bias = _get(estimate, "bias")
    frame = _get(bias, "frame")
    unit, scale, spec = _force_unit([_get(bias, "x_n"), _get(bias, "y_n")])
    _row(table, f"bias X/Y [{unit}] ({frame or _DASH})",
                  f"{_fmt(_get(bias, 'x_n'), spec, scale)} / {_fmt(_get(bias, 'y_n'), spec, scale)}", "")
    unit, scale, spec = _force_unit([_get(bias, "n_nm")], "N·m")
    _row(table, f"bias N [{unit}]", _fmt(_get(bias, "n_nm"), spec, scale), "")
    wave = _get(estimate, "wave_n")
    _row(table, "WF north/east [m]", f"{_fmt(_get(wave, 'north_m'))} / {_fmt(_get(wave, 'east_m'))}", "")
    _row(table, "WF heading [deg]", _deg(_get(wave, "heading_rad"), ".2f"), "")
    return Panel(table, title=_title(state, "estimate", "Velocity / bias / waves"), title_align="left")


#: How the daemon's sea-state classes read (Froude-scaled seed 001 Table I, see ``SeaStateTable.froude_scaled``).
_SEA_STATE_LABEL = {"long_swell": "long swell (longer than high, for this hull)",
                    "outside_table": "outside the table (longer than high)"}


def _mmae_panel(state: MonitorState) -> Panel:
    mmae = state.message("mmae")
    if mmae is None:
        return _no_data(state, "mmae", "MMAE")
    omegas = _get(mmae, "omegas_rad_s")
    weights = _get(mmae, "weights")
    table = Table(box=None, pad_edge=False, expand=True)
    _col(table, "ω [rad/s]", justify="right")
    _col(table, "weight", ratio=1)
    _col(table, "", justify="right")
    if isinstance(omegas, list) and isinstance(weights, list):
        numbers = [_number(w) for w in weights]
        best = max(range(len(numbers)), key=lambda i: numbers[i] or 0.0) if numbers else -1
        for i, omega in enumerate(omegas):
            w = numbers[i] if i < len(numbers) else None
            style = "bold green" if i == best else "blue"
            bar = Bar(1.0, 0.0, min(max(w or 0.0, 0.0), 1.0), width=24, color=style.rsplit(maxsplit=1)[-1])
            _row(table, _fmt(omega), bar, Text(_fmt(w, ".1%", 1.0) if w is not None else _DASH, style=style))
    omega_hat = _number(_get(mmae, "omega_hat_rad_s"))
    sea_state = _get(mmae, "sea_state")
    # the peak period a sea-keeping engineer reads; the class is the daemon's, drawn for this hull's length
    period = "" if not omega_hat else f" (Tp {2.0 * math.pi / omega_hat:.1f} s)"
    summary = Text(f"ω̂ = {_fmt(omega_hat, '.3f')} rad/s{period}   sea state: ")
    summary.append(_SEA_STATE_LABEL.get(str(sea_state), _text(sea_state)) or _DASH, style="bold")
    return Panel(Group(table, summary), title=_title(state, "mmae", "MMAE wave filter"), title_align="left")


def _control_panel(state: MonitorState) -> Panel:
    control = state.message("control")
    if control is None:
        return _no_data(state, "control", "Control")
    table = Table(box=None, pad_edge=False, expand=True)
    _col(table, "")
    forces = ("tau_b", "tau_achieved_b", "shortfall_b")
    units = [_force_unit([_get(control, key, k) for key in forces], "N·m" if k == "n_nm" else "N")
             for k in ("x_n", "y_n", "n_nm")]
    for name, (unit, _, _) in zip(("X", "Y", "N"), units, strict=True):
        _col(table, f"{name} [{unit}]", justify="right")
    for key, label in zip(forces, ("commanded τ", "achieved", "shortfall"), strict=True):
        force = _get(control, key)
        _row(table, label, *(_fmt(_get(force, k), spec, scale)
                             for k, (_, scale, spec) in zip(("x_n", "y_n", "n_nm"), units, strict=True)))
    wave = _get(state.message("status"), "wave_band")  # how much wave motion reaches the controller
    if isinstance(wave, Mapping):
        f_unit, f_scale, f_spec = _force_unit([_get(wave, "force_n")])
        m_unit, m_scale, m_spec = _force_unit([_get(wave, "moment_nm")], "N·m")
        _row(table, "wave-band std", f"{_fmt(_get(wave, 'force_n'), f_spec, f_scale)} {f_unit}", "(X, Y)",
             f"{_fmt(_get(wave, 'moment_nm'), m_spec, m_scale)} {m_unit}")
    mrac = _get(control, "mrac")
    if isinstance(mrac, Mapping):
        mass, damping = _get(mrac, "mass"), _get(mrac, "damping")
        _row(table, "MRAC mass [t, t, t·m²]",
                      *(_fmt(_get(mass, k), ".5g", 1e-3) for k in ("surge_kg", "sway_kg", "yaw_kgm2")))
        _row(table, "MRAC damping [t/s …]",
                      *(_fmt(_get(damping, k), ".5g", 1e-3) for k in ("surge_kgps", "sway_kgps", "yaw_kgm2ps")))
        adaptation = _adaptation_cells(mrac)
        if adaptation is not None:
            _row(table, "MRAC mass / nominal", *adaptation)
    else:
        _row(table, "MRAC", "off", "", "")
    controller = _get(control, "controller")
    name = "Control" + (f" · {controller}" if isinstance(controller, str) else "")
    return Panel(table, title=_title(state, "control", name), title_align="left")


def _adaptation_cells(mrac: Mapping[str, Any]) -> list[Text] | None:
    """Per DOF ``1.12× adapting``: the mass estimate over its nominal value and what it does, coloured by the
    state (``control.mrac.ratio`` / ``state``); None when the daemon does not send them."""
    ratio, states = _get(mrac, "ratio"), _get(mrac, "state")
    if not isinstance(ratio, Mapping) and not isinstance(states, Mapping):
        return None
    cells = []
    for dof in ("surge", "sway", "yaw"):
        value = _number(_get(ratio, dof))
        what = _get(states, dof)
        text = (_DASH if value is None else f"{value:.2f}×") + (f" {_text(what, 10)}" if isinstance(what, str) else "")
        cells.append(Text(text, style=_ADAPTATION_STYLE.get(str(what), "")))
    return cells


def _sensors_panel(state: MonitorState) -> Panel:
    status = state.message("status")
    sensors = _get(status, "sensors")
    if not isinstance(sensors, list):
        return _no_data(state, "status", "Sensors")
    table = Table(box=None, pad_edge=False, expand=True)
    for name, justify in (("sensor", "left"), ("kind", "left"), ("state", "left"), ("age [s]", "right"),
                          ("weight", "right"), ("detail", "left")):
        _col(table, name, justify=justify)
    for sensor in sensors:
        sensor_state = _get(sensor, "state")
        _row(table, _text(_get(sensor, "name"), 20), _text(_get(sensor, "kind"), 16),
                      Text(_text(sensor_state, 14) or _DASH, style=_STATE_STYLE.get(str(sensor_state), "")),
                      _fmt(_get(sensor, "age_s"), ".2f"), _fmt(_get(sensor, "weight"), ".2f"),
                      _text(_get(sensor, "detail"), 40))
    if not sensors:
        _row(table, "(none)", "", "", "", "", "")
    return Panel(table, title=_title(state, "status", "Sensors"), title_align="left")


def _thrusters_panel(state: MonitorState) -> Panel:
    command = state.message("command")
    feedback = state.message("feedback")
    availability = _get(state.message("status"), "thrusters")
    if command is None and feedback is None and not isinstance(availability, list):
        return _no_data(state, "command", "Thrusters")
    rows: dict[str, dict[str, Any]] = {}
    for source, items in (("cmd", _get(command, "thrusters")), ("fb", _get(feedback, "thrusters")),
                          ("avail", availability)):
        if isinstance(items, list):
            for item in items:
                name = _get(item, "name")
                if isinstance(name, str):
                    rows.setdefault(name, {})[source] = item
    cmd_unit, cmd_scale, cmd_spec = _force_unit([_get(p.get("cmd"), "thrust_n") for p in rows.values()])
    fb_unit, fb_scale, fb_spec = _force_unit([_get(p.get("fb"), "thrust_n") for p in rows.values()])
    table = Table(box=None, pad_edge=False, expand=True)
    for name in ("thruster", f"cmd [{cmd_unit}]", "cmd [deg]", "on", f"fb [{fb_unit}]", "fb [deg]", "ready",
                 "available"):
        _col(table, name, justify="left" if name == "thruster" else "right")
    for name, parts in rows.items():
        cmd, fb, avail = parts.get("cmd"), parts.get("fb"), parts.get("avail")
        enabled = _get(cmd, "enabled")
        ready = _get(fb, "ready")
        available = _get(avail, "available")
        _row(table,
            _text(name, 20), _fmt(_get(cmd, "thrust_n"), cmd_spec, cmd_scale), _deg(_get(cmd, "azimuth_rad")),
            _flag(enabled), _fmt(_get(fb, "thrust_n"), fb_spec, fb_scale), _deg(_get(fb, "azimuth_rad")), _flag(ready),
            _flag(available, _text(_get(avail, "detail"), 24)))
    title = _title(state, "command", "Thrusters (command)")
    fb_label, fb_style = _feedback_age(state)
    title.append(f"  feedback ({fb_label})", style=fb_style)
    worst_case = _worst_case_line(_get(state.message("status"), "consequence"))
    return Panel(table if worst_case is None else Group(table, worst_case), title=title, title_align="left")


def _feedback_age(state: MonitorState) -> tuple[str, str]:
    """``(label, style)``: how old the thruster feedback the daemon last received is (``status.drives``), else
    what this session itself receives (marked so)."""
    drives = _get(state.message("status"), "drives")
    if not isinstance(drives, Mapping):
        label, style = _age(state, "feedback")
        return label + " here", style
    age = _number(_get(drives, "feedback_age_s"))
    if age is None:
        return "none received by the daemon", "yellow"
    if age > state.stale_after_s:
        return f"daemon's stale {age:.1f} s", "yellow"
    return f"daemon's {age:.1f} s", "green"


def _worst_case_line(check: Any) -> Text | None:
    """The last worst-case failure check (``status.consequence``): per failure group, whether the thrusters left
    would hold the demand and how hard the busiest of them would work (and which); nothing when no check ran."""
    groups = _get(check, "groups")
    if not isinstance(groups, list):
        return None
    line = Text("worst case:")
    for group in groups[:16]:
        holds = _get(group, "holds")
        utilisation = _number(_get(group, "utilisation"))
        line.append(f"  {_text(_get(group, 'name'), 20)} ")
        if holds is True:
            busiest = _get(group, "busiest")
            share = "" if utilisation is None else f" {100.0 * utilisation:.0f} %"
            if share and isinstance(busiest, str):
                share = f" ({_text(busiest, 20)}{share})"
            line.append("holds" + share, style="yellow" if utilisation is not None and utilisation >= 0.9 else "green")
        else:
            line.append("WOULD NOT HOLD" if holds is False else _DASH, style="bold red" if holds is False else "dim")
    return line


def _flag(value: Any, detail: str = "") -> Text:
    if value is True:
        return Text("yes", style="green")
    if value is False:
        return Text("no" + (f" ({detail})" if detail else ""), style="red")
    return Text(_DASH, style="dim")


def alarm_times(state: MonitorState, since_t_s: Any) -> tuple[float | None, float | None]:
    """``(age [s], UTC epoch [s])`` of an alarm raised at ``since_t_s`` on the daemon's clock.

    The age is counted on the daemon's clock (``status.t_s − since_t_s``) plus how long ago the status arrived;
    the clock time is this host's wall clock minus that age (``None`` without :attr:`MonitorState.wall_s`).
    """
    status = state.message("status")
    view = state.view("status")
    now, since = _number(_get(status, "t_s")), _number(since_t_s)
    if now is None or since is None:
        return None, None
    age = max(0.0, now - since) + (0.0 if view.rx_t_s is None else max(0.0, state.now_s - view.rx_t_s))
    return age, None if state.wall_s is None else state.wall_s - age


def _age_text(age_s: float | None) -> str:
    if age_s is None:
        return _DASH
    if age_s < 120.0:
        return f"{age_s:.0f} s"
    if age_s < 7200.0:
        return f"{age_s / 60.0:.0f} min"
    return f"{age_s / 3600.0:.1f} h"


def _alarms_panel(state: MonitorState, limit: int = 10) -> Panel:
    alarms = _get(state.message("status"), "alarms")
    if not isinstance(alarms, list):
        return _no_data(state, "status", "Alarms")
    ordered = sorted((a for a in alarms if isinstance(a, Mapping)), key=lambda a: _get(a, "active") is not True)
    table = Table(box=None, pad_edge=False, expand=True)
    for name in ("code", "severity", "state", "age", "since (UTC)", "text"):
        _col(table, name, no_wrap=name != "text")
    for alarm in ordered[:limit]:
        severity = _get(alarm, "severity")
        active = _get(alarm, "active") is True
        style = _SEVERITY_STYLE.get(str(severity), "") if active else "dim"
        age, wall = alarm_times(state, _get(alarm, "since_t_s"))
        clock = _DASH if wall is None else time.strftime("%H:%M:%S", time.gmtime(wall))
        # the full code (the schema bounds it at 64 characters): codes are what an operator looks up
        _row(table, Text(_text(_get(alarm, "code"), 64), style=style), Text(_text(severity, 10), style=style),
             Text("active" if active else "cleared", style=style), _age_text(age), clock,
             Text(_text(_get(alarm, "text"), 120), style=style))
    active_count = sum(1 for a in ordered if _get(a, "active") is True)
    if not ordered:
        _row(table, Text("none", style="green"), "", "", "", "", "")
    elif len(ordered) > limit:
        _row(table, "…", "", "", "", "", f"{len(ordered) - limit} more")
    title = Text("Alarms", style="bold")
    title.append(f" ({active_count} active", style="red" if active_count else "green")
    title.append(f", {len(ordered) - active_count} cleared)", style="dim")
    return Panel(table, title=title, title_align="left")


def _footer(state: MonitorState) -> Text:
    cycle = _get(state.message("status"), "cycle")
    line = Text("cycle ")
    if isinstance(cycle, Mapping):
        missed = _get(cycle, "missed_deadlines")
        line.append(f"period {_fmt(_get(cycle, 'period_s'), '.3f')} s  "
                    f"duration {_fmt(_get(cycle, 'duration_us'), '.0f')} µs  "
                    f"p99 {_fmt(_get(cycle, 'p99_us'), '.0f')} µs  missed ")
        line.append(str(missed) if isinstance(missed, int) else _DASH, style="red" if missed else "green")
        steal = _get(cycle, "host_steal_percent")
        if isinstance(steal, (int, float)):  # absent from older daemons, null where it cannot be read
            # yellow from 1 %: in the HIL demos of 2026-12-02 the latency p99 passed 2 ms in every run with 0.5 %
            # of steal or more (README, Benchmarks); 1 % marks a host that is clearly in the way
            line.append(f"  host steal {steal:.1f} %", style="yellow" if steal >= 1.0 else "")
    else:
        line.append(_NO_DATA, style="dim")
    line.append("\nages: ")
    for i, topic in enumerate(MONITOR_TOPICS):
        label, style = _age(state, topic)
        line.append(("  " if i else "") + f"{topic} ")
        line.append(label, style=style)
    rejected = [(topic, state.view(topic)) for topic in MONITOR_TOPICS if state.view(topic).rejected]
    for topic, view in rejected:
        line.append(f"\nrejected {topic}: {view.rejected}", style="red")
        if view.last_rejection:
            line.append(f" (last: {_text(view.last_rejection, 90)})", style="red")
    return line


def render(state: MonitorState) -> RenderableType:
    """Draw the monitor from ``state`` alone (pure: no clock, no I/O).

    Parameters
    ----------
    state : MonitorState
        Latest validated messages, liveliness, and the time to compute ages against.

    Returns
    -------
    rich.console.RenderableType
        Print it with a :class:`rich.console.Console`, or hand it to ``rich.live.Live``.
    """
    # Side by side on a wide terminal, stacked on a narrow one.
    top = Columns([_pose_panel(state), _motion_panel(state), _mmae_panel(state), _control_panel(state)],
                  width=_PANEL_WIDTH, expand=True)
    return Group(_header(state), top, _sensors_panel(state), _thrusters_panel(state), _alarms_panel(state),
                 _footer(state))


# ---------------------------------------------------------------------------------------------
# Live view over zenoh
# ---------------------------------------------------------------------------------------------

_LIVELINESS_GRACE_S = 0.3
"""Longest extra wait of ``--once`` for a liveliness token once every topic has data [s]."""


class _Feed:
    """The zenoh side of the monitor: one validating subscriber per topic, two liveliness watchers."""

    def __init__(self, node: ZenohNode, vessel: str, stale_after_s: float, clock: Callable[[], float]) -> None:
        self.node = node
        self.vessel = vessel
        self.stale_after_s = stale_after_s
        self.clock = clock
        self.changed = threading.Event()
        changed = self.changed.set
        # Watchers before subscribers: a peer answers the watchers' history interest on the same link before
        # it sees the subscribers and starts sending data, so a --once snapshot that has every topic also has
        # the liveliness of the peers that sent them (declared the other way round, a loaded host printed
        # "controller not seen" next to the controller's data).
        self.watchers = {role: node.watch_alive(role, on_change=lambda _present, _t: changed()) for role in ROLES}
        self.subscribers: dict[str, TopicSubscriber[LatestSlot[Received[Any]]]] = {
            topic: node.subscribe(topic, LatestSlot(on_put=changed), parse=functools.partial(parse_message, topic))
            for topic in MONITOR_TOPICS}

    def snapshot(self) -> MonitorState:
        topics = {}
        for topic, subscriber in self.subscribers.items():
            latest = subscriber.sink.latest()
            stats = subscriber.stats
            last = stats.last_rejection
            topics[topic] = TopicView(
                message=None if latest is None else latest.message, rx_t_s=None if latest is None else latest.rx_t_s,
                received=stats.accepted, rejected=stats.rejected,
                last_rejection=None if last is None else f"{last.reason}: {last.detail}")
        return MonitorState(vessel=self.vessel, now_s=self.clock(), topics=topics,
                            alive={role: w.state for role, w in self.watchers.items()},
                            peers=len(self.node.peers()), stale_after_s=self.stale_after_s, wall_s=time.time())

    def complete(self) -> bool:
        return all(s.sink.count > 0 for s in self.subscribers.values())

    def print_once(self, console: Console, wait_s: float) -> int:
        deadline = self.clock() + wait_s
        while not self.complete():
            remaining = deadline - self.clock()
            if remaining <= 0.0:
                break
            self.changed.wait(remaining)
            self.changed.clear()
        # Ordering on the link (see __init__) is what zenoh does today, not what it promises: give a token
        # not heard yet a short grace, still within wait_s.
        grace_end = min(deadline, self.clock() + _LIVELINESS_GRACE_S)
        for watcher in self.watchers.values():
            watcher.wait_for(True, max(0.0, grace_end - self.clock()))
        state = self.snapshot()
        console.print(render(state))
        heard = any(view.message is not None for view in state.topics.values()) or any(
            alive is not None and alive.seen for alive in state.alive.values())
        return 0 if heard else 1

    def live(self, console: Console, duration_s: float | None, refresh_hz: float) -> None:
        min_interval = 1.0 / refresh_hz
        start = last = self.clock()
        with Live(render(self.snapshot()), console=console, auto_refresh=False, transient=False) as live:
            while duration_s is None or self.clock() - start < duration_s:
                # Wake on new data (the publish rate) or every 0.5 s so the ages keep moving.
                left = 0.5 if duration_s is None else duration_s - (self.clock() - start)
                self.changed.wait(max(0.0, min(0.5, left)))
                self.changed.clear()
                pause = min_interval - (self.clock() - last)
                if pause > 0.0:
                    time.sleep(pause)  # rate limit, not a wait for a condition
                last = self.clock()
                live.update(render(self.snapshot()), refresh=True)


def run_monitor(vessel: str, connect: Sequence[str] = DEFAULT_CONNECT, *, listen: Sequence[str] = (),  # noqa: PLR0913 - the command line's options, keyword-only
                once: bool = False, wait_s: float = 3.0, duration_s: float | None = None,
                refresh_hz: float = 10.0, stale_after_s: float = 2.0, console: Console | None = None,
                clock: Callable[[], float] = time.monotonic, security: ZenohSecurity | None = None) -> int:
    """Run the live monitor (or print one snapshot) for ``vessel``.

    Parameters
    ----------
    vessel : str
        Vessel ID (``dp/<vessel>/…``).
    connect : sequence of str
        Zenoh endpoints to connect to (the daemon's listen endpoint); default ``tcp/127.0.0.1:7447``.
    listen : sequence of str
        Endpoints to listen on (none by default: the monitor only connects).
    once : bool
        Print one snapshot and exit: as soon as every topic has data, at the latest after ``wait_s``.
    wait_s : float
        Longest wait for data with ``once`` [s].
    duration_s : float, optional
        Stop the live view after this long [s] (default: until Ctrl-C).
    refresh_hz : float
        Most redraws per second; the view redraws when data arrives (at the publish rate) and at
        least twice a second so ages move.
    stale_after_s : float
        Age beyond which data is shown as stale [s].
    console : rich.console.Console, optional
        Output (default: stdout).
    clock : callable
        Monotonic clock [s].
    security : ZenohSecurity, optional
        This tool's TLS identity (a monitor's or a console's) on a secured vessel network.

    Returns
    -------
    int
        0 on success (with ``once``: something was heard from the vessel); 1 if the zenoh session
        could not be opened or, with ``once``, nothing was heard within ``wait_s``; 2 for invalid
        arguments (message on stderr).
    """
    console = console or Console()
    errors = Console(stderr=True, soft_wrap=True)  # one line per message, whatever the width
    try:
        validate_vessel_id(vessel)
        if not refresh_hz > 0.0 or not wait_s >= 0.0 or (duration_s is not None and not duration_s >= 0.0):
            raise ValueError("refresh_hz must be > 0, wait_s and duration_s >= 0")
        config = ZenohConfig(listen=tuple(listen), connect=tuple(connect), security=security)
    except ValueError as exc:
        errors.print(f"dpcontrol monitor: {exc}", markup=False, highlight=False)
        return 2
    try:
        node = ZenohNode(config, vessel, clock=clock)
    except ZenohOpenError as exc:
        errors.print(f"dpcontrol monitor: {exc}", markup=False, highlight=False)
        return 1
    try:
        feed = _Feed(node, vessel, stale_after_s, clock)
        if once:
            code = feed.print_once(console, wait_s)
            if code != 0:
                where = ", ".join([*(f"connecting to {e}" for e in connect), *(f"listening on {e}" for e in listen)])
                errors.print(f"dpcontrol monitor: nothing heard from vessel {vessel!r} within {wait_s:g} s "
                             f"({where or 'no endpoints'}; {len(node.peers())} zenoh peers): is `dpcontrol run` up, "
                             "with this vessel_id, and is the endpoint its zenoh.listen?", markup=False,
                             highlight=False)
            return code
        feed.live(console, duration_s, refresh_hz)
        return 0
    except KeyboardInterrupt:
        return 0
    finally:
        node.close()


# ---------------------------------------------------------------------------------------------
# Command-line glue (the lead wires it into ``dpcontrol monitor``)
# ---------------------------------------------------------------------------------------------

def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``monitor`` options to an argparse (sub)parser."""
    add_zenoh_arguments(parser)
    parser.add_argument("--once", action="store_true",
                        help="print one snapshot (when every topic has data, at most after --wait seconds) and exit")
    parser.add_argument("--wait", type=float, default=3.0, metavar="SECONDS",
                        help="with --once: longest wait for data (default 3)")
    parser.add_argument("--duration", type=float, default=None, metavar="SECONDS",
                        help="stop the live view after this many seconds")
    parser.add_argument("--refresh-hz", type=float, default=10.0, help="most redraws per second (default 10)")


def run_from_args(args: argparse.Namespace) -> int:
    """Run :func:`run_monitor` from parsed :func:`add_arguments` options."""
    try:
        config = tool_config(args, DEFAULT_CONNECT)
    except ValueError as exc:
        print(f"dpcontrol monitor: {exc}", file=sys.stderr)
        return 2
    return run_monitor(args.vessel, config.connect, listen=config.listen, once=args.once, wait_s=args.wait,
                       duration_s=args.duration, refresh_hz=args.refresh_hz, security=config.security)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m dpcontrol.monitor --vessel ID`` (until the ``dpcontrol monitor`` subcommand is wired)."""
    parser = argparse.ArgumentParser(prog="dpcontrol monitor", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run_from_args(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
