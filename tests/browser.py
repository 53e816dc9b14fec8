"""A report page opened in a real headless Chromium, driven through the DevTools protocol over
a pipe (``--remote-debugging-pipe``: JSON messages ending in a NUL byte on file descriptors 3
and 4; no websocket, no package beyond the standard library): what the page logged, every
network request it made, the size each figure rendered at, and optionally a screenshot.

    python tests/browser.py OUT/index.html [--screenshot FILE.png] [--width 1200]

prints what it found and exits with 1 when the page logged an error, made a network request
or rendered a figure empty. Chromium is looked up as ``chromium``, ``chromium-browser``,
``google-chrome`` on the PATH (Debian: ``apt-get install chromium``)."""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")

# Every <svg> at the top of a figure and every <img>: its rendered size in CSS pixels.
_FIGURES_JS = """JSON.stringify({
  figures: Array.from(document.querySelectorAll('figure')).map(f => {
    const g = f.querySelector('svg, img'); const r = g ? g.getBoundingClientRect() : {width: 0, height: 0};
    return {id: f.id, kind: g ? g.tagName.toLowerCase() : 'none', width: r.width, height: r.height,
            complete: g && g.tagName === 'IMG' ? g.complete && g.naturalWidth > 0 : true};
  }),
  title: document.title, height: document.documentElement.scrollHeight,
  tables: document.querySelectorAll('table').length})"""


def find_browser() -> str | None:
    """The path of a Chromium on the PATH, or None."""
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


class _Pipe:
    """The DevTools protocol over Chromium's pipe: send a command, read messages until its answer,
    keeping the events seen on the way."""

    def __init__(self, write_fd: int, read_fd: int) -> None:
        self.write_fd, self.read_fd = write_fd, read_fd
        self.buffer = b""
        self.events: list[dict] = []
        self.next_id = 0

    def _read(self, deadline: float) -> dict:
        while b"\0" not in self.buffer:
            if time.monotonic() > deadline:
                raise TimeoutError("Chromium did not answer in time")
            chunk = os.read(self.read_fd, 1 << 16)
            if not chunk:
                raise RuntimeError("Chromium closed its DevTools pipe")
            self.buffer += chunk
        message, _, self.buffer = self.buffer.partition(b"\0")
        return json.loads(message)

    def call(self, method: str, timeout: float = 30.0, session: str | None = None, **params) -> dict:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params}
        if session:
            message["sessionId"] = session
        os.write(self.write_fd, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._read(deadline)
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error'].get('message')}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str, timeout: float = 30.0) -> dict:
        deadline = time.monotonic() + timeout
        for event in self.events:
            if event.get("method") == method:
                return event
        while True:
            event = self._read(deadline)
            self.events.append(event)
            if event.get("method") == method:
                return event


def inspect(page: str | Path, screenshot: str | Path | None = None, width: int = 1200, browser: str | None = None,
            timeout: float = 60.0) -> dict:
    """Open ``page`` (a file) in headless Chromium and return what it did: ``errors`` (console
    errors, uncaught exceptions, failed loads), ``requests`` (every URL it asked for besides the
    page itself), ``figures`` (id, kind, rendered width and height of each ``<figure>``'s first
    SVG or image), ``tables``, ``title`` and the page's ``height``. ``screenshot``: a PNG of the
    whole page at ``width`` CSS pixels."""
    browser = browser or find_browser()
    if browser is None:
        raise FileNotFoundError("no Chromium on the PATH (Debian: apt-get install chromium)")
    url = Path(page).resolve().as_uri()
    to_browser_r, to_browser_w = os.pipe()
    from_browser_r, from_browser_w = os.pipe()
    with tempfile.TemporaryDirectory(prefix="zrp-chromium-") as profile:
        args = [browser, "--headless=new", "--remote-debugging-pipe", "--no-sandbox", "--disable-gpu", "--no-first-run",
                "--no-default-browser-check", "--disable-extensions", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage", f"--user-data-dir={profile}",
                "--hide-scrollbars", "about:blank"]  # fmt: skip

        def fds() -> None:  # the child's fd 3 reads our commands, fd 4 writes its answers
            r, w = os.dup(to_browser_r), os.dup(from_browser_w)  # above 4: neither is overwritten by the other
            os.dup2(r, 3)
            os.dup2(w, 4)  # dup2 leaves both inheritable

        proc = subprocess.Popen(args, preexec_fn=fds, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, close_fds=False)
        os.close(to_browser_r)
        os.close(from_browser_w)
        pipe = _Pipe(to_browser_w, from_browser_r)
        try:
            target = pipe.call("Target.createTarget", url="about:blank")["targetId"]
            session = pipe.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
            for domain in ("Page", "Runtime", "Log", "Network"):
                pipe.call(f"{domain}.enable", session=session)
            pipe.call("Emulation.setDeviceMetricsOverride", session=session, width=width, height=900, deviceScaleFactor=1,
                      mobile=False)  # fmt: skip
            pipe.events.clear()
            pipe.call("Page.navigate", session=session, url=url, timeout=timeout)
            pipe.wait_for("Page.loadEventFired", timeout)
            time.sleep(0.3)  # late console messages
            found = json.loads(pipe.call("Runtime.evaluate", session=session, expression=_FIGURES_JS, returnByValue=True)["result"]["value"])
            if screenshot is not None:
                shot = pipe.call("Page.captureScreenshot", session=session, format="png", captureBeyondViewport=True,
                                 clip={"x": 0, "y": 0, "width": width, "height": found["height"], "scale": 1}, timeout=timeout)  # fmt: skip
                Path(screenshot).write_bytes(base64.b64decode(shot["data"]))
            events = list(pipe.events)
        finally:
            try:
                pipe.call("Browser.close", timeout=5)
            except (RuntimeError, TimeoutError, OSError):
                pass
            os.close(to_browser_w)
            os.close(from_browser_r)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    return dict(found, errors=_errors(events), requests=_requests(events, url))


def _errors(events: list[dict]) -> list[str]:
    out = []
    for e in events:
        method, params = e.get("method"), e.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            out.append("console: " + " ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", [])))
        elif method == "Runtime.exceptionThrown":
            d = params.get("exceptionDetails", {})
            out.append("exception: " + str(d.get("exception", {}).get("description") or d.get("text")))
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            out.append("log: " + params["entry"].get("text", ""))
        elif method == "Network.loadingFailed":
            out.append("failed load: " + params.get("errorText", ""))
    return out


def _requests(events: list[dict], page_url: str) -> list[str]:
    urls = [e["params"]["request"]["url"] for e in events if e.get("method") == "Network.requestWillBeSent"]
    return [u for u in urls if u != page_url]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python tests/browser.py", description=__doc__.splitlines()[0])
    p.add_argument("page", help="the report's index.html")
    p.add_argument("--screenshot", default=None, metavar="PNG", help="write a screenshot of the whole page")
    p.add_argument("--width", type=int, default=1200, help="the window's width in CSS pixels (default 1200)")
    args = p.parse_args(argv)
    found = inspect(args.page, args.screenshot, args.width)
    empty = [f["id"] for f in found["figures"] if not (f["width"] > 0 and f["height"] > 0 and f["complete"])]
    print(f"{found['title']}: {len(found['figures'])} figures, {found['tables']} tables, {found['height']} px tall")
    for what, items in (("error", found["errors"]), ("network request", found["requests"]), ("empty figure", empty)):
        for item in items:
            print(f"{what}: {item}")
    sys.exit(1 if found["errors"] or found["requests"] or empty else 0)


if __name__ == "__main__":
    main()
