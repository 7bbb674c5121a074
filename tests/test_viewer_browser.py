"""The replay in a real browser: headless Chromium (Debian's) driven by Playwright opens the
live server's page and an exported HTML file, and checks that the net is drawn (against an
empty viser scene), that the timeline advances on play, that frame steps land on recorded
frames, that the mouth panel is there, and that the page logs no error."""

from __future__ import annotations

import io
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
VIEWPORT = {"width": 960, "height": 600}
SCENE_CLIP = {"x": 120, "y": 0, "width": 440, "height": 520}
"""The part of the page between viser's axes gizmo (bottom left) and its control panel
(right), above its playback bar [px]."""
HIDE_OVERLAYS = "#bulletnet-panel, .mantine-Notifications-root { display: none !important; }"


@pytest.fixture(scope="module")
def browser():
    if not Path(CHROMIUM).exists():
        pytest.skip(f"no browser: {CHROMIUM} is missing (apt-get install -y chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("no browser driver: the playwright package is missing "
                    "(pip install -e '.[test]')")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


@pytest.fixture
def runs(viewer_runs):
    return viewer_runs


def open_page(browser, url: str):
    """A page at ``url`` with its canvas up; the list collects console errors."""
    page = browser.new_page(viewport=VIEWPORT)
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    page.wait_for_selector("canvas", timeout=30_000)
    return page, errors


def recording_pixels(page) -> tuple[int, int]:
    """Pixels of the scene area in the first recording's colours (blues: blue over red by 40
    of 255) and in the second's (oranges: red over blue by 80); the background, the grid, the
    slack threads and the debris are grey, contacts magenta."""
    from PIL import Image

    style = page.add_style_tag(content=HIDE_OVERLAYS)
    png = page.screenshot(clip=SCENE_CLIP)
    style.evaluate("element => element.remove()")
    r, g, b = np.moveaxis(np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), int), 2, 0)
    return (int(np.count_nonzero((b - r > 40) & (b >= g))),
            int(np.count_nonzero((r - b > 80) & (r > g))))


@pytest.fixture(scope="module")
def empty_scene(browser, tmp_path_factory):
    """viser's client showing nothing: the detector of recording colours finds none there."""
    from bulletnet.viewer import viser_server

    with viser_server() as server:
        html = server.get_scene_serializer().as_html()
    path = tmp_path_factory.mktemp("empty") / "empty.html"
    path.write_text(html)
    page, _ = open_page(browser, path.as_uri())
    time.sleep(1.0)
    counts = recording_pixels(page)
    page.close()
    assert counts == (0, 0)


def wait_for(predicate, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def net_drawn(page) -> None:
    """Both recordings' colours appear where an empty scene has none."""
    wait_for(lambda: min(recording_pixels(page)) > 0, 30, "both recordings to be drawn")


def slider_value(page, nth: int = 0) -> float:
    return float(page.locator('[role="slider"]').nth(nth).get_attribute("aria-valuenow"))


def test_exported_html_draws_plays_and_steps(browser, runs, empty_scene):
    from bulletnet.viewer import export_html, load_replay

    replay = load_replay([runs["plain"], runs["bending"]])
    out = export_html(replay, runs["dir"] / "replay.html", [0.1, 0.2], force=True)
    page, errors = open_page(browser, out.as_uri())
    page.wait_for_selector("#bulletnet-mouth #mouth-1")
    first = slider_value(page)
    wait_for(lambda: slider_value(page) != first, 20, "the playback time to advance")
    # frame steps pause playback and land on the recorded frames, one at a time
    times = replay.time - replay.time[0]
    page.click("#bulletnet-next")
    wait_for(lambda: np.min(np.abs(times - slider_value(page))) < 1e-6, 10,
             "a step to a recorded frame")
    k = int(np.argmin(np.abs(times - slider_value(page))))
    # the step lands wherever playback was, the last frame included: a step past it stays there
    j = min(k + 1, times.size - 1)
    page.click("#bulletnet-next")
    wait_for(lambda: abs(slider_value(page) - times[j]) < 1e-6, 10, "the next frame")
    wait_for(lambda: page.text_content("#time-label") == f"t = {replay.time[j]:.3f} s", 5,
             "the panel's time")
    page.click("#bulletnet-prev")
    wait_for(lambda: abs(slider_value(page) - times[j - 1]) < 1e-6, 10, "the previous frame")
    net_drawn(page)
    assert errors == []


def test_live_server_draws_plays_and_hides_missing_controls(browser, runs, empty_scene):
    proc = subprocess.Popen(
        [sys.executable, "-m", "bulletnet.cli.main", "view", str(runs["capture"]),
         str(runs["bending"]), "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)
    try:
        line = proc.stdout.readline()
        match = re.search(r"http://127\.0\.0\.1:\d+", line)
        assert match, (line, proc.stderr.read() if proc.poll() is not None else "")
        page, errors = open_page(browser, match.group(0))
        page.wait_for_selector("#bulletnet-mouth #mouth-0", timeout=30_000)
        for control in ("debris", "thread colour", "contacts"):
            assert page.get_by_text(control, exact=True).count() == 1, control
        assert slider_value(page) == 0
        page.get_by_role("button", name="Play").click()
        wait_for(lambda: slider_value(page) > 0, 20, "the frame slider to advance")
        net_drawn(page)
        assert errors == []
        page.close()
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err


def test_exported_tow_shows_its_panel_over_the_folded_mouth_panel(browser, viewer_tow,
                                                                  tmp_path):
    from bulletnet.viewer import export_html, load_replay

    out = export_html(load_replay([viewer_tow]), tmp_path / "tow.html", [0.1])
    page, errors = open_page(browser, out.as_uri())
    page.wait_for_selector("#bulletnet-tow #value-tension")
    assert not page.is_visible("#bulletnet-mouth")
    # the burn starts at 0.2 s of the 0.5 s replay, which plays and loops
    wait_for(lambda: page.text_content("#value-thrust") != "- [N]", 30,
             "the thrust read out during the burn")
    wait_for(lambda: page.text_content("#tow-time-label") == page.text_content("#time-label"),
             5, "both panels at one frame")
    page.click("summary:has-text('Mouth')")
    page.wait_for_selector("#bulletnet-mouth", state="visible")
    assert errors == []
