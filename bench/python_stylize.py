"""The cost of the Python binding on one stylised frame: `model.stylize` timed from Python against the same
library calls timed in C++ (StyleModel._cpp_stylize_seconds: render_camera_content, stylize_camera,
over_background, as the binding runs them), in one process, the two interleaved call by call so that
both see the same machine state.

    PYTHONPATH=build/python python3 bench/python_stylize.py STYLE.ckpt STYLE_IMG [--size 256] [--calls 15]
"""
import argparse
import statistics
import time

import stylerf


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("ckpt")
    ap.add_argument("style")
    ap.add_argument("--size", type=int, default=256, help="the frame's width and height")
    ap.add_argument("--calls", type=int, default=15)
    args = ap.parse_args()

    model = stylerf.StyleModel.open(args.ckpt)
    code = model.encode_style(args.style)
    cam = model.cameras[0].resized(args.size, args.size)
    model.stylize(cam, code)  # warm-up: kernel builds and first-touch buffers
    py, cpp = [], []
    for _ in range(args.calls):
        t0 = time.perf_counter()
        model.stylize(cam, code)
        py.append(time.perf_counter() - t0)
        cpp += model._cpp_stylize_seconds(cam, code, repeats=1)
    mp, mc = statistics.median(py), statistics.median(cpp)
    print(f"{args.size}x{args.size} stylize, supersample {model.supersample}, {args.calls} calls each, "
          f"device {stylerf.device()['name']}")
    print(f"  python: median {mp * 1e3:.2f} ms (min {min(py) * 1e3:.2f})")
    print(f"  c++:    median {mc * 1e3:.2f} ms (min {min(cpp) * 1e3:.2f})")
    print(f"  python / c++: {mp / mc:.4f} (median), {min(py) / min(cpp):.4f} (min)")


if __name__ == "__main__":
    main()
