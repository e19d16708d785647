"""Analysis tools (Qt-free): translators, exports, range of motion, walked path.

Every tool reads recordings through :func:`bpms.io.recordings.open_recording` and filters them
with :class:`bpms.filter.processor.BodyPoseProcessor`; nothing here re-implements filtering.
See ``docs/analysis.md``.
"""
