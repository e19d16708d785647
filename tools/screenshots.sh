#!/bin/sh
# Save docs/screenshots/*.png under a virtual X display (see tools/screenshots.py).
# PYTHON overrides the interpreter (default: the repository's .venv).
cd "$(dirname "$0")/.." && QT_QPA_PLATFORM=xcb exec xvfb-run -a -s "-screen 0 1920x1080x24" "${PYTHON:-.venv/bin/python}" tools/screenshots.py "$@"
