//! `builtin:sky[:T]`: a procedural, time-varying environment (no files needed).
//!
//! A sky gradient (zenith blue -> bright horizon), a dim ground below the horizon, and a sun disk
//! whose radiance is 30,000 x the zenith sky (realistic order: the sun gives most of the
//! illuminance at midday). `T` is the time of day in hours: the sun rises in the east at 6,
//! culminates at 12 and sets in the west at 18; at night a faint sky remains (never all-zero).
//! The sun's angular radius is 1.5 degrees (about 5x the real sun) so that it stays resolvable
//! on practical cube faces (a 64^2 face has ~1.4 degree texels).

use glam::Vec3;

/// Time of day used by `builtin:sky` without `:T`.
pub const DEFAULT_HOURS: f32 = 10.0;
/// Angular radius of the sun disk (radians).
pub const SUN_RADIUS: f32 = 1.5 * std::f32::consts::PI / 180.0;
/// Sun radiance relative to the zenith sky radiance at full daylight.
pub const SUN_TO_ZENITH: f32 = 3.0e4;

/// Unit direction towards the sun at `hours` (+Y up; east = +X, south = -Z).
pub fn sun_direction(hours: f32) -> Vec3 {
    let h = hours.rem_euclid(24.0);
    // Hour angle: 0 at noon; the sun moves from east (+X) through south (-Z, tilted) to west.
    let ang = (h - 12.0) / 12.0 * std::f32::consts::PI;
    let max_elev = 60f32.to_radians();
    let elev = max_elev * ang.cos(); // below the horizon at night
    let az = Vec3::new(-ang.sin(), 0.0, -ang.cos() * 0.4).normalize_or(Vec3::X);
    (az * elev.cos() + Vec3::Y * elev.sin()).normalize()
}

/// Daylight factor in [0.02, 1]: how bright the sky is at `hours`.
pub fn daylight(hours: f32) -> f32 {
    let s = sun_direction(hours).y;
    (0.02 + 0.98 * (s / 0.3).clamp(0.0, 1.0)).min(1.0)
}

/// Radiance of the built-in sky in unit direction `d` at `hours`.
pub fn sky_radiance(d: Vec3, hours: f32) -> Vec3 {
    let day = daylight(hours);
    let sun = sun_direction(hours);
    let zenith = Vec3::new(0.20, 0.36, 0.80);
    let horizon = Vec3::new(0.85, 0.88, 0.95);
    let ground = Vec3::new(0.12, 0.10, 0.08);
    let mut c = if d.y >= 0.0 {
        let t = (1.0 - d.y).powi(3);
        zenith * (1.0 - t) + horizon * t
    } else {
        ground * (1.0 + d.y).max(0.2)
    };
    // Warm glow around the sun, strongest near the horizon.
    let glow = d.dot(sun).max(0.0).powi(32) * 2.0;
    c += Vec3::new(1.0, 0.7, 0.4) * glow;
    c *= day;
    if sun.y > -SUN_RADIUS && d.y >= 0.0 && d.dot(sun) >= SUN_RADIUS.cos() {
        c += Vec3::new(1.0, 0.93, 0.82) * (SUN_TO_ZENITH * 0.38 * day.max(0.3));
    }
    c
}

/// The sky as a cube map; each texel is the solid-angle-weighted mean of 8x8 sub-points, so the
/// small sun disk keeps its energy on coarse faces.
pub fn sky_cube(size: usize, hours: f32) -> super::CubeMap {
    super::resample::cube_from_fetch(size, 8, |d| sky_radiance(d, hours))
}
