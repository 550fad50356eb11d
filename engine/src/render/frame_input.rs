//! What one compositor frame is made of, as plain CPU data: the environment meshes, the lens
//! objects with their per-vertex shading terms and cube-map directions, and the viewpoint samples'
//! layered environment maps. The GPU frame ([`super::Frame`]) and the CPU f64 model
//! ([`super::model`]) both consume exactly this.

use std::sync::Arc;

use glam::{Mat4, Vec3};

/// Maximum number of viewpoint samples blended in one frame (the paper blends the two nearest).
pub const MAX_VIEWPOINTS: usize = 2;

/// Maximum layers per lens object that the single-pass variant supports (its vertex shader carries
/// one interpolated direction per layer and term, 2·MAX_LAYERS_SINGLE_PASS + 2 varyings, within
/// Vulkan's guaranteed 16 locations). The multipass variant has no such limit.
pub const MAX_LAYERS_SINGLE_PASS: usize = 6;

/// The two shading terms: the ray tracer's, so per-vertex data and reference images agree.
pub use crate::trace::path::Term;

/// A cube map of premultiplied RGBA (α·rgb, α) texels with a full mip chain.
///
/// Faces follow Vulkan's order (+X, −X, +Y, −Y, +Z, −Z) and its face-coordinate conventions
/// (Vulkan spec, "Cube Map Face Selection"); texels are row-major with row 0 at t = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct CubeMap {
    /// Edge length of a level-0 face in texels (a power of two, ≥ 1).
    pub size: u32,
    /// `levels[l][face]` holds `(size >> l)²` texels; `levels.len() == log2(size) + 1`.
    pub levels: Vec<[Vec<[f32; 4]>; 6]>,
}

impl CubeMap {
    /// Number of mip levels of a full chain for a face of `size` texels.
    pub fn full_chain_levels(size: u32) -> u32 {
        32 - size.max(1).leading_zeros()
    }

    /// Edge length of mip level `level`.
    pub fn level_size(&self, level: usize) -> u32 {
        (self.size >> level).max(1)
    }

    /// A cube map whose every texel of every level is `texel`.
    pub fn uniform(size: u32, texel: [f32; 4]) -> Self {
        let levels = (0..Self::full_chain_levels(size))
            .map(|l| {
                let n = ((size >> l).max(1) as usize).pow(2);
                std::array::from_fn(|_| vec![texel; n])
            })
            .collect();
        CubeMap { size, levels }
    }
}

/// Per-vertex data of one shading term of a lens object.
#[derive(Clone, Debug, PartialEq)]
pub struct TermVertices {
    /// Which term.
    pub term: Term,
    /// Per-vertex F·G (Fresnel product times attenuation), rgb, usually in [0, 1].
    pub fg: Vec<Vec3>,
    /// `directions[layer][vertex]`: the cube-map direction (shell hit − EM origin, not normalized).
    pub directions: Vec<Vec<Vec3>>,
}

/// A lens object: a triangle mesh whose vertices carry both terms' shading data.
#[derive(Clone, Debug, PartialEq)]
pub struct LensObject {
    /// Debug name (pass labels).
    pub name: String,
    /// World-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Counter-clockwise (front-facing, seen from the camera) triangles.
    pub triangles: Vec<[u32; 3]>,
    /// The terms this object has: a mirror has only [`Term::Reflection`].
    pub terms: Vec<TermVertices>,
    /// `layers[viewpoint][layer]`: the layered EM of each viewpoint sample, nearest shell first.
    /// Every viewpoint has the same number of layers n, equal to each term's `directions.len()`.
    /// Shared (`Arc`): frames reuse the same maps, and the renderer keeps a map uploaded for as
    /// long as frames keep handing it the same `Arc`.
    pub layers: Vec<Vec<Arc<CubeMap>>>,
}

impl LensObject {
    /// Number of layers n of this object's layered EMs.
    pub fn layer_count(&self) -> usize {
        self.layers.first().map_or(0, Vec::len)
    }
}

/// An opaque environment mesh drawn before the lens objects with depth test and write.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMesh {
    /// World-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex linear rgb colour.
    pub colours: Vec<Vec3>,
    /// Counter-clockwise triangles (both sides are drawn).
    pub triangles: Vec<[u32; 3]>,
}

/// Everything one compositor frame needs.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameInput {
    /// Framebuffer width in pixels.
    pub width: u32,
    /// Framebuffer height in pixels.
    pub height: u32,
    /// World → Vulkan clip space (y down, depth 0..1).
    pub view_proj: Mat4,
    /// Opaque environment, drawn first. Shared (`Arc`) like the layered EMs: the renderer keeps a
    /// mesh's buffers for as long as frames keep handing it the same `Arc`.
    pub environment: Vec<Arc<EnvironmentMesh>>,
    /// Lens objects.
    pub lenses: Vec<LensObject>,
    /// Weight of each viewpoint sample (one or two entries, summing to 1). A zero weight skips
    /// that viewpoint's passes.
    pub viewpoint_weights: Vec<f32>,
}

impl CubeMap {
    /// A cube map from its level-0 faces, with the rest of the chain made by 2×2 box filtering.
    /// Averaging premultiplied texels is exact (filtering commutes with premultiplication).
    pub fn from_level0(size: u32, faces: [Vec<[f32; 4]>; 6]) -> Self {
        let mut levels = vec![faces];
        let mut edge = size as usize;
        while edge > 1 {
            let half = edge / 2;
            let previous = &levels[levels.len() - 1];
            let next: [Vec<[f32; 4]>; 6] = std::array::from_fn(|face| {
                let src = &previous[face];
                (0..half * half)
                    .map(|i| {
                        let (x, y) = (2 * (i % half), 2 * (i / half));
                        let texels = [
                            src[y * edge + x],
                            src[y * edge + x + 1],
                            src[(y + 1) * edge + x],
                            src[(y + 1) * edge + x + 1],
                        ];
                        std::array::from_fn(|c| 0.25 * texels.iter().map(|t| t[c]).sum::<f32>())
                    })
                    .collect()
            });
            levels.push(next);
            edge = half;
        }
        CubeMap { size, levels }
    }

    /// A cube map whose level-0 texel is `f(direction through the texel centre)`, mips box-filtered.
    pub fn from_fn(size: u32, f: impl Fn(glam::DVec3) -> [f32; 4]) -> Self {
        let edge = size as usize;
        let faces = std::array::from_fn(|face| {
            let face = super::cube_sampling::CubeFace::ALL[face];
            (0..edge * edge)
                .map(|i| {
                    let s = ((i % edge) as f64 + 0.5) / edge as f64;
                    let t = ((i / edge) as f64 + 0.5) / edge as f64;
                    f(face.direction(2.0 * s - 1.0, 2.0 * t - 1.0))
                })
                .collect()
        });
        CubeMap::from_level0(size, faces)
    }
}
