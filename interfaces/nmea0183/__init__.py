"""NMEA 0183: codec (bytes ⇄ typed messages, pynmea2 underneath) and serial transport (pyserial).

Codec: :class:`Nmea0183Decoder` (streaming ``feed(bytes)``), :func:`decode_sentence`, and the
encoders the plant emulator sends with (``encode_gga``, ``encode_gns``, ``encode_rmc``,
``encode_vtg``, ``encode_gst``, ``encode_hdt``, ``encode_ths``, ``encode_rot``, ``encode_mwv``).
Transport: :class:`SerialReader` (background thread, reconnects), :class:`SerialWriter`,
:class:`PtyPair` (the pseudo-terminal loopback twin).
"""

from interfaces.nmea0183.codec import (
    DECODED_SENTENCES,
    DEFAULT_MAX_SENTENCE_CHARS,
    LATLON_QUANTISATION_M,
    NMEA_MAX_SENTENCE_CHARS,
    REJECT_REASONS,
    Frame,
    Nmea0183Decoder,
    decode_sentence,
    encode_gga,
    encode_gga_no_fix,
    encode_gns,
    encode_gst,
    encode_hdt,
    encode_mwv,
    encode_rmc,
    encode_rmc_no_fix,
    encode_rot,
    encode_ths,
    encode_vtg,
)
from interfaces.nmea0183.transport import LinkState, PtyPair, ReceivedLine, SerialReader, SerialWriter

__all__ = [
    "DECODED_SENTENCES",
    "DEFAULT_MAX_SENTENCE_CHARS",
    "LATLON_QUANTISATION_M",
    "NMEA_MAX_SENTENCE_CHARS",
    "REJECT_REASONS",
    "Frame",
    "LinkState",
    "Nmea0183Decoder",
    "PtyPair",
    "ReceivedLine",
    "SerialReader",
    "SerialWriter",
    "decode_sentence",
    "encode_gga",
    "encode_gga_no_fix",
    "encode_gns",
    "encode_gst",
    "encode_hdt",
    "encode_mwv",
    "encode_rmc",
    "encode_rmc_no_fix",
    "encode_rot",
    "encode_ths",
    "encode_vtg",
]
