"""TI mmWave UART frames written, SDK 1.x/2.x xWR14xx layout (``ti_frames.py`` reads them):
for the parser's benchmark and for a fake sensor."""

from __future__ import annotations

import numpy as np

from smokyslam.frontends.sensors.ti_frames import _SDK1_POINT, HEADER_SDK1, MAGIC, TLV_HEADER

SDK1_VERSION = 0x01020000


def encode_sdk1_frame(
    number: int,
    xyz_sensor_m: np.ndarray,
    doppler_idx: np.ndarray,
    peak: np.ndarray,
    q_format: int = 9,
) -> bytes:
    """One frame: ``xyz_sensor_m`` (N, 3) in sensor axes, ``doppler_idx`` and ``peak`` (N,);
    a type-1 TLV when N > 0, padded to a multiple of 32 bytes."""
    xyz = np.asarray(xyz_sensor_m, dtype=float).reshape(-1, 3)
    records = np.zeros(len(xyz), _SDK1_POINT)
    records["range"] = np.round(np.linalg.norm(xyz, axis=1) * 20)
    records["doppler"] = doppler_idx
    records["peak"] = peak
    records["xyz"] = np.round(xyz * (1 << q_format))
    tlvs = b""
    if len(xyz):
        payload = np.array([len(xyz), q_format], "<u2").tobytes() + records.tobytes()
        tlvs = TLV_HEADER.pack(1, len(payload)) + payload
    total = (HEADER_SDK1.size + len(tlvs) + 31) // 32 * 32
    header = HEADER_SDK1.pack(
        MAGIC, SDK1_VERSION, total, 0x1443, number, 0, len(xyz), 1 if len(xyz) else 0
    )
    return (header + tlvs).ljust(total, b"\0")
