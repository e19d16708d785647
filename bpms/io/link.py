"""The suit link: the host side of the arbiter protocol (docs/suit.md) over pyserial.

Layers, lowest first:

- :func:`list_candidate_ports` / :func:`discover_suit`: find the port that answers ``BPMS``;
- :class:`SuitLink`: one open port (a device path or any pyserial URL, e.g.
  ``socket://127.0.0.1:5050``) with the commands ``identify``, ``battery_volts``, ``start``,
  ``stop`` and :meth:`SuitLink.read_frames`, which returns the whole 340-byte frames parsed so
  far (:class:`bpms.io.parser.FrameParser`; its stats are the resync counters).

Every read waits at most a bounded time. Problems raise :class:`LinkError` with a one-line
message. The port is opened non-blocking (pyserial ``timeout=0``) and waits use ``select`` on
its file descriptor, which works for serial devices, pseudo-terminals and sockets alike.
"""

from __future__ import annotations

import contextlib
import glob
import logging
import re
import select
import time
from dataclasses import dataclass

import serial
import serial.tools.list_ports

from bpms.io.parser import FrameParser

log = logging.getLogger(__name__)

CMD_START = b"\x00"
CMD_BATTERY = b"\x01"
CMD_IDENTIFY = b"\x02"
IDENTITY = b"BPMS"
BATTERY_REPLY = re.compile(rb"V(\d{1,2}\.\d{1,3})\r?\n")
DEFAULT_BAUD = 1_000_000
READ_CHUNK = 65536


class LinkError(Exception):
    """A suit-link problem, with a one-line message for the user."""


def describe_candidate_ports() -> list[tuple[str, str]]:
    """``(device, description)`` of every serial port that may lead to the suit: pyserial's
    list (``COMn`` on Windows, ``/dev/cu.*`` on macOS, USB and Bluetooth ports on Linux) plus
    Linux's ``/dev/rfcomm*`` Bluetooth bindings, which pyserial does not list."""
    ports = [(p.device, p.description if p.description not in (None, "", "n/a") else "")
             for p in serial.tools.list_ports.comports()]
    extra = sorted(glob.glob("/dev/rfcomm*")) + sorted(glob.glob("/dev/cu.*"))
    for path in extra:
        if path not in (d for d, _ in ports):
            ports.append((path, "Bluetooth serial port" if "rfcomm" in path else ""))
    return ports


def list_candidate_ports() -> list[str]:
    """The devices of :func:`describe_candidate_ports`."""
    return [device for device, _ in describe_candidate_ports()]


def discover_suit(candidates: list[str] | None = None, timeout_s: float = 1.0,
                  baud: int = DEFAULT_BAUD) -> str | None:
    """The first port among ``candidates`` (default :func:`list_candidate_ports`) that answers
    0x02 with ``BPMS`` within ``timeout_s``; None when none does. Ports that cannot be opened
    or do not answer are skipped (logged)."""
    for port in list_candidate_ports() if candidates is None else candidates:
        try:
            with SuitLink(port, baud=baud, reply_timeout_s=timeout_s) as link:
                link.identify()
        except LinkError as exc:
            log.info("discovery: %s", exc)
            continue
        return port
    return None


@dataclass
class LinkStats:
    """Counters of a :class:`SuitLink` (the parser keeps the frame/resync counters)."""

    starts: int = 0
    stale_discarded: int = 0  # first frames after a start, dropped (docs/suit.md)
    frames_read: int = 0  # frames returned by read_frames
    reply_bytes_skipped: int = 0  # bytes before/after a reply that were not part of it


class SuitLink:
    """An open link to the suit. ``port``: a device path or a pyserial URL.

    ``baud`` is nominal over Bluetooth SPP; ``read_timeout_s`` bounds each
    :meth:`read_frames` wait; ``reply_timeout_s`` bounds the wait for a command's reply and
    for the first frames after :meth:`start`.
    """

    def __init__(self, port: str, baud: int = DEFAULT_BAUD, read_timeout_s: float = 0.05,
                 reply_timeout_s: float = 1.0) -> None:
        self.port = port
        self.read_timeout_s = read_timeout_s
        self.reply_timeout_s = reply_timeout_s
        self.parser = FrameParser()
        self.stats = LinkStats()
        self.streaming = False
        self._pending: list[bytes] = []  # frames parsed while waiting for something else
        self._synced = False  # a reply was seen since opening: the line is quiet
        try:
            self._ser = serial.serial_for_url(port, baudrate=baud, timeout=0, write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkError(f"cannot open {port}: {_reason(exc)}") from None

    # -- low level ------------------------------------------------------------------------
    def _write(self, data: bytes) -> None:
        try:
            self._ser.write(data)
            self._ser.flush()
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"cannot write to {self.port}: {_reason(exc)}") from None

    def _read(self, wait_s: float) -> bytes:
        """The bytes available now, waiting up to ``wait_s`` for the first ones."""
        try:
            try:
                fd = self._ser.fileno()
            except (AttributeError, NotImplementedError, serial.SerialException):
                fd = None
            if fd is not None:
                ready, _, _ = select.select([fd], [], [], max(wait_s, 0.0))
                if not ready:
                    return b""
                return self._ser.read(READ_CHUNK)
            deadline = time.monotonic() + wait_s
            while True:
                data = self._ser.read(READ_CHUNK)
                if data or time.monotonic() >= deadline:
                    return data
                time.sleep(0.002)
        except (serial.SerialException, OSError) as exc:
            self.streaming = False  # the stream is gone with the port
            raise LinkError(f"cannot read from {self.port}: {_reason(exc)}") from None

    def _command(self, cmd: bytes, reply: re.Pattern[bytes], what: str,
                 keep_frames: bool | None = None) -> re.Match[bytes]:
        """Send ``cmd`` and wait for ``reply``. Bytes before it (frames still in flight when
        the command stopped a stream) go to the parser when streaming (or ``keep_frames``);
        the match is returned."""
        keep = self.streaming if keep_frames is None else keep_frames
        self.streaming = False
        self._write(cmd)
        buf = bytearray()
        deadline = time.monotonic() + self.reply_timeout_s
        while True:
            match = reply.search(buf)
            if match:
                before = bytes(buf[: match.start()])
                if keep:
                    self._pending += self.parser.feed(before)
                else:
                    self.stats.reply_bytes_skipped += len(before)
                self.stats.reply_bytes_skipped += len(buf) - match.end()
                self._synced = True
                return match
            left = deadline - time.monotonic()
            if left <= 0:
                frames = self.parser.feed(bytes(buf)) if keep else []
                if frames:  # the suit is streaming (it did not hear us): keep its frames
                    self._pending += frames
                    self.streaming = True
                shown = bytes(buf[-24:])
                got = f"got {len(buf)} bytes ending {shown!r}" if buf else "no answer"
                raise LinkError(f"{self.port} did not answer {what} within "
                                f"{self.reply_timeout_s:g} s ({got})")
            buf += self._read(min(left, 0.05))

    # -- commands -------------------------------------------------------------------------
    def identify(self, keep_frames: bool | None = None) -> None:
        """Send 0x02; raise :class:`LinkError` unless ``BPMS`` comes back in time. Frames
        that arrive before the reply are kept for read_frames when streaming (or
        ``keep_frames``); if they arrive but the reply does not, the stream is on."""
        self._command(CMD_IDENTIFY, re.compile(re.escape(IDENTITY)), "'BPMS'", keep_frames)

    def battery_volts(self) -> float:
        """Send 0x01 and return the battery voltage, V (reply ``V3.27\\n``)."""
        match = self._command(CMD_BATTERY, BATTERY_REPLY, "a battery reading")
        return float(match.group(1))

    def start(self) -> None:
        """Send 0x00 and discard the first (stale) frame; later frames go to read_frames.

        On a freshly opened link, an identify round trip comes first, so that frames of a
        stream left running by a previous host cannot pass for this stream's first frame."""
        if not self._synced:
            self.identify()
        self._write(CMD_START)
        self.streaming = True
        self.stats.starts += 1
        deadline = time.monotonic() + self.reply_timeout_s
        frames: list[bytes] = []
        while not frames:
            left = deadline - time.monotonic()
            if left <= 0:
                self.streaming = False
                raise LinkError(f"{self.port} sent no frame within {self.reply_timeout_s:g} s "
                                "of the start command")
            frames = self.parser.feed(self._read(min(left, 0.05)))
        self.stats.stale_discarded += 1
        self._pending += frames[1:]

    def stop(self) -> None:
        """Stop the stream: send 0x02 (any byte stops it) and wait for its ``BPMS`` reply, so
        that the frames still in flight are parsed (kept for read_frames) and the line is
        quiet afterwards."""
        self._command(CMD_IDENTIFY, re.compile(re.escape(IDENTITY)), "the stop command",
                      keep_frames=True)

    def send_stop(self) -> None:
        """Stop the stream without waiting for a reply (for shutting down): one byte, 0x02."""
        self.streaming = False
        self._write(CMD_IDENTIFY)

    def read_frames(self, wait_s: float | None = None) -> list[bytes]:
        """Whole frames received so far (waiting up to ``wait_s``, default read_timeout_s,
        when none is ready yet), in order."""
        out, self._pending = self._pending, []
        fresh: list[bytes] = []
        if not out:
            wait = self.read_timeout_s if wait_s is None else wait_s
            fresh = self.parser.feed(self._read(wait))
        while True:  # drain what else is already there, without waiting
            more = self._read(0.0)
            if not more:
                break
            fresh += self.parser.feed(more)
        if fresh:
            self.streaming = True  # frames keep coming: the stream is on
        out += fresh
        self.stats.frames_read += len(out)
        return out

    def close(self) -> None:
        """Close the port (does not send anything)."""
        with contextlib.suppress(serial.SerialException, OSError):
            self._ser.close()

    def __enter__(self) -> SuitLink:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _reason(exc: BaseException) -> str:
    """A short reason from a pyserial/OS exception."""
    text = str(exc).strip() or type(exc).__name__
    found = re.findall(r"\[Errno \d+\] ([^:']+)", text)
    if found:
        return found[-1].strip()
    if isinstance(exc, OSError) and isinstance(exc.strerror, str) and exc.strerror:
        return exc.strerror.splitlines()[0]
    return text.splitlines()[0]
