"""A vessel's certificate authority and the role certificates of its Zenoh network (``cryptography``).

Zenoh's TLS links authenticate both ends with X.509 certificates (``transport/link/tls``, mutual TLS);
its access control names a remote end by its certificate's *common name* (``cert_common_names``).
This module makes what that needs with the well-kept ``cryptography`` library — nothing of the TLS
or the checks on the wire is ours:

* :func:`init_ca` — a self-signed vessel CA (ECDSA P-256), written as ``ca.pem`` / ``ca.key``;
* :func:`issue` — a certificate for one identity (``CN=<name>``, ``OU=<role>`` for the reader; the
  configuration, not the certificate, grants the role), signed by that CA, written as
  ``<name>.pem`` / ``<name>.key``; it carries ``subjectAltName`` ``DNS:<name>``, ``localhost``,
  ``127.0.0.1`` and any address given, so a peer that verifies the name on connect can;
* :func:`check_identity_files` — what ``check-config`` verifies: readable, parseable, not expired,
  signed by the CA, the key matches the certificate, the expected common name.

Private keys are written mode 0600 in a directory made mode 0700 (readable by the service user only).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

#: An identity becomes a file name and a certificate common name: keep it plain.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
CA_NAME = "ca"
DEFAULT_CA_DAYS = 3650
DEFAULT_DAYS = 825


class PkiError(ValueError):
    """A certificate or key is missing, unreadable, expired, or not what the configuration expects."""


def _name(name: str) -> str:
    if not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None or name == CA_NAME:
        raise PkiError(f"invalid identity name {name!r}: expected 1-64 characters from [A-Za-z0-9_.-] "
                       f"starting with a letter or digit, not {CA_NAME!r}")
    return name


def _now() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc)


def _write_private(path: Path, data: bytes) -> None:
    """Write ``data`` readable by its owner only (created 0600, never world-readable in between)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "wb") as out:
        out.write(data)
    os.chmod(path, 0o600)


def _key_pem(key: ec.EllipticCurvePrivateKey) -> bytes:
    # PKCS#8 unencrypted: the service reads it unattended (systemd's LoadCredential= or a 0700 directory
    # protects it); rustls (zenoh's TLS) reads PKCS#8 and SEC1 keys.
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


@dataclass(frozen=True, slots=True)
class IdentityFiles:
    """Where one identity's files are: the vessel CA certificate, its certificate and private key."""

    ca: Path
    cert: Path
    key: Path

    @classmethod
    def in_dir(cls, directory: str | os.PathLike[str], name: str) -> IdentityFiles:
        """The files :func:`issue` writes for ``name`` in ``directory``."""
        base = Path(directory)
        return cls(base / f"{CA_NAME}.pem", base / f"{_name(name)}.pem", base / f"{name}.key")


def init_ca(directory: str | os.PathLike[str], vessel: str, *, days: int = DEFAULT_CA_DAYS,
            overwrite: bool = False) -> tuple[Path, Path]:
    """Make the vessel CA: ``ca.pem`` (certificate, to every node) and ``ca.key`` (keep it off the vessel
    network once the certificates are issued). Returns their paths.

    Raises
    ------
    PkiError
        A CA exists already there and ``overwrite`` is false (re-making it would orphan every certificate).
    """
    base = Path(directory)
    base.mkdir(mode=0o700, parents=True, exist_ok=True)
    cert_path, key_path = base / f"{CA_NAME}.pem", base / f"{CA_NAME}.key"
    if not overwrite and (cert_path.exists() or key_path.exists()):
        raise PkiError(f"{cert_path}: a CA exists already (every certificate it signed would stop working; "
                       "remove it first if that is what you want)")
    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.ORGANIZATION_NAME, "dpcontrol"),
                         x509.NameAttribute(NameOID.COMMON_NAME, f"{vessel} vessel CA")])
    now = _now()
    cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject).public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - dt.timedelta(minutes=5)).not_valid_after(now + dt.timedelta(days=days))
            .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
            .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=True, crl_sign=True,
                                         content_commitment=False, key_encipherment=False, data_encipherment=False,
                                         key_agreement=False, encipher_only=False, decipher_only=False),
                           critical=True)
            .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
            .sign(key, hashes.SHA256()))
    _write_private(key_path, _key_pem(key))
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return cert_path, key_path


def issue(directory: str | os.PathLike[str], role: str, name: str, *, days: int = DEFAULT_DAYS,
          addresses: Sequence[str] = (), not_before: dt.datetime | None = None,
          ca_dir: str | os.PathLike[str] | None = None) -> IdentityFiles:
    """Issue ``<name>.pem`` / ``<name>.key`` in ``directory``, signed by the CA in ``ca_dir`` (default: the same
    directory), valid ``days`` from ``not_before`` (default now). ``role`` goes in the OU for the reader.

    ``addresses`` are extra host names or IP addresses the certificate is valid for (subjectAltName).

    Raises
    ------
    PkiError
        Bad name, no CA there, or an unreadable CA.
    """
    _name(name)
    ca_base = Path(ca_dir if ca_dir is not None else directory)
    ca_cert = _load_cert(ca_base / f"{CA_NAME}.pem", "CA certificate")
    ca_key = _load_key(ca_base / f"{CA_NAME}.key", "CA key")
    key = ec.generate_private_key(ec.SECP256R1())
    start = (not_before or _now()) - dt.timedelta(minutes=5)
    alt: list[x509.GeneralName] = [x509.DNSName(name), x509.DNSName("localhost"),
                                   x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
    for address in addresses:
        try:
            alt.append(x509.IPAddress(ipaddress.ip_address(address)))
        except ValueError:
            alt.append(x509.DNSName(address))
    subject = x509.Name([x509.NameAttribute(NameOID.ORGANIZATION_NAME, "dpcontrol"),
                         x509.NameAttribute(NameOID.ORGANIZATIONAL_UNIT_NAME, role),
                         x509.NameAttribute(NameOID.COMMON_NAME, name)])
    cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(ca_cert.subject)
            .public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(start).not_valid_after(start + dt.timedelta(days=days))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.KeyUsage(digital_signature=True, key_cert_sign=False, crl_sign=False,
                                         content_commitment=False, key_encipherment=False, data_encipherment=False,
                                         key_agreement=False, encipher_only=False, decipher_only=False),
                           critical=True)
            # every node both listens (server) and connects (client) in a peer network
            .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]),
                           critical=False)
            .add_extension(x509.SubjectAlternativeName(alt), critical=False)
            .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(ca_key.public_key()), critical=False)
            .sign(ca_key, hashes.SHA256()))
    base = Path(directory)
    base.mkdir(mode=0o700, parents=True, exist_ok=True)
    files = IdentityFiles(ca_base / f"{CA_NAME}.pem", base / f"{name}.pem", base / f"{name}.key")
    _write_private(files.key, _key_pem(key))
    files.cert.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    if files.ca.parent != base:
        (base / f"{CA_NAME}.pem").write_bytes(files.ca.read_bytes())
        files = IdentityFiles(base / f"{CA_NAME}.pem", files.cert, files.key)
    return files


def _read(path: Path, what: str) -> bytes:
    try:
        return Path(path).read_bytes()
    except FileNotFoundError:
        raise PkiError(f"{what} {path}: no such file") from None
    except PermissionError:
        raise PkiError(f"{what} {path}: not readable by this user (uid {os.getuid()})") from None
    except OSError as exc:
        raise PkiError(f"{what} {path}: cannot read: {exc.strerror}") from None


def _load_cert(path: Path, what: str) -> x509.Certificate:
    try:
        return x509.load_pem_x509_certificate(_read(path, what))
    except ValueError as exc:
        raise PkiError(f"{what} {path}: not a PEM certificate ({exc})") from None


def _load_key(path: Path, what: str) -> ec.EllipticCurvePrivateKey:
    try:
        key = serialization.load_pem_private_key(_read(path, what), password=None)
    except (ValueError, TypeError) as exc:
        raise PkiError(f"{what} {path}: not an unencrypted PEM private key ({exc})") from None
    return key  # type: ignore[return-value]


def common_name(cert: x509.Certificate) -> str | None:
    """The certificate's subject common name (what zenoh's ``cert_common_names`` matches)."""
    names = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    return str(names[0].value) if names else None


def check_identity_files(files: IdentityFiles, *, expected_name: str | None = None,
                         now: dt.datetime | None = None) -> str:
    """Verify one node's TLS files as zenoh will need them; return the certificate's common name.

    Checks: each file readable; the CA a PEM CA certificate within its validity; the certificate a PEM
    certificate within its validity, issued and signed by that CA; the key a PEM private key matching the
    certificate; the common name ``expected_name`` when given.

    Raises
    ------
    PkiError
        The first thing wrong, naming the file and what to do.
    """
    when = now or _now()
    ca = _load_cert(files.ca, "CA certificate")
    cert = _load_cert(files.cert, "certificate")
    key = _load_key(files.key, "private key")
    for what, path, c in (("CA certificate", files.ca, ca), ("certificate", files.cert, cert)):
        if when < c.not_valid_before_utc:
            raise PkiError(f"{what} {path}: not valid before {c.not_valid_before_utc:%Y-%m-%d %H:%M} UTC "
                           "(is the clock right?)")
        if when > c.not_valid_after_utc:
            raise PkiError(f"{what} {path}: expired on {c.not_valid_after_utc:%Y-%m-%d %H:%M} UTC "
                           "(issue a new one: dpcontrol pki issue)")
    constraints = ca.extensions.get_extension_for_class(x509.BasicConstraints).value \
        if _has(ca, x509.BasicConstraints) else None
    if constraints is None or not constraints.ca:
        raise PkiError(f"CA certificate {files.ca}: not a CA certificate (basicConstraints CA:TRUE missing)")
    if cert.issuer != ca.subject:
        raise PkiError(f"certificate {files.cert}: issued by '{cert.issuer.rfc4514_string()}', not by the "
                       f"configured CA '{ca.subject.rfc4514_string()}' ({files.ca})")
    try:
        cert.verify_directly_issued_by(ca)
    except (InvalidSignature, ValueError, TypeError) as exc:
        raise PkiError(f"certificate {files.cert}: not signed by the configured CA {files.ca} "
                       f"({exc or 'bad signature'})") from None
    pub = cert.public_key().public_bytes(serialization.Encoding.DER, serialization.PublicFormat.SubjectPublicKeyInfo)
    if key.public_key().public_bytes(serialization.Encoding.DER,
                                     serialization.PublicFormat.SubjectPublicKeyInfo) != pub:
        raise PkiError(f"private key {files.key}: does not belong to certificate {files.cert}")
    name = common_name(cert)
    if name is None:
        raise PkiError(f"certificate {files.cert}: no common name (zenoh's access control names peers by it)")
    if expected_name is not None and name != expected_name:
        raise PkiError(f"certificate {files.cert}: common name {name!r}, expected {expected_name!r}")
    return name


def days_left(files: IdentityFiles, *, now: dt.datetime | None = None) -> float:
    """Days until the first of the CA and the certificate expires (negative: expired; ``inf``: unreadable,
    which :func:`check_identity_files` reports)."""
    when = now or _now()
    try:
        ends = [_load_cert(path, "certificate").not_valid_after_utc for path in (files.ca, files.cert)]
    except PkiError:
        return float("inf")
    return min(ends).timestamp() / 86400.0 - when.timestamp() / 86400.0


def _has(cert: x509.Certificate, kind: type[x509.ExtensionType]) -> bool:
    try:
        cert.extensions.get_extension_for_class(kind)
    except x509.ExtensionNotFound:
        return False
    return True
