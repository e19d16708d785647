"""The simulated suit: scripted motion, sensor model, arbiter emulator and transports.

- :mod:`.motion` scripted body motion (exact ground truth);
- :mod:`.sensors` orientations and motion → raw counts;
- :mod:`.session` offline generation (:func:`~.session.simulate`);
- :mod:`.arbiter` the arbiter board's protocol state machine (transport-independent);
- :mod:`.server` pseudo-terminal and TCP transports.
"""
