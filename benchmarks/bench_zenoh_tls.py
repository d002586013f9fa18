"""What mutual TLS and access control cost on the Zenoh transport: the command → feedback round trip
between two peer sessions on 127.0.0.1, plaintext TCP against TLS + ACL (certificates made in a temporary
directory; the controller's and the drives' sessions each enforce the vessel's access control).

The round trip is ``bench_zenoh.py``'s ``full`` loop: the controller builds and puts a thruster command
(8 thrusters), the drives' validating subscriber parses it and answers with feedback, which the controller
parses. Plaintext and secured runs alternate (``--rounds``) so that the host's load falls on both alike.

Usage::

    .venv/bin/python benchmarks/bench_zenoh_tls.py [--n 2000] [--rounds 3] [--json]

Prints the median and p99 [µs] of each run and the host's steal over the whole benchmark.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_zenoh import VESSEL, _full_round_trip

from dpcontrol.platform_info import cpu_times, host_steal
from interfaces.zenoh import pki
from interfaces.zenoh.loopback import free_tcp_port
from interfaces.zenoh.node import ZenohNode
from interfaces.zenoh.security import ZenohSecurity
from interfaces.zenoh.session_config import ZenohConfig

IDENTITIES = {"dp": ("controller",), "drives": ("drives",)}


def _pair(tls_dir: Path | None) -> tuple[ZenohNode, ZenohNode]:
    scheme = "tcp" if tls_dir is None else "tls"
    endpoint = f"{scheme}/127.0.0.1:{free_tcp_port()}"

    def security(name: str) -> ZenohSecurity | None:
        return None if tls_dir is None else ZenohSecurity(pki.IdentityFiles.in_dir(tls_dir, name), IDENTITIES, name)

    a = ZenohNode(ZenohConfig(listen=(endpoint,), security=security("dp")), VESSEL)
    b = ZenohNode(ZenohConfig(connect=(endpoint,), security=security("drives")), VESSEL)
    if not b.wait_for_peers(1, 10.0):
        raise TimeoutError(f"no session over {endpoint}")
    return a, b


def run(n: int = 2000, rounds: int = 3, warmup: int = 200) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as tmp:
        tls_dir = Path(tmp)
        pki.init_ca(tls_dir, VESSEL)
        for name, roles in IDENTITIES.items():
            pki.issue(tls_dir, roles[0], name)
        ticks = cpu_times()
        runs: dict[str, list[dict[str, float]]] = {"plaintext": [], "tls_acl": []}
        for _ in range(rounds):
            for label, directory in (("plaintext", None), ("tls_acl", tls_dir)):
                a, b = _pair(directory)
                try:
                    runs[label].append(_full_round_trip(a, b, n, warmup))
                finally:
                    b.close()
                    a.close()
        return {"runs": runs, "host_steal": host_steal(ticks, cpu_times())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = run(args.n, args.rounds)
    if args.json:
        print(json.dumps(result, indent=2))
        return
    for label, items in result["runs"].items():
        for item in items:
            print(f"{label:9s} command -> feedback round trip: median {item['median_us']:6.0f} us, "
                  f"p99 {item['p99_us']:6.0f} us, lost {item['lost']} of {item['n'] + item['lost']}")
    print(f"host steal during the benchmark: {result['host_steal']}")


if __name__ == "__main__":
    main()
