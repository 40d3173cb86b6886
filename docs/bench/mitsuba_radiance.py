#!/usr/bin/env python3
"""Error at equal samples of `envis render` and Mitsuba 3 on a near-mirror sphere (issue 28, item 7).

The scene of `mitsuba_compare.py` (the unit sphere, orthographic camera on +Z covering
[-1, 1]^2, envis's GGX with F = 1 times albedo 0.8 against Mitsuba's `roughconductor` with
`material: none`, visible-normal sampling), GGX alpha --alpha (0.02), a distribution of
--face-size (32^2 faces), 32 light / emitter + 32 BRDF samples per pixel, one camera sample.
Per map (each shared map clamped to >= 0 and written as float32 EXR for both, as envis clamps):
- the reference: Mitsuba `direct` (1 emitter + 1 BSDF sample) at --ref-spp samples per pixel;
- Mitsuba at 32 + 32, --seeds runs;
- envis at 32 + 32 with `--radiance full` (the map at its own resolution, the default) and with
  `--radiance distribution` (the --face-size map: what envis did before), --seeds runs each.
relMSE of luminance, mean of (x - r)^2 / (r^2 + 1e-2) over interior pixels (radius < 0.95: away
from the silhouette, where Mitsuba jitters within the pixel and envis shades its centre), averaged
over the seeds (`*`), each envis error over Mitsuba's (`*_over_mitsuba`), and the relMSE of the
mean image over the seeds (`*_of_mean`: what bias remains once the noise is averaged down, up
to the reference's own noise). Writes JSON to stdout and --out.

Needs `pip install mitsuba` (variant llvm_ad_rgb), Debian `libllvm19`, and an envis build
(`cargo build --release`). Usage:
    python3 docs/bench/mitsuba_radiance.py [--maps park,sky,...] [--size 128] [--out FILE]
"""
import argparse, json, os, subprocess, tempfile

import numpy as np
import mitsuba as mi
import drjit as dr

ap = argparse.ArgumentParser()
ap.add_argument("--maps", default="park,sky,studio,sunset,venice,forest")
ap.add_argument("--data", default=os.path.join(os.path.dirname(__file__), "../../../shared/data/hdri"))
ap.add_argument("--size", type=int, default=128)
ap.add_argument("--face-size", type=int, default=32)
ap.add_argument("--alpha", type=float, default=0.02)
ap.add_argument("--seeds", type=int, default=4)
ap.add_argument("--ref-spp", type=int, default=4096)
ap.add_argument("--envis", default=os.environ.get("ENVIS", "target/release/envis"))
ap.add_argument("--baseline", help="another envis build, run with --radiance full beside --envis "
                "(e.g. the one before a change, in the same sitting): adds envis_baseline_*")
ap.add_argument("--out")
a = ap.parse_args()
mi.set_variant("llvm_ad_rgb")
W = a.size


def scene(env_path, spp, emitter, bsdf):
    return mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": emitter, "bsdf_samples": bsdf},
        "sensor": {
            "type": "orthographic",
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": W, "height": W, "rfilter": {"type": "box"}},
            "sampler": {"type": "independent", "sample_count": spp},
        },
        "sphere": {"type": "sphere", "radius": 1.0, "bsdf": {
            "type": "roughconductor", "material": "none", "distribution": "ggx", "alpha": a.alpha,
            "sample_visible": True, "specular_reflectance": {"type": "rgb", "value": 0.8}}},
        "env": {"type": "envmap", "filename": env_path},
    })


def luminance(img):
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def render(sc, seed):
    img = mi.render(sc, seed=seed)
    dr.eval(img)
    return luminance(np.array(img)[..., :3].astype(np.float64))


c = (np.arange(W) + 0.5) / W * 2 - 1
x, y = np.meshgrid(c, -c)
interior = x * x + y * y < 0.95 ** 2


def relmse(img, ref):
    e = (img - ref) ** 2 / (ref * ref + 1e-2)
    return float(e[interior].mean())


def envis_run(env_path, radiance, seed, d, exe=None):
    out = os.path.join(d, "e.exr")
    subprocess.run([exe or a.envis, "render", "--env", env_path, "--face-size", str(a.face_size), "--size", str(W),
                    "--brdf", "ggx", "--alpha", str(a.alpha), "--albedo", "0.8", "--light-samples", "32",
                    "--brdf-samples", "32", "--seed", str(seed), "--radiance", radiance, "--out", out],
                   check=True, capture_output=True)
    return luminance(np.array(mi.Bitmap(out)).astype(np.float64)[..., :3])


rows = []
with tempfile.TemporaryDirectory() as d:
    for name in a.maps.split(","):
        src = np.array(mi.Bitmap(os.path.join(a.data, f"{name}.exr"))).astype(np.float32)[..., :3]
        env = os.path.join(d, f"{name}.exr")
        mi.Bitmap(np.maximum(src, 0.0)).write(env)
        ref = render(scene(env, a.ref_spp, 1, 1), 7)
        imgs = [render(scene(env, 1, 32, 32), s) for s in range(a.seeds)]
        mts = np.mean([relmse(i, ref) for i in imgs])
        row = {"map": name, "mitsuba": mts, "mitsuba_of_mean": relmse(np.mean(imgs, axis=0), ref)}
        runs = [("full", "full", None), ("distribution", "distribution", None)]
        if a.baseline:
            runs.append(("baseline", "full", a.baseline))
        for key, radiance, exe in runs:
            imgs = [envis_run(env, radiance, s, d, exe) for s in range(a.seeds)]
            e = np.mean([relmse(i, ref) for i in imgs])
            row[f"envis_{key}"] = e
            row[f"envis_{key}_over_mitsuba"] = e / mts
            row[f"envis_{key}_of_mean"] = relmse(np.mean(imgs, axis=0), ref)
        print(json.dumps(row), flush=True)
        rows.append(row)
res = {"baseline": a.baseline, "alpha": a.alpha, "face_size": a.face_size, "size": W, "seeds": a.seeds, "ref_spp": a.ref_spp,
       "samples": "32 + 32", "threads": os.cpu_count(), "mitsuba": mi.__version__, "rows": rows}
print(json.dumps(res, indent=2))
if a.out:
    json.dump(res, open(a.out, "w"), indent=2)
