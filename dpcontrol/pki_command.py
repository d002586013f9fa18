"""``dpcontrol pki``: make a vessel CA and the role certificates of its zenoh network (docs/security.md).

``dpcontrol pki init DIR --vessel V`` writes ``DIR/ca.pem`` and ``DIR/ca.key``; ``dpcontrol pki issue ROLE NAME
--dir DIR`` writes ``DIR/NAME.pem`` and ``DIR/NAME.key`` (mode 0600) signed by it, and prints the
``zenoh.identities`` line that grants NAME its role. The work is :mod:`interfaces.zenoh.pki` (``cryptography``).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from interfaces.zenoh.pki import DEFAULT_CA_DAYS, DEFAULT_DAYS, PkiError, init_ca, issue
from interfaces.zenoh.security import ROLE_NAMES


def add_parser(commands: Any) -> None:
    """The ``pki`` sub-command and its ``init``/``issue`` actions."""
    p = commands.add_parser("pki", help="make the vessel CA and role certificates for TLS on zenoh")
    actions = p.add_subparsers(dest="pki_action", required=True)
    init = actions.add_parser("init", help="make the vessel CA (DIR/ca.pem, DIR/ca.key)")
    init.add_argument("dir")
    init.add_argument("--vessel", required=True, help="vessel id (in the CA's name)")
    init.add_argument("--days", type=int, default=DEFAULT_CA_DAYS)
    new = actions.add_parser("issue", help="issue DIR/NAME.pem and DIR/NAME.key for one identity")
    new.add_argument("role", choices=ROLE_NAMES)
    new.add_argument("name", help="the certificate's common name (what zenoh.identities maps to a role)")
    new.add_argument("--dir", required=True, help="directory of the CA (and of the new files)")
    new.add_argument("--days", type=int, default=DEFAULT_DAYS)
    new.add_argument("--address", action="append", default=[], help="extra host name or IP address (repeatable)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    try:
        if args.pki_action == "init":
            cert, key = init_ca(args.dir, args.vessel, days=args.days)
            print(f"vessel CA: {cert} (give it to every node), {key} (keep it off the vessel network)")
        else:
            files = issue(args.dir, args.role, args.name, days=args.days, addresses=args.address)
            print(f"{args.role} {args.name!r}: {files.cert}, {files.key} (mode 0600)\n"
                  f"grant the role in the configuration's zenoh.identities:  {args.name}: {args.role}")
    except (PkiError, OSError) as error:
        print(f"dpcontrol pki: {error}", file=sys.stderr)
        return 2
    return 0
