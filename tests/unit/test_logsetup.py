"""Logging under systemd: a ``<priority>`` prefix and no timestamp when stderr is the journal stream
systemd named in ``JOURNAL_STREAM``; timestamps everywhere else (``dpcontrol.logsetup``)."""

from __future__ import annotations

import io
import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from dpcontrol.logsetup import JournalFormatter, stream_is_journal, syslog_priority


def test_levels_map_to_syslog_priorities() -> None:
    assert [syslog_priority(level) for level in (logging.DEBUG, logging.INFO, logging.WARNING, logging.ERROR,
                                                  logging.CRITICAL)] == [7, 6, 4, 3, 2]
    assert syslog_priority(logging.WARNING + 5) == 4 and syslog_priority(1) == 7


def test_the_journal_stream_is_recognised_by_device_and_inode(tmp_path: Path) -> None:
    with (tmp_path / "journal").open("w") as journal, (tmp_path / "other").open("w") as other:
        status = os.fstat(journal.fileno())
        environ = {"JOURNAL_STREAM": f"{status.st_dev}:{status.st_ino}"}
        assert stream_is_journal(journal, environ)
        assert not stream_is_journal(other, environ)  # a child's stderr redirected elsewhere inherits the variable
        assert not stream_is_journal(journal, {})
        assert not stream_is_journal(journal, {"JOURNAL_STREAM": "garbage"})
    assert not stream_is_journal(io.StringIO(), environ)  # no file descriptor


def test_every_line_of_a_traceback_keeps_the_priority() -> None:
    formatter = JournalFormatter("%(name)s: %(message)s")
    try:
        raise RuntimeError("injected")
    except RuntimeError:
        record = logging.LogRecord("dpcontrol.service.daemon", logging.ERROR, __file__, 1, "control step failed",
                                   None, sys.exc_info())
    lines = formatter.format(record).split("\n")
    assert lines[0] == "<3>dpcontrol.service.daemon: control step failed"
    assert len(lines) > 3 and all(line.startswith("<3>") for line in lines)
    assert lines[-1] == "<3>RuntimeError: injected"


@pytest.mark.parametrize("journal", [True, False])
def test_dpcontrol_run_writes_priorities_to_the_journal_and_timestamps_elsewhere(tmp_path: Path,
                                                                                 journal: bool) -> None:
    config = tmp_path / "vessel.yaml"
    config.write_text(f"""
vessel_id: journal
vessel: cybership2
transports: [{{name: serial0, protocol: nmea0183, port: {tmp_path / 'no-tty'}}}]
sensors:
  - {{name: gnss1, kind: position, transport: serial0}}
  - {{name: gyro1, kind: heading, transport: serial0}}
zenoh: {{listen: ["tcp/127.0.0.1:0"]}}
""", encoding="utf-8")
    with (tmp_path / "stderr").open("w") as stderr:
        status = os.fstat(stderr.fileno())
        env = dict(os.environ)
        env.pop("JOURNAL_STREAM", None)
        if journal:
            env["JOURNAL_STREAM"] = f"{status.st_dev}:{status.st_ino}"
        completed = subprocess.run([sys.executable, "-m", "dpcontrol.cli", "run", "--config", str(config),
                                    "--duration", "1.5"], check=False, stderr=stderr, env=env, timeout=120)
    assert completed.returncode == 0
    lines = (tmp_path / "stderr").read_text(encoding="utf-8").splitlines()
    link = [line for line in lines if "alarm raised [WARNING] transport.serial0.link" in line]
    assert len(link) == 1, lines
    if journal:
        assert link[0].startswith("<4>dpcontrol.service.daemon: alarm raised"), link
        assert all(line[:3] in ("<2>", "<3>", "<4>", "<6>", "<7>") for line in lines), lines
    else:
        assert link[0][:4].isdigit() and " WARNING dpcontrol.service.daemon: alarm raised" in link[0], link


def test_a_fresh_machines_font_cache_note_stays_out_of_the_tools_output(tmp_path: Path) -> None:
    """matplotlib logs "generated new fontManager" at INFO on the first plot of a fresh machine; it
    printed itself among the demo's results. An empty MPLCONFIGDIR is such a machine."""
    code = ("import logging; from dpcontrol.logsetup import configure_logging; configure_logging(logging.INFO); "
            "import matplotlib; matplotlib.use('Agg'); import matplotlib.pyplot as plt; plt.figure(); "
            "logging.getLogger('dpcontrol.test').info('own line')")
    environ = {**os.environ, "MPLCONFIGDIR": str(tmp_path / "mpl"), "JOURNAL_STREAM": ""}
    done = subprocess.run([sys.executable, "-c", code], env=environ, capture_output=True, text=True, timeout=120,
                          check=True)
    assert "own line" in done.stderr
    assert "fontManager" not in done.stderr and "matplotlib" not in done.stderr, done.stderr
    assert (tmp_path / "mpl").is_dir()  # the cache was built in the run (the case it checks)
