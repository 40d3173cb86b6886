//! Sampling: per-face tabulated distributions, the per-frame light-sample pool, per-pixel face
//! weighting and counts, BRDF warps and materials, MIS, and the global (pbrt-style) baseline.
//! Each routine keeps its pdf beside it; f32 at run time, f64 in the reference.

pub mod brdf;
pub mod conditionals;
pub mod counts;
pub mod distribution;
pub mod faceweights;
pub mod fastmath;
pub mod global;
pub mod mis;
pub mod pool;
pub mod rng;
pub mod subtexel;
pub mod tiles;
pub mod warp;

pub use brdf::{Ggx, LANES, Lambert, Lobe, LocalBsdf, Material, Phong, SampleLanes};
pub use counts::{Counts, FaceCount, face_count};
pub use distribution::{CubeDistribution, Distribution1D, FaceDistribution, TileDistribution};
pub use faceweights::{FaceWeights, face_weights};
pub use global::GlobalDistribution;
pub use mis::Heuristic;
pub use pool::{LightPool, PoolSample};
pub use subtexel::SubTexels;
pub use tiles::{MAX_REGIONS, MAX_TILES, TileCounts, TileGrid, TileWeights};
