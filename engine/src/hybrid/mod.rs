//! The hybrid runtime (hybrid-rendering paper §5): per frame, on the CPU, the lens object's
//! vertices are ray traced from the real camera, the mesh is adaptively tessellated where ray
//! paths differ, texture coordinates into the layered environment maps are generated, and the
//! viewpoint samples are chosen and weighted: the two nearest along a 1D view space, the three
//! of the enclosing spherical triangle in a 2D one.

pub mod frame;
pub mod glossy;
pub mod gpu;
pub mod hull;
pub mod paths;
pub mod scene;
pub mod sky;
pub mod sphere;
pub mod tessellate;
mod texgen;
pub mod viewpoints;

pub use frame::{
    BuiltFrame, DEFAULT_ANGLE_DEGREES, FresnelModel, HybridOptions, HybridStats,
    MAX_FOOTPRINT_COARSENING, VertexPrecision, VertexTracer, ViewpointBlending, Wireframe,
    WireframeLens,
};
pub use scene::{
    BakeIdentityError, HybridError, HybridScene, HybridSceneOptions, LayeredEms, LensLayers,
};
pub use viewpoints::{ViewSpaceBlender, ViewSpaceFit, ViewpointBlend};
