#!/usr/bin/env python3
"""Proof that the tests bite: each deliberate mistake below, applied alone to a clean copy of the committed
tree, must make at least one of the CTest entries it names fail.

usage: python3 tests/mutation_check.py [--work DIR] [--only NAME ...] [--list]

It checks out HEAD into DIR/src (a git worktree; DIR defaults to a new temporary folder, kept so that a
rerun with --work DIR reuses its build), builds it once (about 6 minutes on 2 cores), then for each mutation:
replaces its exact texts (each must occur exactly once), rebuilds the test targets it names, runs those
CTest entries, records which failed and their first failing assertion, and restores the file. Your own
checkout is never touched. Exit status 1 when a mutation survives (no named entry failed) or its text is no
longer found (the code moved: update the mutation).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

# Each mutation: a name, its file, edits (exact text -> replacement; each text must occur exactly once), the
# CTest entries expected to catch it (at least one must fail), and what it breaks.
MUTATIONS = [
    dict(name="sict-dv-sign", file="kernels/sict.cl",
         edits=[("vstore16(dv0, 0, d + 2 * E);", "vstore16(-dv0, 0, d + 2 * E);")],
         tests=["test_sict_dst", "test_style_stage_gradient"],
         what="SICT's channel attention backward: the sign of dV (its first 16 channels)"),
    dict(name="sict-attention-transposed", file="kernels/sict.cl",
         edits=[("const float16 q0 = vload16(0, r), q1 = vload16(1, r);\n  const float16 k0 = vload16(0, r + E), k1 = vload16(1, r + E);",
                 "const float16 q0 = vload16(0, r + E), q1 = vload16(1, r + E);\n  const float16 k0 = vload16(0, r), k1 = vload16(1, r);"),
                ("const float kj = r[E + j], vj = r[2 * E + j];\n    const float16 e0 = exp(fma(q0, (float16)kj, -m0))",
                 "const float kj = r[j], vj = r[2 * E + j];\n    const float16 e0 = exp(fma(q0, (float16)kj, -m0))")],
         tests=["test_sict_dst"],
         what="SICT's attention logits transposed (q_j k_i for q_i k_j), the per-point outer product read the wrong way"),
    dict(name="dst-bias-backward-dropped", file="lib/style/dst.cpp",
         edits=[("host::gemm(Trans::Yes, Trans::No, C, 1, R, 1.0f, dy.mem(), 0, C, ctx.acc.mem()",
                 "host::gemm(Trans::Yes, Trans::No, C, 1, R, 0.0f, dy.mem(), 0, C, ctx.acc.mem()")],
         tests=["test_sict_dst", "test_style_stage_gradient"],
         what="DST's backward without its adaptive-bias term (d mean = 0)"),
    dict(name="dst-transposed-transform", file="lib/style/dst.cpp",
         edits=[("host::gemm(Trans::Yes, Trans::No, E, C, E, 1.0f, code.T.mem()",
                 "host::gemm(Trans::No, Trans::No, E, C, E, 1.0f, code.T.mem()")],
         tests=["test_sict_dst"],
         what="DST's transformation T (made from the style's covariance) applied transposed (the covariance "
              "itself is symmetric: transposing it changes nothing)"),
    dict(name="dst-zero-std-guard-removed", file="kernels/dst.cl",
         edits=[("if (sd > 0.0f) g += dstd[j + k]", "g += dstd[j + k]")],
         tests=["test_dst_hard_cases"],
         what="DST's statistics backward divides by a zero std (a dead ReLU channel of a real style image)"),
    dict(name="content-weight-doubled", file="lib/train/style_losses.cpp",
         edits=[("v.content = w.content * scalar(nn::mse_forward(a, b));",
                 "v.content = 2 * w.content * scalar(nn::mse_forward(a, b));"),
                ("unsel(nn::mse_backward(a, b, w.content), out[K - 1], K - 1)",
                 "unsel(nn::mse_backward(a, b, 2 * w.content), out[K - 1], K - 1)")],
         tests=["test_style_model", "test_style_stage_gradient"],
         what="the style stage's content weight doubled, in the loss and its gradient alike (differences agree)"),
    dict(name="style-loss-mask-ignored", file="lib/train/style_losses.cpp",
         edits=[("const Tensor a = sel(out[t], t);", "const Tensor a = out[t];"),
                ("Tensor g = unsel(nn::style_loss_backward(a, style[size_t(t)], w.style), out[t], t);",
                 "Tensor g = nn::style_loss_backward(a, style[size_t(t)], w.style);")],
         tests=["test_style_stage_gradient"],
         what="the style loss over every position, not the positions the opacity mask keeps"),
    dict(name="composite-backward-no-background", file="kernels/composite.cl",
         edits=[("dacc[r] = (accumulate ? dacc[r] : 0.0f) - s;", "dacc[r] = (accumulate ? dacc[r] : 0.0f);")],
         tests=["test_composite_hard_cases", "test_density_stage_gradient", "test_render"],
         what="compositing's backward without the background's (1 - acc) term"),
    dict(name="feature-background-backward-dropped", file="lib/model/feature_field.cpp",
         edits=[("host::matmul(transparency, Trans::No, dfeat, Trans::No, dbg, 1.0f, 1.0f);", "(void)dbg;")],
         tests=["test_feature_stage_gradient"],
         what="the feature stage's background feature gets no gradient"),
    dict(name="nan-sigma-not-empty", file="kernels/composite.cl",
         edits=[("inline float od_of(float sigma, float delta) { return delta > 0.0f ? fmax(sigma * delta, 0.0f) : 0.0f; }",
                 "inline float od_of(float sigma, float delta) { return delta > 0.0f ? (sigma * delta < 0.0f ? 0.0f : sigma * delta) : 0.0f; }")],
         tests=["test_composite_hard_cases"],
         what="a NaN density no longer counts as empty space in compositing"),
    dict(name="consistency-pairs-averaged-over-all", file="lib/eval/consistency.cpp",
         edits=[("out.rmse = counted ? rmse_sum / counted : kNaN;",
                 "out.rmse = counted ? rmse_sum / double(range.warps.size()) : kNaN;")],
         tests=["test_consistency"],
         what="the consistency score divides by every pair, the one with no valid pixel included"),
    dict(name="lpips-channel-weight", file="lib/eval/lpips.cpp",
         edits=[("lin.push_back(Tensor::from_host(st.get(key, {channels}).data, {channels}, \"lpips \" + key));",
                 "auto w = st.get(key, {channels}).data;\n    if (l == 2) w[7] *= 1.5f;\n"
                 "    lin.push_back(Tensor::from_host(w, {channels}, \"lpips \" + key));")],
         tests=["test_lpips"],
         what="one channel weight of LPIPS's third linear head off by half"),
]


def run(cmd, cwd, env=None, log=None):
    p = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if log:
        with open(log, "a") as f:
            f.write(f"$ {' '.join(cmd)}\n{p.stdout}\n")
    return p.returncode, p.stdout


def targets_of(entries):
    # CTest entry -> its executable target: <suite>, <suite>_shared, <suite>_work_group share one binary.
    out = []
    for e in entries:
        t = re.sub(r"_(shared|work_group)$", "", e)
        if t.startswith("test_") and t not in out:
            out.append(t)
    return out


def first_errors(output, limit=2):
    lines = output.splitlines()
    found = []
    for i, line in enumerate(lines):
        if "ERROR:" in line:
            found.append(" ".join(l.strip() for l in lines[i:i + 3] if l.strip()))
            if len(found) == limit:
                break
    return found


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", help="folder for the checkout and its build (reused when given again)")
    ap.add_argument("--only", nargs="*", help="run only these mutations")
    ap.add_argument("--list", action="store_true", help="list the mutations and exit")
    args = ap.parse_args()
    if args.list:
        for m in MUTATIONS:
            print(f"{m['name']:32s} {m['file']:34s} named tests {', '.join(m['tests'])}: {m['what']}")
        return 0
    repo = subprocess.run(["git", "rev-parse", "--show-toplevel"], cwd=os.path.dirname(os.path.abspath(__file__)),
                          stdout=subprocess.PIPE, text=True, check=True).stdout.strip()
    work = os.path.abspath(args.work or tempfile.mkdtemp(prefix="stylerf_mutations_"))
    src, build, log = os.path.join(work, "src"), os.path.join(work, "build"), os.path.join(work, "mutations.log")
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=repo, stdout=subprocess.PIPE, text=True).stdout.strip()
    if os.path.isdir(src):
        run(["git", "checkout", "--detach", "--force", head], src, log=log)
    else:
        os.makedirs(work, exist_ok=True)
        rc, out = run(["git", "worktree", "add", "--detach", src, head], repo, log=log)
        if rc:
            print(out)
            return 2
    # The checkout sits elsewhere; its tests read ../shared beside the repository, and the weights from the
    # user's weights folder (STYLERF_WEIGHTS or ~/.cache/stylerf/weights, which set-up fills).
    shared = os.path.join(os.path.dirname(repo), "shared")
    if os.path.isdir(shared) and not os.path.exists(os.path.join(work, "shared")):
        os.symlink(shared, os.path.join(work, "shared"))
    env = dict(os.environ, STYLERF_CACHE_DIR=os.path.join(work, "cache"))
    print(f"checkout of {head[:10]} in {src}; log in {log}", flush=True)
    rc, out = run(["cmake", "-S", src, "-B", build, "-DCMAKE_BUILD_TYPE=Release"], src, env, log)
    if rc:
        print(out[-3000:])
        return 2
    t0 = time.time()
    rc, out = run(["cmake", "--build", build, "-j", str(os.cpu_count() or 2)], src, env, log)
    if rc:
        print(out[-3000:])
        return 2
    print(f"built in {time.time() - t0:.0f} s", flush=True)

    # A reused build may hold a mutant from an interrupted run: stamp every mutated file so it is rebuilt.
    for m in MUTATIONS:
        os.utime(os.path.join(src, m["file"]))
    chosen = [m for m in MUTATIONS if not args.only or m["name"] in args.only]
    results, bad = [], 0
    for m in chosen:
        path = os.path.join(src, m["file"])
        text = open(path).read()
        counts = [text.count(before) for before, _ in m["edits"]]
        if any(n != 1 for n in counts):
            results.append((m, None, [f"its texts occur {counts} times in {m['file']}: update the mutation"]))
            bad += 1
            continue
        mutated = text
        for before, after in m["edits"]:
            mutated = mutated.replace(before, after)
        shutil.copyfile(path, path + ".orig")
        try:
            with open(path, "w") as f:
                f.write(mutated)
            t0 = time.time()
            rc, out = run(["cmake", "--build", build, "-j", str(os.cpu_count() or 2), "--target"] + targets_of(m["tests"]),
                          src, env, log)
            if rc:
                results.append((m, ["(build failed)"], first_errors(out) or [out[-500:]]))
                continue
            regex = "^(" + "|".join(m["tests"]) + ")$"
            rc, out = run(["ctest", "--output-on-failure", "-R", regex], build, env, log)
            failed = re.findall(r"\d+ - (\S+) \(Failed|\d+ - (\S+) \(SEGFAULT|\d+ - (\S+) \(Subprocess", out)
            failed = [next(x for x in f if x) for f in failed]
            if rc == 0 or not failed:
                bad += 1
                results.append((m, [], ["SURVIVED: every named entry passed"]))
            else:
                results.append((m, failed, first_errors(out)))
            print(f"{m['name']}: {'caught by ' + ', '.join(failed) if failed else 'SURVIVED'} "
                  f"({time.time() - t0:.0f} s)", flush=True)
        finally:
            shutil.move(path + ".orig", path)
            # The restored text is older than the objects just built from the mutant: stamp it new, or make
            # would keep the mutant in the build for every later mutation.
            os.utime(path)

    print("\n| mutation | file | caught by | first failing assertion |\n|---|---|---|---|")
    for m, failed, errors in results:
        caught = ", ".join(failed) if failed else "**survived**" if failed is not None else "**not applied**"
        print(f"| {m['name']} | {m['file']} | {caught} | {'; '.join(errors)[:300]} |")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
