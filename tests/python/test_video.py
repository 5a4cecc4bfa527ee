"""stylerf.save_video: frames from numpy to an mp4 through the library's video writer (the CLI's), decoded
back with ffmpeg to check what was written; and its errors, each before anything is left behind."""
import os
import shutil
import subprocess

import numpy as np
import pytest

import stylerf

needs_ffmpeg = pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="ffmpeg is not installed")


def ramp(n, h=16, w=24):
    """n flat frames whose red goes 0 -> 1 and whose green goes 1 -> 0: a decoded frame says which it was."""
    t = np.linspace(0, 1, n, dtype=np.float32)
    frames = np.empty((n, h, w, 3), np.float32)
    frames[..., 0] = t[:, None, None]
    frames[..., 1] = 1 - t[:, None, None]
    frames[..., 2] = 0.5
    return list(frames)


def decode(path):
    """The video's frames as uint8 arrays (ffmpeg to raw RGB) and its size."""
    probe = subprocess.run(["ffprobe", "-v", "error", "-select_streams", "v:0", "-show_entries",
                            "stream=width,height,r_frame_rate", "-of", "csv=p=0", str(path)],
                           stdout=subprocess.PIPE, check=True, text=True).stdout.strip().split(",")
    w, h, rate = int(probe[0]), int(probe[1]), probe[2]
    raw = subprocess.run(["ffmpeg", "-nostdin", "-v", "error", "-i", str(path), "-f", "rawvideo", "-pix_fmt", "rgb24",
                          "-"], stdout=subprocess.PIPE, check=True).stdout
    return np.frombuffer(raw, np.uint8).reshape(-1, h, w, 3), rate


@pytest.fixture
def private_tmpdir(tmp_path, monkeypatch):
    """The writer's temporary folder for the frames goes here, so a test can see that it was removed."""
    d = tmp_path / "tmp"
    d.mkdir()
    monkeypatch.setenv("TMPDIR", str(d))
    return d


@needs_ffmpeg
def test_the_frames_come_back_in_order(tmp_path, private_tmpdir):
    frames = ramp(12)
    stylerf.save_video(frames, tmp_path / "ramp.mp4", fps=24)
    video, rate = decode(tmp_path / "ramp.mp4")
    assert video.shape == (12, 16, 24, 3) and rate == "24/1"
    red = video[..., 0].mean(axis=(1, 2)) / 255
    green = video[..., 1].mean(axis=(1, 2)) / 255
    want = np.linspace(0, 1, 12)
    assert np.abs(red - want).max() < 0.04 and np.abs(green - (1 - want)).max() < 0.04
    assert os.listdir(private_tmpdir) == []
    assert sorted(os.listdir(tmp_path)) == ["ramp.mp4", "tmp"]


@needs_ffmpeg
def test_uint8_frames_an_array_of_frames_and_odd_sizes(tmp_path):
    frames = (np.stack(ramp(3, h=17, w=33)) * 255).round().astype(np.uint8)
    stylerf.save_video(frames, str(tmp_path / "odd.mp4"), 10)
    video, rate = decode(tmp_path / "odd.mp4")
    assert video.shape == (3, 18, 34, 3), "yuv420p needs even sizes: padded by a pixel"
    assert rate == "10/1"
    assert np.abs(video[:, :17, :33].astype(int) - frames).mean() < 8


@pytest.mark.parametrize("frames, fps, error", [
    ([], 30, "^frames: empty"),
    (ramp(2), 0, "^fps: must be a positive number"),
    (ramp(2), -5, "^fps: "),
    (ramp(2), float("nan"), "^fps: "),
    (ramp(2) + ramp(1, h=8), 30, r"^frames\[2\]: 8 x 24 pixels, frames\[0\] 16 x 24"),
    (ramp(2) + [np.zeros((16, 24, 3))], 30, r"^frames\[2\]: dtype float64"),
    (ramp(2) + ["frame.png"], 30, r"^frames\[2\]: expected a numpy array"),
])
def test_bad_input_is_a_value_error_and_leaves_nothing(tmp_path, private_tmpdir, frames, fps, error):
    if "dtype" in error or "numpy array" in error:
        if shutil.which("ffmpeg") is None:
            pytest.skip("the frames are read only once ffmpeg is found")
    with pytest.raises(ValueError, match=error):
        stylerf.save_video(frames, tmp_path / "v.mp4", fps)
    assert sorted(os.listdir(tmp_path)) == ["tmp"] and os.listdir(private_tmpdir) == []


def test_without_ffmpeg_the_error_says_so(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))  # a folder without ffmpeg
    with pytest.raises(stylerf.Error, match="ffmpeg is not on PATH"):
        stylerf.save_video(ramp(2), tmp_path / "v.mp4", 30)
    assert os.listdir(tmp_path) == []


def test_a_missing_folder_is_named(tmp_path):
    with pytest.raises(stylerf.Error, match="the folder .*missing does not exist"):
        stylerf.save_video(ramp(2), tmp_path / "missing" / "v.mp4", 30)
