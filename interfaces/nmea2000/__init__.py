"""NMEA 2000 (CAN): codec (frames ⇄ typed messages, fast packet), candump logs, python-can transport.

* :mod:`~interfaces.nmea2000.codec` — :class:`N2kDecoder`, :class:`N2kEncoder`,
  :class:`FastPacketAssembler`, :func:`parse_can_id` / :func:`make_can_id` (pure).
* :mod:`~interfaces.nmea2000.candump` — the three candump text formats.
* :mod:`~interfaces.nmea2000.logs` — :func:`decode_candump_log` for ``dpcontrol decode``.
* :mod:`~interfaces.nmea2000.transport` — :class:`CanBusConfig`, :class:`N2kCanReader`,
  :class:`N2kCanWriter`, :func:`start_remote_server` (python-can ``remote`` between processes).
"""

from interfaces.nmea2000.codec import (
    FAST_PACKET_PGNS,
    SUPPORTED_PGNS,
    FastPacketAssembler,
    N2kDecoded,
    N2kDecoder,
    N2kEncoder,
    N2kHeader,
    make_can_id,
    parse_can_id,
)

__all__ = [
    "FAST_PACKET_PGNS",
    "SUPPORTED_PGNS",
    "FastPacketAssembler",
    "N2kDecoded",
    "N2kDecoder",
    "N2kEncoder",
    "N2kHeader",
    "make_can_id",
    "parse_can_id",
]
