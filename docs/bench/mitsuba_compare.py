#!/usr/bin/env python3
"""Samples per second of `envis render` (CPU) vs Mitsuba 3's `direct` integrator, in one run.

Two modes. Without `--scene` (below): the lone sphere, speed only, with `--brdf diffuse` (albedo
0.8), `--brdf ggx --alpha A` (envis's GGX, F = 1 times albedo 0.8, against Mitsuba's
`roughconductor` with `material: none`, visible-normal sampling and `specular_reflectance` 0.8:
the same BRDF and sampler) or `--brdf phong` (exponent 150; Mitsuba has no Phong, so its
samples/s is reported against envis's diffuse, run in the same sitting). With
`--scene FILE` (a scene file of diffuse spheres, planes and glTF meshes, e.g.
`assets/scenes/occluded.toml`): speed, equal-sample error and contact shadows with visibility,
see `occluded()` at the end of this file.

Same scene (unit sphere, orthographic camera on +Z covering [-1,1]^2, the same BRDF),
same lat-long map (Mitsuba 3's convention is envis's), same sample counts (32 emitter/light +
32 BSDF samples per pixel, one camera sample per pixel), same machine, same process tree.
Samples/s = (pixels on the sphere) x (N_L + N_B) / shading seconds for both.

Needs: `pip install mitsuba` (variant llvm_ad_rgb) and Debian `libllvm19`; a release build of
envis (`cargo build --release`). Usage:
    python3 docs/bench/mitsuba_compare.py [--env ../shared/data/hdri/sky.exr] [--size 256] [--repeat 5]
        [--brdf diffuse|ggx|phong] [--alpha 0.3]
"""
import argparse, json, os, subprocess, sys, tempfile, time

ap = argparse.ArgumentParser()
ap.add_argument("--env", help="the map (default: ../shared/data/hdri/sky.exr; with --scene, the scene's)")
ap.add_argument("--size", type=int, default=256)
ap.add_argument("--face-size", type=int, default=64)
ap.add_argument("--repeat", type=int, default=5)
ap.add_argument("--envis", default=os.environ.get("ENVIS", "target/release/envis"))
ap.add_argument("--scene", help="an occluded scene file: error and speed with visibility")
ap.add_argument("--seeds", type=int, default=8, help="--scene: envis / Mitsuba 32 spp runs averaged")
ap.add_argument("--ref-spp", type=int, default=4096, help="--scene: the converged reference's spp")
ap.add_argument("--out", help="write the JSON here too")
ap.add_argument("--brdf", choices=["diffuse", "ggx", "phong"], default="diffuse")
ap.add_argument("--alpha", type=float, default=0.3, help="--brdf ggx: the roughness")
a = ap.parse_args()

import mitsuba as mi
import drjit as dr
mi.set_variant("llvm_ad_rgb")

if a.scene:
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import mitsuba_occluded
    mitsuba_occluded.run(a)
    sys.exit(0)
a.env = a.env or os.path.join(os.path.dirname(__file__), "../../../shared/data/hdri/sky.exr")

W = a.size
on_sphere = sum(1 for j in range(W) for i in range(W)
                if (-1 + 2 * (i + .5) / W) ** 2 + (1 - 2 * (j + .5) / W) ** 2 < 1)
samples = on_sphere * 64

scene = mi.load_dict({
    "type": "scene",
    "integrator": {"type": "direct", "emitter_samples": 32, "bsdf_samples": 32},
    "sensor": {
        "type": "orthographic",
        "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
        "film": {"type": "hdrfilm", "width": W, "height": W, "rfilter": {"type": "box"}},
        "sampler": {"type": "independent", "sample_count": 1},
    },
    "sphere": {"type": "sphere", "radius": 1.0, "bsdf": (
        {"type": "roughconductor", "material": "none", "distribution": "ggx", "alpha": a.alpha,
         "sample_visible": True, "specular_reflectance": {"type": "rgb", "value": 0.8}}
        if a.brdf == "ggx" else {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.8}})},
    "env": {"type": "envmap", "filename": os.path.abspath(a.env)},
})

def mitsuba_once(seed):
    t = time.perf_counter()
    img = mi.render(scene, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    return time.perf_counter() - t

first = mitsuba_once(0)  # includes JIT compilation
mts = sorted(mitsuba_once(s) for s in range(1, a.repeat + 1))[a.repeat // 2]

def envis_samples_per_s(brdf):
    """Median over --repeat seeds of envis's samples/s for the BRDF arguments `brdf`."""
    sps = []
    with tempfile.TemporaryDirectory() as d:
        for s in range(a.repeat):
            st = os.path.join(d, "s.json")
            subprocess.run([a.envis, "render", "--env", a.env, "--face-size", str(a.face_size), "--scene", "sphere",
                            "--size", str(W), *brdf, "--albedo", "0.8", "--light-samples", "32",
                            "--brdf-samples", "32", "--strategy", "paper", "--counts", "fractional", "--mis", "balance",
                            "--seed", str(s), "--out", os.path.join(d, "o.exr"), "--stats", st], check=True)
            js = json.load(open(st))
            sps.append(samples / (js["shade_ms"] / 1e3))
    return sorted(sps)[a.repeat // 2]

brdf = {"diffuse": ["--brdf", "diffuse"], "ggx": ["--brdf", "ggx", "--alpha", str(a.alpha)],
        "phong": ["--brdf", "phong", "--exponent", "150"]}[a.brdf]
envis = envis_samples_per_s(brdf)
res = {"brdf": a.brdf, "alpha": a.alpha if a.brdf == "ggx" else None, "pixels_on_sphere": on_sphere,
       "samples": samples, "mitsuba_first_s": first, "mitsuba_s": mts,
       "mitsuba_samples_per_s": samples / mts, "envis_samples_per_s": envis, "ratio": envis / (samples / mts),
       "threads": os.cpu_count(), "mitsuba": mi.__version__}
if a.brdf == "phong":
    # Mitsuba has no Phong: its figure above is its diffuse sphere; Phong against envis's diffuse.
    res["envis_diffuse_samples_per_s"] = envis_samples_per_s(brdf_d := ["--brdf", "diffuse"])
    res["phong_over_envis_diffuse"] = envis / res["envis_diffuse_samples_per_s"]
print(json.dumps(res, indent=2))
if a.out:
    json.dump(res, open(a.out, "w"), indent=2)
