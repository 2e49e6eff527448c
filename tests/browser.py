"""Headless Debian Chromium driven over the DevTools protocol (CDP), for the browser-view tests.

`Browser(url)` starts `/usr/bin/chromium --headless` on a page, attaches to it over CDP
(the `websockets` client viser already depends on) and offers screenshots, JavaScript
evaluation and a count of the WebSocket frames the page receives.
"""

from __future__ import annotations

import base64
import io
import json
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
import urllib.request

import numpy as np

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars"]


def available() -> bool:
    return os.path.exists(CHROMIUM)


class Browser:
    """A headless Chromium showing `url`, driven over CDP."""

    def __init__(self, url: str, *, width: int = 800, height: int = 600) -> None:
        from websockets.sync.client import connect

        self._dir = tempfile.mkdtemp(prefix="rhi-chromium-")
        self.proc = subprocess.Popen(
            [CHROMIUM, *FLAGS, f"--user-data-dir={self._dir}", "--remote-debugging-port=0",
             f"--window-size={width},{height}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
        port = None
        deadline = time.monotonic() + 30
        while port is None and time.monotonic() < deadline:
            line = self.proc.stderr.readline()
            m = re.search(r"DevTools listening on ws://[^:]+:(\d+)/", line)
            if m:
                port = int(m.group(1))
        self.ws = None
        try:
            if port is None:
                raise RuntimeError("chromium did not start its DevTools endpoint")
            # the rest of chromium's stderr is read and dropped: a full pipe would block the browser
            threading.Thread(target=self.proc.stderr.read, daemon=True, name="chromium-stderr").start()
            pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
            page = next(p for p in pages if p.get("type") == "page")
            # no keepalive pings and an unbounded queue: while a test does not read the page's events (viser's
            # frames, many a second), a bounded queue stops the reader and a missed pong would close the connection
            self.ws = connect(page["webSocketDebuggerUrl"], max_size=64 << 20, ping_interval=None, max_queue=None)
        except BaseException:
            self.close()
            raise
        self._id = 0
        self.ws_frames: list[float] = []
        self.call("Network.enable")
        self.call("Page.enable")
        # viser's page talks to its server from a web worker: attach to it to see its frames
        self.call("Target.setAutoAttach", autoAttach=True, waitForDebuggerOnStart=False, flatten=True)
        self.call("Page.navigate", url=url)

    def call(self, method: str, timeout: float = 120.0, **params):
        """Send a CDP command and return its result (events met meanwhile are recorded).

        The timeout is generous: on a loaded machine the page's renderer waits for software WebGL (SwiftShader),
        seen to take 25-30 s at a load of 14 on 2 cores, before it answers.
        """
        self._id += 1
        my = self._id
        self.ws.send(json.dumps({"id": my, "method": method, "params": params}))
        deadline = time.monotonic() + timeout
        while True:
            msg = json.loads(self.ws.recv(timeout=max(deadline - time.monotonic(), 0.01)))
            if msg.get("id") == my:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self._event(msg)

    def _event(self, msg: dict) -> None:
        method = msg.get("method")
        if method == "Network.webSocketFrameReceived":
            self.ws_frames.append(time.monotonic())
        elif method == "Target.attachedToTarget":
            self._id += 1
            self.ws.send(json.dumps({"id": self._id, "method": "Network.enable", "params": {},
                                     "sessionId": msg["params"]["sessionId"]}))

    def pump(self, seconds: float) -> None:
        """Process events for `seconds`."""
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            try:
                self._event(json.loads(self.ws.recv(timeout=left)))
            except TimeoutError:
                return

    def evaluate(self, expression: str):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return r.get("result", {}).get("value")

    def wait_for(self, expression: str, timeout: float = 60.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.evaluate(expression):
                return True
            self.pump(0.2)
        return False

    def screenshot(self) -> np.ndarray:
        """(H, W, 3) uint8 RGB of the page."""
        from PIL import Image

        self.call("Page.bringToFront")
        data = base64.b64decode(self.call("Page.captureScreenshot", timeout=60.0, format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def close(self) -> None:
        """End the browser: its whole process group (the zygotes and renderers too)."""
        if self.ws is not None:
            try:
                self.ws.close()
            except Exception:  # noqa: BLE001
                pass
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(self.proc.pid, sig)
                self.proc.wait(timeout=5)
                break
            except (ProcessLookupError, subprocess.TimeoutExpired):
                continue
        shutil.rmtree(self._dir, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
