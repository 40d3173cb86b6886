//! The lighting pass's GPU objects: its bind group layout as one table, the fragment entry
//! points its pipelines run (compiled per target format by [`EnvisPrograms`], off the frame
//! path), and the resources it keeps: the probe and its readback, and per view the uniforms and
//! the accumulation buffer, written in place each frame.
//!
//! [`EnvisPrograms`]: crate::programs::EnvisPrograms

use crate::lighting_uniforms::PROBE_BYTES;
use crate::timing::AsyncRead;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_depth_2d,
    uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, BindGroupLayoutEntries, ShaderStages, TextureSampleType,
};
use std::collections::HashMap;
use std::sync::Mutex;

/// Which fragment entry point of the pass a pipeline runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LightingEntry {
    /// `lighting`: shades the pixel (or shows an overlay, or the resampled image).
    Shade,
    /// `show_resampled`: the resampling passes' image only, for a camera that resamples and
    /// shows no overlay. Through `lighting`'s early return the same image cost lavapipe 23 ms
    /// a 192² frame, through its own entry point 3.6 ms (docs/temporal.md): lavapipe runs the
    /// fragment stage compiled from the whole shader, early return or not.
    ShowResampled,
}

impl LightingEntry {
    /// The entry point's name in `shaders/lighting.wgsl`.
    pub fn entry_point(self) -> &'static str {
        match self {
            LightingEntry::Shade => "lighting",
            LightingEntry::ShowResampled => "show_resampled",
        }
    }
}

/// The bind group layout, in binding order (`@binding(0)` ... `@binding(13)` of
/// `shaders/lighting.wgsl`; `envis_lighting` binds the resources in the same order).
pub fn lighting_layout() -> BindGroupLayoutDescriptor {
    let ro = || storage_buffer_read_only_sized(false, None);
    let entries = BindGroupLayoutEntries::sequential(
        ShaderStages::FRAGMENT,
        (
            texture_2d(TextureSampleType::Uint), // 0: the deferred G-buffer
            texture_depth_2d(),                  // 1: depth
            ro(),                                // 2: texel table
            ro(),                                // 3: light pool
            ro(),                                // 4: regions
            uniform_buffer_sized(false, None),   // 5: ShadeParams
            uniform_buffer_sized(false, None),   // 6: LightingView
            storage_buffer_sized(false, None),   // 7: probe record
            storage_buffer_sized(false, None),   // 8: accumulation / resampled image
            ro(),                                // 9: global CDFs
            texture_2d(TextureSampleType::Uint), // 10: deferred lighting pass ids
            envis_wgpu::resample::source_binding(), // 11: the environment image
            ro(),                                // 12: BVH nodes
            ro(),                                // 13: BVH triangles
        ),
    );
    BindGroupLayoutDescriptor::new("envis lighting layout", &entries)
}

/// One view's kept buffers: its uniforms (written each frame) and its running mean.
pub(super) struct ViewBuffers {
    pub(super) params: wgpu::Buffer,
    pub(super) view: wgpu::Buffer,
    /// One vec4 per viewport pixel while accumulating, a 16-byte placeholder otherwise.
    pub(super) accum: wgpu::Buffer,
    accum_size: UVec2,
}

/// What the lighting pass keeps between frames.
#[derive(Resource)]
pub struct LightingResources {
    /// The probed pixel's record (`lighting_uniforms::PROBE_RECORD`) and its readback.
    pub(super) probe: wgpu::Buffer,
    pub(super) probe_read: AsyncRead,
    /// Bound in place of the shadow BVH when a camera casts no shadow rays.
    pub(super) no_shadows: wgpu::Buffer,
    /// The seed of the frame whose probe is being read back.
    pub(super) probe_seed: Mutex<u32>,
    /// Per view, its buffers (dropped with the view).
    pub(super) views: Mutex<HashMap<Entity, ViewBuffers>>,
}

impl LightingResources {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let probe = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis probe"),
            size: PROBE_BYTES,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let probe_read = AsyncRead::new(device, "envis probe readback", PROBE_BYTES);
        // Bound in place of the shadow BVH when there is none (one triangle's 48 bytes).
        let no_shadows = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis no shadow geometry"),
            size: 48,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        LightingResources {
            probe,
            probe_read,
            no_shadows,
            probe_seed: Mutex::new(0),
            views: Mutex::new(HashMap::new()),
        }
    }

    /// The view's buffers, its uniforms written (`params`, `view`: the bytes of `ShadeParams`
    /// and `LightingView`) and its running mean sized for viewport `vp` while `accumulate` (a new
    /// one, so a new mean, when the viewport size changes).
    pub(super) fn view_buffers(
        &self,
        (device, queue): (&wgpu::Device, &wgpu::Queue),
        view: Entity,
        (accumulate, vp): (bool, UVec4),
        (params, lv): (&[u8], &[u8]),
    ) -> (wgpu::Buffer, wgpu::Buffer, wgpu::Buffer) {
        let buffer = |label: &str, bytes: u64, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let uniform = wgpu::BufferUsages::UNIFORM;
        let mut map = self.views.lock().expect("view buffers");
        let size = UVec2::new(vp.z.max(1), vp.w.max(1));
        let v = map.entry(view).or_insert_with(|| ViewBuffers {
            params: buffer("envis shade params", params.len() as u64, uniform),
            view: buffer("envis lighting view", lv.len() as u64, uniform),
            accum: buffer("envis accumulation", 16, wgpu::BufferUsages::STORAGE),
            accum_size: UVec2::ZERO,
        });
        if accumulate && v.accum_size != size {
            let bytes = size.x as u64 * size.y as u64 * 16;
            v.accum = buffer("envis accumulation", bytes, wgpu::BufferUsages::STORAGE);
            v.accum_size = size;
        }
        // Each view has its own buffers: writes land before this frame's passes, one per view.
        queue.write_buffer(&v.params, 0, params);
        queue.write_buffer(&v.view, 0, lv);
        (v.params.clone(), v.view.clone(), v.accum.clone())
    }

    /// Buffers of views that are gone (or stopped sampling) are freed.
    pub(super) fn retain_views(&self, keep: impl Fn(Entity) -> bool) {
        let mut map = self.views.lock().expect("view buffers");
        if map.keys().any(|e| !keep(*e)) {
            map.retain(|e, _| keep(*e));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What a WGSL declaration binds, in the layout's terms.
    fn wgsl_kind(decl: &str) -> &'static str {
        if decl.starts_with("var<uniform>") {
            "uniform"
        } else if decl.starts_with("var<storage, read_write>") {
            "storage rw"
        } else if decl.starts_with("var<storage, read>") {
            "storage ro"
        } else {
            "texture"
        }
    }

    fn layout_kind(ty: &wgpu::BindingType) -> &'static str {
        use wgpu::{BindingType as B, BufferBindingType as BB};
        match ty {
            B::Buffer {
                ty: BB::Uniform, ..
            } => "uniform",
            B::Buffer {
                ty: BB::Storage { read_only: false },
                ..
            } => "storage rw",
            B::Buffer {
                ty: BB::Storage { read_only: true },
                ..
            } => "storage ro",
            _ => "texture",
        }
    }

    /// The one table (`lighting_layout`) and `shaders/lighting.wgsl` declare the same bindings,
    /// in order, of the same kinds.
    #[test]
    fn lighting_layout_matches_the_wgsl_bindings() {
        let wgsl: Vec<(u32, &str)> = envis_wgpu::shaders::LIGHTING
            .lines()
            .filter_map(|l| l.strip_prefix("@group(0) @binding("))
            .map(|l| {
                let (n, rest) = l.split_once(") ").unwrap();
                (n.parse().unwrap(), wgsl_kind(rest))
            })
            .collect();
        let layout: Vec<(u32, &str)> = lighting_layout()
            .entries
            .iter()
            .map(|e| (e.binding, layout_kind(&e.ty)))
            .collect();
        assert_eq!(wgsl, layout);
    }
}
