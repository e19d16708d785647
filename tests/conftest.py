"""Shared test set-up: hypothesis profiles and a headless Qt platform."""

from __future__ import annotations

import os
import tempfile

import pytest
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
# The folder goes when the session ends, so runs do not pile folders up in the temp folder.
_USER_ROOT_FOLDER = tempfile.TemporaryDirectory(prefix="bpms-test-user-")
_USER_ROOT = _USER_ROOT_FOLDER.name
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


@pytest.fixture(scope="session", autouse=True)
def _filters_compiled():
    """The numba filters compiled (first run on a machine) or loaded once, quietly, before any
    test: no test's output then depends on whether the compile notice appeared."""
    import io

    from bpms.filter.warmup import ensure_kernels

    ensure_kernels(stream=io.StringIO())


@pytest.fixture(autouse=True)
def _no_modal_question_blocks(monkeypatch):
    """A static ``QMessageBox.question`` (e.g. "Logging is on. Stop logging and close?" when a
    failed test leaves a window logging) would wait for a click forever under the offscreen
    platform: it answers Yes and is recorded instead, so a failure stays a failure, not a
    hang. Only patched where a test already imported Qt."""
    import sys

    widgets = sys.modules.get("PyQt6.QtWidgets")
    if widgets is None:
        yield
        return
    asked: list[str] = []

    def question(parent, title, text, *args, **kwargs):
        asked.append(text)
        return widgets.QMessageBox.StandardButton.Yes

    monkeypatch.setattr(widgets.QMessageBox, "question", staticmethod(question))
    yield


@pytest.fixture(scope="session")
def deadline_scale() -> float:
    """The factor every waiting deadline is multiplied by on this machine (tests/deadlines.py:
    the load per core, or BPMS_TEST_DEADLINE_SCALE). Printed in the run's header."""
    from deadlines import deadline_scale as scale

    return scale()


def pytest_report_header(config):
    from deadlines import deadline_scale as scale

    return f"bpms: deadlines scaled x{scale():.2f} (tests/deadlines.py)"


def pytest_collection_modifyitems(config, items):
    """Every test's pytest-timeout limit (its ``timeout`` mark, else the ini value) scaled
    like its deadlines (tests/deadlines.py): a test that waits longer on a loaded machine
    must not be cut off by a limit meant for a quiet one."""
    from deadlines import deadline_scale as scale

    factor = scale()
    if factor <= 1.0:
        return
    default = float(config.getini("timeout") or 0)
    for item in items:
        mark = item.get_closest_marker("timeout")
        limit = float(mark.args[0]) if mark is not None and mark.args else default
        if limit > 0:
            item.add_marker(pytest.mark.timeout(limit * factor), append=False)
