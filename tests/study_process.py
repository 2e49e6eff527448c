"""`rhi study run` as a test's child process (its own process group), with the address of its pages."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

from conftest import child_env


class StudyProcess:
    """`rhi study run PROTOCOL --participant P --study FOLDER` on a free port, the hand field "right", 500 Hz.

    Args:
        protocol: the protocol file.
        study: the study folder.
        participant: the participant's id.
        extra: more command-line words (e.g. "--mouse").
        timeout: how long the command may take to serve its pages [s].

    Attributes:
        proc: the child process.
        url: the address of its pages ("http://…/").

    Raises:
        RuntimeError: it did not serve within `timeout` (it is killed; its output is in the message).
    """

    def __init__(self, protocol: Path, study: Path, participant: str = "P01", *, extra: tuple[str, ...] = (),
                 timeout: float = 180.0) -> None:
        env = {**child_env(), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa")}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "rhi", "study", "run", str(protocol), "--participant", participant, "--study",
             str(study), "--port", "0", "--field", "handedness=right", "--rate", "500", *extra],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, start_new_session=True)
        self.url = None
        lines = []
        deadline = time.monotonic() + timeout
        while self.url is None and time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line and self.proc.poll() is not None:
                break
            lines.append(line)
            if line.startswith("participant page: "):
                self.url = line.split(": ", 1)[1].strip()
        if self.url is None:
            self.kill()
            raise RuntimeError("rhi study run did not start:\n" + "".join(lines))

    def view(self, page: str = "experimenter") -> dict:
        """The page's state (its `api/<page>` JSON)."""
        return json.load(urllib.request.urlopen(self.url + "api/" + page, timeout=30))

    def kill(self) -> None:
        """SIGKILL its process group and wait for it."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait(timeout=30)
