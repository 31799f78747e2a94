"""The page of ``turbinefit view`` in a real headless browser (Debian's Chromium, driven by
playwright): it loads with no console error and no request beyond itself, draws a
non-blank scene with the turbine in the middle, and a click on a camera shows its photo
with the skeleton over it. Skipped, saying why, where there is no Chromium or playwright
(``.ci/run`` installs both, and requires the test to run)."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from support_browser import opened, why_no_browser

from turbinefit.cli import main

#: CI sets it (``.ci/run`` installs Chromium): there the test must run, not skip.
REQUIRED = os.environ.get("TURBINEFIT_REQUIRE_BROWSER") == "1"
pytestmark = pytest.mark.skipif(why_no_browser() is not None and not REQUIRED,
                                reason=str(why_no_browser()))


@pytest.fixture(scope="module")
def page_path(photo_flight_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("browser")
    fit = folder / "fit"
    assert main(["fit", str(photo_flight_dir), "--out", str(fit), "--no-plots", "--quiet"]) == 0
    assert main(["plan", str(fit), "--standoff", "10", "--out", str(folder / "plan"),
                 "--no-plots", "--quiet"]) == 0
    out = folder / "view.html"
    assert main(["view", str(fit), "--plan", str(folder / "plan"), "--out", str(out),
                 "--thumbnail", "120", "--quiet"]) == 0
    return out


def _shot(page: object, path: Path) -> np.ndarray:
    png = page.screenshot(path=str(path))  # type: ignore[attr-defined]
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.int16)


def test_the_page_draws_the_turbine_and_loads_nothing_else(page_path: Path,
                                                          tmp_path: Path) -> None:
    with opened(page_path) as view:
        page = view.page
        assert page.evaluate("() => document.documentElement.dataset.ready") == "true", \
            page.evaluate("() => window.turbinefitView.error")
        assert view.errors == []
        assert view.requests == [page_path.resolve().as_uri()]  # data: images are no requests
        layers = {layer["key"] for layer in page.evaluate("() => window.turbinefitView.layers()")}
        assert {"turbine", "coverage", "cameras_optimised", "cameras_initial",
                "cameras_ground_truth", "plan", "grid"} <= layers
        # plain colours: the turbine off-white, as turbine.glb
        page.evaluate("() => window.turbinefitView.setLayer('coverage', false)")
        page.evaluate("() => window.turbinefitView.render()")
        shown = _shot(page, tmp_path / "shown.png")
        for key in layers:
            on = "true" if key == "turbine" else "false"
            page.evaluate(f"() => window.turbinefitView.setLayer('{key}', {on})")
        page.evaluate("() => window.turbinefitView.render()")
        alone = _shot(page, tmp_path / "turbine.png")
        page.evaluate("() => window.turbinefitView.setLayer('turbine', false)")
        page.evaluate("() => window.turbinefitView.render()")
        empty = _shot(page, tmp_path / "empty.png")
        assert view.errors == []
    h, w, _ = shown.shape
    # the canvas is not blank: lines, frusta, the grid and the turbine vary it
    canvas = shown[int(0.25 * h):int(0.95 * h), int(0.30 * w):int(0.95 * w)]
    assert canvas.std() > 10
    # the turbine is in the middle, in its colour: grey-white where the scene without it is not
    centre = (slice(int(0.2 * h), int(0.8 * h)), slice(int(0.3 * w), int(0.7 * w)))
    changed = np.abs(alone[centre] - empty[centre]).sum(axis=-1) > 30
    assert changed.mean() > 0.01, changed.mean()
    px = alone[centre][changed]
    neutral = (np.ptp(px, axis=-1) < 24) & (px.mean(axis=-1) > 90)
    assert neutral.mean() > 0.6, neutral.mean()


def test_a_click_on_a_camera_shows_its_photo_with_the_skeleton(page_path: Path) -> None:
    with opened(page_path) as view:
        page = view.page
        xy = None
        for k in (2, 3, 1, 4, 0, 5):  # a keyframe drawn in view
            xy = page.evaluate(f"() => window.turbinefitView.screenOf('optimised', {k})")
            if xy is not None:
                break
        assert xy is not None
        page.mouse.click(*xy)
        panel = page.locator("#photo")
        panel.wait_for(state="visible", timeout=5000)
        k = page.evaluate("() => window.turbinefitView.selected()")
        assert k is not None and panel.locator("h2").inner_text().startswith(f"Keyframe {k} of 6")
        img = panel.locator("img")
        assert img.evaluate("i => i.complete && i.naturalWidth") == 120
        assert panel.locator("svg polyline").count() >= 2 * 5  # the lines, outlined
        page.keyboard.press("ArrowRight" if k < 5 else "ArrowLeft")
        assert page.evaluate("() => window.turbinefitView.selected()") != k
        page.keyboard.press("Escape")
        assert panel.is_hidden()
        assert view.errors == []
