"""The GUI's LSL switch (SessionRunner.set_lsl) on file playback: an inlet in another process
receives the playback's segment stream while the switch is on."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from waiting import wait_until

from bpms.firmware.sim.session import simulate
from bpms.gui.modes import ModeConfig, SessionRunner
from bpms.io.options import Options

ROOT = Path(__file__).resolve().parents[1]


def test_lsl_switch_streams_file_playback(tmp_path):
    cfg = tmp_path / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nKnownPeers = {{127.0.0.1}}\nSessionID = bpms-gui-{os.getpid()}\n")
    env = {**os.environ, "LSLAPICFG": str(cfg)}
    raw = simulate(6.0, seed=5).save_raw(tmp_path / "Raw_gui_001.bpmsraw")
    inlet = subprocess.Popen([sys.executable, str(ROOT / "tests" / "lsl_inlet.py"), "300",
                              "40"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             env=env)
    old = os.environ.get("LSLAPICFG")
    os.environ["LSLAPICFG"] = str(cfg)  # liblsl reads it when first loaded in this process
    runner = SessionRunner(ModeConfig(mode="file", path=str(raw),
                                      recording_dir=str(tmp_path)), Options())
    try:
        runner.prepare()
        assert runner.set_lsl(True) is None and runner.lsl_on
        bridge = runner._lsl
        # wait for the inlet to connect to every stream before playing, as a lab would start
        # LabRecorder first (a stream it joins late misses the first samples: the inlet would
        # then wait for its deadline)
        for outlet in bridge.outlets.outlets.values():
            assert outlet.wait_for_consumers(30)
        runner.start_data()
        assert wait_until(lambda: bridge.sent >= 300, timeout=60)
        runner.set_lsl(False)
        assert not runner.lsl_on
    finally:
        runner.close()
        if old is None:
            os.environ.pop("LSLAPICFG", None)
        else:
            os.environ["LSLAPICFG"] = old
    out, err = inlet.communicate(timeout=90)
    data = json.loads(out)["data"]
    assert len(data["BPMS Segments"]["stamps"]) == 300, err.decode()[-500:]
