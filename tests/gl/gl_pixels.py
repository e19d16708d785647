"""Pixel measures of grabbed GL frames, shared by the scripts in tests/gl."""

from __future__ import annotations

import time

import numpy as np
from PyQt6.QtGui import QImage
from PyQt6.QtWidgets import QApplication

from bpms.gui.avatar import LEFT_ARM, LEFT_LEG, RIGHT_ARM, RIGHT_LEG, TRUNK
from bpms.gui.view3d_geometry import AXIS_COLOURS


def pump(app: QApplication, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        app.processEvents()
        time.sleep(0.005)


def pixels(image: QImage) -> np.ndarray:
    image = image.convertToFormat(QImage.Format.Format_RGB888)
    h, w, stride = image.height(), image.width(), image.bytesPerLine()
    buf = np.frombuffer(image.constBits().asstring(stride * h), np.uint8)
    return buf.reshape(h, stride)[:, : w * 3].reshape(h, w, 3)


def hue(rgb: np.ndarray, *colours: tuple[float, ...], cos: float = 0.995) -> int:
    """Pixels of one of ``colours`` whatever the shading (the shaded solid scales a colour's
    brightness, not its direction in RGB space); dark pixels are left out."""
    p = rgb.reshape(-1, 3).astype(float)
    bright = p.max(axis=1) > 40
    unit = p / np.maximum(np.linalg.norm(p, axis=1), 1e-9)[:, None]
    hit = np.zeros(len(p), bool)
    for colour in colours:
        c = np.array(colour[:3], float)
        hit |= unit @ (c / np.linalg.norm(c)) > cos
    return int((hit & bright).sum())


def measure(image: QImage) -> dict:
    rgb = pixels(image)
    spread = rgb.max(axis=2).astype(int) - rgb.min(axis=2)
    return {
        "size": [image.width(), image.height()],
        "non_background": int((rgb.max(axis=2) > 30).sum()),
        "right": hue(rgb, RIGHT_ARM, RIGHT_LEG),
        "left": hue(rgb, LEFT_ARM, LEFT_LEG),
        "grey": int(((spread < 8) & (rgb.max(axis=2) > 70)).sum()),
        "axis_blue": hue(rgb, AXIS_COLOURS[2], cos=0.98),
    }


def extent(image) -> dict:
    """Rows / columns holding figure pixels (both sides' hues or the trunk's grey)."""
    rgb = pixels(image)
    h, w, _ = rgb.shape
    mask = np.zeros(h * w, bool)
    flat = rgb.reshape(-1, 3).astype(float)
    unit = flat / np.maximum(np.linalg.norm(flat, axis=1), 1e-9)[:, None]
    # the trunk's grey needs a tighter match (the bluish floor grid is within 0.996 of it)
    # and more light than the shadow (the same hue, 51 at most)
    for colour, cos, light in ((RIGHT_ARM, 0.995, 40), (RIGHT_LEG, 0.995, 40),
                               (LEFT_ARM, 0.995, 40), (LEFT_LEG, 0.995, 40),
                               (TRUNK, 0.9995, 60)):
        c = np.array(colour[:3], float)
        mask |= (unit @ (c / np.linalg.norm(c)) > cos) & (flat.max(axis=1) > light)
    mask = mask.reshape(h, w)
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    return {"size": [w, h], "rows": [int(rows.min()), int(rows.max())] if len(rows) else None,
            "cols": [int(cols.min()), int(cols.max())] if len(cols) else None}
