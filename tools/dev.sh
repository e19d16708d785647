#!/usr/bin/env bash
# BPMS Suite developer entry point: prepares this machine, then runs one job.
#
#   bash tools/dev.sh app     set everything up and start BPMS on the simulated suit
#                             (a real suit is used instead when one answers)
#   bash tools/dev.sh test    set everything up and run the whole test suite, in a random
#                             order fixed by a seed (BPMS_TEST_SEED, default 46; printed)
#   bash tools/dev.sh test --load 2   the same with 2 CPU-bound processes running beside it
#   bash tools/dev.sh setup   only set up (virtualenv in .venv, Python and Debian packages)
#
# Everything that is missing is installed: a virtualenv with the package and its dev extra,
# and (when run as root with apt-get) the Debian packages for Xvfb, Qt's xcb platform and the
# AVR toolchain. Nothing is installed twice: a stamp file remembers the last install.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${BPMS_VENV:-.venv}
PY="$VENV/bin/python"

DEBIAN_PACKAGES=(
  xvfb xauth libgl1-mesa-dri libegl1 libgl1 libxkbcommon0 libxkbcommon-x11-0 libfontconfig1
  libglib2.0-0 libdbus-1-3 libxcb-icccm4 libxcb-image0 libxcb-keysyms1 libxcb-randr0
  libxcb-render-util0 libxcb-shape0 libxcb-xinerama0 libxcb-xfixes0 libxcb-cursor0
  g++ make gcc-avr avr-libc arduino-core-avr simavr libsimavr-dev libsimavrparts1
)

log() { printf '[dev.sh] %s\n' "$*" >&2; }

ensure_debian_packages() {
  command -v dpkg-query >/dev/null 2>&1 || { log "not a Debian system: skipping system packages"; return 0; }
  local missing=() p
  for p in "${DEBIAN_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    log "missing Debian packages (install them as root): ${missing[*]}"
    return 0
  fi
  log "installing Debian packages: ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

ensure_venv() {
  if [ ! -x "$PY" ]; then
    log "creating virtualenv $VENV"
    python3 -m venv "$VENV"
  fi
  local stamp="$VENV/.bpms-installed"
  if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
    log "installing bpms and its dev extra into $VENV"
    "$PY" -m pip install -q --upgrade pip >/dev/null
    "$PY" -m pip install -q -e ".[dev]"
    # OpenSim's Python package (tests/test_opensim_ik.py): pip wheels exist for Linux and
    # Windows only; elsewhere that test is skipped and says why.
    "$PY" -m pip install -q "opensim>=4.6" \
      || log "no OpenSim pip package for this platform: tests/test_opensim_ik.py is skipped"
    log "compiling the filters for this machine (bpms warmup)"
    "$VENV/bin/bpms" warmup || log "bpms warmup failed: the filters compile at their first use"
    touch "$stamp"
  fi
}

setup() {
  ensure_debian_packages
  ensure_venv
}

build_firmware() {
  # The AVR images and the simulator host that runs them (bpms sim --avr), into
  # bpms/firmware/build (ignored by git); make rebuilds only what changed. Without the tools
  # the firmware tests skip with the reason.
  local tool
  for tool in make g++ avr-gcc; do
    command -v "$tool" >/dev/null 2>&1 || { log "no $tool: the firmware is not built"; return 0; }
  done
  local targets=(host avr)
  if [ ! -d /usr/share/arduino/hardware/arduino/avr/cores/arduino ]; then
    log "no Arduino AVR core (arduino-core-avr): only the firmware's host tests are built"
    targets=(host)
  fi
  case "$(gcc -print-file-name=libsimavr.a 2>/dev/null)" in
    /*) [ "${targets[*]}" = "host avr" ] && targets+=(avr-suit) ;;
    *) log "no libsimavr.a (libsimavr-dev): the AVR simulator host is not built" ;;
  esac
  log "building the firmware (make ${targets[*]})"
  make --no-print-directory -s -C bpms/firmware -j2 "${targets[@]}" >/dev/null
}

start_load() {
  # $1 CPU-bound processes beside the suite (a busy CI machine); stopped by stop_load, by id.
  local n=$1 k
  LOAD_PIDS=()
  for ((k = 0; k < n; k++)); do
    "$PY" -c "while True: pass" &
    LOAD_PIDS+=("$!")
  done
  log "load: $n CPU-bound processes beside the suite (pids ${LOAD_PIDS[*]})"
}

stop_load() {
  local pid
  for pid in "${LOAD_PIDS[@]:-}"; do
    [ -n "$pid" ] || continue
    kill "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true  # a killed child's status (143) must not end the script
  done
  LOAD_PIDS=()
  return 0
}

run_tests() {
  # Options before pytest's own:
  #   --load N   run N CPU-bound processes beside the suite (also: BPMS_TEST_LOAD=N); the
  #              tests' deadlines scale with the machine's load (tests/deadlines.py)
  # The test files and tests run in a random order fixed by a seed (pytest-randomly): the
  # same order every run unless BPMS_TEST_SEED is set (a number, or "random" for a new one).
  local load=${BPMS_TEST_LOAD:-0}
  while [ $# -gt 0 ]; do
    case "$1" in
      --load) load=${2:?--load needs a number}; shift 2 ;;
      --load=*) load=${1#--load=}; shift ;;
      *) break ;;
    esac
  done
  case "$load" in ''|*[!0-9]*) log "--load wants a whole number, not '$load'"; return 2 ;; esac
  local seed=${BPMS_TEST_SEED:-46}
  if [ "$seed" = random ]; then seed=$((RANDOM * 32768 + RANDOM)); fi
  log "ruff check"
  "$VENV/bin/ruff" check bpms tests bench tools
  build_firmware
  log "pytest: random order, seed $seed (repeat with BPMS_TEST_SEED=$seed)"
  local rc=0
  # Modules load from cached bytecode, as installed (the tests start many `python -m bpms`
  # children); a crash in a child prints its Python stack.
  unset PYTHONDONTWRITEBYTECODE
  LOAD_PIDS=()
  if [ "$load" -gt 0 ]; then
    trap stop_load EXIT INT TERM
    start_load "$load"
  fi
  BPMS_TEST_LOAD=$load HYPOTHESIS_PROFILE=ci PYTHONFAULTHANDLER=1 \
    "$PY" -m pytest -q -p randomly --randomly-seed="$seed" "$@" || rc=$?
  stop_load
  log "pytest: seed was $seed, load $load"
  if [ "$rc" -eq 5 ]; then
    log "pytest collected no tests"
    return 1
  fi
  return "$rc"
}

job=${1:-app}
shift || true
case "$job" in
  setup) setup ;;
  test) setup; run_tests "$@" ;;
  app) setup; exec "$VENV/bin/bpms" "$@" ;;
  *) log "unknown job '$job' (use: app, test, setup)"; exit 2 ;;
esac
