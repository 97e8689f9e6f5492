"""The HumV editor in a real browser: ``humv-usd edit`` on a copy of humvvex, driven with selenium
on Debian's headless chromium (/usr/bin/chromium + /usr/bin/chromedriver)."""

from __future__ import annotations

import importlib.util
import json
import shutil
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "humvvex.toml"

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not (Path("/usr/bin/chromium").exists() and Path("/usr/bin/chromedriver").exists()),
        reason="needs Debian's chromium and chromium-driver (tools/setup.sh installs them)",
    ),
]


def _helpers():
    spec = importlib.util.spec_from_file_location(
        "editor_screenshots", ROOT / "tools" / "editor_screenshots.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


H = _helpers()


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """One editor server and one browser for the module: (driver, url, scenario, out, timings)."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    folder = tmp_path_factory.mktemp("editor")
    scenario = folder / "humvvex.toml"
    shutil.copy(EXAMPLE, scenario)
    out = folder / "out"
    timings: dict[str, float] = {}
    with H.editor_server(scenario, out) as (url, _answered, _proc):
        t0 = time.perf_counter()
        driver = H.chromium()
        try:
            driver.get(url)
            WebDriverWait(driver, 60).until(
                ec.presence_of_element_located((By.CSS_SELECTOR, '[data-field="general.name"] input'))
            )
            timings["page_usable_s"] = _answered + time.perf_counter() - t0
            yield driver, url, scenario, out, timings
        finally:
            driver.quit()
            print("editor timings:", json.dumps({k: round(v, 2) for k, v in timings.items()}))


def _input(driver, where: str):
    from selenium.webdriver.common.by import By

    return driver.find_element(By.CSS_SELECTOR, f'[data-field="{where}"] input')


def _field_messages(driver, where: str) -> str:
    from selenium.webdriver.common.by import By

    found = driver.find_elements(By.CSS_SELECTOR, f'[data-field="{where}"] .q-field__messages')
    return found[0].text if found else ""


def _type(driver, where: str, text: str) -> None:
    from selenium.webdriver.common.keys import Keys

    box = _input(driver, where)
    box.send_keys(Keys.CONTROL, "a")
    box.send_keys(Keys.BACKSPACE)
    box.send_keys(text)


def _click(driver, testid: str, limit: float = 15.0) -> None:
    """Click the element with this data-testid once it can be clicked (tab panels animate in)."""
    from selenium.common.exceptions import (
        ElementClickInterceptedException,
        ElementNotInteractableException,
        NoSuchElementException,
        StaleElementReferenceException,
    )

    t0 = time.time()
    while True:
        try:
            driver.find_element("css selector", f'[data-testid="{testid}"]').click()
            return
        except (
            ElementClickInterceptedException,
            ElementNotInteractableException,
            NoSuchElementException,
            StaleElementReferenceException,
        ):
            if time.time() - t0 > limit:
                raise
            time.sleep(0.2)


def _wait(predicate, limit: float = 20.0, what: str = ""):
    from selenium.common.exceptions import NoSuchElementException, StaleElementReferenceException

    t0 = time.time()
    while time.time() - t0 < limit:
        try:
            value = predicate()
        except (StaleElementReferenceException, NoSuchElementException):  # the page re-rendered it
            value = None
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out after {limit} s: {what}")


def test_opens_humvvex(session):
    driver, _, _, _, timings = session
    assert _input(driver, "general.name").get_attribute("value") == "humvvex"
    assert _input(driver, "general.start").get_attribute("value") == "2018-10-24T14:05:00"
    assert timings["page_usable_s"] < 60


def test_invalid_value_shows_the_message_then_fix_and_save(session):
    driver, _, scenario, _, _ = session
    original = scenario.read_text()
    H.open_tab(driver, "sensor")
    _type(driver, "sensor[1].netd_k", "9")
    message = "sensor[1].netd_k = 9: allowed range 0.0..5.0"
    _wait(lambda: message in _field_messages(driver, "sensor[1].netd_k"), what=message)

    def status():
        return driver.find_element("css selector", '[data-testid="status"]').text

    _wait(lambda: status().startswith("1 problem"), what="1 problem")
    _click(driver, "save")
    _wait(lambda: "not saved" in driver.page_source, what="the refusal")
    assert scenario.read_text() == original  # a valid file is not replaced by an invalid one
    _type(driver, "sensor[1].netd_k", "0.04")
    _wait(lambda: _field_messages(driver, "sensor[1].netd_k") in ("", "0.0..5.0"), what="message gone")
    _wait(lambda: status().startswith("valid"), what="valid")
    _click(driver, "save")
    expected = original.replace(
        "position_m = [0.8, -15.0, 1.6]\nlook_at_m = [0.0, 0.0, 1.2]\n",
        "position_m = [0.8, -15.0, 1.6]\nlook_at_m = [0.0, 0.0, 1.2]\nnetd_k = 0.04\n",
    )
    assert expected != original
    _wait(lambda: scenario.read_text() == expected, what="the saved file")


def test_plan_shows_every_sensor(session):
    from humv_usd.scenario import load_scenario

    driver, _, scenario, _, _ = session
    H.open_tab(driver, "plan")
    shown = [
        g.get_attribute("data-id") for g in driver.find_elements("css selector", "svg.humv-plan g.sensor")
    ]
    assert shown == [s["id"] for s in load_scenario(scenario)["sensor"]]
    assert driver.find_elements("css selector", "svg.humv-plan g.north")
    assert driver.find_elements("css selector", "svg.humv-plan g.sun")
    assert [
        g.get_attribute("data-id") for g in driver.find_elements("css selector", "svg.humv-plan g.person")
    ] == ["p1"]


def test_preview_image_appears_after_the_page_reconnects(session):
    """Start a preview, reload the page (the job keeps running in the server), see the image."""
    driver, url, _, out, timings = session
    H.open_tab(driver, "preview")
    t0 = time.perf_counter()
    _click(driver, "preview")
    _wait(lambda: (out / ".editor").exists() or "preview" in driver.page_source, what="job started")
    driver.get(url)  # the page closes and opens again
    _wait(lambda: driver.find_elements("css selector", '[data-testid="tab-preview"]'), what="page again")
    H.open_tab(driver, "preview")

    def image_shown():
        imgs = driver.find_elements("css selector", '[data-testid="preview-image"] img')
        return any(
            "preview_colour.png" in (i.get_attribute("src") or "")
            and driver.execute_script("return arguments[0].complete && arguments[0].naturalWidth", i)
            for i in imgs
        )

    _wait(image_shown, limit=240, what="the preview image")
    timings["preview_click_to_image_s"] = time.perf_counter() - t0
    manifest = json.loads((out / "preview" / "manifest.json").read_text())
    lo, hi = manifest["sensors"][0]["frames"][0]["preview_levels_k"]
    assert driver.find_element("css selector", '[data-testid="bar-high"]').text == f"{hi:.1f} K"
    assert driver.find_element("css selector", '[data-testid="bar-low"]').text == f"{lo:.1f} K"
    # the fast preview (the default) says so, and composed its own copy, not the real layers
    mark = driver.find_element("css selector", '[data-testid="preview-mark"]').text
    assert mark.startswith("FAST PREVIEW") and "thermal.radiation_rays 8 (scenario: " in mark
    assert (out / ".editor" / "preview" / "stage.usda").is_file() and not (out / "stage.usda").exists()
    H.open_tab(driver, "run")
    assert "preview: done" in driver.find_element("css selector", '[data-testid="job-state"]').text
    # a second preview: the layers are cached
    H.open_tab(driver, "preview")
    before = driver.find_element("css selector", '[data-testid="preview-image"] img').get_attribute("src")
    t1 = time.perf_counter()
    _click(driver, "preview")

    def new_image():
        img = driver.find_element("css selector", '[data-testid="preview-image"] img')
        src = img.get_attribute("src")
        return src != before and driver.execute_script(
            "return arguments[0].complete && arguments[0].naturalWidth", img
        )

    _wait(new_image, limit=240, what="second preview")
    timings["preview_cached_s"] = time.perf_counter() - t1


def _status(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as exc:
        return exc.code
    except urllib.error.URLError:  # not listening (yet)
        return 0


def test_files_are_served_only_from_the_two_folders(session):
    _, url, scenario, _, _ = session
    assert _status(url + "files/scenario/humvvex.toml") == 200
    for bad in (
        "files/scenario/%2e%2e/%2e%2e/etc/passwd",
        "files/out/..%2f..%2fhumvvex.toml",
        "files/scenario/%2fetc%2fpasswd",
    ):
        assert _status(url + bad) in (403, 404), bad


def test_other_interfaces_need_the_token(tmp_path):
    scenario = tmp_path / "humvvex.toml"
    shutil.copy(EXAMPLE, scenario)
    with H.editor_server(scenario, tmp_path / "out", extra=("--host", "127.0.0.2"), check_url=False) as (
        _,
        _,
        proc,
    ):
        first = proc.stdout.readline()
        assert "?token=" in first
        address = first.split("-> ", 1)[1].strip()
        base = address.split("?", 1)[0]
        _wait(lambda: _status(address) == 200, limit=60, what="server on 127.0.0.2")
        assert _status(base) == 403
        assert _status(base + "files/scenario/humvvex.toml") == 403
        assert _status(base + "?token=wrong") == 403


def test_three_d_view_shows_the_composed_stage(session):
    """After the preview composed the stage: the 3D tab loads its meshes and cameras."""
    from selenium.webdriver.common.by import By

    driver, _, _, out, _ = session
    H.open_tab(driver, "view3d")
    _click(driver, "show-3d")
    _wait(lambda: "4 cameras" in driver.page_source, limit=240, what="the 3D view")
    assert (out / ".editor" / "stage.glb").stat().st_size > 10_000
    assert driver.find_elements(By.CSS_SELECTOR, '[data-testid="scene3d"] canvas')


def test_sweep_tab_checks_every_variant(session):

    driver, _, scenario, _, _ = session
    H.open_tab(driver, "sweep")
    _click(driver, "sweep-save")
    _wait(lambda: "2 variant(s), every one valid" in driver.page_source, limit=60, what="sweep check")
    assert 'base = "humvvex.toml"' in (scenario.parent / "sweep.toml").read_text()


def test_sensor_tab_marks_preset_values_and_the_users(session):
    """Issue 26 (7): preset values were blank fields. A key the table leaves out shows the
    preset's value (grey, as the placeholder) and says so; a key the table gives says it is
    the user's, with the preset's value beside it."""
    driver = session[0]
    H.open_tab(driver, "sensor")
    _wait(
        lambda: _input(driver, "sensor[0].resolution").get_attribute("placeholder") == "[1024, 768]",
        what="the preset's resolution as the placeholder",
    )
    assert _input(driver, "sensor[0].resolution").get_attribute("value") == ""  # not written into the file
    # the hints render after the placeholder (a CI run read the resolution's while still empty)
    _wait(
        lambda: "from preset atom1024_lwir" in _field_messages(driver, "sensor[0].resolution"),
        what="the resolution's hint: from preset atom1024_lwir",
    )
    _wait(
        lambda: "your value (preset atom1024_lwir: 14)" in _field_messages(driver, "sensor[0].bit_depth"),
        what="the bit depth's hint: your value (preset atom1024_lwir: 14)",
    )
