"""``python -m interfaces.nmea2000.remote_server``: a python-can-remote server for NMEA 2000 between processes.

Bridges every websocket client onto one python-can ``virtual`` channel. Prints
``LISTENING <port>`` on stdout once it accepts connections (so ``--port 0`` can pick a free
port), then serves until SIGTERM/SIGINT — or, with ``--exit-with-stdin``, until its stdin reaches
end of file (the parent holding the pipe has exited) — when it disconnects its clients and exits
0. Started by :func:`interfaces.nmea2000.transport.start_remote_server`.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
from types import FrameType

from can_remote import RemoteServer

from interfaces.nmea2000.transport import _stop_server


def _terminate(signum: int, _frame: FrameType | None) -> None:
    raise SystemExit(0)


def _exit_at_stdin_eof() -> None:
    """Block until stdin ends, then stop the server the way SIGTERM does (in the main thread)."""
    while sys.stdin.buffer.read(4096):
        pass
    os.kill(os.getpid(), signal.SIGTERM)


def main(argv: list[str] | None = None) -> int:
    """Run the server (see the module docstring); returns the exit status."""
    parser = argparse.ArgumentParser(prog="python -m interfaces.nmea2000.remote_server", description=__doc__)
    parser.add_argument("--host", default="127.0.0.1", help="listen address (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=0, help="TCP port, 0 = a free one (default 0)")
    parser.add_argument("--channel", default="dpcontrol", help="virtual CAN channel name (default dpcontrol)")
    parser.add_argument("--log-level", default="WARNING", help="logging level on stderr (default WARNING)")
    parser.add_argument("--exit-with-stdin", action="store_true",
                        help="exit when stdin is closed (so the server does not outlive its parent)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=args.log_level.upper(), format="%(asctime)s %(name)s %(levelname)s %(message)s")
    server = RemoteServer(args.host, args.port, interface="virtual", channel=args.channel)
    signal.signal(signal.SIGTERM, _terminate)
    signal.signal(signal.SIGINT, _terminate)
    if args.exit_with_stdin:
        threading.Thread(target=_exit_at_stdin_eof, name="stdin-watch", daemon=True).start()
    sys.stdout.write(f"LISTENING {server.server_port}\n")
    sys.stdout.flush()
    try:
        server.serve_forever(poll_interval=0.2)
    except SystemExit:
        pass
    finally:
        _stop_server(server)
    return 0


if __name__ == "__main__":
    sys.exit(main())
