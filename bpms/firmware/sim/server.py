"""Transports of the simulated suit: a pseudo-terminal and a TCP socket.

- :class:`PtyServer`: ``os.openpty()`` in raw mode; the host opens :attr:`~PtyServer.path`
  (``/dev/pts/N``) with pyserial like a Bluetooth SPP port. The server keeps a slave fd open
  itself, so the pty survives clients closing and reopening it. Unix only: ``tty`` is
  imported when a pty is made, never at import time.
- :class:`TcpServer`: one client at a time on 127.0.0.1, for pyserial's
  ``socket://127.0.0.1:PORT``. A client that disconnects stops the stream. Every platform.
- :func:`local_server`: whichever the platform offers (a pty where there is one, else TCP);
  :attr:`SimServer.address` is what to open with pyserial either way.

Both run the same loop (:meth:`SimServer.serve_forever`) in the foreground or in a thread
(:meth:`SimServer.start`). Nothing ever blocks for long: every wait is bounded, writes are
non-blocking, and when the host does not read, realtime frames beyond a small backlog are
dropped whole and counted (:attr:`SimServer.frames_unread`).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import socket
import threading
import time
from typing import TYPE_CHECKING

from bpms.io.frames import FRAME_SIZE

if TYPE_CHECKING:
    from bpms.firmware.sim.arbiter import Arbiter

log = logging.getLogger(__name__)

BACKLOG_BYTES = 16 * FRAME_SIZE  # bytes held for a host that does not read (≈ 0.3 s)
MAX_WAIT_S = 0.02  # longest select wait: bounds the reaction to stop()


class SimServer:
    """Runs an :class:`Arbiter` over a byte transport. Subclasses provide the file objects."""

    def __init__(self, arbiter: Arbiter) -> None:
        self.arbiter = arbiter
        self.frames_unread = 0  # realtime frames dropped because the host was not reading
        self.bytes_written = 0
        self.bytes_read = 0
        self._out = bytearray()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- transport hooks ------------------------------------------------------------------
    def _fds(self) -> list:  # pragma: no cover - abstract
        raise NotImplementedError

    def _on_readable(self, fileobj) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _write(self, data: bytes) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def _connected(self) -> bool:
        return True

    @property
    def address(self) -> str:  # pragma: no cover - abstract
        """What a host opens with pyserial: a device path or a ``socket://`` URL."""
        raise NotImplementedError

    def close(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    # -- the loop -------------------------------------------------------------------------
    def serve_forever(self) -> None:
        """Serve until :meth:`stop` (or KeyboardInterrupt in the foreground); then close."""
        try:
            while not self._stop.is_set():
                self._once()
        finally:
            self.close()

    def _once(self) -> None:
        now = time.monotonic()
        nxt = self.arbiter.next_event()
        wait = MAX_WAIT_S if nxt is None else min(max(nxt - now, 0.0), MAX_WAIT_S)
        if self._out and self._connected():
            wait = min(wait, 0.002)
        rlist = self._fds()
        try:
            readable, _, _ = select.select(rlist, [], [], wait)
        except (OSError, ValueError):
            time.sleep(wait)
            readable = []
        for f in readable:
            self._on_readable(f)
        now = time.monotonic()
        if not self._connected():
            return
        room = max((BACKLOG_BYTES - len(self._out)) // FRAME_SIZE, 0)
        chunks = self.arbiter.poll(now, None if self.arbiter.realtime else room)
        for chunk in chunks:
            if len(self._out) + len(chunk) > BACKLOG_BYTES and len(chunk) >= FRAME_SIZE - 16:
                self.frames_unread += 1
                continue
            self._out += chunk
        self._flush()

    def _flush(self) -> None:
        while self._out:
            try:
                n = self._write(bytes(self._out[:65536]))
            except BlockingIOError:
                return
            except OSError as exc:
                if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK):
                    return
                log.debug("write failed: %s", exc)
                self._out.clear()
                return
            if n <= 0:
                return
            self.bytes_written += n
            del self._out[:n]

    # -- threads --------------------------------------------------------------------------
    def start(self) -> SimServer:
        """Serve in a daemon thread; returns self."""
        self._thread = threading.Thread(target=self.serve_forever, name=type(self).__name__,
                                        daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout: float = 2.0) -> None:
        """Stop serving and close (joins the thread when there is one)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            self._thread = None

    def __enter__(self) -> SimServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


class PtyServer(SimServer):
    """The simulated suit on a pseudo-terminal; :attr:`path` is the device to open."""

    def __init__(self, arbiter: Arbiter) -> None:
        if not pty_available():
            raise OSError(errno.ENOSYS, "pseudo-terminals are not available on this system "
                                        "(use the TCP transport)")
        import tty  # Unix only: imported here so that importing this module works everywhere

        super().__init__(arbiter)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        tty.setraw(self._master)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)
        self._closed = False

    @property
    def address(self) -> str:
        return self.path

    def _fds(self) -> list:
        return [] if self._closed else [self._master]

    def _on_readable(self, fileobj) -> None:
        try:
            data = os.read(self._master, 4096)
        except BlockingIOError:
            return
        except OSError as exc:  # EIO cannot happen while we hold the slave, but be safe
            log.debug("pty read failed: %s", exc)
            return
        self.bytes_read += len(data)
        self.arbiter.receive(data, time.monotonic())

    def _write(self, data: bytes) -> int:
        return os.write(self._master, data)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class TcpServer(SimServer):
    """The simulated suit on a TCP port (one client at a time); :attr:`url` for pyserial."""

    def __init__(self, arbiter: Arbiter, port: int = 0, host: str = "127.0.0.1") -> None:
        super().__init__(arbiter)
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._listener.bind((host, port))
        self._listener.listen(1)
        self._listener.setblocking(False)
        self.host, self.port = self._listener.getsockname()[:2]
        self.url = f"socket://{self.host}:{self.port}"
        self._client: socket.socket | None = None
        self.clients = 0

    @property
    def address(self) -> str:
        return self.url

    def _connected(self) -> bool:
        return self._client is not None

    def _fds(self) -> list:
        if self._listener.fileno() < 0:
            return []
        return [self._client] if self._client is not None else [self._listener]

    def _on_readable(self, fileobj) -> None:
        if fileobj is self._listener:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            client.setblocking(False)
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._client = client
            self.clients += 1
            self._out.clear()
            return
        try:
            data = fileobj.recv(4096)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._drop_client()
            return
        self.bytes_read += len(data)
        self.arbiter.receive(data, time.monotonic())

    def _drop_client(self) -> None:
        if self._client is not None:
            with contextlib.suppress(OSError):
                self._client.close()
        self._client = None
        self._out.clear()
        self.arbiter.host_disconnected()

    def _write(self, data: bytes) -> int:
        if self._client is None:
            return 0
        try:
            return self._client.send(data)
        except (BrokenPipeError, ConnectionResetError):
            self._drop_client()
            return 0

    def close(self) -> None:
        if self._client is not None:
            self._drop_client()
        with contextlib.suppress(OSError):
            self._listener.close()


def pty_available() -> bool:
    """True where this platform offers pseudo-terminals (``os.openpty`` and ``tty``)."""
    if not hasattr(os, "openpty"):
        return False
    try:
        import tty  # noqa: F401  (termios underneath; absent on Windows)
    except ImportError:
        return False
    return True


def local_server(arbiter: Arbiter, transport: str = "auto") -> SimServer:
    """The simulated suit on a local transport, not started.

    ``transport``: ``"pty"``, ``"tcp"`` (127.0.0.1, a free port) or ``"auto"`` (a pty where
    the platform offers one, else TCP). Open :attr:`SimServer.address` with pyserial.
    Raises OSError when the transport cannot be opened.
    """
    if transport not in ("auto", "pty", "tcp"):
        raise ValueError(f"unknown transport {transport!r} (auto, pty or tcp)")
    if transport == "pty" or (transport == "auto" and pty_available()):
        return PtyServer(arbiter)
    return TcpServer(arbiter)
