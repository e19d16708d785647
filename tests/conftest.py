"""Shared test set-up: hypothesis profiles and a headless Qt platform."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

# 2D Qt widgets render offscreen; OpenGL tests run in their own Xvfb subprocess.
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

settings.register_profile("dev", deadline=None, max_examples=100)
# CI: the same examples every run, so a green run means the same thing twice.
settings.register_profile("ci", deadline=None, max_examples=150, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "dev"))

# Every test starts from a fresh, empty per-user folder: a developer's own defaults never leak
# into the suite (bpms.io.userdirs reads these variables; subprocesses inherit them).
_USER_ROOT = __import__("tempfile").mkdtemp(prefix="bpms-test-user-")
for _variable, _sub in (("BPMS_CONFIG_DIR", "config"), ("BPMS_DATA_DIR", "data"),
                        ("BPMS_LOG_DIR", "log")):
    os.environ[_variable] = os.path.join(_USER_ROOT, _sub)


@__import__("pytest").fixture(autouse=True)
def _fresh_user_folder(tmp_path_factory, monkeypatch):
    """Each test its own empty per-user folder: defaults saved or GUI settings remembered by
    one test never reach the next."""
    root = tmp_path_factory.mktemp("user")
    for variable, sub in (("BPMS_CONFIG_DIR", "config"), ("BPMS_DATA_DIR", "data"),
                          ("BPMS_LOG_DIR", "log")):
        monkeypatch.setenv(variable, str(root / sub))
