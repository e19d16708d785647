"""The sensor calibration tool's core (docs/units.md), free of Qt.

- :mod:`.procedures` — gyroscope, accelerometer and magnetometer procedures as state machines
  fed with raw frames;
- :mod:`.ellipsoid` — the optional magnetometer ellipsoid fit (hard and soft iron);
- :mod:`.result` — merging into an existing table, the old-vs-new summary, quality figures;
- :mod:`.output` — reading the existing files and saving the legacy + modern pair;
- :mod:`.frames` — raw readings from any frame source (suit link, simulated suit).

The CLI (:mod:`bpms.commands.calibrate`) and the GUI wizard
(:mod:`bpms.gui.calibration_wizard`) drive these. See docs/calibration.md.
"""
