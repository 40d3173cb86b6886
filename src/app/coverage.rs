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

/// Count the opaque `StandardMaterial` meshes that render forward while an envis camera exists,
/// and warn once, with the one line that fixes it.
pub fn warn_forward_meshes(
    cameras: Query<(), With<EnvironmentSampling>>,
    meshes: Query<&MeshMaterial3d<StandardMaterial>>,
    materials: Res<Assets<StandardMaterial>>,
    default_method: Option<Res<DefaultOpaqueRendererMethod>>,
    mut warned: Local<bool>,
) {
    if *warned || cameras.is_empty() {
        return;
    }
    // The resource has no getter nor PartialEq in Bevy 0.19: read its Debug form.
    let default_forward = default_method.is_none_or(|m| !format!("{:?}", *m).contains("Deferred"));
    let forward = meshes
        .iter()
        .filter_map(|m| materials.get(&m.0))
        .filter(|m| matches!(m.alpha_mode, AlphaMode::Opaque | AlphaMode::Mask(_)))
        .filter(|m| match m.opaque_render_method {
            OpaqueRendererMethod::Forward => true,
            OpaqueRendererMethod::Deferred => false,
            OpaqueRendererMethod::Auto => default_forward,
        })
        .count();
    if forward > 0 {
        warn!(
            "envis: {forward} opaque StandardMaterial mesh(es) render forward, so envis cannot light \
             them; add `app.insert_resource(DefaultOpaqueRendererMethod::deferred())` (docs/bevy.md)"
        );
        *warned = true;
    }
}
