//! The gather (`shaders/gather.wgsl`): Bevy's prepass textures into what the resampling passes
//! read (surfaces, the reprojection, the split map). Its uniform is [`GatherView`].

use envis_wgpu::{buffer_entry, dispatch_size, sequential_entries, shaders};

/// `GatherView` of `shaders/gather.wgsl`, field for field (offsets checked by a test).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct GatherView {
    pub world_from_clip: [[f32; 4]; 4],
    pub env_from_world: [[f32; 4]; 4],
    pub camera: [f32; 3],
    pub orthographic: u32,
    pub forward: [f32; 3],
    pub has_prev: u32,
    pub prev_camera: [f32; 3],
    pub texel_count: u32,
    pub prev_forward: [f32; 3],
    pub _pad: u32,
    pub viewport: [f32; 4],
}

/// The gather's two pipelines and their layout.
pub(super) struct GatherPipelines {
    layout: wgpu::BindGroupLayout,
    gather: wgpu::ComputePipeline,
    split: wgpu::ComputePipeline,
}

/// What one frame's gather binds.
pub(super) struct GatherInputs<'a> {
    pub gbuffer: &'a wgpu::TextureView,
    pub depth: &'a wgpu::TextureView,
    pub pass_ids: &'a wgpu::TextureView,
    pub motion_vectors: &'a wgpu::TextureView,
    pub view: &'a wgpu::Buffer,
    pub texels: &'a wgpu::Buffer,
    pub surfaces: &'a wgpu::Buffer,
    pub reproject: &'a wgpu::Buffer,
    pub split: &'a wgpu::Buffer,
}

/// A compute-stage texture binding.
fn texture(binding: u32, sample_type: wgpu::TextureSampleType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

impl GatherPipelines {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        use wgpu::BufferBindingType as B;
        use wgpu::TextureSampleType as T;
        let rw = B::Storage { read_only: false };
        let entries = [
            texture(0, T::Uint),
            texture(1, T::Depth),
            texture(2, T::Uint),
            texture(3, T::Float { filterable: false }),
            buffer_entry(4, B::Uniform),
            buffer_entry(5, B::Storage { read_only: true }),
            buffer_entry(6, rw),
            buffer_entry(7, rw),
            buffer_entry(8, rw),
        ];
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("envis gather layout"),
            entries: &entries,
        });
        let pl = envis_wgpu::one_group_layout(device, "envis gather", &layout);
        let module = shaders::module(device, "envis gather.wgsl", &shaders::gather_source());
        GatherPipelines {
            gather: envis_wgpu::compute_pipeline(device, &pl, &module, "gather"),
            split: envis_wgpu::compute_pipeline(device, &pl, &module, "gather_split"),
            layout,
        }
    }

    /// Record the gather over `pixels` viewport pixels and `texels` cube texels (0: none, the
    /// split map is written otherwise).
    pub(super) fn record(
        &self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        inputs: &GatherInputs,
        (pixels, texels): (u32, u32),
    ) {
        use wgpu::BindingResource as R;
        let resources = [
            R::TextureView(inputs.gbuffer),
            R::TextureView(inputs.depth),
            R::TextureView(inputs.pass_ids),
            R::TextureView(inputs.motion_vectors),
            inputs.view.as_entire_binding(),
            inputs.texels.as_entire_binding(),
            inputs.surfaces.as_entire_binding(),
            inputs.reproject.as_entire_binding(),
            inputs.split.as_entire_binding(),
        ];
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("envis gather"),
            layout: &self.layout,
            entries: &sequential_entries(resources),
        });
        let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("envis gather"),
            timestamp_writes: None,
        });
        cp.set_bind_group(0, &bind, &[]);
        // texels 0: the split map is written from the CPU (the bright part, `bright.rs`).
        for (pipeline, count) in [(&self.gather, pixels), (&self.split, texels)] {
            if count == 0 {
                continue;
            }
            let (x, y) = dispatch_size(count, 64);
            cp.set_pipeline(pipeline);
            cp.dispatch_workgroups(x, y, 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Rust struct has the WGSL struct's fields at the same offsets, and its size.
    #[test]
    fn gather_view_matches_the_wgsl_struct() {
        use std::mem::offset_of;
        macro_rules! rust_fields {
            ($($f:ident),*) => { vec![$((stringify!($f), offset_of!(GatherView, $f))),*] };
        }
        let rust = rust_fields!(
            world_from_clip,
            env_from_world,
            camera,
            orthographic,
            forward,
            has_prev,
            prev_camera,
            texel_count,
            prev_forward,
            _pad,
            viewport
        );
        crate::lighting_uniforms::tests::assert_wgsl_struct(
            shaders::GATHER,
            "GatherView",
            &rust,
            size_of::<GatherView>(),
        );
    }
}
