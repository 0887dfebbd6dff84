"""End-to-end test of `penumbra report` in a real browser: the page is served on localhost
and driven in headless Chromium (Debian's, through Playwright); pixels are read from
screenshots of the view.

    python -m pytest tests/browser          # after `cargo build --release` and the module

The images are synthetic, so every displayed value is known: a 16x16 reference that is a
checkerboard of 0.1 and 0.05 (grey), image A = 1.5 x the reference, image B = 0.5 x. The
view is 768 px wide, so the page fits the image at 48 screen pixels per image pixel.
"""

import functools
import http.server
import os
import re
import subprocess
import threading
from io import BytesIO
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from playwright.sync_api import sync_playwright

import penumbra

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
# As this machine's notes prescribe for headless Chromium without network.
FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
N = 16
ZOOM = 768 // N  # 48
# The canvas point at the middle of image pixel (8, 8).
PROBE = (8 * ZOOM + ZOOM // 2, 8 * ZOOM + ZOOM // 2)


def cli():
    path = Path(os.environ.get("PENUMBRA_BIN", ROOT / "target" / "release" / "penumbra"))
    assert path.exists(), f"{path} missing: run `cargo build --release` or set PENUMBRA_BIN"
    return str(path)


def srgb_to_linear(v8):
    s = v8 / 255
    return s / 12.92 if s <= 0.04045 else ((s + 0.055) / 1.055) ** 2.4


def linear_interval(v8):
    """The linear values that the 8-bit sRGB value v8 can stand for (round to nearest)."""
    lo, hi = max(v8 - 0.5, 0), min(v8 + 0.5, 255)
    return srgb_to_linear(lo), srgb_to_linear(hi)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    y, x = np.mgrid[0:N, 0:N]
    ref = np.where((x + y) % 2 == 0, 0.1, 0.05).astype(np.float32)[..., None].repeat(3, axis=2)
    penumbra.write_exr(d / "ref.exr", ref, variance=np.full_like(ref, 1e-4), attributes={"spp": 4096})
    penumbra.write_exr(d / "a.exr", 1.5 * ref, variance=np.full_like(ref, 1e-4), attributes={"spp": 64})
    penumbra.write_exr(d / "b.exr", 0.5 * ref, variance=np.full_like(ref, 1e-4), attributes={"spp": 64})
    out = d / "page"
    subprocess.run(
        [cli(), "report", "--reference", d / "ref.exr", d / "a.exr", d / "b.exr", "-o", out],
        check=True,
        capture_output=True,
    )
    return out


@pytest.fixture(scope="module")
def server(report):
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    handler = functools.partial(Quiet, directory=str(report))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}/index.html"
    httpd.shutdown()


@pytest.fixture(scope="module")
def browser():
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=FLAGS)
        yield b
        b.close()


@pytest.fixture
def page(browser, server):
    page = browser.new_page(viewport={"width": 1400, "height": 1000}, device_scale_factor=1)
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(server)
    page.wait_for_selector("#metrics tr[data-image]")
    yield page
    assert errors == [], errors
    page.close()


def view(page):
    return Image.open(BytesIO(page.locator("#view").screenshot())).convert("RGB")


def pixel(page, at=PROBE):
    return view(page).getpixel(at)


def run_length(img, at):
    """Width of the run of pixels of the same colour as `at` along its row."""
    x0, y = at
    c = img.getpixel(at)
    left = x0
    while left > 0 and img.getpixel((left - 1, y)) == c:
        left -= 1
    right = x0
    while right < img.width - 1 and img.getpixel((right + 1, y)) == c:
        right += 1
    return right - left + 1


def test_page_shows_the_reference_and_flips_between_images(page):
    grey = pixel(page)
    assert grey[0] == grey[1] == grey[2]
    # image pixel (8, 8) is 0.1 in the reference: its sRGB value, rounded
    lo, hi = linear_interval(grey[0])
    assert lo <= 0.1 <= hi, grey
    page.keyboard.press("2")  # image A = 1.5 x reference
    lo, hi = linear_interval(pixel(page)[0])
    assert lo <= 0.15 <= hi
    page.keyboard.press("ArrowRight")  # image B = 0.5 x reference
    lo, hi = linear_interval(pixel(page)[0])
    assert lo <= 0.05 <= hi
    page.keyboard.press("ArrowRight")  # wraps to the reference
    assert pixel(page) == grey
    page.click("button.img >> nth=1")
    assert page.locator("#metrics tr.active td").first.inner_text().startswith("2: a.exr")


def test_one_stop_more_exposure_doubles_the_displayed_linear_value(page):
    before = pixel(page)[0]
    page.locator("#exposure").fill("1")
    after = pixel(page)[0]
    assert page.locator("#exposure-value").inner_text() == "+1.0"
    # the ratio of the linear values the two 8-bit pixels can stand for must include 2
    (lo0, hi0), (lo1, hi1) = linear_interval(before), linear_interval(after)
    assert lo1 / hi0 <= 2 <= hi1 / lo0, (before, after)
    assert after > before
    page.keyboard.press("[")  # one stop down again, by key
    assert pixel(page)[0] == before
    page.keyboard.press("]")
    assert pixel(page)[0] == after


def test_zoom_goes_down_to_single_pixels_and_keeps_the_point_under_the_cursor(page):
    page.mouse.move(page.locator("#view").bounding_box()["x"] + PROBE[0],
                    page.locator("#view").bounding_box()["y"] + PROBE[1])
    assert "pixel x 8, y 8" in page.locator("#readout").inner_text()
    img = view(page)
    assert run_length(img, PROBE) == ZOOM  # checkerboard: one image pixel is 48 px wide
    page.mouse.wheel(0, -100)  # zoom in x2 at the cursor
    img = view(page)
    assert run_length(img, PROBE) == 2 * ZOOM
    assert "pixel x 8, y 8" in page.locator("#readout").inner_text()
    page.keyboard.press("+")  # x2 at the view's centre
    assert run_length(view(page), PROBE) == 4 * ZOOM
    page.keyboard.press("0")  # fit
    assert run_length(view(page), PROBE) == ZOOM


def test_readout_shows_the_pixel_values(page):
    box = page.locator("#view").bounding_box()
    page.keyboard.press("2")
    page.mouse.move(box["x"] + PROBE[0], box["y"] + PROBE[1])
    text = page.locator("#readout").inner_text()
    lines = text.splitlines()
    assert lines[0] == "pixel x 8, y 8" and lines[1].startswith("a.exr: "), text
    values = [float(v) for line in lines[1:3] for v in line.split(": ")[1].split(", ")]
    values += [float(re.search(r"A − ref (\S+),", lines[3]).group(1)), float(lines[3].split()[-1])]
    # a.exr (0.15, 0.15, 0.15), ref.exr (0.1, 0.1, 0.1), A - ref 0.05, rel. error 0.05 / 0.11;
    # half floats keep 11 significant bits
    expected = [0.15] * 3 + [0.1] * 3 + [0.05, 0.05 / 0.11]
    assert len(values) == len(expected), text
    for v, e in zip(values, expected):
        assert abs(v - e) <= 2e-3 * e, text


def test_error_maps_colour_the_signed_difference(page):
    page.keyboard.press("2")  # A > reference everywhere
    page.select_option("#mode", "diff")
    red = pixel(page)
    assert red[0] > red[2] + 50, red
    page.keyboard.press("3")  # B < reference everywhere
    blue = pixel(page)
    assert blue[2] > blue[0] + 50, blue
    assert page.locator("#legend-what").inner_text().startswith("A − ref")
    page.keyboard.press("1")  # the reference against itself: zero, the middle colour
    mid = pixel(page)
    assert abs(mid[0] - mid[2]) < 10, mid
    page.select_option("#mode", "relerr")
    assert pixel(page) == pixel(page, (PROBE[0] + ZOOM, PROBE[1]))  # zero everywhere


def test_metrics_table_lists_every_image(page):
    rows = page.locator("#metrics tr[data-image]")
    assert rows.count() == 3
    assert "reference" in rows.nth(0).inner_text()
    # image A: RMSE = 0.5 x RMS of the reference (|A - ref| = 0.5 ref)
    rms = np.sqrt((0.1**2 + 0.05**2) / 2)
    rmse = float(rows.nth(1).locator("td").nth(3).inner_text())
    assert abs(rmse - 0.5 * rms) <= 1e-3 * rmse


def test_page_opens_from_disk(browser, report):
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto((report / "index.html").as_uri())
    page.wait_for_selector("#metrics tr[data-image]")
    img = Image.open(BytesIO(page.locator("#view").screenshot())).convert("RGB")
    lo, hi = linear_interval(img.getpixel(PROBE)[0])
    assert lo <= 0.1 <= hi
    assert errors == []
    page.close()


# A file name that is markup: shown as the text it is, never run (it would set window.pwned).
HOSTILE = "<img src=x onerror=\"window.pwned=1\">.exr"


def test_file_names_are_shown_as_text_and_never_run(browser, tmp_path):
    ref = np.full((4, 4, 3), 0.25, dtype=np.float32)
    penumbra.write_exr(tmp_path / "ref.exr", ref)
    penumbra.write_exr(tmp_path / HOSTILE, 2 * ref)
    out = tmp_path / "page"
    subprocess.run(
        [cli(), "report", "--reference", tmp_path / "ref.exr", tmp_path / HOSTILE, "-o", out],
        check=True,
        capture_output=True,
    )
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto((out / "index.html").as_uri())
    page.wait_for_selector("#metrics tr[data-image]")
    page.wait_for_timeout(200)  # an onerror handler runs once the image fails to load
    assert page.evaluate("window.pwned") is None
    assert page.locator("#metrics img").count() == 0
    rows = page.locator("#metrics tr[data-image]")
    assert rows.nth(1).locator("td").nth(0).inner_text() == f"2: {HOSTILE}"
    assert page.locator("#images button").nth(1).inner_text() == f"2: {HOSTILE}"
    assert errors == []
    page.close()
