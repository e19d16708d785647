"""The filtered file: CSV text, one row per frame (docs/filtered-file.md).

One module per job: :mod:`~bpms.io.filtered_file.columns` (the column layout and names,
the column groups), :mod:`~bpms.io.filtered_file.writer` (:class:`FilteredWriter`) and
:mod:`~bpms.io.filtered_file.reader` (the one reader of every version). Import each name
from its module.

Version 2 (written now)::

    # bpms-filtered-file 2
    # euler: sensor
    # convention: ...
    # groups: euler,joints
    time_s,host_time_s,hole,imu0_right_leg_roll_rad,...,joint_elbow_r_flexion_rad,...

- ``#`` lines: the header, ``key: value``. ``euler`` says which Euler angles the ``euler``
  group holds: ``sensor`` (each IMU's filter orientation, filter frame → NED) or ``segment``
  (segment orientations corrected by Reset Zero); ``groups`` lists the column groups in order.
- Fixed columns: ``time_s`` (s since the stream started, fixed filter clock,
  :mod:`bpms.io.timebase`), ``host_time_s`` (s since the epoch, UTC, when the host received the
  frame; ``nan`` when unknown) and ``hole`` (1 for a frame that was received but not filtered:
  its values are ``nan``; 0 otherwise).
- Then the column groups (:func:`register_column_group`), each a fixed set of named columns;
  angular groups are radians (``_rad``) or degrees (``_deg``) for the whole file.

One reader, :func:`iter_filtered` (streaming, block by block) / :func:`read_filtered` (whole
file), reads every version:

- version 2 (above), with column groups it does not know kept by name in ``extra``;
- version 1, this project's earlier layout: one header row ``time_s,imu0_..._roll_rad,...``
  (+ joint columns), no host time, no holes;
- version 0, the original suite's file: no header, one line per frame, ``time.time()`` epoch
  seconds then roll, pitch, yaw (rad) of IMU 0..17, each value followed by a comma (a trailing
  comma ends the line). Its absolute time becomes ``host_time`` (float64, to the millisecond
  and better) and ``time_s`` counts from its first row.
"""
