"""The suit source reopens its port after a read error (the device vanished and came back),
against the simulated suit over a real TCP socket. The planted-fault script's "link never
reopens" fault must fail here."""

from __future__ import annotations

import pytest
from waiting import wait_until

from bpms.firmware.sim.arbiter import Arbiter, MotionSource
from bpms.firmware.sim.server import TcpServer
from bpms.io.options import SerialOptions
from bpms.pipeline.sources import SuitFrameSource

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def motion() -> MotionSource:
    return MotionSource.simulated(duration_s=20.0, seed=11)


def test_reopens_the_port_after_a_read_error(motion):
    first = TcpServer(Arbiter(motion)).start()
    port = first.port
    source = SuitFrameSource(first.url, SerialOptions(discovery_timeout_s=0.5), retry_s=0.2)
    events = []

    def pump(n: int) -> bool:
        events.extend(source.read(0.05))
        return len(events) >= n

    try:
        assert wait_until(lambda: pump(10), timeout=15.0), "no frames from the simulated suit"
        assert source.connections == 1 and events[0].discontinuity
        first.stop()  # the device vanishes: the next reads fail
        assert wait_until(lambda: pump(10**9) or source.status().state in ("gone", "reopening"),
                          timeout=10.0), "the read error was not noticed"
        assert source.links_lost == 1 and source.connected_port is None
        before = len(events)
        second = TcpServer(Arbiter(motion), port=port).start()  # it comes back, same address
        try:
            assert wait_until(lambda: pump(before + 10), timeout=15.0), (
                f"the port was not reopened: {source.status()}")
            assert source.connections == 2
            assert events[before].discontinuity  # the filters re-initialise
            assert not any(e.discontinuity for e in events[before + 1:])
            assert source.status().state == "streaming"
        finally:
            source.close()
            second.stop()
    finally:
        source.close()
        first.stop()
