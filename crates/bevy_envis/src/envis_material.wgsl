// envis — EnvisMaterial's deferred fragment shader: writes an envis BRDF into Bevy's G-buffer
// under envis's lighting pass id (layout in bevy_envis/src/material.rs; decoded by
// shaders/lighting.wgsl). Normal and motion-vector outputs follow bevy_pbr's prepass.wgsl.

#import bevy_pbr::{
    prepass_bindings,
    prepass_io::{VertexOutput, FragmentOutput},
    mesh_view_bindings::view,
    utils::octahedral_encode,
}

struct EnvisMaterialUniform {
    // rgb: diffuse albedo; w: the lobe's code (LOBE_* of shaders/sampling.wgsl, Lobe::gpu_code).
    kd: vec4<f32>,
    // rgb: specular albedo; w: Phong exponent or GGX alpha.
    ks: vec4<f32>,
}

@group(#{MATERIAL_BIND_GROUP}) @binding(0) var<uniform> material: EnvisMaterialUniform;

// material::ENVIS_LIGHTING_PASS_ID.
const ENVIS_LIGHTING_PASS_ID: u32 = 231u;

@fragment
fn fragment(in: VertexOutput, @builtin(front_facing) is_front: bool) -> FragmentOutput {
    var out: FragmentOutput;
    var n = normalize(in.world_normal);
    if (!is_front) {
        n = -n;
    }
#ifdef NORMAL_PREPASS
    out.normal = vec4(n * 0.5 + vec3(0.5), 1.0);
#endif
#ifdef UNCLIPPED_DEPTH_ORTHO_EMULATION
    out.frag_depth = in.unclipped_depth;
#endif
#ifdef MOTION_VECTOR_PREPASS
    let clip_position_t = view.unjittered_clip_from_world * in.world_position;
    let clip_position = clip_position_t.xy / clip_position_t.w;
    let previous_clip_position_t = prepass_bindings::previous_view_uniforms.clip_from_world * in.previous_world_position;
    let previous_clip_position = previous_clip_position_t.xy / previous_clip_position_t.w;
    out.motion_vector = (clip_position - previous_clip_position) * vec2(0.5, -0.5);
#endif
#ifdef DEFERRED_PREPASS
    let oct = octahedral_encode(n);
    let nx = u32(saturate(oct.x) * 4095.0 + 0.5);
    let ny = u32(saturate(oct.y) * 4095.0 + 0.5);
    out.deferred = vec4(
        pack4x8unorm(vec4(pow(saturate(material.kd.rgb), vec3(1.0 / 2.2)), material.kd.w / 255.0)),
        pack4x8unorm(vec4(pow(saturate(material.ks.rgb), vec3(1.0 / 2.2)), 0.0)),
        bitcast<u32>(material.ks.w),
        (nx & 0xFFFu) | ((ny & 0xFFFu) << 12u),
    );
    out.deferred_lighting_pass_id = ENVIS_LIGHTING_PASS_ID;
#endif
    return out;
}
