"""A real headless browser for tests: Debian's chromium driven over the DevTools protocol (its
websocket, with the ``websockets`` client viser already needs). WebGL runs in software (SwiftShader).

    with Browser() as browser:
        shot, requests = browser.open(url, until=lambda png: ..., timeout=60)

``open`` navigates, then takes a screenshot every second until ``until(png bytes)`` holds or the
timeout passes, and returns the last screenshot and every URL the page requested (network log).
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.request

import pytest

FLAGS = ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--disable-quic",
         # no network but this machine: any other host fails to resolve
         "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1"]


def chromium_or_skip() -> str:
    """Path of chromium; skip if absent (fail when CI is set: .ci/run installs Debian's chromium)."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        msg = "chromium not installed (apt-get install -y chromium; .ci/run installs it)"
        if os.environ.get("CI"):
            pytest.fail(msg)
        pytest.skip(msg)
    return browser


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Browser:
    def __init__(self, width: int = 1200, height: int = 800):
        self.binary = chromium_or_skip()
        self.size = (width, height)

    def __enter__(self) -> "Browser":
        from websockets.sync.client import connect

        self.profile = tempfile.mkdtemp(prefix="spq-chromium-")
        port = free_port()
        self.process = subprocess.Popen(
            [self.binary, *FLAGS, f"--remote-debugging-port={port}", f"--user-data-dir={self.profile}",
             f"--window-size={self.size[0]},{self.size[1]}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.time() + 30
        while True:
            try:
                targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=2))
                pages = [t for t in targets if t.get("type") == "page"]
                if pages:
                    break
            except OSError:
                pass
            if time.time() > deadline:
                self.__exit__()
                raise RuntimeError("chromium's DevTools endpoint did not come up in 30 s")
            time.sleep(0.2)
        self.ws = connect(pages[0]["webSocketDebuggerUrl"], max_size=2 ** 27)
        self.next_id = 0
        self.events: list[dict] = []
        self.call("Network.enable")
        self.call("Page.enable")
        return self

    def __exit__(self, *exc) -> None:
        if getattr(self, "ws", None) is not None:
            self.ws.close()
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
        shutil.rmtree(self.profile, ignore_errors=True)

    def call(self, method: str, **params) -> dict:
        self.next_id += 1
        mine = self.next_id
        self.ws.send(json.dumps({"id": mine, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=60))
            if msg.get("id") == mine:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def requested(self) -> list[str]:
        return [e["params"]["request"]["url"] for e in self.events if e.get("method") == "Network.requestWillBeSent"]

    def open(self, url: str, until=None, timeout: float = 60.0) -> tuple[bytes, list[str]]:
        self.call("Page.navigate", url=url)
        deadline = time.time() + timeout
        while True:
            time.sleep(1.0)
            shot = self.screenshot()
            if (until is not None and until(shot)) or time.time() > deadline:
                return shot, self.requested()
