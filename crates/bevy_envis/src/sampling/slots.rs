//! The environments' GPU samplers, one slot per `SamplerKey`: allocated on first use from an
//! image whose texture can be sampled.

use super::*;

/// The layout of an environment texture, or why it cannot be one.
pub(super) fn check_source(gpu: &GpuImage) -> Result<SourceLayout, String> {
    let d = &gpu.texture_descriptor;
    if !matches!(
        d.format.sample_type(None, None),
        Some(wgpu::TextureSampleType::Float { .. })
    ) {
        return Err(format!("its format {:?} is not a float format", d.format));
    }
    if !d.usage.contains(wgpu::TextureUsages::TEXTURE_BINDING) {
        return Err("its texture cannot be bound (no TEXTURE_BINDING usage)".into());
    }
    SourceLayout::detect(d.size.width, d.size.height, d.size.depth_or_array_layers)
}

/// The slot for `key`, allocated on first use with the compiled `build`; `None` (reported once)
/// when the device refuses.
pub(super) fn slot_for<'a>(
    samplers: &'a mut EnvSamplers,
    key: SamplerKey,
    (gpu, layout): (&GpuImage, SourceLayout),
    build: &std::sync::Arc<envis_wgpu::BuildPipelines>,
    (device, queue): (&RenderDevice, &RenderQueue),
    counters: &EnvisCounters,
) -> Option<&'a mut SamplerSlot> {
    use std::collections::hash_map::Entry;
    let vacant = match samplers.slots.entry(key) {
        Entry::Occupied(e) => return Some(e.into_mut()),
        Entry::Vacant(v) => v,
    };
    let grid = envis::sampling::TileGrid::new(key.face_size, key.tiles);
    let built = EnvSampler::with_pipelines(
        device.wgpu_device(),
        queue,
        build,
        grid,
        key.pool_slots,
        false,
    )
    .and_then(|mut s| {
        s.set_blocks(key.pool_blocks)?;
        Ok(s)
    });
    match built {
        Ok(sampler) => {
            counters.bump(|c: &Counters| &c.allocations);
            Some(vacant.insert(SamplerSlot {
                sampler,
                source: source_view(&gpu.texture),
                layout,
                width: gpu.texture_descriptor.size.width,
                built: None,
                seed: None,
                dirty: true,
                generation: 0,
            }))
        }
        Err(e) => {
            if samplers.refused.insert(key.image) {
                error!("envis: {e}");
            }
            None
        }
    }
}

impl SamplerSlot {
    /// Mark the slot for a rebuild when its image has a new version or texture (or is
    /// `dynamic`: every frame), its pool seed changed, or the `global` strategy needs its
    /// distribution for the first time; a new texture gets a new source view.
    pub(super) fn refresh(
        &mut self,
        (gpu, layout, (version, dynamic)): (&GpuImage, SourceLayout, (u64, bool)),
        pool: u32,
        strategy: Strategy,
        (device, queue): (&RenderDevice, &RenderQueue),
    ) {
        let source_id = gpu.texture.id();
        let width = gpu.texture_descriptor.size.width;
        if self.built != Some((version, source_id)) || dynamic {
            if self.built.is_some_and(|b| b.1 != source_id) || self.width != width {
                self.source = source_view(&gpu.texture);
                self.width = width;
                self.layout = layout;
            }
            self.built = Some((version, source_id));
            self.dirty = true;
        }
        if self.seed != Some(pool) {
            self.sampler.set_seed(queue, pool);
            self.seed = Some(pool);
            self.dirty = true;
        }
        if strategy == Strategy::Global && !self.sampler.has_global() {
            match self.sampler.enable_global(device.wgpu_device(), queue) {
                Ok(()) => self.dirty = true,
                Err(e) => error!("envis: {e}"),
            }
        }
    }
}
