"""Headless Chromium for the browser tests: Debian's chromium driven by playwright.

The browser is the system's (`make system-deps` installs Debian's chromium), found on PATH
and handed to playwright by executable path: playwright's own browser builds are never
downloaded (never run `playwright install`). Without chromium or playwright the test is
skipped with the reason.

WebGL runs in software, on the SwiftShader that Debian's chromium ships
(/usr/lib/chromium/libvk_swiftshader.so), through ANGLE. Measured with chromium 156 and
playwright 1.65, as root: only ``--no-sandbox`` is needed (without it "Chromium sandboxing
failed!"), and playwright adds it itself unless ``chromium_sandbox=True``; headless Chromium
picks ``--use-angle=swiftshader-webgl`` on its own, and playwright adds
``--enable-unsafe-swiftshader`` (the opt-in Chromium asks for as it retires the automatic
software fallback of WebGL). All three are passed explicitly all the same, so that neither
an older playwright nor a GPU on the machine changes what the tests render with.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

# Chromium's switches (software WebGL on SwiftShader, no sandbox: see the module docstring),
# one list for the tests and the bench
from joint_space_control.lab.bench.browser import CHROMIUM_ARGS, without_sys_nice

if TYPE_CHECKING:
    from playwright.sync_api import Browser, Playwright


def chromium_path() -> str:
    """The system Chromium's executable, or skip the test."""
    path = shutil.which("chromium")
    if path is None:
        pytest.skip("chromium is not installed (`make system-deps` installs Debian's chromium)")
    return path


def launch_chromium(
    playwright: Playwright, executable: str | None = None, **options: Any
) -> Browser:
    """A headless system Chromium launched by ``playwright`` (``sync_playwright()``'s
    object) with software WebGL; ``executable``: what starts it (default: chromium itself);
    ``options`` go to ``chromium.launch`` (``args`` are added after
    :data:`CHROMIUM_ARGS`). Skips the test when chromium is missing."""
    args = [*CHROMIUM_ARGS, *options.pop("args", ())]
    return playwright.chromium.launch(
        executable_path=executable or chromium_path(), headless=True, args=args, **options
    )


def niced_chromium(folder: Path, nice: int) -> str:
    """A script in ``folder`` that starts the system Chromium at niceness ``nice``: every
    process of the browser inherits it (docs/dashboard.md: on the loop's machine, open the
    page at the lowest priority, so that the loop and the dashboard come first), without
    CAP_SYS_NICE so that the niceness holds (:func:`without_sys_nice`)."""
    drop = "".join(f"{word} " for word in without_sys_nice())
    script = folder / "chromium-niced"
    script.write_text(f'#!/bin/sh\nexec {drop}nice -n {int(nice)} {chromium_path()} "$@"\n')
    script.chmod(0o755)
    return str(script)


@contextmanager
def chromium(nice: int = 0, **options: Any) -> Iterator[Browser]:
    """Playwright started and the system Chromium launched (:func:`launch_chromium`) at
    niceness ``nice``, both stopped on leaving, also on failure. Skips the test when
    playwright or chromium is missing."""
    sync_api = pytest.importorskip(
        "playwright.sync_api", reason="playwright is not installed (the test extra has it)"
    )
    chromium_path()  # skip before starting playwright's driver
    with tempfile.TemporaryDirectory() as folder, sync_api.sync_playwright() as playwright:
        executable = niced_chromium(Path(folder), nice) if nice else None
        browser = launch_chromium(playwright, executable, **options)
        try:
            yield browser
        finally:
            browser.close()
