//! The resampling pipelines and what a frame binds to them: shared by the headless resampler
//! ([`super::GpuResampler`]) and the Bevy pass (`bevy_envis::resampling`), which own their buffers
//! each in their own way and record the same passes.

use super::super::sampler::EnvSampler;
use super::super::{buffer_layout, compute_pipeline, dispatch_size, one_group_layout, shaders};
use envis::error::{Error, Result};

/// Storage buffers one pass binds (bindings 0..=21 less the two uniforms): above WebGPU's
/// default of 8 per stage, within what desktop Vulkan, Metal and DX12 offer.
pub const STORAGE_BUFFERS: u32 = 20;

/// The entry points, in dispatch order.
pub const PASSES: [&str; 5] = [
    "candidates",
    "history_targets",
    "temporal",
    "spatial",
    "shade_reservoirs",
];

/// The five compute pipelines of `shaders/resampling.wgsl` and `reuse.wgsl`, their layout and a
/// placeholder bound where a frame has nothing (no history, no bright part, no geometry).
pub struct ResamplingPasses {
    layout: wgpu::BindGroupLayout,
    pipelines: Vec<wgpu::ComputePipeline>,
    placeholder: wgpu::Buffer,
}

/// A BVH as the shaders bind it: nodes and triangles.
pub type BvhBuffers<'a> = (&'a wgpu::Buffer, &'a wgpu::Buffer);

/// Every buffer a frame's passes bind (bindings 0..=21 of `shaders/resampling.wgsl`); `None`
/// binds the placeholder.
pub struct PassBuffers<'a> {
    pub sampler: &'a EnvSampler,
    /// `ShadeParams` and `ResampleParams` (uniforms).
    pub shade_params: &'a wgpu::Buffer,
    pub params: &'a wgpu::Buffer,
    pub surfaces: &'a wgpu::Buffer,
    pub prev_surfaces: Option<&'a wgpu::Buffer>,
    pub split: &'a wgpu::Buffer,
    pub prev_split: Option<&'a wgpu::Buffer>,
    /// The bright part's CDF and texels.
    pub bright: Option<(&'a wgpu::Buffer, &'a wgpu::Buffer)>,
    pub bvh: Option<BvhBuffers<'a>>,
    /// The previous frame's shadow geometry (bound in `history_targets` only).
    pub prev_bvh: Option<BvhBuffers<'a>>,
    /// Candidates, after temporal reuse (the next history), after spatial reuse, shaded (the
    /// last may be the first: see `bind_group`).
    pub res: [&'a wgpu::Buffer; 4],
    /// The previous frame's temporal reservoirs.
    pub history: Option<&'a wgpu::Buffer>,
    pub reproject: Option<&'a wgpu::Buffer>,
    pub hist_targets: &'a wgpu::Buffer,
    pub counters: &'a wgpu::Buffer,
    pub color: &'a wgpu::Buffer,
    pub stats: &'a wgpu::Buffer,
    pub pixels: u32,
}

impl ResamplingPasses {
    pub fn new(device: &wgpu::Device) -> Self {
        use wgpu::BufferBindingType as Kind;
        let (ro, rw) = (
            Kind::Storage { read_only: true },
            Kind::Storage { read_only: false },
        );
        // Bindings 0..=21 as in `shaders/resampling.wgsl`.
        let mut kinds = vec![ro; STORAGE_BUFFERS as usize + 2];
        kinds[4] = Kind::Uniform;
        kinds[5] = Kind::Uniform;
        for b in [16, 18, 19, 20, 21] {
            kinds[b] = rw;
        }
        let layout = buffer_layout(device, "envis resampling layout", &kinds);
        let pl = one_group_layout(device, "envis resampling", &layout);
        let module = shaders::module(
            device,
            "envis resampling.wgsl",
            &shaders::resampling_source(),
        );
        let pipelines = PASSES
            .iter()
            .map(|entry| compute_pipeline(device, &pl, &module, entry))
            .collect();
        let placeholder = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis resampling placeholder"),
            size: 256,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        ResamplingPasses {
            layout,
            pipelines,
            placeholder,
        }
    }

    /// Whether a device with `limits` can run the passes: an error (one line) where it binds
    /// fewer storage buffers per stage than they need.
    pub fn supported(limits: &wgpu::Limits) -> Result<()> {
        let have = limits.max_storage_buffers_per_shader_stage;
        if have < STORAGE_BUFFERS {
            return Err(Error::invalid(format!(
                "GPU: resampling binds {STORAGE_BUFFERS} storage buffers per shader stage, this device {have}"
            )));
        }
        Ok(())
    }

    /// Record the frame's passes into `enc` (`history_targets` only with a history; without
    /// one, `temporal` passes its input through).
    pub fn record(&self, device: &wgpu::Device, enc: &mut wgpu::CommandEncoder, b: &PassBuffers) {
        let (x, y) = dispatch_size(b.pixels, 64);
        for (pass, pipeline) in self.pipelines.iter().enumerate() {
            if pass == 1 && b.history.is_none() {
                continue;
            }
            let bind = self.bind_group(device, b, pass);
            let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(PASSES[pass]),
                timestamp_writes: None,
            });
            cp.set_pipeline(pipeline);
            cp.set_bind_group(0, &bind, &[]);
            cp.dispatch_workgroups(x, y, 1);
        }
    }

    /// Pass `pass`'s bind group: its input and output reservoirs, and the shadow geometry
    /// (the previous frame's for `history_targets`).
    fn bind_group(&self, device: &wgpu::Device, b: &PassBuffers, pass: usize) -> wgpu::BindGroup {
        fn or<'a>(o: Option<&'a wgpu::Buffer>, ph: &'a wgpu::Buffer) -> wgpu::BindingResource<'a> {
            o.unwrap_or(ph).as_entire_binding()
        }
        let ph = &self.placeholder;
        // Candidates write res[0] (their input is not read: any other buffer); temporal reads
        // res[0] (history_targets too) and writes res[1]; spatial res[1] -> res[2]; shading
        // res[2] -> res[3]. No pass reads what it writes, so res[3] may be res[0].
        let (input, output) = match pass {
            0 => (b.res[2], b.res[0]),
            1 | 2 => (b.res[0], b.res[1]),
            3 => (b.res[1], b.res[2]),
            _ => (b.res[2], b.res[3]),
        };
        let bvh = if pass == 1 { b.prev_bvh } else { b.bvh };
        let (nodes, tris) = bvh.unwrap_or((ph, ph));
        let (cdf, ids) = b.bright.unwrap_or((ph, ph));
        let resources = [
            b.sampler.texels.as_entire_binding(),
            b.sampler.pool.as_entire_binding(),
            wgpu::BindingResource::Buffer(b.sampler.regions_binding()),
            b.sampler.gdist.as_entire_binding(),
            b.shade_params.as_entire_binding(),
            b.params.as_entire_binding(),
            b.surfaces.as_entire_binding(),
            or(b.prev_surfaces, ph),
            b.split.as_entire_binding(),
            or(b.prev_split, ph),
            cdf.as_entire_binding(),
            ids.as_entire_binding(),
            nodes.as_entire_binding(),
            tris.as_entire_binding(),
            input.as_entire_binding(),
            or(b.history, ph),
            output.as_entire_binding(),
            or(b.reproject, ph),
            b.hist_targets.as_entire_binding(),
            b.counters.as_entire_binding(),
            b.color.as_entire_binding(),
            b.stats.as_entire_binding(),
        ];
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(PASSES[pass]),
            layout: &self.layout,
            entries: &super::super::sequential_entries(resources),
        })
    }
}
