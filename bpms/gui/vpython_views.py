"""VPython scripting views (the ``vpython`` extra): the original suite's 3D routines, re-done.

- :class:`BodyScene`: the stick figure (cylinders, joint spheres, optional IMU axis arrows) on a
  ground grid, updated from segment orientations ``C [18, 3, 3]`` or joint positions
  ``[21, 3]`` (NED metres), e.g. a :class:`bpms.filter.processor.Result` row or a live
  :class:`bpms.pipeline.session.PoseSample`;
- :class:`SingleIMUView`: one IMU as an axis triad or a box, from a DCM ``[3, 3]``
  (body or segment axes → NED);
- :func:`play`: animate a processed recording at its own pace;
- :func:`open_browser_view`: what the GUI's "Browser 3D view" button calls: a child process
  (``python -m bpms.gui.vpython_views --stdin``) draws the figure in a browser tab, fed the
  newest segment orientations on every display tick through a pipe.

VPython serves a page over HTTP and talks to it over a websocket; ``import vpython`` starts
both servers, opens a browser tab and *waits until a browser connects*. So vpython is imported
only when a scene is built, never when bpms or the GUI is imported. Set
``VPYTHON_NO_LAUNCH_BROWSER=1`` (and ``VPYTHON_HTTP_PORT``) to open the page yourself.

Frames: scenes use the display frame of :mod:`bpms.gui.view3d_geometry` (x north, y west,
z up, metres; ground z = 0).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import subprocess
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any

import numpy as np

from bpms.filter.body_model import BODY_POINTS, joint_positions
from bpms.gui.view3d_geometry import (
    AXIS_COLOURS,
    AXIS_IMUS,
    AXIS_LENGTH_M,
    AXIS_SEGMENTS,
    CALIBRATION_POSE,
    JOINT_COLOUR,
    NED_TO_DISPLAY,
    SEG_COLOURS,
    SEG_END,
    SEG_START,
    to_display,
)
from bpms.io.options import BodyOptions

#: Bytes per pipe message of the browser view: C [18, 3, 3] float64.
MESSAGE_BYTES = 18 * 9 * 8

_NAMES = {p.imu: p.name for p in BODY_POINTS}


def vpython_problem() -> str | None:
    """Why the vpython views are unavailable (one line), or None. Does not import vpython."""
    if importlib.util.find_spec("vpython") is None:
        return "vpython is not installed (pip install 'bpms[vpython]')"
    return None


def browser_problem() -> str | None:
    """Why no web browser can be opened for the browser view (one line), or None; None also
    when vpython is told not to launch one (``VPYTHON_NO_LAUNCH_BROWSER``: the user opens
    the page)."""
    import webbrowser

    if os.environ.get("VPYTHON_NO_LAUNCH_BROWSER"):
        return None
    try:
        webbrowser.get()
    except webbrowser.Error:
        return ("no web browser could be opened for it (install one, or name it in the "
                "BROWSER environment variable)")
    return None


def _vp() -> ModuleType:
    """Import vpython (starts its servers and waits for a browser: see the module doc)."""
    import vpython

    return vpython


def _vec(vp: ModuleType, v: Sequence[float]) -> Any:
    """A vpython vector (a position, a direction or an RGB colour)."""
    return vp.vector(float(v[0]), float(v[1]), float(v[2]))


def ground_grid(vp: ModuleType, size_m: float = 2.0, step_m: float = 0.5) -> list[Any]:
    """Grey lines on z = 0 from -size to +size metres."""
    lines = []
    for v in np.arange(-size_m, size_m + step_m / 2, step_m):
        grey = vp.vector(0.45, 0.45, 0.45)
        lines.append(vp.curve(pos=[vp.vector(v, -size_m, 0), vp.vector(v, size_m, 0)],
                              color=grey))
        lines.append(vp.curve(pos=[vp.vector(-size_m, v, 0), vp.vector(size_m, v, 0)],
                              color=grey))
    return lines


class BodyScene:
    """The stick figure in its own vpython canvas.

    lengths: segment lengths (default docs/body-model.md); show_axes: draw each IMU's axes (red x,
    green y, blue z, segment axes); keys in the browser: x/y/z view along an axis, d toggle
    the axes, r reset the view (as in the Qt window).
    """

    def __init__(self, lengths: BodyOptions | None = None, *, title: str = "BPMS 3D body view",
                 show_axes: bool = False, width: int = 500, height: int = 650) -> None:
        vp = self.vp = _vp()
        self.lengths = lengths or BodyOptions()
        self.canvas = vp.canvas(title=title, width=width, height=height,
                                background=vp.color.black)
        self.canvas.select()
        self.reset_view()
        self.grid = ground_grid(vp)
        points = to_display(CALIBRATION_POSE)
        self.bones = [vp.cylinder(pos=_vec(vp, points[a]), axis=_vec(vp, points[b] - points[a]),
                                  radius=0.015, color=_vec(vp, c))
                      for a, b, c in zip(SEG_START, SEG_END, SEG_COLOURS, strict=True)]
        self.joints = [vp.sphere(pos=_vec(vp, p), radius=0.025, color=_vec(vp, JOINT_COLOUR))
                       for p in points]
        self.axes = [[vp.arrow(pos=vp.vector(0, 0, 0), axis=vp.vector(AXIS_LENGTH_M, 0, 0),
                               shaftwidth=0.01, color=_vec(vp, c), visible=show_axes)
                      for c in AXIS_COLOURS] for _ in AXIS_IMUS]
        self.show_axes = show_axes
        self.canvas.bind("keydown", self._on_key)

    def reset_view(self) -> None:
        vp = self.vp
        self.canvas.up = vp.vector(0, 0, 1)
        self.canvas.center = vp.vector(0, 0, 0.9)
        self.canvas.forward = vp.vector(-0.8, -0.55, -0.25)
        self.canvas.range = 1.2

    def look_along(self, axis: str) -> None:
        """View along display axis 'x', 'y' or 'z' (from +x, from +y, from above)."""
        vp = self.vp
        forward = {"x": (-1, 0, 0), "y": (0, -1, 0), "z": (0, 0, -1)}[axis]
        self.canvas.up = vp.vector(1, 0, 0) if axis == "z" else vp.vector(0, 0, 1)
        self.canvas.forward = vp.vector(*forward)

    def set_axes_visible(self, visible: bool) -> None:
        self.show_axes = visible
        for triad in self.axes:
            for arrow in triad:
                arrow.visible = visible

    def _on_key(self, evt: Any) -> None:
        key = str(getattr(evt, "key", "")).lower()
        if key in ("x", "y", "z"):
            self.look_along(key)
        elif key == "d":
            self.set_axes_visible(not self.show_axes)
        elif key == "r":
            self.reset_view()

    def update(self, C: np.ndarray | None = None, positions: np.ndarray | None = None) -> None:
        """Draw a pose: segment orientations ``C [18, 3, 3]`` (segment → NED) and/or joint
        positions ``[21, 3]`` (NED metres, lowest foot on the ground; computed from C when
        None). Segments with unknown (NaN) ends are hidden."""
        vp = self.vp
        if positions is None:
            if C is None:
                raise ValueError("update() needs C or positions")
            positions = joint_positions(np.asarray(C), self.lengths)
        points = to_display(positions)
        finite = np.isfinite(points).all(axis=1)
        for bone, a, b in zip(self.bones, SEG_START, SEG_END, strict=True):
            bone.visible = bool(finite[a] and finite[b])
            if bone.visible:
                bone.pos = _vec(vp, points[a])
                bone.axis = _vec(vp, points[b] - points[a])
        for sphere, p, ok in zip(self.joints, points, finite, strict=True):
            sphere.visible = bool(ok)
            if ok:
                sphere.pos = _vec(vp, p)
        if C is None:
            return
        mid = 0.5 * (points[SEG_START[AXIS_SEGMENTS]] + points[SEG_END[AXIS_SEGMENTS]])
        for triad, imu, m in zip(self.axes, AXIS_IMUS, mid, strict=True):
            axes = np.asarray(C[imu]).T @ NED_TO_DISPLAY * AXIS_LENGTH_M
            ok = np.isfinite(axes).all() and np.isfinite(m).all()
            for arrow, axis in zip(triad, axes, strict=True):
                arrow.visible = bool(ok and self.show_axes)
                if ok:
                    arrow.pos = _vec(vp, m)
                    arrow.axis = _vec(vp, axis)

    def update_sample(self, sample: Any) -> None:
        """Draw a live :class:`PoseSample` (or anything with ``C`` and ``joint_positions``)."""
        self.update(sample.C, sample.joint_positions)


class SingleIMUView:
    """One IMU in its own small canvas: fixed green world axes plus the IMU as an axis triad
    (``mode="axis"``: red x, green y, blue z) or a flat box with an arrow along x
    (``mode="box"``), as the original's SingleSensor3DView."""

    def __init__(self, imu: int, mode: str = "axis", *, title: str | None = None,
                 size: int = 250) -> None:
        if mode not in ("axis", "box"):
            raise ValueError(f"mode must be 'axis' or 'box', not {mode!r}")
        vp = self.vp = _vp()
        self.imu, self.mode = imu, mode
        name = _NAMES.get(imu, f"imu{imu}")
        self.canvas = vp.canvas(title=title or f"IMU {imu} ({name}) 3D view", width=size,
                                height=size, background=vp.color.black, range=1.6,
                                up=vp.vector(0, 0, 1), forward=vp.vector(-0.5, -0.5, -0.5))
        self.canvas.select()
        green = vp.color.green
        for axis, text in (((1, 0, 0), "N"), ((0, 1, 0), "W"), ((0, 0, 1), "Up")):
            vp.arrow(axis=vp.vector(*axis), shaftwidth=0.02, color=green)
            vp.label(pos=vp.vector(*axis), text=text, box=False, opacity=0)
        if mode == "axis":
            self.arrows = [vp.arrow(axis=vp.vector(*np.eye(3)[k]), shaftwidth=0.04,
                                    color=_vec(vp, AXIS_COLOURS[k])) for k in range(3)]
        else:
            self.body = vp.box(length=1.0, height=0.05, width=0.5, color=vp.color.red)
            self.pointer = vp.arrow(axis=vp.vector(0.8, 0, 0), shaftwidth=0.06,
                                    color=vp.color.yellow)

    def update(self, R: np.ndarray) -> None:
        """Draw the orientation ``R [3, 3]`` (IMU or segment axes → NED)."""
        vp = self.vp
        M = NED_TO_DISPLAY @ np.asarray(R, dtype=np.float64)  # columns: IMU axes, display
        if not np.isfinite(M).all():
            return
        if self.mode == "axis":
            for k, arrow in enumerate(self.arrows):
                arrow.axis = _vec(vp, M[:, k])
        else:
            up = _vec(vp, -M[:, 2])  # IMU z is down
            self.body.axis = _vec(vp, M[:, 0])
            self.body.up = up
            self.body.length = 1.0
            self.pointer.axis = _vec(vp, 0.8 * M[:, 0])
            self.pointer.up = up


def play(result: Any, scene: BodyScene, *, imu_views: Sequence[SingleIMUView] = (),
         rate_hz: float = 50.0, start: int = 0, stop: int | None = None) -> None:
    """Animate a :class:`bpms.filter.processor.Result` (frames ``start:stop``) at ``rate_hz``
    frames/s; ``imu_views`` follow their IMU's segment orientation ``C``."""
    vp = scene.vp
    C, positions = result.C, result.joint_positions
    for i in range(start, len(C) if stop is None else min(stop, len(C))):
        vp.rate(rate_hz)
        scene.update(C[i], positions[i])
        for view in imu_views:
            view.update(C[i, view.imu])


# -- the GUI's "Browser 3D view" -----------------------------------------------------------
class BrowserView:
    """A child process drawing the figure in a browser, fed over a pipe (see module doc).

    ``feed(samples)`` is a ``SessionModel.samplesArrived`` slot: it writes the newest sample's
    ``C`` without blocking; when the child is slow the message is dropped (counted)."""

    def __init__(self, env: dict[str, str] | None = None) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "bpms.gui.vpython_views", "--stdin"],
            stdin=subprocess.PIPE, env={**os.environ, **(env or {})})
        assert self.process.stdin is not None
        self._fd = self.process.stdin.fileno()
        os.set_blocking(self._fd, False)
        self.dropped = 0
        self.sent = 0

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    def send(self, C: np.ndarray) -> bool:
        """Send one pose ``C [18, 3, 3]``; False (dropped) when the pipe is full or closed."""
        data = np.ascontiguousarray(C, dtype="<f8").tobytes()
        try:
            # ≤ PIPE_BUF (4096) bytes: POSIX writes it whole or not at all (EAGAIN).
            os.write(self._fd, data)
        except OSError:  # BlockingIOError (child lagging), BrokenPipeError (child gone)
            self.dropped += 1
            return False
        self.sent += 1
        return True

    def feed(self, samples: list[Any]) -> None:
        if samples and self.alive:
            self.send(samples[-1].C)

    def close(self, timeout: float = 5.0) -> None:
        """Close the pipe (the child exits at EOF); a child still waiting for its browser
        does not read the pipe, so it is terminated after 1 s (killed after ``timeout``)."""
        if self.process.stdin is not None and not self.process.stdin.closed:
            with contextlib.suppress(OSError):
                self.process.stdin.close()
        for stop, wait in ((None, min(1.0, timeout)), (self.process.terminate, timeout),
                           (self.process.kill, timeout)):
            if stop is not None:
                stop()
            try:
                self.process.wait(wait)
                return
            except subprocess.TimeoutExpired:
                continue


def open_browser_view(model: Any) -> BrowserView:
    """Start a browser 3D view following a :class:`bpms.gui.model.SessionModel`.

    Raises RuntimeError (one line) when the vpython extra is missing or no web browser can
    be opened; the GUI shows it.
    The caller keeps the returned object and calls ``close()`` when done."""
    problem = vpython_problem() or browser_problem()
    if problem is not None:
        raise RuntimeError(problem)
    view = BrowserView()
    model.samplesArrived.connect(view.feed)
    if getattr(model, "latest", None) is not None:
        view.feed([model.latest])
    return view


def _serve_stdin() -> int:
    scene = BodyScene(title="BPMS 3D body view (browser)")
    stream = sys.stdin.buffer
    while True:
        data = stream.read(MESSAGE_BYTES)
        if len(data) < MESSAGE_BYTES:
            return 0
        C = np.frombuffer(data, dtype="<f8").reshape(18, 3, 3)
        if np.isfinite(C).any():
            scene.update(C)


def _play_file(path: str, rate_hz: float, imu: int | None, mode: str) -> int:
    from bpms.filter.door import process_file

    result = process_file(path)
    scene = BodyScene(title=f"BPMS 3D body view: {os.path.basename(path)}")
    views = [SingleIMUView(imu, mode)] if imu is not None else []
    play(result, scene, imu_views=views, rate_hz=rate_hz)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bpms.gui.vpython_views",
                                     description="VPython 3D views of BPMS data in a browser.")
    parser.add_argument("--stdin", action="store_true",
                        help="draw poses C [18,3,3] float64 read from stdin (the GUI's feed)")
    parser.add_argument("file", nargs="?", help="raw recording to filter and play")
    parser.add_argument("--rate", type=float, default=50.0, help="frames/s (default 50)")
    parser.add_argument("--imu", type=int, help="also show this IMU alone (0..17)")
    parser.add_argument("--mode", choices=("axis", "box"), default="axis")
    args = parser.parse_args(argv)
    problem = vpython_problem()
    if problem is not None:
        print(problem, file=sys.stderr)
        return 2
    if args.stdin:
        code = _serve_stdin()
        # vpython's server threads are not daemons on Linux: end now that the GUI closed us.
        sys.stdout.flush()
        os._exit(code)
    if not args.file:
        parser.error("give a recording to play, or --stdin")
    return _play_file(args.file, args.rate, args.imu, args.mode)


if __name__ == "__main__":
    sys.exit(main())
