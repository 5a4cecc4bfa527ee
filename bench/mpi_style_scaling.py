#!/usr/bin/env python3
"""What a second rank buys in the style stage: `stylerf train-style` on one rank with one core (one style a
step) against two ranks with one core each (PoCL's thread count per device, POCL_MAX_PTHREAD_COUNT=1, each
rank bound to its core; two styles a step, one a rank), in one run, one after the other on an otherwise
idle machine. Styles a second are the styles a step over the mean step time of the steps after the first
--skip (the first pays for PoCL's kernel code generation), read off the progress lines.

    python3 bench/mpi_style_scaling.py --stylerf build/stylerf --features OUT/features.ckpt \\
        --styles ../shared/data/styles [--steps 12] [--warm-start 0]

--warm-start N > steps times the 2D warm-start steps instead of rendered ones. Writes OUT/mpi_style_scaling.json
with the gradient bytes a step and the averaging's milliseconds a step (what the all-reduce costs here).
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time


def run(stylerf: str, ranks: int, args: list, out: str, skip: int) -> dict:
    env = dict(os.environ, POCL_MAX_PTHREAD_COUNT="1", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpirun", "-np", str(ranks), "--bind-to", "core", stylerf, "train-style", *args, "-o", out]
    t = time.monotonic()
    r = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.monotonic() - t
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{r.stdout}")
    steps = [float(m.group(1)) for m in re.finditer(r"^it \d+/\d+.*?\s([0-9.]+) s/it", r.stdout, re.M)]
    if len(steps) <= skip:
        sys.exit(f"{len(steps)} progress lines, need more than --skip {skip}:\n{r.stdout}")
    per_step = sum(steps[skip:]) / len(steps[skip:])
    per = re.search(r"(\d+) styles? a step", r.stdout)
    styles = int(per.group(1)) if per else 1
    sync = re.search(r"([0-9.]+) MB a step, ([0-9.]+) ms a step", r.stdout)
    row = {"ranks": ranks, "styles_per_step": styles, "s_per_step": per_step, "styles_per_s": styles / per_step,
           "steps_timed": len(steps) - skip, "wall_s": wall,
           "gradient_mb_per_step": float(sync.group(1)) if sync else 0.0,
           "sync_ms_per_step": float(sync.group(2)) if sync else 0.0}
    print(f"{ranks} rank(s), 1 core each: {styles} style(s) a step, {per_step:.2f} s a step, "
          f"{row['styles_per_s']:.3f} styles/s; gradient {row['gradient_mb_per_step']:.1f} MB a step, averaged in "
          f"{row['sync_ms_per_step']:.1f} ms ({wall:.0f} s in all)", flush=True)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stylerf", required=True)
    ap.add_argument("--features", required=True, help="feature checkpoint")
    ap.add_argument("--styles", required=True, help="folder of style images")
    ap.add_argument("--steps", type=int, default=12)
    ap.add_argument("--skip", type=int, default=2, help="first steps not timed")
    ap.add_argument("--warm-start", type=int, default=0, help="2D warm-start steps (> --steps: time those)")
    ap.add_argument("-o", "--out", default=None)
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="stylerf-mpi-style-")
    os.makedirs(out, exist_ok=True)
    args = ["--features", a.features, "--styles", a.styles, "--iters", str(a.steps), "--warm-start",
            str(a.warm_start), "--eval-every", "0", "--log-every", "1", "--ckpt-every", "0", "--force"]
    one = run(a.stylerf, 1, args, os.path.join(out, "one.ckpt"), a.skip)
    two = run(a.stylerf, 2, args, os.path.join(out, "two.ckpt"), a.skip)
    speedup = two["styles_per_s"] / one["styles_per_s"]
    kind = "2D warm-start" if a.warm_start > a.steps else "rendered"
    print(f"2 ranks / 1 rank: {speedup:.2f}x the styles a second, {kind} steps (target >= 1.7x)")
    with open(os.path.join(out, "mpi_style_scaling.json"), "w") as f:
        json.dump({"one": one, "two": two, "speedup": speedup, "steps": kind, "args": vars(a)}, f, indent=2)


if __name__ == "__main__":
    main()
