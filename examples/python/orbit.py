"""An orbit around a trained scene whose style moves from one image to another (StyleRF's interpolation).

    python3 examples/python/orbit.py STYLE.ckpt STYLE_A.jpg STYLE_B.jpg OUT.mp4 [--frames 60] [--size 256]

Each frame mixes the two style codes with weights (1 - t, t), t going 0 -> 1 -> 0 over the orbit; the
frames are written as an mp4 by stylerf.save_video (through ffmpeg, as `stylerf stylize` writes its videos).
"""
import argparse
from pathlib import Path

import numpy as np

import stylerf


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for name in ("ckpt", "style_a", "style_b", "out"):
        ap.add_argument(name, type=Path)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--size", type=int, default=None, help="longer image side (default: the scene's)")
    ap.add_argument("--fps", type=float, default=30)
    args = ap.parse_args()

    model = stylerf.StyleModel.open(args.ckpt)
    a, b = model.encode_style(args.style_a), model.encode_style(args.style_b)
    cams = model.path_cameras(args.frames)
    frames = []
    for i, cam in enumerate(cams):
        t = 1 - abs(1 - 2 * i / max(1, len(cams) - 1))  # 0 -> 1 -> 0: the video loops
        if args.size is not None:
            cam = cam.with_longer_side(args.size)
        frame = model.stylize(cam, stylerf.mix([a, b], [1 - t, t]))
        frames.append(np.floor(frame * 255 + 0.5).astype(np.uint8))  # a quarter of the memory, same 8 bits
        print(f"frame {i + 1}/{len(cams)}  t={t:.2f}", end="\r", flush=True)
    stylerf.save_video(frames, args.out, args.fps)
    print(f"\n{args.out}: {len(cams)} frames")


if __name__ == "__main__":
    main()
