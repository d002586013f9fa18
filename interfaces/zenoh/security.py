"""Who may do what on a vessel's Zenoh network: roles, mutual TLS and the access-control list (Zenoh's own).

Nothing here inspects traffic: the protection is Zenoh 1.x's. Links are TLS with mutual authentication
(``transport/link/tls``: the vessel CA, this node's certificate and key, ``enable_mtls``); a peer whose
certificate the CA did not sign, or that has expired, never gets a session. Each node's session filters
what crosses its links with ``access_control`` (default *deny*), naming remote nodes by the common name of
the certificate they presented (``subjects: [{cert_common_names: [...]}]``). The configuration maps each
identity (common name) to a role; this module turns the role table below into Zenoh rules.

Roles (what a remote node of that role may do to *this* node; keys under ``dp/<vessel>/``):

========== ======================================== ================================================
role       publishes (puts we accept)               reads (puts we send it, queries we answer)
========== ======================================== ================================================
controller ``thrusters/command``, estimate, mmae,   feedback, setpoint, command, liveliness
           control, status; serves ``config``;
           token ``alive/controller``
drives     ``thrusters/feedback``; token            ``thrusters/command``, liveliness
           ``alive/plant``
console    ``setpoint`` (operator requests)         everything; queries ``config``
monitor    nothing                                  estimate, mmae, control, status, liveliness;
                                                    queries ``config``
========== ======================================== ================================================

Both directions are filtered: a put of a key the remote role may not publish is dropped on *ingress*
(before any subscriber sees it), and our subscriber's declaration is not even sent to it (*egress*), so
its session has nobody to send to. A node with no certificate, or a certificate whose name no role lists,
matches no subject: the default permission (deny) applies to everything.

Shared by every program (:func:`add_tls_arguments` / :func:`security_from_args` for the command lines,
:meth:`ZenohSecurity.from_mapping` for the YAML ``zenoh:`` section): ``dpcontrol run``/``monitor``/
``setpoint``, the console, ``sim-plant hil``/``demo``.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dpbase.schema import ConfigError, Section, join
from interfaces.zenoh.pki import NAME_PATTERN, IdentityFiles, PkiError, check_identity_files, days_left

ROLE_NAMES: tuple[str, ...] = ("controller", "drives", "console", "monitor")
#: A certificate (or the CA) closer than this to its end is warned about (check-config, a daemon alarm) [days].
EXPIRY_WARNING_DAYS = 30.0
_TELEMETRY = ("estimate", "mmae", "control", "status")


@dataclass(frozen=True, slots=True)
class RoleRights:
    """Keys (relative to ``dp/<vessel>/``) a role may publish, read, query, serve, and hold tokens on."""

    publishes: tuple[str, ...] = ()
    reads: tuple[str, ...] = ()
    queries: tuple[str, ...] = ()
    serves: tuple[str, ...] = ()
    tokens: tuple[str, ...] = ()


ROLE_RIGHTS: dict[str, RoleRights] = {
    "controller": RoleRights(publishes=("thrusters/command", *_TELEMETRY),
                             reads=("thrusters/feedback", "thrusters/command", "setpoint"),
                             serves=("config",), tokens=("alive/controller",)),
    "drives": RoleRights(publishes=("thrusters/feedback",), reads=("thrusters/command",),
                         tokens=("alive/plant",)),
    "console": RoleRights(publishes=("setpoint",), reads=("**",), queries=("config",)),
    "monitor": RoleRights(reads=_TELEMETRY, queries=("config",)),
}
#: Every role sees who is alive (``dp/<vessel>/alive/*``).
_ALIVE = "alive/*"


def _rules_for(role: str, prefix: str) -> list[dict[str, Any]]:
    """Zenoh ACL rules granting a remote node of ``role`` what :data:`ROLE_RIGHTS` says, on both flows."""
    rights = ROLE_RIGHTS[role]

    def keys(suffixes: tuple[str, ...]) -> list[str]:
        return [f"{prefix}/{suffix}" for suffix in suffixes]

    rules: list[dict[str, Any]] = []

    def rule(name: str, messages: list[str], flow: str, suffixes: tuple[str, ...]) -> None:
        if suffixes:
            rules.append({"id": f"{role}-{name}", "messages": messages, "flows": [flow], "permission": "allow",
                          "key_exprs": keys(suffixes)})

    # what it publishes: its puts come in; our subscriptions go out so that it sends them
    rule("publish-in", ["put"], "ingress", rights.publishes)
    rule("publish-sub-out", ["declare_subscriber"], "egress", rights.publishes)
    # what it reads: its subscriptions come in; our puts go out
    rule("read-sub-in", ["declare_subscriber"], "ingress", rights.reads)
    rule("read-out", ["put"], "egress", rights.reads)
    # queries it asks / queryables it serves
    rule("query-in", ["query"], "ingress", rights.queries)
    rule("query-out", ["declare_queryable", "reply"], "egress", rights.queries)
    rule("serve-out", ["query"], "egress", rights.serves)
    rule("serve-in", ["declare_queryable", "reply"], "ingress", rights.serves)
    # liveliness: its own tokens come in; everybody watches who is alive
    rule("token-in", ["liveliness_token"], "ingress", rights.tokens)
    rule("alive-in", ["declare_liveliness_subscriber", "liveliness_query"], "ingress", (_ALIVE,))
    rule("alive-out", ["liveliness_token", "reply"], "egress", (_ALIVE,))
    rule("alive-watch-out", ["declare_liveliness_subscriber", "liveliness_query"], "egress", rights.tokens)
    return rules


def _roles(held: str | tuple[str, ...] | list[str]) -> tuple[str, ...]:
    return (held,) if isinstance(held, str) else tuple(held)


def access_control(vessel: str, identities: Mapping[str, str | tuple[str, ...]]) -> dict[str, Any]:
    """Zenoh's ``access_control`` section for a node of ``vessel`` given ``{common name: role or roles}``.

    Default deny; one subject per role listing the common names mapped to it; one policy per role binding
    its subject to its rules. Roles nobody holds are left out (a policy with an empty subject is refused).
    """
    prefix = f"dp/{vessel}"
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for role in ROLE_NAMES:
        names = sorted(name for name, held in identities.items() if role in _roles(held))
        if not names:
            continue
        role_rules = _rules_for(role, prefix)
        rules.extend(role_rules)
        subjects.append({"id": f"{role}-identities", "cert_common_names": names})
        policies.append({"id": f"{role}-policy", "rules": [r["id"] for r in role_rules],
                         "subjects": [f"{role}-identities"]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def _expand(path: str) -> Path:
    """``$CREDENTIALS_DIRECTORY`` (systemd ``LoadCredential=``) and ``~`` expanded."""
    return Path(os.path.expanduser(os.path.expandvars(path)))


@dataclass(frozen=True, slots=True)
class ZenohSecurity:
    """TLS files of this node and the identity → role map its access control enforces.

    Attributes
    ----------
    files : IdentityFiles or None
        The vessel CA, this node's certificate and key (``None``: plaintext, only where allowed).
    identities : mapping of str to tuple of str
        Certificate common name → its roles (``controller``, ``drives``, ``console``, ``monitor``; usually one:
        the HIL emulator stands for both the drives and the scenario's operator, ``(drives, console)``). Empty:
        no access control in this session (a tool that only connects: the nodes it reaches enforce theirs).
        A single role may be given as a string.
    expected_name : str or None
        The common name this node's certificate must carry (checked by ``check-config``).
    insecure : bool
        Plaintext off loopback explicitly allowed (the daemon then raises a standing warning alarm).
    """

    files: IdentityFiles | None = None
    identities: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    expected_name: str | None = None
    insecure: bool = False

    def __post_init__(self) -> None:
        identities = {name: _roles(held) for name, held in self.identities.items()}
        object.__setattr__(self, "identities", identities)
        for name, roles in identities.items():
            if NAME_PATTERN.fullmatch(name) is None:
                raise ValueError(f"identity {name!r}: expected a certificate common name from [A-Za-z0-9_.-]")
            for role in roles or ("(none)",):
                if role not in ROLE_NAMES:
                    raise ValueError(f"identity {name!r}: unknown role {role!r} "
                                     f"(expected one of {', '.join(ROLE_NAMES)})")
        if self.identities and self.files is None:
            raise ValueError("identities (access control by certificate name) need tls certificates")

    @property
    def tls(self) -> bool:
        return self.files is not None

    def roles_of(self, name: str | None) -> tuple[str, ...]:
        """The roles of a certificate common name (none: unknown or no name)."""
        return () if name is None else self.identities.get(name, ())

    def settings(self, vessel: str | None) -> dict[str, Any]:
        """Zenoh configuration entries (``{json5 key path: value}``): TLS with mTLS, and the ACL when
        identities are mapped (needs ``vessel``)."""
        out: dict[str, Any] = {}
        if self.files is not None:
            ca, cert, key = (str(p) for p in (self.files.ca, self.files.cert, self.files.key))
            out.update({
                "transport/link/tls/root_ca_certificate": ca,
                "transport/link/tls/listen_certificate": cert, "transport/link/tls/listen_private_key": key,
                "transport/link/tls/connect_certificate": cert, "transport/link/tls/connect_private_key": key,
                "transport/link/tls/enable_mtls": True,
                # peers are named by certificate (the ACL's subjects), not by host name: the vessel network's
                # addresses need not be in each certificate
                "transport/link/tls/verify_name_on_connect": False,
                # A certificate that expires during an operation must not cut the thrusters' link: the links
                # open stay, new ones are refused (check-config and the daemon's alarm warn weeks ahead).
                "transport/link/tls/close_link_on_expiration": False,
            })
        if self.identities:
            if vessel is None:
                raise ValueError("access control needs the vessel id (its keys are dp/<vessel>/...)")
            out["access_control"] = access_control(vessel, self.identities)
        return out

    @classmethod
    def from_mapping(cls, tls: object, identities: object, insecure: bool, path: str = "zenoh") -> ZenohSecurity:
        """From the YAML ``zenoh:`` keys ``tls`` (``{dir, identity}`` or ``{ca, cert, key, identity?}``; paths
        may use ``$CREDENTIALS_DIRECTORY``), ``identities`` (``{common name: role}``) and ``insecure``.

        Raises
        ------
        ConfigError
        """
        files = None
        expected = None
        if tls is not None:
            sec = Section.of(tls, join(path, "tls"))
            directory, expected, ca, cert, key = (_optional_string(sec, k) for k in ("dir", "identity", "ca", "cert",
                                                                                     "key"))
            sec.finish()
            if expected is not None and NAME_PATTERN.fullmatch(expected) is None:
                raise ConfigError(join(path, "tls", "identity"), "a certificate common name ([A-Za-z0-9_.-])",
                                  expected)
            if directory is not None:
                if expected is None:
                    raise ConfigError(join(path, "tls", "identity"), "this node's name (its files are "
                                      "<dir>/ca.pem, <dir>/<identity>.pem, <dir>/<identity>.key)", None)
                base = _expand(directory)
                files = IdentityFiles(_expand(ca) if ca else base / "ca.pem",
                                      _expand(cert) if cert else base / f"{expected}.pem",
                                      _expand(key) if key else base / f"{expected}.key")
            elif ca and cert and key:
                files = IdentityFiles(_expand(ca), _expand(cert), _expand(key))
            else:
                raise ConfigError(join(path, "tls"), "either dir + identity, or ca + cert + key", tls)
        names: dict[str, tuple[str, ...]] = {}
        if identities is not None:
            sec = Section.of(identities, join(path, "identities"))
            for name in list(sec.data):
                held = sec.raw(name)
                where = join(join(path, "identities"), name)
                if isinstance(held, str):
                    held = [held]
                if not isinstance(held, list) or not held or any(r not in ROLE_NAMES for r in held):
                    raise ConfigError(where, f"a role or a list of roles from {', '.join(ROLE_NAMES)}", held)
                names[name] = tuple(held)
            sec.finish()
        try:
            return cls(files, names, expected, insecure)
        except ValueError as exc:
            raise ConfigError(join(path, "identities"), str(exc), identities) from None


def _optional_string(sec: Section, key: str) -> str | None:
    return None if sec.raw(key, None) is None else sec.string(key)


def is_loopback_host(host: str) -> bool:
    """True when ``host`` names this machine only (``localhost``, ``127.0.0.0/8``, ``::1``)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def is_loopback(endpoint: str) -> bool:
    """True when the endpoint's host is a loopback address (``127.0.0.0/8``, ``::1``, ``localhost``) or a
    local socket."""
    proto, _, address = endpoint.partition("/")
    if proto == "unixsock-stream":
        return True
    address = address.split("?", 1)[0].split("#", 1)[0]
    return is_loopback_host(address.rpartition(":")[0].strip("[]"))


def unprotected_endpoints(listen: tuple[str, ...], connect: tuple[str, ...],
                          security: ZenohSecurity | None) -> list[str]:
    """The endpoints off loopback that would carry plaintext, or TLS without mutual authentication and
    access control: what ``dpcontrol run`` refuses unless ``insecure: true``."""
    secured = security is not None and security.tls and bool(security.identities)
    return [e for e in (*listen, *connect)
            if not is_loopback(e) and not (secured and e.startswith(("tls/", "quic/")))]


# -- command lines --------------------------------------------------------------------------------

def add_tls_arguments(parser: argparse.ArgumentParser) -> None:
    """``--tls-dir DIR --identity NAME``: the TLS options of every tool (monitor, setpoint, console, hil)."""
    group = parser.add_argument_group("TLS (a secured vessel network; see docs/security.md)")
    group.add_argument("--tls-dir", metavar="DIR", default=os.environ.get("DPCONTROL_TLS_DIR"),
                       help="directory with ca.pem, <identity>.pem, <identity>.key "
                            "(default $DPCONTROL_TLS_DIR; none: plaintext)")
    group.add_argument("--identity", metavar="NAME", default=os.environ.get("DPCONTROL_IDENTITY"),
                       help="this tool's certificate name (default $DPCONTROL_IDENTITY)")


def security_from_args(args: argparse.Namespace,
                       identities: Mapping[str, tuple[str, ...]] | None = None) -> ZenohSecurity | None:
    """The :class:`ZenohSecurity` of :func:`add_tls_arguments`'s options (``None`` when no ``--tls-dir``).

    ``identities`` (``{name: role}``) turns on this session's own access control (a node others connect to:
    the plant emulator); tools that only connect leave it empty.

    Raises
    ------
    ValueError
        ``--tls-dir`` without ``--identity``; a :class:`~interfaces.zenoh.pki.PkiError` when the files are
        missing, expired, not signed by the CA in that directory, or not ``--identity``'s.
    """
    directory = getattr(args, "tls_dir", None)
    if not directory:
        return None
    name = getattr(args, "identity", None)
    if not name:
        raise ValueError("--tls-dir needs --identity NAME (this tool's certificate: <dir>/<NAME>.pem)")
    security = ZenohSecurity(IdentityFiles.in_dir(_expand(directory), name), dict(identities or {}), name)
    check_identity_files(security.files, expected_name=name)  # type: ignore[arg-type]  # a clear error, not zenoh's
    return security


def check_security(security: ZenohSecurity | None, role: str) -> str:
    """Verify this node's TLS files (see :func:`interfaces.zenoh.pki.check_identity_files`) and that its own
    certificate name holds ``role`` in the identity map; a one-line description of what is in force.

    Raises
    ------
    interfaces.zenoh.pki.PkiError
        The first thing wrong, naming the file or the identity.
    """
    if security is None or security.files is None:
        return "zenoh: plaintext (no tls)" + (", insecure: true" if security is not None and security.insecure else "")
    unset = [str(p) for p in (security.files.ca, security.files.cert, security.files.key) if "$" in str(p)]
    if unset:
        raise PkiError(f"zenoh.tls: {unset[0]}: a variable is not set (CREDENTIALS_DIRECTORY is set by systemd's "
                       "LoadCredential= inside the unit; outside it, check a copy of the configuration that gives "
                       "the files' own paths)")
    name = check_identity_files(security.files, expected_name=security.expected_name)
    if security.identities and role not in security.roles_of(name):
        held = "/".join(security.roles_of(name)) or "none"
        raise PkiError(f"zenoh.identities: this node's certificate name {name!r} has role {held!r}, expected "
                       f"{role!r} (the other nodes' access control names it by that role)")
    roles = ", ".join(f"{n}={'/'.join(r)}" for n, r in sorted(security.identities.items()))
    days = days_left(security.files)
    soon = f"; WARNING: a certificate expires in {days:.0f} days" if days < EXPIRY_WARNING_DAYS else ""
    return (f"zenoh: mutual TLS as {name!r} (CA {security.files.ca}); access control by role: "
            f"{roles or 'off'}{soon}")
