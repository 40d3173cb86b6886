//! The environment maps of resampling cameras on the CPU, where the bright part's split
//! (`bright.rs`) reads them: the envis stream's current frame (its [`EnvFrame`]'s cube map), and
//! any other image a resampling camera is lit by, read from the main world's `Assets<Image>`
//! once per version of the image ([`EnvImageVersions`]).
//!
//! Why on the CPU: the split is the CPU oracle's (`render::resampling::Split`, the same
//! threshold and table), so the Bevy pass and the oracle resample the same bright part. A
//! user's `Image` keeps its texels in the main world as long as its `RenderAssetUsages` has
//! `MAIN_WORLD` (the default of Bevy's loaders); one without them (render-world only, or written
//! on the GPU: `EnvisEnvironment::dynamic`) is resampled whole, with one warning.

use super::EnvironmentResampling;
use crate::app::components::EnvisEnvironment;
use crate::app::sampling::EnvImageVersions;
use crate::app::{EnvFrame, EnvMapStream};
use crate::envmap::resample::{SourceImage, SourceLayout, bevy_cube_layers};
use crate::envmap::{CubeMap, Image as EnvImage};
use bevy::prelude::*;
use bevy::render::MainWorld;
use std::collections::{HashMap, HashSet};
use std::sync::Arc;

/// Where a map's texels came from, and which version of them: what decides whether the CPU
/// copy is still current.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Version {
    /// The stream's frame of this generation.
    Stream(u64),
    /// An image asset at this version.
    Asset(u64),
}

/// One map on the CPU.
pub struct CpuEnvMap {
    version: Version,
    /// Distinct for every content this cache has held: what a view's split is keyed by.
    pub revision: u64,
    /// `None` where this version could not be read (said once; not tried again until the
    /// image changes).
    pub source: Option<Arc<SourceImage>>,
}

/// The render world's CPU copies of the maps resampling cameras are lit by, by image.
#[derive(Resource, Default)]
pub struct CpuEnvMaps {
    pub maps: HashMap<AssetId<Image>, CpuEnvMap>,
    revisions: u64,
}

impl CpuEnvMaps {
    /// The map of `image`, where there is one on the CPU.
    pub fn source(&self, image: AssetId<Image>) -> Option<(u64, &SourceImage)> {
        let m = self.maps.get(&image)?;
        Some((m.revision, m.source.as_deref()?))
    }

    /// Keep `id`'s entry if it is at `version`, else make it with `make` (an entry without a
    /// map, and one warning, where `make` fails).
    fn refresh(
        &mut self,
        id: AssetId<Image>,
        version: Version,
        make: impl FnOnce() -> Result<SourceImage, String>,
    ) {
        if self.maps.get(&id).is_some_and(|m| m.version == version) {
            return;
        }
        let source = make()
            .map_err(|e| {
                bevy::log::warn_once!("envis resampling: the map's bright part is not split ({e})")
            })
            .ok()
            .map(Arc::new);
        self.revisions += 1;
        let revision = self.revisions;
        self.maps.insert(
            id,
            CpuEnvMap {
                version,
                revision,
                source,
            },
        );
    }
}

/// Bring [`CpuEnvMaps`] up to date with the maps the active resampling cameras are lit by,
/// dropping the others. An image still loading (no version yet) is skipped in silence.
pub(super) fn extract_cpu_maps(maps: &mut CpuEnvMaps, main_world: &mut MainWorld) {
    let mut cameras =
        main_world.query_filtered::<(&Camera, &EnvisEnvironment), With<EnvironmentResampling>>();
    let used: Vec<(AssetId<Image>, bool)> = (cameras.iter(main_world))
        .filter(|(c, _)| c.is_active)
        .map(|(_, e)| (e.image.id(), e.dynamic))
        .collect();
    let stream = main_world
        .get_resource::<EnvMapStream>()
        .map(|s| s.image.id())
        .zip(main_world.get_resource::<EnvFrame>());
    let (images, versions) = (
        main_world.get_resource::<Assets<Image>>(),
        main_world.get_resource::<EnvImageVersions>(),
    );
    for &(id, dynamic) in &used {
        let version = versions.and_then(|v| v.0.get(&id)).copied();
        match (stream, version) {
            (Some((s, frame)), _) if s == id => {
                let map = frame.map.clone();
                maps.refresh(id, Version::Stream(frame.generation), || {
                    Ok(SourceImage::new_cube(bevy_cube_layers(&map)))
                });
            }
            (_, Some(version)) if !dynamic => {
                maps.refresh(id, Version::Asset(version), || {
                    let image = images.and_then(|a| a.get(id));
                    source_from_image(image.ok_or("the image is not in the main world")?)
                });
            }
            _ => {
                maps.maps.remove(&id);
            }
        }
    }
    let used: HashSet<AssetId<Image>> = used.into_iter().map(|(id, _)| id).collect();
    maps.maps.retain(|id, _| used.contains(id));
}

/// A Bevy environment image's texels as the GPU's resample reads them: a 2:1 lat-long or a
/// cube of six square layers (as `SourceLayout::detect` decides for the GPU), any format Bevy
/// can read a colour from (`Image::get_color_at`), sanitised; an error for an image without
/// CPU texels or of another shape.
pub fn source_from_image(image: &Image) -> Result<SourceImage, String> {
    if image.data.is_none() {
        return Err("the image has no texels in the main world (RenderAssetUsages)".into());
    }
    let size = image.texture_descriptor.size;
    let (w, h) = (size.width, size.height);
    let layout = SourceLayout::detect(w, h, size.depth_or_array_layers)?;
    let texel = |x: u32, y: u32, z: u32| -> Result<Vec3, String> {
        let c = match layout {
            SourceLayout::LatLong => image.get_color_at(x, y),
            SourceLayout::Cube => image.get_color_at_3d(x, y, z),
        };
        let c = c.map_err(|e| format!("cannot read its texels: {e}"))?;
        Ok(c.to_linear().to_vec3())
    };
    let layers = match layout {
        SourceLayout::LatLong => 1,
        SourceLayout::Cube => 6,
    };
    let mut data = Vec::with_capacity((w * h * layers) as usize);
    for z in 0..layers {
        for y in 0..h {
            for x in 0..w {
                data.push(texel(x, y, z)?);
            }
        }
    }
    Ok(match layout {
        SourceLayout::LatLong => SourceImage::new_latlong(EnvImage {
            width: w as usize,
            height: h as usize,
            data,
        }),
        SourceLayout::Cube => SourceImage::new_cube(CubeMap {
            size: w as usize,
            data,
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};

    /// A Bevy float image of `layers` layers `w x h` holding `texels` in order.
    fn bevy_image(w: u32, h: u32, layers: u32, texels: &[Vec3], usage: RenderAssetUsages) -> Image {
        let bytes: Vec<u8> = (texels.iter())
            .flat_map(|c| [c.x, c.y, c.z, 1.0])
            .flat_map(f32::to_ne_bytes)
            .collect();
        let size = Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: layers,
        };
        Image::new(
            size,
            TextureDimension::D2,
            bytes,
            TextureFormat::Rgba32Float,
            usage,
        )
    }

    /// A lat-long and a cube image read back as the GPU's resample reads them: the same
    /// radiance in every direction as the maps they were made from.
    #[test]
    fn bevy_images_read_as_their_maps() {
        let f = |d: Vec3| Vec3::new(d.x.max(0.0), 0.5 + 0.5 * d.y, 40.0 * d.z.max(0.9) - 36.0);
        let mut ll = EnvImage::new(16, 8);
        for (i, t) in ll.data.iter_mut().enumerate() {
            let (u, v) = ((i % 16) as f32 + 0.5, (i / 16) as f32 + 0.5);
            *t = f(crate::envmap::latlong_to_dir(u / 16.0, v / 8.0));
        }
        let cube = CubeMap::from_fn(8, f);
        let layers = bevy_cube_layers(&cube);
        let all = RenderAssetUsages::default();
        let from_ll = source_from_image(&bevy_image(16, 8, 1, &ll.data, all)).unwrap();
        let from_cube = source_from_image(&bevy_image(8, 8, 6, &layers.data, all)).unwrap();
        let (want_ll, want_cube) = (SourceImage::new_latlong(ll), SourceImage::new_cube(layers));
        for k in 0..200 {
            // A spiral over the sphere.
            let (z, phi) = (1.0 - (k as f32 + 0.5) / 100.0, k as f32 * 2.399_963);
            let r = (1.0 - z * z).sqrt();
            let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            assert_eq!(
                from_ll.radiance_nearest(d),
                want_ll.radiance_nearest(d),
                "{d}"
            );
            assert_eq!(
                from_cube.radiance_nearest(d),
                want_cube.radiance_nearest(d),
                "{d}"
            );
            assert_eq!(from_cube.radiance_nearest(d), cube.lookup(d), "{d}");
        }
    }

    /// An image without main-world texels, or of no environment shape, is refused in words.
    #[test]
    fn images_without_texels_or_shape_are_refused() {
        let texels = vec![Vec3::ONE; 8 * 8];
        let gpu_only = bevy_image(8, 8, 1, &texels, RenderAssetUsages::RENDER_WORLD);
        let mut gpu_only = gpu_only;
        gpu_only.data = None;
        let e = source_from_image(&gpu_only).err().unwrap();
        assert!(e.contains("no texels"), "{e}");
        let square = bevy_image(8, 8, 1, &texels, RenderAssetUsages::default());
        let e = source_from_image(&square).err().unwrap();
        assert!(e.contains("not a 2:1"), "{e}");
    }
}
