//! The tessellation of a frame's lens objects as the hybrid-rendering paper's Figure 5 shows
//! it: each triangle with its subdivision depth.

use glam::Vec3;

/// The tessellation of a frame's lens objects, for drawing as a wireframe coloured by
/// subdivision depth (the hybrid-rendering paper's Figure 5); see
/// [`super::FrameBuilder::last_wireframe`].
#[derive(Clone, Debug, PartialEq)]
pub struct Wireframe {
    /// One entry per lens object of the frame, TraceScene order (a lens object outside the view
    /// has no triangles).
    pub lenses: Vec<WireframeLens>,
}

/// One lens object's tessellated mesh in a [`Wireframe`]: the mesh the frame draws.
#[derive(Clone, Debug, PartialEq)]
pub struct WireframeLens {
    /// The lens object's name.
    pub name: String,
    /// World-space vertex positions, metres.
    pub positions: Vec<Vec3>,
    /// Triangles, indices into `positions`, counter-clockwise seen from their front side.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle (same order as `triangles`), the subdivision depth of the tessellation leaf
    /// it belongs to: 0 for an input triangle left whole, one more per level of splitting
    /// (each level halves the split edges), saturated at 255.
    pub depths: Vec<u8>,
}
