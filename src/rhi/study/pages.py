"""The participant's and the experimenter's pages of `rhi study run`, served by rhi over HTTP.

``/`` is the participant's page: it shows only what `StudyRun.participant_view` returns (the protocol's
``[display]``): a "next sample" control, the two answer buttons and their keys (N or space; 1 or ←, 2 or →),
for path following the reference path and the teleoperated slave's end effector (in a mouse dry run the
pointer on that canvas is the hand). ``/experimenter`` shows progress, the trial, the device's live state and
safety, the path with the slave and the master's handle mapped onto it, and pause, resume, abort and a note
field. Each page polls its JSON view (``/api/participant``, ``/api/experimenter``) and posts its actions
(``/api/participant/next|answer|hand``, ``/api/experimenter/pause|resume|abort|note|hand``). The pages are plain
HTML and JavaScript with no dependencies (the 3-D viser view shows a device, not a study; a participant must see
nothing but what the protocol allows).
"""

from __future__ import annotations

import json
import signal
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from typing import Any, TextIO

from rhi.errors import InvalidInput, RhiError
from rhi.study.haptics import Haptics
from rhi.study.live import StudyRun
from rhi.study.protocol import load_protocol
from rhi.study.session import Session


def _page(name: str) -> bytes:
    return (resources.files("rhi.study") / "pages" / f"{name}.html").read_bytes()


class _Handler(BaseHTTPRequestHandler):
    run: StudyRun  # set on the subclass `make_server` builds

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the stdlib's name
        pass

    def _send(self, code: int, body: bytes, kind: str = "application/json") -> None:
        self.send_response(code)
        self.send_header("Content-Type", kind)
        self.send_header("Cache-Control", "no-store")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def _json(self, code: int, obj: Any) -> None:
        self._send(code, json.dumps(obj, allow_nan=False, default=float).encode())

    def do_GET(self) -> None:  # noqa: N802 - the stdlib's name
        path = self.path.split("?")[0]
        if path in ("/", "/participant"):
            self._send(200, _page("participant"), "text/html; charset=utf-8")
        elif path == "/experimenter":
            self._send(200, _page("experimenter"), "text/html; charset=utf-8")
        elif path == "/api/participant":
            self._json(200, self.run.participant_view())
        elif path == "/api/experimenter":
            self._json(200, self.run.experimenter_view())
        else:
            self._json(404, {"error": f"no page {path}"})

    def do_POST(self) -> None:  # noqa: N802 - the stdlib's name
        n = int(self.headers.get("Content-Length") or 0)
        try:
            body = json.loads(self.rfile.read(n) or b"{}") if n < 65536 else None
            if not isinstance(body, dict):
                raise InvalidInput("request: expected a JSON object under 64 KiB")
            run, path = self.run, self.path.split("?")[0]
            actions = {
                "/api/participant/next": lambda: run.next(),
                "/api/participant/answer": lambda: run.answer(str(body.get("answer"))),
                "/api/participant/hand": lambda: run.haptics.hand_point(body.get("point")),
                "/api/experimenter/pause": run.pause,
                "/api/experimenter/resume": run.resume,
                "/api/experimenter/abort": run.abort,
                "/api/experimenter/note": lambda: run.note(str(body.get("text", ""))),
                "/api/experimenter/hand": lambda: run.haptics.hand_target(float(body.get("depth", "nan"))),
            }
            if path not in actions:
                self._json(404, {"error": f"no action {path}"})
                return
            actions[path]()
            self._json(200, {"ok": True})
        except (RhiError, ValueError, TypeError) as exc:
            self._json(400, {"ok": False, "error": str(exc)})


def make_server(run: StudyRun, host: str = "127.0.0.1", port: int = 8090) -> ThreadingHTTPServer:
    """An HTTP server of the two pages for `run` (not yet serving: call ``serve_forever`` in a thread)."""
    handler = type("StudyHandler", (_Handler,), {"run": run})
    try:
        srv = ThreadingHTTPServer((host, int(port)), handler)
    except OSError as exc:
        raise InvalidInput(f"port: cannot serve the pages on {host}:{port} ({exc})") from None
    srv.daemon_threads = True
    return srv


def serve_session(protocol: str | Path, participant: str, *, study_dir: str | Path = "study", link: str = "sim",
                  fields: dict[str, str] | None = None, host: str = "127.0.0.1", port: int = 8090,
                  mouse: bool = False, rate: float = 1000.0, out: TextIO | None = None) -> int:
    """`rhi study run`: open (or resume) the participant's session and serve its pages until done or aborted.

    Returns:
        0 when every trial is committed, 1 when aborted (run the same command to resume).
    """
    session = Session(study_dir, load_protocol(protocol), participant, fields=fields)
    run = StudyRun(session, Haptics(session.protocol, link, rate=rate, mouse=mouse))
    srv = make_server(run, host, port)
    thread = threading.Thread(target=srv.serve_forever, name="rhi-study-pages", daemon=True)
    thread.start()
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, lambda *_: run.abort())
    h, p = str(srv.server_address[0]), int(srv.server_address[1])
    if out is not None:
        state = "resumed at trial" if session.next_trial else "starting at trial"
        print(f"rhi study run: {session.protocol.name}, participant {participant} ({state} {session.next_trial} "
              f"of {len(session.plan)}), link {link}{', mouse as the hand' if mouse else ''}\n"
              f"participant page: http://{h}:{p}/\nexperimenter page: http://{h}:{p}/experimenter\n"
              f"folder: {session.folder}", file=out, flush=True)
    try:
        run.finished.wait()
        if run.phase == "done":
            time.sleep(2.0)  # the pages show the end before the server goes
    finally:
        run.haptics.stop()
        srv.shutdown()
        srv.server_close()
    if out is not None:
        print(f"rhi study run: {run.phase}; {session.next_trial} of {len(session.plan)} trials committed",
              file=out, flush=True)
    return 0 if run.phase == "done" else 1


__all__ = ["make_server", "serve_session"]
