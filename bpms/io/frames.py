"""The suit's 340-byte frame (docs/frame-format.md): constants, encoder, vectorised decoder.

Layout::

    offset  size  content
    0       2     b"$#"                 start of sentence
    2       56    cluster 0: IMU0 (18 B), IMU1 (18 B), IMU2 (18 B), error word (2 B)
    ...           clusters 1..5
    338     2     b"#$"                 end of sentence

Each IMU block is 9 big-endian int16 raw counts ``ax ay az mx my mz gx gy gz`` in the
sensor-stick (board) axes. The cluster's big-endian uint16 error word has bit ``3*slot + s``
set when sensor ``s`` (0 accel, 1 mag, 2 gyro) of IMU ``slot`` (0..2) failed in this frame.

The streaming parser lives in :mod:`bpms.io.parser`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

START = b"$#"
END = b"#$"
FRAME_SIZE = 340
N_CLUSTERS = 6
IMUS_PER_CLUSTER = 3
N_IMUS = N_CLUSTERS * IMUS_PER_CLUSTER
N_CHANNELS = 9
N_SENSORS = 3
CLUSTER_SIZE = IMUS_PER_CLUSTER * N_CHANNELS * 2 + 2
END_OFFSET = FRAME_SIZE - len(END)
FRAME_RATE_HZ = 50.0
FRAME_PERIOD_S = 1.0 / FRAME_RATE_HZ

#: IMU names in wire order (docs/suit.md).
IMU_NAMES: tuple[str, ...] = (
    "Right Leg",
    "Right Foot",
    "Right Shank",
    "Right Hand",
    "Right Arm",
    "Right Forearm",
    "Hip",
    "Neck",
    "Spine",
    "Left Hand",
    "Left Arm",
    "Left Forearm",
    "Left Leg",
    "Left Foot",
    "Left Shank",
    "Right Shoulder",
    "Left Shoulder",
    "Head",
)
SENSOR_NAMES: tuple[str, ...] = ("accel", "mag", "gyro")
CHANNEL_NAMES: tuple[str, ...] = ("ax", "ay", "az", "mx", "my", "mz", "gx", "gy", "gz")

_CLUSTER_DTYPE = np.dtype(
    [("imu", ">i2", (IMUS_PER_CLUSTER, N_CHANNELS)), ("error", ">u2")]
)
#: numpy view of one frame; ``np.frombuffer(buf, FRAME_DTYPE)`` decodes many at once.
FRAME_DTYPE = np.dtype(
    [("start", "S2"), ("clusters", _CLUSTER_DTYPE, (N_CLUSTERS,)), ("end", "S2")]
)
assert _CLUSTER_DTYPE.itemsize == CLUSTER_SIZE
assert FRAME_DTYPE.itemsize == FRAME_SIZE

#: An unsigned 16-bit word as the wire sends it (big-endian); the markers as such words.
_WIRE_WORD = np.dtype(">u2")
_START_WORD = int.from_bytes(START, "big")
_END_WORD = int.from_bytes(END, "big")

_ERROR_BITS = np.arange(IMUS_PER_CLUSTER * N_SENSORS, dtype=np.uint16)
#: ``_FLAGS_OF_WORD[w]``: the 9 flags (bit ``3·slot + sensor``) of any 16-bit error word ``w``
#: (bits 9–15 are zero by definition and ignored), so decoding a word is one table look-up.
_FLAGS_OF_WORD = ((np.arange(1 << 16, dtype=np.uint16)[:, None] >> _ERROR_BITS) & 1).astype(bool)
#: Where a frame's counts and error words are: cluster c's 27 counts start at byte
#: 2 + 56·c, its error word follows them (byte offset, strides of (frame, cluster[, count])).
_COUNTS_AT, _COUNTS_STRIDES = 2, (FRAME_SIZE, CLUSTER_SIZE, 2)
_COUNTS_PER_CLUSTER = IMUS_PER_CLUSTER * N_CHANNELS
_ERROR_AT, _ERROR_STRIDES = _COUNTS_AT + 2 * _COUNTS_PER_CLUSTER, (FRAME_SIZE, CLUSTER_SIZE)
_WIRE_COUNT = np.dtype(">i2")  # a signed count as the wire sends it (big-endian)


class FrameError(ValueError):
    """A byte string that is not a well-formed 340-byte frame."""


@dataclass(frozen=True)
class DecodedFrames:
    """N decoded frames.

    raw: int16 ``[N, 18, 9]`` raw counts per IMU (wire order), channels ``ax..gz``.
    errors: bool ``[N, 18, 3]``, True where sensor (accel, mag, gyro) of that IMU failed.
    """

    raw: np.ndarray
    errors: np.ndarray

    def __len__(self) -> int:
        return len(self.raw)


def error_words_to_flags(words: np.ndarray) -> np.ndarray:
    """Cluster error words ``[..., 6]`` (uint16) → bool flags ``[..., 18, 3]``. Other integer
    types are taken modulo 2¹⁶, as a 16-bit word; bits 9–15 are ignored."""
    words = np.asarray(words)
    if words.dtype.kind != "u" or words.dtype.itemsize != 2:  # (the wire's are already)
        words = words.astype(np.uint16)
    return _FLAGS_OF_WORD.take(words, axis=0).reshape(*words.shape[:-1], N_IMUS, N_SENSORS)


def flags_to_error_words(flags: np.ndarray) -> np.ndarray:
    """Bool flags ``[..., 18, 3]`` → cluster error words ``[..., 6]`` (uint16)."""
    flags = np.asarray(flags, dtype=bool)
    per_cluster = flags.reshape(*flags.shape[:-2], N_CLUSTERS, IMUS_PER_CLUSTER * N_SENSORS)
    weights = (np.uint16(1) << _ERROR_BITS).astype(np.uint16)
    return (per_cluster.astype(np.uint16) * weights).sum(axis=-1).astype(np.uint16)


def encode_frames(raw: np.ndarray, errors: np.ndarray | None = None) -> bytes:
    """Encode frames: raw ``[N, 18, 9]`` (or ``[18, 9]``) counts, errors ``[N, 18, 3]`` bool.

    Values are saturated to the int16 range, as the firmware does.
    """
    raw = np.asarray(raw)
    single = raw.ndim == 2
    if single:
        raw = raw[None]
    if raw.shape[1:] != (N_IMUS, N_CHANNELS):
        raise ValueError(f"raw must have shape [N, {N_IMUS}, {N_CHANNELS}], got {raw.shape}")
    n = raw.shape[0]
    out = np.zeros(n, dtype=FRAME_DTYPE)
    out["start"] = START
    out["end"] = END
    clipped = np.clip(np.rint(raw), -32768, 32767).astype(np.int16)
    out["clusters"]["imu"] = clipped.reshape(n, N_CLUSTERS, IMUS_PER_CLUSTER, N_CHANNELS)
    if errors is not None:
        errors = np.asarray(errors, dtype=bool)
        if single and errors.ndim == 2:
            errors = errors[None]
        out["clusters"]["error"] = flags_to_error_words(errors)
    return out.tobytes()


def encode_frame(raw: np.ndarray, errors: np.ndarray | None = None) -> bytes:
    """Encode one frame from raw ``[18, 9]`` counts and optional ``[18, 3]`` error flags."""
    flags = None if errors is None else np.asarray(errors)[None]
    return encode_frames(np.asarray(raw)[None], flags)


def is_frame(buf: bytes | bytearray | memoryview) -> bool:
    """True when ``buf`` is exactly 340 bytes with both markers in place."""
    return (
        len(buf) == FRAME_SIZE
        and bytes(buf[:2]) == START
        and bytes(buf[END_OFFSET:]) == END
    )


def decode_frames(buf: bytes | bytearray | memoryview | np.ndarray) -> DecodedFrames:
    """Decode a contiguous run of N whole frames in one vectorised pass (no per-frame loop).

    Raises FrameError when the length is not a multiple of 340 or any frame lacks a marker.
    """
    if isinstance(buf, np.ndarray):
        buf = np.ascontiguousarray(buf, dtype=np.uint8).tobytes()
    if len(buf) % FRAME_SIZE:
        raise FrameError(f"{len(buf)} bytes is not a whole number of {FRAME_SIZE}-byte frames")
    n = len(buf) // FRAME_SIZE
    if not n:
        return DecodedFrames(raw=np.zeros((0, N_IMUS, N_CHANNELS), np.int16),
                             errors=np.zeros((0, N_IMUS, N_SENSORS), np.bool_))
    if n == 1:  # a live frame: the markers compared as bytes
        if not is_frame(buf):
            raise FrameError("1 frame(s) lack the $#/#$ markers, first at index 0")
    else:
        start = np.ndarray((n,), _WIRE_WORD, buf, 0, (FRAME_SIZE,))
        end = np.ndarray((n,), _WIRE_WORD, buf, END_OFFSET, (FRAME_SIZE,))
        bad = np.flatnonzero((start != _START_WORD) | (end != _END_WORD))
        if bad.size:
            raise FrameError(f"{bad.size} frame(s) lack the $#/#$ markers, first at index "
                             f"{bad[0]}")
    # Strided views of the counts and the error words straight on the bytes (a frame is the
    # start marker, 6 clusters of 27 big-endian counts and an error word, the end marker): a
    # live frame pays each numpy call's fixed cost, so as few calls as possible.
    counts = np.ndarray((n, N_CLUSTERS, _COUNTS_PER_CLUSTER), _WIRE_COUNT, buf, _COUNTS_AT,
                        _COUNTS_STRIDES)
    words = np.ndarray((n, N_CLUSTERS), _WIRE_WORD, buf, _ERROR_AT, _ERROR_STRIDES)
    return DecodedFrames(raw=counts.astype(np.int16).reshape(n, N_IMUS, N_CHANNELS),
                         errors=error_words_to_flags(words))


def decode_frame(frame: bytes | bytearray | memoryview) -> DecodedFrames:
    """Decode one frame; the result has N = 1."""
    if len(frame) != FRAME_SIZE:
        raise FrameError(f"a frame is {FRAME_SIZE} bytes, got {len(frame)}")
    return decode_frames(frame)


def describe_errors(flags: np.ndarray) -> list[str]:
    """Human-readable list of failed sensors for one frame's ``[18, 3]`` flags."""
    imus, sensors = np.nonzero(flags)
    pairs = zip(imus, sensors, strict=True)
    return [f"IMU {i} ({IMU_NAMES[i]}) {SENSOR_NAMES[s]}" for i, s in pairs]
