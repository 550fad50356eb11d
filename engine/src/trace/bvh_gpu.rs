//! A [`TraceScene`]'s geometry in the layout the GPU tracer reads (`shaders/wgsl/tracer.wgsl`):
//! every part's triangles in one array and a binary BVH per part, built by obvhs on the CPU.
//!
//! Why a binary BVH and not obvhs's compressed-wide one (which the CPU traverses, and which
//! published GPU traversals use): a lens object has a few thousand triangles, where a BVH2 walked
//! with a short stack is already a few levels deep, and its traversal is forty lines of WGSL that
//! are easy to check against the CPU's hits; the CWBVH's quantized 8-wide nodes pay off on large
//! incoherent scenes. The two have not been measured against each other yet.

use std::time::Duration;

use obvhs::{Boundable, BvhBuildParams, bvh2::builder::build_bvh2};

use super::bvh::{MeshBvh, padded_bounds};
use super::world::TraceScene;
use crate::scene::Material;

/// The root index of a part without triangles.
pub const NO_NODE: u32 = u32::MAX;

/// vec4s per triangle: (v0, object), (e1, CPU triangle id), e2, face normal, three vertex normals.
pub const TRIANGLE_VEC4S: usize = 7;

/// Entries of the traversal stack in `tracer.wgsl` (`STACK_SIZE`). Each level of a walk leaves at
/// most one sibling on the stack, so a BVH of depth d needs d + 1 entries: a deeper one is
/// refused ([`GpuGeometry::depth`]), never traversed with children dropped.
pub const STACK_ENTRIES: u32 = 64;

/// The scene's geometry for the GPU tracer.
#[derive(Clone, Debug, Default)]
pub struct GpuGeometry {
    /// Two vec4 per node: (min, first index as bits), (max, primitive count as bits). A leaf's
    /// first index names a triangle, an inner node's its first child (the second follows).
    pub nodes: Vec<[f32; 4]>,
    /// [`TRIANGLE_VEC4S`] vec4 per triangle, in BVH order, f32.
    pub triangles: Vec<[f32; 4]>,
    /// The same in f64, the CPU's own values (the object and id as exact f64 values), for the
    /// tracer's f64 passes (`shaders/wgsl/include/real_f64.wgsl`).
    pub triangles_f64: Vec<[f64; 4]>,
    /// Root node per part: the environment, then each lens object ([`NO_NODE`]: no triangle).
    pub roots: Vec<u32>,
    /// Per part its first triangle and its triangle count: what the tracer's ray-query
    /// traversal reads instead of the roots (`shaders/wgsl/include/walk_rq.wgsl`).
    pub ranges: Vec<[u32; 2]>,
    /// Per part each triangle's padded box `[min, max]`, in triangle order: the boxes of the
    /// driver's acceleration structures (`crate::gpu::acceleration::BoxScene`), the same boxes
    /// as the BVH's leaves.
    pub boxes: Vec<Vec<[f32; 6]>>,
    /// Two vec4 per scene object: (kind: 0 diffuse, 1 glass, 2 mirror; index of refraction),
    /// (absorption per metre, or reflectance at normal incidence).
    pub materials: Vec<[f32; 4]>,
    /// The deepest leaf of any part's BVH (the root has depth 0).
    pub depth: u32,
}

impl GpuGeometry {
    /// Flattens `trace`: the environment (part 0) and each lens object (part 1 + l), with the
    /// triangles the CPU's BVHs hold (degenerate ones already left out).
    pub fn new(trace: &TraceScene) -> GpuGeometry {
        let mut geometry = GpuGeometry::default();
        let parts = std::iter::once(&trace.environment).chain(trace.lenses.iter().map(|l| &l.bvh));
        for bvh in parts {
            let first = geometry.triangle_count() as u32;
            let root = geometry.push_part(bvh);
            geometry.roots.push(root);
            geometry
                .ranges
                .push([first, geometry.triangle_count() as u32 - first]);
        }
        geometry.materials = trace
            .object_materials
            .iter()
            .flat_map(|material| match *material {
                Material::Glass { ior, absorption } => {
                    [[1.0, ior, 0.0, 0.0], absorption.extend(0.0).to_array()]
                }
                Material::Mirror { reflectance } => {
                    [[2.0, 1.0, 0.0, 0.0], reflectance.extend(0.0).to_array()]
                }
                Material::Diffuse { .. } | Material::Glossy(_) => [[0.0; 4], [0.0; 4]],
            })
            .collect();
        if geometry.materials.is_empty() {
            geometry.materials.push([0.0; 4]);
        }
        geometry
    }

    /// The parts and triangles [`GpuGeometry::new`] makes of `trace`, without building it.
    pub fn shape_of(trace: &TraceScene) -> (usize, usize) {
        let parts = std::iter::once(&trace.environment).chain(trace.lenses.iter().map(|l| &l.bvh));
        let triangles = parts.map(|bvh| bvh.triangles.len()).sum();
        (1 + trace.lenses.len(), triangles)
    }

    /// Triangles of all parts.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len() / TRIANGLE_VEC4S
    }

    /// Appends one part's triangles and BVH; returns its root node.
    fn push_part(&mut self, bvh: &MeshBvh) -> u32 {
        let triangles = &bvh.triangles;
        if triangles.is_empty() {
            self.boxes.push(Vec::new());
            return NO_NODE;
        }
        let bounds: Vec<_> = triangles.iter().map(|t| padded_bounds(t, 1.0)).collect();
        let bvh2 = build_bvh2(
            &bounds,
            BvhBuildParams {
                max_prims_per_leaf: 3,
                ..BvhBuildParams::medium_build()
            },
            &mut Duration::default(),
        );
        self.depth = self.depth.max(depth(&bvh2.nodes));
        let node_base = (self.nodes.len() / 2) as u32;
        let triangle_base = self.triangle_count() as u32;
        for node in &bvh2.nodes {
            let leaf = node.prim_count > 0;
            let first = if leaf {
                triangle_base + node.first_index
            } else {
                node_base + node.first_index
            };
            let (lo, hi) = (node.aabb.min, node.aabb.max);
            self.nodes.push([lo.x, lo.y, lo.z, f32::from_bits(first)]);
            self.nodes
                .push([hi.x, hi.y, hi.z, f32::from_bits(node.prim_count)]);
        }
        self.boxes.push(
            bvh2.primitive_indices
                .iter()
                .map(|&index| {
                    let b = bounds[index as usize].aabb();
                    [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z]
                })
                .collect(),
        );
        for &index in &bvh2.primitive_indices {
            let t = &triangles[index as usize];
            let w = |d: glam::DVec3, w: u32| [d.x, d.y, d.z, f64::from(w)];
            self.triangles_f64.extend([
                w(t.v0, t.object),
                w(t.e1, index),
                w(t.e2, 0),
                w(t.geometric_normal, 0),
            ]);
            self.triangles_f64.extend(t.normals.map(|n| w(n, 0)));
            let v = |d: glam::DVec3, w: f32| [d.x as f32, d.y as f32, d.z as f32, w];
            self.triangles.push(v(t.v0, f32::from_bits(t.object)));
            // The CPU BVH's id of the triangle: what ties between hits at one distance are
            // broken by on both sides ([`super::bvh::TIE`]).
            self.triangles.push(v(t.e1, f32::from_bits(index)));
            self.triangles.push(v(t.e2, 0.0));
            self.triangles.push(v(t.geometric_normal, 0.0));
            for n in t.normals {
                self.triangles.push(v(n, 0.0));
            }
        }
        node_base
    }
}

/// The deepest leaf below node 0 of `nodes` (obvhs BVH2: an inner node's children are at
/// `first_index` and the one after).
fn depth(nodes: &[obvhs::bvh2::node::Bvh2Node]) -> u32 {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 0u32)];
    while let Some((index, level)) = stack.pop() {
        let Some(node) = nodes.get(index) else {
            continue;
        };
        deepest = deepest.max(level);
        if node.prim_count == 0 {
            let first = node.first_index as usize;
            stack.extend([(first, level + 1), (first + 1, level + 1)]);
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stack_bound_is_the_shaders() {
        let wgsl = include_str!("../../../shaders/wgsl/include/walk_bvh.wgsl");
        let declared = format!("const STACK_SIZE: u32 = {STACK_ENTRIES}u;");
        assert!(wgsl.contains(&declared), "walk_bvh.wgsl lacks `{declared}`");
    }

    #[test]
    fn the_depth_is_the_deepest_leafs() {
        let scene = crate::scene::Scene::load_named("glass-sphere").expect("built in");
        let trace = TraceScene::new(&scene).expect("traces");
        let geometry = GpuGeometry::new(&trace);
        let triangles = geometry.triangle_count() as f64;
        // A binary tree over n leaves of at most a few triangles each is at least log2(n / 8)
        // deep, and obvhs's SAH build of a sphere and a room stays far from the stack's bound.
        assert!(f64::from(geometry.depth) >= (triangles / 8.0).log2().floor());
        assert!(
            geometry.depth < STACK_ENTRIES / 2,
            "depth {}",
            geometry.depth
        );
    }
}
