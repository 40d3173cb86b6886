//! `MisLightingPlugin`: the face-weighted MIS deferred lighting pass, replacing Bevy's for cameras
//! marked [`EnvisCamera`]. Meshes write Bevy's deferred G-buffer through a `StandardMaterial`
//! made by [`EnvisMaterial`]; the pass decodes it and runs the same `shade` function as the
//! headless backend (`shaders/shade.wgsl`).

use super::sampling::EnvSamplingState;
use super::timing::{AsyncRead, AsyncTimer, EnvisTimings};
use super::{EnvisCounters, EnvisSettings};
use super::{EnvisProbe, Overlay, ProbeResult};
use crate::gpu::shaders;
use crate::gpu::shading::ShadeParams;
use crate::render::Strategy;
use crate::sampling::{Lobe, Material};
use bevy::core_pipeline::core_3d::main_opaque_pass_3d;
use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass, ViewPrepassTextures};
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::material::OpaqueRendererMethod;
use bevy::pbr::deferred::SkipDeferredLighting;
use bevy::prelude::*;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::renderer::{RenderContext, RenderDevice, ViewQuery};
use bevy::render::view::{ExtractedView, ViewTarget};
use bevy::render::{Render, RenderApp, RenderStartup, RenderSystems};
use std::collections::HashMap;
use std::sync::Mutex;
use wgpu::util::DeviceExt;

/// Marks a 3D camera whose lighting is done by envis. Brings the deferred prepasses it needs;
/// the camera must also have `Msaa::Off` (deferred rendering has no MSAA).
#[derive(Component, Clone, Copy, Default, ExtractComponent)]
#[require(DepthPrepass, DeferredPrepass)]
pub struct EnvisCamera;

/// An envis material, written into Bevy's deferred G-buffer as a `StandardMaterial`
/// (the encoding is documented in `shaders/lighting.wgsl` and `docs/gpu.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EnvisMaterial {
    Lambert {
        albedo: Vec3,
    },
    /// Normalised Phong; exponent up to 1e4 (stored as roughness `(2 / (e + 2))^(1/4)`, 8 bits).
    Phong {
        albedo: Vec3,
        exponent: f32,
    },
    /// GGX with F = 1 (stored as perceptual roughness `sqrt(alpha)`, 8 bits).
    Ggx {
        albedo: Vec3,
        alpha: f32,
    },
    /// Lambert `(1 - specular) albedo` plus GGX `specular albedo`.
    Mix {
        albedo: Vec3,
        specular: f32,
        alpha: f32,
    },
}

/// sRGB-ish 8-bit round trip of Bevy's G-buffer base colour (`pow(c, 1/2.2)` in unorm8).
fn gbuffer_color(c: Vec3) -> Vec3 {
    c.map(|x| ((x.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() / 255.0).powf(2.2))
}
fn unorm8(x: f32) -> f32 {
    (x.clamp(0.0, 1.0) * 255.0).round() / 255.0
}

impl EnvisMaterial {
    fn encode(&self) -> (Vec3, f32, f32, f32) {
        // (albedo, metallic, reflectance, perceptual roughness)
        match *self {
            EnvisMaterial::Lambert { albedo } => (albedo, 0.0, 0.0, 1.0),
            EnvisMaterial::Phong { albedo, exponent } => (
                albedo,
                1.0,
                1.0,
                (2.0 / (exponent.max(0.0) + 2.0)).powf(0.25),
            ),
            EnvisMaterial::Ggx { albedo, alpha } => {
                (albedo, 1.0, 0.5, alpha.clamp(1e-4, 1.0).sqrt())
            }
            EnvisMaterial::Mix {
                albedo,
                specular,
                alpha,
            } => (
                albedo,
                specular.clamp(0.0, 1.0),
                0.5,
                alpha.clamp(1e-4, 1.0).sqrt(),
            ),
        }
    }

    /// The `StandardMaterial` that writes this material into the deferred G-buffer.
    pub fn standard(&self) -> StandardMaterial {
        let (c, metallic, reflectance, roughness) = self.encode();
        StandardMaterial {
            base_color: Color::linear_rgb(c.x, c.y, c.z),
            metallic,
            reflectance,
            perceptual_roughness: roughness,
            opaque_render_method: OpaqueRendererMethod::Deferred,
            ..default()
        }
    }

    /// The core material the lighting pass decodes from the G-buffer (8-bit quantised), i.e.
    /// what the CPU twin must render to compare with a Bevy frame.
    pub fn decoded(&self) -> Material {
        let (c, metallic, reflectance, roughness) = self.encode();
        let (base, m, refl, r) = (
            gbuffer_color(c),
            unorm8(metallic),
            unorm8(reflectance),
            unorm8(roughness),
        );
        let lobe = if refl >= 0.75 {
            let r2 = (r * r).max(1e-4);
            Lobe::Phong {
                exponent: (2.0 / (r2 * r2) - 2.0).clamp(0.0, 1e6),
            }
        } else if refl >= 0.25 {
            Lobe::Ggx {
                alpha: (r * r).clamp(1e-4, 1.0),
            }
        } else {
            Lobe::None
        };
        let ks = if lobe == Lobe::None {
            Vec3::ZERO
        } else {
            base * m
        };
        Material {
            kd: base * (1.0 - m),
            ks,
            lobe,
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct LightingView {
    world_from_clip: [[f32; 4]; 4],
    camera: [f32; 4],
    forward: [f32; 4],
    viewport: [f32; 4],
    options: [f32; 4],
    accumulate: [f32; 4],
}

/// The lighting pipeline (raw wgpu, shared WGSL with the headless backend), one per target format.
#[derive(Resource)]
pub struct LightingPipelines {
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    module: wgpu::ShaderModule,
    by_format: Mutex<HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>>,
    /// Times the first envis camera's lighting pass of a frame.
    timer: Option<AsyncTimer>,
    /// The probed pixel's record (6 vec4) and its readback.
    probe: wgpu::Buffer,
    probe_read: AsyncRead,
    /// Per view: the running mean of the accumulated frames (one vec4 per pixel) and its size.
    accum: Mutex<HashMap<Entity, (wgpu::Buffer, UVec2)>>,
}

impl LightingPipelines {
    fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        use wgpu::{BindingType as B, BufferBindingType as BB, ShaderStages as S};
        let e = |binding: u32, ty: B| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: S::FRAGMENT,
            ty,
            count: None,
        };
        let buf = |ty: BB| B::Buffer {
            ty,
            has_dynamic_offset: false,
            min_binding_size: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("envis lighting layout"),
            entries: &[
                e(
                    0,
                    B::Texture {
                        sample_type: wgpu::TextureSampleType::Uint,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                e(
                    1,
                    B::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                e(2, buf(BB::Storage { read_only: true })),
                e(3, buf(BB::Storage { read_only: true })),
                e(4, buf(BB::Storage { read_only: true })),
                e(5, buf(BB::Uniform)),
                e(6, buf(BB::Uniform)),
                e(7, buf(BB::Storage { read_only: false })),
                e(8, buf(BB::Storage { read_only: false })),
                e(9, buf(BB::Storage { read_only: true })),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("envis lighting"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = shaders::module(device, "envis lighting.wgsl", &shaders::lighting_source());
        let timer = AsyncTimer::new(device, queue, "envis lighting timer");
        let probe = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("envis probe"),
            size: 96,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let probe_read = AsyncRead::new(device, "envis probe readback", 96);
        LightingPipelines {
            layout,
            pipeline_layout,
            module,
            by_format: Mutex::new(HashMap::new()),
            timer,
            probe,
            probe_read,
            accum: Mutex::new(HashMap::new()),
        }
    }

    fn pipeline(&self, device: &wgpu::Device, format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
        let mut map = self.by_format.lock().expect("lighting pipelines");
        map.entry(format)
            .or_insert_with(|| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some("envis lighting"),
                    layout: Some(&self.pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &self.module,
                        entry_point: Some("fullscreen"),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    fragment: Some(wgpu::FragmentState {
                        module: &self.module,
                        entry_point: Some("lighting"),
                        compilation_options: Default::default(),
                        targets: &[Some(wgpu::ColorTargetState {
                            format,
                            blend: None,
                            write_mask: wgpu::ColorWrites::ALL,
                        })],
                    }),
                    primitive: Default::default(),
                    depth_stencil: None,
                    multisample: Default::default(),
                    multiview_mask: None,
                    cache: None,
                })
            })
            .clone()
    }
}

/// Adds the envis deferred lighting pass for [`EnvisCamera`] views.
pub struct MisLightingPlugin;

impl Plugin for MisLightingPlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(ExtractComponentPlugin::<EnvisCamera>::default());
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .add_systems(RenderStartup, init_lighting)
            .init_resource::<EnvisTimings>()
            .add_systems(
                Render,
                skip_bevy_deferred_lighting.in_set(RenderSystems::CreateViews),
            )
            .init_resource::<EnvisProbe>()
            .add_systems(
                Render,
                poll_lighting_readbacks.in_set(RenderSystems::Prepare),
            )
            .add_systems(
                Core3d,
                mis_lighting
                    .before(main_opaque_pass_3d)
                    .in_set(Core3dSystems::MainPass),
            );
    }
}

fn init_lighting(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<bevy::render::renderer::RenderQueue>,
) {
    commands.insert_resource(LightingPipelines::new(device.wgpu_device(), &queue));
}

/// Collect the lighting pass's GPU time and the probed pixel of an earlier frame (never waits).
fn poll_lighting_readbacks(
    pipes: Option<Res<LightingPipelines>>,
    timings: Res<EnvisTimings>,
    probe: Res<EnvisProbe>,
) {
    let Some(pipes) = pipes else { return };
    if let Some(ms) = pipes.timer.as_ref().and_then(|t| t.poll()) {
        timings.set(|t| t.lighting_gpu_ms = Some(ms));
    }
    if let Some(bytes) = pipes.probe_read.poll() {
        let v: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        if v[5][3] == 1.0 {
            let lobe = match v[2][3] as u32 {
                1 => Lobe::Phong { exponent: v[3][3] },
                2 => Lobe::Ggx { alpha: v[3][3] },
                _ => Lobe::None,
            };
            let v3 = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
            let r = ProbeResult {
                pixel: UVec2::new(v[5][0] as u32, v[5][1] as u32),
                gpixel: crate::render::GPixel {
                    n: v3(v[0]),
                    o: v3(v[1]),
                    material: Material {
                        kd: v3(v[2]),
                        ks: v3(v[3]),
                        lobe,
                    },
                },
                estimate: v3(v[4]),
                pixel_index: v[5][2] as u32,
            };
            *probe.lock().expect("probe") = Some(r);
        }
    }
}

/// Bevy's own deferred lighting must not also light envis views.
fn skip_bevy_deferred_lighting(
    mut commands: Commands,
    views: Query<Entity, (With<EnvisCamera>, Without<SkipDeferredLighting>)>,
) {
    for e in &views {
        commands.entity(e).insert(SkipDeferredLighting);
    }
}

/// The per-view lighting pass: G-buffer + this frame's distribution and pool -> HDR radiance.
#[allow(clippy::too_many_arguments)]
fn mis_lighting(
    view: ViewQuery<(&ViewTarget, &ViewPrepassTextures, &ExtractedView), With<EnvisCamera>>,
    pipes: Option<Res<LightingPipelines>>,
    state: Res<EnvSamplingState>,
    settings: Res<EnvisSettings>,
    counters: Res<EnvisCounters>,
    timings: Res<EnvisTimings>,
    mut ctx: RenderContext,
) {
    let t0 = std::time::Instant::now();
    let view_entity = view.entity();
    let (target, prepass, ev) = view.into_inner();
    let (Some(pipes), Some(sampler)) = (pipes, state.sampler.as_ref()) else {
        return;
    };
    let (Some(depth), Some(deferred)) = (prepass.depth_view(), prepass.deferred_view()) else {
        return;
    };
    let mut s = settings.sampling;
    if s.strategy == Strategy::Global && !sampler.has_global() {
        return; // its distribution is built from the next frame on
    }
    if s.light_samples + s.brdf_samples == 0 {
        s.light_samples = 1;
    }
    let vp = ev.viewport;
    s.seed = settings.frame_seed();
    let params = ShadeParams::new(&s, sampler.n, sampler.m, (vp.z * vp.w) as usize);
    let world_from_view = ev.world_from_view.to_matrix();
    let lv = LightingView {
        world_from_clip: (world_from_view * ev.clip_from_view.inverse()).to_cols_array_2d(),
        camera: ev
            .world_from_view
            .translation()
            .extend(if ev.clip_from_view.w_axis.w == 1.0 {
                1.0
            } else {
                0.0
            })
            .to_array(),
        forward: ev
            .world_from_view
            .forward()
            .as_vec3()
            .extend(settings.exposure)
            .to_array(),
        viewport: [vp.x as f32, vp.y as f32, vp.z as f32, vp.w as f32],
        options: {
            let overlay = Overlay::ALL
                .iter()
                .position(|o| *o == settings.overlay)
                .unwrap_or(0) as f32;
            let p = settings
                .probe
                .map_or([-1.0, -1.0], |p| [p.x as f32, p.y as f32]);
            [settings.show_sky as u32 as f32, overlay, p[0], p[1]]
        },
        accumulate: [
            settings.accumulate as u32 as f32,
            settings.frame as f32,
            0.0,
            0.0,
        ],
    };
    let device = ctx.render_device().wgpu_device().clone();
    let accum = {
        let mut map = pipes.accum.lock().expect("accumulation buffers");
        let size = UVec2::new(vp.z.max(1), vp.w.max(1));
        let entry = map.entry(view_entity).or_insert_with(|| {
            (
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("envis accumulation"),
                    size: 16,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                }),
                UVec2::ZERO,
            )
        });
        if settings.accumulate && entry.1 != size {
            let bytes = size.x as u64 * size.y as u64 * 16;
            *entry = (
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("envis accumulation"),
                    size: bytes,
                    usage: wgpu::BufferUsages::STORAGE,
                    mapped_at_creation: false,
                }),
                size,
            );
        }
        entry.0.clone()
    };
    let pipeline = pipes.pipeline(&device, target.main_texture_format());
    let ubuf = |label: &str, bytes: &[u8]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytes,
            usage: wgpu::BufferUsages::UNIFORM,
        })
    };
    let (pbuf, vbuf) = (
        ubuf("envis shade params", bytemuck::bytes_of(&params)),
        ubuf("envis lighting view", bytemuck::bytes_of(&lv)),
    );
    let energies = wgpu::BufferBinding {
        buffer: &sampler.totals,
        offset: 0,
        size: wgpu::BufferSize::new(crate::gpu::sampler::TOTALS_COLUMNS as u64 * 4),
    };
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("envis lighting"),
        layout: &pipes.layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(deferred),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::TextureView(depth),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: sampler.texels.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: sampler.pool.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: wgpu::BindingResource::Buffer(energies),
            },
            wgpu::BindGroupEntry {
                binding: 5,
                resource: pbuf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 6,
                resource: vbuf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 7,
                resource: pipes.probe.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 8,
                resource: accum.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 9,
                resource: sampler.gdist.as_entire_binding(),
            },
        ],
    });
    let probing = settings.probe.is_some() && pipes.probe_read.ready();
    let timer = pipes.timer.as_ref().filter(|t| t.ready());
    let enc = ctx.command_encoder();
    if probing {
        enc.clear_buffer(&pipes.probe, 0, None);
    }
    {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("envis mis lighting"),
            color_attachments: &[Some(target.get_color_attachment())],
            depth_stencil_attachment: None,
            timestamp_writes: timer.map(|t| t.render_writes()),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..3, 0..1);
    }
    if let Some(t) = timer {
        t.resolve(enc);
    }
    if probing {
        pipes.probe_read.copy_from(enc, &pipes.probe);
    }
    counters.bump(|c| &c.lighting_passes);
    if settings.overlay != Overlay::None {
        counters.bump(|c| &c.overlay_passes);
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    timings.set(|t| t.lighting_cpu_ms = Some(ms));
}
