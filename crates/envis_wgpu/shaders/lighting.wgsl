// envis — the Bevy lighting pass: a fullscreen triangle over the view's viewport whose fragment
// decodes Bevy's deferred G-buffer, runs `shade` (shade.wgsl, the twin of render::shade_pixel) and
// ADDS the environment's radiance to what Bevy's deferred lighting wrote (its lights, shadows,
// emissive); pixels without geometry show the environment image at full resolution. Needs
// common.wgsl, sampling.wgsl, shade.wgsl, image_source.wgsl and gbuffer.wgsl before it.
//
// The output is premultiplied: the pipeline blends src + (1 - src.a) dst, so alpha 0 adds (lit
// pixels) and alpha 1 replaces (the background, overlays).
//
// Which pixels it lights, and their materials: gbuffer.wgsl.

struct LightingView {
    world_from_clip: mat4x4<f32>,
    // The inverse of EnvisEnvironment::rotation: world directions -> the map's.
    env_from_world: mat4x4<f32>,
    // Camera position (world); 1 for an orthographic projection.
    camera: vec3<f32>,
    orthographic: u32,
    // Camera forward (world); the radiance scale (intensity x exposure).
    forward: vec3<f32>,
    radiance_scale: f32,
    // Viewport origin and size in pixels.
    viewport: vec4<f32>,
    // The probed pixel in the viewport (negative: none).
    probe_pixel: vec2<f32>,
    // 1 to draw the environment where there is no geometry.
    show_background: u32,
    // OVERLAY_*.
    overlay: u32,
    // 1 to average frames (the pass clears the running mean at each restart; each pixel keeps
    // its own count in it).
    accumulate: u32,
    // SOURCE_* (image_source.wgsl).
    source_layout: u32,
    // The camera's RenderLayers as visibility::Layers: the shadow casters it sees.
    render_layers: u32,
    // 1 where the camera resamples (EnvironmentResampling): the image is the one the
    // resampling passes made before this one, bound as `accum`.
    resampled: u32,
}
// The shadow BVH's node count is sp.bvh_nodes (shade.wgsl's ShadeParams; 0: no shadow rays).

// envis_wgpu::codes's GpuCode for Overlay.
const OVERLAY_NONE: u32 = 0u;
const OVERLAY_EFFECTIVE_SAMPLES: u32 = 1u;
const OVERLAY_WASTED: u32 = 2u;
const OVERLAY_COUNTS_DIFFERENCE: u32 = 3u;
const OVERLAY_HISTORY: u32 = 4u;
// The confidence the history overlay draws red (envis_wgpu::resampling::HISTORY_FULL_SCALE).
const HISTORY_FULL_SCALE: f32 = 20.0;

@group(0) @binding(0) var gbuffer: texture_2d<u32>;
@group(0) @binding(1) var depth_tex: texture_depth_2d;
@group(0) @binding(2) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> pool: array<vec4<f32>>;
// Per region (face, or tile) four vec4: its corners (xyz), its energy in the first one's w.
@group(0) @binding(4) var<storage, read> regions: array<vec4<f32>>;
@group(0) @binding(5) var<uniform> sp: ShadeParams;
@group(0) @binding(6) var<uniform> lv: LightingView;
// The probed pixel, for the sample-debug view: n, o, kd, ks (as GPixel), estimate, (x, y, index,
// 1), (world position, 1 when shadow rays were cast).
@group(0) @binding(7) var<storage, read_write> probe: array<vec4<f32>, 7>;
// Running mean of the accumulated frames and how many each pixel averaged (w), one per viewport
// pixel (bound only when accumulating; cleared at each restart). Where the camera resamples
// (lv.resampled) it is the resampling passes' image instead, read only (w: the reservoir's
// confidence M): one binding for both keeps the fragment stage at 8 storage buffers, WebGPU's
// default limit.
@group(0) @binding(8) var<storage, read_write> accum: array<vec4<f32>>;
// The `global` distribution (global_layout.wgsl); a dummy unless the strategy is global.
@group(0) @binding(9) var<storage, read> cdfs: array<f32>;
// Bevy's deferred lighting pass id of each pixel.
@group(0) @binding(10) var pass_ids: texture_2d<u32>;
// The environment image itself (image_source.wgsl), for the background.
@group(0) @binding(11) var source: texture_2d_array<f32>;
// The scene's shadow-casting meshes as a BVH (visibility.wgsl; placeholders when off).
@group(0) @binding(12) var<storage, read> bvh_nodes: array<BvhNode>;
@group(0) @binding(13) var<storage, read> bvh_triangles: array<array<vec4<f32>, 3>>;

// Sample radiance comes from the full-resolution image (the texel a direction falls in); the
// texel table gives only densities (render::FrameData::fine is the CPU twin).
fn env_radiance(d: vec3<f32>, coarse: vec3<f32>) -> vec3<f32> {
    return source_nearest(source, lv.source_layout, d);
}

// The radiance and, in w, the sub-texel factor of direction d. The pass samples uniformly
// inside the distribution's texels (no sub-texel level, unlike the headless backend's refined
// pool: subtexel.wgsl), so a direction's density is the texel's: the factor is 1.
fn env_radiance_factor(d: vec3<f32>, coarse: vec3<f32>) -> vec4<f32> {
    return vec4(env_radiance(d, coarse), 1.0);
}

// The shading point in world space and the map's rotation back to world space, set by the
// fragment before it shades (shade.wgsl's hooks take only the pixel and a direction).
var<private> shadow_point: vec3<f32>;
var<private> world_from_env: mat3x3<f32>;

// A shadow ray through the scene's meshes (bevy_envis::shadows), from the shading point; no rays when
// the camera's shadows are off (node count 0). Directions arrive in the map's frame.
fn sample_blocked(px: GPixel, pixel_index: u32, d: vec3<f32>) -> bool {
    if (sp.bvh_nodes == 0u) {
        return false;
    }
    let dw = world_from_env * d;
    let o = shadow_origin(shadow_point, world_from_env * px.n.xyz, dw);
    return bvh_occluded(o, dw, 1e-4, 3.4028235e38, sp.bvh_nodes, lv.render_layers);
}

// Blue -> cyan -> green -> yellow -> red for t in [0, 1].
fn heat(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0) * 4.0;
    return clamp(vec3(x - 2.0, select(x, 4.0 - x, x > 2.0), 2.0 - x), vec3(0.0), vec3(1.0));
}

@vertex
fn fullscreen(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32(i >> 1u), f32(i & 1u)) * 2.0;
    return vec4(uv * vec2(2.0, -2.0) + vec2(-1.0, 1.0), 0.0, 1.0);
}

// The pixel's normalised device coordinates.
fn pixel_ndc(pos: vec4<f32>) -> vec2<f32> {
    let uv = (pos.xy - lv.viewport.xy) / lv.viewport.zw;
    return vec2(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
}

// The map's frame from world space (the inverse of EnvisEnvironment::rotation).
fn env_from_world() -> mat3x3<f32> {
    return mat3x3(lv.env_from_world[0].xyz, lv.env_from_world[1].xyz, lv.env_from_world[2].xyz);
}

// Where there is no geometry (reverse-Z far plane): the environment image in the direction of
// the pixel's ray, or what Bevy drew there.
fn background(pos: vec4<f32>) -> vec4<f32> {
    if (lv.show_background == 0u) {
        return vec4(0.0);
    }
    var dir = lv.forward;
    if (lv.orthographic == 0u) {
        let p = lv.world_from_clip * vec4(pixel_ndc(pos), 1.0, 1.0);
        dir = p.xyz / p.w - lv.camera;
    }
    let d = normalize(env_from_world() * dir);
    return vec4(source_radiance(source, lv.source_layout, d) * lv.radiance_scale, 1.0);
}

// The pixel's index in the viewport (the accumulation's and the resampled image's).
fn viewport_index(pos: vec4<f32>) -> u32 {
    let local = vec2<u32>(max(pos.xy - lv.viewport.xy, vec2(0.0)));
    return local.y * u32(lv.viewport.z) + local.x;
}

// The pass where the camera resamples and shows no overlay (lv.resampled): the resampling
// passes' image where `lighting` would shade, its background elsewhere. An entry point of its
// own: through `lighting`'s early return the same image cost lavapipe 23 ms a 192² frame, this
// way 3.6 ms (its fragment stage is compiled from what the entry point uses; docs/temporal.md).
@fragment
fn show_resampled(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let coord = vec2<i32>(floor(pos.xy));
    if (textureLoad(depth_tex, coord, 0) <= 0.0) {
        return background(pos);
    }
    if (!ours_to_light(textureLoad(pass_ids, coord, 0).r, textureLoad(gbuffer, coord, 0))) {
        return vec4(0.0);
    }
    return vec4(accum[viewport_index(pos)].xyz * lv.radiance_scale, 0.0);
}

@fragment
fn lighting(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let coord = vec2<i32>(floor(pos.xy));
    let depth = textureLoad(depth_tex, coord, 0);
    let ndc = pixel_ndc(pos);
    let ortho = lv.orthographic != 0u;
    let scale = lv.radiance_scale;
    let env = env_from_world();
    if (depth <= 0.0) {
        return background(pos);
    }
    let pass_id = textureLoad(pass_ids, coord, 0).r;
    let g = textureLoad(gbuffer, coord, 0);
    if (!ours_to_light(pass_id, g)) {
        return vec4(0.0);
    }
    let wp = lv.world_from_clip * vec4(ndc, depth, 1.0);
    let world = wp.xyz / wp.w;
    var o = -lv.forward;
    if (!ortho) {
        o = normalize(lv.camera - world);
    }
    // Shade in the map's frame: rotating normal and view together leaves the BRDF unchanged.
    o = env * o;
    shadow_point = world;
    world_from_env = transpose(env);
    var px = decode_gbuffer(pass_id, g, o);
    px.n = vec4(env * px.n.xyz, 1.0);
    let local = vec2<u32>(max(pos.xy - lv.viewport.xy, vec2(0.0)));
    let pixel_index = viewport_index(pos);
    if (lv.overlay == OVERLAY_HISTORY) {
        return vec4(heat(select(0.0, accum[pixel_index].w, lv.resampled != 0u) / HISTORY_FULL_SCALE), 1.0);
    }
    if (lv.resampled != 0u && lv.overlay == OVERLAY_NONE) {
        // The resampled image replaces this pass's estimate (and its accumulation: reuse
        // across frames is the resampling's own).
        return vec4(accum[pixel_index].xyz * scale, 0.0);
    }
    let r = shade(px, pixel_index);
    if (all(vec2<f32>(local) == lv.probe_pixel)) {
        probe[0] = px.n;
        probe[1] = px.o;
        probe[2] = px.kd;
        probe[3] = px.ks;
        probe[4] = vec4(r.color, 1.0);
        probe[5] = vec4(f32(local.x), f32(local.y), f32(pixel_index), 1.0);
        probe[6] = vec4(world, select(0.0, 1.0, sp.bvh_nodes > 0u));
    }
    if (lv.overlay == OVERLAY_EFFECTIVE_SAMPLES) {
        // Samples this pixel evaluated (used light samples + BRDF samples) over its budget.
        let used = f32(r.stats.y + r.stats.z + r.stats.w);
        return vec4(heat(used / max(f32(sp.nl + sp.nb), 1.0)), 1.0);
    }
    if (lv.overlay == OVERLAY_WASTED) {
        // Fraction of the light samples used that had a negative cosine (the paper's yellow).
        let light = r.stats.y + r.stats.z;
        return vec4(heat(select(0.0, f32(r.stats.z) / f32(light), light > 0u)), 1.0);
    }
    if (lv.overlay == OVERLAY_COUNTS_DIFFERENCE) {
        // Where integer counts differ from fractional ones (where integer counts pop).
        let other = shade_counts(px, pixel_index, select(COUNTS_FRACTIONAL, COUNTS_INTEGER, sp.counts == COUNTS_FRACTIONAL));
        let d = length(r.color - other.color) / max(length(r.color), 1e-3);
        return vec4(heat(d * 4.0), 1.0);
    }
    var color = r.color;
    if (lv.accumulate != 0u && lv.resampled == 0u) {
        // The pixel's own count (w) of the frames it averaged since the restart (the buffer is
        // cleared then): a pixel not shaded in some frame (no geometry yet) is not averaged
        // with a zero for it.
        let prev = accum[pixel_index];
        color = prev.xyz + (color - prev.xyz) / (prev.w + 1.0);
        accum[pixel_index] = vec4(color, prev.w + 1.0);
    }
    return vec4(color * scale, 0.0);
}

// Where a used sample goes (render::estimator's Sink for Vec3): summed into the pixel's colour.
fn emit(res: ptr<function, Shaded>, dir: vec3<f32>, fl: vec3<f32>, cos: f32, scale: f32) {
    (*res).color += fl * scale;
}
