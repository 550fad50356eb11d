//! Layered environment maps as geometry and as files: the shells each layer lives on and their
//! intersection with a lens object's outgoing rays ([`shell`], the cube-map direction of a vertex
//! for a layer), and the bake directory the baker writes and the runtime reads ([`bake`]).

pub mod bake;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod projected;
pub mod shell;

/// How a lens object's outgoing rays are split between its layers.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Layering {
    /// By distance (the hybrid-rendering paper §4.2): a ray's paths are traced until they leave
    /// the lens object, and each layer holds the hits in its distance range.
    #[default]
    Distance,
    /// By bounce (the PEM paper §4, a reflector's): a ray stops at its first bounce; layer 0, the
    /// local layer, holds what the first bounce sees of the lens objects (RGBA: coverage in α),
    /// layer 1, the distant one, the environment seen through them (opaque).
    Bounce,
}

impl Layering {
    /// Where this layering's paths stop.
    pub fn bounces(self) -> crate::trace::Bounces {
        match self {
            Layering::Distance => crate::trace::Bounces::UntilLeaving,
            Layering::Bounce => crate::trace::Bounces::First,
        }
    }

    /// Whether this is the default (for serde's skip).
    pub fn is_distance(&self) -> bool {
        *self == Layering::Distance
    }
}

pub use bake::{Bake, BakeError, BakedLens, Manifest, MapReader, Provenance, Staging};
pub use shell::{LayerShell, ShellError, ShellHit};
