"""LSL streams are unique per sender (issue 45.4). On 682dd18 every bpms sender on a computer
had the same ``source_id`` (``bpms@HOST:joints``): an inlet whose sender ended recovered by
itself onto the next bpms sender and pulled its samples as if nothing had happened. Now the
``source_id`` names the host, the process and the session, and an inlet left over from an
ended session receives nothing of another.

liblsl runs in a child process with a configuration of this test only (this machine, its own
session id), as in tests/test_lab_streams.py."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("pylsl")
pytestmark = pytest.mark.timeout(90)
ROOT = Path(__file__).resolve().parents[1]

CHILD = r'''
import json, sys, time
import numpy as np
import pylsl
from bpms.pipeline.lsl import LslOutlets

first = LslOutlets()
ids = [first.outlets["joints"].get_info().source_id()]
inlet = pylsl.StreamInlet(pylsl.resolve_byprop("name", "BPMS Joint Angles", timeout=10)[0])
inlet.open_stream(timeout=10)
got = 0
deadline = time.monotonic() + 10
while got < 10 and time.monotonic() < deadline:  # the inlet follows the first sender
    first.outlets["joints"].push_sample(np.full(28, 1.0, dtype=np.float32))
    sample, _ = inlet.pull_sample(timeout=0.02)
    got += sample is not None
first.close()
del first
second = LslOutlets()  # the same program's next session (another bpms sender alike)
ids.append(second.outlets["joints"].get_info().source_id())
foreign = 0
end = time.monotonic() + 2.5  # liblsl re-resolves a broken stream within ~0.5 s
while time.monotonic() < end:
    second.outlets["joints"].push_sample(np.full(28, 2.0, dtype=np.float32))
    sample, _ = inlet.pull_sample(timeout=0.01)
    foreign += sample is not None and sample[0] == 2.0
import os
print(json.dumps({"ids": ids, "first": got, "foreign": foreign, "pid": os.getpid()}))
'''


def test_an_inlet_never_slips_onto_another_bpms_sender(tmp_path):
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-sid-{os.getpid()}\n")
    run = subprocess.run([sys.executable, "-c", CHILD], cwd=ROOT, capture_output=True,
                         text=True, timeout=60, env={**os.environ, "LSLAPICFG": str(cfg)})
    assert run.returncode == 0, run.stderr[-2000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    first, second = out["ids"]
    assert out["first"] == 10
    assert first != second  # 682dd18: both "bpms@HOST:joints"
    for sid in (first, second):
        assert sid.startswith(f"bpms@{socket.gethostname()}/pid{out['pid']}/")
        assert sid.endswith(":joints")

    assert out["foreign"] == 0  # 682dd18: thousands of the second sender's samples


def _inlet_script() -> str:
    text = (ROOT / "docs" / "lsl.md").read_text(encoding="utf-8")
    start = text.index("```python\n# bpms-lsl-inlet")
    return text[start + len("```python\n"):text.index("```", start + 10)]


def test_the_documented_inlet_waits_out_lsl_wait_and_says_when_the_stream_ends(tmp_path):
    """docs/lsl.md's inlet against `bpms replay --lsl --lsl-wait 2` of a 2 s recording: the
    replay plays after its wait (the script reads one stream of five), the inlet gets every
    sample, then says the stream ended (682dd18's script waited for a sender that had gone)."""
    from bpms.firmware.sim.session import simulate

    raw = simulate(duration_s=2.0, seed=45).save_raw(tmp_path / "Raw_short_1.bpmsraw")
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-doc-{os.getpid()}\n")
    env = {**os.environ, "LSLAPICFG": str(cfg)}
    script = tmp_path / "inlet.py"
    script.write_text(_inlet_script(), encoding="utf-8")
    replay = subprocess.Popen([sys.executable, "-m", "bpms", "replay", str(raw), "--lsl",
                               "--lsl-wait", "2"], cwd=ROOT, env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        inlet = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                               capture_output=True, text=True, timeout=60)
    finally:
        _, replay_err = replay.communicate(timeout=60)
    assert replay.returncode == 0, replay_err
    assert inlet.returncode == 0, inlet.stderr[-2000:]
    lines = inlet.stdout.splitlines()
    assert lines[0].startswith("convention: isb") and "| sender: bpms@" in lines[0]
    assert lines[1].startswith("100 samples over 1.98 s") and lines[1].endswith(
        "(the stream ended)"), lines
