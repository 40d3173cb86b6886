//! Per-pixel face-weighted MIS shading on the GPU (`shaders/shade.wgsl`), twin of
//! [`envis::render::shade_pixel`].

use super::sampler::{EnvSampler, check_binding};
use super::{GpuContext, dispatch_size, shaders};
use crate::GpuCode;
use envis::error::Result;
use envis::render::{GPixel, PixelStats, Settings};

/// A G-buffer texel as the shader reads it: `n.w = 1` where there is geometry, `kd.w` = the lobe's
/// [`envis::sampling::Lobe::gpu_code`], `ks.w` = its
/// parameter, [`crate::codes::lobe_param`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuGPixel {
    pub n: [f32; 4],
    pub o: [f32; 4],
    pub kd: [f32; 4],
    pub ks: [f32; 4],
}

impl From<&Option<GPixel>> for GpuGPixel {
    fn from(p: &Option<GPixel>) -> Self {
        let Some(p) = p else {
            return GpuGPixel::default();
        };
        let m = &p.material;
        let (kind, param) = (m.lobe.gpu_code() as f32, crate::codes::lobe_param(m.lobe));
        GpuGPixel {
            n: p.n.extend(1.0).into(),
            o: p.o.extend(0.0).into(),
            kd: m.kd.extend(kind).into(),
            ks: m.ks.extend(param).into(),
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShadeParams {
    pub n: u32,
    pub m: u32,
    pub nl: u32,
    pub nb: u32,
    /// [`envis::render::Strategy::gpu_code`].
    pub strategy: u32,
    /// [`envis::sampling::Counts::gpu_code`].
    pub counts: u32,
    /// [`envis::sampling::Heuristic::gpu_code`].
    pub mis: u32,
    pub seed: u32,
    /// [`envis::render::PoolLayout::gpu_code`].
    pub pool_layout: u32,
    pub pixel_count: u32,
    pub material_budget: u32,
    /// Nodes of the shadow-ray BVH; 0: no shadow rays. The one place the GPU passes learn it.
    pub bvh_nodes: u32,
    /// Blocks of the pool (1 unless `PoolLayout::Blocks`).
    pub pool_blocks: u32,
    /// Tiles per face side `K` (1: the paper's whole faces).
    pub tiles: u32,
    /// [`envis::sampling::TileCounts::gpu_code`].
    pub tile_counts: u32,
    /// Face size of the full-resolution radiance table ([`super::subtexel::FineRadiance`]); 0:
    /// radiance from the texel table.
    pub fine_n: u32,
}

impl ShadeParams {
    /// The shader's view of [`Settings`] (the same remapping of N_L / N_B per strategy as the CPU:
    /// [`Settings::strategy_budget`]; the material budget's split is made per pixel).
    pub fn new(s: &Settings, n: usize, m: usize, pixel_count: usize) -> Self {
        let (nl, nb) = s.strategy_budget();
        ShadeParams {
            n: n as u32,
            m: m as u32,
            nl: nl as u32,
            nb: nb as u32,
            strategy: s.strategy.gpu_code(),
            counts: s.counts.gpu_code(),
            mis: s.heuristic.gpu_code(),
            seed: s.seed,
            pool_layout: s.pool_layout.gpu_code(),
            pixel_count: pixel_count as u32,
            material_budget: s.material_budget as u32,
            bvh_nodes: 0,
            pool_blocks: s.pool_block_count() as u32,
            tiles: envis::sampling::TileGrid::new(n, s.tiles).k as u32,
            tile_counts: s.tile_counts.gpu_code(),
            fine_n: 0,
        }
    }
}

/// Begin/end timestamps of one compute pass, resolved into a readable buffer.
pub struct PassTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
}

impl PassTimer {
    pub fn new(device: &wgpu::Device, label: &str) -> Self {
        let (set, resolve) = super::timestamp_pair(device, label);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: 16,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        PassTimer {
            set,
            resolve,
            readback,
        }
    }
    pub fn writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }
    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        enc.copy_buffer_to_buffer(&self.resolve, 0, &self.readback, 0, 16);
    }
    /// Milliseconds between the two timestamps of the last resolved pass.
    pub fn read_ms(&self, ctx: &GpuContext) -> Option<f64> {
        Self::ms(ctx, &ctx.read_buffer(&self.readback, 0, 16).ok()?)
    }
    /// The readback range to pass to [`GpuContext::read_many`]; [`PassTimer::ms`] decodes it.
    pub fn part(&self) -> (&wgpu::Buffer, u64, u64) {
        (&self.readback, 0, 16)
    }
    /// Milliseconds from the 16 bytes of a resolved pass.
    pub fn ms(ctx: &GpuContext, bytes: &[u8]) -> Option<f64> {
        let t: Vec<u64> = bytemuck::pod_collect_to_vec(bytes);
        (t.len() == 2 && t[1] > t[0])
            .then(|| (t[1] - t[0]) as f64 * ctx.queue.get_timestamp_period() as f64 * 1e-6)
    }
}

/// The shading pipeline (one compute entry point over a G-buffer buffer).
pub struct Shader {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    placeholder: wgpu::Buffer,
    timer: Option<PassTimer>,
}

/// What a shading job can add to the sampler's frame.
#[derive(Clone, Copy, Default)]
pub struct ShadeExtras<'a> {
    /// Shadow rays through the BVH, from each pixel's surface point.
    pub shadows: Option<(&'a super::visibility::GpuBvh, &'a [glam::Vec3])>,
    /// Radiance from the map at its own resolution, the sampler's table giving only densities
    /// (the twin of [`envis::render::Extras::fine`] reading [`envis::envmap::CubeMap::lookup`]).
    pub fine: Option<&'a super::subtexel::FineRadiance>,
}

/// What one shading job returns.
pub struct ShadeJob {
    pub color: Vec<[f32; 4]>,
    /// Per pixel (available, green, yellow, brdf).
    pub stats: Vec<[u32; 4]>,
    /// Per pixel (shadow rays cast, light samples blocked).
    pub rays: Vec<[u32; 2]>,
    pub gpu_ms: Option<f64>,
}

impl ShadeJob {
    /// Each pixel's statistics as the CPU twin reports them (`None` where `gbuf` has no
    /// geometry).
    pub fn pixel_stats(&self, gbuf: &[Option<GPixel>]) -> Vec<Option<PixelStats>> {
        (self.stats.iter().zip(&self.rays).zip(gbuf))
            .map(|((q, r), g)| {
                g.as_ref().map(|_| PixelStats {
                    available: q[0],
                    green: q[1],
                    yellow: q[2],
                    brdf: q[3],
                    shadow_rays: r[0],
                    blocked: r[1],
                })
            })
            .collect()
    }
}

impl Shader {
    pub fn new(ctx: &GpuContext) -> Self {
        Self::with_device(&ctx.device, ctx.timestamps)
    }

    pub fn with_device(device: &wgpu::Device, timestamps: bool) -> Self {
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let uniform = wgpu::BufferBindingType::Uniform;
        // Bindings 0..=12 as in `shaders/shade_compute.wgsl`.
        let kinds = [ro, ro, ro, ro, rw, rw, uniform, ro, ro, ro, ro, rw, ro];
        let layout = super::buffer_layout(device, "envis shade layout", &kinds);
        let pl = super::one_group_layout(device, "envis shade", &layout);
        let module = shaders::module(device, "envis shade.wgsl", &shaders::shade_source());
        let pipeline = super::compute_pipeline(device, &pl, &module, "shade_gbuffer");
        let params = super::uniform_buffer::<ShadeParams>(device, "envis shade params");
        // Bound in place of the shadow-ray BVH and points when there are none (a binding may not
        // be shorter than one element: 48 bytes for a triangle).
        let placeholder = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis no shadow rays"),
            size: 48,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        Shader {
            pipeline,
            layout,
            params,
            placeholder,
            timer: timestamps.then(|| PassTimer::new(device, "envis shade timer")),
        }
    }

    /// Headless: upload the G-buffer, shade every pixel with the sampler's current frame, read back.
    pub fn shade(
        &self,
        ctx: &GpuContext,
        sampler: &EnvSampler,
        pixels: &[GpuGPixel],
        s: &Settings,
    ) -> Result<ShadeJob> {
        self.shade_with_shadows(ctx, sampler, pixels, s, None)
    }

    /// [`Self::shade`] with shadow rays through `bvh` from each pixel's surface point `points`
    /// (the GPU twin of `render::render_with` with [`envis::render::Extras::shadows`]).
    pub fn shade_with_shadows(
        &self,
        ctx: &GpuContext,
        sampler: &EnvSampler,
        pixels: &[GpuGPixel],
        s: &Settings,
        shadows: Option<(&super::visibility::GpuBvh, &[glam::Vec3])>,
    ) -> Result<ShadeJob> {
        let extras = ShadeExtras {
            shadows,
            fine: None,
        };
        self.shade_with(ctx, sampler, pixels, s, extras)
    }

    /// [`Self::shade`] with [`ShadeExtras`]: shadow rays, radiance at full resolution.
    pub fn shade_with(
        &self,
        ctx: &GpuContext,
        sampler: &EnvSampler,
        pixels: &[GpuGPixel],
        s: &Settings,
        extras: ShadeExtras,
    ) -> Result<ShadeJob> {
        let count = pixels.len();
        let limits = ctx.device.limits();
        check_binding(&limits, "the G-buffer", count as u64 * 64)?;
        let mk = |label: &str, size: u64| super::sampler::storage(&ctx.device, label, size);
        let gbuf = mk("envis gbuffer", count as u64 * 64);
        let color = mk("envis color", count as u64 * 16);
        let stats = mk("envis pixel stats", count as u64 * 16);
        let rays = mk("envis pixel shadow rays", count as u64 * 8);
        ctx.queue
            .write_buffer(&gbuf, 0, bytemuck::cast_slice(pixels));
        let mut params = ShadeParams::new(s, sampler.n, sampler.m, count);
        let points = extras.shadows.map(|(bvh, p)| {
            assert_eq!(p.len(), count, "one surface point per pixel");
            params.bvh_nodes = bvh.node_count;
            let v: Vec<[f32; 4]> = p.iter().map(|p| p.extend(0.0).to_array()).collect();
            let b = mk("envis surface points", count as u64 * 16);
            ctx.queue.write_buffer(&b, 0, bytemuck::cast_slice(&v));
            b
        });
        let (nodes, triangles, points) = match (extras.shadows, &points) {
            (Some((bvh, _)), Some(p)) => (&bvh.nodes, &bvh.triangles, p),
            _ => (&self.placeholder, &self.placeholder, &self.placeholder),
        };
        params.fine_n = extras.fine.map_or(0, |f| f.size);
        let fine = extras.fine.map_or(&self.placeholder, |f| &f.texels);
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        // In binding order (`shaders/shade_compute.wgsl`).
        let bind = self.bind_group(
            ctx,
            [
                sampler.texels.as_entire_binding(),
                sampler.pool.as_entire_binding(),
                wgpu::BindingResource::Buffer(sampler.regions_binding()),
                gbuf.as_entire_binding(),
                color.as_entire_binding(),
                stats.as_entire_binding(),
                self.params.as_entire_binding(),
                sampler.gdist.as_entire_binding(),
                nodes.as_entire_binding(),
                triangles.as_entire_binding(),
                points.as_entire_binding(),
                rays.as_entire_binding(),
                fine.as_entire_binding(),
            ],
        );
        self.dispatch_and_read(ctx, &bind, count, [&color, &stats, &rays])
    }

    /// The pass's bind group of `resources`, numbered in order.
    fn bind_group<const N: usize>(
        &self,
        ctx: &GpuContext,
        resources: [wgpu::BindingResource; N],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = resources
            .into_iter()
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource,
            })
            .collect();
        ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("envis shade bind group"),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// Shade `count` pixels with `bind` and read back the colour, statistics and shadow-ray
    /// buffers (`out`) and the pass timer, in one readback.
    fn dispatch_and_read(
        &self,
        ctx: &GpuContext,
        bind: &wgpu::BindGroup,
        count: usize,
        [color, stats, rays]: [&wgpu::Buffer; 3],
    ) -> Result<ShadeJob> {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("envis shade"),
                timestamp_writes: self.timer.as_ref().map(|t| t.writes()),
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, bind, &[]);
            let (x, y) = dispatch_size(count as u32, 64);
            pass.dispatch_workgroups(x, y, 1);
        }
        if let Some(t) = &self.timer {
            t.resolve(&mut enc);
        }
        let idx = ctx.queue.submit([enc.finish()]);
        ctx.wait(idx)?;
        let mut parts = vec![
            (color, 0, count as u64 * 16),
            (stats, 0, count as u64 * 16),
            (rays, 0, count as u64 * 8),
        ];
        parts.extend(self.timer.as_ref().map(|t| t.part()));
        let data = ctx.read_many(&parts)?;
        let gpu_ms = data.get(3).and_then(|b| PassTimer::ms(ctx, b));
        Ok(ShadeJob {
            color: bytemuck::pod_collect_to_vec(&data[0]),
            stats: bytemuck::pod_collect_to_vec(&data[1]),
            rays: bytemuck::pod_collect_to_vec(&data[2]),
            gpu_ms,
        })
    }
}
