"""What a live session reports: :class:`LiveStatus` and its :class:`RecordingStatus`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from bpms.io.events import SourceStatus
from bpms.io.options import FilterOptions
from bpms.pipeline.health import health_text


@dataclass
class RecordingStatus:
    raw_path: Path | None = None
    filtered_path: Path | None = None
    raw_records: int = 0  # handed to the file
    raw_bytes: int = 0
    raw_received: int = 0  # frames given to the raw logger
    raw_on_disk: int = 0  # records known to be on the disk (at the end: what a reader finds)
    raw_lost: int = 0  # at the end: received but not on the disk
    filtered_rows: int = 0
    error: str | None = None  # a write error: shown (in red) until logging stops
    filtered_stopped: str | None = None  # set by the raw logger: the disk reserve is reached


@dataclass
class LiveStatus:
    """A snapshot for status lines and the GUI (all counts since the session started)."""

    source: SourceStatus
    running: bool
    rate_hz: float
    frames: int
    processed: int
    error_bits: int
    dropped: int  # display_skipped + not_filtered (both kinds of loss; see below)
    processing_backlog: int  # frames waiting for the processing thread
    recording: RecordingStatus | None
    forwarding: list[str] = field(default_factory=list)
    forwarded: int = 0  # datagrams sent (RAW frames, POSE, ZERO), one per target
    forwarded_poses: int = 0  # those of ``forwarded`` that are POSE datagrams
    forward_errors: int = 0
    forward_refused: int = 0  # datagrams a target refused: nobody listening there (not errors)
    latency_p99_ms: float = 0.0
    events: list[str] = field(default_factory=list)  # recent notable events, newest last
    reinit_count: int = 0  # filter re-initialisations by the state guard (all IMUs)
    # bpms.pipeline.health: frames received (recorded raw) but never filtered (holes in the
    # filtered file, each marked), and processed samples a slow display did not take.
    not_filtered: int = 0
    display_skipped: int = 0
    holes_marked: int = 0
    #: What produced the numbers, from the processor itself: the Reset Zero in force
    #: (``PoseCalibrator.state_text``), the calibration's and options' sources, the filter.
    reset_zero: str = ""
    calibration_source: str = ""
    options_source: str = ""
    filter_name: str = ""
    #: The filter and its settings in force, the processor's own (``options.filter``: it
    #: replaces the object at each change, never edits it), what the GUI's panel shows.
    filter_settings: FilterOptions | None = None
    #: changes queued and not yet applied (``filter_settings`` may be about to change)
    settings_pending: int = 0
    event_warnings: list[str] = field(default_factory=list)  # those of ``events`` that warn

    def health_line(self) -> str:
        """``not filtered N  backlog B  display skipped M`` (capitals when frames are lost)."""
        return health_text(self.not_filtered, self.processing_backlog, self.display_skipped)
