//! What the integration-test binaries share: when a test may skip instead of failing, and where
//! the real data is. A test that cannot run fails, saying how to get what it needs; it skips only
//! when the person running it asked for that (`ENVIS_SKIP_GPU=1`, `ENVIS_SKIP_DATA=1`), and never
//! under CI, so a green run always means the whole suite ran.
#![allow(dead_code)] // each test binary uses its own part of this module

use std::path::{Path, PathBuf};

/// Two uniform numbers in `[0, 1)` from `r`.
pub fn rng_vec2(r: &mut envis::sampling::rng::Rng) -> glam::Vec2 {
    glam::Vec2::new(r.next_f32(), r.next_f32())
}

/// A [`TempDir`] named `test`.
pub fn tempdir() -> TempDir {
    TempDir::new("test")
}

/// `|a - b|` relative to the larger magnitude (0 for two zeros).
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-30)
}

/// The mean luminance of an image's pixels.
pub fn mean_lum(d: &[glam::Vec3]) -> f64 {
    d.iter()
        .map(|c| envis::envmap::luminance(*c) as f64)
        .sum::<f64>()
        / d.len() as f64
}

/// The workspace's root (every test crate is `crates/NAME`): `assets/` and `../shared` are there.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// How many `.exr` maps `../shared/data/hdri` holds (see its README): fewer means a partial copy.
pub const REAL_MAP_COUNT: usize = 18;

/// An environment variable set to a true value (`1`, `true`, `yes`, `on`); `CI=false` or `CI=`
/// is not true.
pub fn truthy(var: &str) -> bool {
    std::env::var(var).is_ok_and(|v| {
        matches!(
            v.trim().to_ascii_lowercase().as_str(),
            "1" | "true" | "yes" | "on"
        )
    })
}

/// Running under CI (`CI` set to a true value): nothing may be skipped.
pub fn ci() -> bool {
    truthy("CI")
}

/// `what` cannot run because of `why`. Fails with `install` (how to get the missing piece)
/// unless `ENVIS_SKIP_GPU=1` asks to skip GPU and window tests (outside CI); then says so on
/// stderr, where `cargo test -- --nocapture` shows it.
pub fn skip_gpu_or_fail(what: &str, why: &str, install: &str) {
    if truthy("ENVIS_SKIP_GPU") && !ci() {
        eprintln!("SKIPPING {what} (ENVIS_SKIP_GPU=1): {why}");
    } else {
        panic!(
            "{what} cannot run: {why}. {install} Or set ENVIS_SKIP_GPU=1 to skip GPU and window \
             tests (not honoured under CI)."
        );
    }
}

/// How to get a Vulkan device on a machine without a GPU.
pub const INSTALL_LAVAPIPE: &str = "Install Mesa's CPU Vulkan driver (apt-get install \
    mesa-vulkan-drivers libvulkan1) and run with WGPU_ADAPTER_NAME=llvmpipe.";

/// The shared real maps (`../shared/data/hdri`, all [`REAL_MAP_COUNT`] of them), sorted. A
/// missing or short folder fails, unless `ENVIS_SKIP_DATA=1` (outside CI) asks the tests to use
/// generated maps instead: then `None`, said on stderr.
pub fn real_maps() -> Option<Vec<PathBuf>> {
    let dir = repo().join("../shared/data/hdri");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "exr"))
                .collect()
        })
        .unwrap_or_default();
    if v.len() < REAL_MAP_COUNT {
        let why = format!(
            "{} holds {} of the {REAL_MAP_COUNT} real maps",
            dir.display(),
            v.len()
        );
        if truthy("ENVIS_SKIP_DATA") && !ci() {
            eprintln!("note (ENVIS_SKIP_DATA=1): {why}; using generated maps instead");
            return None;
        }
        panic!(
            "{why}. Clone envis beside the project's shared/ folder, or set ENVIS_SKIP_DATA=1 to \
             test on generated maps (not honoured under CI)."
        );
    }
    v.sort();
    Some(v)
}

/// A JSON file a test's command wrote (the error names the file).
pub fn read_json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The bunny on a plane as one triangle soup (the geometry the GPU traces), and 20,000 rays:
/// half from a sphere around it towards its box, half shadow rays leaving the plane upwards.
pub fn bunny_on_plane_rays() -> (envis::scene::TriMesh, Vec<(glam::Vec3, glam::Vec3)>) {
    let root = repo();
    let mut mesh = envis::scene::load_glb(&root.join("assets/models/bunny_plain.glb")).unwrap();
    let (lo, hi) = mesh.positions.iter().fold(
        (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let (centre, extent) = (0.5 * (lo + hi), (hi - lo).max_element());
    let base = mesh.positions.len() as u32;
    for (x, z) in [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)] {
        mesh.positions.push(glam::Vec3::new(
            centre.x + x * extent,
            lo.y,
            centre.z + z * extent,
        ));
    }
    mesh.indices.push([base, base + 2, base + 1]);
    mesh.indices.push([base, base + 3, base + 2]);
    let mut r = envis::sampling::rng::Rng::new(29, 3);
    let mut rays = Vec::new();
    for _ in 0..10_000 {
        let o = centre + {
            let z = 1.0 - 2.0 * r.next_f32();
            let phi = std::f32::consts::TAU * r.next_f32();
            let s = (1.0 - z * z).max(0.0).sqrt();
            glam::Vec3::new(s * phi.cos(), s * phi.sin(), z)
        } * 2.0
            * extent;
        let target = lo + (hi - lo) * glam::Vec3::new(r.next_f32(), r.next_f32(), r.next_f32());
        rays.push((o, (target - o).normalize()));
    }
    for _ in 0..10_000 {
        let (u, v) = (r.next_f32() - 0.5, r.next_f32() - 0.5);
        let p = glam::Vec3::new(centre.x + u * extent, lo.y, centre.z + v * extent);
        let d = envis::sampling::warp::Frame::new(glam::Vec3::Y).to_world(
            envis::sampling::warp::sample_cosine_hemisphere(glam::Vec2::new(
                r.next_f32(),
                r.next_f32(),
            )),
        );
        rays.push((p + glam::Vec3::Y * envis::visibility::ray_offset(p), d));
    }
    (mesh, rays)
}

/// The bunny placed four times (rotated, scaled, one non-uniformly) on a plane, as instances
/// of two meshes, every instance moved by `shift` along +X and turned by `shift` radians: the
/// two-level BVH and its parts, and the same triangles merged in world space.
pub struct Instanced {
    pub flat: envis::visibility::FlatBvh,
    pub tlas: envis::visibility::Tlas,
    pub bounds: Vec<envis::visibility::Bounds>,
    pub placed: Vec<envis::visibility::FlatInstance>,
    /// The bunny's and the plane's BVHs (`placed[i].blas` indexes them).
    pub blases: Vec<envis::visibility::FlatBlas>,
    pub instances: Vec<envis::scene::MeshInstance>,
    pub world: envis::scene::TriMesh,
}

pub fn instanced_bunnies(shift: f32) -> Instanced {
    use envis::visibility::{FlatBvh, FlatInstance, Layers, Tlas, world_bounds};
    use glam::{Affine3A, Quat, Vec3};
    use std::sync::Arc;
    let root = repo();
    let bunny =
        Arc::new(envis::scene::load_glb(&root.join("assets/models/bunny_plain.glb")).unwrap());
    let square = Arc::new(envis::scene::square_mesh());
    let (lo, hi) = bunny.bounds().unwrap();
    let (c, e) = (0.5 * (lo + hi), (hi - lo).max_element());
    let turn = |a: f32| Quat::from_rotation_y(a + shift);
    let at = |x: f32| c + Vec3::new(x * e + shift, 0.0, 0.0);
    let placements = [
        (
            &bunny,
            Affine3A::from_rotation_translation(turn(0.0), at(0.0)),
        ),
        (
            &bunny,
            Affine3A::from_scale_rotation_translation(Vec3::splat(0.7), turn(1.6), at(1.0)),
        ),
        (
            &bunny,
            Affine3A::from_scale_rotation_translation(
                Vec3::new(1.0, 1.5, 0.8),
                turn(-0.5),
                at(-1.0),
            ),
        ),
        (
            &bunny,
            Affine3A::from_rotation_translation(turn(3.0), c + Vec3::new(0.0, 0.0, e)),
        ),
        (
            &square,
            Affine3A::from_scale_rotation_translation(
                Vec3::splat(2.0 * e),
                Quat::IDENTITY,
                Vec3::new(c.x, lo.y, c.z),
            ),
        ),
    ];
    // Centre each bunny on its own origin so a turn keeps it in place.
    let recentre = Affine3A::from_translation(-c);
    let blases = [&bunny, &square].map(|m| m.bvh().flat_blas(&m.positions, &m.indices).unwrap());
    let mut out = Instanced {
        flat: FlatBvh::default(),
        tlas: Tlas::default(),
        bounds: Vec::new(),
        placed: Vec::new(),
        blases: Vec::new(),
        instances: Vec::new(),
        world: envis::scene::TriMesh::default(),
    };
    for (mesh, place) in placements {
        let is_bunny = Arc::ptr_eq(mesh, &bunny);
        let world = if is_bunny { place * recentre } else { place };
        let inst = envis::scene::MeshInstance::new(mesh.clone(), world).unwrap();
        let base = out.world.positions.len() as u32;
        out.world.positions.extend(inst.world_positions());
        out.world
            .indices
            .extend(mesh.indices.iter().map(|t| t.map(|v| v + base)));
        let blas = if is_bunny { 0 } else { 1 };
        out.bounds
            .push(world_bounds(blases[blas].bounds.unwrap(), &world));
        out.placed.push(FlatInstance {
            blas,
            to_object: inst.to_object,
            layers: Layers::ALL,
        });
        out.instances.push(inst);
    }
    out.tlas = Tlas::build(&out.bounds);
    out.flat = FlatBvh::build(&blases, &out.placed, &out.tlas).unwrap();
    out.blases = blases.into();
    out
}

/// A fresh directory under the system's temporary directory, removed when dropped (kept when
/// the test is failing, so what it wrote can be looked at; the panic message says where).
/// Derefs to its `Path`.
pub struct TempDir(PathBuf);

impl TempDir {
    /// `envis-NAME-PID-K`, K counting this process's directories.
    pub fn new(name: &str) -> Self {
        use std::sync::atomic::{AtomicUsize, Ordering};
        static N: AtomicUsize = AtomicUsize::new(0);
        let k = N.fetch_add(1, Ordering::SeqCst);
        let dir = std::env::temp_dir().join(format!("envis-{name}-{}-{k}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
        TempDir(dir)
    }
}

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TempDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept {} (the test failed)", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// The resampling tests' small scene (the CPU oracle's and its WGSL twin's): a diffuse and a
/// glossy sphere on a plane (contact shadows) under the built-in sky with 8^2 faces, the camera
/// close enough that almost every pixel sees geometry. `orbit` (degrees per second), the glossy
/// sphere's `velocity` (x, units per second) and the sky's `speed` (hours per second) move it on
/// a clock of `fps` frames per second.
pub fn resampling_scene(
    dir: &Path,
    name: &str,
    orbit: f32,
    velocity: f32,
    speed: f32,
    fps: f32,
) -> envis::scene::Scene {
    load_scene(
        dir,
        name,
        &resampling_scene_text(orbit, velocity, speed, fps),
    )
}

/// The resampling tests' scene held still, its sky switching at frame `at` (of 30 a second) to
/// `assets/hdri/park.exr`, as a carousel step would: another map's light.
pub fn switching_scene(dir: &Path, name: &str, at: u32) -> envis::scene::Scene {
    let mut text = resampling_scene_text(0.0, 0.0, 0.0, 30.0);
    let at = (at as f32 - 0.5) / 30.0;
    let park = repo().join("assets/hdri/park.exr");
    let park = park.display().to_string().replace('\\', "/");
    text += &format!("[[animation.switch]]\nat = {at}\nsource = \"{park}\"\n");
    load_scene(dir, name, &text)
}

/// `text` written to `dir/name.toml` and loaded.
fn load_scene(dir: &Path, name: &str, text: &str) -> envis::scene::Scene {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    envis::scene::Scene::load(&p).unwrap()
}

fn resampling_scene_text(orbit: f32, velocity: f32, speed: f32, fps: f32) -> String {
    format!(
        r#"
[environment]
source = "builtin:sky:14"
face_size = 8
speed = {speed}
[camera]
position = [0.0, 1.6, 3.2]
target = [0.0, 0.5, 0.0]
fov = 45.0
[animation]
fps = {fps}
orbit = {orbit}
[sampling]
light_samples = 2
brdf_samples = 2
material_budget = false
visibility = "on"
[[object]]
shape = "sphere"
radius = 0.5
position = [-0.55, 0.5, 0.0]
material = {{ type = "diffuse", albedo = [0.8, 0.6, 0.4] }}
[[object]]
shape = "sphere"
radius = 0.4
position = [0.5, 0.4, 0.3]
velocity = [{velocity}, 0.0, 0.0]
material = {{ type = "ggx", albedo = 0.9, alpha = 0.3 }}
[[object]]
shape = "plane"
size = 8.0
material = {{ type = "diffuse", albedo = 0.6 }}
"#
    )
}

// Scene files the visibility tests of the core and of the CLI share.

/// A scene file written to `dir/scene.toml` and loaded.
pub fn scene_in(dir: &Path, camera: &str, objects: &str) -> envis::scene::Scene {
    let path = dir.join("scene.toml");
    let text = format!(
        "[environment]\nsource = \"builtin:sky:15\"\nface_size = 8\n\n[camera]\n{camera}\n\n{objects}"
    );
    std::fs::write(&path, text).unwrap();
    envis::scene::Scene::load(&path).unwrap()
}

pub const PLANE: &str =
    "[[object]]\nshape = \"plane\"\nsize = 8.0\nmaterial = { type = \"diffuse\", albedo = 0.6 }\n";
pub const SPHERE: &str = "[[object]]\nshape = \"sphere\"\nposition = [0.0, 1.0, 0.0]\nmaterial = { type = \"diffuse\", albedo = 0.8 }\n";
pub const TORUS: &str = "[[object]]\nshape = \"torus\"\nposition = [0.0, 0.45, 0.0]\nmaterial = { type = \"ggx\", albedo = 0.8, alpha = 0.3 }\n";
/// Looking down at the contact region, from the side of the low afternoon sun's shadow.
pub const CAMERA: &str = "position = [0.0, 3.2, 3.2]\ntarget = [0.0, 0.5, 0.0]\nfov = 50.0";
