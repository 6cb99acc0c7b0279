"""`uwnr serve` in a real browser: Debian's chromium and chromedriver driven by selenium, headless.

Starts the server on the bundled samples (a free port), selects a reference, waits for the six
methods' renders, changes an option and sees its render change, runs the `uwnr render` command
the page shows and checks that it writes the pixels of the page's full-resolution download, and
saves a screenshot (to $UWNR_SCREENSHOT when set: that is how docs/images/serve.png is made).
Skips, saying why, without selenium, chromium, chromedriver or the uwnr binary."""

import io
import json
import os
import shlex
import shutil
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

webdriver = pytest.importorskip(
    "selenium.webdriver", reason="selenium is not installed (pip install selenium)"
)
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.support.ui import Select, WebDriverWait  # noqa: E402

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
# Generous: renders in a debug build on a shared 2-core machine. Not a timing assertion.
WAIT_S = 300
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    # A 1400x1000 page: headless chromium's window includes 143 pixels of browser frame.
    "--window-size=1400,1143",
]


@pytest.fixture
def folders(tmp_path, samples):
    """clean/ in an RGB-D layout (rgb/ photos, depth/ with the room's measured map), refs/."""
    rgb = tmp_path / "clean" / "rgb"
    depth = tmp_path / "clean" / "depth"
    refs = tmp_path / "refs"
    for d in (rgb, depth, refs):
        d.mkdir(parents=True)
    shutil.copy(samples / "clean-room.jpg", rgb / "clean-room.jpg")
    shutil.copy(samples / "clean-statues.jpg", rgb / "clean-statues.jpg")
    shutil.copy(samples / "clean-room-depth.png", depth / "clean-room.png")
    shutil.copy(samples / "ref-blue.jpg", refs / "ref-blue.jpg")
    shutil.copy(samples / "ref-green.png", refs / "ref-green.png")
    return tmp_path / "clean", refs


def start_server(cli, folders, *extra):
    clean, refs = folders
    # Relative folders, as a user types them: the page's commands then name them so (and the
    # screenshot shows no temporary paths); the commands run in the same folder.
    return subprocess.Popen(
        [str(cli), "serve", "--clean", clean.name, "--references", refs.name, "--port", "0",
         *(() if "--preview-size" in extra else ("--preview-size", "256")), *extra],
        cwd=clean.parent,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )


@pytest.fixture
def server(cli, folders):
    proc = start_server(cli, folders)
    try:
        line = proc.stdout.readline().strip()
        assert line.startswith("serving on http://127.0.0.1:"), line
        yield line.removeprefix("serving on ")
    finally:
        proc.kill()
        proc.wait()


@pytest.fixture
def one_worker_server(cli, folders):
    """One render thread and larger previews: a tab's renders are still queued when another
    tab asks for the same cells."""
    proc = start_server(cli, folders, "--workers", "1", "--preview-size", "640")
    try:
        yield proc.stdout.readline().strip().removeprefix("serving on ")
    finally:
        proc.kill()
        proc.wait()


@pytest.fixture
def exposed_server(cli, folders):
    """Listening on every address: the printed address carries the run's token, and is one a
    browser on this machine can open (loopback, not 0.0.0.0)."""
    proc = start_server(cli, folders, "--host", "0.0.0.0")
    try:
        line = proc.stdout.readline().strip()
        assert line.startswith("serving on http://127.0.0.1:") and "/?token=" in line, line
        yield line.removeprefix("serving on ")
    finally:
        proc.kill()
        proc.wait()


@pytest.fixture
def browser(tmp_path):
    if not CHROMIUM.exists() or not CHROMEDRIVER.exists():
        pytest.skip("needs Debian's chromium and chromium-driver (/usr/bin/chromium, /usr/bin/chromedriver)")
    # Selenium must never fetch a browser or driver of its own.
    os.environ["SE_OFFLINE"] = "true"
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    profile = tmp_path / "chromium-profile"
    profile.mkdir()
    options.add_argument(f"--user-data-dir={profile}")
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()


def get(url):
    with urllib.request.urlopen(url, timeout=60) as r:
        return r.read()


def post_json(url, body):
    req = urllib.request.Request(
        url, data=json.dumps(body).encode(), headers={"Content-Type": "application/json"}
    )
    with urllib.request.urlopen(req, timeout=60) as r:
        return json.loads(r.read())


def pixels(png):
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def full_resolution(base, request):
    """What the page's full-resolution button does: the cell's request at full size, polled."""
    request = dict(request, size="full", view=request["view"] + "|full")
    job = post_json(base + "api/render", request)["job"]
    while True:
        status = json.loads(get(f"{base}api/job/{job}"))
        if status["state"] not in ("queued", "running"):
            break
        time.sleep(0.1)
    assert status["state"] == "done", status
    return get(f"{base}api/job/{job}/image")


def cells(driver, row=0):
    return driver.find_elements(By.CSS_SELECTOR, f".cell[data-row='{row}']")


def all_done(driver, row=0):
    cs = cells(driver, row)
    states = [c.get_attribute("data-state") for c in cs]
    failed = [c.text for c in cs if c.get_attribute("data-state") == "failed"]
    assert not failed, failed
    return len(cs) == 6 and all(s == "done" for s in states)


def cell(driver, method, row=0):
    return driver.find_element(By.CSS_SELECTOR, f".cell[data-row='{row}'][data-method='{method}']")


def check_command_reproduces(driver, base, cli, method, tmp_path):
    """Focus the cell, read the shown `uwnr render` command, run it, compare with the download."""
    cell(driver, method).find_element(By.CSS_SELECTOR, ".cmdbtn").click()
    shown = driver.find_element(By.ID, "render-cmd")
    command = shown.text
    request = json.loads(shown.get_attribute("data-request"))
    assert request["options"]["method"] == method
    words = shlex.split(command)
    assert words[:2] == ["uwnr", "render"], command
    assert words[-2] == "--output"
    run = subprocess.run([str(cli), *words[1:]], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    written = (tmp_path / words[-1]).read_bytes()
    downloaded = full_resolution(base, request)
    np.testing.assert_array_equal(pixels(written), pixels(downloaded))
    assert written == downloaded, "the same PNG bytes"
    return command


def test_the_page_compares_methods_and_its_commands_reproduce_them(server, browser, cli, tmp_path):
    base = server
    browser.get(base)
    wait = WebDriverWait(browser, WAIT_S)
    wait.until(lambda d: len(d.find_elements(By.CSS_SELECTOR, "#ref-grid .ref img")) == 2)
    # The room photo with its measured depth from depth/ beside it.
    Select(browser.find_element(By.ID, "depth-select")).select_by_value("beside")
    wait.until(lambda d: d.find_element(By.ID, "depth-img").get_attribute("src"))

    # Select a reference: all six methods render.
    browser.find_elements(By.CSS_SELECTOR, "#ref-grid .ref")[0].click()
    wait.until(all_done)

    # Change an option: the render changes.
    before_job = cell(browser, "jerlov").get_attribute("data-job")
    before = get(f"{base}api/job/{before_job}/image")
    water = browser.find_element(By.CSS_SELECTOR, "select[data-method='jerlov'][data-key='water_type']")
    Select(water).select_by_value("9C")
    wait.until(lambda d: cell(d, "jerlov").get_attribute("data-job") != before_job and all_done(d))
    after = get(f"{base}api/job/{cell(browser, 'jerlov').get_attribute('data-job')}/image")
    assert pixels(before).shape == pixels(after).shape
    assert not np.array_equal(pixels(before), pixels(after)), "water type 9C changed nothing"

    # The shown commands render what the page's full-resolution download gives.
    uwnr_cmd = check_command_reproduces(browser, base, cli, "uwnr", tmp_path)
    assert "--reference" in uwnr_cmd and "--depth" in uwnr_cmd, uwnr_cmd
    jerlov_cmd = check_command_reproduces(browser, base, cli, "jerlov", tmp_path)
    assert "--water-type 9C" in jerlov_cmd, jerlov_cmd
    dataset_cmd = browser.find_element(By.ID, "dataset-cmd").text
    assert dataset_cmd.startswith("uwnr dataset --clean "), dataset_cmd

    # Both references, drawn as the dataset would (K=2), then the screenshot.
    browser.find_element(By.ID, "draw").click()
    wait.until(lambda d: len(d.find_elements(By.CSS_SELECTOR, "#ref-grid .ref.selected")) == 2)
    wait.until(lambda d: all_done(d, 0) and all_done(d, 1))
    cell(browser, "uwnr").click()
    # The before/after slider at 70 %: the clean photo shows on the right of each render.
    browser.execute_script(
        "const s = document.getElementById('split'); s.value = 70;"
        " s.dispatchEvent(new Event('input'));"
    )
    time.sleep(1.2)  # one status poll, so the header shows the idle queue
    shot = Path(os.environ.get("UWNR_SCREENSHOT") or tmp_path / "serve.png")
    assert browser.save_screenshot(str(shot))
    assert Image.open(shot).size[0] >= 1000


def references_listed(driver):
    return len(driver.find_elements(By.CSS_SELECTOR, "#ref-grid .ref img")) == 2


def test_two_tabs_of_the_page_do_not_cancel_each_other(one_worker_server, browser):
    """Each page instance names its own views: the same cell rendered in two tabs finishes in
    both (with one name for both, the second tab's requests made the first's stale, and the first
    waited forever)."""
    server = one_worker_server
    wait = WebDriverWait(browser, WAIT_S)
    browser.get(server)
    first = browser.current_window_handle
    wait.until(references_listed)
    browser.switch_to.new_window("tab")
    browser.get(server)
    second = browser.current_window_handle
    wait.until(references_listed)
    for handle in (first, second):
        browser.switch_to.window(handle)
        browser.find_elements(By.CSS_SELECTOR, "#ref-grid .ref")[0].click()
    for handle in (second, first):
        browser.switch_to.window(handle)
        wait.until(all_done)


def test_beyond_loopback_the_page_works_through_its_tokened_address_only(exposed_server, browser):
    wait = WebDriverWait(browser, WAIT_S)
    base, token = exposed_server.split("?token=")
    with pytest.raises(urllib.error.HTTPError) as refused:
        get(base + "api/info")
    assert refused.value.code == 403
    assert json.loads(get(f"{base}api/info?token={token}"))
    # The printed address: the page loads, carries the token on each of its API calls, which
    # work, and never keeps it as a cookie (a browser would send that to every port of the host).
    browser.get(exposed_server)
    wait.until(references_listed)
    browser.find_elements(By.CSS_SELECTOR, "#ref-grid .ref")[0].click()
    wait.until(all_done)
    assert browser.get_cookies() == [], browser.get_cookies()
