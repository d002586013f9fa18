"""Output folders are checked before the work that fills them (``dpcontrol.outputs``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dpcontrol.cli import main
from dpcontrol.outputs import unwritable_folder


def test_a_missing_folder_is_created_with_its_parents(tmp_path: Path) -> None:
    folder = tmp_path / "runs" / "tanker" / "mrac"
    assert unwritable_folder(folder) is None
    assert folder.is_dir() and list(folder.iterdir()) == []  # the probe file leaves nothing behind


def test_a_folder_under_a_file_is_refused_with_the_reason(tmp_path: Path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("kept\n")
    why = unwritable_folder(blocker / "out")
    assert why == f"cannot write into the output folder {blocker / 'out'}: Not a directory"
    assert blocker.read_text() == "kept\n"


def test_replay_checks_its_output_folder_before_reading_the_recording(tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    # the recording and the configuration do not exist either: the folder is what is reported, first
    code = main(["replay", str(tmp_path / "day.mcap"), "--config", str(tmp_path / "vessel.yaml"),
                 "--out", str(blocker / "out"), "--no-plots"])
    assert code == 2
    assert f"dpcontrol replay: cannot write into the output folder {blocker / 'out'}" in capsys.readouterr().err
