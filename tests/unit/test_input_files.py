"""Files handed to the tools that are not what they should be — a binary picked by mistake, a Latin-1
file, a folder, a file that is not a recording — get one line naming the file and what was expected,
and a usage exit code; never a traceback (``dpbase.yamlfile``, ``dpcontrol replay`` / ``log export``)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml

from dpbase.schema import ConfigError
from dpbase.yamlfile import read_yaml_file
from dpcontrol.cli import main as dpcontrol_main
from dpcontrol.replay import replay
from dpcontrol.runtime.config import load_config
from sim_plant.cli import main as sim_plant_main
from sim_plant.hil_config import load_controller_wiring
from sim_plant.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
ELF_HEAD = b"\x7fELF\x02\x01\x01\x00" + bytes(16) + b"\xd0\x11\x00\x00"  # a binary: 0xd0 at offset 24


@pytest.fixture()
def bad_files(tmp_path: Path) -> dict[str, Path]:
    binary = tmp_path / "vessel.bin"
    binary.write_bytes(ELF_HEAD)
    latin1 = tmp_path / "latin1.yaml"
    latin1.write_bytes("vessel_id: tanker\nname: Sjøfart\n".encode("latin-1"))  # ø is 0xf8 in Latin-1
    folder = tmp_path / "a-folder.yaml"
    folder.mkdir()
    return {"binary": binary, "latin1": latin1, "folder": folder}


def test_the_reader_names_the_file_and_the_first_bad_byte(bad_files: dict[str, Path]) -> None:
    with pytest.raises(ConfigError) as info:
        read_yaml_file(bad_files["binary"])
    assert str(info.value) == (f"{bad_files['binary']}: <root>: expected UTF-8 text, got 'byte 0xd0 at offset 24 "
                               "(a binary file, or text in another encoding)'")
    with pytest.raises(ConfigError, match=r"latin1\.yaml: <root>: expected UTF-8 text, got 'byte 0xf8 at offset 26"):
        read_yaml_file(bad_files["latin1"])
    with pytest.raises(ConfigError, match=r"a-folder\.yaml: <root>: expected a readable scenario file, got .*"
                                          r"Is a directory"):
        read_yaml_file(bad_files["folder"], what="a readable scenario file")


def test_every_loader_reports_a_file_that_is_not_utf8_text(bad_files: dict[str, Path]) -> None:
    for load in (load_config, load_scenario, load_controller_wiring):
        for kind in ("binary", "latin1", "folder"):
            with pytest.raises(ConfigError) as info:
                load(bad_files[kind])
            assert str(info.value).startswith(f"{bad_files[kind]}: <root>: expected "), (load, kind, info.value)


def test_utf8_with_non_ascii_text_is_read(tmp_path: Path) -> None:
    path = tmp_path / "ok.yaml"
    path.write_text("name: Sjøfart — ω₀\n", encoding="utf-8")
    assert read_yaml_file(path) == ("name: Sjøfart — ω₀\n", {"name": "Sjøfart — ω₀"})


@pytest.mark.parametrize("kind", ["binary", "latin1", "folder"])
def test_the_command_lines_exit_2_with_one_line(kind: str, bad_files: dict[str, Path], tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    path = str(bad_files[kind])
    controller = str(ROOT / "deploy" / "config" / "cybership2.yaml")
    out = str(tmp_path / "out")
    calls = [
        (dpcontrol_main, ["check-config", path], "dpcontrol: invalid configuration: "),
        (dpcontrol_main, ["run", "--config", path, "--duration", "1"], "dpcontrol: invalid configuration: "),
        (sim_plant_main, ["run", path, "--out", out, "--duration", "1"], "sim-plant run: "),
        (sim_plant_main, ["run", "cs2-seed000", "--controller-config", path, "--out", out, "--duration", "1"],
         "sim-plant run: "),
        (sim_plant_main, ["hil", path, "--controller-config", controller, "--duration", "1"], "sim-plant hil: "),
        (sim_plant_main, ["hil", "cs2-seed000", "--controller-config", path, "--duration", "1"], "sim-plant hil: "),
        (sim_plant_main, ["demo", path, "--duration", "1", "--no-live", "--out", out], "sim-plant demo: "),
    ]
    for main, argv, prefix in calls:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith(f"{prefix}{path}: <root>: expected "), (argv, err)
        assert "Traceback" not in err and len(err.strip().splitlines()) == 1, (argv, err)


def test_demo_checks_the_scenario_like_run_before_starting_anything(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    typo = tmp_path / "typo.yaml"
    typo.write_text(yaml.safe_dump({"name": "typo", "vessel": "cybership2", "duration_s": 60, "sensros": []}),
                    encoding="utf-8")
    started = time.monotonic()
    assert sim_plant_main(["demo", str(typo), "--no-live", "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"sim-plant demo: {typo}: sensros: expected a known key"), err
    assert time.monotonic() - started < 10.0  # before the emulator and the daemon were started
    assert not (tmp_path / "run").exists()
    assert sim_plant_main(["demo", "no-such-scenario", "--no-live", "--out", str(tmp_path / "run")]) == 2
    assert "unknown built-in scenario 'no-such-scenario' (known: " in capsys.readouterr().err


def test_a_missing_input_file_exits_2_in_every_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The same kind of error, the same exit code: a file named on the command line that is not there is a
    usage error (2) whichever command was given it."""
    missing = str(tmp_path / "missing.file")
    controller = str(ROOT / "deploy" / "config" / "cybership2.yaml")
    out = str(tmp_path / "out")
    calls = [
        (dpcontrol_main, ["check-config", missing]),
        (dpcontrol_main, ["run", "--config", missing, "--duration", "1"]),
        (dpcontrol_main, ["decode", "nmea0183", missing]),
        (dpcontrol_main, ["replay", missing, "--config", controller]),
        (dpcontrol_main, ["replay", missing, "--config", missing]),
        (dpcontrol_main, ["log", "export", missing, "--csv", out]),
        (sim_plant_main, ["run", missing, "--out", out, "--duration", "1"]),
        (sim_plant_main, ["run", "cs2-seed000", "--controller-config", missing, "--out", out, "--duration", "1"]),
        (sim_plant_main, ["hil", missing, "--controller-config", controller, "--duration", "1"]),
        (sim_plant_main, ["hil", "cs2-seed000", "--controller-config", missing, "--duration", "1"]),
        (sim_plant_main, ["demo", missing, "--duration", "1", "--no-live", "--out", out]),
    ]
    for main, argv in calls:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "missing.file" in err and "Traceback" not in err, (argv, err)


def test_replay_and_export_say_a_file_is_not_a_recording(bad_files: dict[str, Path], tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    config = ROOT / "deploy" / "config" / "cybership2.yaml"
    for kind in ("binary", "folder"):
        with pytest.raises(ValueError, match="no records read — not a dpcontrol recording"):
            replay(bad_files[kind], config)
        out = tmp_path / f"csv-{kind}"
        assert dpcontrol_main(["log", "export", str(bad_files[kind]), "--csv", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"dpcontrol log export: {bad_files[kind]}: no records read" in err and "nothing written" in err, err
        assert list(out.iterdir()) == []
    blocker = tmp_path / "a-file"
    blocker.write_text("kept\n")
    assert dpcontrol_main(["log", "export", str(bad_files["binary"]), "--csv", str(blocker / "csv")]) == 2
    assert f"cannot write into the output folder {blocker / 'csv'}" in capsys.readouterr().err




@pytest.mark.parametrize("duration", ["-5", "0", "nan", "inf", "ten"])
def test_run_refuses_a_duration_that_is_not_a_finite_positive_time(duration: str,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    # nan ran the daemon forever; -5 and 0 started it (opening ports, zenoh, the recorder) to stop at once
    with pytest.raises(SystemExit) as info:
        dpcontrol_main(["run", "--config", str(ROOT / "deploy" / "config" / "cybership2.yaml"), "--duration", duration])
    assert info.value.code == 2
    assert "argument --duration: expected a" in capsys.readouterr().err
