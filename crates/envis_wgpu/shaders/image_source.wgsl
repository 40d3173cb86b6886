// envis — reading an environment straight from a Bevy `Image` texture (twin of
// envmap::resample::latlong_bilinear / cube_bilinear). The texture is bound as a 2D array: one
// layer for a 2:1 lat-long image (Mitsuba's convention, +Y up), six for a cube image in Bevy's
// convention (layers +X -X +Y -Y +Z -Z, left-handed: world direction d is looked up at
// (d.x, d.y, -d.z), as Bevy's skybox and environment light do). Texels are read with textureLoad
// (Rgba32Float is not filterable everywhere) and filtered by hand; non-finite and negative values
// read as 0, the same clamp the distribution build applies and counts. Needs common.wgsl.

const SOURCE_LATLONG: u32 = 0u;
const SOURCE_CUBE: u32 = 1u;

fn source_texel(src: texture_2d_array<f32>, x: i32, y: i32, layer: i32) -> vec3<f32> {
    let c = textureLoad(src, vec2(x, y), layer, 0).rgb;
    return vec3(sanitize_channel(c.x), sanitize_channel(c.y), sanitize_channel(c.z));
}

// envmap::resample::latlong_bilinear: wraps in u, clamps in v.
fn latlong_bilinear(src: texture_2d_array<f32>, d: vec3<f32>) -> vec3<f32> {
    let dims = vec2<i32>(textureDimensions(src));
    let uv = dir_to_latlong(d);
    let x = uv.x * f32(dims.x) - 0.5;
    let y = clamp(uv.y * f32(dims.y) - 0.5, 0.0, f32(dims.y - 1));
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi0 = ((i32(x0) % dims.x) + dims.x) % dims.x;
    let xi1 = ((i32(x0) + 1) % dims.x + dims.x) % dims.x;
    let yi0 = i32(y0);
    let yi1 = min(yi0 + 1, dims.y - 1);
    let top = source_texel(src, xi0, yi0, 0) * (1.0 - fx) + source_texel(src, xi1, yi0, 0) * fx;
    let bot = source_texel(src, xi0, yi1, 0) * (1.0 - fx) + source_texel(src, xi1, yi1, 0) * fx;
    return top * (1.0 - fy) + bot * fy;
}

// envmap::resample::cube_bilinear on Bevy's cube layers: bilinear within the face d falls in.
fn cube_bilinear(src: texture_2d_array<f32>, d: vec3<f32>) -> vec3<f32> {
    let n = i32(textureDimensions(src).x);
    let hit = dir_to_texel(vec3(d.x, d.y, -d.z), 1u);
    let face = i32(hit.face);
    let x = clamp(0.5 * (hit.a + 1.0) * f32(n) - 0.5, 0.0, f32(n - 1));
    let y = clamp(0.5 * (hit.b + 1.0) * f32(n) - 0.5, 0.0, f32(n - 1));
    let x0 = i32(floor(x));
    let y0 = i32(floor(y));
    let x1 = min(x0 + 1, n - 1);
    let y1 = min(y0 + 1, n - 1);
    let fx = x - f32(x0);
    let fy = y - f32(y0);
    let top = source_texel(src, x0, y0, face) * (1.0 - fx) + source_texel(src, x1, y0, face) * fx;
    let bot = source_texel(src, x0, y1, face) * (1.0 - fx) + source_texel(src, x1, y1, face) * fx;
    return top * (1.0 - fy) + bot * fy;
}

// The source texel direction d falls in, unfiltered: the radiance of light and BRDF samples
// (SourceImage::radiance_nearest). Filtering would spread a small sun into neighbouring texels of
// low density: still unbiased, but heavy-tailed.
fn source_nearest(src: texture_2d_array<f32>, kind: u32, d: vec3<f32>) -> vec3<f32> {
    let dims = vec2<i32>(textureDimensions(src));
    if (kind == SOURCE_CUBE) {
        let hit = dir_to_texel(vec3(d.x, d.y, -d.z), u32(dims.x));
        return source_texel(src, i32(hit.col), i32(hit.row), i32(hit.face));
    }
    let uv = dir_to_latlong(d);
    let x = min(i32(uv.x * f32(dims.x)), dims.x - 1);
    let y = min(i32(uv.y * f32(dims.y)), dims.y - 1);
    return source_texel(src, x, y, 0);
}

// Radiance of the source image in direction d (environment space), filtered: the background.
fn source_radiance(src: texture_2d_array<f32>, kind: u32, d: vec3<f32>) -> vec3<f32> {
    if (kind == SOURCE_CUBE) {
        return cube_bilinear(src, d);
    }
    return latlong_bilinear(src, d);
}
