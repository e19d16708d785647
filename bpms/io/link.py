"""The suit link: the host side of the arbiter protocol (docs/suit.md) over pyserial.

Layers, lowest first:

- :func:`list_candidate_ports` / :func:`discover_suit`: find the port that answers ``BPMS``;
- :class:`SuitLink`: one open port (a device path or any pyserial URL, e.g.
  ``socket://127.0.0.1:5050``) with the commands ``identify``, ``battery_volts``, ``start``,
  ``stop`` and :meth:`SuitLink.read_frames`, which returns the whole 340-byte frames parsed so
  far (:class:`bpms.io.parser.FrameParser`; its stats are the resync counters).

Every read waits at most a bounded time. Problems raise a typed :class:`LinkError` with a
one-line message: :class:`LinkTimeoutError` (nothing, or not the awaited reply, came in time),
:class:`NotASuitError` (bytes came, but neither ``BPMS`` nor frames), :class:`DeviceGoneError` (the
port cannot be opened, read or written: unplugged, out of range, connection dropped) and
:class:`LinkClosedError` (the link was closed, possibly from another thread, under a read).

The bytes move through a :class:`Transport`; :class:`SerialTransport` is pyserial's (a device
path or any URL), opened non-blocking, whose waits use ``select`` on the port's descriptor and
on a wake-up socket, so that :meth:`SuitLink.close` from any thread wakes a blocked reader at
once (where the port has no descriptor, e.g. on Windows, the wait polls every 2 ms). Tests
plug in a scripted transport.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import logging
import re
import select
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import serial
import serial.tools.list_ports

from bpms.io.closing import Closing
from bpms.io.frames import FRAME_SIZE
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


class LinkTimeoutError(LinkError):
    """The other end sent nothing (or not the awaited reply or frame) in time."""


class NotASuitError(LinkError):
    """Bytes came back, but neither ``BPMS`` nor suit frames: another device."""


class DeviceGoneError(LinkError):
    """The port cannot be opened, read or written (device removed, connection dropped)."""


class PortInUseError(DeviceGoneError):
    """Another program holds the port (it is opened for exclusive access, docs/suit.md)."""


class LinkClosedError(LinkError):
    """The link was closed (possibly by another thread) during or before the operation."""


class TransportEndedError(OSError):
    """The device is gone, and ``data`` holds the bytes the same read got before the end (a
    transport that learns of the end while reading raises this rather than dropping them)."""

    def __init__(self, message: str, data: bytes = b"") -> None:
        super().__init__(message)
        self.data = bytes(data)


class Transport(Protocol):
    """A byte pipe to the suit. ``read`` waits up to ``wait_s`` for the first bytes and
    returns b"" when none came; it raises OSError when the device is gone (with the bytes it
    had read by then in :class:`TransportEndedError`'s ``data``) and :class:`LinkClosedError`
    once closed. ``close`` may be called from any thread: it wakes a blocked ``read``, writes
    ``goodbye`` (best effort) and releases the port."""

    def read(self, wait_s: float) -> bytes: ...

    def write(self, data: bytes) -> None: ...

    def close(self, goodbye: bytes = b"") -> None: ...


class SerialTransport:
    """A pyserial port (device path or URL) as a :class:`Transport`. Thread-safe close.

    The port is opened with ``timeout=0``: each pyserial ``read`` makes one system read, so a
    call that raises on a disconnect has read nothing (the bytes before the end came in an
    earlier call, and :class:`SuitLink` keeps those). It is opened for exclusive access
    (``exclusive=True``: an advisory ``flock`` on POSIX, which every bpms takes; Windows COM
    ports are exclusive anyway): a second program that asks for it gets
    :class:`PortInUseError`, and the one holding it loses nothing."""

    def __init__(self, port: str, baud: int = DEFAULT_BAUD) -> None:
        try:
            self._ser = serial.serial_for_url(port, baudrate=baud, timeout=0,
                                              write_timeout=1.0, exclusive=True)
        except (serial.SerialException, OSError) as exc:
            if _in_use(exc):
                raise PortInUseError(f"{port} is in use by another program") from None
            raise
        self._io = threading.RLock()  # held by a read or write; close waits for it
        self._closing = False
        try:
            self._fd: int | None = self._ser.fileno()
        except (AttributeError, NotImplementedError, serial.SerialException, OSError):
            self._fd = None
        self._wake_r: socket.socket | None = None
        self._wake_w: socket.socket | None = None
        if self._fd is not None:
            self._wake_r, self._wake_w = socket.socketpair()

    def read(self, wait_s: float) -> bytes:
        with self._io:
            if self._closing:
                raise LinkClosedError("the link is closed")
            if self._fd is not None:
                waits: list[Any] = [self._fd, self._wake_r]  # (both set together)
                ready, _, _ = select.select(waits, [], [], max(wait_s, 0.0))
                if self._closing:
                    raise LinkClosedError("the link was closed during a read")
                return self._ser.read(READ_CHUNK) if self._fd in ready else b""
            deadline = time.monotonic() + wait_s
            while True:
                data = self._ser.read(READ_CHUNK)
                if data or time.monotonic() >= deadline:
                    return data
                if self._closing:
                    raise LinkClosedError("the link was closed during a read")
                time.sleep(0.002)

    def write(self, data: bytes) -> None:
        with self._io:
            if self._closing:
                raise LinkClosedError("the link is closed")
            self._ser.write(data)
            self._ser.flush()

    def close(self, goodbye: bytes = b"") -> None:
        if self._closing:
            return
        self._closing = True
        if self._wake_w is not None:
            with contextlib.suppress(OSError):
                self._wake_w.send(b"x")
        with self._io:  # the reader leaves select at once; then the port can go
            if goodbye:
                with contextlib.suppress(serial.SerialException, OSError):
                    self._ser.write(goodbye)
                    self._ser.flush()
            with contextlib.suppress(serial.SerialException, OSError):
                self._ser.close()
            for sock in (self._wake_r, self._wake_w):
                if sock is not None:
                    sock.close()


def open_serial(port: str, baud: int = DEFAULT_BAUD) -> Transport:
    """The default transport factory: :class:`SerialTransport`."""
    return SerialTransport(port, baud)


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


class SuitLink(Closing):
    """An open link to the suit. ``port``: a device path or a pyserial URL.

    ``baud`` is nominal over Bluetooth SPP; ``read_timeout_s`` bounds each
    :meth:`read_frames` wait; ``reply_timeout_s`` bounds the wait for a command's reply and
    for the first frames after :meth:`start`. ``transport``: an already open
    :class:`Transport` (default: :class:`SerialTransport` on ``port``); ``clock``: the
    monotonic clock in s used for every deadline (tests pass a scripted one).
    """

    def __init__(self, port: str, baud: int = DEFAULT_BAUD, read_timeout_s: float = 0.05,
                 reply_timeout_s: float = 1.0, *, transport: Transport | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.port = port
        self.read_timeout_s = read_timeout_s
        self.reply_timeout_s = reply_timeout_s
        self.parser = FrameParser()
        self.stats = LinkStats()
        self.streaming = False
        self._pending: list[bytes] = []  # frames parsed while waiting for something else
        self._gone: DeviceGoneError | None = None  # the end, seen after bytes still to hand
        self._synced = False  # a reply was seen since opening: the line is quiet
        self._clock = clock
        if transport is None:
            try:
                transport = open_serial(port, baud)
            except (serial.SerialException, OSError, ValueError) as exc:
                raise DeviceGoneError(f"cannot open {port}: {_reason(exc)}") from None
        self._t = transport

    # -- low level ------------------------------------------------------------------------
    def _write(self, data: bytes) -> None:
        try:
            self._t.write(data)
        except (serial.SerialException, OSError) as exc:
            self.streaming = False
            raise DeviceGoneError(f"cannot write to {self.port}: {_reason(exc)}") from None

    def _read(self, wait_s: float) -> bytes:
        """The bytes available now, waiting up to ``wait_s`` for the first ones. Bytes a
        transport read before the device went away come first; the end is raised at the next
        call (:class:`DeviceGoneError`)."""
        if self._gone is not None:
            self.streaming = False
            raise self._gone
        try:
            return self._t.read(wait_s)
        except (serial.SerialException, OSError) as exc:
            self.streaming = False  # the stream is gone with the port
            gone = DeviceGoneError(f"cannot read from {self.port}: {_reason(exc)}")
            data = getattr(exc, "data", b"")
            if data:
                self._gone = gone
                return data
            raise gone from None

    def _keep_until_gone(self, buf: bytes | bytearray, keep: bool) -> None:
        """The device went away while a command waited: frames in ``buf`` stay pending."""
        if keep and buf:
            self._pending += self.parser.feed(bytes(buf))

    def take_pending(self) -> list[bytes]:
        """Frames parsed but not yet returned (what a link that just failed still holds)."""
        out, self._pending = self._pending, []
        self.stats.frames_read += len(out)
        return out

    def _command(self, cmd: bytes, reply: re.Pattern[bytes], what: str,
                 keep_frames: bool | None = None) -> re.Match[bytes]:
        """Send ``cmd`` and wait for ``reply``. Bytes before it (frames still in flight when
        the command stopped a stream) go to the parser when streaming (or ``keep_frames``);
        the match is returned."""
        keep = self.streaming if keep_frames is None else keep_frames
        self.streaming = False
        self._write(cmd)
        buf = bytearray()
        deadline = self._clock() + self.reply_timeout_s
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
            left = deadline - self._clock()
            if left <= 0:
                frames = self.parser.feed(bytes(buf)) if keep else []
                if frames:  # the suit is streaming (it did not hear us): keep its frames
                    self._pending += frames
                    self.streaming = True
                shown = bytes(buf[-24:])
                got = f"got {len(buf)} bytes ending {shown!r}" if buf else "no answer"
                suit_like = bool(frames) or bool(FrameParser().feed(bytes(buf)))
                kind = NotASuitError if buf and not suit_like else LinkTimeoutError
                raise kind(f"{self.port} did not answer {what} within "
                           f"{self.reply_timeout_s:g} s ({got})")
            try:
                buf += self._read(min(left, 0.05))
            except DeviceGoneError:
                self._keep_until_gone(buf, keep)
                raise

    # -- commands -------------------------------------------------------------------------
    def identify(self, keep_frames: bool | None = None) -> None:
        """Send 0x02; raise :class:`LinkError` unless ``BPMS`` comes back in time. Frames
        that arrive before the reply are kept for read_frames when streaming (or
        ``keep_frames``); if they arrive but the reply does not, the stream is on."""
        self._command(CMD_IDENTIFY, re.compile(re.escape(IDENTITY)), "'BPMS'", keep_frames)

    def probe(self, grace_s: float = 0.1) -> bool:
        """Ask a silent suit whether it is there (0x02). True: it answered ``BPMS``, so it is
        idle (switched off and on, or the probe stopped its stream): it needs a start. False:
        frames came and no ``BPMS`` within ``grace_s`` after them: it streams again (the
        frames are kept for read_frames). Raises :class:`LinkTimeoutError` when nothing came
        within ``reply_timeout_s``, :class:`NotASuitError` for other bytes."""
        self._write(CMD_IDENTIFY)
        buf = bytearray()
        deadline = self._clock() + self.reply_timeout_s
        frames_at: float | None = None
        while True:
            at = buf.find(IDENTITY)
            if at >= 0:
                self._pending += self.parser.feed(bytes(buf[:at]))
                self.stats.reply_bytes_skipped += len(buf) - at - len(IDENTITY)
                self._synced = True
                self.streaming = False
                return True
            now = self._clock()
            if frames_at is None and len(buf) >= FRAME_SIZE and FrameParser().feed(bytes(buf)):
                frames_at = now
            if frames_at is not None and now - frames_at >= grace_s:
                self._pending += self.parser.feed(bytes(buf))
                self.streaming = True
                return False
            if now >= deadline and frames_at is None:
                if buf:
                    raise NotASuitError(f"{self.port} answered the probe with "
                                        f"{len(buf)} bytes that are neither BPMS nor frames")
                raise LinkTimeoutError(f"{self.port} did not answer within "
                                       f"{self.reply_timeout_s:g} s (no answer)")
            wait = min(deadline - now, 0.02) if frames_at is None else 0.02
            try:
                buf += self._read(max(wait, 0.0))
            except DeviceGoneError:
                self._keep_until_gone(buf, True)
                raise

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
        deadline = self._clock() + self.reply_timeout_s
        frames: list[bytes] = []
        while not frames:
            left = deadline - self._clock()
            if left <= 0:
                self.streaming = False
                raise LinkTimeoutError(f"{self.port} sent no frame within "
                                       f"{self.reply_timeout_s:g} s of the start command")
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
        """Stop the stream without waiting for a reply: one byte, 0x02."""
        self.streaming = False
        self._write(CMD_IDENTIFY)

    def read_frames(self, wait_s: float | None = None) -> list[bytes]:
        """Whole frames received so far (waiting up to ``wait_s``, default read_timeout_s,
        when none is ready yet), in order."""
        out, self._pending = self._pending, []
        fresh: list[bytes] = []
        try:
            if not out:
                wait = self.read_timeout_s if wait_s is None else wait_s
                fresh = self.parser.feed(self._read(wait))
            while True:  # drain what else is already there, without waiting
                more = self._read(0.0)
                if not more:
                    break
                fresh += self.parser.feed(more)
        except DeviceGoneError as exc:
            if not (out or fresh):
                raise
            self._gone = exc  # these frames came before the end: hand them over first
        if fresh and self._gone is None:
            self.streaming = True  # frames keep coming: the stream is on
        out += fresh
        self.stats.frames_read += len(out)
        return out

    def close(self, goodbye: bytes = b"") -> None:
        """Close the port, from any thread: a blocked read returns at once (raising
        :class:`LinkClosedError`). ``goodbye``: bytes to send first, best effort (``CMD_IDENTIFY``
        stops a stream)."""
        self.streaming = False
        with contextlib.suppress(serial.SerialException, OSError):
            self._t.close(goodbye)


def _in_use(exc: BaseException) -> bool:
    """True when opening failed because another program holds the port: the exclusive lock
    refused (POSIX: EWOULDBLOCK/EAGAIN from flock; EBUSY) or, on Windows, access denied to a
    COM port another program opened."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    return (code in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EBUSY)
            or "exclusively lock" in text or "Access is denied" in text)


def _reason(exc: BaseException) -> str:
    """A short reason from a pyserial/OS exception."""
    text = str(exc).strip() or type(exc).__name__
    found = re.findall(r"\[Errno \d+\] ([^:']+)", text)
    if found:
        return found[-1].strip()
    if isinstance(exc, OSError) and isinstance(exc.strerror, str) and exc.strerror:
        return exc.strerror.splitlines()[0]
    return text.splitlines()[0]
