//! An environment written on the GPU every frame: a compute shader paints a procedural sky (a
//! small, very bright sun circling the sky) into a lat-long `Image`; envis rebuilds its sampling
//! distribution from that texture every frame (`dynamic: true`), with no CPU round trip and no
//! bytes uploaded from the CPU.
//!
//! The paint runs in the render world's `RenderGraph` schedule before envis's
//! `build_distributions`, so the sky painted in a frame lights that same frame.
//!
//! `cargo run --release --example dynamic_sky`

use bevy::asset::RenderAssetUsages;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{texture_storage_2d, uniform_buffer};
use bevy::render::render_resource::*;
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::texture::GpuImage;
use bevy::render::{Render, RenderApp, RenderStartup, RenderSystems};
use bevy_envis::prelude::*;

const SHADER: &str = "shaders/dynamic_sky.wgsl";
const SIZE: UVec2 = UVec2::new(256, 128);

fn main() {
    App::new()
        .add_plugins((DefaultPlugins, EnvisPlugin))
        // Edit shaders/*.wgsl while it runs: the lighting pass recompiles.
        .add_plugins(EnvisShaderReloadPlugin::default())
        .add_plugins(example)
        .run();
}

/// The sky image, the sun's direction and radiance (main world, extracted every frame).
#[derive(Resource, Clone, ExtractResource)]
pub struct Sky {
    pub image: Handle<Image>,
    pub params: SkyParams,
}

#[derive(Clone, Copy, ShaderType)]
pub struct SkyParams {
    pub sun: Vec4,
}

/// The scene, the sky and its compute pass (everything but the window and `EnvisPlugin`).
pub fn example(app: &mut App) {
    app.add_plugins(ExtractResourcePlugin::<Sky>::default())
        .add_systems(Startup, setup)
        .add_systems(Update, move_sun);
    let render_app = app.sub_app_mut(RenderApp);
    render_app
        .add_systems(RenderStartup, init_pipeline)
        .add_systems(
            Render,
            prepare_bind_group.in_set(RenderSystems::PrepareBindGroups),
        )
        .add_systems(
            RenderGraph,
            paint_sky
                .before(bevy_envis::sampling::build_distributions)
                .before(camera_driver),
        );
}

fn setup(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut envis_materials: ResMut<Assets<EnvisMaterial>>,
) {
    // Written only on the GPU: no data, storage + sampling usage, render world only.
    let mut sky = Image::new_uninit(
        Extent3d {
            width: SIZE.x,
            height: SIZE.y,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        TextureFormat::Rgba32Float,
        RenderAssetUsages::RENDER_WORLD,
    );
    sky.texture_descriptor.usage = TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING;
    let image = images.add(sky);
    commands.insert_resource(Sky {
        image: image.clone(),
        params: SkyParams { sun: Vec4::ZERO },
    });
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.6).mesh().ico(5).expect("icosphere"))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.9, 0.9, 0.9),
            perceptual_roughness: 0.6,
            ..default()
        })),
        Transform::from_xyz(-0.8, 0.6, 0.0),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.6).mesh().ico(5).expect("icosphere"))),
        MeshMaterial3d(envis_materials.add(EnvisMaterial::ggx(Vec3::splat(0.9), 0.1))),
        Transform::from_xyz(0.8, 0.6, 0.0),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.5, 0.5, 0.5),
            perceptual_roughness: 1.0,
            ..default()
        })),
    ));
    commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 1.4, 3.8).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y),
        EnvironmentSampling::default(),
        EnvisEnvironment {
            // GPU writes are invisible to change detection: rebuild every frame.
            dynamic: true,
            ..EnvisEnvironment::new(image)
        },
        exposure_multiplier(1.0),
    ));
}

/// The sun circles the sky once every 20 seconds, 30 degrees above the horizon.
fn move_sun(time: Res<Time>, mut sky: ResMut<Sky>) {
    let a = time.elapsed_secs() * std::f32::consts::TAU / 20.0;
    let (e, c) = (30f32.to_radians().sin(), 30f32.to_radians().cos());
    let dir = Vec3::new(c * a.cos(), e, c * a.sin());
    // About 0.004 sr of sun at this radiance: ~1.5x the sky's own light on the ground.
    sky.params.sun = dir.extend(400.0);
}

#[derive(Resource)]
struct SkyPipeline {
    layout: BindGroupLayoutDescriptor,
    pipeline: CachedComputePipelineId,
}

#[derive(Resource)]
struct SkyBindGroup(BindGroup);

fn init_pipeline(mut commands: Commands, assets: Res<AssetServer>, cache: Res<PipelineCache>) {
    let layout = BindGroupLayoutDescriptor::new(
        "dynamic sky",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                texture_storage_2d(TextureFormat::Rgba32Float, StorageTextureAccess::WriteOnly),
                uniform_buffer::<SkyParams>(false),
            ),
        ),
    );
    let pipeline = cache.queue_compute_pipeline(ComputePipelineDescriptor {
        layout: vec![layout.clone()],
        shader: assets.load(SHADER),
        entry_point: Some("paint".into()),
        ..default()
    });
    commands.insert_resource(SkyPipeline { layout, pipeline });
}

fn prepare_bind_group(
    mut commands: Commands,
    sky: Option<Res<Sky>>,
    pipeline: Res<SkyPipeline>,
    images: Res<RenderAssets<GpuImage>>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    cache: Res<PipelineCache>,
) {
    let Some(image) = sky.as_ref().and_then(|s| images.get(&s.image)) else {
        return;
    };
    let mut params = UniformBuffer::from(sky.as_ref().map(|s| s.params).expect("sky"));
    params.write_buffer(&device, &queue);
    let bind_group = device.create_bind_group(
        "dynamic sky",
        &cache.get_bind_group_layout(&pipeline.layout),
        &BindGroupEntries::sequential((&image.texture_view, &params)),
    );
    commands.insert_resource(SkyBindGroup(bind_group));
}

fn paint_sky(
    mut ctx: RenderContext,
    bind_group: Option<Res<SkyBindGroup>>,
    pipeline: Res<SkyPipeline>,
    cache: Res<PipelineCache>,
) {
    let (Some(bind_group), Some(pipeline)) =
        (bind_group, cache.get_compute_pipeline(pipeline.pipeline))
    else {
        return; // the shader is still loading
    };
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor::default());
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &bind_group.0, &[]);
    pass.dispatch_workgroups(SIZE.x.div_ceil(8), SIZE.y.div_ceil(8), 1);
}
