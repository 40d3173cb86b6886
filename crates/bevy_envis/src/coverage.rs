//! Which meshes envis can light on an envis camera, and a warning (once) about those it cannot.
//!
//! Bevy's deferred path is chosen per material, not per camera: a `StandardMaterial` renders
//! forward unless `DefaultOpaqueRendererMethod::deferred()` is set (or the material asks for
//! `OpaqueRendererMethod::Deferred`). Forward meshes do not write the G-buffer, so the envis pass
//! cannot light them; transparent (blended) meshes are always forward.

use super::components::EnvironmentSampling;
use bevy::material::OpaqueRendererMethod;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;

/// Count the opaque `StandardMaterial` meshes that render forward while an envis camera exists
/// (warning once, with the one line that fixes it), and the transparent ones (which envis never
/// lights).
#[allow(
    clippy::too_many_arguments,
    reason = "a Bevy system's parameters are the data it touches"
)]
pub fn warn_forward_meshes(
    cameras: Query<(), With<EnvironmentSampling>>,
    meshes: Query<&MeshMaterial3d<StandardMaterial>>,
    added: Query<(), Added<MeshMaterial3d<StandardMaterial>>>,
    mut events: MessageReader<AssetEvent<StandardMaterial>>,
    materials: Res<Assets<StandardMaterial>>,
    default_method: Option<Res<DefaultOpaqueRendererMethod>>,
    mut warned: Local<(bool, bool)>,
    counters: Res<super::EnvisCounters>,
) {
    // Look again only when meshes or materials came or changed (glTF scenes load late).
    let changed = !added.is_empty() | (events.read().count() > 0);
    if !changed || cameras.is_empty() {
        return;
    }
    let default_forward = default_method.is_none_or(|m| !super::setup::is_deferred(&m));
    let (mut forward, mut blended) = (0u64, 0u64);
    for m in meshes.iter().filter_map(|m| materials.get(&m.0)) {
        if !matches!(m.alpha_mode, AlphaMode::Opaque | AlphaMode::Mask(_)) {
            blended += 1;
        } else if match m.opaque_render_method {
            OpaqueRendererMethod::Forward => true,
            OpaqueRendererMethod::Deferred => false,
            OpaqueRendererMethod::Auto => default_forward,
        } {
            forward += 1;
        }
    }
    use std::sync::atomic::Ordering::Relaxed;
    counters.0.forward_meshes.store(forward, Relaxed);
    counters.0.transparent_meshes.store(blended, Relaxed);
    if forward > 0 && !warned.0 {
        warn!(
            "envis: {forward} opaque StandardMaterial mesh(es) render forward, so envis cannot light \
             them; EnvisPlugin makes `DefaultOpaqueRendererMethod::deferred()` the default unless the \
             app sets another after it, or a material asks for forward (docs/bevy.md)"
        );
        warned.0 = true;
    }
    if blended > 0 && !warned.1 {
        warn!(
            "envis: {blended} transparent StandardMaterial mesh(es) (alpha blend) are drawn forward, \
             after the envis pass: Bevy's lights reach them, the envis environment does not \
             (docs/bevy.md)"
        );
        warned.1 = true;
    }
}
