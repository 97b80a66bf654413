"""The browser the dashboard's test uses renders: system Chromium, headless, through
playwright (test/integration/browser.py), with WebGL on software (SwiftShader).

A local page (a data: URL, no server, no network) clears a WebGL canvas to a colour and
reads the pixel back, for WebGL 1 and 2 (three.js, viser's renderer, asks for 2), and draws
a line of text, which must leave dark pixels (fonts present). About 1 s.
"""

from __future__ import annotations

from io import BytesIO

import numpy as np
from PIL import Image

from .browser import chromium

#: Clears a canvas of the given context kind to (255, 0, 0) and reads a pixel back; null
#: when the context cannot be had.
CLEAR_AND_READ = """kind => {
  const gl = document.createElement('canvas').getContext(kind);
  if (!gl) return null;
  gl.clearColor(1, 0, 0, 1);
  gl.clear(gl.COLOR_BUFFER_BIT);
  const px = new Uint8Array(4);
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const renderer = gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER);
  return {pixel: Array.from(px), renderer: renderer};
}"""

PAGE = "data:text/html,<p style='font:40px sans-serif;margin:0'>joint_space_control</p>"


def test_chromium_renders_webgl_and_text() -> None:
    with chromium() as browser:
        page = browser.new_page(viewport={"width": 480, "height": 60})
        page.goto(PAGE)
        for kind in ("webgl", "webgl2"):
            result = page.evaluate(CLEAR_AND_READ, kind)
            assert result is not None, f"no {kind} context in headless chromium"
            assert result["pixel"] == [255, 0, 0, 255], result
        png = page.screenshot()

    gray = np.asarray(Image.open(BytesIO(png)).convert("L"))
    assert (gray < 100).sum() > 500, "the line of text left (almost) no dark pixels"
