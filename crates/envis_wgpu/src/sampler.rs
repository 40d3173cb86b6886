//! The per-frame distribution build and light-sample pool on the GPU (`shaders/distribution.wgsl`),
//! twin of [`envis::sampling::CubeDistribution::build`] and [`envis::sampling::LightPool::build`].

use super::{GpuContext, dispatch_size, shaders};
use envis::envmap::{CubeMap, SanitizeReport};
use envis::error::{Error, Result};
use envis::sampling::distribution::{
    Conditionals, Distribution1D, FaceDistribution, TileDistribution, face_solid_angles,
};
use envis::sampling::{CubeDistribution, LightPool, PoolSample, TileGrid};
use glam::Vec3;

mod global;
mod readback;
use global::GlobalBuild;
pub use global::global_len;
pub use readback::GpuTables;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    n: u32,
    m: u32,
    seed: u32,
    blocks: u32,
    tiles: u32,
    _pad: [u32; 3],
}

/// Floats of one region's record at the start of the `totals` buffer: four corner directions
/// (`xyz`), the region's energy in the first corner's `w`.
pub const REGION_RECORD: usize = 16;

/// Offset of the column totals in the `totals` buffer for `k x k` tiles per face (the regions'
/// records come first).
pub fn totals_columns(k: usize) -> usize {
    REGION_RECORD * 6 * k * k
}

/// GPU buffers and pipelines of the per-frame build for faces of `n x n` texels cut into
/// [`Self::tiles`]` x `[`Self::tiles`] tiles, and `m` pool slots per region (face, or tile; in
/// [`Self::blocks`] blocks). Re-create it when `n`, `m` or the tiles change; re-upload and
/// re-encode every frame.
pub struct EnvSampler {
    pub n: usize,
    pub m: usize,
    /// Tiles per face side `K` (1: the paper's whole faces).
    pub tiles: usize,
    /// Independent stratified blocks the `m` slots are split into (`PoolLayout::Blocks`; 1: the
    /// paper's pool). Set with [`Self::set_blocks`].
    pub blocks: usize,
    /// Per texel `(r, g, b, pdf_area)`: radiance in, sanitised radiance + pdf table out.
    pub texels: wgpu::Buffer,
    pub weights: wgpu::Buffer,
    /// All CDFs: per (face, column) the conditionals over the rows of its `K` bands (`n + K`
    /// values), then per region the marginal over its columns (`n + 1` values reserved).
    pub cdfs: wgpu::Buffer,
    /// Per region a record of [`REGION_RECORD`] floats (corners, energy), then per (face, band,
    /// column) the column's total in the band from [`totals_columns`].
    pub totals: wgpu::Buffer,
    /// Two `vec4` per sample: `(dir, pdf)`, `(radiance, 0)`.
    pub pool: wgpu::Buffer,
    pub problems: wgpu::Buffer,
    /// The `global` distribution (a 16-byte placeholder until [`Self::enable_global`]).
    pub gdist: wgpu::Buffer,
    params: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    pipelines: std::sync::Arc<BuildPipelines>,
    timer: Option<super::shading::PassTimer>,
    pool_timer: Option<super::shading::PassTimer>,
    global: Option<GlobalBuild>,
}

/// A storage buffer a pass reads or writes and the host fills or reads back (at least 16 bytes:
/// an empty binding is invalid).
pub fn storage(device: &wgpu::Device, label: &str, size: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Refuse a buffer the device cannot bind, naming it, before allocating anything.
pub fn check_binding(limits: &wgpu::Limits, what: &str, bytes: u64) -> Result<()> {
    let max = limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size);
    if bytes > max {
        return Err(Error::invalid(format!(
            "GPU: {what} needs {bytes} bytes, above this device's storage-binding limit of {max} bytes"
        )));
    }
    Ok(())
}

/// The byte sizes of the build's large buffers, each checked against the device's binding limit
/// before anything is allocated.
struct BufferSizes {
    /// The texel table, `6 N^2` texels of 16 bytes.
    texels: u64,
    cdfs: u64,
    pool: u64,
}

impl BufferSizes {
    fn check(limits: &wgpu::Limits, grid: TileGrid, m: usize) -> Result<Self> {
        let (n, k) = (grid.size, grid.k);
        if n == 0 || m == 0 {
            return Err(Error::invalid(
                "GPU sampler: face size and pool size must be positive",
            ));
        }
        let texels = (6 * n * n) as u64 * 16;
        check_binding(limits, "the texel table (6 N^2 x 16 bytes)", texels)?;
        let cdfs = (6 * n * (n + k) + grid.regions() * (n + 1)) as u64 * 4;
        check_binding(limits, "the CDF tables", cdfs)?;
        let pool = (grid.regions() * m) as u64 * 32;
        check_binding(limits, "the light pool", pool)?;
        Ok(BufferSizes { texels, cdfs, pool })
    }
}

impl EnvSampler {
    /// The paper's sampler: whole faces, `m` pool slots per face.
    pub fn new(ctx: &GpuContext, n: usize, m: usize) -> Result<Self> {
        Self::with_device(
            &ctx.device,
            &ctx.queue,
            TileGrid::new(n, 1),
            m,
            ctx.timestamps,
        )
    }

    /// The sampler a render with settings `s` needs on faces of `n`: its tiles, its pool's slots
    /// and blocks.
    pub fn for_settings(ctx: &GpuContext, n: usize, s: &envis::render::Settings) -> Result<Self> {
        s.validate_for(n)?;
        let grid = TileGrid::new(n, s.tiles);
        let mut sampler = Self::with_device(
            &ctx.device,
            &ctx.queue,
            grid,
            s.pool_slots(),
            ctx.timestamps,
        )?;
        sampler.set_blocks(s.pool_block_count())?;
        Ok(sampler)
    }

    /// Build on any device, for faces and tiles `grid`, compiling the build's pipelines for it
    /// (see [`Self::with_pipelines`] to share them).
    pub fn with_device(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        grid: TileGrid,
        m: usize,
        timestamps: bool,
    ) -> Result<Self> {
        let pipelines = std::sync::Arc::new(BuildPipelines::new(device));
        Self::with_pipelines(device, queue, &pipelines, grid, m, timestamps)
    }

    /// [`Self::with_device`] with `pipelines` compiled before (the Bevy render world compiles
    /// them once, off the frame path, for all its samplers).
    pub fn with_pipelines(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pipelines: &std::sync::Arc<BuildPipelines>,
        grid: TileGrid,
        m: usize,
        timestamps: bool,
    ) -> Result<Self> {
        let (n, k) = (grid.size, grid.k);
        let sizes = BufferSizes::check(&device.limits(), grid, m)?;
        let texels = storage(device, "envis texels", sizes.texels);
        let solid_angle = storage(device, "envis solid angles", (n * n) as u64 * 4);
        // One f32 per texel: a quarter of the texel table, so within the limit it passed.
        let weights = storage(device, "envis weights", sizes.texels / 4);
        let cdfs = storage(device, "envis cdfs", sizes.cdfs);
        let totals = storage(
            device,
            "envis totals",
            (totals_columns(k) + 6 * k * n) as u64 * 4,
        );
        let pool = storage(device, "envis pool", sizes.pool);
        let problems = storage(device, "envis sanitise counters", 16);
        let params = super::uniform_buffer::<Params>(device, "envis build params");
        let angles = face_solid_angles(n);
        queue.write_buffer(&solid_angle, 0, bytemuck::cast_slice(angles.as_slice()));
        let bufs = [
            &texels,
            &solid_angle,
            &weights,
            &cdfs,
            &totals,
            &pool,
            &problems,
            &params,
        ];
        let bind_group =
            super::whole_buffers(device, "envis build bind group", &pipelines.layout, &bufs);
        let timer = |label| timestamps.then(|| super::shading::PassTimer::new(device, label));
        let (timer, pool_timer) = (timer("envis build timer"), timer("envis pool timer"));
        let gdist = storage(device, "envis global placeholder", 16);
        Ok(EnvSampler {
            n,
            m,
            tiles: k,
            blocks: 1,
            texels,
            weights,
            cdfs,
            totals,
            pool,
            problems,
            gdist,
            params,
            bind_group,
            pipelines: pipelines.clone(),
            timer,
            pool_timer,
            global: None,
        })
    }

    /// The compiled build this sampler records (to make another sampler without compiling it
    /// again: [`Self::with_pipelines`]).
    pub fn build_pipelines(&self) -> &std::sync::Arc<BuildPipelines> {
        &self.pipelines
    }

    /// The pool's slots: `m` per region, over every face's tiles (one thread each in the pool's
    /// build and in its sub-texel refinement).
    pub fn pool_slots(&self) -> u32 {
        (6 * self.tiles * self.tiles * self.m) as u32
    }

    /// The regions' records (corners and energies) at the start of `totals`: what the shading
    /// passes bind as `regions`.
    pub fn regions_binding(&self) -> wgpu::BufferBinding<'_> {
        wgpu::BufferBinding {
            buffer: &self.totals,
            offset: 0,
            size: wgpu::BufferSize::new(totals_columns(self.tiles) as u64 * 4),
        }
    }

    /// Upload a frame's radiance (the `w` channel is written by the build).
    pub fn upload(&self, queue: &wgpu::Queue, map: &CubeMap) {
        assert_eq!(map.size, self.n, "EnvSampler built for another face size");
        let data: Vec<[f32; 4]> = map.data.iter().map(|c| [c.x, c.y, c.z, 0.0]).collect();
        queue.write_buffer(&self.texels, 0, bytemuck::cast_slice(&data));
    }

    /// Split the pool into `blocks` blocks of `m / blocks` samples per region from the next
    /// [`Self::set_seed`] on (the CPU twin's `LightPool::build_blocks`).
    pub fn set_blocks(&mut self, blocks: usize) -> Result<()> {
        if blocks == 0 || !self.m.is_multiple_of(blocks) {
            return Err(Error::invalid(format!(
                "a pool of {} per face does not split into {blocks} blocks",
                self.m
            )));
        }
        self.blocks = blocks;
        Ok(())
    }

    /// Set the pool seed for the next [`Self::encode`] (the CPU twin's `render::pool_seed`).
    pub fn set_seed(&self, queue: &wgpu::Queue, seed: u32) {
        let p = Params {
            n: self.n as u32,
            m: self.m as u32,
            seed,
            blocks: self.blocks as u32,
            tiles: self.tiles as u32,
            _pad: [0; 3],
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&p));
    }

    /// Record the whole build as two compute passes, no CPU round trip: the distribution
    /// (sanitise + weights, column CDFs, marginal CDFs, pdf table, and `global`'s when enabled),
    /// then the light pool.
    pub fn encode(&self, enc: &mut wgpu::CommandEncoder) {
        self.encode_with(
            enc,
            self.timer.as_ref().map(|t| t.writes()),
            self.pool_timer.as_ref().map(|t| t.writes()),
        );
        for t in [&self.timer, &self.pool_timer].into_iter().flatten() {
            t.resolve(enc);
        }
    }

    /// [`Self::encode`] with the caller's timestamp writes for the distribution pass and the pool
    /// pass (the Bevy app times them asynchronously).
    pub fn encode_with(
        &self,
        enc: &mut wgpu::CommandEncoder,
        dist_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
        pool_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        self.encode_distribution(enc, dist_writes);
        self.encode_pool(enc, pool_writes);
    }

    /// The distribution pass of [`Self::encode_with`]: weights, CDFs, region energies, the pdf
    /// table (and the `global` build when it is on).
    pub fn encode_distribution(
        &self,
        enc: &mut wgpu::CommandEncoder,
        writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let (n, k) = (self.n as u32, self.tiles as u32);
        let texels = 6 * n * n;
        enc.clear_buffer(&self.problems, 0, None);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("envis distribution"),
            timestamp_writes: writes,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        grid(
            &mut pass,
            &self.pipelines.passes[0],
            dispatch_size(texels, 256),
        );
        grid(
            &mut pass,
            &self.pipelines.passes[1],
            dispatch_size(6 * n * k, 1),
        );
        grid(
            &mut pass,
            &self.pipelines.passes[2],
            dispatch_size(6 * k * k, 1),
        );
        grid(
            &mut pass,
            &self.pipelines.passes[3],
            dispatch_size(texels, 256),
        );
        if let Some(g) = &self.global {
            let (w, h) = (4 * n, 2 * n);
            pass.set_bind_group(0, &g.bind_group, &[]);
            grid(&mut pass, &g.pipelines[0], dispatch_size(w * h, 256));
            grid(&mut pass, &g.pipelines[1], (h, 1));
            grid(&mut pass, &g.pipelines[2], (1, 1));
            grid(&mut pass, &g.pipelines[3], (h, 1));
            grid(&mut pass, &g.pipelines[4], (1, 1));
            grid(&mut pass, &g.pipelines[5], dispatch_size(w * h, 256));
        }
    }

    /// The pool pass of [`Self::encode_with`]: `M` light samples per region and block.
    pub fn encode_pool(
        &self,
        enc: &mut wgpu::CommandEncoder,
        writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("envis pool"),
            timestamp_writes: writes,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        grid(
            &mut pass,
            &self.pipelines.passes[4],
            dispatch_size(self.pool_slots(), 64),
        );
    }

    /// Headless: seed, encode, submit.
    pub fn run(&self, ctx: &GpuContext, seed: u32) -> wgpu::SubmissionIndex {
        self.set_seed(&ctx.queue, seed);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        self.encode(&mut enc);
        ctx.queue.submit([enc.finish()])
    }

    /// GPU milliseconds of the last build, distribution + pool (when the device has timestamps).
    pub fn last_gpu_ms(&self, ctx: &GpuContext) -> Option<f64> {
        let (d, p) = self.last_gpu_ms_split(ctx);
        Some(d? + p?)
    }

    /// GPU milliseconds of the last distribution pass and of the last pool pass.
    pub fn last_gpu_ms_split(&self, ctx: &GpuContext) -> (Option<f64>, Option<f64>) {
        (
            self.timer.as_ref().and_then(|t| t.read_ms(ctx)),
            self.pool_timer.as_ref().and_then(|t| t.read_ms(ctx)),
        )
    }
}

/// One dispatch of `p` over `(x, y)` workgroups.
fn grid(pass: &mut wgpu::ComputePass, p: &wgpu::ComputePipeline, (x, y): (u32, u32)) {
    pass.set_pipeline(p);
    pass.dispatch_workgroups(x, y, 1);
}

/// The build's five compute pipelines (`shaders/distribution.wgsl`) and their bind group layout:
/// storage buffers bound 0..=7 (the solid angles, 1, read only), then the parameters. One set
/// serves every [`EnvSampler`] of a device.
pub struct BuildPipelines {
    layout: wgpu::BindGroupLayout,
    /// `texel_weights`, `column_cdfs`, `marginal_cdfs`, `pdf_table`, `build_pool`.
    passes: [wgpu::ComputePipeline; 5],
}

impl BuildPipelines {
    /// Compile the build on `device` (what takes time: a driver compiling five entry points).
    pub fn new(device: &wgpu::Device) -> Self {
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let kinds = [rw, ro, rw, rw, rw, rw, rw, wgpu::BufferBindingType::Uniform];
        let layout = super::buffer_layout(device, "envis build layout", &kinds);
        let pl = super::one_group_layout(device, "envis build", &layout);
        let module = shaders::module(
            device,
            "envis distribution.wgsl",
            &shaders::distribution_source(),
        );
        let pipe = |entry: &str| super::compute_pipeline(device, &pl, &module, entry);
        let passes = [
            pipe("texel_weights"),
            pipe("column_cdfs"),
            pipe("marginal_cdfs"),
            pipe("pdf_table"),
            pipe("build_pool"),
        ];
        BuildPipelines { layout, passes }
    }
}
