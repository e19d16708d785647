"""``bpms ports [--probe]``: the serial ports that may lead to the suit, with what the operating
system says each one is (``COM5  Standard Serial over Bluetooth link``, ``/dev/rfcomm0``,
``/dev/cu.RN41-...``). ``--probe`` also asks each port whether it is the suit (sends 0x02 and
waits for ``BPMS``, as the automatic discovery does). See docs/suit.md.
"""

from __future__ import annotations

import argparse

from bpms.commands._shared import LONGEST_S, number


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = sub.add_parser("ports", help="list the serial ports (and find the suit with --probe)")
    p.add_argument("--probe", action="store_true", help="ask every port whether it is the suit")
    p.add_argument("--timeout", type=number(float, 0, LONGEST_S, above=True),
                   default=1.0, metavar="S",
                   help="wait for the answer per port, s (default 1)")
    return p


def run(args: argparse.Namespace) -> int:
    from bpms.io.link import describe_candidate_ports, discover_suit

    ports = describe_candidate_ports()
    if not ports:
        print("no serial port found (pair the suit over Bluetooth first; see docs/suit.md)")
        return 0
    width = max(len(device) for device, _ in ports)
    for device, description in ports:
        answer = ""
        if args.probe:
            found = discover_suit([device], timeout_s=args.timeout)
            answer = "  <- the suit" if found else "  (no answer)"
        print(f"{device:<{width}}  {description or '-'}{answer}", flush=True)
    return 0
