"""Headless Chromium, driven over its DevTools pipe: load a page, run JavaScript, screenshot.

This module owns finding a Chromium-family browser (:func:`browser`) and
:class:`Chromium`, a headless browser whose commands go over
``--remote-debugging-pipe`` (the DevTools protocol as NUL-terminated JSON on
the browser's fds 3 and 4; no network port, no WebSocket library). WebGL
runs on the CPU (SwiftShader), so no GPU or display is needed. It knows
nothing of symcushion's pages; ``symcushion.viz.viewer`` uses it for screenshots.
"""
from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import tempfile
import time

__all__ = ["browser", "Chromium", "BROWSERS", "FLAGS"]

#: Chromium executables looked up on the PATH, in order.
#: Tries, and the pause between them (s), to remove the browser's profile folder while
#: its helper processes finish writing into it.
PROFILE_REMOVE_TRIES, PROFILE_REMOVE_PAUSE = 20, 0.1

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")

#: Command-line flags of the headless browser.
FLAGS = (
    "--headless",
    "--remote-debugging-pipe",          # DevTools on fds 3 and 4
    "--no-sandbox",                     # Chromium's sandbox refuses root, as CI runs
    "--use-angle=swiftshader",          # WebGL on the CPU: no GPU, no display
    "--enable-unsafe-swiftshader",      # ... which recent versions only allow when asked
    "--hide-scrollbars", "--no-first-run", "--mute-audio",
)


def browser() -> str | None:
    """Path of a Chromium-family browser on the PATH (:data:`BROWSERS`), or None."""
    for candidate in BROWSERS:
        path = shutil.which(candidate)
        if path:
            return path
    return None


class Chromium:
    """Headless Chromium showing one page, driven over ``--remote-debugging-pipe``.

    Commands are JSON messages ending in a NUL byte, written to the browser's
    fd 3; replies and events come back on its fd 4. Use it as a context
    manager: the browser and its temporary profile are removed on exit. The
    page is loaded (its ``load`` event fired) when the constructor returns.

    Parameters
    ----------
    exe : str
        The browser (:func:`browser`).
    url : str
        The page to load (``file://...``).
    size : (int, int)
        Viewport width and height (px).
    timeout : float
        Seconds to wait for each answer of the browser.
    """

    def __init__(self, exe: str, url: str, size, timeout: float):
        import fcntl

        self.timeout, self.next_id, self.buffer = timeout, 0, b""
        to_browser, from_browser = os.pipe(), os.pipe()
        # high copies, so that placing them on 3 and 4 in the child cannot clobber either
        self.child_ends = [fcntl.fcntl(to_browser[0], fcntl.F_DUPFD, 100),
                           fcntl.fcntl(from_browser[1], fcntl.F_DUPFD, 100)]
        for fd in (to_browser[0], from_browser[1]):
            os.close(fd)
        self.write_fd, self.read_fd = to_browser[1], from_browser[0]
        self.profile = tempfile.TemporaryDirectory(prefix="symcushion-chromium-",
                                                   ignore_cleanup_errors=True)
        reader, writer = self.child_ends

        def place_pipes():
            os.dup2(reader, 3)
            os.dup2(writer, 4)

        self.process = subprocess.Popen(
            [exe, *FLAGS, f"--user-data-dir={self.profile.name}",
             f"--window-size={size[0]},{size[1]}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            pass_fds=(3, 4), preexec_fn=place_pipes)
        for fd in self.child_ends:
            os.close(fd)
        try:
            self._open(url, size)
        except BaseException:
            self.close()
            raise

    def _open(self, url: str, size):
        """Attach to the browser's page, size its viewport, load ``url`` and wait for it."""
        pages = [t for t in self.send("Target.getTargets")["targetInfos"] if t["type"] == "page"]
        if not pages:
            raise RuntimeError(f"the browser opened no page for {url}.")
        self.session = self.send("Target.attachToTarget", targetId=pages[0]["targetId"],
                                 flatten=True)["sessionId"]
        # the window's size is not the page's in headless mode: set the viewport itself
        self.send("Emulation.setDeviceMetricsOverride", self.session, width=int(size[0]),
                  height=int(size[1]), deviceScaleFactor=1, mobile=False)
        # answered once the page's document is committed: evaluations then run in it
        self.send("Page.navigate", self.session, url=url)
        self.evaluate("document.readyState === 'complete' || new Promise(function (done) {"
                      " window.addEventListener('load', done); })")

    def send(self, method: str, session: str | None = None, **params) -> dict:
        """Send one command and wait for its reply (events in between are dropped)."""
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        os.write(self.write_fd, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + self.timeout
        while True:
            while b"\0" in self.buffer:
                raw, self.buffer = self.buffer.split(b"\0", 1)
                reply = json.loads(raw)
                if reply.get("id") == self.next_id:
                    if "error" in reply:
                        raise RuntimeError(f"the browser refused {method}: {reply['error']}")
                    return reply["result"]
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.read_fd], [], [], left)[0]:
                raise TimeoutError(f"the browser did not answer {method} within "
                                   f"{self.timeout:g} s.")
            chunk = os.read(self.read_fd, 1 << 20)
            if not chunk:
                raise RuntimeError(f"the browser closed while running {method}.")
            self.buffer += chunk

    def evaluate(self, expression: str):
        """Value of a JavaScript expression in the page (a promise is awaited)."""
        result = self.send("Runtime.evaluate", self.session, expression=expression,
                           awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in result:
            details = result["exceptionDetails"]
            message = (details.get("exception") or {}).get("description") or details.get("text")
            raise RuntimeError(f"the page raised: {message}")
        return result["result"].get("value")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def close(self):
        """End the browser and remove its profile (once; later calls do nothing)."""
        if self.write_fd is None:
            return
        for fd in (self.write_fd, self.read_fd):
            os.close(fd)
        self.write_fd = self.read_fd = None
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._remove_profile()

    def _remove_profile(self):
        """Remove the profile folder; Chromium's helper processes may still write into it
        for a moment after the browser ended, so try again briefly before giving up
        quietly (a temporary folder left behind loses nothing)."""
        for _ in range(PROFILE_REMOVE_TRIES):
            if not os.path.exists(self.profile.name):
                break
            try:
                shutil.rmtree(self.profile.name)
            except OSError:
                time.sleep(PROFILE_REMOVE_PAUSE)
        self.profile.cleanup()              # ignores what is left (ignore_cleanup_errors)
