"""TI mmWave UART frames: found by their magic word, checked, decoded, or dropped and counted.

A frame is a header, then type-length-value blocks (TLVs), padded to a multiple of 32 bytes:

- SDK 1.x / 2.x xWR14xx: a 36-byte header ``magic[8], version, totalPacketLen, platform,
  frameNumber, timeCpuCycles, numDetectedObj, numTLVs`` (uint32, little endian). Detected
  objects are TLV type 1: ``{uint16 numObj, uint16 xyzQFormat}`` then 12-byte records
  ``{uint16 rangeIdx, int16 dopplerIdx, uint16 peakVal, int16 x, y, z}``, metres = int /
  2^xyzQFormat, velocity = dopplerIdx x the Doppler resolution of the ``.cfg``, intensity =
  10 log10(peakVal + 1).
- SDK 3.x: a 40-byte header (``subFrameNumber`` added). Type 1 holds ``numDetectedObj`` float
  records ``{x, y, z, velocity}``; type 7 the side info ``{int16 snr, int16 noise}`` (0.1 dB),
  the intensity being the SNR in dB.

The SDK is told by the version field's major byte (or given). Points are turned into ROS axes
as ti_mmwave_rospkg does: x = sensor y (forward), y = -sensor x, z = sensor z. Velocity keeps
TI's sign (radial, positive moving away).

Robustness: a header whose length is out of bounds or whose TLVs do not fit the packet, a
type-1 block whose size disagrees with its count, or a frame cut short by the next magic word
is dropped and counted; parsing resumes at the next magic word, never waiting for bytes of a
later frame. Bytes between frames are skipped and counted. A frame with no TLV is a frame with
no detection.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from smokyslam.types import RadarScan

MAGIC = bytes([2, 1, 4, 3, 6, 5, 8, 7])
HEADER_SDK1 = struct.Struct("<8s7I")
HEADER_SDK3 = struct.Struct("<8s8I")
TLV_HEADER = struct.Struct("<2I")
MAX_PACKET_BYTES = 1 << 16
"""A packet longer than this is no UART frame of these radars (a lying header)."""
MAX_TLVS = 32
DETECTED_POINTS, SIDE_INFO = 1, 7
_SDK1_POINT = np.dtype([("range", "<u2"), ("doppler", "<i2"), ("peak", "<u2"), ("xyz", "<i2", 3)])
_SDK3_POINT = np.dtype([("xyz", "<f4", 3), ("velocity", "<f4")])
_SIDE = np.dtype([("snr", "<i2"), ("noise", "<i2")])


@dataclass(frozen=True)
class TiFrame:
    """One decoded frame: ``frame_number`` (the sensor's counter), ``sdk`` (1 or 3: the
    header it had), ``points_xyz_m`` (N, 3) in ROS axes, ``velocity_mps`` (N,) (SDK 1.x: the
    Doppler index times the resolution given to the parser), ``intensity`` (N,) dB."""

    frame_number: int
    sdk: int
    points_xyz_m: np.ndarray
    velocity_mps: np.ndarray
    intensity: np.ndarray

    def scan(self, stamp_s: float) -> RadarScan:
        """The frame as the radar scan every stage reads, stamped ``stamp_s``."""
        return RadarScan(stamp_s, self.points_xyz_m, self.intensity, self.velocity_mps)


@dataclass
class ParseStats:
    """What the parser has seen: valid ``frames``, ``dropped`` frames, ``bytes_skipped``
    between frames, and the reason of each drop (``reasons``)."""

    frames: int = 0
    dropped: int = 0
    bytes_skipped: int = 0
    reasons: dict[str, int] = field(default_factory=dict)

    def drop(self, reason: str) -> None:
        self.dropped += 1
        self.reasons[reason] = self.reasons.get(reason, 0) + 1


class _FrameDropError(Exception):
    """A frame that fails a check: its reason."""


class TiFrameParser:
    """Streaming parser: :meth:`feed` bytes as they come, get the frames they complete."""

    def __init__(self, doppler_resolution_mps: float, sdk: int | None = None) -> None:
        """``doppler_resolution_mps``: from the ``.cfg`` (SDK 1.x frames carry indices).
        ``sdk``: 1 or 3 to force a header format; None tells it by the version field."""
        self._doppler_resolution = float(doppler_resolution_mps)
        self._sdk = sdk
        self._buffer = bytearray()
        self.stats = ParseStats()

    def feed(self, data: bytes) -> list[TiFrame]:
        """Add ``data`` and return every frame it completes (in order)."""
        self._buffer += data
        frames = []
        while (frame := self._next()) is not None:
            if isinstance(frame, TiFrame):
                frames.append(frame)
        return frames

    def finish(self) -> None:
        """The stream has ended: a frame still incomplete is dropped (``truncated``)."""
        start = self._buffer.find(MAGIC)
        if start < 0:
            self.stats.bytes_skipped += len(self._buffer)
        else:
            self.stats.bytes_skipped += start
            self.stats.drop("truncated")
        self._buffer.clear()

    # ------------------------------------------------------------------ one frame

    def _next(self) -> TiFrame | bool | None:
        """The next frame (a TiFrame), True after a drop, None when more bytes are needed."""
        buffer = self._buffer
        start = buffer.find(MAGIC)
        if start < 0:
            keep = len(MAGIC) - 1  # a magic word may be cut across two reads
            self.stats.bytes_skipped += max(len(buffer) - keep, 0)
            del buffer[: max(len(buffer) - keep, 0)]
            return None
        self.stats.bytes_skipped += start
        del buffer[:start]
        if len(buffer) < HEADER_SDK3.size:
            return None
        header = HEADER_SDK1.unpack_from(buffer)
        sdk = self._sdk or (3 if header[1] >> 24 >= 3 else 1)
        layout = HEADER_SDK3 if sdk == 3 else HEADER_SDK1
        _, _, total, _, number, _, objects, tlvs, *_ = layout.unpack_from(buffer)
        following = buffer.find(MAGIC, len(MAGIC))
        if not layout.size <= total <= MAX_PACKET_BYTES or tlvs > MAX_TLVS:
            return self._drop("bad header", len(MAGIC))
        if 0 <= following < total:  # the next frame starts inside this one: cut short
            return self._drop("truncated", following)
        if len(buffer) < total:
            return None
        packet = bytes(buffer[:total])
        del buffer[:total]
        try:
            frame = self._decode(packet, layout.size, sdk, number, objects, tlvs)
        except _FrameDropError as reason:
            self.stats.drop(str(reason))
            return True
        self.stats.frames += 1
        return frame

    def _drop(self, reason: str, skip: int) -> bool:
        self.stats.drop(reason)
        del self._buffer[:skip]
        return True

    def _decode(
        self, packet: bytes, offset: int, sdk: int, number: int, objects: int, tlvs: int
    ) -> TiFrame:
        points = velocity = intensity = None
        snr = None
        for _ in range(tlvs):
            if offset + TLV_HEADER.size > len(packet):
                raise _FrameDropError("tlv past packet")
            kind, length = TLV_HEADER.unpack_from(packet, offset)
            offset += TLV_HEADER.size
            if length > len(packet) - offset:
                raise _FrameDropError("tlv past packet")
            payload = packet[offset : offset + length]
            offset += length
            if kind == DETECTED_POINTS and sdk == 1:
                points, velocity, intensity = self._sdk1_points(payload, objects)
            elif kind == DETECTED_POINTS:
                points, velocity = self._sdk3_points(payload, objects)
            elif kind == SIDE_INFO and sdk == 3:
                if length != objects * _SIDE.itemsize:
                    raise _FrameDropError("side info size")
                snr = np.frombuffer(payload, _SIDE)["snr"].astype(float) * 0.1
        if points is None:
            if objects:
                raise _FrameDropError("objects without points")
            points, velocity, intensity = np.zeros((0, 3)), np.zeros(0), np.zeros(0)
        if intensity is None:
            intensity = snr if snr is not None else np.zeros(len(points))
        ros = np.column_stack([points[:, 1], -points[:, 0], points[:, 2]])
        return TiFrame(number, sdk, ros, velocity, intensity)

    def _sdk1_points(self, payload: bytes, objects: int):
        if len(payload) < 4:
            raise _FrameDropError("points size")
        count, q_format = struct.unpack_from("<2H", payload)
        if len(payload) != 4 + count * _SDK1_POINT.itemsize or count != objects or q_format > 15:
            raise _FrameDropError("points size")
        records = np.frombuffer(payload, _SDK1_POINT, count=count, offset=4)
        xyz = records["xyz"].astype(float) / float(1 << q_format)
        velocity = records["doppler"].astype(float) * self._doppler_resolution
        return xyz, velocity, 10.0 * np.log10(records["peak"].astype(float) + 1.0)

    @staticmethod
    def _sdk3_points(payload: bytes, objects: int):
        if len(payload) != objects * _SDK3_POINT.itemsize:
            raise _FrameDropError("points size")
        records = np.frombuffer(payload, _SDK3_POINT)
        xyz, velocity = records["xyz"].astype(float), records["velocity"].astype(float)
        if not (np.isfinite(xyz).all() and np.isfinite(velocity).all()):
            raise _FrameDropError("non-finite point")
        return xyz, velocity
