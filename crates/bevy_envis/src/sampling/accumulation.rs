//! What a view's frame is drawn with: its seed (a new one per frame while accumulating or
//! jittered) and the key whose change restarts its accumulation.

use super::*;

/// The seed of a view's frame: the camera's own for a still, unjittered view; one per frame
/// averaged while accumulating; one per frame drawn (`tick`) for a jittered view that does not
/// accumulate.
pub(super) fn frame_seed(seed: u32, frame: u32, tick: Option<u32>) -> u32 {
    use envis::sampling::rng::hash_combine;
    match tick {
        _ if frame > 0 => hash_combine(&[seed, frame]),
        Some(t) => hash_combine(&[seed, t, 0x7aa]),
        None => seed,
    }
}

/// A hash of everything a view's image depends on besides the frame's seed (its layers decide
/// which meshes shadow it).
pub(super) fn accumulation_key(
    s: &EnvironmentSampling,
    env: &EnvisEnvironment,
    (view, layers): (&ExtractedView, envis::visibility::Layers),
    version: (u64, u64),
) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    format!("{s:?}").hash(&mut h);
    let floats = [
        env.intensity,
        env.rotation.x,
        env.rotation.y,
        env.rotation.z,
        env.rotation.w,
    ];
    for x in floats
        .iter()
        .chain(view.world_from_view.to_matrix().to_cols_array().iter())
        .chain(view.clip_from_view.to_cols_array().iter())
    {
        x.to_bits().hash(&mut h);
    }
    (
        env.image.id(),
        env.show_background,
        view.viewport,
        version,
        layers.0,
    )
        .hash(&mut h);
    h.finish()
}

/// View `entity`'s frame in its running mean (0: a restart, when `acc_key` changed, the view does
/// not accumulate or its environment is dynamic) and, for a jittered view that does not
/// accumulate, its frame count (`tick`). Such a view is averaged over frames by its temporal
/// antialiasing (TAA): each of its frames draws new samples too, or TAA would average the same
/// noise.
pub(super) fn next_frame(
    samplers: &mut EnvSamplers,
    entity: Entity,
    (sampling, env): (&EnvironmentSampling, &EnvisEnvironment),
    acc_key: u64,
    jittered: bool,
) -> (u32, Option<u32>) {
    let e = samplers.accumulation.entry(entity).or_insert((acc_key, 0));
    if !sampling.accumulate || e.0 != acc_key || env.dynamic {
        *e = (acc_key, 0);
    } else {
        e.1 += 1;
    }
    let frame = e.1;
    let tick = (jittered && !sampling.accumulate).then(|| {
        let t = samplers.ticks.entry(entity).or_insert(0);
        *t = t.wrapping_add(1);
        *t
    });
    (frame, tick)
}
