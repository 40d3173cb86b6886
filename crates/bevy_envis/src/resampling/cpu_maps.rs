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
//!
//! A user's image is read, and resampled to the cameras' face sizes, on Bevy's async compute
//! pool (for a 2048 x 1024 lat-long about 0.2 s, docs/temporal.md): the frames meanwhile
//! resample the map whole (the previous version's split is dropped with it), so loading a map
//! never stalls a frame. A face size asked for later (a camera's `face_size` changed) is made
//! there too, from the texels already read, the frames meanwhile resampling the map whole. The
//! stream's frame is a cube map already, copied at once and resampled in the pass.

use super::EnvironmentResampling;
use crate::components::{EnvironmentSampling, EnvisEnvironment};
use crate::sampling::{EnvImageVersions, face_size_of};
use crate::{EnvFrame, EnvMapStream};
use bevy::prelude::*;
use bevy::render::MainWorld;
use bevy::tasks::{AsyncComputeTaskPool, Task, futures::check_ready};
use envis::envmap::resample::{SourceImage, SourceLayout, bevy_cube_layers};
use envis::envmap::{CubeMap, Image as EnvImage};
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

/// A map read on the CPU, and resampled to the face sizes asked for when it was read.
pub struct CpuMap {
    pub source: Arc<SourceImage>,
    cubes: Vec<CubeMap>,
    /// Whether a face size not made with the map is made when asked: the stream's frame (a
    /// cube already, copied in the extraction), not a user's image (a large lat-long's
    /// resampling would stall the render thread; [`extract_cpu_maps`] makes it on the async
    /// pool instead).
    on_demand: bool,
}

impl CpuMap {
    /// The map as the sampler's texel table of face size `n` (`SourceImage::to_cube`), made
    /// now where it was not made with the map and the map allows it; `None` until then.
    pub fn cube(&self, n: usize) -> Option<std::borrow::Cow<'_, CubeMap>> {
        match self.made(n) {
            Some(c) => Some(std::borrow::Cow::Borrowed(c)),
            None if self.on_demand => Some(std::borrow::Cow::Owned(self.source.to_cube(n))),
            None => None,
        }
    }

    /// The cube of face size `n`, where it was made with the map.
    fn made(&self, n: usize) -> Option<&CubeMap> {
        self.cubes.iter().find(|c| c.size == n)
    }

    /// Whether every face size of `sizes` is made (or made when asked).
    fn has_cubes(&self, sizes: &[usize]) -> bool {
        self.on_demand || sizes.iter().all(|&n| self.made(n).is_some())
    }

    /// This map with the cubes of `sizes` it lacks made (the work of an async task).
    fn with_cubes(&self, sizes: &[usize]) -> CpuMap {
        let mut sizes = sizes.to_vec();
        sizes.sort_unstable();
        sizes.dedup();
        let missing = sizes.into_iter().filter(|&n| self.made(n).is_none());
        let new: Vec<CubeMap> = missing.map(|n| self.source.to_cube(n)).collect();
        CpuMap {
            source: self.source.clone(),
            cubes: self.cubes.iter().cloned().chain(new).collect(),
            on_demand: self.on_demand,
        }
    }
}

/// One map's CPU copy, being read or read.
enum Content {
    Pending(Task<Result<CpuMap, String>>),
    /// `None` where it could not be read (said once; not tried again until the image changes).
    Ready(Option<Arc<CpuMap>>),
}

/// One image's entry.
struct CpuEnvMap {
    version: Version,
    /// Distinct for every content this cache has held: what a view's split is keyed by.
    revision: u64,
    content: Content,
}

/// The render world's CPU copies of the maps resampling cameras are lit by, by image.
#[derive(Resource, Default)]
pub struct CpuEnvMaps {
    maps: HashMap<AssetId<Image>, CpuEnvMap>,
    revisions: u64,
}

impl CpuEnvMaps {
    /// The map of `image` with its revision, where one is on the CPU.
    pub fn map(&self, image: AssetId<Image>) -> Option<(u64, &CpuMap)> {
        let m = self.maps.get(&image)?;
        match &m.content {
            Content::Ready(Some(map)) => Some((m.revision, map)),
            _ => None,
        }
    }

    /// Keep `id`'s entry if it is at `version` and has the cubes of `sizes` (taking its result
    /// if it was being read), else start it anew with `make`, given the map read at this
    /// version where one lacks cubes (so that only they are made).
    fn refresh(
        &mut self,
        (id, version): (AssetId<Image>, Version),
        sizes: &[usize],
        make: impl FnOnce(Option<Arc<CpuMap>>) -> Content,
    ) {
        let entry = self.maps.get_mut(&id).filter(|m| m.version == version);
        let content = match entry {
            Some(CpuEnvMap {
                content: Content::Pending(task),
                ..
            }) => match check_ready(task) {
                Some(read) => ready(read),
                None => return,
            },
            Some(CpuEnvMap {
                content: Content::Ready(Some(map)),
                ..
            }) if !map.has_cubes(sizes) => make(Some(map.clone())),
            Some(_) => return,
            None => make(None),
        };
        self.revisions += 1;
        let revision = self.revisions;
        self.maps.insert(
            id,
            CpuEnvMap {
                version,
                revision,
                content,
            },
        );
    }
}

/// A read map as an entry's content (one warning where it could not be read).
fn ready(read: Result<CpuMap, String>) -> Content {
    let map = read.map_err(|e| {
        bevy::log::warn_once!("envis resampling: the map's bright part is not split ({e})")
    });
    Content::Ready(map.ok().map(Arc::new))
}

/// Bring [`CpuEnvMaps`] up to date with the maps the active resampling cameras are lit by,
/// dropping the others. An image still loading (no version yet) is skipped in silence.
pub(super) fn extract_cpu_maps(maps: &mut CpuEnvMaps, main_world: &mut MainWorld) {
    let mut cameras = main_world.query_filtered::<
        (&Camera, &EnvisEnvironment, &EnvironmentSampling),
        With<EnvironmentResampling>,
    >();
    let mut used: HashMap<AssetId<Image>, (bool, Vec<usize>)> = HashMap::new();
    for (_, env, sampling) in cameras.iter(main_world).filter(|(c, ..)| c.is_active) {
        let e = used
            .entry(env.image.id())
            .or_insert((env.dynamic, Vec::new()));
        e.1.push(face_size_of(sampling));
    }
    let stream = main_world
        .get_resource::<EnvMapStream>()
        .map(|s| s.image.id())
        .zip(main_world.get_resource::<EnvFrame>());
    let (images, versions) = (
        main_world.get_resource::<Assets<Image>>(),
        main_world.get_resource::<EnvImageVersions>(),
    );
    for (&id, (dynamic, sizes)) in &used {
        let version = versions.and_then(|v| v.0.get(&id)).copied();
        match (stream, version) {
            (Some((s, frame)), _) if s == id => {
                let map = frame.map.clone();
                maps.refresh((id, Version::Stream(frame.generation)), sizes, |_| {
                    let source = SourceImage::new_cube(bevy_cube_layers(&map));
                    ready(Ok(CpuMap {
                        source: Arc::new(source),
                        cubes: Vec::new(),
                        on_demand: true,
                    }))
                });
            }
            (_, Some(version)) if !dynamic => {
                // The image is cloned (for the task) only when this version is new; a face
                // size asked for later is made from the map already read.
                maps.refresh((id, Version::Asset(version)), sizes, |read| {
                    let image = read
                        .is_none()
                        .then(|| images.and_then(|a| a.get(id)).cloned());
                    let sizes = sizes.clone();
                    Content::Pending(AsyncComputeTaskPool::get().spawn(async move {
                        match read {
                            Some(map) => Ok(map.with_cubes(&sizes)),
                            None => read_map(image.flatten().as_ref(), &sizes),
                        }
                    }))
                });
            }
            _ => {
                maps.maps.remove(&id);
            }
        }
    }
    let used: HashSet<AssetId<Image>> = used.into_keys().collect();
    maps.maps.retain(|id, _| used.contains(id));
}

/// `image` read ([`source_from_image`]) and resampled to each face size of `sizes`.
fn read_map(image: Option<&Image>, sizes: &[usize]) -> Result<CpuMap, String> {
    let source = source_from_image(image.ok_or("the image is not in the main world")?)?;
    let read = CpuMap {
        source: Arc::new(source),
        cubes: Vec::new(),
        on_demand: false,
    };
    Ok(read.with_cubes(sizes))
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
            *t = f(envis::envmap::latlong_to_dir(u / 16.0, v / 8.0));
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

    /// A map read for face sizes 4 and 8 gives those cubes, each the source's `to_cube`, and
    /// no other until it is made with the map (on the async pool: never on the render thread);
    /// the stream's frame makes any when asked.
    #[test]
    fn read_maps_have_the_cubes_asked_for() {
        let layers = bevy_cube_layers(&CubeMap::from_fn(8, |d| Vec3::splat(1.0 + d.x)));
        let image = bevy_image(8, 8, 6, &layers.data, RenderAssetUsages::default());
        let map = read_map(Some(&image), &[8, 4, 8]).unwrap();
        assert_eq!(map.cubes.len(), 2);
        let cube = |m: &CpuMap, n| m.cube(n).map(|c| c.data.clone());
        for n in [4, 8] {
            assert_eq!(cube(&map, n), Some(map.source.to_cube(n).data), "{n}");
        }
        assert!(map.has_cubes(&[4, 8]) && !map.has_cubes(&[8, 5]));
        assert_eq!(cube(&map, 5), None);
        let more = map.with_cubes(&[5, 8]);
        assert_eq!(more.cubes.len(), 3);
        assert_eq!(cube(&more, 5), Some(map.source.to_cube(5).data));
        let stream = CpuMap {
            on_demand: true,
            ..map.with_cubes(&[])
        };
        assert_eq!(cube(&stream, 5), Some(map.source.to_cube(5).data));
        assert!(read_map(None, &[8]).is_err());
    }

    /// An entry lacking a face size asked for is extended from the map it read (not read
    /// again), and one that has them all is kept as it is.
    #[test]
    fn entries_lacking_a_face_size_are_extended() {
        let layers = bevy_cube_layers(&CubeMap::from_fn(4, |_| Vec3::ONE));
        let image = bevy_image(4, 4, 6, &layers.data, RenderAssetUsages::default());
        let map = Arc::new(read_map(Some(&image), &[4]).unwrap());
        let mut maps = CpuEnvMaps::default();
        let (id, version) = (AssetId::<Image>::default(), Version::Asset(1));
        let made = std::cell::Cell::new(0);
        let refresh = |maps: &mut CpuEnvMaps, sizes: &[usize]| {
            maps.refresh((id, version), sizes, |read| {
                made.set(made.get() + 1);
                let map = read.map_or_else(|| map.with_cubes(sizes), |m| m.with_cubes(sizes));
                Content::Ready(Some(Arc::new(map)))
            })
        };
        refresh(&mut maps, &[4]);
        refresh(&mut maps, &[4]);
        assert_eq!(made.get(), 1, "a complete entry is kept");
        refresh(&mut maps, &[4, 6]);
        assert_eq!(made.get(), 2, "a missing face size is made");
        let (_, m) = maps.map(id).unwrap();
        assert!(m.cube(6).is_some() && m.cube(4).is_some());
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
