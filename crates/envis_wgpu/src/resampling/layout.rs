//! What the resampling passes read and write, laid out as `shaders/resampling.wgsl` and
//! `shaders/reservoir.wgsl` declare it: reservoirs, surfaces, the split map and the bright
//! part's table, the reprojection, and the passes' parameters.

use super::super::shading::GpuGPixel;
use envis::render::GPixel;
use envis::render::resampling::{Reservoir, Split, Surface};
use glam::Vec3;

/// A [`Reservoir`] as the shaders hold it (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuReservoir {
    pub dir: [f32; 3],
    pub ucw: f32,
    pub rgb: [f32; 3],
    pub p_hat: f32,
    pub m: f32,
    pub visible: u32,
    pub penumbra: u32,
    pub pad: u32,
}

impl From<GpuReservoir> for Reservoir {
    fn from(q: GpuReservoir) -> Self {
        Reservoir {
            dir: q.dir.into(),
            ucw: q.ucw,
            m: q.m,
            target: q.p_hat,
            rgb: q.rgb.into(),
            visible: q.visible != 0,
            penumbra: q.penumbra != 0,
        }
    }
}

/// A pixel as reuse reads it (96 bytes): its G-buffer texel, its surface point and distance
/// from the camera, its object.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuSurface {
    px: GpuGPixel,
    p: [f32; 4],
    id: [u32; 4],
}

/// Per pixel: the G-buffer, the point and the [`Surface`].
pub fn surfaces(gbuf: &[Option<GPixel>], points: &[Vec3], surf: &[Surface]) -> Vec<GpuSurface> {
    (gbuf.iter().zip(points).zip(surf))
        .map(|((g, p), s)| GpuSurface {
            px: GpuGPixel::from(g),
            p: p.extend(s.depth).to_array(),
            id: [s.id, 0, 0, 0],
        })
        .collect()
}

/// The split map as `split_tex`: per cube texel the rest's radiance, then the bright part's with
/// its probability ([`envis::render::resampling::BrightLight`]'s `bin_pmf`) in `w`; and the
/// bright part's CDF and texel indices (empty without one).
pub fn split_tables(split: &Split) -> (Vec<[f32; 4]>, Vec<f32>, Vec<u32>) {
    let mut tex: Vec<[f32; 4]> = (split.rest.data.iter())
        .flat_map(|l| [l.extend(0.0).to_array(), [0.0; 4]])
        .collect();
    let mut ids = Vec::new();
    for (t, l, pmf) in split.bright.texels() {
        tex[2 * t as usize + 1] = l.extend(pmf).to_array();
        ids.push(t);
    }
    (tex, split.bright.cdf().to_vec(), ids)
}

/// Per pixel, where it was in the previous frame: `(pixel, bits of the distance)`, or
/// `u32::MAX` for none.
pub fn reprojection(map: &[Option<(usize, f32)>]) -> Vec<[u32; 2]> {
    map.iter()
        .map(|r| match r {
            Some((q, depth)) => [*q as u32, depth.to_bits()],
            None => [u32::MAX, 0],
        })
        .collect()
}

/// `shaders/resampling.wgsl`'s `ResampleParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ResampleParams {
    pub width: u32,
    pub height: u32,
    pub n: u32,
    pub prev_n: u32,
    pub bright_count: u32,
    pub history: u32,
    pub bright_history: u32,
    pub temporal: u32,
    pub spatial: u32,
    pub max_history: f32,
    pub unbiased: u32,
    pub seed: u32,
    pub bvh_nodes: u32,
    pub prev_bvh_nodes: u32,
    /// The shadow casters seen (`visibility::Layers`' bits; all of them headless).
    pub layers: u32,
    /// How far this frame's map and the history's agree as light
    /// ([`envis::render::resampling::map_agreement`]): the rest's history confidence is scaled
    /// by it.
    pub map_agreement: f32,
    /// 1 where nothing that casts shadows moved since the previous frame
    /// ([`envis::render::resampling::History::still_geometry`]).
    pub still_geometry: u32,
    pub _pad: [u32; 3],
    /// The rotation from the map's frame (normals, view and sample directions) to the world's
    /// (points, the shadow BVH): a `mat3x3<f32>`'s three padded columns.
    pub world_from_map: [[f32; 4]; 3],
}

impl ResampleParams {
    /// `world_from_map` where the map's frame is the world's.
    pub const MAP_IS_WORLD: [[f32; 4]; 3] = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
}

// The WGSL structs' sizes: a field added on one side only fails the build, not a test.
const _: () = assert!(size_of::<GpuReservoir>() == 48);
const _: () = assert!(size_of::<GpuSurface>() == 96);
const _: () = assert!(size_of::<ResampleParams>() == 128);
