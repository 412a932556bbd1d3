"""Screenshot a recording as a user sees it in Rerun's web viewer, in headless Chromium.

    python tools/screenshot_viewer.py circle.rrd -o docs/viewer.png

Serves the file with ``swarm_mj.output.viewer.serve_web`` (the viewer bundled in rerun-sdk), opens the
page in headless Chromium through Playwright (WebGL on the CPU through SwiftShader), waits until
the viewer holds the recording, waits for the 3D view to settle, and saves the screenshot.

"The viewer holds the recording" is read from the viewer itself, not guessed from a delay: an
init script keeps the page's ``WebHandle`` (``window.__swarm_rerun_handle``) and the wait polls
``handle.save_recording()``, the RRD encoding of the viewer's active recording. Those bytes are
written to ``--page-rrd`` and decoded with ``rerun rrd print``, which names the application id
and the entity paths the page loaded (``/world/drones/leader`` ...). The egui canvas has no DOM
text to search, so this is the page's own account of what it loaded.

Prints one JSON object: the timings, what the page loaded, and pixel statistics of the whole
screenshot and of the 3D view's region (the left 3/5 of the viewport, recording.blueprint).
``tests/integration/test_view.py`` imports :func:`shoot` and :func:`pixel_stats`.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
# WebGL on the CPU (SwiftShader); no network: the page needs nothing from outside localhost.
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
]
LEADER_RGB = (220, 40, 40)  # recording.LEADER_COLOR
FOLLOWER_RGB = (40, 110, 220)  # recording.FOLLOWER_COLOR

_CAPTURE_HANDLE = """
document.addEventListener("DOMContentLoaded", () => {
  if (typeof wasm_bindgen === "undefined" || !wasm_bindgen.WebHandle) return;
  const Orig = wasm_bindgen.WebHandle;
  wasm_bindgen.WebHandle = function (options) {
    const h = new Orig(options);
    window.__swarm_rerun_handle = h;
    return h;
  };
});
"""

_POLL = """() => {
  const h = window.__swarm_rerun_handle;
  if (!h) return {state: "no-handle"};
  if (h.has_panicked()) return {state: "panicked", message: h.panic_message()};
  try { const b = h.save_recording(); return {state: "recording", bytes: b.length}; }
  catch (e) { return {state: "no-recording", message: String(e)}; }
}"""


_SAVE_B64 = """() => {
  const b = window.__swarm_rerun_handle.save_recording();
  let s = "";
  for (let i = 0; i < b.length; i += 0x8000) s += String.fromCharCode.apply(null, b.subarray(i, i + 0x8000));
  return btoa(s);
}"""


def region_3d(width: int, height: int) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) well inside the 3D view: the blueprint gives it 3/5 of the width, below
    the top bar (~35 px) and above the time panel (~45 px)."""
    return (int(0.02 * width), 60, int(0.57 * width), height - 70)


def pixel_stats(png: str | Path, box: tuple[int, int, int, int] | None = None) -> dict:
    """Statistics of a PNG (or of ``box`` in it): grey-level std, number of distinct colours, and
    the fraction of pixels of the leader's red and of the followers' blue (recording.py colours,
    shaded: the hue test has a margin)."""
    import numpy as np
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB"), dtype=np.int32)
    if box is not None:
        x0, y0, x1, y1 = box
        img = img[y0:y1, x0:x1]
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    red = (r > 150) & (g < 90) & (b < 90)
    blue = (b > 150) & (r < 110) & (g < 160) & (b - r > 80)
    flat = img.reshape(-1, 3)
    return {
        "shape": list(img.shape[:2]),
        "grey_std": float(img.mean(axis=2).std()),
        "distinct_colours": len(np.unique(flat[:, 0] * 65536 + flat[:, 1] * 256 + flat[:, 2])),
        "leader_red_fraction": float(red.mean()),
        "follower_blue_fraction": float(blue.mean()),
    }


def rrd_contents(rrd: str | Path, timeout: float = 60) -> dict:
    """Application ids and entity paths of an .rrd, from ``rerun rrd print`` (bounded in time)."""
    from swarm_mj.output.viewer import find_rerun

    out = subprocess.run(
        [str(find_rerun()), "rrd", "print", str(rrd)], capture_output=True, text=True, timeout=timeout, check=False
    )
    text = out.stdout + out.stderr
    apps = sorted(set(re.findall(r'StoreId\(\s*Recording,\s*"([^"]+)"', text)))
    entities = sorted(set(re.findall(r" - (/[^\s]+) - data columns", text)))
    return {"rc": out.returncode, "application_ids": apps, "entities": entities}


def shoot(
    url: str,
    png: str | Path,
    *,
    page_rrd: str | Path | None = None,
    expected_bytes: int | None = None,
    timeout: float = 240,
    size: tuple[int, int] = (1600, 900),
    chromium: str = CHROMIUM,
    settle: float = 60,
) -> dict:
    """Open ``url`` in headless Chromium, wait (at most ``timeout`` s) for the viewer to hold the
    recording, then (at most ``settle`` s more) for two screenshots 3 s apart to match; save the
    last as ``png``. Returns the timings and, with ``page_rrd``, what the page loaded.

    Loaded: the viewer's own encoding of its recording reaches 90 % of ``expected_bytes`` (the
    served file's size; the viewer's copy measured 97 % of it for circle) and holds for one poll,
    or stops growing for ten polls (it streams in, and on a busy CPU it can stall for seconds)."""
    from playwright.sync_api import sync_playwright

    png = Path(png)
    t0 = time.monotonic()
    info: dict = {"url": url, "console_errors": []}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS, timeout=60_000)
        try:
            page = browser.new_page(viewport={"width": size[0], "height": size[1]})

            def on_console(m) -> None:  # distinct first lines (offline: fonts and update checks fail)
                line = m.text.splitlines()[0][:200] if m.text else ""
                if m.type == "error" and line not in info["console_errors"] and len(info["console_errors"]) < 10:
                    info["console_errors"].append(line)

            page.on("console", on_console)
            page.add_init_script(_CAPTURE_HANDLE)
            page.goto(url, timeout=60_000, wait_until="load")
            info["page_loaded_s"] = round(time.monotonic() - t0, 1)
            # the recording streams in: loaded = the viewer's copy stopped growing (3 polls, 6 s)
            state: dict = {}
            sizes: list[int] = []
            while time.monotonic() - t0 < timeout:
                state = page.evaluate(_POLL)
                if state["state"] == "panicked":
                    break
                if state["state"] == "recording":
                    if "recording_seen_s" not in info:
                        info["recording_seen_s"] = round(time.monotonic() - t0, 1)
                    sizes.append(state["bytes"])
                    if _loaded(sizes, expected_bytes):
                        break
                page.wait_for_timeout(2000)
            info["viewer_state"] = state
            if state.get("state") != "recording" or not _loaded(sizes, expected_bytes):
                page.screenshot(path=str(png))
                info["error"] = f"the viewer did not load the recording within {timeout:.0f} s: {state}"
                return info
            info["recording_loaded_s"] = round(time.monotonic() - t0, 1)
            # rendering on the CPU takes a while: wait for the picture to stop changing
            prev = cur = page.screenshot()
            t_settle = time.monotonic()
            while time.monotonic() - t_settle < settle:
                page.wait_for_timeout(3000)
                cur = page.screenshot()
                if cur == prev:
                    break
                prev = cur
            png.write_bytes(prev)
            info["settled"] = cur == prev
            info["screenshot_s"] = round(time.monotonic() - t0, 1)
            if page_rrd is not None:  # what the viewer holds as the picture is taken
                import base64

                data = base64.b64decode(page.evaluate(_SAVE_B64))
                Path(page_rrd).write_bytes(data)
                info["page_rrd_bytes"] = len(data)
        finally:
            browser.close()
    return info


def _loaded(sizes: list[int], expected_bytes: int | None) -> bool:
    """Reached 90 % of the file's size and steady for two polls, or steady for ten polls (20 s)."""
    if expected_bytes and len(sizes) >= 2 and sizes[-1] >= 0.9 * expected_bytes and sizes[-1] == sizes[-2]:
        return True
    return len(sizes) >= 10 and len(set(sizes[-10:])) == 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("rrd", help="recording to serve (ignored with --url)")
    ap.add_argument("-o", "--output", default="viewer.png", help="screenshot PNG (default viewer.png)")
    ap.add_argument("--url", help="an already served page (default: serve RRD on --port)")
    ap.add_argument("--port", type=int, default=9090, help="web page port; the recording on PORT+1")
    ap.add_argument("--size", default="1600x900", help="viewport WxH (default 1600x900)")
    ap.add_argument("--timeout", type=float, default=240, help="max wait for the recording (s)")
    ap.add_argument("--page-rrd", help="also save the recording as the page holds it, and list it")
    ap.add_argument("--chromium", default=CHROMIUM, help=f"browser executable (default {CHROMIUM})")
    a = ap.parse_args(argv)
    size = tuple(int(v) for v in a.size.lower().split("x"))
    from swarm_mj.output.viewer import serve_web, web_url

    if a.url:
        info = shoot(a.url, a.output, page_rrd=a.page_rrd, timeout=a.timeout, size=size, chromium=a.chromium)
    else:
        with serve_web(a.rrd, a.port):
            info = shoot(
                web_url(a.port),
                a.output,
                page_rrd=a.page_rrd,
                expected_bytes=Path(a.rrd).stat().st_size,
                timeout=a.timeout,
                size=size,
                chromium=a.chromium,
            )
    if "error" not in info:
        info["screenshot"] = pixel_stats(a.output)
        info["region_3d"] = region_3d(*size)
        info["view_3d"] = pixel_stats(a.output, region_3d(*size))
        if a.page_rrd:
            c = rrd_contents(a.page_rrd)
            info["page_application_ids"] = c["application_ids"]
            info["page_drone_entities"] = [
                e for e in c["entities"] if e.startswith("/world/drones/") and e.count("/") == 3
            ]
    print(json.dumps(info, indent=1))
    return 1 if "error" in info else 0


if __name__ == "__main__":
    sys.exit(main())
