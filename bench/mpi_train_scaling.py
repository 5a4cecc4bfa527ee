#!/usr/bin/env python3
"""What a second rank buys in training: each stage's same step (2 sub-batches: ray slices, patches or styles)
taken by one rank with one core and by two ranks with one core each (PoCL's thread count per device,
POCL_MAX_PTHREAD_COUNT=1, each rank bound to its core), one run after the other on an otherwise idle machine.
Steps a second are the steps over the training seconds each run prints (kernel builds and loading not
counted); the gradient's bytes a step and the exchange's milliseconds a step are what the run prints.

    python3 bench/mpi_train_scaling.py --stylerf build/stylerf --scene SCENE --density D.ckpt \\
        --features F.ckpt --styles STYLES [--stages density,features,style] [-o OUT]

Writes OUT/mpi_train_scaling.json.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time


def stage_args(a, stage: str) -> tuple:
    """The stage's command (its steps fixed) and its flag for the sub-batches a step."""
    if stage == "density":
        return (["train-density", "--scene", a.scene, "--iters", str(a.density_steps), "--log-every", "50"],
                "--batch-slices")
    if stage == "features":
        return (["train-features", "--density", a.density, "--iters", str(a.feature_steps), "--log-every", "10",
                 "--eval-views", "0"], "--patches-per-step")
    return (["train-style", "--features", a.features, "--styles", a.styles, "--iters", str(a.style_steps),
             "--warm-start", "0", "--eval-every", "0", "--log-every", "2"], "--styles-per-step")


def run(stylerf: str, ranks: int, args: list, out: str) -> dict:
    env = dict(os.environ, POCL_MAX_PTHREAD_COUNT="1", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = ["mpirun", "-np", str(ranks), "--bind-to", "core", stylerf, *args, "--ckpt-every", "0", "--force", "-o", out]
    t = time.monotonic()
    r = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.monotonic() - t
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{r.stdout}")
    trained = re.search(r"^trained (\d+) iterations in ([0-9.]+) s", r.stdout, re.M)
    sync = re.search(r"([0-9.]+) MB of gradient a step, ([0-9.]+) ms a step", r.stdout)
    if not trained or not sync:
        sys.exit(f"no training time or gradient exchange in the output of {' '.join(cmd)}:\n{r.stdout}")
    steps, seconds = int(trained.group(1)), float(trained.group(2))
    return {"ranks": ranks, "steps": steps, "train_s": seconds, "steps_per_s": steps / seconds, "wall_s": wall,
            "gradient_mb": float(sync.group(1)), "exchange_ms": float(sync.group(2))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stylerf", required=True)
    ap.add_argument("--scene", required=True, help="the scene the density checkpoint was trained on")
    ap.add_argument("--density", required=True, help="density checkpoint (the feature stage's input)")
    ap.add_argument("--features", required=True, help="feature checkpoint (the style stage's input)")
    ap.add_argument("--styles", required=True, help="folder of style images")
    ap.add_argument("--stages", default="density,features,style")
    ap.add_argument("--density-steps", type=int, default=100)
    ap.add_argument("--feature-steps", type=int, default=30)
    ap.add_argument("--style-steps", type=int, default=12)
    ap.add_argument("-o", "--out", default=None)
    a = ap.parse_args()
    out = a.out or tempfile.mkdtemp(prefix="stylerf-mpi-train-")
    os.makedirs(out, exist_ok=True)
    rows = {}
    for stage in a.stages.split(","):
        cmd, flag = stage_args(a, stage)
        one = run(a.stylerf, 1, [*cmd, flag, "2"], os.path.join(out, stage + "-one.ckpt"))
        two = run(a.stylerf, 2, cmd, os.path.join(out, stage + "-two.ckpt"))
        rows[stage] = {"one": one, "two": two, "speedup": two["steps_per_s"] / one["steps_per_s"]}
        print(f"{stage}: 2 sub-batches a step; 1 rank {one['steps_per_s']:.3f} steps/s, 2 ranks "
              f"{two['steps_per_s']:.3f} steps/s: {rows[stage]['speedup']:.2f}x; gradient {two['gradient_mb']:.1f} MB "
              f"a step, exchanged in {two['exchange_ms']:.1f} ms (2 ranks; {one['exchange_ms']:.1f} ms summing 2 "
              f"sub-batches on 1)", flush=True)
    with open(os.path.join(out, "mpi_train_scaling.json"), "w") as f:
        json.dump({"stages": rows, "args": vars(a)}, f, indent=2)


if __name__ == "__main__":
    main()
