"""``bpms monitor`` prints a status line every second, also while it probes a silent suit and
each probe waits its whole ``--timeout`` (issue 26.6). A real subprocess against the
simulated suit over TCP, silenced for 8 s while the probes wait 3 s each."""

from __future__ import annotations

import itertools
import re

import pytest
from test_link_faults_e2e import Cli, Suit

from bpms.firmware.sim.arbiter import MotionSource

pytestmark = pytest.mark.timeout(120)
T = re.compile(r"^t +([\d.]+) s ")


def test_a_line_every_second_while_probing(tmp_path):
    suit = Suit("tcp", tmp_path, MotionSource.simulated(duration_s=60.0, seed=5))
    try:
        cli = Cli("monitor", suit.port, "--timeout", "3")
        k = cli.wait_line(lambda s: "rate" in s and float(s.split("rate")[1].split("Hz")[0])
                          > 40.0, timeout=40)
        suit.arbiter.silence(8.0)
        probed = cli.wait_line(lambda s: "SILENT" in s and "did not answer" in s, k + 1)
        end = cli.wait_line(lambda s: "rate" in s and "SILENT" not in s
                            and float(s.split("rate")[1].split("Hz")[0]) > 40.0, probed + 1)
        code, err = cli.stop()
    finally:
        suit.close()
    assert code == 0 and "Traceback" not in err, err
    times = [float(T.match(line).group(1)) for line in cli.lines[1:end + 1]
             if T.match(line)]
    gaps = [b - a for a, b in itertools.pairwise(times)]
    # each probe blocks the reader for 3 s; the lines keep their one-second rhythm
    assert max(gaps) < 2.0, gaps
    probing = [line for line in cli.lines[k:end] if "SILENT" in line]
    assert len(probing) >= 5, "\n".join(cli.lines)  # 8 s of silence, 1 s to notice it
