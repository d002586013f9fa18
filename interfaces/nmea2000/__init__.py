"""NMEA 2000 (CAN): codec (frames ⇄ typed messages, fast packet), capture logs, CAN and gateway transports.

* :mod:`~interfaces.nmea2000.codec` — :class:`N2kDecoder`, :class:`N2kEncoder`,
  :class:`FastPacketAssembler`, :func:`parse_can_id` / :func:`make_can_id` (pure).
* :mod:`~interfaces.nmea2000.candump` — the three candump text formats.
* :mod:`~interfaces.nmea2000.logformats` — the capture formats boats log (candump, Actisense, canboat
  PLAIN/FAST, YDWG raw, iKonvert, PCAN-View, pcap/pcapng) and their detection.
* :mod:`~interfaces.nmea2000.logs` — :func:`decode_nmea2000_log` for ``dpcontrol decode``.
* :mod:`~interfaces.nmea2000.transport` — :class:`CanBusConfig`, :class:`N2kCanReader`,
  :class:`N2kCanWriter`, :func:`start_remote_server` (python-can ``remote`` between processes).
* :mod:`~interfaces.nmea2000.gateways` — :class:`N2kGatewayReader` for Yacht Devices RAW (TCP/UDP) and
  Actisense NGT-1 (serial), and their loopback twins.
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
