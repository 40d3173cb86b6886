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

/// What one frame's [`ResampleParams`] are made of, as both recorders of the passes know it
/// (the headless twin, `GpuResampler`, and the Bevy pass): [`ResampleParams::for_frame`] is the
/// one place the uniform is made, so the two cannot drift apart.
#[derive(Clone, Copy, Debug)]
pub struct FrameReuse {
    pub width: u32,
    pub height: u32,
    /// The face size of this frame's map (of its rest, where the bright part is apart).
    pub face_size: u32,
    /// The face size of the history's map, where a history is reused (`None`: none).
    pub prev_face_size: Option<u32>,
    /// Texels of the bright part (0: the map is resampled whole).
    pub bright_count: u32,
    /// The history's bright part is the same light as this frame's: its history is reused.
    pub bright_history: bool,
    pub temporal: bool,
    /// Spatial neighbours (clamped to [`super::MAX_SPATIAL`]).
    pub spatial: u32,
    /// The cap on a reservoir's confidence (at least 1).
    pub max_history: u32,
    pub unbiased: bool,
    pub seed: u32,
    /// Nodes of this frame's shadow BVH and of the history's (0: none).
    pub bvh_nodes: u32,
    pub prev_bvh_nodes: u32,
    /// The shadow casters seen (`u32::MAX`: all).
    pub layers: u32,
    /// See [`ResampleParams::map_agreement`].
    pub map_agreement: f32,
    /// See [`ResampleParams::still_geometry`].
    pub still_geometry: bool,
    /// The rotation from the map's frame to the world's.
    pub world_from_map: glam::Mat3,
}

impl ResampleParams {
    /// The uniform of one frame.
    pub fn for_frame(f: &FrameReuse) -> Self {
        let m = f.world_from_map;
        ResampleParams {
            width: f.width,
            height: f.height,
            n: f.face_size,
            prev_n: f.prev_face_size.unwrap_or(0),
            bright_count: f.bright_count,
            history: f.prev_face_size.is_some() as u32,
            bright_history: f.bright_history as u32,
            temporal: f.temporal as u32,
            spatial: f.spatial.min(super::MAX_SPATIAL),
            max_history: f.max_history.max(1) as f32,
            unbiased: f.unbiased as u32,
            seed: f.seed,
            bvh_nodes: f.bvh_nodes,
            prev_bvh_nodes: f.prev_bvh_nodes,
            layers: f.layers,
            map_agreement: f.map_agreement,
            still_geometry: f.still_geometry as u32,
            _pad: [0; 3],
            world_from_map: [m.x_axis, m.y_axis, m.z_axis].map(|c| c.extend(0.0).to_array()),
        }
    }
}

// The WGSL structs' sizes: a field added on one side only fails the build, not a test.
const _: () = assert!(size_of::<GpuReservoir>() == 48);
const _: () = assert!(size_of::<GpuSurface>() == 96);
const _: () = assert!(size_of::<ResampleParams>() == 128);
