"""Sensor samples → the bytes a real device sends, per protocol (pure: no I/O, no clock).

One encoder per sensor, shared by the real-time emulator's links and the lockstep simulation, so
what the controller decodes in a lockstep run is byte for byte what the emulator would put on the
wire:

* NMEA 0183 (:class:`NmeaSensorEncoder`): a GNSS sends GGA + VTG + GST (or the configured sentences among
  GGA, GNS, RMC, VTG, GST; its velocity, SOG/COG, goes in VTG and RMC), a gyrocompass THS + ROT (or HDT,
  THS, ROT); an invalid sample is GGA quality 0 (+ RMC status V when RMC is sent; no VTG) or THS mode V
  (+ ROT status V). HDT has no validity field, so an HDT-only gyro sends a THS V for an invalid sample. A
  rate-of-turn sensor (``rot``) sends ``$TIROT`` (talker TI, turn indicator), status V when invalid.
* NMEA 2000 (:class:`N2kSensorEncoder`): a GNSS sends PGN 129029 (fast packet) + 129026 (COG & SOG,
  rapid update), a gyro 127250 (true) + 127251, a rate-of-turn sensor 127251; an invalid sample is
  129029 with method "no GNSS" (no 129026) or 127250 / 127251 with the heading / rate "not available".
  GST statistics have no PGN here and are counted as not carried.
* MAVLink 2 (:class:`MavlinkSensorEncoder`): a GNSS sends GPS_RAW_INT (``vel``/``cog`` from its
  velocity), a gyro ATTITUDE (yaw and yaw rate in one message), a rate-of-turn sensor ATTITUDE with only
  ``yawspeed``; an invalid sample is GPS_RAW_INT fix_type 0 or ATTITUDE without values.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from interfaces.mavlink.codec import MavlinkEncoder
from interfaces.messages import (
    Attitude,
    CourseOverGround,
    Heading,
    PositionErrorStats,
    PositionFix,
    RateOfTurn,
    SensorMessage,
)
from interfaces.nmea0183 import (
    encode_gga,
    encode_gga_no_fix,
    encode_gns,
    encode_gst,
    encode_hdt,
    encode_rmc,
    encode_rmc_no_fix,
    encode_rot,
    encode_ths,
    encode_vtg,
)
from interfaces.nmea2000.codec import N2kEncoder
from sim_plant.sensors import InvalidFix

Message = SensorMessage | InvalidFix

POSITION_SENTENCES = ("GGA", "GNS", "RMC", "VTG", "GST")
HEADING_SENTENCES = ("HDT", "THS", "ROT")
DEFAULT_POSITION_SENTENCES = ("GGA", "VTG", "GST")
DEFAULT_HEADING_SENTENCES = ("THS", "ROT")
RATE_SENTENCES = ("ROT",)
DATE_DDMMYY = "010126"  # RMC needs a date; the plant has none (1 January 2026)
DATE_DAYS_SINCE_1970 = 20454  # the same date for PGN 129029


class NmeaSensorEncoder:
    """NMEA 0183 sentences of one sensor.

    Parameters
    ----------
    kind : {"gnss", "gyro", "rot"}
    talker : str or None
        Talker ID (default GP for a GNSS, HE for a gyrocompass, TI for a rate-of-turn sensor).
    sentences : sequence of str, optional
        Sentence types to send (defaults above).
    """

    def __init__(self, kind: str, talker: str | None = None, sentences: Sequence[str] = (), *,
                 rate_of_turn: bool = True) -> None:
        gnss = kind in ("gnss", "position")
        rate = kind in ("rot", "rate_of_turn")
        self.talker = talker or ("GP" if gnss else "TI" if rate else "HE")
        self.gns_talker = talker or "GN"  # GNS is a multi-constellation sentence
        applicable = POSITION_SENTENCES if gnss else RATE_SENTENCES if rate else HEADING_SENTENCES
        chosen = tuple(x for x in sentences if x in applicable)
        self.sentences = chosen or (DEFAULT_POSITION_SENTENCES if gnss else RATE_SENTENCES if rate
                                    else DEFAULT_HEADING_SENTENCES)
        self.rate_of_turn = rate_of_turn  # a gyro that also sends its rate flags it invalid with the heading
        self.counters: Counter[str] = Counter()

    def encode(self, messages: Sequence[Message]) -> list[bytes]:
        """The sentences (with checksum and CR LF) of one sample group."""
        talker, wanted = self.talker, self.sentences
        out: list[bytes] = []
        course = next((m for m in messages if isinstance(m, CourseOverGround)), None)
        for m in messages:
            if isinstance(m, PositionFix):
                if "GGA" in wanted:
                    out.append(encode_gga(m, talker))
                if "GNS" in wanted:
                    out.append(encode_gns(m, self.gns_talker))
                if "RMC" in wanted:
                    out.append(encode_rmc(m, course, talker=talker, date_ddmmyy=DATE_DDMMYY))
            elif isinstance(m, CourseOverGround):
                if "VTG" in wanted:
                    out.append(encode_vtg(m, talker))
            elif isinstance(m, PositionErrorStats):
                if "GST" in wanted:
                    out.append(encode_gst(m, talker))
            elif isinstance(m, Heading):
                if "THS" in wanted:
                    out.append(encode_ths(m, talker))
                if "HDT" in wanted:
                    out.append(encode_hdt(m, talker))
            elif isinstance(m, RateOfTurn):
                if "ROT" in wanted:
                    out.append(encode_rot(m, talker))
            elif isinstance(m, InvalidFix):
                out.extend(self._invalid(m))
        return out

    def _invalid(self, fix: InvalidFix) -> list[bytes]:
        talker, wanted = self.talker, self.sentences
        if fix.kind == "position":
            # GNS has no "no fix" form among our encoders: a receiver configured for GNS says it in GGA.
            out = [encode_gga_no_fix(talker, fix.utc_time_s)]
            if "RMC" in wanted:
                out.append(encode_rmc_no_fix(talker, fix.utc_time_s, DATE_DDMMYY))
            return out
        if fix.kind == "rate":
            return [encode_rot(RateOfTurn(0.0), talker, valid=False)]
        out = []
        if "THS" in wanted or "HDT" not in wanted:  # HDT has no validity field: say it with THS V
            out.append(encode_ths(Heading(fix.heading_rad or 0.0), talker, mode="V"))
        if "ROT" in wanted and self.rate_of_turn:
            out.append(encode_rot(RateOfTurn(0.0), talker, valid=False))
        return out


class N2kSensorEncoder:
    """NMEA 2000 frames ``(can_id, data)`` of one sensor at its source address."""

    def __init__(self, source_address: int, *, rate_of_turn: bool = True) -> None:
        self.encoder = N2kEncoder(source_address)
        self.source_address = source_address
        self.rate_of_turn = rate_of_turn
        self.sid = 0
        self.counters: Counter[str] = Counter()

    def encode(self, messages: Sequence[Message]) -> list[tuple[int, bytes]]:
        """The CAN frames of one sample group (one sequence id per group)."""
        encoder = self.encoder
        sid = self.sid
        self.sid = (sid + 1) % 250  # 0..250; 251+ are "not available"/reserved
        frames: list[tuple[int, bytes]] = []
        for m in messages:
            if isinstance(m, PositionFix):
                frames += encoder.gnss_position(m, date_days=DATE_DAYS_SINCE_1970, sid=sid)
            elif isinstance(m, Heading):
                frames += encoder.heading(m, sid=sid)
            elif isinstance(m, RateOfTurn):
                frames += encoder.rate_of_turn(m, sid=sid)
            elif isinstance(m, CourseOverGround):
                frames += encoder.cog_sog(m, sid=sid)
            elif isinstance(m, InvalidFix):
                if m.kind == "position":
                    frames += encoder.gnss_position(None, date_days=DATE_DAYS_SINCE_1970, sid=sid)
                elif m.kind == "rate":
                    frames += encoder.rate_of_turn(None, sid=sid)
                else:
                    frames += encoder.heading(None, sid=sid)
                    if self.rate_of_turn:
                        frames += encoder.rate_of_turn(None, sid=sid)
            else:  # GST statistics have no PGN here
                self.counters["not_carried"] += 1
        return frames


class MavlinkSensorEncoder:
    """MAVLink 2 packets of one sensor, as a boat autopilot of ``system_id`` sends them.

    ``encoder`` shares an autopilot's encoder (its packet sequence numbers) between its sensors.
    """

    def __init__(self, system_id: int = 1, component_id: int = 1, signing_key: bytes | None = None, *,
                 encoder: MavlinkEncoder | None = None) -> None:
        self.encoder = encoder or MavlinkEncoder(system_id, component_id, signing_key=signing_key)
        self.counters: Counter[str] = Counter()

    def encode(self, t_s: float, messages: Sequence[Message]) -> list[bytes]:
        """The packets of one sample group (a heading and its rate go in one ATTITUDE)."""
        encoder = self.encoder
        boot_ms = int(t_s * 1000.0) % (1 << 32)
        heading = next((m for m in messages if isinstance(m, Heading)), None)
        rate = next((m for m in messages if isinstance(m, RateOfTurn)), None)
        course = next((m for m in messages if isinstance(m, CourseOverGround)), None)
        out: list[bytes] = []
        for m in messages:
            if isinstance(m, PositionFix):
                out.append(encoder.gps_raw_int(m, course=course))
            elif isinstance(m, InvalidFix):
                if m.kind == "position":
                    out.append(encoder.gps_raw_int(None, fix_type=0))
                else:
                    out.append(encoder.attitude(None, time_boot_ms=boot_ms))
            elif isinstance(m, PositionErrorStats):
                self.counters["not_carried"] += 1
        if heading is not None or rate is not None:
            yaw = None if heading is None else heading.heading_rad
            out.append(encoder.attitude(Attitude(None, None, yaw), rate=rate, time_boot_ms=boot_ms))
        return out
