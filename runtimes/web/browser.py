"""
Drive headless Chromium against an exported viewer (tests and benchmarks).

The folder is served on ``127.0.0.1`` by Python's :mod:`http.server` in a thread; the
page is opened with URL parameters (see ``assets/viewer.js``) that make it render,
measure frame times and POST a JSON report (frame times, the canvas pixels read back
with ``readPixels``) to ``/report`` on the same server.  :func:`screenshot` takes a
browser screenshot (``--screenshot``) of the canvas-only page instead.  :func:`open_page` drives
the page as a user does, through the DevTools protocol over a pipe (``--remote-debugging-pipe``:
JSON messages ending in a NUL byte on file descriptors 3 and 4 of Chromium): it evaluates
expressions in the page, taps and drags with emulated touch, resizes the viewport and takes
screenshots of the whole page.

Chromium runs with SwiftShader (a CPU implementation of WebGL2), no sandbox, a fresh
profile and no background network traffic::

    chromium --headless --no-sandbox --disable-gpu --use-angle=swiftshader ...

Examples
--------
>>> find_chromium() is None or find_chromium().name.startswith("chrom")   # doctest: +SKIP
True
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import urlencode

import numpy as np

__all__ = ["find_chromium", "chromium_flags", "serve", "BrowserReport", "run_viewer", "screenshot",
           "image_delta_e00", "Page", "open_page"]

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> Path | None:
    """The Chromium executable on PATH (Debian's package installs ``/usr/bin/chromium``)."""
    for name in CHROMIUM_NAMES:
        p = shutil.which(name)
        if p:
            return Path(p)
    return None


def chromium_flags(profile_dir: Path, width_px: int, height_px: int) -> list[str]:
    """Headless, software WebGL2 (SwiftShader through ANGLE), no network side traffic,
    sRGB output (no colour management of the canvas), device pixels = CSS pixels."""
    return ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--no-first-run", "--no-default-browser-check", "--disable-extensions",
            "--disable-features=Translate,MediaRouter,OptimizationHints",
            "--force-color-profile=srgb", "--force-device-scale-factor=1",
            "--hide-scrollbars", f"--user-data-dir={profile_dir}",
            f"--window-size={width_px},{height_px}"]


class _Handler(SimpleHTTPRequestHandler):
    def __init__(self, *a, reports=None, **kw):
        self._reports = reports
        super().__init__(*a, **kw)

    def log_message(self, *args) -> None:   # quiet
        pass

    def do_POST(self) -> None:  # noqa: N802 (http.server's name)
        n = int(self.headers.get("Content-Length", "0"))
        body = self.rfile.read(n)
        try:
            self._reports.append(json.loads(body))
        except ValueError:
            self._reports.append({"kind": "error", "error": "unreadable report"})
        self.send_response(204)
        self.end_headers()


@contextmanager
def serve(folder: Path):
    """Serve ``folder`` on an ephemeral localhost port; yields ``(base_url, reports)``."""
    reports: list[dict] = []
    handler = partial(_Handler, directory=str(folder), reports=reports)
    srv = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    th = threading.Thread(target=srv.serve_forever, daemon=True)
    th.start()
    try:
        yield f"http://127.0.0.1:{srv.server_address[1]}", reports
    finally:
        srv.shutdown()
        srv.server_close()


@dataclass
class BrowserReport:
    """What the page reported: ``rgba8`` (H, W, 4) uint8 top row first, frame times (ms)."""

    raw: dict
    rgba8: np.ndarray | None
    frame_ms: list[float]
    first_frame_ms: float | None
    gl_renderer: str
    wall_s: float


def _wait(proc, reports, want, timeout_s):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        hit = [r for r in reports if r.get("kind") in (want, "error")]
        if hit:
            return hit[0]
        if proc.poll() is not None and not reports:
            time.sleep(0.2)
            if not reports:
                break
        time.sleep(0.1)
    return None


def _stop_chromium(proc) -> None:
    """Stop Chromium and every process it started (its renderer, GPU and crash handlers run in
    its process group, and may still write into the profile after the browser itself exits)."""
    import signal

    def group(sig):
        try:
            os.killpg(proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    group(signal.SIGTERM)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass
    group(signal.SIGKILL)
    proc.wait()


@contextmanager
def _profile_dir():
    """A fresh Chromium profile folder, removed afterwards (retried while the last of
    Chromium's processes let go of it)."""
    d = tempfile.mkdtemp(prefix="lbscene-chromium-")
    try:
        yield d
    finally:
        for _ in range(50):
            try:
                shutil.rmtree(d)
                break
            except FileNotFoundError:
                break
            except OSError:
                time.sleep(0.1)
        else:
            shutil.rmtree(d, ignore_errors=True)


def run_viewer(folder: Path, *, size_px=(512, 384), bench: int = 10, timeout_s: float = 180.0,
               extra: dict | None = None, want: str = "frame", chromium: Path | None = None) -> BrowserReport:
    """Open the viewer in headless Chromium, let it render ``bench`` frames and return
    its report (raises RuntimeError with Chromium's output when none comes)."""
    chromium = chromium or find_chromium()
    if chromium is None:
        raise RuntimeError("chromium not found")
    w, h = size_px
    q = {"size": f"{w}x{h}", "bench": bench, "report": "/report", "shot": 1}
    q.update(extra or {})
    with serve(Path(folder)) as (base, reports), _profile_dir() as prof:
        url = f"{base}/index.html?{urlencode(q)}"
        t0 = time.monotonic()
        proc = subprocess.Popen([str(chromium), *chromium_flags(Path(prof), w, h),
                                 "--remote-debugging-port=0", url],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            rep = _wait(proc, reports, want, timeout_s)
        finally:
            proc.terminate()
            try:
                out = proc.communicate(timeout=10)[0]
            except subprocess.TimeoutExpired:
                out = b""
            _stop_chromium(proc)
            out = out or proc.communicate()[0]
        wall = time.monotonic() - t0
    if rep is None:
        raise RuntimeError(f"no report from the viewer within {timeout_s} s; chromium said:\n"
                           + out.decode(errors="replace")[-3000:])
    if rep.get("kind") == "error":
        raise RuntimeError(f"the viewer failed: {rep.get('error')}")
    rgba = None
    if "rgba8_base64" in rep:
        rgba = np.frombuffer(base64.b64decode(rep["rgba8_base64"]), np.uint8).reshape(
            rep["height"], rep["width"], 4).copy()
    return BrowserReport(raw=rep, rgba8=rgba, frame_ms=list(rep.get("frame_ms", [])),
                         first_frame_ms=rep.get("first_frame_ms"), gl_renderer=str(rep.get("gl_renderer", "")),
                         wall_s=wall)


def screenshot(folder: Path, out_png: Path, *, size_px=(512, 384), extra: dict | None = None,
               timeout_s: float = 180.0, chromium: Path | None = None) -> Path:
    """A Chromium screenshot (``--screenshot``) of the canvas-only page (``shot=1``).

    ``--virtual-time-budget`` lets the page load, compile and draw before the capture.
    """
    chromium = chromium or find_chromium()
    if chromium is None:
        raise RuntimeError("chromium not found")
    w, h = size_px
    q = {"size": f"{w}x{h}", "shot": 1}
    q.update(extra or {})
    out_png = Path(out_png).resolve()
    with serve(Path(folder)) as (base, _), _profile_dir() as prof:
        cmd = [str(chromium), *chromium_flags(Path(prof), w, h), f"--screenshot={out_png}",
               "--virtual-time-budget=30000", f"{base}/index.html?{urlencode(q)}"]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            out = proc.communicate(timeout=timeout_s)[0]
        except subprocess.TimeoutExpired:
            out = b""
        _stop_chromium(proc)
    if not out_png.is_file():
        raise RuntimeError("chromium wrote no screenshot:\n" + out.decode(errors="replace")[-3000:])
    return out_png


class Page:
    """A page of a Chromium started by :func:`open_page`, driven through the DevTools protocol.

    Each method sends one or a few protocol commands and waits for their answers
    (``timeout_s``); a protocol error raises RuntimeError with Chromium's message.
    """

    def __init__(self, proc, to_browser, from_browser, timeout_s: float) -> None:
        self._proc = proc
        self._out = to_browser
        self._in = from_browser
        self._buf = b""
        self._next_id = 0
        self._timeout_s = timeout_s
        self.session: str | None = None

    # -- protocol
    def _read_message(self, deadline: float) -> dict:
        import select

        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise RuntimeError("no answer from chromium in time")
            ready, _, _ = select.select([self._in], [], [], min(left, 1.0))
            if ready:
                chunk = os.read(self._in, 1 << 20)
                if not chunk:
                    raise RuntimeError("chromium closed the DevTools pipe")
                self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        return json.loads(raw)

    def send(self, method: str, params: dict | None = None, *, session: bool = True) -> dict:
        """One protocol command; its ``result``."""
        self._next_id += 1
        msg = {"id": self._next_id, "method": method, "params": params or {}}
        if session and self.session:
            msg["sessionId"] = self.session
        os.write(self._out, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + self._timeout_s
        while True:
            m = self._read_message(deadline)
            if m.get("id") == self._next_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error'].get('message')}")
                return m.get("result", {})

    # -- the page
    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (promises awaited)."""
        r = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                           "awaitPromise": True})
        if "exceptionDetails" in r:
            raise RuntimeError(f"page raised: {r['exceptionDetails'].get('text')} "
                               f"{r['exceptionDetails'].get('exception', {}).get('description', '')}")
        return r["result"].get("value")

    def wait_for(self, expression: str, timeout_s: float | None = None):
        """Poll ``expression`` until it is truthy; its value."""
        deadline = time.monotonic() + (timeout_s or self._timeout_s)
        while time.monotonic() < deadline:
            v = self.evaluate(expression)
            if v:
                return v
            time.sleep(0.1)
        raise RuntimeError(f"timed out waiting for {expression!r}")

    def set_viewport(self, width_px: int, height_px: int) -> None:
        """The CSS viewport (device pixels = CSS pixels), as a tablet of that size in landscape."""
        self.send("Emulation.setDeviceMetricsOverride",
                  {"width": width_px, "height": height_px, "deviceScaleFactor": 1, "mobile": False})

    def _touch(self, kind: str, points: list[tuple[float, float]]) -> None:
        self.send("Input.dispatchTouchEvent",
                  {"type": kind, "touchPoints": [{"x": x, "y": y, "id": 1} for x, y in points]})

    def tap(self, x: float, y: float) -> None:
        """A finger's tap at CSS pixel (x, y)."""
        self._touch("touchStart", [(x, y)])
        self._touch("touchEnd", [])

    def drag(self, x0: float, y0: float, x1: float, y1: float, steps: int = 8) -> None:
        """A finger's drag from (x0, y0) to (x1, y1)."""
        self._touch("touchStart", [(x0, y0)])
        for i in range(1, steps + 1):
            f = i / steps
            self._touch("touchMove", [(x0 + f * (x1 - x0), y0 + f * (y1 - y0))])
        self._touch("touchEnd", [])

    def reload(self, ready: str = "document.body && document.body.dataset.ready === '1'") -> None:
        """Reload the page (same browser session: ``sessionStorage`` is kept) and wait until the new
        document's ``ready`` expression is true."""
        self.evaluate("window.__lbsceneOld = true")
        self.evaluate("location.reload(), true")
        self.wait_for(f"!window.__lbsceneOld && document.readyState === 'complete' && ({ready})")

    def screenshot_png(self) -> bytes:
        """The viewport as PNG bytes."""
        return base64.b64decode(self.send("Page.captureScreenshot", {"format": "png"})["data"])


@contextmanager
def open_page(folder: Path, *, size_px=(1024, 768), query: dict | None = None, timeout_s: float = 120.0,
              chromium: Path | None = None, page_name: str = "index.html", ready: str | None = None):
    """Serve ``folder``, open its ``page_name?query`` (the viewer's ``index.html``) in headless
    Chromium at a CSS viewport of ``size_px`` with touch input, and yield a :class:`Page` once the
    expression ``ready`` is true (default: the viewer has drawn its first frame,
    ``document.body.dataset.ready``)."""
    chromium = chromium or find_chromium()
    if chromium is None:
        raise RuntimeError("chromium not found")
    w, h = size_px
    to_r, to_w = os.pipe()          # our commands: Chromium reads them on its fd 3
    from_r, from_w = os.pipe()      # its answers: Chromium writes them on its fd 4

    def child_fds():
        # in the child, before exec: the two ends onto descriptors 3 and 4 (through copies above
        # them, in case an end already is 3 or 4); dup2 makes them inheritable
        import fcntl

        r, w = fcntl.fcntl(to_r, fcntl.F_DUPFD, 10), fcntl.fcntl(from_w, fcntl.F_DUPFD, 10)
        os.dup2(r, 3)
        os.dup2(w, 4)

    with serve(Path(folder)) as (base, _), _profile_dir() as prof:
        proc = subprocess.Popen([str(chromium), *chromium_flags(Path(prof), w, h), "--remote-debugging-pipe",
                                 "about:blank"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                close_fds=False, preexec_fn=child_fds, start_new_session=True)
        os.close(to_r)
        os.close(from_w)
        page = Page(proc, to_w, from_r, timeout_s)
        try:
            targets = page.send("Target.getTargets")["targetInfos"]
            target = next((t["targetId"] for t in targets if t["type"] == "page"), None)
            if target is None:
                target = page.send("Target.createTarget", {"url": "about:blank"})["targetId"]
            page.session = page.send("Target.attachToTarget", {"targetId": target, "flatten": True},
                                     session=False)["sessionId"]
            page.send("Page.enable")
            page.set_viewport(w, h)
            page.send("Emulation.setTouchEmulationEnabled", {"enabled": True, "maxTouchPoints": 5})
            page.send("Page.navigate", {"url": f"{base}/{page_name}?{urlencode(query or {})}"})
            page.wait_for("document.readyState === 'complete' && "
                          + (ready or "document.body && document.body.dataset.ready === '1'"))
            yield page
        finally:
            _stop_chromium(proc)
            os.close(to_w)
            os.close(from_r)


def image_delta_e00(a_rgb8: np.ndarray, b_rgb8: np.ndarray, display_path: Path | None = None) -> np.ndarray:
    """Per-pixel CIEDE2000 between two 8-bit images *after the display model*: codes → the
    XYZ the display emits (``display_path``: a display document through the colour module's
    ``DisplayModel.drive_to_xyz``; None: the sRGB reference display, IEC 61966-2-1), then
    CIELAB relative to the display's white."""
    import colour

    a = np.asarray(a_rgb8)[..., :3]
    b = np.asarray(b_rgb8)[..., :3]
    if a.shape != b.shape:
        raise ValueError(f"image sizes differ: {a.shape} and {b.shape}")
    if display_path is None:
        to_xyz = lambda c: colour.sRGB_to_XYZ(c / 255.0)              # noqa: E731 (Y of white = 1)
        white = colour.sRGB_to_XYZ(np.ones(3))
    else:
        from lbscene.engine.colour.display_model import load_display

        model = load_display(display_path)
        to_xyz = lambda c: model.drive_to_xyz(c / 255.0)               # noqa: E731 (8-bit frames)
        white = model.drive_to_xyz(np.ones(3))
    white = np.asarray(white, float)

    def lab(codes):
        return colour.XYZ_to_Lab(np.asarray(to_xyz(codes.astype(float)), float) / white[1],
                                 colour.XYZ_to_xy(white))

    return np.asarray(colour.delta_E(lab(a), lab(b), method="CIE 2000"), float)
