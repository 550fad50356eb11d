//! lensmap: hybrid rendering of shiny and glass "lens" objects.
//!
//! The local lens object is ray traced per vertex; the rest of the world is approximated by layered
//! environment maps composited on the GPU (Hakura & Snyder, EGWR 2001). The rooms, in data-flow
//! order: [`scene`] (scene files and meshes), [`trace`] (the CPU reference ray tracer),
//! [`gpu`] (ash: devices, memory, images), [`graph`] (the pass graph, no Vulkan calls) and
//! [`render`] (the compositor frame and its CPU f64 model).

pub mod cubemap;
pub mod gpu;
pub mod graph;
pub mod hybrid;
pub mod layers;
pub mod render;
pub mod scene;
pub mod trace;
