"""A TI mmWave radar on its two UART ports (pyserial): configure it, then stream its frames.

The CLI port (115200 baud) takes the ``.cfg`` line by line; the radar echoes each line and
answers ``Done``, or an error (``Error -1``, ``... not recognized``). The first line it refuses
stops the configuration with the sensor's own words and the likely cause (a ``.cfg`` written
for another SDK version). The data port (921600 baud) streams frames to
:class:`~smokyslam.frontends.sensors.ti_frames.TiFrameParser`. Ports are opened with
``serial.serial_for_url``, so ``loop://``, ``socket://host:port``, ``spy://`` URLs and pty
paths work as well as ``/dev/ttyACM0``.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Iterator

from smokyslam.errors import SensorError
from smokyslam.frontends.sensors.ti_config import TiRadarConfig
from smokyslam.frontends.sensors.ti_frames import TiFrame, TiFrameParser

logger = logging.getLogger(__name__)

CLI_BAUD, DATA_BAUD = 115200, 921600
ANSWER_TIMEOUT_S = 3.0
READ_BYTES = 4096
ERROR_WORDS = ("error", "not recognized", "exception", "invalid")


class TiRadar:
    """The radar's two ports. Verbs: :meth:`configure`, :meth:`frames`, :meth:`close`."""

    def __init__(self, cli_port: str, data_port: str, read_timeout_s: float = 0.2) -> None:
        import serial

        self._serial = serial
        try:
            self._cli = serial.serial_for_url(cli_port, CLI_BAUD, timeout=read_timeout_s)
            self._data = serial.serial_for_url(data_port, DATA_BAUD, timeout=read_timeout_s)
        except (serial.SerialException, ValueError, OSError) as exc:
            raise SensorError(f"cannot open the radar's ports ({exc})") from None
        self.stopped = False

    def configure(self, config: TiRadarConfig) -> None:
        """Send every command of ``config`` and check each answer."""
        for number, line in enumerate(config.commands, start=1):
            answer = self._command(line)
            lowered = answer.lower()
            if "done" in lowered and not any(word in lowered for word in ERROR_WORDS):
                continue
            said = " ".join(answer.split()) or "nothing"
            hint = (
                "the radar did not answer: check the CLI port and that the demo firmware runs"
                if not answer.strip()
                else "the .cfg may be written for another mmWave SDK version than the firmware's"
            )
            raise SensorError(
                f"radar config line {number} '{line}' was refused: the sensor said '{said}' "
                f"({hint})"
            )
        logger.info("radar configured: %d commands", len(config.commands))

    def _command(self, line: str) -> str:
        """Send one CLI line; the answer up to ``Done`` or an error (or the timeout)."""
        try:
            self._cli.reset_input_buffer()
            self._cli.write((line + "\n").encode("ascii"))
            answer, deadline = b"", time.monotonic() + ANSWER_TIMEOUT_S
            while time.monotonic() < deadline:
                answer += self._cli.read(self._cli.in_waiting or 1)
                text = answer.decode("ascii", errors="replace")
                reply = text.replace(line, "", 1).lower()
                if "done" in reply or any(word in reply for word in ERROR_WORDS):
                    return text.replace(line, "", 1)
        except (self._serial.SerialException, OSError) as exc:
            raise SensorError(f"the radar's CLI port failed at '{line}' ({exc})") from None
        return answer.decode("ascii", errors="replace").replace(line, "", 1)

    def frames(self, parser: TiFrameParser) -> Iterator[TiFrame]:
        """Frames as they arrive, until :meth:`stop` or the sensor goes away (a disconnect
        ends the stream; the frame it cut is counted as truncated)."""
        while not self.stopped:
            try:
                data = self._data.read(READ_BYTES)
            except (self._serial.SerialException, OSError) as exc:
                logger.warning("radar data port closed: %s", exc)
                break
            if data:
                yield from parser.feed(data)
        parser.finish()

    def stop(self) -> None:
        self.stopped = True

    def close(self) -> None:
        for port in (self._cli, self._data):
            with contextlib.suppress(self._serial.SerialException, OSError):
                port.close()
