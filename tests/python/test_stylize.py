"""Zero-shot use from Python against the command-line tool and against itself."""
import os

import numpy as np
import pytest

import stylerf
from conftest import run_cli


def quantise(img):
    """What save_png writes: clamp to [0, 1], times 255 in float32, rounded half away from zero."""
    scaled = np.clip(img, 0, 1).astype(np.float32) * np.float32(255)
    return np.floor(scaled.astype(np.float64) + 0.5).astype(np.uint8)


def test_stylize_equals_the_cli(stages, model, tmp_path):
    # The CLI writes 8-bit PNG frames only, so the comparison is at 8 bits: every pixel's rounded value must be
    # equal (a float difference above 1/510 anywhere would show). Python's floats are checked bitwise
    # against its own repeated call and against the custom-camera path below.
    style = stages.style_images[0]
    out = tmp_path / "cli"
    code, log = run_cli("stylize", "--ckpt", stages.style, "--style", style, "--views", "test", "--max-views", "1",
                        "--no-losses", "--cache", "none", "-o", str(out))
    assert code == 0, log
    cli = stylerf.load_image(str(out / "test_000.png"))
    ours = model.stylize(0, model.encode_style(style))
    assert ours.shape == cli.shape == (32, 32, 3) and ours.dtype == np.float32
    assert not ours.flags.owndata  # the library's result handed to numpy, not copied into a new array
    # The object must cover part of the frame: over a plain background the comparison would prove little.
    assert (ours < 0.99).any(axis=-1).mean() > 0.1
    assert np.array_equal(quantise(ours), np.round(cli * 255).astype(np.uint8))
    assert np.array_equal(ours, model.stylize(0, model.encode_style(style)))


def test_strength_blends_as_the_cli(stages, tmp_path):
    # A model of its own: the shared fixture keeps the recipe's strength for the other tests.
    m = stylerf.StyleModel.open(stages.style)
    assert 0.0 <= m.strength <= 1.0
    style = stages.style_images[0]
    m.strength = 1.0
    full = m.stylize(0, m.encode_style(style))
    m.strength = 0.0
    plain = m.stylize(0, m.encode_style(style))
    assert not np.array_equal(full, plain)
    out = tmp_path / "cli"
    code, log = run_cli("stylize", "--ckpt", stages.style, "--style", style, "--views", "test", "--max-views", "1",
                        "--no-losses", "--cache", "none", "--strength", "0", "-o", str(out))
    assert code == 0, log
    assert np.array_equal(quantise(plain), np.round(stylerf.load_image(str(out / "test_000.png")) * 255).astype(np.uint8))
    with pytest.raises(ValueError, match="strength"):
        m.strength = 1.5
    assert m.strength == 0.0


def test_custom_camera_equals_the_scene_view(stages, model):
    code = model.encode_style(stages.style_images[1])
    view = stylerf.Scene.open(stages.scene).test_cameras[0]
    cam = stylerf.Camera(view.c2w, view.fx, view.fy, view.cx, view.cy, view.width, view.height)
    assert np.array_equal(cam.c2w, model.cameras[0].c2w)
    assert np.array_equal(model.stylize(cam, code), model.stylize(0, code))
    cam34 = stylerf.Camera(view.c2w[:3].copy(), view.fx, view.fy, view.cx, view.cy, view.width, view.height)
    assert np.array_equal(model.stylize(cam34, code), model.stylize(0, code))


def test_array_style_and_mix(stages, model):
    a = model.encode_style(stages.style_images[0])
    b = model.encode_style(stylerf.load_image(stages.style_images[1]))
    fa, fb = model.stylize(0, a), model.stylize(0, b)
    assert not np.array_equal(fa, fb)
    assert np.array_equal(model.stylize(0, stylerf.mix([a, b], [1.0, 0.0])), fa)
    half = model.stylize(0, stylerf.mix([a, b], [0.5, 0.5]))
    assert not np.array_equal(half, fa) and not np.array_equal(half, fb)
    u8 = (stylerf.load_image(stages.style_images[1]) * 255).round().astype(np.uint8)
    from_u8 = model.stylize(0, model.encode_style(u8))
    assert np.array_equal(from_u8, model.stylize(0, model.encode_style(u8.astype(np.float32) / 255)))


def test_render_gives_rgb_depth_opacity(model):
    r = model.render(0)
    cam = model.cameras[0]
    h, w = -(-cam.height // model.stride), -(-cam.width // model.stride)
    assert r["rgb"].shape == (cam.height, cam.width, 3)
    assert r["depth"].shape == r["opacity"].shape == (h, w)
    assert np.all((r["opacity"] >= 0) & (r["opacity"] <= 1 + 1e-5))
    assert np.all(np.isfinite(r["depth"])) and r["opacity"].max() > 0.5


def test_consistency_returns_both_ranges(stages, model):
    score = stylerf.consistency(model, model.encode_style(stages.style_images[0]), frames=8, path_frames=60,
                                lpips=None)
    assert set(score) == {"short_range", "long_range"}
    assert score["short_range"]["k"] == 1 and score["long_range"]["k"] == 7
    assert np.isfinite(score["short_range"]["rmse"]) and score["short_range"]["rmse"] >= 0
    assert score["short_range"]["lpips"] is None  # not measured


def test_lpips_and_images(tmp_path):
    rng = np.random.default_rng(0)
    a = rng.random((32, 32, 3), dtype=np.float32)
    b = np.ascontiguousarray(a[::-1])
    assert stylerf.lpips(a, a) == 0.0
    assert stylerf.lpips(a, b) > 0.01
    path = str(tmp_path / "a.png")
    stylerf.save_image(path, a)
    back = stylerf.load_image(path)
    assert np.abs(back - a).max() <= 0.5 / 255 + 1e-6


def test_devices_and_version():
    assert stylerf.__version__.count(".") == 2
    # The commit the module was built from: a short hash, or "unknown" outside a git checkout.
    assert stylerf.__commit__ == "unknown" or all(c in "0123456789abcdef" for c in stylerf.__commit__)
    names = [d["name"] for d in stylerf.devices()]
    assert stylerf.device()["name"] in names
    assert os.path.basename(stylerf.__file__) == "__init__.py"


def test_kernels_flush_denormals_and_numpy_keeps_them():
    # The kernels are built with -cl-denorms-are-zero (x86 runs values below 1e-38 slowly); PoCL applies it
    # to each kernel's thread for that kernel only, so NumPy here still computes denormals.
    dev = stylerf.device()
    if dev["type"] == "cpu":
        assert dev["denormals_flushed"] is True
    tiny = np.float32(1e-20)
    assert tiny * tiny > 0


def test_threads_take_turns_in_the_library(stages, model):
    # The GIL is released during compute, so threads reach the library together; it serialises them.
    import threading

    code = model.encode_style(stages.style_images[0])
    alone = [model.stylize(v, code) for v in (0, 1)]
    got = [None] * 4

    def work(i):
        got[i] = model.stylize(i % 2, code)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(np.array_equal(got[i], alone[i % 2]) for i in range(4))
