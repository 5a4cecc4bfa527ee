"""`stylerf view`'s HTTP API over loopback, against the tiny trained scene of the `stages` fixture:
each endpoint, each refusal docs/viewer.md promises (413, 415, 400, 404, 403, 409), a bounded fuzz of
malformed requests after which the server still answers, eight clients at once, a client that sends half a
request and stalls, and a clean stop on SIGINT.
"""
import http.client
import json
import os
import random
import re
import signal
import socket
import subprocess
import threading
import time
from typing import Dict, List, Optional, Tuple

import pytest

from conftest import cli_path

START_S = 300  # loading and the first frames on a loaded 2-core machine


class Server:
    """`stylerf view` as a subprocess, listening on a free port; stopped with SIGINT."""

    def __init__(self, ckpt: str, styles: str, *extra: str) -> None:
        self.proc = subprocess.Popen([cli_path(), "view", "--ckpt", ckpt, "--styles", styles, "--port", "0", *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: List[str] = []
        found = threading.Event()
        self.url = ""

        def read() -> None:
            for line in self.proc.stdout:
                self.lines.append(line)
                m = re.search(r"http://([0-9.]+):(\d+)/(\S*)", line)
                if m and not self.url:
                    self.host, self.port, self.url = m.group(1), int(m.group(2)), m.group(0)
                    found.set()

        threading.Thread(target=read, daemon=True).start()
        if not found.wait(START_S):
            self.proc.kill()
            pytest.fail("stylerf view did not start:\n" + "".join(self.lines))
        self.token = self.url.split("token=")[1] if "token=" in self.url else ""

    def request(self, method: str, path: str, body: Optional[bytes] = None,
                headers: Optional[Dict[str, str]] = None, timeout: float = 120) -> Tuple[int, Dict[str, str], bytes]:
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=timeout)
        h = dict(headers or {})
        if self.token and "X-Stylerf-Token" not in h:
            h["X-Stylerf-Token"] = self.token
        conn.request(method, path, body=body, headers=h)
        r = conn.getresponse()
        data = r.read()
        conn.close()
        return r.status, {k.lower(): v for k, v in r.getheaders()}, data

    def json(self, method: str, path: str, doc) -> Tuple[int, Dict[str, str], bytes]:
        return self.request(method, path, json.dumps(doc).encode(), {"Content-Type": "application/json"})

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return -999


@pytest.fixture(scope="module")
def server(stages):
    s = Server(stages.style, stages.styles)
    yield s
    code = s.stop()
    assert code == 0, "".join(s.lines)


def render_doc(info, **over):
    doc = {"client": "t", "camera": {"view": 0, "yaw": 0.2, "pitch": 0.1, "zoom": 0.0},
           "side": info["preview_side"], "style": info["styles"][0]["id"]}
    doc.update(over)
    return doc


def is_png(data: bytes) -> bool:
    return data[:8] == b"\x89PNG\r\n\x1a\n"


def png_size(data: bytes) -> Tuple[int, int]:
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def test_page_info_styles_and_thumbnails(server, stages):
    status, headers, page = server.request("GET", "/")
    assert status == 200 and b"<canvas" in page and "text/html" in headers["content-type"]
    for asset in ("/app.js", "/app.css"):
        assert server.request("GET", asset)[0] == 200
    status, _, body = server.request("GET", "/api/info")
    info = json.loads(body)
    assert info["kind"] == "orbit" and info["views"] >= 1 and not info["token_required"]
    names = {s["name"] for s in info["styles"]}
    assert {os.path.splitext(os.path.basename(p))[0] for p in stages.style_images} <= names
    status, headers, thumb = server.request("GET", "/api/styles/%s/thumb" % info["styles"][0]["id"])
    assert status == 200 and is_png(thumb) and max(png_size(thumb)) == 96
    assert server.request("GET", "/api/styles/s999/thumb")[0] == 404


def test_render_preview_full_mix_region_and_camera_path(server):
    info = json.loads(server.request("GET", "/api/info")[2])
    full = max(info["full"]["width"], info["full"]["height"])
    status, headers, png = server.json("POST", "/api/render", render_doc(info))
    assert status == 200 and is_png(png) and max(png_size(png)) == info["preview_side"]
    assert float(headers["x-render-ms"]) > 0
    status, headers, png = server.json("POST", "/api/render", render_doc(info, side=full))
    assert status == 200 and max(png_size(png)) == full
    # The same camera and size again: its content comes from the cache.
    status, headers, again = server.json("POST", "/api/render", render_doc(info, side=full))
    assert headers["x-content-cached"] == "1" and again == png
    second = info["styles"][1]["id"]
    mixed = server.json("POST", "/api/render", render_doc(info, side=full, style_b=second, mix=0.5))
    assert mixed[0] == 200 and mixed[2] != png
    region = server.json("POST", "/api/render", render_doc(info, side=full, style_b=second,
                                                         region={"shape": "box", "scale": 1.5}))
    assert region[0] == 200 and is_png(region[2])
    status, _, body = server.json("POST", "/api/camera_path", {"camera": {"view": 0, "yaw": 0.2}, "side": full})
    path = json.loads(body)
    assert status == 200 and len(path["camera_path"]) == 1 and path["render_height"] * path["render_width"] > 0


def test_upload_becomes_a_style_and_refusals_say_why(server, stages):
    with open(stages.style_images[0], "rb") as f:
        image = f.read()
    status, _, body = server.request("POST", "/api/styles?name=mine.png", image, {"Content-Type": "image/png"})
    assert status == 201, body
    up = json.loads(body)
    assert up["source"] == "upload" and up["name"] == "mine"
    assert any(s["id"] == up["id"] for s in json.loads(server.request("GET", "/api/styles")[2]))
    info = json.loads(server.request("GET", "/api/info")[2])
    assert server.json("POST", "/api/render", render_doc(info, style=up["id"]))[0] == 200
    # Not an image; too large; empty.
    status, _, body = server.request("POST", "/api/styles", b"hello, not an image", {"Content-Type": "image/png"})
    assert status == 415 and "not an image" in json.loads(body)["error"]
    # A header that claims 25120 x 29813 pixels: refused before decoding, and the answer names no server path.
    status, _, body = server.request("POST", "/api/styles", b"GIF89a but not really", {"Content-Type": "image/gif"})
    error = json.loads(body)["error"]
    assert status == 415 and "/" not in error.replace("w/", ""), error
    status, _, body = server.request("POST", "/api/styles", b"\0" * (16 * 2**20 + 1), {"Content-Type": "image/png"})
    assert status == 413 and "error" in json.loads(body)
    assert server.request("POST", "/api/styles", b"", {"Content-Type": "image/png"})[0] == 415


@pytest.mark.parametrize("doc,status,needle", [
    ("{not json", 400, "not JSON"),
    ([1, 2], 400, "object"),
    ({"camera": {"view": 0}, "side": 64, "style": "s0"}, 400, "client"),
    ({"client": "t", "side": 64, "style": "s0"}, 400, "camera"),
    ({"client": "t", "camera": {"view": 0}, "side": 5, "style": "s0"}, 400, "side"),
    ({"client": "t", "camera": {"view": 0}, "side": 100000, "style": "s0"}, 400, "side"),
    ({"client": "t", "camera": {"view": 0}, "side": 64.5, "style": "s0"}, 400, "integer"),
    ({"client": "t", "camera": {"view": 10**6}, "side": 64, "style": "s0"}, 400, "view"),
    ({"client": "t", "camera": {"view": 0, "yaw": "left"}, "side": 64, "style": "s0"}, 400, "yaw"),
    ({"client": "t", "camera": {"view": 0, "zoom": 1e400}, "side": 64, "style": "s0"}, 400, ""),
    ({"client": "t", "camera": {"view": 0}, "side": 64, "style": "nope"}, 404, "nope"),
    ({"client": "t", "camera": {"view": 0}, "side": 64, "style": "s0", "mix": 2}, 400, "mix"),
    ({"client": "t", "camera": {"view": 0}, "side": 64, "style": "s0", "region": {"shape": "box"}}, 400, "style_b"),
    ({"client": "../etc", "camera": {"view": 0}, "side": 64, "style": "s0"}, 400, "client"),
])
def test_malformed_render_requests_get_4xx_with_a_reason(server, doc, status, needle):
    body = doc.encode() if isinstance(doc, str) else json.dumps(doc).encode()
    got, _, answer = server.request("POST", "/api/render", body, {"Content-Type": "application/json"})
    assert got == status, answer
    assert needle in json.loads(answer)["error"]


def test_a_nan_camera_is_refused(server):
    # JSON has no NaN; Python writes it as the bare word, which is not JSON.
    body = b'{"client": "t", "camera": {"view": 0, "yaw": NaN}, "side": 64, "style": "s0"}'
    assert server.request("POST", "/api/render", body, {"Content-Type": "application/json"})[0] == 400


def test_a_thousand_malformed_requests_leave_the_server_answering(server):
    rng = random.Random(5)
    paths = ["/api/render", "/api/styles", "/api/camera_path", "/api/record", "/api/info", "/nope", "/api/styles/x/thumb"]
    pieces = [b"{", b"}", b'"camera"', b":", b"[", b"]", b"null", b"1e999", b"-1", b'"side"', b"\xff\xfe", b",",
              b'"view"', b"NaN", b'"client"', b"\x00", b'"style"', b"0", b"99999999999999999999"]
    for i in range(1000):
        body = b"".join(rng.choice(pieces) for _ in range(rng.randint(0, 24)))
        method = rng.choice(["POST", "POST", "GET", "PUT", "DELETE"])
        status, _, _ = server.request(method, rng.choice(paths), body, {"Content-Type": rng.choice(
            ["application/json", "image/png", "text/plain"])})
        assert status < 500 or status == 503, (i, method, body)
    assert server.request("GET", "/api/info")[0] == 200


def test_eight_clients_at_once_each_get_their_frames(server):
    info = json.loads(server.request("GET", "/api/info")[2])
    results: Dict[int, List[int]] = {}

    def client(k: int) -> None:
        codes = []
        for j in range(3):
            doc = render_doc(info, client=f"tab{k}", camera={"view": k % info["views"], "yaw": 0.1 * j})
            codes.append(server.json("POST", "/api/render", doc)[0])
        results[k] = codes

    threads = [threading.Thread(target=client, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    assert sorted(results) == list(range(8))
    assert all(code == 200 for codes in results.values() for code in codes), results


def test_a_newer_frame_supersedes_a_tabs_older_one(server):
    info = json.loads(server.request("GET", "/api/info")[2])
    full = max(info["full"]["width"], info["full"]["height"])
    answers: List[int] = []
    together = threading.Barrier(6)

    def ask(yaw: float) -> None:
        doc = render_doc(info, client="busy", side=full, camera={"view": 0, "yaw": yaw}, style_b=info["styles"][1]["id"],
                         region={"shape": "sphere", "scale": 1.0})
        together.wait()
        answers.append(server.json("POST", "/api/render", doc)[0])

    # Six frames of one tab at once: one renders, each later one replaces the pending one before it.
    threads = [threading.Thread(target=ask, args=(1.0 + 0.01 * k,)) for k in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    assert sorted(set(answers)) <= [200, 409] and answers.count(200) >= 1 and answers.count(409) >= 1, answers


def test_a_stalled_client_does_not_block_the_others(server):
    stalled = socket.create_connection(("127.0.0.1", server.port))
    stalled.sendall(b"POST /api/render HTTP/1.1\r\nHost: x\r\nContent-Length: 1000\r\n\r\n{\"client\"")
    try:
        t = time.time()
        assert server.request("GET", "/api/info")[0] == 200
        assert time.time() - t < 5
    finally:
        stalled.close()


def test_record_returns_an_mp4(server):
    info = json.loads(server.request("GET", "/api/info")[2])
    status, headers, body = server.json("POST", "/api/record", render_doc(info, frames=4))
    if status == 503:
        pytest.skip("no ffmpeg: " + json.loads(body)["error"])
    assert status == 200 and headers["content-type"] == "video/mp4" and body[4:8] == b"ftyp"
    assert server.json("POST", "/api/record", render_doc(info, frames=1))[0] == 400


def test_another_address_needs_the_token(stages):
    s = Server(stages.style, stages.styles, "--host", "0.0.0.0")
    try:
        assert s.token and re.fullmatch(r"[0-9a-f]{32}", s.token)
        assert s.request("GET", "/api/info", headers={"X-Stylerf-Token": "wrong"})[0] == 403
        assert s.request("GET", "/", headers={"X-Stylerf-Token": ""})[0] == 403
        assert s.request("GET", "/api/info")[0] == 200
        assert s.request("GET", "/api/info?token=" + s.token, headers={"X-Stylerf-Token": ""})[0] in (200, 403)
        assert json.loads(s.request("GET", "/api/info")[2])["token_required"]
    finally:
        assert s.stop() == 0, "".join(s.lines)
