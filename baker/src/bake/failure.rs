//! Why a bake failed ([`BakeFailure`]), and the user's input a bake cannot use
//! ([`BakeInputError`]), said through [`OptionWords`] so that each front end names the options
//! its own way.

use std::path::PathBuf;

use lensmap::{
    error::{Classified, ErrorKind, kind_in_chain},
    hybrid::HybridError,
    identity::IDENTITY_VERSION,
    layers::bake::BakeError,
    metrics,
    options::{LibraryWords, OptionError, OptionWords, Worded},
    runner::RunError,
    trace::TraceError,
};

use super::merge::MergeError;
use super::names;
use crate::{infer::InferError, placement::PlacementError};

/// Why a bake failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeFailure {
    /// An option out of range (the user's input).
    #[error("{0}")]
    Option(#[from] OptionError),
    /// Other input a bake cannot use: samples, the target views' size, a staged file.
    #[error("{0}")]
    Input(#[from] BakeInputError),
    /// Bakes that cannot be merged.
    #[error("{0}")]
    Merge(#[from] MergeError),
    /// Reading or writing the bake directory.
    #[error(transparent)]
    Bake(#[from] BakeError),
    /// Inference.
    #[error(transparent)]
    Infer(#[from] InferError),
    /// Layer placement.
    #[error(transparent)]
    Placement(#[from] PlacementError),
    /// Layers by bounce.
    #[error(transparent)]
    Bounce(#[from] crate::bounce::BounceError),
    /// The ray tracer.
    #[error(transparent)]
    Trace(#[from] TraceError),
    /// Building the hybrid scene.
    #[error(transparent)]
    Hybrid(#[from] HybridError),
    /// A hybrid frame.
    #[error(transparent)]
    Run(#[from] RunError),
    /// A metric.
    #[error(transparent)]
    Metrics(#[from] metrics::MetricsError),
}

impl Worded for BakeFailure {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match self {
            BakeFailure::Option(error) => error.worded(words),
            BakeFailure::Input(error) => error.worded(words),
            BakeFailure::Merge(error) => error.worded(words),
            BakeFailure::Hybrid(error) => error.worded(words),
            BakeFailure::Run(error) => error.worded(words),
            BakeFailure::Bake(_)
            | BakeFailure::Infer(_)
            | BakeFailure::Placement(_)
            | BakeFailure::Bounce(_)
            | BakeFailure::Trace(_)
            | BakeFailure::Metrics(_) => self.to_string(),
        }
    }
}

impl Classified for BakeFailure {
    fn kind(&self) -> ErrorKind {
        match self {
            BakeFailure::Option(_) | BakeFailure::Input(_) | BakeFailure::Bounce(_) => {
                ErrorKind::Input
            }
            BakeFailure::Merge(_) => ErrorKind::Bake,
            BakeFailure::Bake(error) => error.kind(),
            BakeFailure::Trace(error) => error.kind(),
            BakeFailure::Hybrid(error) => error.kind(),
            BakeFailure::Run(error) => error.kind(),
            // The baker's own stages fail as work does, unless a library error inside says
            // otherwise (a device lost in a frame they render).
            BakeFailure::Infer(error) => kind_in_chain(error).unwrap_or(ErrorKind::Failed),
            BakeFailure::Placement(error) => kind_in_chain(error).unwrap_or(ErrorKind::Failed),
            BakeFailure::Metrics(error) => kind_in_chain(error).unwrap_or(ErrorKind::Failed),
        }
    }
}

/// Input a bake cannot use, beyond a single option out of range. Options are named by their
/// fields in [`super::BakeOptions`] and [`super::BakeJob`] (`samples`, `resume`).
#[derive(Debug, thiserror::Error)]
#[error("{}", self.worded(&LibraryWords))]
pub enum BakeInputError {
    /// The target views' size: a width, height or supersampling of 0.
    Resolution {
        /// [`super::BakeOptions::width`].
        width: u32,
        /// [`super::BakeOptions::height`].
        height: u32,
        /// [`super::BakeOptions::supersampling`].
        supersampling: u32,
    },
    /// A sample list that names no samples of the scene ([`super::parse_samples`]).
    SampleList {
        /// The list as given.
        spec: String,
        /// What is wrong with it.
        problem: String,
        /// The scene's name.
        scene: String,
        /// Samples in the scene's view space.
        count: usize,
    },
    /// A sample index beyond the view space.
    MissingSample {
        /// The index.
        sample: usize,
        /// The scene's name.
        scene: String,
        /// Samples in the scene's view space.
        count: usize,
    },
    /// Nothing to bake: the sample list (or the shard of it) is empty.
    NoSamples,
    /// The scene has no lens object.
    NoLensObjects {
        /// The scene's name.
        scene: String,
    },
    /// The bake to resume names its scene and options in another identity version than this
    /// lensmap's, so its samples cannot be matched to this scene and these options.
    OtherIdentityVersion {
        /// Its manifest.
        manifest: PathBuf,
        /// The version it names (0: before lensmap had one).
        version: u32,
    },
    /// A staged file is not what this code wrote.
    Staged {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl Worded for BakeInputError {
    fn worded(&self, words: &dyn OptionWords) -> String {
        match self {
            BakeInputError::Resolution {
                width,
                height,
                supersampling,
            } => format!(
                "{} {} {}: give values ≥ 1",
                words.setting(names::WIDTH, &width.to_string()),
                words.setting(names::HEIGHT, &height.to_string()),
                words.setting(names::SUPERSAMPLING, &supersampling.to_string()),
            ),
            BakeInputError::SampleList {
                spec,
                problem,
                scene,
                count,
            } => format!(
                "{}: {problem}; scene \"{scene}\" has samples 0..{count} (give all, I,J,K, A..B or A..=B)",
                words.setting(names::SAMPLES, spec)
            ),
            BakeInputError::MissingSample {
                sample,
                scene,
                count,
            } => format!(
                "{}: sample {sample} does not exist; scene \"{scene}\" has samples 0..{count}",
                words.option(names::SAMPLES)
            ),
            BakeInputError::NoSamples => "no samples to bake (the shard or the sample list is empty); give more samples or fewer shards".into(),
            BakeInputError::NoLensObjects { scene } => format!(
                "scene \"{scene}\" has no lens objects, so there is nothing to bake; add a glass or mirror object"
            ),
            BakeInputError::OtherIdentityVersion { manifest, version } => format!(
                "{}: provenance.identity_version: the bake names its scene and options in identity version {version}, this lensmap in version {IDENTITY_VERSION}, so its samples cannot be resumed; bake again without {}",
                manifest.display(),
                words.option(names::RESUME)
            ),
            BakeInputError::Staged { path, message } => format!(
                "{}: {message}; delete it (or bake without {})",
                path.display(),
                words.option(names::RESUME)
            ),
        }
    }
}
