//! The WGSL sources, embedded in the binary. Each program's source is `common.wgsl` plus its own
//! files, joined by one builder function each below (`distribution_source`, `shade_source`,
//! `lighting_source`, ...): WGSL has no includes, and a fixed concatenation per program is
//! simpler than Bevy's naga_oil imports for programs that share only a few files.

pub const COMMON: &str = include_str!("../shaders/common.wgsl");
pub const SAMPLING: &str = include_str!("../shaders/sampling.wgsl");
pub const DISTRIBUTION: &str = include_str!("../shaders/distribution.wgsl");
pub const SHADE: &str = include_str!("../shaders/shade.wgsl");
pub const SCAN: &str = include_str!("../shaders/scan.wgsl");
pub const CDF: &str = include_str!("../shaders/cdf.wgsl");
pub const GLOBAL: &str = include_str!("../shaders/global.wgsl");
pub const GLOBAL_LAYOUT: &str = include_str!("../shaders/global_layout.wgsl");
pub const SHADE_COMPUTE: &str = include_str!("../shaders/shade_compute.wgsl");
pub const LIGHTING: &str = include_str!("../shaders/lighting.wgsl");
pub const GBUFFER: &str = include_str!("../shaders/gbuffer.wgsl");
pub const GATHER: &str = include_str!("../shaders/gather.wgsl");
pub const IMAGE_SOURCE: &str = include_str!("../shaders/image_source.wgsl");
pub const RESAMPLE: &str = include_str!("../shaders/resample.wgsl");
pub const VISIBILITY: &str = include_str!("../shaders/visibility.wgsl");
pub const TRACE_RAYS: &str = include_str!("../shaders/trace_rays.wgsl");
pub const SUBTEXEL: &str = include_str!("../shaders/subtexel.wgsl");
pub const RESERVOIR: &str = include_str!("../shaders/reservoir.wgsl");
pub const BRIGHT: &str = include_str!("../shaders/bright.wgsl");
pub const RESAMPLING: &str = include_str!("../shaders/resampling.wgsl");
pub const REUSE: &str = include_str!("../shaders/reuse.wgsl");
pub const SHADE_FUNCTIONS_TEST: &str = include_str!("../shaders/shade_functions_test.wgsl");

/// Distribution build + pool module.
pub fn distribution_source() -> String {
    [COMMON, SCAN, CDF, DISTRIBUTION].concat()
}

/// The sub-texel refinement of the light pool (`refine_pool`).
pub fn subtexel_source() -> String {
    [COMMON, SUBTEXEL].concat()
}

/// The resample stage (an environment texture -> the cube texel table).
pub fn resample_source() -> String {
    [COMMON, IMAGE_SOURCE, RESAMPLE].concat()
}

/// A batch of shadow rays through a flattened BVH.
pub fn trace_rays_source() -> String {
    [VISIBILITY, TRACE_RAYS].concat()
}

/// Per-pixel shading module (compute entry point `shade_gbuffer`).
pub fn shade_source() -> String {
    [
        COMMON,
        SAMPLING,
        CDF,
        GLOBAL_LAYOUT,
        SHADE,
        VISIBILITY,
        SHADE_COMPUTE,
    ]
    .concat()
}

/// Reservoir resampling of a frame (`candidates`, `history_targets`, `temporal`, `spatial`,
/// `shade_reservoirs`): the shading module's sample loops with a reservoir as their sink.
pub fn resampling_source() -> String {
    [
        COMMON,
        SAMPLING,
        CDF,
        GLOBAL_LAYOUT,
        SHADE,
        VISIBILITY,
        RESERVOIR,
        BRIGHT,
        RESAMPLING,
        REUSE,
    ]
    .concat()
}

/// The shading module with its test-only entry points (`test_brdf`, `test_mis`,
/// `test_face_count`, `test_draw_tile`, `test_pool_window`): one function at a time against its
/// CPU twin (`tests/gpu/functions.rs`).
pub fn shade_functions_test_source() -> String {
    shade_source() + SHADE_FUNCTIONS_TEST
}

/// The Bevy resampling pass's gather (`gather`, `gather_split`): Bevy's prepass textures into
/// what the resampling passes read.
pub fn gather_source() -> String {
    [COMMON, SAMPLING, GBUFFER, GATHER].concat()
}

/// Compile a module, turning a WGSL error into a readable panic (a shader that does not compile
/// is a build defect, caught by the tests).
pub fn module(device: &wgpu::Device, label: &str, source: &str) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

/// The Bevy deferred lighting pass's modules, in order: file name and embedded text.
pub const LIGHTING_MODULES: [(&str, &str); 9] = [
    ("common.wgsl", COMMON),
    ("sampling.wgsl", SAMPLING),
    ("cdf.wgsl", CDF),
    ("global_layout.wgsl", GLOBAL_LAYOUT),
    ("shade.wgsl", SHADE),
    ("image_source.wgsl", IMAGE_SOURCE),
    ("visibility.wgsl", VISIBILITY),
    ("gbuffer.wgsl", GBUFFER),
    ("lighting.wgsl", LIGHTING),
];

/// The Bevy deferred lighting pass (fullscreen vertex + fragment `lighting`).
pub fn lighting_source() -> String {
    LIGHTING_MODULES.iter().map(|(_, text)| *text).collect()
}

/// [`lighting_source`] read from the `.wgsl` files in `dir` (the shaders' folder) instead of the
/// copies embedded at build time: what `EnvisShaderReloadPlugin` recompiles.
pub fn lighting_source_from(dir: &std::path::Path) -> std::io::Result<String> {
    LIGHTING_MODULES
        .iter()
        .map(|(name, _)| std::fs::read_to_string(dir.join(name)))
        .collect()
}

/// The `global` baseline's build (lat-long distribution over the sphere).
pub fn global_source() -> String {
    [COMMON, SCAN, CDF, GLOBAL_LAYOUT, GLOBAL].concat()
}

#[cfg(test)]
mod tests {
    /// The value of `const NAME: f32 = VALUE;` in a WGSL source.
    fn wgsl_const(src: &str, name: &str) -> f32 {
        let line = src
            .lines()
            .find(|l| l.trim_start().starts_with(&format!("const {name}: f32 =")))
            .unwrap_or_else(|| panic!("no const {name} in the WGSL"));
        let v = line.split('=').nth(1).unwrap().trim().trim_end_matches(';');
        v.parse().unwrap_or_else(|_| panic!("{name}: '{v}'"))
    }

    /// WGSL constants equal their Rust twins (WGSL cannot import them).
    #[test]
    fn wgsl_constants_match_their_rust_twins() {
        use envis::render::{NEAR_MIRROR_ALPHA, NEAR_MIRROR_EXPONENT};
        use envis::sampling::rng::ONE_MINUS_EPSILON;
        assert_eq!(
            wgsl_const(super::COMMON, "ONE_MINUS_EPSILON"),
            ONE_MINUS_EPSILON
        );
        assert_eq!(
            wgsl_const(super::SHADE, "NEAR_MIRROR_EXPONENT"),
            NEAR_MIRROR_EXPONENT
        );
        assert_eq!(
            wgsl_const(super::SHADE, "NEAR_MIRROR_ALPHA"),
            NEAR_MIRROR_ALPHA
        );
        assert_eq!(
            wgsl_const(super::COMMON, "MAX_RADIANCE"),
            envis::envmap::MAX_RADIANCE
        );
        use envis::render::resampling as r;
        for (name, value) in [
            ("SPATIAL_RADIUS", r::SPATIAL_RADIUS),
            ("SPATIAL_CONFIDENCE", r::SPATIAL_CONFIDENCE),
            ("SPATIAL_UNTIL_HISTORY", r::SPATIAL_UNTIL_HISTORY),
            ("NORMAL_COS", r::NORMAL_COS),
            ("DEPTH_REL", r::DEPTH_REL),
            ("AGREEMENT_SCALE", r::AGREEMENT_SCALE),
            ("DIFFUSE_WIDTH", r::DIFFUSE_WIDTH),
            ("MIN_AGREEMENT_WIDTH", r::MIN_AGREEMENT_WIDTH),
            ("BRIGHT_SAME_POINT", r::BRIGHT_SAME_POINT),
        ] {
            assert_eq!(wgsl_const(super::RESAMPLING, name), value, "{name}");
        }
        for (name, value) in [
            ("BRIGHT_LIGHT_SAMPLES", r::BRIGHT_LIGHT_SAMPLES),
            (
                "BRIGHT_LIGHT_SAMPLES_BIASED",
                r::BRIGHT_LIGHT_SAMPLES_BIASED,
            ),
            ("BRIGHT_PENUMBRA_SAMPLES", r::BRIGHT_PENUMBRA_SAMPLES),
        ] {
            let samples = (super::BRIGHT.lines())
                .find_map(|l| l.strip_prefix(&format!("const {name}: u32 = ")))
                .unwrap_or_else(|| panic!("no {name} in bright.wgsl"));
            assert_eq!(samples, format!("{value}u;"), "{name}");
        }
        assert_eq!(
            wgsl_const(super::LIGHTING, "HISTORY_FULL_SCALE"),
            crate::resampling::HISTORY_FULL_SCALE
        );
    }

    /// The reloadable source is the embedded one, file for file.
    #[test]
    fn lighting_modules_are_the_files() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
        assert_eq!(
            super::lighting_source_from(&dir).unwrap(),
            super::lighting_source()
        );
    }
}
