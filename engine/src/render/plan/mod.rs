//! The compositor frame as a pass graph, built from the frame's shape alone (so `lensmap passes`
//! prints plans without any data or GPU): the environment; then per lens object the single pass,
//! or the multipass variant's prime and its layer passes composited by one blending scheme; then
//! the readback or the box filter into a host's image.
//!
//! [`frame_graph`] is the one entry point. The lens passes are made by a small builder
//! (`lens::LensPasses`: prime, layer passes, alpha clear, scratch clear, group sum), and each
//! blending scheme is one short function of it (`schemes`), so a new scheme is one new function
//! rather than a new flag; more viewpoint samples per lens object are more groups, which every
//! scheme takes as they come.

mod compositing;
mod lens;
mod schemes;
mod shape;

use crate::graph::{
    Blend, BufferId, ColourAttachment, ColourMask, CompareOp, Cull, DepthAttachment, Format, Graph,
    ImageId, LoadOp, Pass, PassKind, Plan, StoreOp,
};

use super::DeviceLensPart;
use super::program::{ProgramError, ShaderProgram, SinglePassLimits};
use crate::index::{LayerIndex, LensIndex};
use crate::trace::Term;
pub use compositing::{BlendScheme, Compositing, CompositingError, Variant};
use lens::{Group, LensPasses};
pub use shape::{FrameShape, LensShape, PartShape};

/// Framebuffer colour format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TargetFormat {
    /// 8-bit unorm (fixed-point blending, like the paper's hardware).
    Rgba8,
    /// 16-bit float.
    Rgba16f,
    /// 32-bit float (the exact reference for the f64 model).
    Rgba32f,
}

impl TargetFormat {
    /// The graph's format.
    pub fn graph_format(self) -> Format {
        match self {
            TargetFormat::Rgba8 => Format::Rgba8Unorm,
            TargetFormat::Rgba16f => Format::Rgba16Float,
            TargetFormat::Rgba32f => Format::Rgba32Float,
        }
    }

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            TargetFormat::Rgba8 => "rgba8",
            TargetFormat::Rgba16f => "rgba16f",
            TargetFormat::Rgba32f => "rgba32f",
        }
    }

    /// All formats, narrowest first.
    pub const ALL: [TargetFormat; 3] = [
        TargetFormat::Rgba8,
        TargetFormat::Rgba16f,
        TargetFormat::Rgba32f,
    ];
}

/// One draw of a frame, as `render/` records it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Draw {
    /// Environment mesh `mesh`.
    Environment {
        /// Index into `FrameInput::environment`.
        mesh: usize,
    },
    /// Glossy object `index`.
    Glossy {
        /// Index into `FrameInput::glossy`.
        index: usize,
    },
    /// The lens object's triangles with the zero shader (prime and alpha clear).
    LensZero {
        /// The lens object.
        lens: LensIndex,
    },
    /// One layer of one (viewpoint, term) group.
    Layer {
        /// The lens object.
        lens: LensIndex,
        /// Viewpoint sample index.
        viewpoint: usize,
        /// The term.
        term: Term,
        /// The layer (0 = nearest).
        layer: LayerIndex,
    },
    /// One layer of the programmable scheme: the layer's source blended in the shader over the
    /// pixel's current value.
    ProgrammableLayer {
        /// The lens object.
        lens: LensIndex,
        /// Viewpoint sample index.
        viewpoint: usize,
        /// The term.
        term: Term,
        /// The layer (0 = nearest).
        layer: LayerIndex,
        /// The scratch image holding the pixel's current value (the lens object's first layer
        /// pass, over the prime's zero, is a plain [`Draw::Layer`]).
        read: u32,
        /// A group boundary lies between the previous layer pass and this one: the alpha clear,
        /// done in the shader (α of the current value taken as 0).
        reset_alpha: bool,
    },
    /// A full-screen pass adding scratch images `0..groups` into the framebuffer: colour summed,
    /// α the last image's.
    GroupSum {
        /// Scratch images summed.
        groups: u32,
    },
    /// The single-pass draw of a lens object.
    SinglePass {
        /// The lens object.
        lens: LensIndex,
    },
    /// Pass `pass` of the compute work that makes part `part` of a lens object resident on the
    /// device (the GPU tessellation, texgen and draw list).
    Compute {
        /// The lens object.
        lens: LensIndex,
        /// The part.
        part: usize,
        /// The work's pass.
        pass: usize,
    },
    /// A full-screen triangle averaging `supersampling`² subpixels of the colour target into
    /// each pixel of an external image.
    BoxFilter {
        /// k for k×k subpixels per pixel.
        supersampling: u32,
        /// The framebuffer or the image is RGBA16F: subpixels are clamped to ±65504 (an
        /// overflowed framebuffer texel is ±Inf; the image would make a larger value ±Inf).
        half: bool,
    },
}

/// Where a frame's pixels go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// Copied into a host-visible buffer at the framebuffer's resolution (the box filter of
    /// supersampling runs on the CPU after the readback).
    Readback,
    /// Box-filtered on the GPU into an image its owner lent (a host's `VkImage`) and handed back
    /// to it: no readback.
    External {
        /// The image's format.
        format: Format,
        /// k for k×k framebuffer subpixels per image pixel (the framebuffer's sides divided by
        /// k are the image's).
        supersampling: u32,
    },
}

/// Images and buffers of a frame graph.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameResources {
    /// The colour target.
    pub colour: ImageId,
    /// The depth target.
    pub depth: ImageId,
    /// `layers[lens][viewpoint]`: the imported cube-map array.
    pub layers: Vec<Vec<ImageId>>,
    /// The external image of an [`Output::External`] frame.
    pub external: Option<ImageId>,
    /// The blending scheme's scratch images, in the order of their layers in the scratch array.
    pub scratch: Vec<ImageId>,
    /// `parts[lens]`: the buffers of a resident lens object's parts that its lens passes read
    /// (each part's data, indices and draws; empty for the rest).
    pub parts: Vec<Vec<BufferId>>,
}

/// What a pass of a frame is, for counting (`lensmap passes`, the renderer's statistics): the
/// category of every [`FrameGraph`] pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PassCategory {
    /// The GPU tessellation of lens objects resident on the device (compute).
    Tessellation,
    /// The opaque environment meshes.
    Environment,
    /// The glossy objects (reflection-space IBR).
    Glossy,
    /// A lens object's prime: its pixels set to (0, 0, 0, 0) with its depth.
    Prime,
    /// One layer of one (viewpoint, term) group.
    Layer,
    /// The alpha clear between two groups (rgb × 1, α × 0).
    AlphaClear,
    /// The clear of a scratch image a group is composited into.
    ScratchClear,
    /// A full-screen sum of scratch images into the framebuffer.
    GroupSum,
    /// A lens object's single-pass draw.
    SinglePass,
    /// The copy of the framebuffer into host-visible memory.
    Readback,
    /// The box filter of supersampling into a host's image.
    BoxFilter,
    /// The hand-back of a host's image.
    Export,
}

impl PassCategory {
    /// Every category, in the order a frame's passes run.
    pub const ALL: [PassCategory; 12] = [
        PassCategory::Tessellation,
        PassCategory::Environment,
        PassCategory::Glossy,
        PassCategory::Prime,
        PassCategory::Layer,
        PassCategory::AlphaClear,
        PassCategory::ScratchClear,
        PassCategory::GroupSum,
        PassCategory::SinglePass,
        PassCategory::Readback,
        PassCategory::BoxFilter,
        PassCategory::Export,
    ];

    /// The category's name in `lensmap passes --json` and the benchmarks' JSON.
    pub fn name(self) -> &'static str {
        match self {
            PassCategory::Tessellation => "tessellation",
            PassCategory::Environment => "environment",
            PassCategory::Glossy => "glossy",
            PassCategory::Prime => "prime",
            PassCategory::Layer => "layer",
            PassCategory::AlphaClear => "alpha-clear",
            PassCategory::ScratchClear => "scratch-clear",
            PassCategory::GroupSum => "group-sum",
            PassCategory::SinglePass => "single-pass",
            PassCategory::Readback => "readback",
            PassCategory::BoxFilter => "box-filter",
            PassCategory::Export => "export",
        }
    }
}

impl std::fmt::Display for PassCategory {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A frame's declared pass graph: draws of [`Draw`] with [`ShaderProgram`]s, in
/// [`PassCategory`]s.
pub type FrameGraph = Graph<Draw, ShaderProgram, PassCategory>;

/// A frame's compiled plan.
pub type FramePlan = Plan<Draw, ShaderProgram, PassCategory>;

/// How a frame is composited and where its pixels go: the options of [`frame_graph`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlanOptions {
    /// How lens objects are composited: the single pass, or the multipass variant and its
    /// blending scheme.
    pub compositing: Compositing,
    /// The framebuffer's format.
    pub format: TargetFormat,
    /// Where the pixels go.
    pub output: Output,
    /// What the single pass composites on the device the plan is for
    /// ([`SinglePassLimits::of_device`]; [`SinglePassLimits::COMPILED`] for a plan without a
    /// device).
    pub single_pass: SinglePassLimits,
}

/// Declares a frame's passes: the environment, each lens object's passes as
/// `options.compositing` says, and `options.output`. Fails where a lens object needs a program
/// that does not exist (more layers than the single pass supports).
pub fn frame_graph(
    shape: &FrameShape,
    options: &PlanOptions,
) -> Result<(FrameGraph, FrameResources), ProgramError> {
    let PlanOptions {
        compositing,
        format,
        output,
        single_pass,
    } = *options;
    let mut graph = Graph::new();
    let mut resources = declare_images(&mut graph, shape, compositing.blend(), format);
    tessellation(&mut graph, shape);
    environment(&mut graph, shape, &resources);
    glossy(&mut graph, shape, &resources);
    for (index, lens) in LensIndex::all(shape.lenses.len()).zip(&shape.lenses) {
        let viewpoints = shape.active_viewpoints(lens);
        if lens.triangles == 0
            || lens.layer_count() == 0
            || lens.terms.is_empty()
            || viewpoints.is_empty()
        {
            continue;
        }
        let mut passes = LensPasses::new(&mut graph, &resources, lens, index);
        let groups = Group::all(&viewpoints, &lens.terms);
        match compositing {
            Compositing::SinglePass => {
                schemes::single_pass(&mut passes, viewpoints.len(), &single_pass)?
            }
            Compositing::Multipass(BlendScheme::FrontToBack) => {
                schemes::front_to_back(&mut passes, &groups)
            }
            Compositing::Multipass(BlendScheme::BackToFront) => {
                schemes::back_to_front(&mut passes, &groups)
            }
            Compositing::Multipass(BlendScheme::GroupTargets) => {
                schemes::group_targets(&mut passes, &groups)
            }
            Compositing::Multipass(BlendScheme::Programmable) => {
                schemes::programmable(&mut passes, &groups)
            }
        }
    }
    resources.external = match output {
        Output::Readback => {
            readback(&mut graph, shape, resources.colour);
            None
        }
        Output::External {
            format: image_format,
            supersampling,
        } => Some(box_filter(
            &mut graph,
            shape,
            resources.colour,
            format,
            image_format,
            supersampling,
        )),
    };
    Ok((graph, resources))
}

/// The frame's images, in the order the plan's barriers list them: colour, depth, the blending
/// scheme's scratch images, then per lens object and viewpoint its layered EM (imported).
fn declare_images(
    graph: &mut FrameGraph,
    shape: &FrameShape,
    blend: BlendScheme,
    format: TargetFormat,
) -> FrameResources {
    let colour = graph.image("colour", format.graph_format(), shape.width, shape.height);
    let depth = graph.image("depth", Format::Depth32Float, shape.width, shape.height);
    let scratch = (0..blend.scratch_images(shape))
        .map(|k| {
            graph.image(
                &format!("scratch{k}"),
                format.graph_format(),
                shape.width,
                shape.height,
            )
        })
        .collect();
    let layers = shape
        .lenses
        .iter()
        .enumerate()
        .map(|(i, lens)| {
            (0..lens.empty.len())
                .map(|v| graph.import_image(&format!("lens{i}/em{v}"), Format::Rgba32Float, 1, 1))
                .collect()
        })
        .collect();
    // Kept across frames: made by this frame's work, or an earlier frame's.
    let parts = shape
        .lenses
        .iter()
        .map(|lens| {
            lens.parts
                .iter()
                .flat_map(|part| DeviceLensPart::buffer_names(&part.name))
                .map(|name| graph.kept_buffer(&name, 0))
                .collect()
        })
        .collect();
    FrameResources {
        colour,
        depth,
        layers,
        external: None,
        scratch,
        parts,
    }
}

/// Per part of a lens object resident on the device that is made this frame, the passes of the
/// work that makes it, before any draw; the graph places their barriers. Side effects: the
/// parts' counts are read after the frame even where no lens pass draws them.
fn tessellation(graph: &mut FrameGraph, shape: &FrameShape) {
    for (index, lens) in LensIndex::all(shape.lenses.len()).zip(&shape.lenses) {
        for (part, work) in lens.parts.iter().enumerate() {
            let Some(work) = &work.work else { continue };
            super::compute::declare(
                graph,
                work,
                &format!("{}/{}/", lens.name, work_prefix(part)),
                PassCategory::Tessellation,
                |pass| Draw::Compute {
                    lens: index,
                    part,
                    pass,
                },
            );
        }
    }
}

/// The name of part `part` of a lens object in its work's pass names.
fn work_prefix(part: usize) -> String {
    format!("part{part}")
}

/// The environment pass: colour cleared to zero and depth to 1, every mesh drawn opaque with
/// depth test and write.
fn environment(graph: &mut FrameGraph, shape: &FrameShape, resources: &FrameResources) {
    let draws = (0..shape.environment_meshes)
        .map(|mesh| Draw::Environment { mesh })
        .collect();
    opaque_pass(
        graph,
        resources,
        PassCategory::Environment,
        ShaderProgram::Environment,
        Start::Cleared,
        draws,
    );
}

/// The glossy pass (reflection-space IBR): every glossy object drawn opaque over the environment
/// with depth test and write, its maps warped and blended per fragment. None without glossy
/// objects.
fn glossy(graph: &mut FrameGraph, shape: &FrameShape, resources: &FrameResources) {
    if shape.glossy.is_empty() {
        return;
    }
    let draws = (0..shape.glossy.len())
        .map(|index| Draw::Glossy { index })
        .collect();
    opaque_pass(
        graph,
        resources,
        PassCategory::Glossy,
        ShaderProgram::Glossy,
        Start::Loaded,
        draws,
    );
}

/// How an opaque pass finds the colour and depth targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Start {
    /// Cleared: colour to zero, depth to 1 (the frame's first pass).
    Cleared,
    /// Loaded with what earlier passes left.
    Loaded,
}

/// A pass of opaque draws named after its category, with depth test LESS and write: colour and
/// depth as `start` says.
fn opaque_pass(
    graph: &mut FrameGraph,
    resources: &FrameResources,
    category: PassCategory,
    program: ShaderProgram,
    start: Start,
    draws: Vec<Draw>,
) {
    let load = |value: [f32; 4]| match start {
        Start::Cleared => LoadOp::Clear(value),
        Start::Loaded => LoadOp::Load,
    };
    graph.add_pass(Pass {
        name: category.name().into(),
        category,
        side_effect: false,
        kind: PassKind::Draw {
            program,
            colour: ColourAttachment {
                image: resources.colour,
                load: load([0.0; 4]),
                store: StoreOp::Store,
                blend: Blend::Replace,
                write_mask: ColourMask::RGBA,
            },
            depth: Some(DepthAttachment {
                image: resources.depth,
                load: load([1.0; 4]),
                store: StoreOp::DontCare,
                test: Some(CompareOp::Less),
                write: true,
            }),
            cull: Cull::None,
            sampled: Vec::new(),
            storage: Vec::new(),
            draws,
        },
    });
}

/// The copy of the colour target into a host-visible buffer (a side effect: it keeps every pass
/// that wrote the colour).
fn readback(graph: &mut FrameGraph, shape: &FrameShape, colour: ImageId) {
    let buffer = graph.buffer(
        "readback",
        u64::from(shape.width) * u64::from(shape.height) * 16,
    );
    graph.add_pass(Pass {
        name: "readback".into(),
        category: PassCategory::Readback,
        side_effect: true,
        kind: PassKind::Readback {
            image: colour,
            buffer,
        },
    });
}

/// The box filter of `supersampling`² subpixels of the colour target into a host's image of
/// `image_format`, and the hand-back of that image; returns the image.
fn box_filter(
    graph: &mut FrameGraph,
    shape: &FrameShape,
    colour: ImageId,
    format: TargetFormat,
    image_format: Format,
    supersampling: u32,
) -> ImageId {
    let k = supersampling.max(1);
    let image = graph.external_image(
        "host-image",
        image_format,
        shape.width / k,
        shape.height / k,
    );
    graph.add_pass(Pass {
        name: "box-filter".into(),
        category: PassCategory::BoxFilter,
        side_effect: false,
        kind: PassKind::Draw {
            program: ShaderProgram::BoxFilter,
            colour: ColourAttachment {
                image,
                load: LoadOp::DontCare,
                store: StoreOp::Store,
                blend: Blend::Replace,
                write_mask: ColourMask::RGBA,
            },
            depth: None,
            cull: Cull::None,
            sampled: vec![colour],
            storage: Vec::new(),
            draws: vec![Draw::BoxFilter {
                supersampling: k,
                // A half-float framebuffer may hold ±Inf; a half-float image would turn
                // larger values into ±Inf.
                half: format == TargetFormat::Rgba16f || image_format == Format::Rgba16Float,
            }],
        },
    });
    graph.add_pass(Pass {
        name: "export".into(),
        category: PassCategory::Export,
        side_effect: true,
        kind: PassKind::Export { image },
    });
    image
}

#[cfg(test)]
mod tests;
