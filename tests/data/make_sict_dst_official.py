#!/usr/bin/env python3
"""Reference values of SICT and DST from the authors' own module, for tests/test_sict_dst.cpp.

Runs StyleRF's models/styleModules.py (SimpleLinearStylizer) as it is, in float64, on parameters and
inputs given by a closed-form formula (below; tests/closed_form_values.hpp is the same formula in C++),
and writes sict_dst_official.safetensors beside this script:

  - SICT (transform_content_3D) in training mode (batch statistics) and the running statistics after
    that call; in evaluation mode with given running statistics; with q/k weights times 128 (logits
    ~1e4, a saturated softmax); and on one point alone (the authors' LearnableIN passes a batch of one
    point through un-normalised: see the README);
  - DST: the style's mean, std and T (get_style_mean_std_matrix) and the styled map (transfer_style_2D)
    with its adaptive bias mean * acc;
  - the gradients of loss = <sict_train, g_sict> + <dst, g_dst> with respect to the three inputs and every
    parameter.

Tensors are in PyTorch's layouts ([1, C, N] features, Conv1d weights [out, in, 1], Linear [out, in]). A
gradient with more than FULL_LIMIT entries is stored as its projection onto a formula direction (seed
"<name>:dir_seed"), the largest magnitude, the direction's L2 norm and SAMPLES entries at stored indices.

Needs torch, numpy and safetensors (never the project itself). Usage:
  make_sict_dst_official.py STYLEMODULES_PY COMMIT
STYLEMODULES_PY: models/styleModules.py of github.com/Kunhao-Liu/StyleRF at COMMIT.
"""

import hashlib
import os
import sys

import numpy as np
import torch
from safetensors.numpy import save_file

P, L, R = 32, 32, 16  # content points, style positions, rays
C, E = 256, 32
FULL_LIMIT = 4096
SAMPLES = 64
LOGIT_SCALE = 128.0  # a power of two: the scaled float32 weights are exact on both sides

MASK64 = (1 << 64) - 1


def splitmix64(z):
    """splitmix64's finaliser on uint64 arrays (wrapping arithmetic)."""
    z = z + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def bits(seed, n):
    with np.errstate(over="ignore"):
        base = splitmix64(np.array([seed], dtype=np.uint64))[0]
        return splitmix64(base + np.arange(n, dtype=np.uint64))


def uniform(seed, n, half_width):
    """n values in [-half_width, half_width) on a grid of half_width / 2^23: exact in float32 when
    half_width is a power of two."""
    k = (bits(seed, n) >> np.uint64(40)).astype(np.int64) - (1 << 23)
    return k.astype(np.float64) * (half_width / float(1 << 23))


def features(seed, channels, n):
    """[channels, n] features: per channel, noise times 2^e_c (e_c in -2..1) plus an offset in [-4, 4),
    summed exactly in double and rounded once to float32."""
    noise = uniform(seed, channels * n, 1.0).reshape(channels, n)
    expo = (bits(seed + 1, channels) >> np.uint64(62)).astype(np.int64) - 2
    offset = uniform(seed + 2, channels, 4.0)
    return (noise * np.ldexp(1.0, expo)[:, None] + offset[:, None]).astype(np.float32)


def f32(seed, shape, half_width):
    n = int(np.prod(shape))
    return uniform(seed, n, half_width).astype(np.float32).reshape(shape)


# Parameters: name in the authors' module -> (seed, half width of the uniform).
PARAMS = {
    "q_embed.weight": (101, 2.0 ** -3), "q_embed.bias": (102, 2.0 ** -4),
    "k_embed.weight": (103, 2.0 ** -3), "k_embed.bias": (104, 2.0 ** -4),
    "v_embed.weight": (105, 2.0 ** -4), "v_embed.bias": (106, 2.0 ** -4),
    "unzipper.weight": (107, 2.0 ** -3),
    "s_net.0.0.weight": (108, 2.0 ** -4), "s_net.0.0.bias": (109, 2.0 ** -4),
    "s_net.1.0.weight": (110, 2.0 ** -3), "s_net.1.0.bias": (111, 2.0 ** -3),
    "s_net.2.weight": (112, 2.0 ** -3), "s_net.2.bias": (113, 2.0 ** -3),
    "s_fc.weight": (114, 2.0 ** -2), "s_fc.bias": (115, 2.0 ** -4),
}
# Inputs: seeds (tests/closed_form_values.hpp uses the same).
SEED_CONTENT, SEED_STYLE, SEED_C32, SEED_ACC = 201, 204, 207, 208
SEED_G_SICT, SEED_G_DST, SEED_RUN_MEAN, SEED_RUN_VAR = 209, 210, 211, 212
SEED_DIR0, SEED_IDX0 = 300, 400


def acc_values():
    """[R] accumulated opacities in [0, 1); the first two rays are transparent."""
    a = (uniform(SEED_ACC, R, 0.5) + 0.5).astype(np.float32)
    a[:2] = 0.0
    return a


def load_module(path):
    ns = {"__name__": "styleModules"}
    with open(path) as f:
        src = f.read()
    exec(compile(src, path, "exec"), ns)
    return ns, hashlib.sha256(src.encode()).hexdigest()


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    path, commit = sys.argv[1], sys.argv[2]
    ns, src_sha = load_module(path)
    torch.manual_seed(0)
    m = ns["SimpleLinearStylizer"](input_dim=C, embed_dim=E, n_layers=3).double()
    state = m.state_dict()
    for name, (seed, hw) in PARAMS.items():
        t = state[name]
        t.copy_(torch.from_numpy(f32(seed, tuple(t.shape), hw).astype(np.float64)))
    # Every parameter is set from the formula (the IN has only buffers).
    assert set(n for n, _ in m.named_parameters()) == set(PARAMS), sorted(n for n, _ in m.named_parameters())

    d = lambda a: torch.from_numpy(np.asarray(a, dtype=np.float64))
    x = d(features(SEED_CONTENT, C, P))[None].requires_grad_(True)
    s = d(features(SEED_STYLE, C, L))[None].requires_grad_(True)
    c32 = d(f32(SEED_C32, (1, E, R), 1.0)).requires_grad_(True)
    acc = d(acc_values())
    g_sict = d(f32(SEED_G_SICT, (1, E, P), 1.0))
    g_dst = d(f32(SEED_G_DST, (1, C, R), 1.0))

    out = {}
    m.train()
    sict_train = m.transform_content_3D(x)
    out["out.running_mean_after"] = m.IN.IN.running_mean.detach().clone()
    out["out.running_var_after"] = m.IN.IN.running_var.detach().clone()
    code = m.get_style_mean_std_matrix(s)
    dst = m.transfer_style_2D(code, c32, acc)
    out["out.sict_train"] = sict_train
    out["out.style_mean"] = code[0]
    out["out.style_std"] = code[1]
    out["out.style_T"] = code[2]
    out["out.dst"] = dst
    loss = (sict_train * g_sict).sum() + (dst * g_dst).sum()
    loss.backward()
    grads = {"grad.content_points": x.grad, "grad.style_features": s.grad, "grad.composited_32": c32.grad}
    for name, p in m.named_parameters():
        grads["grad." + name] = p.grad

    with torch.no_grad():
        m.eval()
        m.IN.IN.running_mean.copy_(d(f32(SEED_RUN_MEAN, (C,), 1.0)))
        m.IN.IN.running_var.copy_(d((uniform(SEED_RUN_VAR, C, 0.5) + 1.0).astype(np.float32)))
        out["out.sict_eval"] = m.transform_content_3D(x)
        out["out.sict_one_point"] = m.transform_content_3D(x[:, :, :1])
        m.q_embed.weight.mul_(LOGIT_SCALE)
        m.k_embed.weight.mul_(LOGIT_SCALE)
        out["out.sict_eval_large_logits"] = m.transform_content_3D(x)

    # transform_content_3D returns a transposed view: store the logical (C-order) layout.
    tensors = {k: np.ascontiguousarray(v.detach().numpy(), dtype=np.float32) for k, v in out.items()}
    for k, (name, g) in enumerate(sorted(grads.items())):
        g = g.detach().numpy().astype(np.float64)
        if g.size <= FULL_LIMIT:
            tensors[name] = np.ascontiguousarray(g, dtype=np.float32)
            continue
        flat = g.reshape(-1)
        dir_seed = SEED_DIR0 + k
        direction = uniform(dir_seed, flat.size, 1.0)
        idx = (bits(SEED_IDX0 + k, SAMPLES) % np.uint64(flat.size)).astype(np.int64)
        tensors[name + ":proj"] = np.array([direction @ flat], dtype=np.float32)
        tensors[name + ":dir_seed"] = np.array([dir_seed], dtype=np.float32)
        tensors[name + ":dir_norm"] = np.array([np.linalg.norm(direction)], dtype=np.float32)
        tensors[name + ":absmax"] = np.array([np.abs(flat).max()], dtype=np.float32)
        tensors[name + ":idx"] = idx.astype(np.float32)
        tensors[name + ":at_idx"] = flat[idx].astype(np.float32)
        tensors[name + ":shape"] = np.array(g.shape, dtype=np.float32)

    # What the one-point output shows: the module's LearnableIN skips the norm for a batch of one point.
    one = out["out.sict_one_point"].detach()
    col0 = out["out.sict_eval"].detach()[:, :, :1]
    print("one point alone vs column 0 of the batch: max |diff| = %.3g" % (one - col0).abs().max().item())

    meta = {
        "source": "github.com/Kunhao-Liu/StyleRF models/styleModules.py (SimpleLinearStylizer)",
        "commit": commit,
        "source_sha256": src_sha,
        "torch": torch.__version__,
        "numpy": np.__version__,
        "dtype": "computed in float64, stored as float32",
        "sizes": "P=%d L=%d R=%d" % (P, L, R),
        "loss": "<out.sict_train, g_sict> + <out.dst, g_dst>",
    }
    dest = os.path.join(os.path.dirname(os.path.abspath(__file__)), "sict_dst_official.safetensors")
    save_file(tensors, dest, metadata=meta)
    print("wrote %s: %d tensors, %d bytes" % (dest, len(tensors), os.path.getsize(dest)))


if __name__ == "__main__":
    main()
