"""``bpms calibrate [PORT] [--imu IDS] [--sensor accel|mag|gyro] -o Calib.cfg``: the sensor
calibration tool in the terminal (docs/calibration.md), for the whole suit or any subset of IMUs.

Steps, in this order, for the sensors chosen (default all three):
  gyro   keep the suit still; N readings averaged per axis (--gyro-samples); when the suit
         moves the capture is refused and asked again;
  accel  for each IMU the 6 poses in a guided order (+z, -z, +x, -x, +y, -y): hold the IMU
         still with the axis at its extreme, press Enter; 200 readings are averaged
         (s Enter = skip the pose, r Enter = redo the previous one, q Enter = stop the step);
  mag    rotate the garment through every orientation for --sweep-s seconds (all IMUs at
         once), with live min/max, sphere coverage and saturation warnings; Enter ends early.
Then a summary (old vs new per value) and quality figures; the result is merged into the
existing file (-o, or --existing) so that only what was measured changes, and written as the
legacy Calib.cfg plus the modern Calib.json beside it.

--sim runs against the simulated suit in-process (it holds the poses asked for; --yes answers
every prompt, capturing each pose as soon as it is held still).
"""

from __future__ import annotations

import argparse

from bpms.commands._shared import LONGEST_S, number


def run(args: argparse.Namespace) -> int:
    from bpms.commands._calibrate_run import run as run_tool  # numpy etc. only when it runs

    return run_tool(args)


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("calibrate", help="calibrate the suit's sensors (gyro, accel, mag)")
    p.add_argument("port", nargs="?", help="serial port or pyserial URL (default: discover)")
    p.add_argument("--imu", default="all", metavar="IDS",
                   help="IMUs to calibrate: 'all' or e.g. 0,2,5-7 (default all)")
    p.add_argument("--sensor", action="append", metavar="accel|mag|gyro",
                   help="sensor(s) to calibrate, repeatable or comma-separated (default all)")
    p.add_argument("-o", "--output", required=True, metavar="Calib.cfg",
                   help="calibration file to write (the modern .json goes beside it)")
    p.add_argument("--existing", metavar="FILE",
                   help="merge into this file (default: the output file when it exists, "
                        "else your default calibration, else the factory table)")
    p.add_argument("--make-default", action="store_true",
                   help="also make the result your default calibration (bpms config); "
                        "without it you are asked")
    p.add_argument("--gyro-samples", type=number(int, 1, 10_000_000), default=500, metavar="N",
                   help="gyro readings averaged per axis (default 500 = 10 s)")
    p.add_argument("--accel-samples", type=number(int, 1, 10_000_000), default=200, metavar="N",
                   help="accel readings averaged per pose (default 200)")
    p.add_argument("--sweep-s", type=number(float, 0, LONGEST_S, above=True),
                   default=120.0, metavar="S",
                   help="magnetometer sweep duration, s (default 120)")
    p.add_argument("--ellipsoid", action="store_true",
                   help="also fit a magnetometer ellipsoid (hard + soft iron)")
    p.add_argument("--yes", action="store_true",
                   help="answer every prompt (capture poses when held still, save)")
    p.add_argument("--sim", action="store_true",
                   help="calibrate the simulated suit in-process (it holds the poses asked)")
    p.add_argument("--sim-speed", type=number(float, 0, 1000), default=1.0, metavar="X",
                   help="simulated frames at X times real time; 0 = as fast as possible")
    p.add_argument("--sim-move-gyro", action="store_true",
                   help="the simulated suit moves during the first gyro capture")
    return p


