//! The hybrid runtime (hybrid-rendering paper §5): per frame, the lens object's vertices are ray
//! traced from the real camera, the mesh is adaptively tessellated where ray paths differ,
//! texture coordinates into the layered environment maps are generated (on the CPU or the GPU,
//! as the frame's vertex stage says), and the viewpoint samples are chosen and weighted: the two
//! nearest along a 1D view space, the three of the enclosing spherical triangle in a 2D one.
//! [`scene`] holds what frames are made from, [`frame`] builds them.

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
    BuiltFrame, CpuStage, DEFAULT_ANGLE_DEGREES, FrameBuilder, FrameId, FresnelModel, GpuReadBack,
    GpuResident, HybridOptions, HybridStats, MAX_FOOTPRINT_COARSENING, ShadingTerms,
    VertexPrecision, VertexStage, VertexTracer, ViewpointBlending, Wireframe, WireframeLens,
    vertex_exact_frame,
};
pub use scene::{
    BakeIdentityError, HybridError, HybridScene, HybridSceneOptions, LayeredEms, LensLayers,
    SceneVersion,
};
pub use viewpoints::{ViewSpaceBlender, ViewSpaceFit, ViewpointBlend};
