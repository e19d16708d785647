"""The shared UDP key (docs/udp.md "Shared key"): where it comes from, and the HMAC-SHA256
tag that signs a datagram and proves it."""

from __future__ import annotations

import hashlib
import hmac
import os
import struct
from pathlib import Path

from bpms.io.udp.addresses import UdpConfigError
from bpms.io.udp.codec import HEADER_SIZE

#: Header flag: a 32-byte HMAC-SHA256 tag (over header and payload) follows the payload.
FLAG_HMAC = 0x0001
TAG_SIZE = 32
#: Environment variable holding the shared UDP key (text; see docs/udp.md "Shared key").
KEY_ENV = "BPMS_UDP_KEY"


def key_from_env() -> bytes | None:
    """The shared UDP key from :data:`KEY_ENV` (UTF-8), or None when unset or empty."""
    text = os.environ.get(KEY_ENV, "")
    return text.encode("utf-8") if text else None


class UdpKeyError(UdpConfigError):
    """The configured key file cannot be read (one line, naming the file)."""


def shared_key(key_file: str = "") -> bytes | None:
    """The shared UDP key: :data:`KEY_ENV` when set, else the text of ``key_file`` (the
    options' ``udp.key_file``; surrounding white space stripped), else None (no key). A key
    file that is set but unreadable or empty raises :class:`UdpKeyError`: a receiver must not
    silently accept unauthenticated datagrams because its key went missing."""
    key = key_from_env()
    if key is not None or not key_file:
        return key
    try:
        text = Path(key_file).expanduser().read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise UdpKeyError(f"the UDP key file {key_file} cannot be read ({exc})") from None
    if not text:
        raise UdpKeyError(f"the UDP key file {key_file} is empty")
    return text.encode("utf-8")


def sign_datagram(datagram: bytes, key: bytes) -> bytes:
    """Set :data:`FLAG_HMAC` in the header and append HMAC-SHA256(key, header + payload)."""
    flags = struct.unpack_from("!H", datagram, 6)[0] | FLAG_HMAC
    body = datagram[:6] + struct.pack("!H", flags) + datagram[8:]
    return body + hmac.new(key, body, hashlib.sha256).digest()


def split_tag(data: bytes) -> tuple[bytes, bytes | None]:
    """(datagram without its tag, tag) when :data:`FLAG_HMAC` is set, else (data, None)."""
    if len(data) >= HEADER_SIZE + TAG_SIZE and struct.unpack_from("!H", data, 6)[0] & FLAG_HMAC:
        return data[:-TAG_SIZE], data[-TAG_SIZE:]
    return data, None


def tag_is_valid(body: bytes, tag: bytes | None, key: bytes) -> bool:
    """True when ``tag`` is HMAC-SHA256(key, body) (constant-time comparison)."""
    return tag is not None and hmac.compare_digest(
        tag, hmac.new(key, body, hashlib.sha256).digest())
