"""The suit link's states and its one transition function (docs/pipeline.md, "The suit link").

::

    connecting --opened--> streaming --quiet--> silent --frames / restarted--> streaming
        |                     |                    |
        |                     +--gone--> gone --retry--> reopening --opened--> streaming
        |                                 ^                  |
        +--opened_idle--> stopped         +---open_failed----+

- **connecting**: no port yet (first connection).
- **streaming**: frames flow.
- **silent**: the port is open but no byte came for ``link_lost_after_s`` (out of Bluetooth
  range, suit switched off). The port keeps listening, so a suit that streams again is taken
  at once; every ``retry_s`` the suit is probed (``0x02``): a ``BPMS`` answer means it was
  power-cycled and is idle, so the stream is started again (its stale first frame dropped).
- **gone**: the port failed (device removed, TCP connection dropped); it is closed and
  reopened every ``retry_s`` (**reopening** while an attempt runs).
- **stopped**: Stop Data: the link is open and quiet by request; no watchdog.
- **closed**: for good.

:func:`next_state` is pure: the link code reports an event, the table says where it goes.
"""

from __future__ import annotations

from enum import Enum, StrEnum


class LinkState(StrEnum):
    CONNECTING = "connecting"
    STREAMING = "streaming"
    SILENT = "silent"
    GONE = "gone"
    REOPENING = "reopening"
    STOPPED = "stopped"
    CLOSED = "closed"


class LinkEvent(Enum):
    OPENED = "opened"  # port open, suit identified, stream started
    OPENED_IDLE = "opened idle"  # port open, suit identified, stream not wanted
    OPEN_FAILED = "open failed"
    FRAMES = "frames"  # frames arrived
    QUIET = "quiet"  # no byte for link_lost_after_s
    PROBE_UNANSWERED = "probe unanswered"  # the suit is still away
    RESTARTED = "restarted"  # the probe was answered (power-cycled suit): stream restarted
    DEVICE_GONE = "device gone"  # read/write error
    RETRY = "retry"  # time to reopen a gone port
    STOP = "stop"  # Stop Data applied
    START = "start"  # Start Data applied, stream started
    START_FAILED = "start failed"  # Start Data applied, the suit did not stream
    CLOSE = "close"


S, E = LinkState, LinkEvent

TRANSITIONS: dict[tuple[LinkState, LinkEvent], LinkState] = {
    (S.CONNECTING, E.OPENED): S.STREAMING,
    (S.CONNECTING, E.OPENED_IDLE): S.STOPPED,
    (S.CONNECTING, E.OPEN_FAILED): S.CONNECTING,
    (S.STREAMING, E.FRAMES): S.STREAMING,
    (S.STREAMING, E.QUIET): S.SILENT,
    (S.STREAMING, E.DEVICE_GONE): S.GONE,
    (S.STREAMING, E.STOP): S.STOPPED,
    (S.SILENT, E.FRAMES): S.STREAMING,
    (S.SILENT, E.PROBE_UNANSWERED): S.SILENT,
    (S.SILENT, E.RESTARTED): S.STREAMING,
    (S.SILENT, E.DEVICE_GONE): S.GONE,
    (S.SILENT, E.STOP): S.STOPPED,
    (S.GONE, E.RETRY): S.REOPENING,
    (S.REOPENING, E.OPENED): S.STREAMING,
    (S.REOPENING, E.OPENED_IDLE): S.STOPPED,
    (S.REOPENING, E.OPEN_FAILED): S.GONE,
    (S.STOPPED, E.FRAMES): S.STOPPED,  # frames still in flight after Stop Data
    (S.STOPPED, E.START): S.STREAMING,
    (S.STOPPED, E.START_FAILED): S.SILENT,
    (S.STOPPED, E.DEVICE_GONE): S.GONE,
}
for _state in LinkState:
    if _state is not S.CLOSED:
        TRANSITIONS[(_state, E.CLOSE)] = S.CLOSED
del _state


class TransitionError(RuntimeError):
    """An event that cannot happen in a state (a programming error, not a link fault)."""


def next_state(state: LinkState, event: LinkEvent) -> LinkState:
    """The state after ``event`` in ``state``. Raises :class:`TransitionError` for an event
    the table does not allow there."""
    try:
        return TRANSITIONS[(state, event)]
    except KeyError:
        raise TransitionError(f"link event {event.value!r} in state {state.value!r}") from None


#: States in which the link counts as lost (status lines, links_lost counter).
LOST_STATES = frozenset({S.SILENT, S.GONE, S.REOPENING})
