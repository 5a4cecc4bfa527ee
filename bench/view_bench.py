#!/usr/bin/env python3
"""How `stylerf view` feels in a browser: the real page in headless Chromium against a trained checkpoint,
timed by the page's own clock (window.stylerfStats: when each frame was asked for and when it reached the
canvas).

    python3 bench/view_bench.py --stylerf build/stylerf --ckpt OUT/style.ckpt --styles STYLES \\
        --style-image new_style.jpg [--minutes 10] -o BENCH_OUT

Measures, each printed beside its target:
  1. the first preview after the page loads;
  2. preview frames a second while the camera is dragged continuously (20 s at about 30 pointer moves a second);
  3. a new style image uploaded (as a drop does) to its first preview frame;
  4. the refined full frame at a new camera (content not cached) against `stylerf stylize --camera-path` of the
     same camera, per frame;
  5. the server's peak memory over --minutes of dragging against stylize's, and whether it stayed steady.

Writes OUT/view_bench.json and screenshots beside it. Needs chromium, chromium-driver and python3-selenium.
"""
import argparse
import json
import math
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request
from typing import Any, Dict, List, Optional

from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

MOVE_MS = 33          # one pointer move a frame of a 30 Hz hand
FPS_DRAG_S = 20       # the drag that counts preview frames
SAMPLE_EVERY_S = 30   # the server's memory is read this often during the long drag

TARGETS = {"first_preview_ms": 1500, "preview_fps": 2.0, "drop_to_preview_ms": 2000, "refined_ratio": 1.10,
           "rss_over_stylize_mb": 500}

T0 = time.monotonic()


def progress(msg: str) -> None:
    print(f"[{time.monotonic() - T0:7.1f} s] {msg}", flush=True)


class Server:
    """`stylerf view` as a subprocess; its URL once it listens, its memory from /proc."""

    def __init__(self, tool: str, ckpt: str, styles: str, extra: List[str]):
        self.lines: List[str] = []
        self.url: Optional[str] = None
        ready = threading.Event()
        self.proc = subprocess.Popen([tool, "view", "--ckpt", ckpt, "--styles", styles, "--port", "0", *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)

        def read() -> None:  # drained all the time: a full pipe would stall the server
            for line in self.proc.stdout:
                self.lines.append(line.rstrip("\n"))
                m = re.search(r"http://127\.0\.0\.1:\d+/\S*", line)
                if m and self.url is None:
                    self.url = m.group(0)
                    ready.set()
            ready.set()

        threading.Thread(target=read, daemon=True).start()
        ready.wait(600)
        if not self.url:
            self.proc.kill()
            sys.exit("stylerf view did not start:\n" + "\n".join(self.lines[-40:]))

    def memory_mb(self) -> Dict[str, float]:
        """VmRSS (now) and VmHWM (the peak so far) of the server process, in MB."""
        out = {}
        with open(f"/proc/{self.proc.pid}/status") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key in ("VmRSS", "VmHWM"):
                    out[key] = int(value.split()[0]) / 1024.0  # kB
        return out

    def get_json(self, path: str) -> Any:
        with urllib.request.urlopen(self.url.split("?")[0].rstrip("/") + path, timeout=60) as r:
            return json.load(r)

    def post(self, path: str, body: Dict[str, Any], headers: Optional[Dict[str, str]] = None) -> bytes:
        req = urllib.request.Request(self.url.split("?")[0].rstrip("/") + path, data=json.dumps(body).encode(),
                                     headers={"Content-Type": "application/json"}, method="POST")
        try:
            with urllib.request.urlopen(req, timeout=600) as r:
                if headers is not None:
                    headers.update({k.lower(): v for k, v in r.getheaders()})
                return r.read()
        except urllib.error.HTTPError as e:  # the server's {"error"} says what was wrong
            sys.exit(f"POST {path} {json.dumps(body)}: {e.code} {e.read().decode(errors='replace')}")

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()


def start_browser(chromedriver: str) -> webdriver.Chrome:
    opts = webdriver.ChromeOptions()
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1200,900"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(executable_path=chromedriver), options=opts)


def stats(drv) -> Dict[str, Any]:
    return drv.execute_script("return window.stylerfStats")


def now_ms(drv) -> float:
    """The page's clock (performance.now()), the one its frame timestamps use."""
    return drv.execute_script("return performance.now()")


def wait_frames(drv, test, timeout: float = 600) -> Dict[str, Any]:
    """The first frame (from window.stylerfStats.frames) for which test(frame) holds, waiting for it."""
    def find(d):
        return next((f for f in stats(d)["frames"] if test(f)), None)
    return WebDriverWait(drv, timeout, poll_frequency=0.05).until(find)


def circle_drag(drv, seconds: float, radius: int = 120) -> None:
    """Hold the button and move on a circle, one small move every MOVE_MS: a steady hand turning the scene.
    A circle, so that the pointer stays inside the window however long it lasts."""
    canvas = drv.find_element(By.ID, "view")
    chain = ActionChains(drv, duration=MOVE_MS).move_to_element(canvas).click_and_hold()
    steps = max(1, int(seconds * 1000 / MOVE_MS))
    period = 90  # moves a turn: about 3 s
    x = y = 0
    for i in range(1, steps + 1):
        a = 2 * math.pi * i / period
        nx, ny = round(radius * math.sin(a)), round(radius * (1 - math.cos(a)) - radius / 2)
        chain.move_by_offset(nx - x, ny - y)
        x, y = nx, ny
    chain.release().perform()


def wait_settled(drv, after_ms: float, timeout: float = 600) -> Dict[str, Any]:
    """The full frame of the camera the page shows now, asked for after after_ms (page clock)."""
    js = """const f = window.stylerfStats.frames, c = window.stylerfState.camera, last = f[f.length - 1];
            if (!last || last.kind !== 'full' || last.requestedAt <= arguments[0]) return null;
            for (const k of ['view', 'yaw', 'pitch', 'zoom']) if (last.camera[k] !== c[k]) return null;
            return last;"""
    return WebDriverWait(drv, timeout, poll_frequency=0.05).until(lambda d: d.execute_script(js, after_ms))


def short_drag(drv, dx: int, dy: int) -> None:
    canvas = drv.find_element(By.ID, "view")
    chain = ActionChains(drv, duration=MOVE_MS).move_to_element(canvas).click_and_hold()
    for _ in range(5):
        chain.move_by_offset(dx // 5, dy // 5)
    chain.release().perform()


def run_stylize(tool: str, ckpt: str, style: str, path_file: str, out: str, extra: List[str]) -> Dict[str, Any]:
    """`stylize --camera-path`: seconds a frame after the first (metrics.json) and its peak RSS in MB (wait4's
    rusage of that one child, so nothing else this script started is counted)."""
    with open(os.path.join(out, "stylize.log"), "w") as log:
        proc = subprocess.Popen([tool, "stylize", "--ckpt", ckpt, "--style", style, "--camera-path", path_file,
                                 "--cache", "none", "--no-losses", "-o", out, *extra],
                                stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        sys.exit(f"stylize failed ({proc.returncode}); see {out}/stylize.log")
    with open(os.path.join(out, "metrics.json")) as f:
        timing = json.load(f)["timing"]
    return {"s_per_frame": 1.0 / timing["frames_per_s_after_first"], "peak_rss_mb": usage.ru_maxrss / 1024.0,
            "timing": timing}


def common_args(args) -> List[str]:
    """Options given to both the server and stylize, so that they render the same scene on the same device."""
    out = []
    if args.scene:
        out += ["--scene", args.scene]
    if args.device:
        out += ["--device", args.device]
    return out


def verdict(ok: bool) -> str:
    return "meets the target" if ok else "MISSES the target"


def measure_first_preview(drv, server: Server, out: str) -> Dict[str, Any]:
    progress("loading the page")
    drv.get(server.url)
    first = wait_frames(drv, lambda f: True)
    s = stats(drv)
    full = wait_frames(drv, lambda f: f["kind"] == "full")
    drv.save_screenshot(os.path.join(out, "1_loaded.png"))
    r = {"first_preview_ms": first["shownAt"] - s["loadedAt"], "since_navigation_ms": first["shownAt"],
         "info_ms": s["infoAt"] - s["loadedAt"], "first_full_ms": full["shownAt"] - s["loadedAt"],
         "first_kind": first["kind"]}
    progress(f"first preview {r['first_preview_ms']:.0f} ms after the script started "
             f"({r['since_navigation_ms']:.0f} ms after navigation; target <= {TARGETS['first_preview_ms']} ms: "
             f"{verdict(r['first_preview_ms'] <= TARGETS['first_preview_ms'])})")
    return r


def measure_drag_fps(drv, out: str) -> Dict[str, Any]:
    progress(f"dragging for {FPS_DRAG_S} s at one move every {MOVE_MS} ms")
    t0 = now_ms(drv)
    circle_drag(drv, FPS_DRAG_S)
    t1 = now_ms(drv)
    drv.save_screenshot(os.path.join(out, "2_dragged.png"))
    frames = [f for f in stats(drv)["frames"] if t0 <= f["shownAt"] <= t1]
    previews = [f for f in frames if f["kind"] == "preview"]
    fps = len(previews) / ((t1 - t0) / 1000.0)
    rt = [f["shownAt"] - f["requestedAt"] for f in previews]
    r = {"seconds": (t1 - t0) / 1000.0, "previews": len(previews), "fulls": len(frames) - len(previews),
         "preview_fps": fps, "median_round_trip_ms": statistics.median(rt) if rt else None,
         "median_render_ms": statistics.median(f["renderMs"] for f in previews) if previews else None,
         "preview_side": previews[0]["side"] if previews else None}
    progress(f"{len(previews)} previews in {r['seconds']:.1f} s: {fps:.2f} frames/s (target >= "
             f"{TARGETS['preview_fps']}: {verdict(fps >= TARGETS['preview_fps'])}); median round trip "
             f"{r['median_round_trip_ms'] or 0:.0f} ms")
    return r


def measure_drop(drv, image: str, out: str) -> Dict[str, Any]:
    progress(f"uploading {os.path.basename(image)}")
    n = len(stats(drv)["uploads"])
    drv.find_element(By.ID, "upload").send_keys(os.path.abspath(image))

    def answered(d):  # the page's record of this upload, once the server has answered it
        ups = stats(d)["uploads"]
        return ups[n] if len(ups) > n and (ups[n]["id"] or ups[n].get("error")) else None
    up = WebDriverWait(drv, 600, poll_frequency=0.05).until(answered)
    if up.get("error"):
        sys.exit(f"the upload was refused: {up['error']}")
    first = wait_frames(drv, lambda f: f["style"] == up["id"])
    wait_frames(drv, lambda f: f["style"] == up["id"] and f["kind"] == "full")
    drv.save_screenshot(os.path.join(out, "3_uploaded.png"))
    r = {"drop_to_preview_ms": first["shownAt"] - up["startedAt"], "upload_ms": up["doneAt"] - up["startedAt"],
         "server_encode_ms": up["encodeMs"], "first_kind": first["kind"], "style_id": up["id"]}
    progress(f"upload to first frame {r['drop_to_preview_ms']:.0f} ms (upload and encoding {r['upload_ms']:.0f} ms; "
             f"target <= {TARGETS['drop_to_preview_ms']} ms: "
             f"{verdict(r['drop_to_preview_ms'] <= TARGETS['drop_to_preview_ms'])})")
    return r


def measure_refined(drv, server: Server, args, out: str) -> Dict[str, Any]:
    """Full frames at new cameras (three drags, content not cached) against stylize of the last camera."""
    progress("refined frames at new cameras")
    fulls = []
    for i in range(3):
        t = now_ms(drv)
        short_drag(drv, 40, 10 if i % 2 else -10)
        fulls.append(wait_settled(drv, t))
    new = [f for f in fulls if not f["cached"]]
    if not new:
        progress("every full frame reused cached content: the server's time is not a new camera's")
    view_ms = statistics.median(f["renderMs"] for f in (new or fulls))
    info = server.get_json("/api/info")
    cam, side = fulls[-1]["camera"], max(info["full"]["width"], info["full"]["height"])
    doc = json.loads(server.post("/api/camera_path", {"camera": cam, "side": side}))
    doc["camera_path"] = doc["camera_path"] * 3  # frames 2 and 3 are timed: each renders its content again
    doc["seconds"] = len(doc["camera_path"]) / doc["fps"]
    path_file = os.path.join(out, "camera_path.json")
    with open(path_file, "w") as f:
        json.dump(doc, f, indent=2)
    progress("stylize --camera-path of the same camera, 3 frames")
    st = run_stylize(args.stylerf, args.ckpt, args.style_image, path_file, os.path.join(out, "stylize"),
                     common_args(args))
    direct = direct_full_frames(server, cam, side, fulls[-1]["style"])
    ratio = view_ms / 1000.0 / st["s_per_frame"]
    direct_ratio = statistics.median(direct) / 1000.0 / st["s_per_frame"] if direct else None
    r = {"view_full_ms": view_ms, "view_full_ms_each": [f["renderMs"] for f in fulls],
         "content_cached": [f["cached"] for f in fulls], "side": side, "camera": cam,
         "direct_full_ms_each": direct, "direct_ratio": direct_ratio,
         "stylize_s_per_frame": st["s_per_frame"], "ratio": ratio, "stylize_peak_rss_mb": st["peak_rss_mb"]}
    progress(f"refined frame {view_ms:.0f} ms vs stylize {st['s_per_frame'] * 1e3:.0f} ms a frame: {ratio:.3f}x "
             f"(target <= {TARGETS['refined_ratio']}x: {verdict(ratio <= TARGETS['refined_ratio'])})")
    if direct_ratio is not None:
        progress(f"  the same asked for over HTTP with the browser idle: {statistics.median(direct):.0f} ms, "
                 f"{direct_ratio:.3f}x")
    return r


def direct_full_frames(server: Server, cam: Dict[str, Any], side: int, style: str) -> List[float]:
    """X-Render-Ms of full frames at three more new cameras, posted straight to the server while the browser
    waits: the server's own time without the page competing for the same cores."""
    ms = []
    for k in range(1, 4):
        c = dict(cam, yaw=cam["yaw"] + 0.05 * k)
        headers: Dict[str, str] = {}
        server.post("/api/render", {"client": "bench-direct", "camera": c, "side": side, "style": style}, headers)
        if headers.get("x-content-cached") == "0":
            ms.append(float(headers["x-render-ms"]))
    return ms


def measure_memory(drv, server: Server, minutes: float, stylize_mb: float, out: str) -> Dict[str, Any]:
    progress(f"dragging for {minutes:g} min, the server's memory read every {SAMPLE_EVERY_S} s")
    samples = [dict(t_s=0.0, **server.memory_mb())]
    t0 = time.monotonic()
    while time.monotonic() - t0 < minutes * 60:
        circle_drag(drv, min(SAMPLE_EVERY_S, minutes * 60 - (time.monotonic() - t0)))
        samples.append(dict(t_s=time.monotonic() - t0, **server.memory_mb()))
        progress(f"  {samples[-1]['t_s']:.0f} s: RSS {samples[-1]['VmRSS']:.0f} MB, peak {samples[-1]['VmHWM']:.0f} MB")
    drv.save_screenshot(os.path.join(out, "4_after_drag.png"))
    peak = max(s["VmHWM"] for s in samples)
    at_1min = next((s for s in samples if s["t_s"] >= 60), samples[0])
    drift = samples[-1]["VmRSS"] - at_1min["VmRSS"]
    r = {"samples": samples, "server_peak_mb": peak, "stylize_peak_mb": stylize_mb,
         "over_stylize_mb": peak - stylize_mb, "rss_drift_since_1min_mb": drift}
    progress(f"server peak {peak:.0f} MB vs stylize {stylize_mb:.0f} MB: {peak - stylize_mb:+.0f} MB (target <= "
             f"+{TARGETS['rss_over_stylize_mb']} MB: {verdict(peak - stylize_mb <= TARGETS['rss_over_stylize_mb'])}); "
             f"RSS from 1 min to the end {drift:+.1f} MB")
    return r


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stylerf", required=True, help="the built stylerf tool")
    ap.add_argument("--ckpt", required=True, help="style checkpoint (train-style)")
    ap.add_argument("--styles", required=True, help="folder of style images the server lists")
    ap.add_argument("--style-image", required=True, help="a style image the server has not seen, to upload")
    ap.add_argument("--minutes", type=float, default=10.0, help="dragging time of the memory check")
    ap.add_argument("--scene", help="scene folder, for both (default: the one the checkpoint was trained on)")
    ap.add_argument("--device", help="OpenCL device, for both (default: the tool's choice)")
    ap.add_argument("--chromedriver", default="/usr/bin/chromedriver")
    ap.add_argument("-o", "--out", default=None, help="output folder (default: a new temporary folder)")
    args = ap.parse_args()
    out = args.out or tempfile.mkdtemp(prefix="stylerf-view-bench-")
    os.makedirs(os.path.join(out, "stylize"), exist_ok=True)

    progress("starting stylerf view")
    server = Server(args.stylerf, args.ckpt, args.styles, common_args(args))
    progress(f"listening at {server.url}")
    drv = start_browser(args.chromedriver)
    result: Dict[str, Any] = {"targets": TARGETS, "args": vars(args)}
    try:
        result["first_preview"] = measure_first_preview(drv, server, out)
        info = server.get_json("/api/info")
        result["device"], result["full"], result["preview_side"] = info["device"], info["full"], info["preview_side"]
        progress(f"scene {info['scene']} ({info['kind']}), full {info['full']['width']}x{info['full']['height']}, "
                 f"previews {info['preview_side']} px, device {info['device']}")
        result["drag"] = measure_drag_fps(drv, out)
        result["drop"] = measure_drop(drv, args.style_image, out)
        result["refined"] = measure_refined(drv, server, args, out)
        result["memory"] = measure_memory(drv, server, args.minutes, result["refined"]["stylize_peak_rss_mb"], out)
    finally:
        drv.quit()
        result["server_exit_code"] = server.stop()
        with open(os.path.join(out, "view_bench.json"), "w") as f:
            json.dump(result, f, indent=2)
    progress(f"server exited {result['server_exit_code']}; wrote {os.path.join(out, 'view_bench.json')}")
    summary(result)


def summary(r: Dict[str, Any]) -> None:
    """The five figures as a table, each beside its target."""
    t = TARGETS
    first, fps = r["first_preview"]["first_preview_ms"], r["drag"]["preview_fps"]
    drop, ratio, over = r["drop"]["drop_to_preview_ms"], r["refined"]["ratio"], r["memory"]["over_stylize_mb"]
    rows = [
        ("first preview after load", f"{first:.0f} ms", f"<= {t['first_preview_ms']} ms",
         first <= t["first_preview_ms"]),
        ("previews while dragging", f"{fps:.2f} /s", f">= {t['preview_fps']} /s", fps >= t["preview_fps"]),
        ("upload to first preview", f"{drop:.0f} ms", f"<= {t['drop_to_preview_ms']} ms",
         drop <= t["drop_to_preview_ms"]),
        ("refined frame / stylize", f"{ratio:.3f}x", f"<= {t['refined_ratio']}x", ratio <= t["refined_ratio"]),
        ("server peak RSS - stylize's", f"{over:+.0f} MB", f"<= +{t['rss_over_stylize_mb']} MB",
         over <= t["rss_over_stylize_mb"]),
    ]
    print(f"\n{'measure':30} {'value':>12}  {'target':>14}")
    for name, value, target, ok in rows:
        print(f"{name:30} {value:>12}  {target:>14}  {'ok' if ok else 'MISSED'}")
    print(f"RSS change from 1 min to the end: {r['memory']['rss_drift_since_1min_mb']:+.1f} MB; "
          f"device: {r.get('device')}")


if __name__ == "__main__":
    main()
