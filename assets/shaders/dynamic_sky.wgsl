// crates/bevy_envis/examples/dynamic_sky.rs: a procedural sky written into a 2:1 lat-long storage texture every
// frame (Mitsuba's convention, +Y up, the one envis reads): a blue gradient, a grey ground and a
// small, very bright sun that circles the sky.

@group(0) @binding(0) var sky: texture_storage_2d<rgba32float, write>;
@group(0) @binding(1) var<uniform> params: SkyParams;

struct SkyParams {
    // xyz: unit direction towards the sun; w: the sun's radiance.
    sun: vec4<f32>,
}

const PI: f32 = 3.14159265358979;
// The sun's angular radius: 2 degrees.
const SUN_COS: f32 = 0.99939083;

@compute @workgroup_size(8, 8, 1)
fn paint(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(sky);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let u = (f32(id.x) + 0.5) / f32(size.x);
    let v = (f32(id.y) + 0.5) / f32(size.y);
    let p = 2.0 * PI * u;
    let t = PI * v;
    let d = vec3(sin(t) * sin(p), cos(t), -sin(t) * cos(p));
    var c = vec3(0.18, 0.17, 0.15);
    if (d.y > 0.0) {
        c = mix(vec3(0.75, 0.85, 1.0), vec3(0.2, 0.35, 0.8), sqrt(d.y));
    }
    if (dot(d, params.sun.xyz) > SUN_COS) {
        c = vec3(params.sun.w);
    }
    textureStore(sky, vec2<i32>(id.xy), vec4(c, 1.0));
}
