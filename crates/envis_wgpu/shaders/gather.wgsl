// envis — the Bevy resampling pass's gather: what resampling.wgsl's passes read, made from Bevy's
// prepass textures instead of the CPU's Screen (the twin of resampling::Screen and
// sequence::Posed::reproject): per viewport pixel its surface (the decoded G-buffer texel, n and
// o in the map's frame, the world point and its distance from the camera) and where it was in
// the previous frame (from the motion vectors); per cube texel the split map (the whole map as
// the rest: the Bevy pass has no bright part). Needs common.wgsl, sampling.wgsl and
// gbuffer.wgsl before it.

struct GatherView {
    world_from_clip: mat4x4<f32>,
    // The inverse of EnvisEnvironment::rotation: world directions -> the map's.
    env_from_world: mat4x4<f32>,
    // Camera position and forward (world), this frame and the previous one.
    camera: vec3<f32>,
    orthographic: u32,
    forward: vec3<f32>,
    // 1 where there is a previous frame to reproject into.
    has_prev: u32,
    prev_camera: vec3<f32>,
    // Cube texels of the split map (6 n^2).
    texel_count: u32,
    prev_forward: vec3<f32>,
    _pad: u32,
    // Viewport origin and size in pixels.
    viewport: vec4<f32>,
}

// resampling.wgsl's Surface.
struct GatherSurface {
    px: GPixel,
    p: vec4<f32>,
    id: vec4<u32>,
}

@group(0) @binding(0) var gbuffer: texture_2d<u32>;
@group(0) @binding(1) var depth_tex: texture_depth_2d;
@group(0) @binding(2) var pass_ids: texture_2d<u32>;
@group(0) @binding(3) var motion_vectors: texture_2d<f32>;
@group(0) @binding(4) var<uniform> gv: GatherView;
@group(0) @binding(5) var<storage, read> texels: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> surfaces: array<GatherSurface>;
@group(0) @binding(7) var<storage, read_write> reproject: array<vec2<u32>>;
@group(0) @binding(8) var<storage, read_write> split_tex: array<vec4<f32>>;

// A point's distance from a camera as the depth test compares it (along the view axis for an
// orthographic camera).
fn view_distance(p: vec3<f32>, camera: vec3<f32>, forward: vec3<f32>) -> f32 {
    if (gv.orthographic != 0u) {
        return dot(p - camera, forward);
    }
    return length(p - camera);
}

@compute @workgroup_size(64)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = linear_id(gid, nwg, 64u);
    let size = vec2<u32>(gv.viewport.zw);
    if (i >= size.x * size.y) {
        return;
    }
    let local = vec2(i % size.x, i / size.x);
    let coord = vec2<i32>(vec2<u32>(gv.viewport.xy) + local);
    surfaces[i] = GatherSurface(GPixel(vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0)), vec4(0.0), vec4(0u));
    reproject[i] = vec2(0xffffffffu, 0u);
    let depth = textureLoad(depth_tex, coord, 0);
    let pass_id = textureLoad(pass_ids, coord, 0).r;
    let g = textureLoad(gbuffer, coord, 0);
    if (depth <= 0.0 || !ours_to_light(pass_id, g)) {
        return;
    }
    let uv = (vec2<f32>(local) + 0.5) / gv.viewport.zw;
    let ndc = vec2(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0);
    let wp = gv.world_from_clip * vec4(ndc, depth, 1.0);
    let world = wp.xyz / wp.w;
    var o = -gv.forward;
    if (gv.orthographic == 0u) {
        o = normalize(gv.camera - world);
    }
    // In the map's frame, as the lighting pass shades: the BRDF is unchanged by a rotation of
    // normal and view together; the shadow rays rotate back (ResampleParams::world_from_map).
    let env = mat3x3(gv.env_from_world[0].xyz, gv.env_from_world[1].xyz, gv.env_from_world[2].xyz);
    var px = decode_gbuffer(pass_id, g, env * o);
    px.n = vec4(env * px.n.xyz, 1.0);
    // No object ids in Bevy's G-buffer: the geometric tests are normal and depth alone.
    surfaces[i] = GatherSurface(px, vec4(world, view_distance(world, gv.camera, gv.forward)), vec4(0u));
    if (gv.has_prev == 0u) {
        return;
    }
    // Bevy's motion vectors: this frame's uv minus the previous frame's.
    let prev_uv = uv - textureLoad(motion_vectors, coord, 0).xy;
    if (any(prev_uv < vec2(0.0)) || any(prev_uv >= vec2(1.0))) {
        return;
    }
    let q = vec2<u32>(prev_uv * gv.viewport.zw);
    // The distance the point had from the previous camera, as if it did not move (a moving
    // object's point was elsewhere: off by its motion in one frame, inside DEPTH_REL).
    let prev_depth = view_distance(world, gv.prev_camera, gv.prev_forward);
    reproject[i] = vec2(q.y * size.x + q.x, bitcast<u32>(prev_depth));
}

// The whole map as the rest (w 0), no bright part.
@compute @workgroup_size(64)
fn gather_split(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let t = linear_id(gid, nwg, 64u);
    if (t >= gv.texel_count) {
        return;
    }
    split_tex[2u * t] = vec4(texels[t].xyz, 0.0);
    split_tex[2u * t + 1u] = vec4(0.0);
}
