"""A live path without stalls: what :class:`bpms.pipeline.session.LiveSession` does before it
accepts the first frame (docs/pipeline.md).

- **Kernels loaded**: the compiled filter kernels (numba, cached on disk) load on their first
  call, 0.15–0.3 s, and compile on the very first run (seconds). :func:`warm_up` calls every
  kernel the live path uses — calibration, the selected attitude filter's batch and one-frame
  steps, Reset Zero, joint angles and positions, quaternions — on a level synthetic frame,
  with a throwaway processor built from the same calibration and options, so the session's
  own processor and its stream are untouched.
- **Garbage collection**: CPython's full collections scan every live object; with numba,
  numpy and Qt loaded that is hundreds of thousands of objects and tens of milliseconds.
  :func:`freeze_heap` collects once, then moves everything alive after warm-up into the
  permanent generation (``gc.freeze``), so later collections scan only what the session
  allocates while running.
"""

from __future__ import annotations

import gc
import logging
import time

import numpy as np

log = logging.getLogger(__name__)
_frozen = False


def level_frame(table) -> np.ndarray:
    """A plausible raw frame ``[18, 9]`` int16 for a calibration table: every IMU level
    (gravity on its z axis), facing magnetic north, not rotating."""
    acc_mm = table.accel_min_max
    mag_mm = table.mag_min_max
    acc = acc_mm.mean(axis=-1)
    acc[:, 2] += (acc_mm[:, 2, 1] - acc_mm[:, 2, 0]) / 2
    mag = mag_mm.mean(axis=-1)
    mag[:, 0] += (mag_mm[:, 0, 1] - mag_mm[:, 0, 0]) / 2
    raw = np.concatenate([acc, mag, table.gyro_avg], axis=1)
    return np.clip(np.round(raw), -32768, 32767).astype(np.int16)


def warm_up(processor) -> float:
    """Load (or compile) every kernel the live path calls, with a throwaway copy of
    ``processor`` (same calibration, options and filter). Returns the seconds it took."""
    from bpms.filter.processor import BodyPoseProcessor
    from bpms.io.frames import encode_frame

    t0 = time.perf_counter()
    clone = BodyPoseProcessor(processor.table, processor.options)
    frame = level_frame(processor.table)
    errors = np.zeros((frame.shape[0], 3), dtype=bool)
    batch = clone.process(np.repeat(frame[None], 4, axis=0), np.repeat(errors[None], 4, 0))
    wire = encode_frame(frame, errors)
    for _ in range(3):  # frames as they come off the wire
        one = clone.step_wire(wire)[0]
    for result in (batch, one):
        _ = result.joint_angles, result.joint_positions
        _ = result.segment_quaternions, result.quaternions
    clone.reset_zero()
    clone.step(frame, errors)
    return time.perf_counter() - t0


def freeze_heap() -> None:
    """Collect once and freeze everything alive now (once per process): later garbage
    collections scan only objects allocated afterwards."""
    global _frozen
    if _frozen:
        return
    gc.collect()
    gc.freeze()
    _frozen = True
    log.debug("gc: %d objects frozen", gc.get_freeze_count())


def prepare_live_path(processor) -> float:
    """:func:`warm_up` then :func:`freeze_heap`; the seconds taken."""
    took = warm_up(processor)
    freeze_heap()
    return took
