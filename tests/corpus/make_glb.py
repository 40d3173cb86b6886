#!/usr/bin/env python3
"""Writes the glTF corpus files of tests/corpus (run from this folder; standard library only).

- tetra_nodes.glb: a tetrahedron (u16 indices, POSITION + NORMAL) instanced by two nodes, one of
  them a child with a translation and a scale: the loader must apply node transforms.
- tetra_no_normals.glb: the same mesh without NORMAL (normals are computed), one node.
- huge_count.glb: a POSITION accessor claiming 2^31 - 1 elements in a 48-byte buffer: must be
  refused with an error before anything is allocated.
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
