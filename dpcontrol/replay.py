"""``dpcontrol replay LOG --config FILE``: a recording fed back through the same control step.

The daemon records every raw input (with a sequence number), and for every control cycle which
inputs' measurements that step consumed, the thruster feedback, the link changes and the operator
requests it saw (``cycle`` records), plus the state it resumed from (``state_loaded``). Replay
decodes the raw inputs with the same codecs and router, runs :meth:`DpController.step` on exactly
those inputs at the recorded times, and compares the commands it produces with the recorded ones:
with the same configuration they must be identical (bit for bit — the recorder keeps floats
exactly); with another (e.g. another estimator) the new commands are written beside the old for
comparison, with plots.
"""

from __future__ import annotations

import json
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from dpbase.yamlfile import load_yaml
from dpcontrol.logtools import read_config, read_records
from dpcontrol.runtime.config import DaemonConfig, load_config
from dpcontrol.runtime.ingest import transport_inputs
from dpcontrol.runtime.inputs import SensorRouter
from dpcontrol.runtime.step import DpController
from dpcontrol.runtime.thruster_monitor import ThrusterFeedback
from dpcontrol.service.daemon import request_from_dict
from interfaces.messages import Measurement


class RawDecoders:
    """The daemon's decoding and routing (:mod:`dpcontrol.runtime.ingest`), applied to recorded raw inputs."""

    def __init__(self, config: DaemonConfig) -> None:
        self.router = SensorRouter(config.routes, config.transports)
        self._inputs = transport_inputs(config.transports, self.router)

    def decode(self, transport: str, t_s: float, payload: dict[str, Any], data: bytes) -> list[Measurement]:
        """Routed measurements of one raw input (as the daemon's :class:`InputPump` produced them); an input of
        a transport the configuration does not have gives none."""
        out: list[Measurement] = []
        stage = self._inputs.get(transport)
        if stage is not None:
            stage.feed_record(t_s, payload, data, out)
        return out


@dataclass
class Recording:
    """What replay needs of a recording: the raw inputs by number, the cycles, the commands, the resumed state."""

    raw: dict[int, tuple[str, float, dict[str, Any], bytes]] = field(default_factory=dict)
    cycles: list[dict[str, Any]] = field(default_factory=list)
    commands: dict[int, dict[str, Any]] = field(default_factory=dict)
    state_loaded: dict[str, Any] | None = None
    state_t_s: float | None = None

    @classmethod
    def read(cls, log: Path) -> Recording:
        """Read ``log`` (an MCAP recording of the daemon).

        Raises
        ------
        ValueError
            Nothing could be read (not an MCAP recording, or empty), or no ``cycle`` records (recorded by another
            version, or recording was off).
        """
        recording = cls()
        n_records = 0
        for record in read_records(log):
            n_records += 1
            recording._add(record.topic, record.payload, record.data, record.t_s)
        if n_records == 0:
            raise ValueError(f"{log}: no records read — not a dpcontrol recording (MCAP), or empty")
        if not recording.cycles:
            raise ValueError(f"{log}: no 'cycle' records — recorded without inputs, cannot replay")
        return recording

    def _add(self, topic: str, payload: dict[str, Any], data: bytes | None, t_s: float | None) -> None:
        if topic.startswith("raw/"):
            seq = payload.get("seq")
            if isinstance(seq, int) and data is not None:
                self.raw[seq] = (topic[4:], float(payload.get("t_s") or 0.0), payload, data)
        elif topic == "cycle":
            self.cycles.append(payload)
        elif topic == "command" and isinstance(payload.get("cycle"), int):
            self.commands[payload["cycle"]] = payload
        elif topic == "state_loaded" and self.state_loaded is None:
            self.state_loaded = payload.get("state")
            self.state_t_s = t_s


@dataclass
class Commands:
    """Recorded and replayed commands, one row per cycle (NaN where the recording has no command)."""

    times: np.ndarray
    old_thrust: np.ndarray
    new_thrust: np.ndarray
    old_azimuth: np.ndarray
    new_azimuth: np.ndarray
    missing_inputs: int = 0
    first_difference: int | None = None


def replay(log: Path, config_path: Path, out_dir: Path | None = None, *, plots: bool = True) -> dict[str, Any]:
    """Replay ``log`` with the configuration ``config_path``; returns the comparison report.

    Raises
    ------
    ValueError
        Nothing could be read from ``log`` (not an MCAP recording, or empty), or it has no ``cycle``
        records (recorded by another version, or recording was off).
    """
    config = load_config(config_path)
    # (damage is reported once, by the full pass below: this one reads up to the first config record)
    recorded = read_config(log, on_issue=lambda _path, _message: None) or {}
    same_config = recorded.get("config_sha256") == config.config_hash
    recording = Recording.read(log)
    controller = DpController(config)
    if recording.state_loaded is not None and same_config:
        controller.load_state_dict(recording.state_loaded, recording.state_t_s if recording.state_t_s is not None
                                   else float(recording.cycles[0]["t_s"]))
    names = [t.name for t in config.vessel.thrusters]
    commands = _step_through(controller, RawDecoders(config), recording, len(names))
    n = len(names)
    rows = len(recording.cycles)
    compared = np.isfinite(commands.old_thrust[:, 0]) if n else np.zeros(rows, dtype=bool)
    thrust_diff = np.abs(commands.new_thrust[compared] - commands.old_thrust[compared])
    azimuth_diff = np.abs(commands.new_azimuth[compared] - commands.old_azimuth[compared])
    report = {
        "log": str(log), "config": str(config_path), "same_config": same_config, "cycles": rows,
        "cycles_compared": int(np.count_nonzero(compared)), "raw_inputs": len(recording.raw),
        "missing_inputs": commands.missing_inputs,
        "identical": commands.first_difference is None and commands.missing_inputs == 0,
        "first_difference_cycle": commands.first_difference,
        "max_thrust_difference_n": float(thrust_diff.max()) if thrust_diff.size else 0.0,
        "max_azimuth_difference_rad": float(azimuth_diff.max()) if azimuth_diff.size else 0.0,
    }
    if out_dir is not None:
        _write(out_dir, report, commands, names, config.source_text, plots=plots and rows > 0,
               same_config=same_config)
    return report


def _step_through(controller: DpController, decoders: RawDecoders, recording: Recording, n: int) -> Commands:
    """Decode every raw input in arrival order (fast-packet state, signing counters), then run the step on each
    cycle's inputs, links, feedback and requests at its recorded time; compare with the recorded commands."""
    decoded: dict[int, list[Measurement]] = {}
    for seq in sorted(recording.raw):
        transport, t_s, payload, data = recording.raw[seq]
        decoded[seq] = decoders.decode(transport, t_s, payload, data)
    rows = len(recording.cycles)
    commands = Commands(np.zeros(rows), np.full((rows, n), np.nan), np.zeros((rows, n)), np.full((rows, n), np.nan),
                        np.zeros((rows, n)))
    cursor: dict[int, int] = defaultdict(int)  # one raw input can give several measurements, possibly over two cycles
    for k, cycle in enumerate(recording.cycles):
        t_s = float(cycle["t_s"])
        commands.times[k] = t_s
        measurements: list[Measurement] = []
        for seq in cycle.get("inputs", []):
            items = decoded.get(seq)
            if items is None:
                commands.missing_inputs += 1
                continue
            i = cursor[seq]
            if i < len(items):
                measurements.append(items[i])
                cursor[seq] = i + 1
        for source, connected, _detail in cycle.get("links", []):
            for sensor in decoders.router.sensors_on(source):
                controller.hub.set_disconnected(sensor, not connected)
        feedback = [ThrusterFeedback(name, thrust, azimuth, ready, t) for name, thrust, azimuth, ready, t
                    in cycle.get("feedback", [])]
        requests = [request_from_dict(r) for r in cycle.get("requests", [])]
        out = controller.step(t_s, measurements, feedback, requests)
        commands.new_thrust[k] = out.thrust_n
        commands.new_azimuth[k] = out.azimuth_rad
        command = recording.commands.get(int(cycle.get("cycle", k)))
        if command is not None and len(command.get("thrust_n", [])) == n:
            commands.old_thrust[k] = command["thrust_n"]
            commands.old_azimuth[k] = command["azimuth_rad"]
            if commands.first_difference is None and (list(out.thrust_n) != command["thrust_n"]
                                                      or list(out.azimuth_rad) != command["azimuth_rad"]):
                commands.first_difference = k
    return commands


def _write(out_dir: Path, report: dict[str, Any], commands: Commands, names: list[str], config_text: str, *,
           plots: bool, same_config: bool) -> None:
    """``commands.csv`` (recorded beside replayed), ``replay.json`` (the report), ``config.yaml``, the plot."""
    out_dir.mkdir(parents=True, exist_ok=True)
    header = ["t_s"] + [f"recorded_thrust_{x}_n" for x in names] + [f"replay_thrust_{x}_n" for x in names] \
        + [f"recorded_azimuth_{x}_rad" for x in names] + [f"replay_azimuth_{x}_rad" for x in names]
    table = np.column_stack([commands.times, commands.old_thrust, commands.new_thrust, commands.old_azimuth,
                             commands.new_azimuth])
    np.savetxt(out_dir / "commands.csv", table, delimiter=",", header=",".join(header), comments="", fmt="%.9g")
    (out_dir / "replay.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    (out_dir / "config.yaml").write_text(yaml.safe_dump(load_yaml(config_text)), encoding="utf-8")
    if plots:
        _plot(out_dir, commands.times, names, old_thrust=commands.old_thrust, new_thrust=commands.new_thrust,
              old_azimuth=commands.old_azimuth, new_azimuth=commands.new_azimuth, same_config=same_config)


def _plot(out_dir: Path, times: np.ndarray, names: list[str], *, old_thrust: np.ndarray, new_thrust: np.ndarray,
          old_azimuth: np.ndarray, new_azimuth: np.ndarray, same_config: bool) -> None:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, axes = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    for i, name in enumerate(names):
        line = axes[0].plot(times, old_thrust[:, i], lw=1.2, label=f"{name} recorded")[0]
        axes[0].plot(times, new_thrust[:, i], lw=0.9, ls="--", color=line.get_color(), label=f"{name} replay")
        axes[1].plot(times, np.degrees(old_azimuth[:, i]), lw=1.2, color=line.get_color())
        axes[1].plot(times, np.degrees(new_azimuth[:, i]), lw=0.9, ls="--", color=line.get_color())
    axes[0].set_ylabel("thrust [N]")
    axes[1].set_ylabel("azimuth / rudder [deg]")
    axes[1].set_xlabel("t [s] (daemon clock)")
    axes[0].legend(fontsize=7, ncol=2)
    axes[0].set_title("replay: recorded (solid) vs replayed (dashed) commands"
                      + ("" if same_config else " — different configuration"))
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_dir / "commands.png", dpi=110)
    plt.close(fig)


__all__ = ["RawDecoders", "Recording", "replay"]
