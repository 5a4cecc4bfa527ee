#!/usr/bin/env python3
"""Seeds for the fuzz harnesses (fuzz/corpus/<harness>/): small valid files of each format, written with
the standard library only, so the fuzzer starts from inputs that reach deep into each reader."""
import json, os, struct, shutil, sys

root = os.path.dirname(os.path.abspath(__file__))
corpus = os.path.join(root, "corpus")


def put(harness, name, data):
    d = os.path.join(corpus, harness)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def npy(shape, values, descr="<f4"):
    header = "{'descr': '%s', 'fortran_order': False, 'shape': (%s), }" % (
        descr, "".join("%d, " % s for s in shape) if len(shape) > 1 else "%d," % shape[0])
    pad = 64 - (10 + len(header) + 1) % 64
    header = header + " " * pad + "\n"
    fmt = {"<f4": "f", "<f8": "d"}[descr]
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + struct.pack(
        "<%d%s" % (len(values), fmt), *values)


def fnv_checksum(tensors):
    h = 1469598103934665603
    def mix(b):
        nonlocal h
        for x in b:
            h ^= x
            h = (h * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    for name in sorted(tensors):
        shape, vals = tensors[name]
        mix(name.encode())
        for d in shape:
            mix(struct.pack("<q", d))
        mix(struct.pack("<%df" % len(vals), *vals))
    return "%016x" % h


def safetensors(tensors, metadata=None):
    header, blobs, off = {}, [], 0
    for name in sorted(tensors):
        shape, vals = tensors[name]
        blob = struct.pack("<%df" % len(vals), *vals)
        header[name] = {"dtype": "F32", "shape": shape, "data_offsets": [off, off + len(blob)]}
        blobs.append(blob)
        off += len(blob)
    if metadata:
        header["__metadata__"] = metadata
    h = json.dumps(header).encode()
    h += b" " * ((8 - len(h) % 8) % 8)
    return struct.pack("<Q", len(h)) + h + b"".join(blobs)


put("npy", "poses.npy", npy([2, 17], [float(i) for i in range(34)]))
put("npy", "f64.npy", npy([3], [1.0, 2.0, 3.0], "<f8"))
t = {"a": ([2, 2], [1.0, 2.0, 3.0, 4.0]), "b": ([3], [0.5, 0.25, 0.125])}
put("safetensors", "two.safetensors", safetensors(t, {"note": "seed"}))
meta = {"stylerf.format": "stylerf-checkpoint", "stylerf.version": "1", "stylerf.kind": "density",
        "stylerf.meta": json.dumps({"scene": {"name": "x"}}), "stylerf.checksum": fnv_checksum(t)}
put("checkpoint", "density.ckpt", safetensors(t, meta))
for f in ["rgb16.png", "grey1x1.png", "cmyk.jpg"]:
    put("image", f, open(os.path.join(root, "..", "tests", "data", "styles", f), "rb").read())
frames = [{"file_path": "./train/r_%d" % i,
           "transform_matrix": [[1, 0, 0, 0.1 * i], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]} for i in range(2)]
put("scene_json", "transforms.json", json.dumps({"camera_angle_x": 0.7, "frames": frames}).encode())
# COLMAP binary model (fuzz_colmap_bin: first byte 0 cameras.bin, 1 images.bin, 2 points3D.bin).
cams = struct.pack("<Q", 2) + struct.pack("<IiQQ4d", 1, 1, 4, 3, 3.0, 3.0, 2.0, 1.5) + \
    struct.pack("<IiQQ3d", 2, 0, 4, 3, 3.0, 2.0, 1.5)
imgs = struct.pack("<Q", 2)
for i in range(2):
    imgs += struct.pack("<I7dI", i + 1, 1, 0, 0, 0, 0.1 * i, 0, 4, 1 + i) + b"frame_%d.png\0" % i
    imgs += struct.pack("<Q", 2) + struct.pack("<ddq", 1.0, 1.0, 1) + struct.pack("<ddq", 2.0, 1.0, -1)
pts = struct.pack("<Q", 1) + struct.pack("<Q3d3BdQ", 1, 0.0, 0.0, 0.0, 10, 20, 30, 0.5, 2) + struct.pack("<4I", 1, 0, 2, 0)
put("colmap_bin", "cameras.bin", b"\x00" + cams)
put("colmap_bin", "images.bin", b"\x01" + imgs)
put("colmap_bin", "points3D.bin", b"\x02" + pts)
ns = {"camera_model": "OPENCV", "fl_x": 3.0, "fl_y": 3.0, "cx": 1.0, "cy": 1.0, "w": 2, "h": 2,
      "k1": 0, "k2": 0, "p1": 0, "p2": 0,
      "applied_transform": [[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0]],
      "frames": [{"file_path": "images/frame_%d.png" % i,
                  "transform_matrix": [[1, 0, 0, 0.1 * i], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]} for i in range(2)]}
put("nerfstudio_json", "transforms.json", json.dumps(ns).encode())
print("corpus written to", corpus)
