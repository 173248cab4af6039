"""TI mmWave UART frames made by hand (SDK 1.x/2.x xWR14xx and SDK 3.x), written independently
of the parser from the byte layout in TI's SDK docs."""

import struct

import numpy as np

MAGIC = bytes([2, 1, 4, 3, 6, 5, 8, 7])
SDK1_VERSION = 0x01020000
SDK3_VERSION = 0x03050004


def _packet(header: bytes, tlvs: list[tuple[int, bytes]]) -> bytes:
    body = b"".join(struct.pack("<2I", kind, len(payload)) + payload for kind, payload in tlvs)
    return header + body


def _pad(length: int) -> int:
    return (length + 31) // 32 * 32


def sdk1_frame(
    number: int,
    xyz_sensor_m: np.ndarray,
    doppler_idx: np.ndarray,
    peak: np.ndarray | None = None,
    q_format: int = 9,
    tlv_count: int | None = None,
) -> bytes:
    """A 36-byte-header frame with one type-1 TLV (none when there are no points)."""
    xyz = np.round(np.asarray(xyz_sensor_m, float).reshape(-1, 3) * (1 << q_format))
    n = len(xyz)
    peak = np.full(n, 1000) if peak is None else np.asarray(peak)
    records = b"".join(
        struct.pack("<HhH3h", 10 + i, int(doppler_idx[i]), int(peak[i]), *map(int, xyz[i]))
        for i in range(n)
    )
    tlvs = [(1, struct.pack("<2H", n, q_format) + records)] if n else []
    body_len = sum(8 + len(p) for _, p in tlvs)
    total = _pad(36 + body_len)
    count = len(tlvs) if tlv_count is None else tlv_count
    header = MAGIC + struct.pack("<7I", SDK1_VERSION, total, 0x1443, number, 0, n, count)
    packet = _packet(header, tlvs)
    return packet + bytes(total - len(packet))


def sdk3_frame(
    number: int, xyz_sensor_m: np.ndarray, velocity_mps: np.ndarray, snr_db: np.ndarray
) -> bytes:
    """A 40-byte-header frame: float points (type 1) and side info (type 7)."""
    xyz = np.asarray(xyz_sensor_m, float).reshape(-1, 3)
    n = len(xyz)
    points = b"".join(struct.pack("<4f", *xyz[i], velocity_mps[i]) for i in range(n))
    side = b"".join(struct.pack("<2h", round(float(snr_db[i]) * 10), 50) for i in range(n))
    tlvs = [(1, points), (7, side)] if n else []
    body_len = sum(8 + len(p) for _, p in tlvs)
    total = _pad(40 + body_len)
    header = MAGIC + struct.pack("<8I", SDK3_VERSION, total, 0x1843, number, 0, n, len(tlvs), 0)
    packet = _packet(header, tlvs)
    return packet + bytes(total - len(packet))


def scene_points(
    number: int, rng: np.random.Generator, n: int = 12
) -> tuple[np.ndarray, np.ndarray]:
    """Sensor-frame points (x right, y forward) of a wall ahead, and Doppler indices."""
    x = rng.uniform(-2.0, 2.0, n)
    y = 3.0 - 0.05 * number + rng.normal(0.0, 0.01, n)
    z = rng.uniform(-0.3, 0.3, n)
    return np.column_stack([x, y, z]), rng.integers(-3, 4, n)
