"""An orbit around a trained scene whose style moves from one image to another (StyleRF's interpolation).

    python3 examples/python/orbit.py STYLE.ckpt STYLE_A.jpg STYLE_B.jpg OUT.mp4 [--frames 60] [--size 256]

Each frame mixes the two style codes with weights (1 - t, t), t going 0 -> 1 -> 0 over the orbit; frames
are written as PNGs next to OUT.mp4 and joined by ffmpeg (as `stylerf stylize` does).
"""
import argparse
import os
import shutil
import subprocess

import stylerf


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for name in ("ckpt", "style_a", "style_b", "out"):
        ap.add_argument(name)
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--size", type=int, default=0, help="longer image side (0: the scene's)")
    ap.add_argument("--fps", type=int, default=30)
    args = ap.parse_args()

    model = stylerf.StyleModel.open(args.ckpt)
    a, b = model.encode_style(args.style_a), model.encode_style(args.style_b)
    frames_dir = os.path.splitext(args.out)[0] + "_frames"
    os.makedirs(frames_dir, exist_ok=True)
    cams = model.path_cameras(args.frames)
    for i, cam in enumerate(cams):
        t = 1 - abs(1 - 2 * i / max(1, len(cams) - 1))  # 0 -> 1 -> 0: the video loops
        frame = model.stylize(cam.with_longer_side(args.size), stylerf.mix([a, b], [1 - t, t]))
        stylerf.save_image(os.path.join(frames_dir, f"frame_{i:04d}.png"), frame)
        print(f"frame {i + 1}/{len(cams)}  t={t:.2f}", end="\r", flush=True)
    if shutil.which("ffmpeg") is None:
        raise SystemExit(f"\nffmpeg is not on PATH; the frames are in {frames_dir}")
    subprocess.run(["ffmpeg", "-loglevel", "error", "-y", "-framerate", str(args.fps), "-i",
                    os.path.join(frames_dir, "frame_%04d.png"), "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                    "-pix_fmt", "yuv420p", args.out], check=True)
    print(f"\n{args.out}: {len(cams)} frames")


if __name__ == "__main__":
    main()
