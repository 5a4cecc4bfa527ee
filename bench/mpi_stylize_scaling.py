#!/usr/bin/env python3
"""What a second rank buys in `stylerf stylize --views path`: one rank on one core against two ranks on one
core each (PoCL's thread count per device, POCL_MAX_PTHREAD_COUNT=1, each rank bound to its core), in one
run, one after the other on an otherwise idle machine.

    python3 bench/mpi_stylize_scaling.py --stylerf build/stylerf --ckpt OUT/style.ckpt --style IMG [--frames 12]

Frames a second are all ranks' frames over the time from the styles encoded to the last frame at rank 0
(metrics.json "ranks"): loading, which each rank does alike, is not counted. Writes OUT/mpi_scaling.json.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time


def run(stylerf: str, ranks: int, args: list, out: str) -> dict:
    env = dict(os.environ, POCL_MAX_PTHREAD_COUNT="1", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpirun", "-np", str(ranks), "--bind-to", "core", stylerf, "stylize", *args, "-o", out]
    t = time.monotonic()
    r = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.monotonic() - t
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{r.stdout}")
    m = json.load(open(os.path.join(out, "metrics.json")))
    fps = m["ranks"]["frames_per_s_after_encoding"]
    print(f"{ranks} rank(s), 1 core each: {m['ranks']['frames']} frames, {fps:.3f} frames/s after encoding "
          f"({wall:.1f} s in all)", flush=True)
    return {"ranks": ranks, "frames_per_s": fps, "wall_s": wall, "frames": m["ranks"]["frames"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stylerf", required=True)
    ap.add_argument("--ckpt", required=True, help="style checkpoint")
    ap.add_argument("--style", required=True, help="style image")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("-o", "--out", default=None)
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="stylerf-mpi-scaling-")
    args = ["--ckpt", a.ckpt, "--style", a.style, "--views", "path", "--frames", str(a.frames), "--no-losses",
            "--cache", "none"]
    one = run(a.stylerf, 1, args, os.path.join(out, "one"))
    two = run(a.stylerf, 2, args, os.path.join(out, "two"))
    speedup = two["frames_per_s"] / one["frames_per_s"]
    print(f"2 ranks / 1 rank: {speedup:.2f}x frames a second (target >= 1.7x)")
    with open(os.path.join(out, "mpi_scaling.json"), "w") as f:
        json.dump({"one": one, "two": two, "speedup": speedup, "args": vars(a)}, f, indent=2)


if __name__ == "__main__":
    main()
