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


def replay(log: Path, config_path: Path, out_dir: Path | None = None, *, plots: bool = True) -> dict[str, Any]:  # noqa: C901, PLR0915 - read, step and compare in one pass over the recording; to split with the daemon's input stage
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
    raw: dict[int, tuple[str, float, dict[str, Any], bytes]] = {}
    cycles: list[dict[str, Any]] = []
    commands: dict[int, dict[str, Any]] = {}
    state_loaded: dict[str, Any] | None = None
    state_t_s: float | None = None
    n_records = 0
    for record in read_records(log):
        n_records += 1
        topic = record.topic
        payload = record.payload
        if topic.startswith("raw/"):
            seq = payload.get("seq")
            data = record.data
            if isinstance(seq, int) and data is not None:
                raw[seq] = (topic[4:], float(payload.get("t_s") or 0.0), payload, data)
        elif topic == "cycle":
            cycles.append(payload)
        elif topic == "command" and isinstance(payload.get("cycle"), int):
            commands[payload["cycle"]] = payload
        elif topic == "state_loaded" and state_loaded is None:
            state_loaded = payload.get("state")
            state_t_s = record.t_s
    if n_records == 0:
        raise ValueError(f"{log}: no records read — not a dpcontrol recording (MCAP), or empty")
    if not cycles:
        raise ValueError(f"{log}: no 'cycle' records — recorded without inputs, cannot replay")

    decoders = RawDecoders(config)
    decoded: dict[int, list[Measurement]] = {}
    for seq in sorted(raw):  # every raw input in arrival order (fast-packet state, signing counters)
        transport, t_s, payload, data = raw[seq]
        decoded[seq] = decoders.decode(transport, t_s, payload, data)

    controller = DpController(config)
    if state_loaded is not None and same_config:
        controller.load_state_dict(state_loaded, state_t_s if state_t_s is not None else float(cycles[0]["t_s"]))
    names = [t.name for t in config.vessel.thrusters]
    n = len(names)
    rows = len(cycles)
    new_thrust = np.zeros((rows, n))
    new_azimuth = np.zeros((rows, n))
    old_thrust = np.full((rows, n), np.nan)
    old_azimuth = np.full((rows, n), np.nan)
    times = np.zeros(rows)
    missing_inputs = 0
    first_difference: int | None = None
    cursor: dict[int, int] = defaultdict(int)
    for k, cycle in enumerate(cycles):
        t_s = float(cycle["t_s"])
        times[k] = t_s
        measurements: list[Measurement] = []
        for seq in cycle.get("inputs", []):
            items = decoded.get(seq)
            if items is None:
                missing_inputs += 1
                continue
            i = cursor[seq]  # one raw input can give several measurements, possibly over two cycles
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
        new_thrust[k] = out.thrust_n
        new_azimuth[k] = out.azimuth_rad
        command = commands.get(int(cycle.get("cycle", k)))
        if command is not None and len(command.get("thrust_n", [])) == n:
            old_thrust[k] = command["thrust_n"]
            old_azimuth[k] = command["azimuth_rad"]
            if first_difference is None and (list(out.thrust_n) != command["thrust_n"]
                                             or list(out.azimuth_rad) != command["azimuth_rad"]):
                first_difference = k
    compared = np.isfinite(old_thrust[:, 0]) if n else np.zeros(rows, dtype=bool)
    thrust_diff = np.abs(new_thrust[compared] - old_thrust[compared])
    azimuth_diff = np.abs(new_azimuth[compared] - old_azimuth[compared])
    report = {
        "log": str(log), "config": str(config_path), "same_config": same_config, "cycles": rows,
        "cycles_compared": int(np.count_nonzero(compared)), "raw_inputs": len(raw),
        "missing_inputs": missing_inputs, "identical": first_difference is None and missing_inputs == 0,
        "first_difference_cycle": first_difference,
        "max_thrust_difference_n": float(thrust_diff.max()) if thrust_diff.size else 0.0,
        "max_azimuth_difference_rad": float(azimuth_diff.max()) if azimuth_diff.size else 0.0,
    }
    if out_dir is not None:
        out_dir.mkdir(parents=True, exist_ok=True)
        header = ["t_s"] + [f"recorded_thrust_{x}_n" for x in names] + [f"replay_thrust_{x}_n" for x in names] \
            + [f"recorded_azimuth_{x}_rad" for x in names] + [f"replay_azimuth_{x}_rad" for x in names]
        table = np.column_stack([times, old_thrust, new_thrust, old_azimuth, new_azimuth])
        np.savetxt(out_dir / "commands.csv", table, delimiter=",", header=",".join(header), comments="",
                   fmt="%.9g")
        (out_dir / "replay.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
        (out_dir / "config.yaml").write_text(yaml.safe_dump(load_yaml(config.source_text)), encoding="utf-8")
        if plots and rows:
            _plot(out_dir, times, names, old_thrust=old_thrust, new_thrust=new_thrust, old_azimuth=old_azimuth,
                  new_azimuth=new_azimuth, same_config=same_config)
    return report


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


__all__ = ["RawDecoders", "replay"]
