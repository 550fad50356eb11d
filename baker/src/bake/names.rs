//! The baker's options, each with its front ends' words (the library's are in
//! [`lensmap::options::names`]).

use lensmap::options::{OptionInfo, OptionName};

/// `BakeOptions::width`, pixels of the baker's test renderings.
pub const WIDTH: OptionName = OptionName(&OptionInfo::field("BakeOptions", "width").flag("width"));
/// `BakeOptions::height`, pixels.
pub const HEIGHT: OptionName =
    OptionName(&OptionInfo::field("BakeOptions", "height").flag("height"));
/// `BakeOptions::supersampling`, subpixels a pixel side.
pub const SUPERSAMPLING: OptionName =
    OptionName(&OptionInfo::field("BakeOptions", "supersampling").flag("supersampling"));
/// `BakeOptions::em_size`, the inferred EMs' face size (or `auto` with a cap).
pub const EM_SIZE: OptionName =
    OptionName(&OptionInfo::field("BakeOptions", "em_size").flag("em-size"));
/// `BakeOptions::layers`, layers per lens object (or `auto`).
pub const LAYERS: OptionName =
    OptionName(&OptionInfo::field("BakeOptions", "layers").flag("layers"));
/// `BakeOptions::multi_view`, the views a sample's inference fits at once.
pub const MULTI_VIEW: OptionName =
    OptionName(&OptionInfo::field("BakeOptions", "multi_view").flag("multi-view"));
/// `BakeOptions::view_elevation_degrees`, how far above the view space the raised view sits.
pub const VIEW_ELEVATION: OptionName = OptionName(
    &OptionInfo::field("BakeOptions", "view_elevation_degrees").flag("view-elevation-degrees"),
);
/// `InferOptions::theta_c`, the confidence angle (front ends take degrees).
pub const CONFIDENCE: OptionName = OptionName(
    &OptionInfo::field("InferOptions", "theta_c")
        .shown_in("°")
        .flag("confidence-degrees"),
);
/// `SolveOptions::tolerance`, the solver's relative residual.
pub const TOLERANCE: OptionName =
    OptionName(&OptionInfo::field("SolveOptions", "tolerance").flag("tolerance"));
/// `BakeJob::samples`, the view-space samples to bake (as `parse_samples` reads them).
pub const SAMPLES: OptionName =
    OptionName(&OptionInfo::field("BakeJob", "samples").flag("samples"));
/// `BakeJob::resume`, whether finished samples are kept.
pub const RESUME: OptionName = OptionName(&OptionInfo::field("BakeJob", "resume").flag("resume"));
/// `parse_shard`'s `spec`, the shard `I/N` to bake.
pub const SHARD: OptionName = OptionName(&OptionInfo::field("parse_shard", "spec").flag("shard"));
/// `merge`'s `shards`, the shard directories joined into one bake.
pub const MERGE: OptionName = OptionName(&OptionInfo::field("merge", "shards").flag("merge"));

/// Every option above.
pub const ALL: &[OptionName] = &[
    WIDTH,
    HEIGHT,
    SUPERSAMPLING,
    EM_SIZE,
    LAYERS,
    MULTI_VIEW,
    VIEW_ELEVATION,
    CONFIDENCE,
    TOLERANCE,
    SAMPLES,
    RESUME,
    SHARD,
    MERGE,
];
