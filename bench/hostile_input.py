"""Hostile input, figures and cost (run on demand): ``python bench/hostile_input.py``.

The figures table (issue 26), each figure beside a reference measured in the same run:

- link faults: a TCP suit that closes right after a frame (20 runs) and a pseudo-terminal whose
  suit end closes after the last frame (5 runs, where there are ptys): faults tried, runs the
  host survived (link *gone*, no exception, frames in order), frames lost; reference: frames
  the suits sent;
- bad inputs: the hostile-input corpus (tools/hostile_corpus.py) through every command that
  reads a recording or a configuration: inputs tried, tracebacks, wrong outputs; reference: the
  intact control recording through the same commands;
- datagrams: the UDP attacks of tools/hostile_peers.py (one datagram during a pause, a replayed
  signed run, a spoofer on the real session, floods, fuzz) against a real receiver, with and
  without a shared key: datagrams forged, forged frames accepted; reference: the real sender's
  frames delivered.

``--quick`` skips the cost section. Then the cost of hostile input:

- Legacy pickle reader on crafted files (every few bytes a record start whose string never
  ends) of 12 KB … 800 KB, beside an intact legacy file of the same size (reference): the
  time must grow linearly with the size.
- UDP receiver: CPU per datagram with a sequence jump of 40,000 at every datagram, beside
  in-order datagrams (reference).
- Recording headers at the 16 MiB bound (issue 43: the depth check was quadratic on runs of
  ``\\"``): seconds and peak memory above the baseline (a recording with a small header) to
  read the header alone, and for a whole ``bpms filter`` of the file, each in a new process.
  The bound is 1 s and 100 MB (``--headers`` runs this section alone).
"""

from __future__ import annotations

import pickle
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import contextlib

from bpms.io.legacy_raw import read_legacy_raw
from bpms.io.rawfile import RawFileError
from bpms.io.udp.sequence import SequenceTracker

ROOT = Path(__file__).resolve().parents[1]
FRAME = b"$#" + bytes(336) + b"#$"


def timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def read(path: Path) -> None:
    with contextlib.suppress(RawFileError):
        read_legacy_raw(path)


def legacy() -> None:
    good = pickle.dumps([1.0, FRAME], protocol=0)
    print("legacy pickle reader: size, crafted s, intact s (reference), crafted s per MB")
    with tempfile.TemporaryDirectory() as tmp:
        for kb in (12, 48, 200, 800):
            crafted = Path(tmp) / "crafted.raw"
            crafted.write_bytes(good + b"(lS" * (kb * 1024 // 3))
            intact = Path(tmp) / "intact.raw"
            intact.write_bytes(good * max(1, kb * 1024 // len(good)))
            tc, ti = timed(lambda: read(crafted)), timed(lambda: read(intact))  # noqa: B023
            print(f"  {kb:5d} KB  {tc:7.3f} s  {ti:7.3f} s  {tc / (kb / 1024):7.2f} s/MB")


def udp() -> None:
    n = 20_000
    for label, step in (("in order (reference)", 1), ("gaps of 2,999 (plausible)", 3000),
                        ("jumps of 40,000 (held)", 40_000)):
        t = SequenceTracker()
        seq = 0
        start = time.perf_counter()
        for _ in range(n):
            t.observe(1, seq)
            seq = (seq + step) % (1 << 32)
        per = (time.perf_counter() - start) / n
        print(f"UDP sequence tracking, {label:22}: {per * 1e6:6.2f} µs per datagram")


_HEADER_PROBE = """
import sys, time, tracemalloc
from bpms.io.raw_layout import read_preamble
from bpms.io.rawfile import RawFileError
read_preamble(sys.argv[2])  # a small header first: everything imported
tracemalloc.start()  # Python's and numpy's allocations from here on
t = time.perf_counter()
try:
    read_preamble(sys.argv[1])
    what = "read"
except RawFileError as exc:
    what = "refused: " + str(exc).split(": ", 1)[1][:60]
dt = time.perf_counter() - t
print(dt, tracemalloc.get_traced_memory()[1] / 1e6, what)
"""


def _header_files(folder: Path) -> dict[str, Path]:
    """Recordings of the intact 6 s corpus body with absurd headers at the 16 MiB bound."""
    import json
    import struct

    from bpms.firmware.sim.session import simulate
    from bpms.io.rawfile import new_header, write_raw

    rec = simulate(6.0, seed=26)
    small = folder / "small.bpmsraw"
    header = new_header(calibration=rec.calibration.values, source="bench")
    write_raw(small, 1.7e9 + rec.t, rec.frames, header)
    data = small.read_bytes()
    length = struct.unpack_from("<I", data, 10)[0]
    body = data[16 + length:]
    cap = 16 * 1024 * 1024 - 64
    texts = {
        "16 MiB of \\\" in a string (unterminated)": b'{"notes": "' + b'\\"' * (cap // 2),
        "16 MiB of \\\" in a string (closed)":
            b'{"notes": "' + b'\\"' * (cap // 2 - 8) + b'"}',
        "15 MiB of notes, a valid header": json.dumps(
            {**header, "notes": "x" * (15 * 1024 * 1024)}).encode(),
        "16 MiB of \"[ pairs": b'{"a": ' + b'"[' * (cap // 2) + b"}",
    }
    out = {"small header (reference)": small}
    for k, (name, text) in enumerate(texts.items()):
        text += b" " * ((-(16 + len(text))) % 16)
        path = folder / f"header{k}.bpmsraw"
        path.write_bytes(data[:10] + struct.pack("<I", len(text)) + text + body)
        out[name] = path
    return out


def headers() -> None:
    import os
    import subprocess

    print("recording headers: reading the header alone (s, MB allocated at the peak), then a "
          "whole bpms filter (s, peak resident MB, beside the small header's)")
    with tempfile.TemporaryDirectory() as tmp:
        files = _header_files(Path(tmp))
        small = files["small header (reference)"]
        for name, path in files.items():
            run = subprocess.run([sys.executable, "-c", _HEADER_PROBE, str(path), str(small)],
                                 capture_output=True, text=True, cwd=ROOT, timeout=600)
            seconds, mb, what = [*run.stdout.split(" ", 2), "", "", run.stderr[-200:]][:3]
            t = time.perf_counter()
            whole = subprocess.Popen([sys.executable, "-m", "bpms", "filter", str(path), "-o",
                                      str(Path(tmp) / "f.csv"), "--force"], cwd=ROOT,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            _, status, usage = os.wait4(whole.pid, 0)
            whole.returncode = os.waitstatus_to_exitcode(status)
            dt = time.perf_counter() - t
            print(f"  {name:42} header {float(seconds or 'nan'):5.3f} s "
                  f"{float(mb or 'nan'):5.1f} MB  {what.strip()[:46]:46}  filter exit "
                  f"{whole.returncode} {dt:4.1f} s {usage.ru_maxrss / 1024:4.0f} MB")


def _tool(name: str):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, ROOT / "tools" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def link_faults() -> tuple[str, str]:
    from bpms.firmware.sim.server import pty_available

    peers = _tool("hostile_peers")
    tried = survived = lost = sent = 0
    runs = [("tcp", 8)] * 20 + ([("pty", 10 + k) for k in range(5)] if pty_available() else [])
    for kind, n in runs:
        tried += 1
        sent += n
        try:
            got, state = (peers.closing_tcp_run(n) if kind == "tcp"
                          else peers.closing_pty_run(n))
        except Exception as exc:  # a fault the host did not survive
            print(f"  {kind}: {type(exc).__name__}: {exc}")
            lost += n
            continue
        ok = state.value == "gone" and got == list(range(len(got)))
        survived += ok
        lost += n - len(got)
    return (f"{tried} / {survived} / {lost}", f"{sent} frames sent")


def bad_inputs() -> tuple[str, str]:
    corpus_tool = _tool("hostile_corpus")
    with tempfile.TemporaryDirectory() as tmp:
        corpus = corpus_tool.Corpus(tmp)
        totals = corpus_tool.run_all(corpus)
        control = [corpus.check(cmd, case) for cmd, case in corpus_tool.pairs()
                   if case.name == "intact"]
    ok = sum(v.ok for v in control)
    for line in totals.failures:
        print("  " + line)
    print(corpus_tool.table(totals.verdicts))
    return (f"{totals.tried} / {totals.tracebacks} / {totals.wrong}",
            f"control {ok}/{len(control)} correct")


def datagrams() -> list[tuple[str, str, str]]:
    peers = _tool("hostile_peers")
    results = peers.udp_attacks()
    for r in results:
        print(f"  {r.name}: forged {r.forged}, accepted {r.accepted}; real frames "
              f"{r.real_delivered}/{r.real_sent}; {r.detected}")
    rows = []
    for keyed, label in ((True, "with a key"), (False, "without a key")):
        mine = [r for r in results if ("(key)" in r.name) == keyed]
        rows.append((f"datagrams forged / accepted, {label}",
                     f"{sum(r.forged for r in mine)} / {sum(r.accepted for r in mine)}",
                     f"real frames delivered {sum(r.real_delivered for r in mine)}/"
                     f"{sum(r.real_sent for r in mine)}"))
    return rows


def figures() -> None:
    rows = [("link faults tried / survived / frames lost", *link_faults()),
            ("bad inputs tried / tracebacks / wrong outputs", *bad_inputs()),
            *datagrams()]
    width = max(len(r[0]) for r in rows)
    print(f"{'figure':<{width}}  value  (reference)")
    for name, value, reference in rows:
        print(f"{name:<{width}}  {value}  ({reference})")


if __name__ == "__main__":
    import argparse
    import logging

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the figures table only")
    parser.add_argument("--headers", action="store_true", help="the recording headers only")
    args = parser.parse_args()
    if args.headers:
        headers()
        sys.exit(0)
    logging.getLogger().setLevel(logging.CRITICAL)  # the corpus's warnings are expected
    figures()
    if not args.quick:
        legacy()
        udp()
        headers()
