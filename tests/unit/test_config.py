"""Daemon configuration: the shipped examples validate, and every bad field is refused by name."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from dpbase.schema import ConfigError
from dpcontrol.cli import main
from dpcontrol.control import MracConfig
from dpcontrol.runtime.config import RealtimeSettings, ReplicaSettings, load_config, parse_config
from dpcontrol.service.daemon import LoopStats

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "deploy" / "config").glob("*.yaml"))

BASE = {
    "vessel_id": "cs2",
    "vessel": "cybership2",
    "transports": [{"name": "serial", "protocol": "nmea0183", "port": "/dev/ttyUSB0", "baud": 38400},
                   {"name": "can0", "protocol": "nmea2000", "interface": "socketcan", "channel": "can0"}],
    "sensors": [{"name": "gnss1", "kind": "position", "transport": "serial", "rate_hz": 5, "sigma_m": 0.5,
                 "lever_arm_m": [1.0, 0.0]},
                {"name": "gyro1", "kind": "heading", "transport": "can0", "source_address": 7, "sigma_deg": 0.1}],
}


def test_every_shipped_example_validates(capsys: pytest.CaptureFixture[str]) -> None:
    assert len(EXAMPLES) >= 5
    for path in EXAMPLES:
        assert main(["check-config", str(path)]) == 0, path
        assert "OK" in capsys.readouterr().out
    names = {load_config(p).vessel.name for p in EXAMPLES}
    assert {"cybership2", "supply", "shuttle_tanker", "blue_lady", "mariner"} <= names


@pytest.mark.parametrize(("edit", "path_expected"), [
    (lambda c: c.update(vessel_id="a/b"), "vessel_id"),
    (lambda c: c.update(vessel="titanic"), "vessel"),
    (lambda c: c["sensors"][0].update(kind="sonar"), "sensors[0].kind"),
    (lambda c: c["sensors"][0].update(rate_hz="fast"), "sensors[0].rate_hz"),
    (lambda c: c["sensors"][0].update(rate_hz=-1), "sensors[0].rate_hz"),
    (lambda c: c["sensors"][0].update(sigma_m=0), "sensors[0].sigma_m"),
    (lambda c: c["sensors"][0].update(lever_arm_m=[1.0]), "sensors[0].lever_arm_m"),
    (lambda c: c["sensors"][0].update(transport="nowhere"), "sensors[0].transport"),
    (lambda c: c["sensors"][0].update(talker="GPS"), "sensors[0].talker"),
    (lambda c: c["sensors"][0].update(sentences=["XYZ"]), "sensors[0].sentences[0]"),
    (lambda c: c["sensors"][0].update(source_address=3), "sensors[0].source_address"),
    (lambda c: c["sensors"][1].update(source_address=300), "sensors[1].source_address"),
    (lambda c: c["sensors"][1].update(sigma_deg="x"), "sensors[1].sigma_deg"),
    (lambda c: c["sensors"][1].update(typo=1), "sensors[1].typo"),
    (lambda c: c["sensors"].append(dict(c["sensors"][0])), "sensors[2].name"),
    (lambda c: c["transports"][0].update(baud=10), "transports[0].baud"),
    (lambda c: c["transports"][0].update(protocol="nmea3000"), "transports[0].protocol"),
    (lambda c: c["transports"][0].pop("port"), "transports[0].port"),
    (lambda c: c["transports"][1].update(channle="can1"), "transports[1].channle"),
    (lambda c: c.update(vessel={"base": "cybership2", "thrusters": [{"name": "t", "kind": "tunnel", "x_m": 1,
                                                                      "y_m": 0, "max_thrust_n": -1}]}),
     "vessel.thrusters[0].max_thrust_n"),
    (lambda c: c.update(vessel={"base": "cybership2", "thrusters": [{"name": "t", "kind": "jet", "x_m": 1,
                                                                      "y_m": 0, "max_thrust_n": 1}]}),
     "vessel.thrusters[0].kind"),
    (lambda c: c.update(vessel={"base": "cybership2", "thrusters": [{"name": "t", "kind": "tunnel", "x_m": "a",
                                                                      "y_m": 0, "max_thrust_n": 1}]}),
     "vessel.thrusters[0].x_m"),
    (lambda c: c.update(vessel={"base": "cybership2", "thrusters": [{"name": "t", "kind": "azimuth", "x_m": 0,
                                                                      "y_m": 0, "max_thrust_n": 1,
                                                                      "azimuth_rate_limit_degps": 0}]}),
     "vessel.thrusters[0].azimuth_rate_limit_degps"),
    (lambda c: c.update(vessel={"base": "cybership2", "thrusters": [{"name": "t", "kind": "propeller_rudder",
                                                                      "x_m": -1, "y_m": 0, "max_thrust_n": 1}]}),
     "vessel.thrusters[0].rudder_max_angle_deg"),
    # a vessel of one's own must say how long she is: every scale-dependent default derives from it
    (lambda c: c.update(vessel={"name": "own", "mass_matrix": [[6.0e6, 0, 0], [0, 8.0e6, 0], [0, 0, 3.0e9]],
                                "damping_matrix": [[1.0e5, 0, 0], [0, 3.0e5, 0], [0, 0, 1.0e8]],
                                "thrusters": [{"name": "t", "kind": "azimuth", "x_m": -30, "y_m": 0,
                                               "max_thrust_n": 2.0e5}]}),
     "vessel.length_m"),
    (lambda c: c.update(estimator={"kind": "mmae", "omegas_rad_s": [0.3, 40.0]}), "estimator.omegas_rad_s[1]"),
    (lambda c: c.update(estimator={"kind": "kf", "omega_rad_s": "x"}), "estimator.omega_rad_s"),
    (lambda c: c.update(estimator={"kind": "ekf"}), "estimator.kind"),
    (lambda c: c.update(estimator={"kind": "kalman_bucy", "process_noise_scale": 0}),
     "estimator.process_noise_scale"),
    (lambda c: c.update(estimator={"kind": "kalman_bucy", "omega0_rad_s": 1.0}), "estimator.omega0_rad_s"),
    (lambda c: c.update(estimator={"kind": "heading_kf"}), "estimator.kind"),  # CyberShip II has no Nomoto model
    (lambda c: c.update(control={"kind": "pid", "kp": [[1, 0, 0]]}), "control.kp"),
    (lambda c: c.update(guidance={"max_speed_mps": 0}), "guidance.max_speed_mps"),
    (lambda c: c.update(hub={"jump_min_m": -4}), "hub.jump_min_m"),
    (lambda c: c.update(fallback={"position_loss": "panic"}), "fallback.position_loss"),
    (lambda c: c.update(zenoh={"listen": ["0.0.0.0"]}), "zenoh.listen[0]"),
    (lambda c: c.update(loop={"rate_hz": 1000}), "loop.rate_hz"),
    (lambda c: c.update(loop={"realtime_priority": 0}), "loop.realtime_priority"),
    (lambda c: c.update(loop={"realtime_priority": 100}), "loop.realtime_priority"),
    (lambda c: c.update(loop={"realtime_priority": "high"}), "loop.realtime_priority"),
    (lambda c: c.update(loop={"cpu_affinity": [-1]}), "loop.cpu_affinity"),
    (lambda c: c.update(loop={"cpu_affinity": 1}), "loop.cpu_affinity"),
    (lambda c: c.update(loop={"cpu_affinity": []}), "loop.cpu_affinity"),
    (lambda c: c.update(loop={"deadline_spin_ms": -1}), "loop.deadline_spin_ms"),
    (lambda c: c.update(loop={"rate_hz": 10, "deadline_spin_ms": 26}), "loop.deadline_spin_ms"),  # > period / 4
    (lambda c: c.update(loop={"deadline_spin_ms": "on"}), "loop.deadline_spin_ms"),
    (lambda c: c.update(loop={"replica_check": "yes"}), "loop.replica_check"),
    (lambda c: c.update(loop={"replica_lead_ms": 0.1}), "loop.replica_lead_ms"),
    (lambda c: c.update(loop={"rate_hz": 10, "replica_lead_ms": 30}), "loop.replica_lead_ms"),  # > period / 4
    (lambda c: c.update(recorder={"flush_s": 5}), "recorder.flush_s"),
    (lambda c: c.update(unknown_section={}), "unknown_section"),
])
def test_bad_field_is_refused_with_its_key_path(edit, path_expected: str) -> None:
    config = copy.deepcopy(BASE)
    edit(config)
    with pytest.raises(ConfigError) as excinfo:
        parse_config(config, file="vessel.yaml")
    message = str(excinfo.value)
    assert message.startswith("vessel.yaml: ")
    assert path_expected in message, message


def test_base_config_is_valid() -> None:
    config = parse_config(copy.deepcopy(BASE))
    assert [s.name for s in config.sensors] == ["gnss1", "gyro1"]
    # the wave filter's measurement noise defaults to what the sensors claim
    assert config.estimator.wave_filter.position_noise_std_m == pytest.approx(0.5)
    assert config.estimator.wave_filter.heading_noise_std_rad == pytest.approx(0.1 * 3.141592653589793 / 180)


def test_an_old_key_name_is_read_with_a_warning_and_a_typo_is_told_every_valid_key(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """kf's wave frequency is ``omega0_rad_s`` like every other single-frequency filter; ``omega_rad_s`` (its old
    name) is read as it for one release, and check-config says so."""
    old = copy.deepcopy(BASE)
    old["estimator"] = {"kind": "kf", "omega_rad_s": 0.7}
    config = parse_config(old)
    assert config.estimator.wave_filter.omegas_rad_s == (0.7,)
    assert config.notices == ("estimator.omega_rad_s is deprecated: write omega0_rad_s (read as it in this release)",)
    new = copy.deepcopy(BASE)
    new["estimator"] = {"kind": "kf", "omega0_rad_s": 0.7}
    renamed = parse_config(new)
    assert renamed.notices == () and renamed.estimator.wave_filter.omegas_rad_s == (0.7,)
    path = tmp_path / "old.yaml"
    path.write_text(yaml.safe_dump(old))
    assert main(["check-config", str(path)]) == 0
    assert "warning: estimator.omega_rad_s is deprecated" in capsys.readouterr().err
    both = copy.deepcopy(BASE)
    both["estimator"] = {"kind": "kf", "omega_rad_s": 0.7, "omega0_rad_s": 0.7}
    with pytest.raises(ConfigError, match="omega0_rad_s alone"):
        parse_config(both)
    typo = copy.deepcopy(BASE)
    typo["estimator"] = {"kind": "mmae", "wf_positon_std_m": 0.3}
    with pytest.raises(ConfigError) as refused:
        parse_config(typo)
    message = str(refused.value)  # the keys the parser never read because they were absent are listed too
    assert "estimator.wf_positon_std_m" in message
    assert all(key in message for key in ("wf_position_std_m", "omegas_rad_s", "zeta", "bias_drift_time_s"))


def test_a_model_scale_bank_is_accepted_up_to_a_quarter_of_the_sampling() -> None:
    """A model basin's waves on a 1:70 hull peak at 5-8 rad/s (a full-scale sea's 0.55-0.9 rad/s × √70): the
    bank may hold them; the limit is the sampling's (four samples a wave period), not a full-scale sea's."""
    config = copy.deepcopy(BASE)
    config["estimator"] = {"kind": "mmae", "omegas_rad_s": [3.0, 4.5, 6.0, 7.5]}
    assert parse_config(config).estimator.wave_filter.omegas_rad_s == (3.0, 4.5, 6.0, 7.5)
    config["loop"] = {"rate_hz": 2.0}  # π/2 · 2 Hz = 3.14 rad/s
    with pytest.raises(ConfigError, match=r"omegas_rad_s\[1\]: expected a wave peak frequency in \[0.05, 3.14\]"):
        parse_config(config)


def test_check_config_cli_refuses_a_broken_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken = copy.deepcopy(BASE)
    broken["sensors"][0]["rate_hz"] = "often"
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(broken))
    assert main(["check-config", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "sensors[0].rate_hz" in err and "expected a number" in err
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("vessel_id: [unclosed\n")
    assert main(["check-config", str(bad_yaml)]) == 2
    assert "valid YAML" in capsys.readouterr().err
    assert main(["check-config", str(tmp_path / "missing.yaml")]) == 2


def test_settings_that_pass_alone_but_build_no_wave_filter_are_refused_by_check_config_and_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # found by a fuzz: each value is in its own range, but the filter's Riccati equation has no stabilising
    # solution; check-config said OK and `dpcontrol run` ended in a traceback when it built the controller
    unbuildable = copy.deepcopy(BASE)
    unbuildable["estimator"] = {"kind": "mmae", "position_noise_std_m": 1e9}
    path = tmp_path / "unbuildable.yaml"
    path.write_text(yaml.safe_dump(unbuildable))
    expected = (f"dpcontrol: invalid configuration: {path}: estimator: expected estimator settings from which the "
                "controller can be built, got 'no stabilising solution of the filter Riccati equation")
    assert main(["check-config", str(path)]) == 2
    assert capsys.readouterr().err.startswith(expected)
    assert main(["run", "--config", str(path), "--duration", "1"]) == 2  # refused before anything is opened
    assert capsys.readouterr().err.startswith(expected)


def test_daemon_refuses_a_stats_file_it_could_not_write_before_starting(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "vessel.yaml"
    path.write_text(yaml.safe_dump(copy.deepcopy(BASE)))
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setattr("dpcontrol.service.daemon.Daemon", _NoDaemon)
    monkeypatch.setattr(_NoDaemon, "runs", 0)
    assert main(["run", "--config", str(path), "--stats-out", str(blocker / "stats.json"), "--duration", "1"]) == 2
    assert f"stats.json: cannot write into the output folder {blocker}" in capsys.readouterr().err
    assert _NoDaemon.runs == 0


def test_stats_that_cannot_be_written_at_the_end_are_an_error_not_a_traceback(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "vessel.yaml"
    path.write_text(yaml.safe_dump(copy.deepcopy(BASE)))
    folder = tmp_path / "stats"
    folder.mkdir()
    monkeypatch.setattr("dpcontrol.service.daemon.Daemon", _NoDaemon)
    monkeypatch.setattr(_NoDaemon, "runs", 0)
    monkeypatch.setattr(_NoDaemon, "remove_during_run", folder)  # the folder goes away while the daemon runs
    assert main(["run", "--config", str(path), "--stats-out", str(folder / "stats.json"), "--duration", "1"]) == 1
    assert "stats.json: not written" in capsys.readouterr().err
    assert _NoDaemon.runs == 1


class _NoDaemon:
    """Stands in for the daemon in the two tests of ``--stats-out`` above (its loop is not what they test)."""

    runs = 0
    remove_during_run: Path | None = None
    resumed_from_state = False
    state_detail = "missing"
    realtime_detail = "normal scheduler"
    replica = None
    spinner = None
    garbage = None

    def __init__(self, config: object) -> None:
        self.stats = LoopStats(0.1)

    def run(self, duration_s: float | None = None) -> int:
        type(self).runs += 1
        if self.remove_during_run is not None:
            self.remove_during_run.rmdir()
        return 0


def test_daemon_refuses_to_start_on_an_invalid_config(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    broken = copy.deepcopy(BASE)
    broken["sensors"][1]["kind"] = "compass"
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(broken))
    assert main(["run", "--config", str(path), "--duration", "1"]) == 2
    assert "sensors[1].kind" in capsys.readouterr().err


def test_loop_scheduling_settings() -> None:
    config = copy.deepcopy(BASE)
    assert parse_config(config).realtime == RealtimeSettings(None, (), 0.002)  # spins the last 2 ms by default
    config["loop"] = {"rate_hz": 10, "realtime_priority": 50, "cpu_affinity": [1, 0, 1], "deadline_spin_ms": 0}
    assert parse_config(config).realtime == RealtimeSettings(50, (0, 1), 0.0)
    config["loop"] = {"rate_hz": 20, "deadline_spin_ms": 12.5}  # 12.5 ms = period / 4
    assert parse_config(config).realtime.spin_s == 0.0125


def test_controller_replica_settings() -> None:
    config = copy.deepcopy(BASE)
    assert parse_config(config).replica == ReplicaSettings(True, 0.003)  # on by default, 3 ms ahead
    config["loop"] = {"rate_hz": 20, "replica_check": False, "replica_lead_ms": 12.5}  # 12.5 ms = period / 4
    assert parse_config(config).replica == ReplicaSettings(False, 0.0125)


def test_transports_built_by_the_caller_take_the_place_of_the_files_list() -> None:
    """The lockstep simulation's configuration: in-process transports (no device) given to the parser, the sensors
    naming them; decoding settings at the protocols' defaults; a name given twice refused."""
    from dpcontrol.runtime.config import in_process_transport  # noqa: PLC0415

    given = [in_process_transport("bus", "nmea2000"), in_process_transport("link", "mavlink")]
    mapping = {"vessel_id": "v", "vessel": "supply",
               "sensors": [{"name": "gnss1", "kind": "position", "transport": "bus", "source_address": 40},
                           {"name": "gyro1", "kind": "heading", "transport": "link", "system_id": 2}]}
    config = parse_config(mapping, transports=given)
    assert [(t.name, t.protocol, t.in_process) for t in config.transports] == [
        ("bus", "nmea2000", True), ("link", "mavlink", True)]
    assert config.transports[1].settings["heartbeat_timeout_s"] == 5.0
    with pytest.raises(ConfigError, match="transports"):  # without them the file must list its own
        parse_config(mapping)
    twice = {**mapping, "transports": [{"name": "bus", "protocol": "nmea0183", "port": "/dev/ttyUSB0"}]}
    with pytest.raises(ConfigError, match=r"transports\[0\]\.name"):
        parse_config(twice, transports=given)
    with pytest.raises(ValueError, match="unknown protocol"):
        in_process_transport("x", "nmea0184")


def _without_control(example: str) -> dict[str, object]:
    mapping = yaml.safe_load((ROOT / "deploy" / "config" / example).read_text())
    mapping.pop("control", None)
    return mapping


@pytest.mark.parametrize(("example", "kind", "options"), [
    ("shuttle_tanker.yaml", "mrac", {"adapt": True}),  # seed 003: the loading tanker
    ("supply.yaml", "pid", {"integral_action": "bias_feedforward"}),
    ("cybership2.yaml", "pid", {"integral_action": "integrator"}),
    ("blue_lady.yaml", "pid", {"integral_action": "integrator"}),
])
def test_without_control_kind_each_vessel_gets_the_controller_measured_to_hold_her(
        example: str, kind: str, options: dict[str, object]) -> None:
    """The default is what each example configures (their measurements in docs/configuration.md), and the
    configuration says it is a default and why."""
    default = parse_config(_without_control(example)).control
    configured = load_config(ROOT / "deploy" / "config" / example).control
    assert default.kind == configured.kind == kind and type(default.kind) is str
    assert repr(default.config) == repr(configured.config)  # the same controller as the example's (arrays: repr)
    assert all(getattr(default.config, key) == value for key, value in options.items())
    assert not default.configured and configured.configured
    assert default.default is not None and default.default.reason
    assert default.default == configured.default  # the default is known either way


def test_the_default_controller_follows_the_estimator_and_the_base_vessel() -> None:
    mariner = _without_control("mariner.yaml")  # estimator heading_kf: the autopilot is the one it pairs with
    assert parse_config(mariner).control.kind == "autopilot"
    mariner["estimator"] = {"kind": "mmae"}  # a DP estimator on a course-keeping ship: a DP controller
    assert parse_config(mariner).control.kind == "pid"
    based = _without_control("supply.yaml")
    based["vessel"] = {"base": "supply", "name": "osv_sister"}
    control = parse_config(based).control
    assert control.kind == "pid" and control.config.integral_action == "bias_feedforward"
    assert control.default is not None and control.default.reason.startswith("based on supply: ")
    own = copy.deepcopy(BASE)  # keys given without a kind apply to the vessel's default kind
    own["control"] = {"integral_action": "bias_feedforward"}
    assert parse_config(own).control.config.integral_action == "bias_feedforward"


def test_check_config_says_which_controller_runs_whether_configured_and_why(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "supply.yaml"
    path.write_text(yaml.safe_dump(_without_control("supply.yaml")))
    assert main(["check-config", str(path)]) == 0
    out = capsys.readouterr().out
    assert "control pid (integral_action bias_feedforward): the default for vessel supply (no control.kind given)" \
        in out and "the MRAC lost her heading" in out
    tanker = tmp_path / "tanker.yaml"
    tanker.write_text(yaml.safe_dump(_without_control("shuttle_tanker.yaml")))
    assert main(["check-config", str(tanker)]) == 0
    assert "control mrac: the default for vessel shuttle_tanker (no control.kind given) — a shuttle tanker, whose " \
        "mass grows 2.66× as she loads (seed 003)" in capsys.readouterr().out
    assert main(["check-config", str(ROOT / "deploy" / "config" / "shuttle_tanker.yaml")]) == 0
    assert "control mrac: configured (control.kind; the default for vessel shuttle_tanker is mrac)" \
        in capsys.readouterr().out


def test_the_mrac_follows_the_guidance_and_fits_the_vessel_and_the_estimator() -> None:
    """``control: {kind: mrac}``: the guidance's reference (one reference, no second lag); the measured dead zone
    except on a vessel whose mass changes (the loading tankers, and a vessel based on one); its own integrator
    where the estimator gives no bias (the Blue Lady's Kalman–Bucy filter), the bias fed forward otherwise."""
    def mrac(example: str, **changes: object) -> MracConfig:
        mapping = _without_control(example)
        mapping["control"] = {"kind": "mrac"}
        mapping.update(changes)
        config = parse_config(mapping).control.config
        assert isinstance(config, MracConfig)
        return config

    tanker, supply, blue_lady = mrac("shuttle_tanker.yaml"), mrac("supply.yaml"), mrac("blue_lady.yaml")
    assert tanker.reference == supply.reference == blue_lady.reference == "guidance"
    assert tanker.dead_zone_noise_factor == 0.0 and supply.dead_zone_noise_factor == 3.0
    assert mrac("shuttle_tanker.yaml", vessel={"base": "shuttle_tanker"}).dead_zone_noise_factor == 0.0
    assert blue_lady.integral_action == "integrator" and supply.integral_action == tanker.integral_action \
        == "bias_feedforward"
    assert mrac("blue_lady.yaml", estimator={"kind": "mmae"}).integral_action == "bias_feedforward"
    given = _without_control("blue_lady.yaml")
    given["control"] = {"kind": "mrac", "integral_action": "bias_feedforward", "reference": "model",
                        "mass_changes": True}
    config = parse_config(given).control.config
    assert isinstance(config, MracConfig)
    assert (config.integral_action, config.reference, config.dead_zone_noise_factor) == ("bias_feedforward",
                                                                                         "model", 0.0)
