"""MAVLink 2 (pymavlink ``common``): codec, heartbeat monitor, UDP transport, tlog decoding.

* :mod:`~interfaces.mavlink.codec` — :class:`MavlinkDecoder`, :class:`MavlinkEncoder`,
  :class:`HeartbeatMonitor`, :func:`parse_signing_key` (pure).
* :mod:`~interfaces.mavlink.transport` — :class:`MavlinkUdpReader`, :class:`MavlinkUdpSender`.
* :mod:`~interfaces.mavlink.logs` — :func:`decode_tlog` for ``dpcontrol decode``.
"""

from interfaces.mavlink.codec import (
    HeartbeatMonitor,
    MavDecoded,
    MavlinkDecoder,
    MavlinkEncoder,
    parse_signing_key,
)

__all__ = ["HeartbeatMonitor", "MavDecoded", "MavlinkDecoder", "MavlinkEncoder", "parse_signing_key"]
