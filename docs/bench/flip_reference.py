#!/usr/bin/env python3
"""Reference FLIP values for envis's FLIP implementation (src/bench/flip.rs), from NVIDIA's
`flip-evaluator` package (pip install flip-evaluator numpy). Writes tests/data/flip_reference.json;
tests/core/bench.rs rebuilds the same images from the same formulas and compares.

Usage: python3 docs/bench/flip_reference.py [tests/data/flip_reference.json]
"""
import json, math, sys
import numpy as np
import flip_evaluator as fe

W, H = 23, 19

def hdr_reference():
    img = np.zeros((H, W, 3), np.float32)
    for y in range(H):
        for x in range(W):
            if (x - 12) ** 2 + (y - 10) ** 2 > 100:
                continue  # black background, as around the sphere
            for c in range(3):
                img[y, x, c] = 4 * (0.5 + 0.5 * math.sin(0.7 * x + 1.3 * y + 2 * c)) ** 3
    img[7, 5, :] += 1000.0  # a highlight: many exposures
    return img

def hdr_test(ref, amp):
    t = np.zeros_like(ref)
    for y in range(H):
        for x in range(W):
            for c in range(3):
                t[y, x, c] = max(0.0, float(ref[y, x, c]) * (1 + amp * math.sin(2.1 * x * x + 3.7 * y + c)))
    return t

def ldr_pair():
    r = np.zeros((H, W, 3), np.float32)
    t = np.zeros((H, W, 3), np.float32)
    for y in range(H):
        for x in range(W):
            for c in range(3):
                v = 0.5 + 0.4 * math.sin(0.3 * x - 0.5 * y + c)
                r[y, x, c] = v
                t[y, x, c] = min(1.0, max(0.0, v + 0.15 * math.sin(1.7 * x * y + c)))
    return r, t

cases = []
ref = hdr_reference()
for amp in [0.0, 0.1, 0.5]:
    err, mean, params = fe.evaluate(ref, hdr_test(ref, amp), "HDR", applyMagma=False)
    cases.append({"kind": "hdr", "amp": amp, "mean": float(mean), "map": [float(v) for v in err.reshape(-1)],
                  "start": params["startExposure"], "stop": params["stopExposure"], "count": params["numExposures"]})
r, t = ldr_pair()
err, mean, params = fe.evaluate(r, t, "LDR", applyMagma=False)
cases.append({"kind": "ldr", "amp": 0.15, "mean": float(mean), "map": [float(v) for v in err.reshape(-1)]})
out = sys.argv[1] if len(sys.argv) > 1 else "tests/data/flip_reference.json"
json.dump({"width": W, "height": H, "generator": "flip-evaluator " + __import__("importlib.metadata").metadata.version("flip-evaluator"), "ppd": float(params["ppd"]), "cases": cases}, open(out, "w"))
print(out, [(c["kind"], c["amp"], round(c["mean"], 5)) for c in cases])
