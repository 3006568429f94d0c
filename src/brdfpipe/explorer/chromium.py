"""Headless Chromium driven over the DevTools protocol, standard library only.

The explorer's tests, its benchmark and the script that takes its screenshots
open the page in a real browser: Debian's ``chromium``, headless, with WebGL2
on SwiftShader (software GL, no GPU needed).  Chromium is started with
``--remote-debugging-pipe``: it reads NUL-terminated JSON commands on file
descriptor 3 and writes replies and events on descriptor 4, so no port, no
WebSocket and no third-party package is needed.

>>> with Browser() as b:                         # doctest: +SKIP
...     b.open(Path("results/explorer/index.html"))
...     b.evaluate("document.title")

:func:`find_chromium` returns the executable or ``None`` (the tests skip with
the reason when it is ``None``).  Console messages, uncaught exceptions and
failed loads are collected in :attr:`Browser.errors`.
"""

from __future__ import annotations

import base64
import fcntl
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any, Final

__all__ = ["FLAGS", "BrowserError", "Browser", "find_chromium"]

#: Flags of every start: headless, nothing fetched from the network, WebGL2 on
#: SwiftShader (ANGLE's Vulkan back end on SwiftShader; checked: WebGL2 with
#: EXT_color_buffer_float on Chromium 156, Debian 12).
FLAGS: Final = (
    "--headless",
    "--no-sandbox",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--allow-file-access-from-files",
    "--mute-audio",
    "--hide-scrollbars",
)


class BrowserError(RuntimeError):
    """Chromium could not be started, did not answer, or a command failed."""


def find_chromium() -> str | None:
    """Path of the Chromium executable (``$BRDFPIPE_CHROMIUM``, ``chromium``, ``chromium-browser``) or ``None``."""
    env = os.environ.get("BRDFPIPE_CHROMIUM")
    if env:
        return env if os.access(env, os.X_OK) else None
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    return None


class Browser:
    """One headless Chromium with one page, as a context manager.

    ``width`` × ``height``: the page's viewport in CSS pixels (device scale 1).
    ``timeout``: seconds to wait for any one reply.
    """

    def __init__(self, *, width: int = 1280, height: int = 860, timeout: float = 60.0,
                 executable: str | None = None) -> None:
        exe = executable or find_chromium()
        if exe is None:
            raise BrowserError("no chromium executable (install Debian's chromium, or set BRDFPIPE_CHROMIUM)")
        self.timeout = float(timeout)
        self.errors: list[str] = []
        self.console: list[str] = []
        self._events: list[dict[str, Any]] = []
        self._id = 0
        self._buf = b""
        self._profile = tempfile.mkdtemp(prefix="brdfpipe-chromium-")
        to_chrome_r, self._to_chrome = os.pipe()
        self._from_chrome, from_chrome_w = os.pipe()
        # the child's ends above 4, so dup2 onto 3 and 4 cannot clobber one another
        for fd in (to_chrome_r, from_chrome_w):
            os.set_inheritable(fd, False)
        to_chrome_r, old_r = fcntl.fcntl(to_chrome_r, fcntl.F_DUPFD_CLOEXEC, 10), to_chrome_r
        from_chrome_w, old_w = fcntl.fcntl(from_chrome_w, fcntl.F_DUPFD_CLOEXEC, 10), from_chrome_w
        os.close(old_r)
        os.close(old_w)

        def child_fds() -> None:  # runs in the child before exec
            os.dup2(to_chrome_r, 3)
            os.dup2(from_chrome_w, 4)

        args = [exe, *FLAGS, f"--user-data-dir={self._profile}", "--remote-debugging-pipe",
                f"--window-size={int(width)},{int(height)}", "about:blank"]
        self._proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=child_fds, stdin=subprocess.DEVNULL,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        try:
            target = self._call("Target.createTarget", {"url": "about:blank"})["targetId"]
            self._session = self._call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
            for domain in ("Runtime", "Page", "Log"):
                self.call(f"{domain}.enable")
            self.call("Emulation.setDeviceMetricsOverride",
                      {"width": int(width), "height": int(height), "deviceScaleFactor": 1, "mobile": False})
        except BaseException:
            self.close()
            raise

    # -- plumbing -----------------------------------------------------------

    def _send(self, method: str, params: dict[str, Any] | None, session: str | None) -> int:
        self._id += 1
        msg: dict[str, Any] = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._to_chrome, json.dumps(msg).encode() + b"\0")
        return self._id

    def _read_message(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise BrowserError("chromium did not answer in time")
            ready, _, _ = select.select([self._from_chrome], [], [], left)
            if not ready:
                continue
            chunk = os.read(self._from_chrome, 1 << 20)
            if not chunk:
                raise BrowserError("chromium closed the DevTools pipe (it exited)")
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        return json.loads(raw)

    def _note(self, msg: dict[str, Any]) -> None:
        method, p = msg.get("method"), msg.get("params", {})
        if method == "Runtime.consoleAPICalled":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
            self.console.append(f"{p.get('type')}: {text}")
            if p.get("type") in ("error", "assert"):
                self.errors.append(f"console.{p.get('type')}: {text}")
        elif method == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            desc = d.get("exception", {}).get("description") or d.get("text", "")
            self.errors.append(f"exception: {desc}")
        elif method == "Log.entryAdded":
            e = p.get("entry", {})
            if e.get("level") == "error":
                self.errors.append(f"log ({e.get('source')}): {e.get('text')} {e.get('url', '')}".strip())
        self._events.append(msg)

    def _call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> dict[str, Any]:
        mid = self._send(method, params, session)
        deadline = time.monotonic() + self.timeout
        while True:
            msg = self._read_message(deadline)
            if msg.get("id") == mid:
                if "error" in msg:
                    raise BrowserError(f"{method}: {msg['error'].get('message')} {msg['error'].get('data', '')}")
                return msg.get("result", {})
            if "method" in msg:
                self._note(msg)

    def call(self, method: str, params: dict[str, Any] | None = None) -> dict[str, Any]:
        """Send one DevTools command to the page and return its result."""
        return self._call(method, params, self._session)

    def wait_event(self, method: str, timeout: float | None = None) -> dict[str, Any]:
        """Wait for (and consume) the next event ``method`` of the page."""
        for i, msg in enumerate(self._events):
            if msg.get("method") == method:
                del self._events[i]
                return msg.get("params", {})
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            msg = self._read_message(deadline)
            if "method" in msg:
                self._note(msg)
                if msg["method"] == method:
                    self._events.pop()
                    return msg.get("params", {})

    # -- the page -----------------------------------------------------------

    def open(self, target: str | os.PathLike[str], *, ready: str | None = None, timeout: float | None = None) -> None:
        """Load a URL or a local file (``file://``) and wait for its load event.

        ``ready``: a JavaScript expression to poll until it is truthy (e.g. the
        page's own "data uploaded" flag).
        """
        url = target if isinstance(target, str) and "://" in target else Path(target).resolve().as_uri()
        self._events.clear()
        res = self.call("Page.navigate", {"url": url})
        if res.get("errorText"):
            raise BrowserError(f"{url}: {res['errorText']}")
        self.wait_event("Page.loadEventFired", timeout)
        if ready is not None:
            self.wait_for(ready, timeout)

    def wait_for(self, expression: str, timeout: float | None = None) -> Any:
        """Poll ``expression`` every 50 ms until it is truthy; return its value."""
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            value = self.evaluate(expression)
            if value:
                return value
            if time.monotonic() > deadline:
                raise BrowserError(f"timed out waiting for {expression!r}; page errors: {self.errors}")
            time.sleep(0.05)

    def evaluate(self, expression: str, *, await_promise: bool = True) -> Any:
        """Evaluate a JavaScript expression in the page and return its JSON value."""
        res = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                             "awaitPromise": await_promise})
        if "exceptionDetails" in res:
            d = res["exceptionDetails"]
            raise BrowserError(f"{expression[:80]!r}: {d.get('exception', {}).get('description') or d.get('text')}")
        return res.get("result", {}).get("value")

    def mouse(self, kind: str, x: float, y: float, *, buttons: int = 0) -> None:
        """A mouse event at page coordinates: kind ``mouseMoved``, ``mousePressed`` or ``mouseReleased``."""
        params: dict[str, Any] = {"type": kind, "x": float(x), "y": float(y), "buttons": buttons}
        if kind != "mouseMoved":
            params.update(button="left", clickCount=1)
        self.call("Input.dispatchMouseEvent", params)

    def wheel(self, x: float, y: float, delta_y: float) -> None:
        """A mouse-wheel turn at page coordinates (``delta_y`` < 0: away from the user, zoom in on a map)."""
        self.call("Input.dispatchMouseEvent", {"type": "mouseWheel", "x": float(x), "y": float(y),
                                               "deltaX": 0.0, "deltaY": float(delta_y)})

    def screenshot(self, path: str | os.PathLike[str] | None = None) -> bytes:
        """PNG screenshot of the viewport (written to ``path`` if given)."""
        data = base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"])
        if path is not None:
            Path(path).write_bytes(data)
        return data

    # -- life cycle ---------------------------------------------------------

    def close(self) -> None:
        """Stop Chromium and remove its profile folder."""
        proc = getattr(self, "_proc", None)
        if proc is not None and proc.poll() is None:
            try:
                self._send("Browser.close", None, None)
                proc.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait()
        for fd in (getattr(self, "_to_chrome", None), getattr(self, "_from_chrome", None)):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._to_chrome = self._from_chrome = None  # type: ignore[assignment]
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
