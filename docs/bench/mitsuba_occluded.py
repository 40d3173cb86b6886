"""`mitsuba_compare.py --scene FILE`: envis (CPU, a shadow ray per sample) against Mitsuba 3's
`direct` integrator on a scene file of diffuse spheres, planes and glTF meshes, in one sitting.

Reported (JSON, on stdout and in --out):
- `relmse`: relMSE of luminance, mean of (x - r)^2 / (r^2 + 1e-2), over interior pixels (the
  3x3 neighbourhood sees one shape: away from silhouettes, since Mitsuba jitters within the pixel
  and envis shades its centre), against Mitsuba converged (`direct`, 1 emitter + 1 BSDF sample,
  --ref-spp samples per pixel). For envis at 32 light + 32 BRDF samples and for Mitsuba at 32
  spp of 1 + 1, each the mean over --seeds runs. Target: envis <= Mitsuba.
- `contact`: for each sphere resting on a plane, the mean luminance of the ground 0.8 to 1.2
  radii from its contact point over that of open ground (every object's centre over 2 units plus
  its size away), in envis's mean image and in the converged render. Target: within 15%.
- `speed`: samples per second, (pixels that see geometry) x 64 / shading seconds, envis's median
  over the runs and Mitsuba's (32 + 32 samples at 1 spp, median of 3 after a warm-up) on all
  cores. Target: envis >= 3x.
The map (the scene's, or --env) is clamped to >= 0 and written as float32 EXR for both: envis
clamps negative texels, Mitsuba would not.
"""
import json, os, re, struct, subprocess, tempfile, time, tomllib

import numpy as np
import mitsuba as mi
import drjit as dr

T = mi.ScalarTransform4f


def read_glb(path):
    """Positions, normals (or None) and triangles of every triangle primitive of a .glb's default
    scene, node transforms applied (as envis's loader does)."""
    data = open(path, "rb").read()
    n = struct.unpack_from("<I", data, 12)[0]
    js = json.loads(data[20:20 + n])
    binary = data[20 + n + 8:]

    def accessor(i):
        acc = js["accessors"][i]
        view = js["bufferViews"][acc["bufferView"]]
        comps = {"SCALAR": 1, "VEC3": 3}[acc["type"]]
        dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[acc["componentType"]]
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        stride = view.get("byteStride", comps * np.dtype(dtype).itemsize)
        raw = np.frombuffer(binary, np.uint8, count=stride * (acc["count"] - 1) + comps * np.dtype(dtype).itemsize, offset=start)
        rows = [np.frombuffer(raw[k * stride:k * stride + comps * np.dtype(dtype).itemsize], dtype) for k in range(acc["count"])]
        return np.array(rows)

    def local(node):
        if "matrix" in node:
            return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
        m = np.eye(4)
        x, y, z, w = node.get("rotation", [0, 0, 0, 1])
        m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        m[:3, :3] = m[:3, :3] * np.array(node.get("scale", [1, 1, 1]))
        m[:3, 3] = node.get("translation", [0, 0, 0])
        return m

    P, N, F = [], [], []

    def visit(i, parent):
        node = js["nodes"][i]
        m = parent @ local(node)
        for prim in js["meshes"][node["mesh"]]["primitives"] if "mesh" in node else []:
            if prim.get("mode", 4) != 4:
                continue
            p = accessor(prim["attributes"]["POSITION"]).astype(np.float64)
            nrm = accessor(prim["attributes"]["NORMAL"]).astype(np.float64) if "NORMAL" in prim["attributes"] else None
            idx = accessor(prim["indices"]).reshape(-1) if "indices" in prim else np.arange(len(p))
            base = sum(len(q) for q in P)
            P.append(p @ m[:3, :3].T + m[:3, 3])
            if nrm is not None:
                nn = nrm @ np.linalg.inv(m[:3, :3])
                N.append(nn / np.linalg.norm(nn, axis=1, keepdims=True))
            F.append(idx.reshape(-1, 3).astype(np.int64) + base)
        for c in node.get("children", []):
            visit(c, m)

    for i in js["scenes"][js.get("scene", 0)]["nodes"]:
        visit(i, np.eye(4))
    normals = np.concatenate(N) if len(N) == len(P) else None
    return np.concatenate(P), normals, np.concatenate(F)


def write_obj(path, p, nrm, f):
    with open(path, "w") as o:
        o.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in p)
        if nrm is not None:
            o.writelines(f"vn {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in nrm)
            o.writelines(f"f {a}//{a} {b}//{b} {c}//{c}\n" for a, b, c in f + 1)
        else:
            o.writelines(f"f {a} {b} {c}\n" for a, b, c in f + 1)


def placement(o):
    """An object's transform as envis builds it: translate, rotate (X, then Y, then Z, intrinsic:
    glam's EulerRot::XYZ), scale."""
    rx, ry, rz = o.get("rotation", [0, 0, 0])
    return T().translate(o.get("position", [0, 0, 0])) @ T().rotate([1, 0, 0], rx) @ T().rotate([0, 1, 0], ry) @ T().rotate([0, 0, 1], rz)


def rotation(o):
    """The rotation alone, as a numpy matrix (the plane's normal)."""
    m = np.array(placement({"rotation": o.get("rotation", [0, 0, 0])}).matrix, dtype=np.float64)
    return m[:3, :3]


def mitsuba_scene(sc, base, env_path, tmp):
    c = sc["camera"]
    scene = {
        "type": "scene",
        "sensor": {
            "type": "perspective", "fov": c.get("fov", 40.0), "fov_axis": "y",
            "to_world": T().look_at(origin=c["position"], target=c["target"], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": W, "height": W, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent"},
        },
        "env": {"type": "envmap", "filename": env_path},
    }
    for i, o in enumerate(sc["object"]):
        m = o.get("material", {})
        if m.get("type", "diffuse") != "diffuse":
            raise SystemExit(f"object {i + 1}: only diffuse materials compare one to one")
        albedo = m.get("albedo", 0.8)
        rgb = [albedo] * 3 if isinstance(albedo, (int, float)) else albedo
        bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": rgb}}
        s = o.get("scale", 1.0)
        if o["shape"] == "sphere":
            shape = {"type": "sphere", "center": o.get("position", [0, 0, 0]), "radius": o.get("radius", 1.0) * s}
        elif o["shape"] == "plane":
            half = 0.5 * o.get("size", 10.0) * s
            # Mitsuba's rectangle is [-1, 1]^2 of the XY plane facing +Z; envis's plane is XZ facing +Y.
            shape = {"type": "rectangle", "to_world": placement(o) @ T().rotate([1, 0, 0], -90) @ T().scale([half, half, 1])}
        elif o["shape"] == "gltf":
            obj = os.path.join(tmp, f"mesh{i}.obj")
            write_obj(obj, *read_glb(os.path.join(base, o["path"])))
            shape = {"type": "obj", "filename": obj, "to_world": placement(o) @ T().scale(s)}
        else:
            raise SystemExit(f"object {i + 1}: shape {o['shape']} is not compared (sphere, plane, gltf)")
        shape["bsdf"] = bsdf
        scene[f"shape{i}"] = shape
    return mi.load_dict(scene)


def luminance(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def render(scene, integrator, spp, seed):
    t = time.perf_counter()
    img = mi.render(scene, integrator=integrator, spp=spp, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    return np.array(img, dtype=np.float64)[..., :3], time.perf_counter() - t


def direct(e, b):
    return mi.load_dict({"type": "direct", "emitter_samples": e, "bsdf_samples": b})


def run(a):
    global W
    W = a.size
    path = os.path.abspath(a.scene)
    text = open(path).read()
    sc = tomllib.loads(text)
    base = os.path.dirname(path)
    tmp = tempfile.mkdtemp(prefix="envis-mitsuba-")
    # The map, clamped to >= 0, as float32 EXR for both renderers.
    src = a.env or os.path.join(base, sc["environment"]["source"])
    env = np.maximum(np.array(mi.Bitmap(src), dtype=np.float32)[..., :3], 0.0)
    env_path = os.path.join(tmp, "env.exr")
    mi.Bitmap(env).write(env_path)
    scene = mitsuba_scene(sc, base, env_path, tmp)

    # Which pixels see one shape over their whole 3x3 neighbourhood, and where they are.
    aov = mi.load_dict({"type": "aov", "aovs": "dd:depth,si:shape_index,pp:position"})
    g = np.array(mi.render(scene, integrator=aov, spp=64, seed=7), dtype=np.float64)
    depth, si, pos = g[..., 0], g[..., 1], g[..., 2:5]
    pad = np.pad(si, 1, mode="edge")
    dpad = np.pad(depth, 1, mode="edge")
    interior = depth > 0
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            interior &= (pad[dy:dy + W, dx:dx + W] == si) & (dpad[dy:dy + W, dx:dx + W] > 0)
    seen = int((depth > 0).sum())

    # Mitsuba: converged, 32 spp (1 + 1), and the speed run (32 + 32 at 1 spp).
    ref = np.zeros((W, W, 3))
    chunks = max(1, a.ref_spp // 256)
    for k in range(chunks):
        ref += render(scene, direct(1, 1), 256, 10_000 + k)[0] / chunks
    ref_l = luminance(ref)
    rel = lambda img: float(((luminance(img) - ref_l) ** 2 / (ref_l ** 2 + 1e-2))[interior].mean())
    m32 = [rel(render(scene, direct(1, 1), 32, 100 + k)[0]) for k in range(a.seeds)]
    render(scene, direct(32, 32), 1, 0)  # JIT compilation
    mts = sorted(render(scene, direct(32, 32), 1, 1 + k)[1] for k in range(3))[1]

    # envis: the same scene file, the clamped map, one seed per run.
    envis_rel, envis_sps, mean = [], [], np.zeros((W, W, 3))
    for k in range(a.seeds):
        t = re.sub(r'(?m)^source\s*=.*$', f'source = "{env_path}"', text, count=1)
        t = re.sub(r'(?m)^\[sampling\]\s*$', f'[sampling]\nseed = {k}', t, count=1)
        t = t.replace('path = "', f'path = "{base}/')
        toml = os.path.join(tmp, "scene.toml")
        open(toml, "w").write(t)
        out, st = os.path.join(tmp, "e.exr"), os.path.join(tmp, "e.json")
        subprocess.run([a.envis, "render", "--scene", toml, "--size", str(W), "--out", out, "--stats", st],
                       check=True, stderr=subprocess.DEVNULL)
        img = np.array(mi.Bitmap(out), dtype=np.float64)[..., :3]
        mean += img / a.seeds
        envis_rel.append(rel(img))
        js = json.load(open(st))
        envis_sps.append(js["shaded_pixels"] * 64 / (js["shade_ms"] / 1e3))

    contact = contacts(sc, pos, interior, luminance(mean), ref_l)
    if a.out:
        # What was compared, to look at: Mitsuba converged and envis's mean over the runs.
        stem = os.path.splitext(a.out)[0]
        mi.util.write_bitmap(stem + "-mitsuba.png", ref.astype(np.float32))
        mi.util.write_bitmap(stem + "-envis.png", mean.astype(np.float32))
    res = {
        "scene": a.scene, "size": W, "env": os.path.basename(src), "seeds": a.seeds, "ref_spp": chunks * 256,
        "interior_pixels": int(interior.sum()), "pixels_seeing_geometry": seen,
        "relmse": {"envis_32_32": float(np.mean(envis_rel)), "mitsuba_32spp": float(np.mean(m32)),
                   "envis_over_mitsuba": float(np.mean(envis_rel) / np.mean(m32))},
        "contact": contact,
        "speed": {"envis_samples_per_s": float(np.median(envis_sps)), "mitsuba_samples_per_s": seen * 64 / mts,
                  "envis_over_mitsuba": float(np.median(envis_sps) / (seen * 64 / mts)), "threads": os.cpu_count()},
        "mitsuba": mi.__version__,
    }
    print(json.dumps(res, indent=2))
    if a.out:
        json.dump(res, open(a.out, "w"), indent=2)


def contacts(sc, pos, interior, envis_l, ref_l):
    """Contact shadow / open ground, per sphere resting on a plane, in envis's mean and the reference."""
    planes = [o for o in sc["object"] if o["shape"] == "plane"]
    if not planes:
        return []
    p = planes[0]
    n = rotation(p) @ np.array([0.0, 1.0, 0.0])
    c0 = np.array(p.get("position", [0, 0, 0]), dtype=np.float64)
    ground = interior & (np.abs((pos - c0) @ n) < 1e-3)
    flat = pos - np.outer((pos - c0).reshape(-1, 3) @ n, n).reshape(pos.shape)
    objects = [(np.array(o.get("position", [0, 0, 0]), dtype=np.float64), o.get("radius", 1.0) * o.get("scale", 1.0))
               for o in sc["object"] if o["shape"] != "plane"]
    open_ground = ground.copy()
    for c, r in objects:
        open_ground &= np.linalg.norm(flat - (c - ((c - c0) @ n) * n), axis=-1) > 2.0 + r
    out = []
    for o in sc["object"]:
        if o["shape"] != "sphere":
            continue
        c = np.array(o.get("position", [0, 0, 0]), dtype=np.float64)
        r = o.get("radius", 1.0) * o.get("scale", 1.0)
        if abs((c - c0) @ n - r) > 1e-3:
            continue  # not resting on the plane
        touch = c - r * n
        # The ground around where it rests (the ring right under it is hidden from the camera).
        d = np.linalg.norm(flat - touch, axis=-1)
        near = ground & (d > 0.8 * r) & (d < 1.2 * r)
        if near.sum() == 0 or open_ground.sum() == 0:
            continue
        e = envis_l[near].mean() / envis_l[open_ground].mean()
        m = ref_l[near].mean() / ref_l[open_ground].mean()
        out.append({"sphere": o.get("name", "sphere"), "pixels": int(near.sum()), "open_pixels": int(open_ground.sum()),
                    "envis_ratio": float(e), "converged_ratio": float(m), "envis_over_converged": float(e / m)})
    return out
