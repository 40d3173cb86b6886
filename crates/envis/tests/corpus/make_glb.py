#!/usr/bin/env python3
"""Writes the glTF corpus files of tests/corpus (run from this folder; standard library only).

- tetra_nodes.glb: a tetrahedron (u16 indices, POSITION + NORMAL) instanced by two nodes, one of
  them a child with a translation and a scale: the loader must apply node transforms.
- tetra_no_normals.glb: the same mesh without NORMAL (normals are computed), one node.
- huge_count.glb: a POSITION accessor claiming 2^31 - 1 elements in a 48-byte buffer: must be
  refused with an error before anything is allocated.
- ../../assets/models/skinned_plate.glb: a 1 x 1 plate at height 0.15 (facing up) skinned wholly to
  one joint node at x = -1.8, with one morph target moving it by +3.6 along x (weight 0): the Bevy
  test of a glTF skin and morph target (tests/gpu/bevy_pose.rs) loads it through Bevy's glTF
  loader, which reads only under assets/.
"""
import json
import struct

P = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
N = [(-0.577, -0.577, -0.577), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
IDX = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]


def glb(doc, bin_bytes):
    while len(bin_bytes) % 4:
        bin_bytes += b"\0"
    js = json.dumps(doc, separators=(",", ":")).encode()
    while len(js) % 4:
        js += b" "
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(bin_bytes), b"BIN\0") + bin_bytes
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def tetra(with_normals, nodes, count=None):
    pos = b"".join(struct.pack("<3f", *p) for p in P)
    nrm = b"".join(struct.pack("<3f", *n) for n in N)
    idx = struct.pack("<12H", *IDX)
    data = pos + (nrm if with_normals else b"") + idx
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 48}]
    acc = [{"bufferView": 0, "componentType": 5126, "count": count or 4, "type": "VEC3",
            "min": [0, 0, 0], "max": [1, 1, 1]}]
    attrs = {"POSITION": 0}
    off = 48
    if with_normals:
        views.append({"buffer": 0, "byteOffset": off, "byteLength": 48})
        acc.append({"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"})
        attrs["NORMAL"] = 1
        off += 48
    views.append({"buffer": 0, "byteOffset": off, "byteLength": 24})
    acc.append({"bufferView": len(views) - 1, "componentType": 5123, "count": 12, "type": "SCALAR"})
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(data)}],
        "bufferViews": views,
        "accessors": acc,
        "meshes": [{"primitives": [{"attributes": attrs, "indices": len(acc) - 1}]}],
        "nodes": nodes,
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    return glb(doc, data)


two_nodes = [{"mesh": 0, "children": [1]}, {"mesh": 0, "translation": [3, 0, 0], "scale": [2, 2, 2]}]
open("tetra_nodes.glb", "wb").write(tetra(True, two_nodes))
open("tetra_no_normals.glb", "wb").write(tetra(False, [{"mesh": 0}]))
open("huge_count.glb", "wb").write(tetra(True, [{"mesh": 0}], count=2**31 - 1))


def skinned_plate():
    """A plate skinned to one joint, with one morph target (see the module's docstring)."""
    corners = [(-0.5, 0.15, -0.5), (0.5, 0.15, -0.5), (0.5, 0.15, 0.5), (-0.5, 0.15, 0.5)]
    parts = [
        ("POSITION", b"".join(struct.pack("<3f", *c) for c in corners), 5126, "VEC3"),
        ("NORMAL", struct.pack("<3f", 0, 1, 0) * 4, 5126, "VEC3"),
        ("JOINTS_0", struct.pack("<4H", 0, 0, 0, 0) * 4, 5123, "VEC4"),
        ("WEIGHTS_0", struct.pack("<4f", 1, 0, 0, 0) * 4, 5126, "VEC4"),
        ("target", struct.pack("<3f", 3.6, 0, 0) * 4, 5126, "VEC3"),
        ("indices", struct.pack("<6H", 0, 2, 1, 0, 3, 2), 5123, "SCALAR"),
    ]
    data, views, acc = b"", [], []
    for name, raw, component, kind in parts:
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(raw)})
        a = {"bufferView": len(views) - 1, "componentType": component, "type": kind,
             "count": 6 if name == "indices" else 4}
        if name == "POSITION":
            a["min"], a["max"] = [-0.5, 0.15, -0.5], [0.5, 0.15, 0.5]
        if name == "target":
            a["min"], a["max"] = [3.6, 0, 0], [3.6, 0, 0]
        acc.append(a)
        data += raw
    attrs = {name: i for i, (name, *_) in enumerate(parts[:4])}
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(data)}],
        "bufferViews": views,
        "accessors": acc,
        "meshes": [{"primitives": [{"attributes": attrs, "indices": 5, "targets": [{"POSITION": 4}]}],
                    "weights": [0.0]}],
        "skins": [{"joints": [1]}],
        "nodes": [{"mesh": 0, "skin": 0}, {"name": "joint", "translation": [-1.8, 0, 0]}],
        "scenes": [{"nodes": [0, 1]}],
        "scene": 0,
    }
    return glb(doc, data)


open("../../assets/models/skinned_plate.glb", "wb").write(skinned_plate())
