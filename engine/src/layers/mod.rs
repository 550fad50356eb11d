//! Layered environment maps as geometry and as files: the shells each layer lives on and their
//! intersection with a lens object's outgoing rays ([`shell`], the cube-map direction of a vertex
//! for a layer), and the bake directory the baker writes and the runtime reads ([`bake`]).

pub mod bake;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod projected;
pub mod shell;

pub use bake::{Bake, BakeError, BakedLens, Manifest, MapReader, Provenance, Staging};
pub use shell::{LayerShell, ShellError, ShellHit};
