// envis — Bevy's deferred G-buffer as envis reads it: which pixels are ours to light and their
// materials (GPixel). Shared by the lighting pass (lighting.wgsl) and the resampling pass's
// gather (gather.wgsl). Needs common.wgsl before it. Which pixels, by Bevy's deferred lighting
// pass id:
//   1 (StandardMaterial): base colour, metallic, perceptual roughness, reflectance and diffuse
//     occlusion -> Lambert kd = base (1 - metallic) occlusion plus GGX with Schlick's Fresnel,
//     F0 = 0.16 reflectance^2 (1 - metallic) + base metallic, alpha = clamp(roughness, 0.089, 1)^2
//     (Bevy's conventions); unlit materials are left alone;
//   231 (EnvisMaterial, bevy_envis/src/material.rs): kd, ks (8-bit), lobe kind, exact lobe parameter;
//   anything else (forward meshes, other deferred materials): left alone.

const PBR_LIGHTING_PASS_ID: u32 = 1u;
// bevy_envis::material::ENVIS_LIGHTING_PASS_ID.
const ENVIS_LIGHTING_PASS_ID: u32 = 231u;
const DEFERRED_FLAGS_UNLIT_BIT: u32 = 1u;

// Bevy's octahedral decode (bevy_pbr utils.wgsl) of a [0, 1]^2 point.
fn octahedral_decode(v: vec2<f32>) -> vec3<f32> {
    let f = v * 2.0 - 1.0;
    var n = vec3(f.xy, 1.0 - abs(f.x) - abs(f.y));
    let t = saturate(-n.z);
    let w = select(vec2(t), vec2(-t), n.xy >= vec2(0.0));
    n = vec3(n.xy + w, n.z);
    return normalize(n);
}

fn gbuffer_normal(packed: u32) -> vec3<f32> {
    let oct = vec2(f32(packed & 0xFFFu), f32((packed >> 12u) & 0xFFFu)) / 4095.0;
    return octahedral_decode(oct);
}

// A StandardMaterial texel of Bevy's deferred G-buffer (pbr_deferred_functions.wgsl) -> the
// matching envis material (see the header).
fn decode_standard(g: vec4<u32>, o: vec3<f32>) -> GPixel {
    let base_rough = unpack4x8unorm(g.r);
    let base = pow(base_rough.rgb, vec3(2.2));
    let pr = clamp(base_rough.a, 0.089, 1.0);
    let props = unpack4x8unorm(g.b);
    let reflectance = props.r;
    let metallic = props.g;
    let occlusion = props.b;
    let kd = base * (1.0 - metallic) * occlusion;
    let f0 = vec3(0.16 * reflectance * reflectance * (1.0 - metallic)) + base * metallic;
    return GPixel(vec4(gbuffer_normal(g.a), 1.0), vec4(o, 0.0), vec4(kd, f32(LOBE_GGX_SCHLICK)), vec4(f0, pr * pr));
}

// An EnvisMaterial texel (bevy_envis/src/material.rs).
fn decode_envis(g: vec4<u32>, o: vec3<f32>) -> GPixel {
    let kd = unpack4x8unorm(g.x);
    let ks = pow(unpack4x8unorm(g.y).rgb, vec3(2.2));
    let lobe = round(kd.a * 255.0);
    return GPixel(vec4(gbuffer_normal(g.w), 1.0), vec4(o, 0.0), vec4(pow(kd.rgb, vec3(2.2)), lobe), vec4(ks, bitcast<f32>(g.z)));
}

// Whether a pixel of pass id `pass_id` and G-buffer texel `g` is lit by envis.
fn ours_to_light(pass_id: u32, g: vec4<u32>) -> bool {
    let standard = pass_id == PBR_LIGHTING_PASS_ID && ((g.a >> 24u) & DEFERRED_FLAGS_UNLIT_BIT) == 0u;
    return standard || pass_id == ENVIS_LIGHTING_PASS_ID;
}

// The material of a pixel ours to light, seen from direction o (world frame; n.w = 1).
fn decode_gbuffer(pass_id: u32, g: vec4<u32>, o: vec3<f32>) -> GPixel {
    if (pass_id == PBR_LIGHTING_PASS_ID) {
        return decode_standard(g, o);
    }
    return decode_envis(g, o);
}
