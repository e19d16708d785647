#!/usr/bin/env bash
# Build the standalone bundle for computers without Python (docs/release.md):
#
#   bash tools/build_bundle.sh          → dist/bpms/bpms (Windows: dist\bpms\bpms.exe)
#
# A virtualenv of its own (build/bundle/venv) gets BPMS Suite from this checkout with the
# figures and lsl extras, and PyInstaller; PyInstaller then freezes it with
# tools/bundle/bpms.spec. Zip dist/bpms/ to hand it out. The bundle runs on the operating
# system (and CPU architecture) it was built on: build it on each.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${BPMS_BUNDLE_BUILD:-build/bundle}
PYTHON=${PYTHON:-python3}
log() { printf '[build_bundle] %s\n' "$*" >&2; }

start=$(date +%s)
if [ ! -d "$BUILD/venv" ]; then
  log "creating $BUILD/venv"
  "$PYTHON" -m venv "$BUILD/venv"
fi
if [ -x "$BUILD/venv/bin/python" ]; then VPY="$BUILD/venv/bin/python"; else VPY="$BUILD/venv/Scripts/python.exe"; fi
log "installing bpms[figures,lsl] and PyInstaller"
"$VPY" -m pip install -q --disable-pip-version-check ".[figures,lsl]" "pyinstaller>=6.0"
log "freezing (pyinstaller tools/bundle/bpms.spec)"
"$VPY" -m PyInstaller --noconfirm --clean --log-level WARN --distpath dist \
  --workpath "$BUILD/work" tools/bundle/bpms.spec
size=$(du -sh dist/bpms | cut -f1)
log "dist/bpms: $size, built in $(( $(date +%s) - start )) s"
