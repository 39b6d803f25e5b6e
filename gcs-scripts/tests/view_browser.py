"""What a person sees in the live view's web viewer, checked in headless Chromium (selenium, software WebGL
through SwiftShader): `check_live_view(url, out_dir)` opens the viewer's URL (as `aco-view --web` or
`sitl run --view` prints it), waits until the 3D view has drawn source 0's orange quadrotor, takes two
screenshots 2 s apart and asserts that (a) an orange blob is inside the 3D panel and (b) the time-series
panels moved on between them (their pixels changed and so did the time axis' tick-label row). It returns the
screenshots' paths. The layout is aco_gcs.view_log.blueprint()'s at a 1280x800 window: the 3D view takes the
left 3/5, the plots the right 2/5."""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

WINDOW = (1280, 800)
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
# Regions of the 1280x800 screenshot (left, top, right, bottom): the 3D panel, and the plot column.
PANEL_3D = (0, 40, 740, 790)
PLOTS = (790, 40, 1280, 600)
# The position-error plot's time-axis tick labels (the top plot's bottom row).
TICKS = (790, 200, 1280, 222)


@dataclass
class LiveView:
    a: Path
    b: Path
    orange_px: int
    plot_changed_px: int
    tick_rows_changed: int
    tick_labels_changed_px: int


def _rgb(img: Image.Image, box: tuple[int, int, int, int]) -> np.ndarray:
    return np.asarray(img.convert("RGB").crop(box), dtype=np.int16)


def orange_mask(img: Image.Image, box: tuple[int, int, int, int]) -> list[tuple[int, int]]:
    """The pixels (screen x, y) of box whose colour is the shaded orange [255, 128, 0]."""
    px = _rgb(img, box)
    r, g, b = px[..., 0], px[..., 1], px[..., 2]
    ys, xs = np.nonzero((r > 200) & (g > 90) & (g < 170) & (b < 60))
    return [(int(x) + box[0], int(y) + box[1]) for y, x in zip(ys, xs, strict=True)]


def largest_blob(pixels: list[tuple[int, int]]) -> int:
    """The size of the largest 8-connected group of the pixels."""
    todo = set(pixels)
    best = 0
    while todo:
        stack = [todo.pop()]
        size = 0
        while stack:
            x, y = stack.pop()
            size += 1
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    n = (x + dx, y + dy)
                    if n in todo:
                        todo.remove(n)
                        stack.append(n)
        best = max(best, size)
    return best


def _diff(a: Image.Image, b: Image.Image, box: tuple[int, int, int, int]) -> np.ndarray:
    """Per pixel of box, whether a and b differ by more than a little."""
    return np.abs(_rgb(a, box) - _rgb(b, box)).max(axis=2) > 24


def changed(a: Image.Image, b: Image.Image, box: tuple[int, int, int, int]) -> int:
    """How many pixels of box differ between a and b."""
    return int(_diff(a, b, box).sum())


def changed_rows(a: Image.Image, b: Image.Image, box: tuple[int, int, int, int]) -> list[int]:
    """The rows of box (screen y) where a and b differ."""
    return [box[1] + int(y) for y in np.nonzero(_diff(a, b, box).any(axis=1))[0]]


def chrome(profile_dir: Path):  # -> selenium.webdriver.Chrome
    """Headless Chromium with software WebGL, offline, a fresh profile."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    os.environ["SE_OFFLINE"] = "true"
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--enable-unsafe-swiftshader",
        "--use-angle=swiftshader",
        f"--window-size={WINDOW[0]},{WINDOW[1]}",
        f"--user-data-dir={profile_dir}",
    ]:
        opts.add_argument(arg)
    return webdriver.Chrome(options=opts, service=Service(CHROMEDRIVER))


def check_live_view(url: str, out_dir: Path | None = None, timeout_s: float = 60.0, airborne: bool = False) -> LiveView:
    """Opens the web viewer at url while frames are flowing into it and asserts what a person would see (see
    the module's docstring). With `airborne`, screenshot A waits until the viewer shows the vehicle in the
    air: its topmost orange pixel above the 3D panel's middle, where the camera looks (1.5 m above the start
    point), so a viewer still loading the run's first seconds is not taken for the flight. Screenshots go to
    out_dir (a new temporary directory if None); when $ACO_VIEW_SCREENSHOT names a path, screenshot A is
    also copied there."""
    out = Path(out_dir) if out_dir is not None else Path(tempfile.mkdtemp(prefix="aco-view-"))
    out.mkdir(parents=True, exist_ok=True)
    driver = chrome(Path(tempfile.mkdtemp(prefix="chromium-", dir=out)))
    middle_y = (PANEL_3D[1] + PANEL_3D[3]) // 2
    try:
        # The window's size includes what headless Chromium keeps for its own chrome: the page gets exactly this.
        driver.execute_cdp_cmd(
            "Emulation.setDeviceMetricsOverride",
            {"width": WINDOW[0], "height": WINDOW[1], "deviceScaleFactor": 1, "mobile": False},
        )
        driver.get(url)
        a_path, b_path = out / "view-a.png", out / "view-b.png"
        deadline = time.monotonic() + timeout_s
        orange: list[tuple[int, int]] = []
        top_y = WINDOW[1]
        while time.monotonic() < deadline:
            driver.save_screenshot(str(a_path))
            orange = orange_mask(Image.open(a_path), PANEL_3D)
            top_y = min((y for _, y in orange), default=WINDOW[1])
            if largest_blob(orange) >= 40 and (not airborne or top_y < middle_y):
                break
            time.sleep(1.0)
        a = Image.open(a_path)
        blob = largest_blob(orange)
        assert blob >= 40, f"no orange quadrotor in the 3D panel after {timeout_s:.0f} s ({len(orange)} px): {a_path}"
        assert not airborne or top_y < middle_y, f"the view never showed the vehicle in the air: {a_path}"
        time.sleep(2.0)
        driver.save_screenshot(str(b_path))
        b = Image.open(b_path)
    finally:
        driver.quit()
    if os.environ.get("ACO_VIEW_SCREENSHOT"):
        a.save(os.environ["ACO_VIEW_SCREENSHOT"])
    moved = changed(a, b, PLOTS)
    rows = changed_rows(a, b, PLOTS)
    assert moved > 500, f"the plots did not move on in 2 s ({moved} px changed): {a_path} {b_path}"
    ticks = changed(a, b, TICKS)
    assert ticks > 20, f"the time axis' tick labels did not change in 2 s: {a_path} {b_path}"
    return LiveView(a_path, b_path, blob, moved, len(rows), ticks)
