"""A headless Chromium driven over the DevTools protocol on a pipe (no
WebSocket client needed): open a page, take screenshots.

WebGL (Rerun's web viewer needs it) comes from SwiftShader, Chromium's
software renderer.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--no-first-run",
    "--remote-debugging-pipe",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--mute-audio",
)


def find_chromium() -> str | None:
    return next((path for name in NAMES if (path := shutil.which(name))), None)


class Page:
    """One tab of a headless Chromium, ``width`` x ``height`` CSS pixels."""

    def __init__(self, proc: subprocess.Popen[bytes], to_browser: int, from_browser: int) -> None:
        self.proc = proc
        self.to_browser, self.from_browser = to_browser, from_browser
        self.last_id = 0
        self.pending = b""
        self.session: str | None = None
        self.target: str | None = None

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """One DevTools command; its result (events in between are skipped)."""
        self.last_id += 1
        msg: dict[str, Any] = {"id": self.last_id, "method": method, "params": params}
        if self.session is not None and not method.startswith("Target."):
            msg["sessionId"] = self.session
        os.write(self.to_browser, json.dumps(msg).encode() + b"\0")
        while True:
            while b"\0" not in self.pending:
                chunk = os.read(self.from_browser, 1 << 20)
                if not chunk:
                    raise RuntimeError(f"Chromium closed its pipe (exit code {self.proc.poll()})")
                self.pending += chunk
            raw, self.pending = self.pending.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self.last_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]

    def open(self, url: str, width: int, height: int) -> None:
        """``url`` in a fresh tab (the previous one closed: a live viewer keeps drawing)."""
        if self.target is not None:
            self.call("Target.closeTarget", targetId=self.target)
        self.target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=self.target, flatten=True)["sessionId"]
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1, mobile=False)
        self.call("Page.navigate", url=url)

    def screenshot(self, path: Path) -> Path:
        path.write_bytes(base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"]))
        return path


@contextlib.contextmanager
def chromium(exe: str, profile: Path) -> Iterator[Page]:
    """A headless Chromium with its own profile folder (a viewer remembers
    layouts per application in it), stopped with its whole process group."""
    browser_reads, we_write = os.pipe()
    we_read, browser_writes = os.pipe()

    def pipes_as_3_and_4() -> None:  # the DevTools pipe: Chromium reads fd 3, writes fd 4
        a, b = os.dup(browser_reads), os.dup(browser_writes)
        a, b = (os.dup(a) if a < 5 else a), (os.dup(b) if b < 5 else b)
        os.dup2(a, 3)
        os.dup2(b, 4)

    # Its singleton socket's folder (org.chromium.Chromium.*) goes under TMPDIR, removed after; a short
    # path of its own, as a socket's path holds at most 107 bytes (a test's tmp_path can be longer).
    scratch = Path(tempfile.mkdtemp(prefix="chromium-"))
    proc = subprocess.Popen(
        [exe, *FLAGS, f"--user-data-dir={profile}", "about:blank"],
        preexec_fn=pipes_as_3_and_4,
        close_fds=False,
        env={**os.environ, "TMPDIR": str(scratch)},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    os.close(browser_reads)
    os.close(browser_writes)
    try:
        yield Page(proc, we_write, we_read)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        os.close(we_write)
        os.close(we_read)
        shutil.rmtree(scratch, ignore_errors=True)
