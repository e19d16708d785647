"""Live-stream forwarding over UDP (docs/udp.md), one module per job:

- :mod:`~bpms.io.udp.codec`: the datagram layout, encoding and decoding, ``DatagramError``;
- :mod:`~bpms.io.udp.addresses`: ``host:port`` parsing, multicast, ``UdpConfigError``;
- :mod:`~bpms.io.udp.auth`: the shared key and the HMAC-SHA256 tag;
- :mod:`~bpms.io.udp.sender`: ``UdpForwarder``;
- :mod:`~bpms.io.udp.sequence`: ``SequenceTracker`` (loss, duplicates, reordering);
- :mod:`~bpms.io.udp.receiver`: ``UdpSource``.

Import each name from the module that owns it. Nothing here imports Qt.
"""
