"""A page open in a browser for the bench: Debian's Chromium, headless, driven by playwright
in a process of its own (``python -m joint_space_control.lab.bench.browser <url>``).

The browser is the system's (``make system-deps`` installs Debian's chromium), found on
PATH and handed to playwright by executable path (playwright's own builds are never
downloaded), with WebGL in software on the SwiftShader Debian's chromium ships, as
test/integration/browser.py launches it for the tests. Its own process keeps the page's
cost (playwright's driver, Chromium's processes) apart from the bench's and lets the bench
spin rclpy meanwhile; the process prints one JSON line once the page is connected (or why
it is not) and keeps the page open until its stdin closes.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

#: Chromium's switches: software WebGL on SwiftShader, no sandbox (why: the docstring of
#: test/integration/browser.py, which launches the tests' browser with these too).
CHROMIUM_ARGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox")
#: The page is connected once this text is on it (the server's label) and a canvas exists.
CONNECTED_TEXT = "joint_space_control"
#: The robot's panel is built once this text is on it (its plots' folder).
PLOTTING_TEXT = "Plots"


def without_sys_nice() -> list[str]:
    """The command prefix that starts a program without CAP_SYS_NICE when this process is
    root (nothing otherwise). As root, Chromium raises its browser, renderer and I/O threads
    to niceness -8 by itself (seen with chromium 156: the renderer drawing WebGL at -8 and
    35 % of a core beside the loop, while the page test timed out waiting for a click);
    without the capability it cannot, and the niceness it was started at holds."""
    if os.geteuid() != 0 or shutil.which("setpriv") is None:
        return []
    return ["setpriv", "--inh-caps=-sys_nice", "--bounding-set=-sys_nice"]


def missing() -> str | None:
    """Why no page can be opened here (chromium or playwright missing), or None."""
    if shutil.which("chromium") is None:
        return "chromium is not installed (`make system-deps` installs Debian's chromium)"
    if importlib.util.find_spec("playwright") is None:
        return "playwright is not installed (the test extra has it)"
    return None


class PageError(RuntimeError):
    pass


class OpenPage:
    """The process holding the page (its descendants: the playwright driver, Chromium)."""

    def __init__(self, proc: subprocess.Popen, url: str) -> None:
        self.proc = proc
        self.pid = proc.pid
        self.url = url

    def _answer(self, what: str) -> None:
        line = self.proc.stdout.readline()
        try:
            answer = json.loads(line)
        except ValueError:
            answer = {
                "error": line + (self.proc.stderr.read() if self.proc.poll() is not None else "")
            }
        if "error" in answer:
            raise PageError(f"the page at {self.url} {what}: {str(answer['error'])[-500:]}")

    def connected(self) -> str:
        """ "" once the page is connected (waits for it), else why not."""
        try:
            self._answer("did not open")
        except PageError as err:
            return str(err).splitlines()[0]
        return ""

    def close(self) -> None:
        _close(self.proc)

    def wait_plotting(self) -> None:
        """Until the page shows a robot's plots (raises :class:`PageError` on time-out)."""
        self.proc.stdin.write("plotting\n")
        self.proc.stdin.flush()
        self._answer("shows no plots")


@contextmanager
def page_open(url: str, timeout: float = 60.0, nice: int = 0) -> Iterator[OpenPage]:
    """The page at ``url`` open and connected in headless Chromium until leaving, the
    browser's processes at niceness ``nice`` (held: :func:`without_sys_nice`); raises
    :class:`PageError` when it does not connect within ``timeout``."""
    page = launch(url, timeout, nice)
    try:
        page._answer("did not open")
        yield page
    finally:
        page.close()


def launch(url: str, timeout: float = 60.0, nice: int = 0) -> OpenPage:
    """The browser started on ``url`` without waiting for it (as a person opens a page):
    :meth:`OpenPage.connected` says later whether it connected; :meth:`OpenPage.close`
    closes it."""
    proc = subprocess.Popen(
        [*without_sys_nice(), sys.executable, "-m", __name__, url, str(timeout)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=(lambda: os.nice(nice)) if nice else None,  # its children inherit it
    )
    return OpenPage(proc, url)


def _close(proc: subprocess.Popen, timeout: float = 10.0) -> None:
    try:
        proc.stdin.close()  # the process closes the browser and exits
        proc.wait(timeout=timeout)
    except (OSError, subprocess.TimeoutExpired):
        proc.kill()
        proc.wait()


def _serve(url: str, timeout: float) -> None:
    import queue

    from playwright.sync_api import TimeoutError as PlaywrightTimeout
    from playwright.sync_api import sync_playwright

    asked: queue.Queue[str | None] = queue.Queue()

    def read() -> None:
        for line in sys.stdin:
            asked.put(line.strip())
        asked.put(None)  # closed: the page is closed

    threading.Thread(target=read, daemon=True).start()
    ms = timeout * 1000
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=shutil.which("chromium"), headless=True, args=list(CHROMIUM_ARGS)
        )
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.goto(url, timeout=ms)
            page.wait_for_selector("canvas", timeout=ms)
            page.get_by_text(CONNECTED_TEXT).first.wait_for(timeout=ms)
            print(json.dumps({"connected": True}), flush=True)
            while True:
                try:
                    request = asked.get_nowait()
                except queue.Empty:
                    page.wait_for_timeout(250)  # playwright's events handled meanwhile
                    continue
                if request is None:
                    break
                if request == "plotting":
                    try:
                        page.get_by_text(PLOTTING_TEXT, exact=True).first.wait_for(timeout=ms)
                    except PlaywrightTimeout as err:  # the page stays open: measured so
                        print(json.dumps({"error": f"TimeoutError: {err}"}), flush=True)
                    else:
                        print(json.dumps({"plotting": True}), flush=True)
        finally:
            browser.close()


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    try:
        _serve(args[0], float(args[1]) if len(args) > 1 else 60.0)
    except Exception as err:  # noqa: BLE001 - the parent reads it as the one line
        print(json.dumps({"error": f"{type(err).__name__}: {err}"}), flush=True)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
