"""A tiny Chrome DevTools Protocol client for the page tests: headless Chromium (Debian's
``chromium`` package) driven over its remote-debugging websocket with ``websocket-client``.

Only what the tests need: open a page, evaluate JavaScript, take a screenshot. Playwright would
download its own browser build, which cannot be fetched here; the system browser and ~80 lines
of protocol do the same job.
"""

from __future__ import annotations

import base64
import itertools
import json
import re
import shutil
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any

#: Seconds to wait for the browser to start and for a page to load (a cold start on a busy
#: 2-core machine takes a few seconds).
STARTUP_S = 60.0


def chromium_path() -> str | None:
    """The Chromium binary, or None when it is not installed (``apt-get install chromium``)."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return None


class Browser:
    """Headless Chromium with one page, closed on exit."""

    def __init__(self, size: tuple[int, int] = (1200, 1100)) -> None:
        import websocket

        binary = chromium_path()
        if binary is None:
            raise RuntimeError("chromium is not installed")
        self.profile = tempfile.mkdtemp(prefix="orbitsim-chromium-")
        args = [binary, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
                "--remote-debugging-port=0", f"--user-data-dir={self.profile}",
                f"--window-size={size[0]},{size[1]}", "about:blank"]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        port = self._port()
        deadline = time.monotonic() + STARTUP_S
        while True:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=5) as reply:
                pages = [t for t in json.load(reply) if t.get("type") == "page"]
            if pages or time.monotonic() > deadline:
                break
            time.sleep(0.1)
        # No Origin header: Chromium refuses a DevTools websocket whose Origin it does not allow ("403
        # ... Use the command line flag --remote-allow-origins"); which origins pass depends on its
        # version, while a client that sends none (as Puppeteer does) is always let in.
        self.ws = websocket.create_connection(pages[0]["webSocketDebuggerUrl"], timeout=STARTUP_S,
                                              suppress_origin=True)
        self.ids = itertools.count(1)

    def _port(self) -> int:
        """The port Chromium prints on stderr as ``DevTools listening on ws://127.0.0.1:PORT/...``."""
        assert self.proc.stderr is not None
        deadline = time.monotonic() + STARTUP_S
        while time.monotonic() < deadline:
            line = self.proc.stderr.readline()
            match = re.search(r"DevTools listening on ws://[^:]+:(\d+)/", line)
            if match:
                return int(match.group(1))
            if not line and self.proc.poll() is not None:
                break
        raise RuntimeError("chromium did not start its DevTools server")

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """Send one command and return its result (events in between are skipped)."""
        msg_id = next(self.ids)
        self.ws.send(json.dumps({"id": msg_id, "method": method, "params": params}))
        while True:
            reply = json.loads(self.ws.recv())
            if reply.get("id") == msg_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression (JSON-serialisable), raising on a JS exception."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def open(self, path: Path, ready: str) -> None:
        """Load a local file and wait until the expression ``ready`` is true."""
        self.call("Page.navigate", url=path.resolve().as_uri())
        deadline = time.monotonic() + STARTUP_S
        while not self.evaluate(f"document.readyState === 'complete' && Boolean({ready})"):
            if time.monotonic() > deadline:
                raise RuntimeError(f"{path}: not ready after {STARTUP_S} s")
            time.sleep(0.1)

    def screenshot(self, path: Path) -> Path:
        """A PNG of the page's viewport."""
        data = self.call("Page.captureScreenshot", format="png")["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def close(self) -> None:
        """Stop the browser (this process's own child) and remove its profile."""
        try:
            self.ws.close()
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
            shutil.rmtree(self.profile, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def has_websocket_client() -> bool:
    """Whether ``websocket-client`` is importable (it comes with ``pip install -e '.[test]'``)."""
    try:
        import websocket  # noqa: F401
    except ImportError:
        return False
    return True
