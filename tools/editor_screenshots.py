"""Screenshots of every tab of the HumV editor on a copy of examples/humvvex.toml
(``make screenshots`` -> docs/editor/<tab>.png).

Starts ``humv-usd edit`` on a free port, drives the page with selenium on Debian's headless
chromium (/usr/bin/chromium, /usr/bin/chromedriver), runs a preview and the 3D view, and stops
the server. Usage: python tools/editor_screenshots.py [OUT_DIR]
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TABS = [
    "general",
    "human",
    "placement",
    "scene",
    "sensor",
    "thermal",
    "atmosphere",
    "annotations",
    "sweep",
    "plan",
    "view3d",
    "preview",
    "run",
]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def editor_server(scenario: Path, out_dir: Path, extra=(), check_url: bool = True):
    """``humv-usd edit`` in a child process; yields (url, seconds until the page answered, the
    process); ``check_url=False`` yields at once (the caller reads the address it prints)."""
    port = free_port()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    env.pop("PYTEST_CURRENT_TEST", None)  # NiceGUI would take the server for its own test harness
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "humv_usd.cli.main",
            "edit",
            str(scenario),
            "-o",
            str(out_dir),
            "--port",
            str(port),
            *extra,
        ],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    url = f"http://127.0.0.1:{port}/"
    try:
        while check_url:
            if proc.poll() is not None:
                raise RuntimeError("humv-usd edit stopped:\n" + proc.stdout.read())
            try:
                with urllib.request.urlopen(url, timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                time.sleep(0.1)
            if time.perf_counter() - t0 > 60:
                raise RuntimeError("humv-usd edit did not answer in 60 s")
        yield url, time.perf_counter() - t0, proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, 15)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, 9)
            proc.wait()


def chromium(width: int = 1400, height: int = 1000):
    from selenium import webdriver

    opts = webdriver.ChromeOptions()
    opts.binary_location = "/usr/bin/chromium"
    for arg in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        f"--window-size={width},{height}",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--ignore-gpu-blocklist",
    ):
        opts.add_argument(arg)
    return webdriver.Chrome(options=opts, service=webdriver.ChromeService("/usr/bin/chromedriver"))


def open_tab(driver, name: str) -> None:
    from selenium.webdriver.common.by import By

    driver.execute_script("window.scrollTo(0, 0)")
    driver.find_element(By.CSS_SELECTOR, f'[data-testid="tab-{name}"]').click()
    time.sleep(0.4)


def main(out: Path) -> None:
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support import expected_conditions as ec
    from selenium.webdriver.support.ui import WebDriverWait

    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        scenario = Path(tmp) / "humvvex.toml"
        shutil.copy(ROOT / "examples" / "humvvex.toml", scenario)
        with editor_server(scenario, Path(tmp) / "out") as (url, seconds, _):
            print(f"page answered {seconds:.1f} s after humv-usd edit")
            driver = chromium()
            try:
                driver.get(url)
                WebDriverWait(driver, 30).until(
                    ec.presence_of_element_located((By.CSS_SELECTOR, '[data-testid="tab-run"]'))
                )
                for name in TABS:
                    open_tab(driver, name)
                    if name == "preview":
                        driver.find_element(By.CSS_SELECTOR, '[data-testid="preview"]').click()
                        WebDriverWait(driver, 180).until(
                            lambda d: d.find_elements(By.CSS_SELECTOR, '[data-testid="bar-high"]')
                        )
                        time.sleep(1.0)
                    if name == "view3d":
                        driver.find_element(By.CSS_SELECTOR, '[data-testid="show-3d"]').click()
                        WebDriverWait(driver, 180).until(lambda d: "triangles" in d.page_source)
                        time.sleep(3.0)
                    driver.save_screenshot(str(out / f"{name}.png"))
                    print(out / f"{name}.png")
            finally:
                driver.quit()


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "editor")
