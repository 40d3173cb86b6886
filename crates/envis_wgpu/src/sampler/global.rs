//! The `global` baseline's lat-long distribution (4N x 2N cells, `shaders/global.wgsl`), built
//! beside the cube distribution when that strategy runs: the twin of
//! [`envis::sampling::GlobalDistribution::build`].

use super::*;

/// Floats in the `global` distribution buffer for N x N faces (`glen` in global_layout.wgsl):
/// `[marg: h + 1][rows: h (w + 1)][pdf: w h][rowtot: h][misc: 4]`, `w = 4N`, `h = 2N`.
pub fn global_len(n: usize) -> usize {
    let (w, h) = (4 * n, 2 * n);
    (h + 1) + h * (w + 1) + w * h + h + 4
}

/// The `global` baseline's build: its own bind group (texels, the distribution, N).
pub(super) struct GlobalBuild {
    pub(super) bind_group: wgpu::BindGroup,
    pub(super) pipelines: [wgpu::ComputePipeline; 6],
    _params: wgpu::Buffer,
}

impl EnvSampler {
    /// Also build the `global` baseline's lat-long distribution (4N x 2N cells) every frame.
    pub fn enable_global(&mut self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<()> {
        if self.global.is_some() {
            return Ok(());
        }
        let bytes = global_len(self.n) as u64 * 4;
        check_binding(
            &device.limits(),
            "the global distribution (4N x 2N cells)",
            bytes,
        )?;
        self.gdist = storage(device, "envis global distribution", bytes);
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis global params"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&params, 0, bytemuck::cast_slice(&[self.n as u32, 0, 0, 0]));
        use wgpu::BufferBindingType as Kind;
        let kinds = [
            Kind::Storage { read_only: true },
            Kind::Storage { read_only: false },
            Kind::Uniform,
        ];
        let layout = crate::buffer_layout(device, "envis global layout", &kinds);
        let bufs = [&self.texels, &self.gdist, &params];
        let bind_group = crate::whole_buffers(device, "envis global", &layout, &bufs);
        let pl = crate::one_group_layout(device, "envis global", &layout);
        let module = shaders::module(device, "envis global.wgsl", &shaders::global_source());
        let pipe = |entry: &str| crate::compute_pipeline(device, &pl, &module, entry);
        let pipelines = [
            pipe("global_cells"),
            pipe("global_row_sums"),
            pipe("global_floor"),
            pipe("global_row_cdfs"),
            pipe("global_marginal"),
            pipe("global_pdf_table"),
        ];
        self.global = Some(GlobalBuild {
            bind_group,
            pipelines,
            _params: params,
        });
        Ok(())
    }

    pub fn has_global(&self) -> bool {
        self.global.is_some()
    }

    /// The `global` distribution buffer, read back (tests).
    pub fn read_global(&self, ctx: &GpuContext) -> Result<Vec<f32>> {
        ctx.read(
            &self.gdist,
            0,
            if self.global.is_some() {
                global_len(self.n)
            } else {
                4
            },
        )
    }
}
