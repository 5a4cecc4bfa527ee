"""`stylerf view` in a real browser: headless Chromium (Selenium) drives the page the server embeds, against
the tiny trained scene of the `stages` fixture.

The page is used as a person would: it loads and shows a frame, a drag turns the camera, an uploaded image
becomes the style, a second style is mixed in with the slider; each step must change the canvas. Last, the
refined (full-size) frame on the canvas must equal what `stylerf stylize --camera-path` renders for the same
camera, exported by the server's /api/camera_path. Stopping the server with SIGINT must exit 0.

Needs Debian's chromium, chromium-driver and python3-selenium; skipped without them. Screenshots of each
step are kept under pytest's tmp_path, and also in the folder STYLERF_VIEW_SCREENSHOTS names, if set.
"""
import base64
import json
import os
import re
import shutil
import signal
import subprocess
import threading
import urllib.request
from typing import Any, Dict, List, Optional

import numpy as np
import pytest

import stylerf
from conftest import cli_path

CHROMEDRIVER = "/usr/bin/chromedriver"
WAIT_S = 120  # a frame on a 2-core CPU is well under a second at 32 px; the margin is for a loaded machine

try:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select, WebDriverWait
    SELENIUM_MISSING = ""
except ImportError as e:  # the browser tests are optional: the rest of the suite runs without them
    SELENIUM_MISSING = f"python3-selenium is not installed ({e})"


def browser_missing() -> str:
    """Why the browser cannot run here, or "" when it can."""
    if SELENIUM_MISSING:
        return SELENIUM_MISSING
    if not (shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")):
        return "no Chromium browser on PATH (apt-get install chromium)"
    if not os.access(CHROMEDRIVER, os.X_OK):
        return f"no {CHROMEDRIVER} (apt-get install chromium-driver)"
    return ""


class ViewServer:
    """`stylerf view` as a subprocess: its URL, once it listens, and everything it printed."""

    URL = re.compile(r"http://127\.0\.0\.1:\d+/\S*")

    def __init__(self, ckpt: str, styles: str):
        self.lines: List[str] = []
        self.url: Optional[str] = None
        self._listening = threading.Event()
        self.proc = subprocess.Popen([cli_path(), "view", "--ckpt", ckpt, "--styles", styles, "--port", "0"],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        # Read the output continuously: a full pipe would block the server.
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
            m = self.URL.search(line)
            if m and self.url is None:
                self.url = m.group(0)
                self._listening.set()
        self._listening.set()  # it exited: stop waiting

    def wait_listening(self, timeout: float) -> str:
        self._listening.wait(timeout)
        assert self.url, f"stylerf view printed no URL within {timeout:.0f} s:\n{self.output()}"
        return self.url

    def output(self) -> str:
        return "\n".join(self.lines[-60:])

    def api(self, path: str, body: Dict[str, Any]) -> bytes:
        """POST a JSON body to the server; the answer's bytes."""
        req = urllib.request.Request(self.url.split("?")[0].rstrip("/") + path, data=json.dumps(body).encode(),
                                     headers={"Content-Type": "application/json"}, method="POST")
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.read()

    def stop(self) -> int:
        """SIGINT, as Ctrl-C sends; the exit code (the process is killed if it has not exited in 10 s)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
                raise AssertionError(f"stylerf view did not exit within 10 s of SIGINT:\n{self.output()}")
        self._reader.join(5)
        return self.proc.returncode


# Checked before any fixture runs, so that a machine without the browser does not train the scene for nothing.
pytestmark = pytest.mark.skipif(bool(browser_missing()), reason=browser_missing() or "the browser is here")


@pytest.fixture(scope="module")
def server(stages):
    """The server on the trained scene; at the end SIGINT must stop it within 10 s with exit code 0."""
    srv = ViewServer(stages.style, stages.styles)
    try:
        srv.wait_listening(120)
        yield srv
    finally:
        code = srv.stop()
        assert code == 0, f"stylerf view exited {code} on SIGINT:\n{srv.output()}"


@pytest.fixture(scope="module")
def driver(server):
    """Headless Chromium through Debian's chromedriver."""
    opts = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1200,900"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})  # the page's console, for failure messages
    drv = webdriver.Chrome(service=Service(executable_path=CHROMEDRIVER), options=opts)
    try:
        yield drv
    finally:
        drv.quit()


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    """save(name): a screenshot of the page, kept under tmp_path and in $STYLERF_VIEW_SCREENSHOTS."""
    folders = [str(tmp_path_factory.mktemp("view_screenshots"))]
    if os.environ.get("STYLERF_VIEW_SCREENSHOTS"):
        folders.append(os.environ["STYLERF_VIEW_SCREENSHOTS"])
        os.makedirs(folders[-1], exist_ok=True)

    def save(drv, name: str) -> None:
        for folder in folders:
            assert drv.save_screenshot(os.path.join(folder, name + ".png"))
    return save


@pytest.fixture(scope="module")
def page(server, driver, shots):
    """The page, loaded, with its first full frame on the canvas."""
    driver.get(server.url)
    wait_full_frame(driver, server, 0)
    shots(driver, "a_loaded")
    return driver


# ---- reading the page --------------------------------------------------------------------------------------

# The newest frame on the canvas if it is a full frame of what the controls show now, numbered at least
# arguments[0]; else null. The state is compared so that a full frame of an older camera or style is not taken
# for the answer to the newest change.
LATEST_FULL_JS = """
const f = window.stylerfStats.frames, s = window.stylerfState;
if (f.length <= arguments[0]) return null;
const last = f[f.length - 1];
if (last.kind !== 'full' || last.style !== s.style || last.styleB !== s.styleB) return null;
for (const k of ['view', 'yaw', 'pitch', 'zoom']) if (last.camera[k] !== s.camera[k]) return null;
if (s.styleB && !s.region.on && last.mix !== s.mix) return null;
return Object.assign({index: f.length - 1}, last);
"""

# The canvas's RGBA bytes, base64 (a long array would travel as JSON numbers, one by one).
CANVAS_JS = """
const c = document.getElementById('view');
const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
let s = '';
for (let i = 0; i < d.length; i += 0x8000) s += String.fromCharCode.apply(null, d.subarray(i, i + 0x8000));
return [c.width, c.height, btoa(s)];
"""


def page_report(drv, server: ViewServer) -> str:
    """What the page and the server said, for a failure message."""
    try:
        logs = "\n".join(e.get("message", "") for e in drv.get_log("browser"))
    except Exception:  # noqa: BLE001 - a log that cannot be read must not hide the failure itself
        logs = "(no browser log)"
    ui = drv.execute_script("return [document.getElementById('status').textContent,"
                            " document.getElementById('error').textContent, window.stylerfStats.frames.length]")
    return (f"status: {ui[0]!r}\nerror: {ui[1]!r}\nframes shown: {ui[2]}\nbrowser console:\n{logs}\n"
            f"server output:\n{server.output()}")


def frame_count(drv) -> int:
    return drv.execute_script("return window.stylerfStats.frames.length")


def wait_full_frame(drv, server: ViewServer, after: int) -> Dict[str, Any]:
    """Wait for a full frame of the current state, shown as frame number `after` or later."""
    try:
        return WebDriverWait(drv, WAIT_S, poll_frequency=0.1).until(
            lambda d: d.execute_script(LATEST_FULL_JS, after))
    except Exception as e:
        raise AssertionError(f"no full frame after frame {after}: {e}\n{page_report(drv, server)}") from None


def canvas_pixels(drv) -> np.ndarray:
    w, h, data = drv.execute_script(CANVAS_JS)
    return np.frombuffer(base64.b64decode(data), np.uint8).reshape(h, w, 4)


def assert_changed(before: np.ndarray, after: np.ndarray, what: str) -> None:
    """At least 1% of the pixels moved by more than 2 levels in some channel."""
    moved = (np.abs(before.astype(int) - after.astype(int))[..., :3] > 2).any(axis=-1).mean()
    assert moved > 0.01, f"{what}: the canvas did not change ({moved:.2%} of the pixels moved)"


def server_styles(server: ViewServer) -> List[Dict[str, str]]:
    with urllib.request.urlopen(server.url.split("?")[0].rstrip("/") + "/api/styles", timeout=30) as r:
        return json.load(r)


def set_range(drv, element_id: str, value: int) -> None:
    """Move a range input as a person would: the value changes, then 'input' and 'change' fire."""
    drv.execute_script("const e = document.getElementById(arguments[0]); e.value = arguments[1];"
                       " e.dispatchEvent(new Event('input', {bubbles: true}));"
                       " e.dispatchEvent(new Event('change', {bubbles: true}));", element_id, str(value))


def stem(path: str) -> str:
    return os.path.splitext(os.path.basename(path))[0]


# ---- the steps, in order on one page -----------------------------------------------------------------------

def test_first_frame(page, server):
    info = page.execute_script("return window.stylerfStats")
    frames = info["frames"]
    assert info["infoAt"] is not None and frames[0]["kind"] == "preview", frames[:2]
    full = wait_full_frame(page, server, 0)
    w, h = page.execute_script("const c = document.getElementById('view'); return [c.width, c.height]")
    assert (full["width"], full["height"]) == (w, h)
    px = canvas_pixels(page)
    assert px[..., :3].std() > 1, "the first full frame is a flat colour"
    assert page.find_element(By.ID, "error").text == ""
    assert "full" in page.find_element(By.ID, "status").text


def test_drag_turns_the_camera(page, server, shots):
    before, n = canvas_pixels(page), frame_count(page)
    canvas = page.find_element(By.ID, "view")
    chain = ActionChains(page).move_to_element(canvas).click_and_hold()
    for _ in range(6):  # small steps, as a hand moves: each is a pointermove
        chain.move_by_offset(10, 2).pause(0.03)
    chain.release().perform()
    full = wait_full_frame(page, server, n)
    cam = full["camera"]
    assert cam["yaw"] != 0 and cam["pitch"] != 0, cam
    assert_changed(before, canvas_pixels(page), "drag")
    shots(page, "b_dragged")


def test_upload_becomes_style_a(page, server, stages, shots):
    names = {s["id"]: stem(s["name"]) for s in server_styles(server)}
    current = page.execute_script("return window.stylerfState.style")
    # An image unlike the one on screen (the holdout style is one of the folder's images too).
    image = next(p for p in stages.style_images if stem(p) != names[current])
    before, n = canvas_pixels(page), frame_count(page)
    page.find_element(By.ID, "upload").send_keys(os.path.abspath(image))
    WebDriverWait(page, WAIT_S).until(lambda d: d.execute_script(
        "return window.stylerfState.style !== arguments[0]", current))
    full = wait_full_frame(page, server, n)
    uploaded = [s for s in server_styles(server) if s["source"] == "upload"]
    assert uploaded and full["style"] == uploaded[-1]["id"], (full, uploaded)
    assert page.find_element(By.CSS_SELECTOR, f".thumb.a[data-id='{full['style']}']")
    assert_changed(before, canvas_pixels(page), "upload")
    shots(page, "c_uploaded")


def test_mix_with_style_b(page, server, shots):
    a = page.execute_script("return window.stylerfState.style")
    styles = server_styles(server)
    # A style B of another image: the upload on screen may be a copy of a folder image under another id.
    a_name = stem(next(s["name"] for s in styles if s["id"] == a))
    b = next(s["id"] for s in styles if s["source"] != "upload" and stem(s["name"]) != a_name)
    Select(page.find_element(By.ID, "style-b")).select_by_value(b)
    before, n = canvas_pixels(page), frame_count(page)
    set_range(page, "mix", 50)
    full = wait_full_frame(page, server, n)
    assert full["styleB"] == b and abs(full["mix"] - 0.5) < 1e-9, full
    assert page.find_element(By.CSS_SELECTOR, f".thumb.b[data-id='{b}']")
    assert_changed(before, canvas_pixels(page), "mix")
    shots(page, "d_mixed")


def test_refined_frame_equals_stylize(page, server, stages, tmp_path, shots):
    # Style A: a folder style, whose image file is known (the server names folder styles by file stem).
    paths = {stem(p): p for p in stages.style_images}
    style = next(s for s in server_styles(server) if s["source"] == "folder" and s["name"] in paths)
    Select(page.find_element(By.ID, "style-b")).select_by_value("")
    set_range(page, "mix", 0)
    n = frame_count(page)
    Select(page.find_element(By.ID, "style-a")).select_by_value(style["id"])
    full = wait_full_frame(page, server, n)
    assert full["style"] == style["id"] and full["styleB"] is None, full
    canvas = canvas_pixels(page)[..., :3].astype(np.float64)
    shots(page, "e_refined")

    side = max(full["width"], full["height"])
    path_file = tmp_path / "camera_path.json"
    path_file.write_bytes(server.api("/api/camera_path", {"camera": full["camera"], "side": side}))
    out = tmp_path / "stylize"
    r = subprocess.run([cli_path(), "stylize", "--ckpt", stages.style, "--style", paths[style["name"]],
                        "--camera-path", str(path_file), "--cache", "none", "--no-losses", "-o", str(out)],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert r.returncode == 0, r.stdout
    ref = np.round(stylerf.load_image(str(out / "frame_0000.png"))[..., :3].astype(np.float64) * 255)
    assert ref.shape == canvas.shape, (ref.shape, canvas.shape)
    diff = np.abs(ref - canvas).mean()
    assert diff <= 2.0, f"the viewer's full frame differs from stylize's by {diff / 255:.4f} on average"
