//! lensmap: hybrid rendering of shiny and glass "lens" objects.
//!
//! The local lens object is ray traced per vertex; the rest of the world is approximated by layered
//! environment maps composited on the GPU (Hakura & Snyder, EGWR 2001). The rooms, bottom up:
//! [`scene`] (scene files and meshes), [`graph`] (the pass graph, no Vulkan calls), [`cubemap`]
//! (cube maps, their faces, f64 sampling and the one validator), [`options`] (option errors),
//! [`identity`] (bake identity: SHA-256 of a canonical, versioned encoding), [`atomic`] (atomic
//! file writes and directory swaps), [`index`] (typed lens-object and layer indices); [`trace`]
//! (the CPU reference ray tracer), [`lightmap`] (the opaque environment's light maps: charts,
//! atlases, ray-traced radiance), [`gpu`] (ash: devices, memory, images); [`metrics`] (masked
//! image errors); [`render`] (the compositor and its CPU f64 model); [`layers`] (shells, projected
//! EMs, the bake format); [`rsibr`] (glossy objects by reflection-space IBR: view samples, radiance
//! maps, their bake); [`hybrid`] (per-frame vertex tracing, tessellation, texgen); and on top
//! [`runner`], the frame runner the command line, the tests and hosts call. [`error`] classifies
//! every library error into the one [`error::ErrorKind`] that front ends map to their codes.

pub mod atomic;
pub mod cubemap;
pub mod error;
pub mod gpu;
pub mod graph;
pub mod hybrid;
pub mod identity;
pub mod index;
pub mod layers;
pub mod lightmap;
pub mod metrics;
pub mod options;
pub mod render;
pub mod rsibr;
pub mod runner;
pub mod scene;
pub mod trace;
