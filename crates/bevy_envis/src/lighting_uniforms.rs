//! What the lighting pass (`lighting.rs`) tells its shader and reads back from it: the per-view
//! uniform `LightingView` (named fields, the twin of `shaders/lighting.wgsl`'s struct) and the
//! probed pixel's record. The `u32` codes are the `GpuCode`s of `envis_wgpu::codes`.

use super::ProbeResult;
use super::components::{EnvironmentSampling, EnvisEnvironment};
use bevy::camera::visibility::RenderLayers;
use bevy::prelude::*;
use bevy::render::camera::{ExtractedCamera, TemporalJitter};
use bevy::render::view::ExtractedView;
use envis::envmap::resample::SourceLayout;
use envis::render::GPixel;
use envis::sampling::Material;
use envis_wgpu::GpuCode;

/// `LightingView` of `shaders/lighting.wgsl`, field for field (offsets checked by a test).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct LightingView {
    world_from_clip: [[f32; 4]; 4],
    /// The inverse of [`EnvisEnvironment::rotation`]: world directions -> the map's.
    env_from_world: [[f32; 4]; 4],
    camera: [f32; 3],
    orthographic: u32,
    forward: [f32; 3],
    /// [`EnvisEnvironment::intensity`] x the camera's exposure.
    radiance_scale: f32,
    /// Viewport origin and size in pixels.
    viewport: [f32; 4],
    /// The probed pixel in the viewport; negative: none.
    probe_pixel: [f32; 2],
    show_background: u32,
    /// `Overlay`'s `GpuCode`.
    overlay: u32,
    accumulate: u32,
    /// [`SourceLayout::gpu_code`].
    source_layout: u32,
    /// The camera's `RenderLayers` ([`super::shadows::layers_of`]): the casters its rays meet.
    render_layers: u32,
    /// 1 where the camera resamples: the pass shows the resampling passes' image.
    pub(super) resampled: u32,
}

/// What of the view the pass needs besides its settings: Bevy's extracted view and camera, and
/// the components that change how its pixels map to the world and which casters it sees.
pub(super) struct ViewParts<'a> {
    pub ev: &'a ExtractedView,
    pub cam: &'a ExtractedCamera,
    /// TAA's sub-pixel jitter, if any: the depth buffer was rasterised with it.
    pub jitter: Option<&'a TemporalJitter>,
    pub render_layers: Option<&'a RenderLayers>,
    /// The view has a `Skybox` with an image: Bevy draws the background, and envis's defers.
    pub skybox: bool,
}

/// `clip_from_view` as the view's depth was rasterised: jittered as Bevy's
/// `prepare_view_uniforms` does under TAA, so a pixel's depth unprojects onto the surface it
/// sampled (`unjittered` would move each point off it by the jitter).
pub(super) fn rasterised_clip_from_view(
    ev: &ExtractedView,
    jitter: Option<&TemporalJitter>,
) -> Mat4 {
    let mut clip_from_view = ev.clip_from_view;
    if let Some(j) = jitter {
        j.jitter_projection(&mut clip_from_view, ev.viewport.zw().as_vec2());
    }
    clip_from_view
}

/// The pass's per-view uniform.
pub(super) fn lighting_view(
    view: ViewParts,
    sampling: &EnvironmentSampling,
    env: &EnvisEnvironment,
    layout: SourceLayout,
) -> LightingView {
    let ViewParts {
        ev,
        cam,
        jitter,
        render_layers,
        skybox,
    } = view;
    let vp = ev.viewport;
    let world_from_view = ev.world_from_view.to_matrix();
    let clip_from_view = rasterised_clip_from_view(ev, jitter);
    LightingView {
        world_from_clip: (world_from_view * clip_from_view.inverse()).to_cols_array_2d(),
        env_from_world: Mat4::from_quat(env.rotation.inverse()).to_cols_array_2d(),
        camera: ev.world_from_view.translation().to_array(),
        orthographic: (ev.clip_from_view.w_axis.w == 1.0) as u32,
        forward: ev.world_from_view.forward().as_vec3().to_array(),
        radiance_scale: env.intensity * cam.exposure,
        viewport: [vp.x as f32, vp.y as f32, vp.z as f32, vp.w as f32],
        probe_pixel: sampling
            .probe
            .map_or([-1.0, -1.0], |p| [p.x as f32, p.y as f32]),
        show_background: (env.show_background && !skybox) as u32,
        overlay: sampling.overlay.gpu_code(),
        accumulate: sampling.accumulate as u32,
        source_layout: layout.gpu_code(),
        render_layers: super::shadows::layers_of(render_layers).0,
        resampled: 0,
    }
}

/// The probed pixel's record as `lighting.wgsl` writes it: n, o, kd (w: lobe code), ks (w: lobe
/// parameter), the estimate, (x, y, index, 1 when written), (world position, 1 when shadow rays
/// were cast).
pub(super) const PROBE_RECORD: [&str; 7] = ["n", "o", "kd", "ks", "estimate", "pixel", "point"];

/// Bytes of the probe record.
pub(super) const PROBE_BYTES: u64 = PROBE_RECORD.len() as u64 * 16;

/// The probed pixel of a record read back, or `None` if no pixel wrote it this time.
pub(super) fn decode_probe(bytes: &[u8], seed: u32) -> Option<ProbeResult> {
    let v: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(bytes);
    if v.len() < PROBE_RECORD.len() || v[5][3] != 1.0 {
        return None;
    }
    let v3 = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
    Some(ProbeResult {
        pixel: UVec2::new(v[5][0] as u32, v[5][1] as u32),
        gpixel: GPixel {
            n: v3(v[0]),
            o: v3(v[1]),
            material: Material {
                kd: v3(v[2]),
                ks: v3(v[3]),
                lobe: envis_wgpu::codes::lobe_from_gpu(v[2][3] as u32, v[3][3]),
            },
        },
        estimate: v3(v[4]),
        pixel_index: v[5][2] as u32,
        seed,
        point: (v[6][3] == 1.0).then(|| v3(v[6])),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use envis_wgpu::codes::wgsl_u32_consts;

    /// The lighting pass ids in the G-buffer WGSL are Bevy's and the material's (the overlay codes are
    /// checked with the other codes in `envis_wgpu::codes`).
    #[test]
    fn lighting_pass_ids_match_bevy_and_the_material() {
        let wgsl = wgsl_u32_consts(envis_wgpu::shaders::GBUFFER);
        let id = super::super::material::ENVIS_LIGHTING_PASS_ID as u32;
        assert_eq!(wgsl["ENVIS_LIGHTING_PASS_ID"], id);
        let material = wgsl_u32_consts(include_str!("envis_material.wgsl"));
        assert_eq!(material["ENVIS_LIGHTING_PASS_ID"], id);
        assert_eq!(
            wgsl["PBR_LIGHTING_PASS_ID"],
            bevy::pbr::deferred::DEFAULT_PBR_DEFERRED_LIGHTING_PASS_ID as u32
        );
    }

    /// WGSL's uniform layout of a struct body: each field's name and byte offset, and the size.
    fn wgsl_layout(body: &str) -> (Vec<(String, usize)>, usize) {
        let (mut fields, mut at, mut max_align) = (Vec::new(), 0usize, 4usize);
        for line in body.lines().map(str::trim).filter(|l| !l.starts_with("//")) {
            let Some((name, ty)) = line.split_once(':') else {
                continue;
            };
            let (align, size) = match ty.trim().trim_end_matches(',') {
                "mat4x4<f32>" => (16, 64),
                "vec4<f32>" => (16, 16),
                "vec3<f32>" => (16, 12),
                "vec2<f32>" => (8, 8),
                "u32" | "f32" => (4, 4),
                other => panic!("no layout rule for {other}"),
            };
            at = at.next_multiple_of(align);
            fields.push((name.trim().to_string(), at));
            at += size;
            max_align = max_align.max(align);
        }
        (fields, at.next_multiple_of(max_align))
    }

    /// `name`'s fields in the WGSL `src` are `rust`'s (name, offset), in order, and its size is
    /// `rust_size`: a field out of place would show only as garbage in test images.
    pub(crate) fn assert_wgsl_struct(
        src: &str,
        name: &str,
        rust: &[(&str, usize)],
        rust_size: usize,
    ) {
        let body = src
            .split(&format!("struct {name} {{"))
            .nth(1)
            .and_then(|s| s.split('}').next())
            .unwrap_or_else(|| panic!("no struct {name} in the WGSL"));
        let (wgsl, size) = wgsl_layout(body);
        let rust: Vec<(String, usize)> = rust.iter().map(|(n, o)| (n.to_string(), *o)).collect();
        assert_eq!(wgsl, rust, "{name}");
        assert_eq!(size, rust_size, "{name}'s size");
    }

    #[test]
    fn lighting_view_matches_the_wgsl_struct() {
        use std::mem::offset_of;
        macro_rules! rust_fields {
            ($($f:ident),*) => { vec![$((stringify!($f), offset_of!(LightingView, $f))),*] };
        }
        let rust = rust_fields!(
            world_from_clip,
            env_from_world,
            camera,
            orthographic,
            forward,
            radiance_scale,
            viewport,
            probe_pixel,
            show_background,
            overlay,
            accumulate,
            source_layout,
            render_layers,
            resampled
        );
        assert_wgsl_struct(
            envis_wgpu::shaders::LIGHTING,
            "LightingView",
            &rust,
            std::mem::size_of::<LightingView>(),
        );
    }
}
