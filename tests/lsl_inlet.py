"""Run as a separate process: resolve the five BPMS LSL streams, pull until ``frames`` samples
arrived on each data stream (or a deadline), print a JSON summary on stdout.

Written against pylsl's public API only (no bpms import): an independent receiver.
"""

from __future__ import annotations

import json
import sys
import time

import pylsl
import pylsl.util

NAMES = ("BPMS Segments", "BPMS Joint Angles", "BPMS Sensors", "BPMS Disturbance",
         "BPMS Events")
if len(sys.argv) > 3:  # a third argument: the stream names, comma-separated
    NAMES = tuple(sys.argv[3].split(","))
DATA_NAMES = [n for n in NAMES if n != "BPMS Events"]
#: a fourth argument: the data streams whose every sample is printed (comma-separated)
KEEP_ALL = set(sys.argv[4].split(",")) if len(sys.argv) > 4 else set()


def channel_labels(info) -> list[str]:
    out = []
    ch = info.desc().child("channels").child("channel")
    while not ch.empty():
        out.append(ch.child_value("label"))
        ch = ch.next_sibling()
    return out


LOST: set = set()


def pull(inlet, timeout):
    """(samples, stamps); nothing once the outlet has gone (the sender ended)."""
    try:
        return inlet.pull_chunk(timeout=timeout)
    except pylsl.util.LostError:
        LOST.add(id(inlet))
        return [], []


def main() -> None:
    frames, timeout = int(sys.argv[1]), float(sys.argv[2])
    deadline = time.monotonic() + timeout
    inlets = {}
    full = {}
    while len(inlets) < len(NAMES) and time.monotonic() < deadline:
        for info in pylsl.resolve_streams(wait_time=1.0):
            if info.name() in NAMES and info.name() not in inlets:
                inlet = pylsl.StreamInlet(info, max_buflen=360, recover=False)
                # the full description before the data connection: once every stream has
                # its consumer (a sender may wait for that), this process only pulls
                info = inlet.info(timeout=10)
                full[info.name()] = {
                    "type": info.type(), "channels": info.channel_count(),
                    "rate": info.nominal_srate(), "labels": channel_labels(info),
                    "convention": info.desc().child_value("convention"),
                    "units": sorted({u for u in [info.desc().child("channels")
                                                 .child("channel").child_value("unit")]})}
                inlets[info.name()] = inlet
    for inlet in inlets.values():
        inlet.open_stream(timeout=10)
    print("ready", file=sys.stderr, flush=True)
    data = {name: {"stamps": [], "values": []} for name in inlets}
    while time.monotonic() < deadline:
        # Keep up with the sender: liblsl drops what an inlet holds once the sender has gone
        # (LostError), so every stream is read at each turn; only the first one waits, a
        # little, for the next frame (which comes on every data stream at once).
        for k, (name, inlet) in enumerate(inlets.items()):
            samples, stamps = pull(inlet, 0.01 if k == 0 else 0.0)
            data[name]["stamps"] += stamps
            if name == "BPMS Events":
                data[name]["values"] += [s[0] for s in samples]
            elif name == "BPMS Disturbance" or name in KEEP_ALL:
                data[name]["values"] += samples  # every sample
            elif samples:
                data[name]["values"] = samples[-1][:8]  # the last sample's first channels
        if all(len(data[n]["stamps"]) >= frames for n in DATA_NAMES if n in data):
            break
        if len(LOST) == len(inlets):
            break
    # a short grace period for the last events
    end = time.monotonic() + 1.0
    while time.monotonic() < end and "BPMS Events" in inlets:
        samples, stamps = pull(inlets["BPMS Events"], 0.1)
        data["BPMS Events"]["stamps"] += stamps
        data["BPMS Events"]["values"] += [s[0] for s in samples]
    print(json.dumps({"info": full, "data": data}))


if __name__ == "__main__":
    main()
