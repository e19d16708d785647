"""Building and driving the :class:`LiveSession` of each start-up mode (no widgets here).

Modes: ``suit`` (serial/Bluetooth), ``sim`` (the simulated suit served in-process on a real
pty and opened like a real suit), ``udp`` (UDP client) and ``file`` (raw-file playback).

:meth:`SessionRunner.prepare` does the blocking part (discovery, opening the port, reading the
file) and is meant for a worker thread; it raises :class:`ModeError` with a one-line message
that says what to check. Start/Stop Data then means: suit → start/stop the stream (the link
stays open); file → play/pause; UDP → a fresh session listening again / the session stopped.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from bpms.io.calib_file import CalibrationTable
from bpms.io.link import LinkError
from bpms.io.options import Options
from bpms.io.rawfile import RawFileError
from bpms.io.replay import ReplaySource
from bpms.pipeline.sources import SuitFrameSource, UdpFrameSource

if TYPE_CHECKING:  # the filter (numba) loads when a session is built, not with the window
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.pipeline.session import LiveSession

MODES = ("suit", "udp", "file", "sim")
MODE_LABELS = {
    "suit": "Suit (serial / Bluetooth)",
    "udp": "UDP client",
    "file": "Raw-file playback",
    "sim": "Simulated suit",
}


class ModeError(Exception):
    """The chosen mode cannot start; the message says what to check (one line).
    ``reason``: what went wrong alone; ``checks``: what to check, each once (a dialog lists
    them)."""

    def __init__(self, message: str, reason: str = "", checks: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.reason = reason or message
        self.checks = checks


#: What to check when no suit answers (said once, in the message and in the dialog).
SUIT_CHECKS = ("the suit is paired over Bluetooth", "it is switched on and its battery charged",
               "the port and the baud rate are right")


@dataclass
class ModeConfig:
    """What the start-up window chose. ``port`` empty = discover; ``baud`` in bit/s;
    ``listen`` host:port; ``group`` a multicast group or empty; ``path`` a raw recording."""

    mode: str = "sim"
    port: str = ""
    baud: int = 1_000_000
    listen: str = "0.0.0.0:5005"
    group: str = ""
    path: str = ""
    sim_seed: int = 0
    recording_dir: str | None = None
    #: more of the simulated subject (``simulate()``'s ``posture``, ``functional``,
    #: ``mounting_error_deg``, ``subject``: docs/simulated-suit.md); none: the standard trial
    sim_options: dict = field(default_factory=dict)
    #: the subject's profile (docs/subject.md: ``id=S01,height=1.80,...`` or a TOML file) for a
    #: live session's body model and its recordings' headers; "" none (file mode: the header's)
    subject: str = ""


class SimulatedSuit:
    """``bpms.firmware.sim``'s arbiter served on a pty in this process (real time, 50 Hz)."""

    def __init__(self, seed: int = 0, **options: object) -> None:
        from bpms.firmware.sim.arbiter import Arbiter, MotionSource
        from bpms.firmware.sim.server import local_server

        self.arbiter = Arbiter(MotionSource.simulated(seed=seed, **options), seed=seed)
        self.server = local_server(self.arbiter).start()  # a pty, or TCP where there is none
        self.path: str = self.server.address

    def close(self) -> None:
        self.server.stop()


class SessionRunner:
    """One mode's session for the main window. ``session`` is None until :meth:`prepare`."""

    def __init__(self, config: ModeConfig, options: Options,
                 calibration: CalibrationTable | None = None) -> None:
        if config.mode not in MODES:
            raise ModeError(f"unknown mode {config.mode!r} (one of {', '.join(MODES)})")
        self.config = config
        self.options = options
        self.calibration = calibration
        self.session: LiveSession | None = None
        self.replay: ReplaySource | None = None
        self.suit: SuitFrameSource | None = None
        self.sim: SimulatedSuit | None = None
        self._data_on = False
        self._udp_stopped = False
        self._lsl = None  # i16: LslBridge while LSL streaming is on (set_lsl)
        self._mvn: list = []  # i16: MvnBridges to the options' mvn.targets
        self.problems: list[str] = []  # warnings about the source (e.g. a truncated file)
        # Playback opens the recording through the one door (bpms.filter.door): these
        # explicit choices win, else the recording's header, else the user's default.
        self.playback_calibration: CalibrationTable | str | None = None
        self.playback_options: Options | str | None = None
        #: which Reset Zero playback applies (bpms.filter.zero_choice: events, auto, none)
        self.playback_reset_zero: str | None = None
        #: the filter chosen in the playback controls (None: the recording's own, its
        #: recorded filter and gain changes applied); recorded_filter: the recording's own
        self.playback_filter: str | None = None
        self.recorded_filter: str | None = None
        self._opened = None  # the door's OpenedRecording of the recording played
        self._start_filter: dict = {}  # its filter settings at the start (FilterOptions)
        #: Where the calibration / options in force came from (for the data panel).
        self.calibration_source = getattr(calibration, "source", "factory")
        self.options_source = getattr(options, "source", "factory")

    @property
    def mode(self) -> str:
        return self.config.mode

    @property
    def data_on(self) -> bool:
        """Start Data pressed and not stopped since."""
        return self._data_on

    def _new_session(self, source, processor: BodyPoseProcessor | None = None) -> LiveSession:
        from bpms.filter.processor import BodyPoseProcessor
        from bpms.pipeline.session import LiveSession

        profile, options = self._profile() if processor is None else None, self.options
        if profile is not None:  # live: the subject's own lengths (docs/subject.md), in a
            # copy: the user's options keep theirs; the other sections are shared
            options = dataclasses.replace(options, body=profile.body_options())
        if processor is None and self.session is not None:  # a new stream (UDP restarted):
            # the filter settings and the alignment in force go on (their one owner: the
            # session's processor)
            previous = self.session.processor
            if not self.session.running:  # the changes asked while it was stopped hold too
                self.session.settings.apply(previous, self.session.note)
            options = dataclasses.replace(
                options, filter=previous.options.filter,
                pose=dataclasses.replace(options.pose,
                                         corrected_output=previous.corrected_output))
        processor = processor or BodyPoseProcessor(calibration=self.calibration,
                                                   options=options)
        session = LiveSession(source, options, processor,
                              recording_dir=self.config.recording_dir,
                              notes=f"BPMS GUI, {MODE_LABELS[self.mode]}")
        if profile is not None:  # stored in the raw recordings' headers (docs/subject.md)
            session.header_extra["subject"] = profile.to_header()
        if self._lsl is not None or self.options.lsl.enabled:  # i16: LSL follows the session
            self.set_lsl(False)
            self.session = session
            self.set_lsl(True)
        if self.options.mvn.targets:  # i16: the MVN-compatible stream (docs/mvn.md)
            from bpms.pipeline.streams import MvnBridge, stop_streams

            stop_streams(self._mvn)
            try:
                self._mvn = [MvnBridge(session, self.options.mvn.targets).start()]
            except (ValueError, OSError) as exc:
                session.note(f"MVN stream not started: {exc}")
        return session

    def set_lsl(self, on: bool) -> str | None:
        """The GUI's LSL switch (docs/lsl.md): stream the session as LSL outlets, or stop.
        Returns None, or a one-line reason it could not start (pylsl missing)."""
        if self._lsl is not None:
            self._lsl.stop()
            self._lsl = None
        if on and self.session is not None:
            try:
                from bpms.pipeline.lsl import LslBridge

                self._lsl = LslBridge(self.session).start()
            except ImportError:
                return 'LSL streaming needs the pylsl package (pip install "bpms[lsl]")'
            except (ValueError, OSError) as exc:
                return str(exc)
        return None

    @property
    def lsl_on(self) -> bool:
        return self._lsl is not None

    def _profile(self):
        """The subject's profile of :attr:`ModeConfig.subject`, else None. Raises ModeError."""
        if not self.config.subject:
            return None
        from bpms.io.subject import SubjectProfile

        try:
            return SubjectProfile.parse(self.config.subject)
        except ValueError as exc:
            raise ModeError(str(exc)) from None

    def prepare(self) -> LiveSession:
        """Open the source (blocking: run it off the GUI thread). Raises ModeError."""
        cfg = self.config
        self._profile()  # a bad profile is said before any source opens
        if cfg.mode == "file":
            if not cfg.path:
                raise ModeError("choose a raw recording to play")
            from bpms.filter.door import open_for_processing

            try:
                # once, through the one door (docs/opening-recordings.md): the recording's
                # own calibration, options and events; the filter only when chosen in the
                # playback controls (a filter picked earlier in the app never overrides it)
                opened = open_for_processing(cfg.path, self.playback_calibration,
                                             self.playback_options,
                                             algorithm=self.playback_filter,
                                             reset_zero=self.playback_reset_zero,
                                             for_replay=True)
            except (RawFileError, OSError, ValueError) as exc:
                raise ModeError(f"cannot play {cfg.path}: {exc}") from None
            recording = opened.slots
            assert recording is not None
            self.problems = list(getattr(recording, "problems", []) or [])
            self.calibration_source = opened.calibration_source
            self.options_source = opened.options_source
            self._opened = opened
            self.recorded_filter = opened.processor.options.filter.algorithm
            self._start_filter = dataclasses.asdict(opened.processor.options.filter)
            # the recorded events (Reset Zero, alignment, gains, markers) at their frames
            self.replay = ReplaySource(recording, speed=1.0, autoplay=False,
                                       events=opened.replay_events(recording.events))
            self.session = self._new_session(self.replay, opened.processor)
        elif cfg.mode == "udp":
            self.session = self._new_session(self._udp_source())
        else:
            port = cfg.port or None
            if cfg.mode == "sim":
                self.sim = SimulatedSuit(cfg.sim_seed, **cfg.sim_options)
                port = self.sim.path
            serial = self.options.serial
            serial.baud = cfg.baud
            source = SuitFrameSource(port, serial, simulated=cfg.mode == "sim")
            source.stop_stream()  # connect without streaming; Start Data starts it
            try:
                source.connect()
            except LinkError as exc:
                self.close()
                where = f"port {port}" if port else "any serial port"
                # the link's own hint ("(is it paired, …?)") is what SUIT_CHECKS say in full
                detail = re.sub(r"\s*\([^()]*\?\)\s*$", "", str(exc))
                reason = detail if detail.startswith("no suit") else \
                    f"no suit on {where}: {detail}"
                raise ModeError(f"{reason}. Check that " + ", ".join(SUIT_CHECKS),
                                reason, SUIT_CHECKS) from None
            self.suit = source
            self.session = self._new_session(source)
        return self.session

    def _udp_source(self) -> UdpFrameSource:
        try:
            from bpms.io.udp.auth import shared_key

            return UdpFrameSource(self.config.listen, self.config.group or None,
                                  key=shared_key(self.options.udp.key_file),
                                  takeover_after_s=self.options.udp.takeover_after_s)
        except (OSError, ValueError) as exc:
            raise ModeError(f"cannot listen on UDP {self.config.listen}: {exc}") from None

    def set_playback_reset_zero(self, choice: str) -> None:
        """Playback: which Reset Zero applies (``events``, ``auto``, ``none``; :mod:`bpms.
        filter.zero_choice`). The recording plays again from its start with it."""
        from bpms.filter.zero_choice import ResetZeroChoice

        self.playback_reset_zero = choice
        opened, replay = self._opened, self.replay
        if opened is None or replay is None:
            return
        opened.use_reset_zero(ResetZeroChoice.parse(choice))
        replay.set_events(opened.replay_events(replay.recording.events))
        replay.seek(0)  # a new stream: the filters and Reset Zero start again

    def set_playback_filter(self, algorithm: str | None) -> None:
        """Playback: play with ``algorithm`` instead of the recording's filter (its recorded
        filter and gain changes then left out), or None: as recorded. The recording plays
        again from its start. Raises ValueError for an unknown filter."""
        opened, replay, session = self._opened, self.replay, self.session
        self.playback_filter = algorithm
        if opened is None or replay is None or session is None:
            return
        opened.settings_given = algorithm is not None or self.playback_options is not None
        self.options_source = opened.options_source + (
            f" with filter {algorithm} (chosen in playback)" if algorithm else "")
        # the recording's starting settings again, with the filter chosen (the session's one
        # road, applied before the next frame); recorded changes then follow, or not
        start = dict(self._start_filter)
        recorded = start.pop("algorithm")
        session.set_gains(**start)
        session.select_filter(algorithm or recorded)
        replay.set_events(opened.replay_events(replay.recording.events))
        replay.seek(0)  # a new stream: the filters and Reset Zero start again

    def start_data(self) -> LiveSession:
        """Start Data. Returns the (possibly new) session. Raises ModeError (UDP rebind)."""
        assert self.session is not None, "prepare() first"
        if self.mode == "udp" and self._udp_stopped:
            self.session = self._new_session(self._udp_source())
            self._udp_stopped = False
        if self.suit is not None:
            self.suit.start_stream()
        if self.replay is not None:
            if self.replay.ended:
                self.replay.seek(0)
            self.replay.play()
        if not self.session.running:
            self.session.start()
        self._data_on = True
        return self.session

    def show_frame(self, index: int, before: int = 0) -> None:
        """File mode, paused: jump to frame ``index`` and deliver it, with the ``before``
        frames that precede it (the plots' window, redrawn from the file; filters pre-rolled
        before the first), so every view shows the frame at the slider. Starts the session's
        threads if needed (nothing plays: the replay stays paused)."""
        assert self.replay is not None and self.session is not None
        last = min(index, len(self.replay) - 1)
        first = max(0, last - max(0, before))
        self.replay.seek(first)
        if last >= first:
            self.replay.step(last - first + 1)
        if not self.session.running:
            self.session.start()

    def show_next(self, n: int) -> bool:
        """File mode, paused, the last frame delivered being the one before the replay's
        position: deliver the ``n`` next frames as playing would (the filters go on: no seek,
        no re-initialisation). False (nothing done) when the replay is elsewhere."""
        assert self.replay is not None and self.session is not None
        if n < 1 or not self.session.running or self.replay.playing:
            return False
        n = min(n, len(self.replay) - self.replay.position)
        if n > 0:
            self.replay.step(n)
        return True

    def stop_data(self) -> None:
        """Stop Data: suit stream stopped, playback paused, UDP session stopped."""
        self._data_on = False
        if self.session is None:
            return
        if self.suit is not None:
            self.suit.stop_stream()
        elif self.replay is not None:
            self.replay.pause()
        else:
            self.session.stop()
            self._udp_stopped = True

    def close(self) -> None:
        """Stop everything (threads joined, files closed, the simulated suit shut down)."""
        if self.session is not None:
            self.session.stop()
            self.set_lsl(False)
            for bridge in self._mvn:
                bridge.stop()
            self._mvn = []
        elif self.suit is not None:
            self.suit.close()
        if self.sim is not None:
            self.sim.close()
            self.sim = None
        self._data_on = False

