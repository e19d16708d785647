"""UDP addresses: ``host:port`` parsing, multicast test, and the configuration error."""

from __future__ import annotations

import ipaddress
import socket

DEFAULT_PORT = 5005


class UdpConfigError(ValueError):
    """A bad ``host:port`` target or listen address, or a socket that cannot be opened."""


def parse_address(text: str, *, default_host: str = "0.0.0.0") -> tuple[str, int]:
    """``"host:port"`` (or ``":port"`` / ``"port"``) → (dotted IPv4, port). Host names are
    resolved (IPv4 only). Raises UdpConfigError with a one-line message."""
    text = str(text).strip()
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = "", text
    host = host.strip() or default_host
    try:
        port = int(port_text)
    except ValueError:
        raise UdpConfigError(f"{text!r}: the port must be a number (host:port)") from None
    if not 0 <= port <= 65535:
        raise UdpConfigError(f"{text!r}: port {port} is out of range 0..65535")
    try:
        addr = socket.gethostbyname(host)
    except (OSError, UnicodeError) as exc:
        raise UdpConfigError(f"{text!r}: cannot resolve host {host!r} ({exc})") from None
    return addr, port


def is_multicast(host: str) -> bool:
    """True for an IPv4 multicast address (224.0.0.0/4)."""
    try:
        return ipaddress.IPv4Address(host).is_multicast
    except ValueError:
        return False
