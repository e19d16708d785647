"""A live session: source → acquisition thread → processing thread → consumers.

Threads and queues (docs/pipeline.md has the picture):

- **acquisition** reads the source, forwards raw frames over UDP (non-blocking sends) and hands
  each frame to the raw logger and to the processing thread. It never waits on a consumer.
- **raw logger** writes raw records from an unbounded queue (raw data are never dropped; the
  writer syncs to disk at least once per second). A write error (disk full, folder gone)
  stops the recording with a message; streaming goes on.
- **processing** runs the filter bank, Reset Zero, joints and the body model
  (:class:`bpms.filter.processor.BodyPoseProcessor`), writes the filtered file, forwards the
  pose over UDP and publishes a :class:`PoseSample` to every subscriber's bounded mailbox (a
  slow subscriber loses its oldest samples, counted; it never blocks anything).

Commands (Reset Zero, gains, logging) may come from any thread; those touching the processor
run in the processing thread between two frames. Every notable event goes through one source,
:attr:`LiveSession.events` (:mod:`bpms.pipeline.events`), to the recording, log and LSL.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import queue
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from bpms.io.event_types import Alignment, Change, FilterChoice, Filters, Gains, Logging, Text
from bpms.io.events import FrameEvent, FrameSource
from bpms.io.filtered_file.writer import FilteredWriter
from bpms.io.frames import decode_frames
from bpms.io.naming import RecordingNamer
from bpms.io.options import Options
from bpms.io.rawfile import RawWriter, new_header
from bpms.io.session_events import SessionEvent
from bpms.io.timebase import stream_time
from bpms.io.udp.auth import shared_key
from bpms.io.udp.sender import UdpForwarder
from bpms.pipeline.events import SessionEvents
from bpms.pipeline.fanout import Fanout, Subscription
from bpms.pipeline.filtered_log import FilteredLog
from bpms.pipeline.handoff import Handoff
from bpms.pipeline.health import (
    MAX_BACKLOG_FRAMES,
    PipelineHealth,
)
from bpms.pipeline.pose_stream import ZeroForwarding, forward_poses
from bpms.pipeline.rate import RateMeter
from bpms.pipeline.raw_logger import RawLogger
from bpms.pipeline.sample import PoseSample
from bpms.pipeline.settings_queue import SettingsQueue
from bpms.pipeline.status import LiveStatus, RecordingStatus
from bpms.pipeline.steady import prepare_live_path

if TYPE_CHECKING:  # the filter (numba) loads with the first session, not with the GUI window
    from bpms.filter.processor import BodyPoseProcessor

log = logging.getLogger(__name__)
_STOP = object()


class LiveSession:
    """Runs a :class:`FrameSource` through the pipeline until :meth:`stop`.

    ``processor``: a BodyPoseProcessor (built from ``options`` and the user's default
    calibration, else the factory one, when None). The processor's calibration and options are
    written into raw recordings' headers. Settings changes go through :attr:`settings`
    (:class:`bpms.pipeline.settings_queue.SettingsQueue`).
    """

    def __init__(self, source: FrameSource, options: Options | None = None,
                 processor: BodyPoseProcessor | None = None, *,
                 recording_dir: str | Path | None = None, notes: str = "",
                 max_backlog: int = MAX_BACKLOG_FRAMES) -> None:
        self.source = source
        if options is None:
            from bpms.io.defaults import default_options

            options = default_options(announce=False)  # the user's default, else factory
        self.options = options
        if processor is None:
            from bpms.filter.processor import BodyPoseProcessor

            processor = BodyPoseProcessor(options=self.options)
        self.processor = processor
        processor.load_kernels()  # compiled/loaded before any frame is accepted, not in frame 1
        self.settings = SettingsQueue()
        self._reinit_seen = 0
        self._reinit_noted = -1e9
        self._reinit_imus: set[int] = set()
        self.notes = notes
        #: more header fields of the next raw recordings (``subject``: docs/subject.md)
        self.header_extra: dict = {}
        self._posture: dict | None = None  # a declared posture waiting for its capture
        self._adopting: tuple[str, dict] | None = None  # a zero adopted: (source, its data)
        self._functional = None  # a live functional calibration collecting its frames
        self.functional_report = None  # the last functional calibration's quality (a report)
        self._namer = RecordingNamer(recording_dir or self.options.logging.directory,
                                     self.options.logging.name)
        self._fanout: Fanout[PoseSample] = Fanout()
        self._proc_queue: Handoff[FrameEvent | object] = Handoff(max_backlog)
        self.health = PipelineHealth()
        self._commands: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()
        self._feed_lock = threading.Lock()  # the raw logger in force, for each frame handed over
        self._rate = RateMeter()
        self._frames = 0
        self._processed = 0
        self._error_bits = 0
        self._latencies: list[float] = []
        #: the session's one source of events (raw file, event log, LSL)
        self.events = SessionEvents(processor.options.filter.dt)
        self._zero_wait_noted = False
        self._own_zero = False  # the user pressed Reset Zero: a sender's zero is not followed
        self._zero_forwarding = ZeroForwarding()
        self._raw_logger: RawLogger | None = None
        self._filtered = FilteredLog(self.health, lambda: self.processor.options.filter.dt,
                                     self.options.logging.flush_interval_s, self.note)
        self._recording: RecordingStatus | None = None
        self._forwarder: UdpForwarder | None = None

    # -- life cycle ---------------------------------------------------------------------
    def start(self) -> None:
        # Hand the GIL over within 0.5 ms instead of CPython's 5 ms, so a frame never waits
        # long for a busy thread (logger, GUI) to let the processing thread run.
        sys.setswitchinterval(min(sys.getswitchinterval(), 0.0005))
        for target, name in ((self._acquire, "bpms-acquisition"),
                             (self._process_loop, "bpms-processing")):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the threads, close the source, the recordings and the forwarder."""
        self._stop.set()
        self.source.close()
        for thread in self._threads:
            thread.join(timeout)
        self._threads.clear()
        self.stop_logging()
        self.stop_forwarding()

    @property
    def running(self) -> bool:
        return any(t.is_alive() for t in self._threads)

    def __enter__(self) -> LiveSession:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def note(self, message: str) -> None:
        """Record a notable event (a warning: logged, kept for the status display, written
        into the raw recording)."""
        self.events.note(message)

    # -- consumers ------------------------------------------------------------------------
    def subscribe(self, maxlen: int = 500, lossless: bool = False
                  ) -> Subscription[PoseSample]:
        """A bounded mailbox of every processed frame from now on. ``lossless``: when the
        source can wait (a recording played), the processing waits for room instead of
        dropping (the network streams of a replay: one sample per frame at every speed)."""
        return self._fanout.subscribe(maxlen, lossless and self.source_can_wait)

    @property
    def source_can_wait(self) -> bool:
        """The source is a recording (it waits for the processing instead of losing frames)."""
        return bool(getattr(self.source, "can_wait", False))

    def unsubscribe(self, sub: Subscription[PoseSample]) -> None:
        self._fanout.unsubscribe(sub)

    # -- commands -------------------------------------------------------------------------
    def reset_zero(self, source: str = "manual") -> None:
        """Reset Zero at the next processed frame (docs/body-model.md); ``source``: who asked
        (``manual``, ``3d-view``), written with the capture into the recording. From then on a
        UDP sender's Reset Zero is no longer followed: the user's own one holds."""
        self._own_zero = True
        self.settings.reset_zero(source)

    def calibrate_posture(self, posture: dict[str, float]) -> None:
        """Declared-posture pose calibration (docs/pose-calibration.md): Reset Zero at the next
        frame (source ``posture``), then, from the next batch of frames (the next frame, live),
        the zero that gives the declared ``posture`` (ISB joint angles, degrees) in that
        window, adopted and recorded as a ``reset_zero`` event (``adopt``, its ``R0``), so
        ``bpms filter`` of the recording repeats it."""
        self._posture = dict(posture)
        self.reset_zero("posture")

    def _adopt_posture(self, zero) -> None:
        """After the ``posture`` capture ``zero``: adopt its declared-posture zero."""
        from bpms.filter.posture_calibration import posture_zero

        posture, self._posture = self._posture, None
        R0, yaw0 = posture_zero(zero.R0, posture)
        self.processor.pose.adopt(R0, yaw0, "posture", zero.window)
        # its event, when it takes effect, says it was adopted
        self._adopting = ("posture", {"adopt": True, "heading": "mean", "posture": posture})

    def calibrate_functional(self, seconds: float = 30.0, still_s: float = 0.5) -> None:
        """Functional pose calibration (docs/pose-calibration.md): from the next frame,
        ``still_s`` s still, then ``seconds`` s of movements; then its zero is adopted and
        recorded (``reset_zero``, source ``functional``, ``adopt``, its quality)."""
        from bpms.pipeline.functional_live import FunctionalCollector

        dt = self.processor.options.filter.dt
        collector = FunctionalCollector(round(still_s / dt), round(seconds / dt), dt)
        self._commands.put(lambda: setattr(self, "_functional", collector))

    def finish_functional(self) -> None:
        """End the functional calibration's movements now (the GUI's Stop): it is made from
        the frames so far at the next frame; stopped within its still window, it is dropped."""
        def finish() -> None:
            if self._functional is not None and not self._functional.finish():
                self._functional = None
                self.note("functional calibration cancelled: stopped before the movements")
        self._commands.put(finish)

    @property
    def functional_progress(self) -> tuple[int, int] | None:
        """(frames collected, frames wanted) of a functional calibration under way, else None."""
        collector = self._functional
        return None if collector is None else (collector.frames, collector.needed)

    def _collect_functional(self, result, raw, errors) -> None:
        done = self._functional.add(result.R, raw, errors, self.processor.sensor_calibration)
        if done is None:
            return
        R0, yaw0, report, data = done
        self._functional, self.functional_report = None, report
        self.processor.pose.adopt(R0, yaw0, "functional", data["window"])
        self._adopting = ("functional", {k: v for k, v in data.items()
                                         if k not in ("R0", "yaw0", "source")})
        if report.missing:
            self.note("functional calibration: missing " + ", ".join(report.missing))

    def marker(self, text: str) -> None:
        """A marker note at the next processed frame: in the raw recording, the event log and
        the LSL event stream."""
        self.events.at_next_frame(SessionEvent.of(Text(str(text))))

    def change(self, change: Change) -> None:
        """Apply a typed change (:mod:`bpms.io.event_types`, checked when made) before the
        next frame: queued for the processing thread, the only one touching the processor,
        which owns the values in force (``LiveStatus.filter_settings`` reports them once
        applied; ``settings_pending`` counts the changes queued until then)."""
        self.settings.put(change)

    def set_gains(self, **gains: float) -> None:
        """A :class:`Gains` change (OptionRangeError, naming the range, here when refused)."""
        self.change(Gains(gains))

    def select_filter(self, algorithm: str) -> None:
        """A :class:`FilterChoice` for all 18 IMUs (Reset Zero and their values kept)."""
        self.change(FilterChoice(algorithm))

    def set_corrected_output(self, on: bool | None = None) -> None:
        """Output angles corrected by Reset Zero (True) or not (False); None toggles."""
        self.change(Alignment(on))

    def start_logging(self, raw: bool = True, filtered: bool = True, name: str | None = None,
                      degrees: bool = False) -> RecordingStatus:
        """Start recording with the next sequence-numbered names. Raises RecordingError when
        the raw file cannot be created (the session goes on)."""
        self.stop_logging()
        if name is not None:
            self._namer = RecordingNamer(self._namer.directory, name)
        self._namer.directory.mkdir(parents=True, exist_ok=True)
        raw_path, filtered_path = self._namer.next_paths()
        status = RecordingStatus()
        if raw:
            # what the processor runs with (run-time gains included): the recording can be
            # filtered again with the same numbers
            header = new_header(calibration=self.processor.table.values,
                                options=_options_dict(self.processor.options), notes=self.notes,
                                source=self.source.status().description,
                                extra={"session_events": True, **self.header_extra})
            writer = RawWriter(raw_path, header, self.options.logging.flush_interval_s)
            logger = RawLogger(writer, status, self.note, self.options.logging.disk_reserve_s)
            logger.start()
            status.raw_path = raw_path
            self._raw_logger = logger
            self.events.sinks.append(logger.queue.put)
        if filtered:
            from bpms.filter.door import (  # not the GUI
                filtered_convention,
                filtered_layout,
                heading_header,
            )

            try:
                groups, kind = filtered_layout()
                # the header `bpms filter` writes from the raw file beside it: the same bytes
                source = {"source": raw_path.name} if raw else {}
                writer = FilteredWriter(filtered_path, degrees=degrees, groups=groups,
                                        euler=kind, convention=filtered_convention(
                                            self.processor.options.joints.convention),
                                        meta={**source, **heading_header(self.processor.options)})
            except OSError as exc:
                self.note(f"filtered recording not started: cannot create {filtered_path}: {exc}")
            else:
                status.filtered_path = filtered_path
                beside = self._raw_logger
                self._commands.put(lambda: self._filtered.open(writer, beside))
        self._recording = status
        self.events.emit(SessionEvent.of(Logging(
            "start", raw_path.name if raw else None,
            status.filtered_path.name if status.filtered_path else None)))
        self._commands.put(self._state_in_force)
        return status

    def _state_in_force(self) -> None:
        """At the first frame processed after logging started: the settings in force and the
        zero, as events (a recording then holds its start state, whatever the header)."""
        proc = self.processor
        values = {k: v for k, v in dataclasses.asdict(proc.options.filter).items()
                  if k != "algorithm"}
        for change in (FilterChoice(proc.options.filter.algorithm, "in force"),
                       Gains(values, "in force"),
                       Alignment(bool(proc.corrected_output), "in force")):
            self.events.at_next_frame(SessionEvent.of(change))
        zero = proc.pose.zero
        if zero is not None:
            self.events.at_next_frame(SessionEvent.of(zero.change("in force")))

    def stop_logging(self) -> RecordingStatus | None:
        """Stop recording; files are flushed and closed. Returns the final status."""
        status, self._recording = self._recording, None
        if status is not None:
            self.events.emit(SessionEvent.of(Logging("stop")))
        with self._feed_lock:  # no frame is handed to the raw file after this
            logger, self._raw_logger = self._raw_logger, None
            if logger is not None:
                logger.fed_done = True  # the filtered file writes no row past its last frame
        if logger is not None:
            with contextlib.suppress(ValueError):
                self.events.sinks.remove(logger.queue.put)
            logger.stop()
            logger.join(10.0)
        done = threading.Event()

        def close_filtered() -> None:
            try:
                self._filtered.close(status)
            finally:
                done.set()

        if self.running:
            self._commands.put(close_filtered)
            done.wait(5.0)
        else:
            close_filtered()
        return status

    def start_forwarding(self, targets: list[str] | None = None) -> UdpForwarder:
        """Send every raw frame and pose to ``targets`` (default: the options' list)."""
        self.stop_forwarding()
        self._forwarder = UdpForwarder(targets or self.options.udp.forward_to,
                                       self.options.udp.multicast_ttl,
                                       key=shared_key(self.options.udp.key_file),
                                       wait=self.source_can_wait)
        return self._forwarder

    def stop_forwarding(self) -> None:
        forwarder, self._forwarder = self._forwarder, None
        if forwarder is not None:
            forwarder.close()

    # -- status ---------------------------------------------------------------------------
    def status(self) -> LiveStatus:
        fwd = self._forwarder
        fstats = fwd.stats if fwd is not None else None
        with self._lock:
            lat = sorted(self._latencies[-500:])
        events, pending = self.events.lines(), self.settings.pending  # (before the values)
        proc = self.processor
        return LiveStatus(
            source=self.source.status(), running=self.running, rate_hz=self._rate.rate_hz(),
            frames=self._frames, processed=self._processed, error_bits=self._error_bits,
            dropped=self._fanout.dropped + self.health.not_filtered,
            processing_backlog=self._proc_queue.qsize(), recording=self._recording,
            forwarding=[f"{h}:{p}" for h, p in fwd.targets] if fwd else [],
            forwarded=fstats.sent if fstats else 0,
            forwarded_poses=fstats.poses_sent if fstats else 0,
            forward_errors=fstats.errors if fstats else 0,
            forward_refused=fstats.refused if fstats else 0,
            latency_p99_ms=1e3 * lat[int(0.99 * (len(lat) - 1))] if lat else 0.0,
            events=events, reinit_count=self._reinit_seen,
            not_filtered=self.health.not_filtered,
            display_skipped=self._fanout.dropped, holes_marked=self.health.holes_marked,
            reset_zero=proc.pose.state_text(proc.options.filter.dt),
            calibration_source=proc.calibration_source, options_source=proc.options_source,
            filter_name=proc.options.filter.algorithm, filter_settings=proc.options.filter,
            settings_pending=pending, event_warnings=self.events.warning_lines())

    # -- threads ----------------------------------------------------------------------------
    def _acquire(self) -> None:
        try:  # kernels loaded and the heap frozen before the first frame is accepted
            prepare_live_path(self.processor)
        except Exception as exc:  # a failed warm-up only costs latency later
            self.note(f"warm-up failed: {exc}")
        while not self._stop.is_set():
            try:
                events = self.source.read(0.1)
            except Exception as exc:  # a source bug must not kill the session silently
                if self._stop.is_set():
                    break  # the source was closed under this read: not an error
                self.note(f"source error: {exc}")
                time.sleep(0.1)
                continue
            if not events:
                continue
            self._rate.mark(len(events))
            forwarder = self._forwarder
            for event in events:
                self._frames += 1
                if forwarder is not None:
                    forwarder.send_frame(event.frame, stream_time(event.index))
                with self._feed_lock:  # stop_logging ends the raw file between two frames
                    logger = self._raw_logger
                    if logger is not None:
                        if logger.first_index is None:
                            logger.first_index = event.index  # the file's slot 0
                        logger.queue.put(event)
                        logger.last_index = event.index
                self._enqueue(event)
        self._proc_queue.put(_STOP)

    def _enqueue(self, event: FrameEvent) -> None:
        """Hand a frame to processing. A file can wait for processing to catch up; a live
        source cannot (its bytes would be lost before the raw logger saw them), so after 60 s
        of backlog its frames skip processing, counted as dropped (they are still recorded)."""
        if self.source_can_wait:
            while not self._stop.is_set():
                try:
                    self._proc_queue.put_wait(event, 0.2)
                    return
                except queue.Full:
                    continue
            return
        try:
            self._proc_queue.put_nowait(event)
        except queue.Full:
            self.health.not_filtered_frame(event.index, event.host_time)

    def _process_loop(self) -> None:
        """Takes frames one by one at 50 Hz; when behind (replay at full speed, a Bluetooth
        burst) takes everything waiting and filters it as one batch (same results)."""
        while True:
            try:
                first = self._proc_queue.get(timeout=0.1)
            except queue.Empty:
                self._run_commands()
                if self._filtered.pending:  # the source went quiet: write what is waiting
                    self._filtered.write(self._recording)
                if self._stop.is_set():
                    break
                continue
            batch = [first]
            while len(batch) < 512 and self._proc_queue.qsize():
                try:
                    batch.append(self._proc_queue.get_nowait())
                except queue.Empty:
                    break
            self._run_commands()
            stop = any(item is _STOP for item in batch)
            events = [item for item in batch if isinstance(item, FrameEvent)]
            # Runs that start at a discontinuity: the filters restart there.
            starts = [k for k, e in enumerate(events) if e.discontinuity and k > 0]
            for lo, hi in zip([0, *starts], [*starts, len(events)], strict=True):
                if lo < hi:
                    try:
                        self._process(events[lo:hi])
                    except Exception as exc:
                        self.note(f"processing error on frames {events[lo].index}..: {exc}")
            if stop:
                break

    def _run_commands(self) -> None:
        for event in self.settings.apply(self.processor, self.note):
            self.events.at_next_frame(event)  # they hold from the next frame on
        while not self._commands.empty():  # (this thread is the only one taking)
            command = self._commands.get_nowait()
            try:
                command()
            except Exception as exc:
                self.note(f"command failed: {exc}")

    def _process(self, events: list[FrameEvent]) -> None:
        """Filter a run of frames (a discontinuity, if any, is on the first)."""
        proc = self.processor
        head = events[0]
        marks = [(k, m) for k, e in enumerate(events) if e.marks for m in e.marks]
        if marks and self._own_zero:  # the user's own Reset Zero wins over the sender's
            marks = [(k, m) for k, m in marks
                     if not (m.kind == "reset_zero" and m.data.get("source") == "network")]
        if head.discontinuity:
            if head.preroll:
                # the state in force at the seek point first, then the pre-roll runs with it
                for m in head.marks:
                    proc.apply_event(m)
                marks = [(k, m) for k, m in marks if k > 0]
                proc.reinitialise()
                decoded = decode_frames(head.preroll)
                proc.process(decoded.raw, decoded.errors)
                action, reason = "reinit", "seek"
            elif head.index <= 0:
                proc.restart()
                self._zero_wait_noted = False
                action, reason = "restart", "stream start"
            else:
                proc.reinitialise()
                action, reason = "reinit", "the stream resumed after a gap"
            self.events.at_next_frame(SessionEvent.of(Filters(action, reason)))
        if self.events.waiting:
            self.events.frame_reached(head.index)
        # one frame live at 50 Hz, several when behind: the same call
        # (bytes.join hands a single frame's bytes back as they are: no copy at N = 1)
        result, raw, errors = proc.step_wire(b"".join(e.frame for e in events),
                                             [(k, m) for k, m in marks if m.changes_numbers])
        done = time.perf_counter()
        samples = [PoseSample.row(result, k, e.index, e.host_time, e.frame, raw[k], errors[k],
                                  done - e.arrival, e.arrival)
                   for k, e in enumerate(events)]
        self._note_reinit(result)
        first = proc.frames - len(events)  # stream frame number of events[0]
        for z in result.zeros:
            change = z.change()
            if self._adopting is not None and z.source == self._adopting[0]:  # adopted
                change = change.merged(self._adopting[1])
                self._adopting = None
            self.events.emit(SessionEvent.of(change, head.index + z.frame - first),
                             warning=z.moved)
            if z.source == "posture" and self._posture is not None:  # the capture
                self._adopt_posture(z)
        if self._functional is not None:
            self._collect_functional(result, raw, errors)
        for k, m in marks:
            if m.kind != "reset_zero":
                self.events.emit(m.at(events[k].index))
        if proc.pose.waiting is not None and not self._zero_wait_noted:
            at = proc.pose.origin + proc.pose.auto_frame - first  # the frame it first could
            self._note_zero_wait(head.index + min(max(at, 0), len(events) - 1))
        self._processed += len(events)
        self._error_bits += int(np.count_nonzero(errors))
        forwarder = self._forwarder
        if forwarder is not None:
            forward_poses(forwarder, events, result)
            problem = self._zero_forwarding.after(forwarder, proc, events, result)
            if problem:
                self.note(problem)
        with self._lock:
            self._latencies.extend(s.latency_s for s in samples)
            if len(self._latencies) > 5000:
                del self._latencies[:-2500]
        for sample in samples:
            self._fanout.publish(sample)
        # after the pose went out: off the latency path
        self._filtered.log(events, result, self._recording)

    def _note_zero_wait(self, index: int) -> None:
        """The automatic Reset Zero waits for a still pose: said once, with the motion."""
        self._zero_wait_noted = True
        moved, imu = self.processor.pose.waiting
        window_s = self.processor.pose.window * self.processor.options.filter.dt
        self.events.note(f"Reset Zero (automatic) waiting for a still pose: moved "
                         f"{moved:.1f}° (IMU {imu}) within {window_s:.2f} s", index,
                         warning=False)

    def _note_reinit(self, result) -> None:
        """State-guard re-initialisations are events (logged, in the status): every one is
        counted (``LiveStatus.reinit_count``), at most one event line per second."""
        total = self.processor.guard.total  # = result.reinit_count.sum(), without numpy
        if total == self._reinit_seen:
            return
        self._reinit_seen = total
        self._reinit_imus.update(int(i) for i in result.reinitialised.nonzero()[1])
        now = time.monotonic()
        if now - self._reinit_noted >= 1.0:
            self.note(f"filter re-initialised (state not a rotation): IMU "
                      f"{', '.join(map(str, sorted(self._reinit_imus)))}; {total} so far")
            self._reinit_noted = now
            self._reinit_imus.clear()


def _options_dict(options: Options) -> dict:
    return {name: dataclasses.asdict(section) for name, section in options.sections().items()}
