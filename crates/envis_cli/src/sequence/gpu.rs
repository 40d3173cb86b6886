//! A sequence on a headless wgpu device: the WGSL twins of the CPU path in [`super`], frame for
//! frame with the same seeds ([`envis_wgpu::resampling::GpuResampler`] with resampling,
//! [`envis_wgpu::GpuRenderer`] without). Shadow rays go through the scene's flattened BVH
//! ([`envis::scene::Scene::shadow_bvh`]), which the CPU's occluders match ray for ray.

use super::{Posed, SequenceFrame, SequenceOptions, frame_stats, split_map};
use envis::error::{Error, Result};
use envis::render::resampling::{ReuseStats, Split, map_agreement};
use envis::scene::Scene;
use envis_wgpu::resampling::{GpuFrame, GpuHistory, GpuResampler};
use envis_wgpu::{GpuContext, GpuRenderer};

/// [`super::run`] on a new headless device.
pub(super) fn run(
    scene: &Scene,
    o: &SequenceOptions,
    mut each: impl FnMut(SequenceFrame) -> Result<()>,
) -> Result<()> {
    let ctx = GpuContext::new()?;
    let (shadows, _) = scene.shadows(o.visibility);
    let mut plain = GpuRenderer::new(&ctx);
    let mut resampler = o.resampling.map(|_| GpuResampler::new(&ctx)).transpose()?;
    let mut prev: Option<(Posed, Split)> = None;
    for k in 0..o.frames {
        let cur = Posed::new(scene, scene.frame_time(k), o.size)?;
        let bvh = shadows
            .then(|| cur.scene.shadow_bvh())
            .transpose()
            .map_err(|e| Error::invalid(format!("shadow geometry: {e}")))?;
        let (Some(r), Some(resampler)) = (o.resampling, resampler.as_mut()) else {
            let (w, h) = (cur.camera.width, cur.camera.height);
            let shadows = bvh.as_ref().map(|b| (b, cur.screen.points.as_slice()));
            let (out, _) = plain.render_with_shadows(
                &cur.map,
                &cur.screen.gbuf,
                w,
                h,
                &o.settings,
                shadows,
            )?;
            each(SequenceFrame {
                stats: frame_stats(k, cur.time, &out.stats, ReuseStats::default()),
                image: out.image,
            })?;
            continue;
        };
        let split = split_map(&cur.map, &r);
        let reproject: Option<Vec<_>> = prev.as_ref().map(|(p, _)| {
            (0..cur.screen.gbuf.len())
                .map(|i| cur.reproject(p, i, r.mutation))
                .collect()
        });
        let history = (prev.as_ref().zip(reproject.as_deref())).map(|((_, ps), rep)| GpuHistory {
            reproject: rep,
            same_bright: ps.bright.same_light(&split.bright),
            map_agreement: map_agreement(&ps.rest, &split.rest),
            still_geometry: scene.geometry_is_still(),
        });
        let input = GpuFrame {
            screen: &cur.screen(None, &split),
            bvh: bvh.as_ref(),
            history,
        };
        let out = resampler.frame(&ctx, input, &o.settings, &r, k)?;
        each(SequenceFrame {
            stats: frame_stats(k, cur.time, &out.stats, out.reuse),
            image: out.image,
        })?;
        prev = Some((cur, split));
    }
    Ok(())
}
