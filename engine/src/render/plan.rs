//! The compositor frame as a pass graph: the environment, then per lens object either the paper's
//! multipass scheme (prime, n layer passes per (viewpoint, term) group, alpha clears between
//! groups) or the single-pass variant; then the readback. Built from the frame's shape alone, so
//! `lensmap passes` prints plans without any data or GPU.

use crate::graph::{
    Blend, ColourAttachment, ColourMask, CompareOp, Cull, DepthAttachment, Format, Graph, ImageId,
    LoadOp, Pass, PassKind, Plan, StoreOp,
};

use super::program::{ProgramError, ShaderProgram, SinglePassProgram};
use super::{FrameInput, LensFaces};
use crate::trace::Term;

/// How lens objects are composited.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Variant {
    /// The paper's scheme: one pass per (viewpoint, term, layer), alpha clears between groups.
    Multipass,
    /// One draw per lens object sampling the four (viewpoint, term) textures per layer at once.
    SinglePass,
}

impl Variant {
    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Multipass => "multipass",
            Variant::SinglePass => "single-pass",
        }
    }
}

/// How the multipass variant combines the layers of a (viewpoint, term) group and the groups of
/// a lens object (`--blend`). Every scheme computes the paper's closed form
/// `Σ_groups w·FG ⊙ (L1 over … over Ln).rgb`, α = the last group's `(L1 over … over Ln).α`; they
/// differ in the passes, attachments and barriers it takes, and in where rounding happens. (Where
/// two lens objects lie at exactly the same depth, the later one's prime fails its `<` test but
/// its layers pass `<=`, and each scheme then mixes the two objects its own way; the f64 model
/// marks such pixels as depth ties and leaves them out.)
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BlendScheme {
    /// The paper's scheme: per group, layers nearest first with `src·(1 − dstα) + dst` straight
    /// into the framebuffer, an alpha clear between groups. One rendering instance, no barriers.
    #[default]
    FrontToBack,
    /// Layers farthest first with the classic `src + dst·(1 − srcα)`. "Over" from the back needs
    /// a clear destination, so each group composites into a cleared scratch image, and a
    /// full-screen pass adds it to the framebuffer (colour only, but α too for the last group):
    /// per group two more passes (the clear and the add) and two more rendering instances, with
    /// three or four barriers.
    BackToFront,
    /// Each group composited front to back into its own cleared image (no alpha clears), then one
    /// full-screen resolve adds the groups' colour and takes the last group's α.
    GroupTargets,
    /// Blending in the fragment shader: each layer pass reads the pixel's current value and
    /// writes `src·(1 − dstα) + dst` (and the alpha clear) with shader arithmetic, so the result
    /// does not depend on fixed-function blend precision. The current value comes from the
    /// previous pass's image (passes alternate between two scratch images and end in the
    /// framebuffer): a rendering instance and two barriers per pass, no device feature needed.
    Programmable,
}

impl BlendScheme {
    /// Every scheme, the default first.
    pub const ALL: [BlendScheme; 4] = [
        BlendScheme::FrontToBack,
        BlendScheme::BackToFront,
        BlendScheme::GroupTargets,
        BlendScheme::Programmable,
    ];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BlendScheme::FrontToBack => "front-to-back",
            BlendScheme::BackToFront => "back-to-front",
            BlendScheme::GroupTargets => "group-targets",
            BlendScheme::Programmable => "programmable",
        }
    }

    /// The scheme named `name` on the command line.
    pub fn from_name(name: &str) -> Option<BlendScheme> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Scratch images (framebuffer-sized, the framebuffer's format) a frame of `shape` needs.
    pub fn scratch_images(self, shape: &FrameShape) -> usize {
        match self {
            BlendScheme::FrontToBack => 0,
            BlendScheme::BackToFront => 1,
            BlendScheme::Programmable => 2,
            BlendScheme::GroupTargets => shape
                .lenses
                .iter()
                .map(|lens| {
                    let viewpoints = shape
                        .viewpoint_weights
                        .iter()
                        .enumerate()
                        .filter(|(v, w)| **w > 0.0 && *v < lens.empty.len())
                        .count();
                    viewpoints * lens.terms.len()
                })
                .max()
                .unwrap_or(0),
        }
    }
}

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

/// What the plan of one lens object depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct LensShape {
    /// Debug name.
    pub name: String,
    /// Number of triangles (0 → no passes).
    pub triangles: usize,
    /// Which faces are drawn: [`LensFaces::Both`] makes every lens pass cull nothing.
    pub faces: LensFaces,
    /// The terms present, in group order (refraction before reflection).
    pub terms: Vec<Term>,
    /// `empty[viewpoint][layer]`: the layer's cube map is all zeros, so its pass changes nothing.
    pub empty: Vec<Vec<bool>>,
}

impl LensShape {
    /// Layers n.
    pub fn layer_count(&self) -> usize {
        self.empty.first().map_or(0, Vec::len)
    }
}

/// What a frame's plan depends on.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameShape {
    /// Framebuffer size.
    pub width: u32,
    /// Framebuffer size.
    pub height: u32,
    /// Number of environment meshes (one draw each).
    pub environment_meshes: usize,
    /// Lens objects.
    pub lenses: Vec<LensShape>,
    /// Viewpoint weights.
    pub viewpoint_weights: Vec<f32>,
}

impl FrameShape {
    /// `[viewpoint][layer]`: whether the layer's cube map is all zeros (its pass changes
    /// nothing and is not recorded).
    pub fn empty_layers(layers: &[Vec<std::sync::Arc<crate::cubemap::CubeMap>>]) -> Vec<Vec<bool>> {
        layers
            .iter()
            .map(|cubes| cubes.iter().map(|cube| cube.is_all_zero()).collect())
            .collect()
    }

    /// The shape of a frame's data.
    pub fn of(frame: &FrameInput) -> FrameShape {
        Self::of_with(frame, |cubes| {
            cubes.iter().map(|cube| cube.is_all_zero()).collect()
        })
    }

    /// The shape of a frame's data, with `empty` saying which cube maps of one viewpoint's
    /// layered EM are all zeros (the renderer answers from its cache instead of scanning).
    pub fn of_with(
        frame: &FrameInput,
        empty: impl Fn(&[std::sync::Arc<crate::cubemap::CubeMap>]) -> Vec<bool>,
    ) -> FrameShape {
        FrameShape {
            width: frame.width,
            height: frame.height,
            environment_meshes: frame
                .environment
                .iter()
                .filter(|m| !m.triangles.is_empty())
                .count(),
            lenses: frame
                .lenses
                .iter()
                .map(|lens| {
                    let mut terms: Vec<Term> = lens.terms.iter().map(|t| t.term).collect();
                    terms.sort();
                    LensShape {
                        name: lens.name.clone(),
                        triangles: lens.triangles.len(),
                        faces: lens.faces,
                        terms,
                        empty: lens.layers.iter().map(|cubes| empty(cubes)).collect(),
                    }
                })
                .collect(),
            viewpoint_weights: frame.viewpoint_weights.clone(),
        }
    }

    /// The most layers a pass-count experiment may ask for: the multipass variant has no shader
    /// limit, but its plan grows as 4n passes per viewpoint, so the bound keeps a plan printable
    /// (256 layers: about 2,000 passes) instead of letting one number exhaust memory.
    pub const MAX_EXPERIMENT_LAYERS: usize = 256;

    /// A synthetic shape for experiments (`lensmap passes`): `lenses` objects with `layers` layers,
    /// `viewpoints` samples of equal weight and the given terms.
    pub fn synthetic(
        width: u32,
        height: u32,
        layers: usize,
        viewpoints: usize,
        terms: &[Term],
    ) -> FrameShape {
        let viewpoints = viewpoints.max(1);
        FrameShape {
            width,
            height,
            environment_meshes: 1,
            lenses: vec![LensShape {
                name: "lens".into(),
                triangles: 1,
                faces: LensFaces::Front,
                terms: terms.to_vec(),
                empty: vec![vec![false; layers]; viewpoints],
            }],
            viewpoint_weights: vec![1.0 / viewpoints as f32; viewpoints],
        }
    }
}

/// One draw of a frame, as `render/` records it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Draw {
    /// Environment mesh `mesh`.
    Environment {
        /// Index into `FrameInput::environment`.
        mesh: usize,
    },
    /// The lens object's triangles with the zero shader (prime and alpha clear).
    LensZero {
        /// Lens index.
        lens: usize,
    },
    /// One layer of one (viewpoint, term) group.
    Layer {
        /// Lens index.
        lens: usize,
        /// Viewpoint sample index.
        viewpoint: usize,
        /// The term.
        term: Term,
        /// Layer index, 0 = nearest.
        layer: usize,
    },
    /// One layer of the programmable scheme: the layer's source blended in the shader over the
    /// pixel's current value.
    ProgrammableLayer {
        /// Lens index.
        lens: usize,
        /// Viewpoint sample index.
        viewpoint: usize,
        /// The term.
        term: Term,
        /// Layer index, 0 = nearest.
        layer: usize,
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
        /// Lens index.
        lens: usize,
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
}

/// A frame's declared pass graph: draws of [`Draw`] with [`ShaderProgram`]s.
pub type FrameGraph = Graph<Draw, ShaderProgram>;

/// A frame's compiled plan.
pub type FramePlan = Plan<Draw, ShaderProgram>;

/// Declares the frame's passes, ending in a readback. Fails only where a lens object needs a
/// program that does not exist (more layers than the single pass supports).
pub fn frame_graph(
    shape: &FrameShape,
    variant: Variant,
    format: TargetFormat,
) -> Result<(FrameGraph, FrameResources), ProgramError> {
    frame_graph_to(shape, variant, format, Output::Readback)
}

/// Declares the frame's passes, ending in `output`: [`frame_graph`] with a choice of where the
/// pixels go.
pub fn frame_graph_to(
    shape: &FrameShape,
    variant: Variant,
    format: TargetFormat,
    output: Output,
) -> Result<(FrameGraph, FrameResources), ProgramError> {
    frame_graph_blended(shape, variant, BlendScheme::FrontToBack, format, output)
}

/// Declares the frame's passes with the multipass variant's layers and groups combined by
/// `blend` (the single pass does not blend: it takes only [`BlendScheme::FrontToBack`]).
pub fn frame_graph_blended(
    shape: &FrameShape,
    variant: Variant,
    blend: BlendScheme,
    format: TargetFormat,
    output: Output,
) -> Result<(FrameGraph, FrameResources), ProgramError> {
    if variant == Variant::SinglePass && blend != BlendScheme::FrontToBack {
        return Err(ProgramError::SinglePassBlend {
            blend: blend.name(),
        });
    }
    let mut graph = Graph::new();
    let colour = graph.image("colour", format.graph_format(), shape.width, shape.height);
    let depth = graph.image("depth", Format::Depth32Float, shape.width, shape.height);
    let scratch: Vec<ImageId> = (0..blend.scratch_images(shape))
        .map(|k| {
            graph.image(
                &format!("scratch{k}"),
                format.graph_format(),
                shape.width,
                shape.height,
            )
        })
        .collect();
    let layers: Vec<Vec<ImageId>> = shape
        .lenses
        .iter()
        .enumerate()
        .map(|(i, lens)| {
            (0..lens.empty.len())
                .map(|v| graph.import_image(&format!("lens{i}/em{v}"), Format::Rgba32Float, 1, 1))
                .collect()
        })
        .collect();

    let attach_to =
        |image: ImageId, load: LoadOp, blend: Blend, write_mask: ColourMask| ColourAttachment {
            image,
            load,
            store: StoreOp::Store,
            blend,
            write_mask,
        };
    let attach = |load: LoadOp, blend: Blend, write_mask: ColourMask| {
        attach_to(colour, load, blend, write_mask)
    };
    let depth_attach = |load: LoadOp, test: CompareOp, write: bool| DepthAttachment {
        image: depth,
        load,
        store: StoreOp::DontCare,
        test: Some(test),
        write,
    };
    let draw_pass = |name: String,
                     category: &'static str,
                     program: ShaderProgram,
                     colour: ColourAttachment,
                     depth: DepthAttachment,
                     cull: Cull,
                     sampled: Vec<ImageId>,
                     draws: Vec<Draw>| Pass {
        name,
        category,
        side_effect: false,
        kind: PassKind::Draw {
            program,
            colour,
            depth: Some(depth),
            cull,
            sampled,
            storage: Vec::new(),
            draws,
        },
    };

    graph.add_pass(draw_pass(
        "environment".into(),
        "environment",
        ShaderProgram::Environment,
        attach(LoadOp::Clear([0.0; 4]), Blend::Replace, ColourMask::RGBA),
        depth_attach(LoadOp::Clear([1.0; 4]), CompareOp::Less, true),
        Cull::None,
        Vec::new(),
        (0..shape.environment_meshes)
            .map(|mesh| Draw::Environment { mesh })
            .collect(),
    ));

    for (lens_index, lens) in shape.lenses.iter().enumerate() {
        let active: Vec<usize> = shape
            .viewpoint_weights
            .iter()
            .enumerate()
            .filter(|(v, w)| **w > 0.0 && *v < lens.empty.len())
            .map(|(v, _)| v)
            .collect();
        let n = lens.layer_count();
        if lens.triangles == 0 || n == 0 || lens.terms.is_empty() || active.is_empty() {
            continue;
        }
        let name = &lens.name;
        let cull = match lens.faces {
            LensFaces::Front => Cull::Back,
            LensFaces::Both => Cull::None,
        };
        match variant {
            Variant::SinglePass => graph.add_pass(draw_pass(
                format!("{name}/single-pass"),
                "single-pass",
                ShaderProgram::LensSinglePass(SinglePassProgram::new(
                    name,
                    n,
                    &lens.terms,
                    active.len(),
                )?),
                attach(LoadOp::Load, Blend::Replace, ColourMask::RGBA),
                depth_attach(LoadOp::Load, CompareOp::Less, true),
                cull,
                layers[lens_index].clone(),
                vec![Draw::SinglePass { lens: lens_index }],
            )),
            Variant::Multipass => {
                graph.add_pass(draw_pass(
                    format!("{name}/prime"),
                    "prime",
                    ShaderProgram::LensZero,
                    attach(LoadOp::Load, Blend::Replace, ColourMask::RGBA),
                    depth_attach(LoadOp::Load, CompareOp::Less, true),
                    cull,
                    Vec::new(),
                    vec![Draw::LensZero { lens: lens_index }],
                ));
                let groups: Vec<(usize, Term)> = active
                    .iter()
                    .flat_map(|&v| lens.terms.iter().map(move |&t| (v, t)))
                    .collect();
                let group_name = |(viewpoint, term): (usize, Term)| {
                    format!("{name}/v{viewpoint}/{}", term.name())
                };
                // The layers of a group in the order `blend` composites them, each with its draw
                // (none for an all-zero layer: the identity, culled by the graph).
                let layer_draws = |(viewpoint, term): (usize, Term), back_to_front: bool| {
                    let mut order: Vec<usize> = (0..n).collect();
                    if back_to_front {
                        order.reverse();
                    }
                    order
                        .into_iter()
                        .map(|layer| {
                            let draws = if lens.empty[viewpoint][layer] {
                                Vec::new()
                            } else {
                                vec![Draw::Layer {
                                    lens: lens_index,
                                    viewpoint,
                                    term,
                                    layer,
                                }]
                            };
                            (layer, draws)
                        })
                        .collect::<Vec<_>>()
                };
                let alpha_clear = |graph: &mut FrameGraph, group: &str, image: ImageId| {
                    graph.add_pass(draw_pass(
                        format!("{group}/alpha-clear"),
                        "alpha-clear",
                        ShaderProgram::LensZero,
                        attach_to(image, LoadOp::Load, Blend::Replace, ColourMask::A),
                        depth_attach(LoadOp::Load, CompareOp::LessOrEqual, false),
                        cull,
                        Vec::new(),
                        vec![Draw::LensZero { lens: lens_index }],
                    ))
                };
                // A group's layers into `image` with `blend`, behind a clear of the image when
                // `clear` (a pass with no draws that the graph keeps for its clear).
                let composite_group = |graph: &mut FrameGraph,
                                       group: (usize, Term),
                                       image: ImageId,
                                       clear: bool,
                                       layer_blend: Blend| {
                    let prefix = group_name(group);
                    if clear {
                        graph.add_pass(draw_pass(
                            format!("{prefix}/clear"),
                            "scratch-clear",
                            ShaderProgram::LensZero,
                            attach_to(
                                image,
                                LoadOp::Clear([0.0; 4]),
                                Blend::Replace,
                                ColourMask::RGBA,
                            ),
                            depth_attach(LoadOp::Load, CompareOp::LessOrEqual, false),
                            cull,
                            Vec::new(),
                            Vec::new(),
                        ));
                    }
                    let back_to_front = layer_blend == Blend::BackToFrontOver;
                    for (layer, draws) in layer_draws(group, back_to_front) {
                        graph.add_pass(draw_pass(
                            format!("{prefix}/layer{layer}"),
                            "layer",
                            ShaderProgram::LensLayer,
                            attach_to(image, LoadOp::Load, layer_blend, ColourMask::RGBA),
                            depth_attach(LoadOp::Load, CompareOp::LessOrEqual, false),
                            cull,
                            vec![layers[lens_index][group.0]],
                            draws,
                        ));
                    }
                };
                // A full-screen pass adding scratch images 0..count into the framebuffer.
                let group_sum = |graph: &mut FrameGraph, pass: String, count: usize, mask| {
                    graph.add_pass(Pass {
                        name: pass,
                        category: "group-sum",
                        side_effect: false,
                        kind: PassKind::Draw {
                            program: ShaderProgram::GroupSum,
                            colour: attach(LoadOp::Load, Blend::Add, mask),
                            depth: None,
                            cull: Cull::None,
                            sampled: scratch[..count].to_vec(),
                            storage: Vec::new(),
                            draws: vec![Draw::GroupSum {
                                groups: count as u32,
                            }],
                        },
                    })
                };
                match blend {
                    BlendScheme::FrontToBack => {
                        for (index, &group) in groups.iter().enumerate() {
                            if index > 0 {
                                alpha_clear(&mut graph, &group_name(group), colour);
                            }
                            composite_group(
                                &mut graph,
                                group,
                                colour,
                                false,
                                Blend::FrontToBackOver,
                            );
                        }
                    }
                    BlendScheme::BackToFront => {
                        for (index, &group) in groups.iter().enumerate() {
                            composite_group(
                                &mut graph,
                                group,
                                scratch[0],
                                true,
                                Blend::BackToFrontOver,
                            );
                            // Colour only, but the last group's α too (α is the last group's).
                            let last = index + 1 == groups.len();
                            group_sum(
                                &mut graph,
                                format!("{}/accumulate", group_name(group)),
                                1,
                                if last {
                                    ColourMask::RGBA
                                } else {
                                    ColourMask::RGB
                                },
                            );
                        }
                    }
                    BlendScheme::GroupTargets => {
                        for (index, &group) in groups.iter().enumerate() {
                            composite_group(
                                &mut graph,
                                group,
                                scratch[index],
                                true,
                                Blend::FrontToBackOver,
                            );
                        }
                        group_sum(
                            &mut graph,
                            format!("{name}/group-sum"),
                            groups.len(),
                            ColourMask::RGBA,
                        );
                    }
                    BlendScheme::Programmable => {
                        // The drawn layers in the front-to-back order, each with its group.
                        let drawn: Vec<(usize, (usize, Term), usize)> = groups
                            .iter()
                            .enumerate()
                            .flat_map(|(index, &group)| {
                                (0..n)
                                    .filter(move |&layer| !lens.empty[group.0][layer])
                                    .map(move |layer| (index, group, layer))
                            })
                            .collect();
                        // Pass i writes scratch i mod 2 and reads the previous pass's image; the
                        // last writes the framebuffer, so no pass reads what it writes.
                        for (i, &(index, (viewpoint, term), layer)) in drawn.iter().enumerate() {
                            let last = i + 1 == drawn.len();
                            let target = if last { colour } else { scratch[i % 2] };
                            let read = (i > 0).then(|| ((i - 1) % 2) as u32);
                            // The first pass blends over the prime's zero, where
                            // src·(1 − 0) + 0 = src: the plain layer shader, replacing.
                            let (program, draw) = match read {
                                None => (
                                    ShaderProgram::LensLayer,
                                    Draw::Layer {
                                        lens: lens_index,
                                        viewpoint,
                                        term,
                                        layer,
                                    },
                                ),
                                Some(read) => (
                                    ShaderProgram::LensLayerProgrammable,
                                    Draw::ProgrammableLayer {
                                        lens: lens_index,
                                        viewpoint,
                                        term,
                                        layer,
                                        read,
                                        reset_alpha: drawn[i - 1].0 != index,
                                    },
                                ),
                            };
                            graph.add_pass(draw_pass(
                                format!("{}/layer{layer}", group_name((viewpoint, term))),
                                "layer",
                                program,
                                attach_to(
                                    target,
                                    if last { LoadOp::Load } else { LoadOp::DontCare },
                                    Blend::Replace,
                                    ColourMask::RGBA,
                                ),
                                depth_attach(LoadOp::Load, CompareOp::LessOrEqual, false),
                                cull,
                                std::iter::once(layers[lens_index][viewpoint])
                                    .chain(read.map(|k| scratch[k as usize]))
                                    .collect(),
                                vec![draw],
                            ));
                        }
                        // Groups after the last drawn layer (all of their layers zero) still
                        // clear α, as the front-to-back scheme's alpha clears do.
                        // (With nothing drawn, the prime's α is 0 already.)
                        if let Some(&(index, _, _)) = drawn.last()
                            && index + 1 < groups.len()
                        {
                            alpha_clear(&mut graph, &group_name(groups[index + 1]), colour);
                        }
                    }
                }
            }
        }
    }

    let external = match output {
        Output::Readback => {
            let readback = graph.buffer(
                "readback",
                u64::from(shape.width) * u64::from(shape.height) * 16,
            );
            graph.add_pass(Pass {
                name: "readback".into(),
                category: "readback",
                side_effect: true,
                kind: PassKind::Readback {
                    image: colour,
                    buffer: readback,
                },
            });
            None
        }
        Output::External {
            format: image_format,
            supersampling,
        } => {
            let k = supersampling.max(1);
            let image = graph.external_image(
                "host-image",
                image_format,
                shape.width / k,
                shape.height / k,
            );
            graph.add_pass(Pass {
                name: "box-filter".into(),
                category: "box-filter",
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
                        half: format == TargetFormat::Rgba16f
                            || image_format == Format::Rgba16Float,
                    }],
                },
            });
            graph.add_pass(Pass {
                name: "export".into(),
                category: "export",
                side_effect: true,
                kind: PassKind::Export { image },
            });
            Some(image)
        }
    };
    Ok((
        graph,
        FrameResources {
            colour,
            depth,
            layers,
            external,
            scratch,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(layers: usize, viewpoints: usize, terms: &[Term], variant: Variant) -> FramePlan {
        let shape = FrameShape::synthetic(64, 64, layers, viewpoints, terms);
        frame_graph(&shape, variant, TargetFormat::Rgba32f)
            .unwrap()
            .0
            .compile()
            .unwrap()
    }

    const BOTH: [Term; 2] = [Term::Refraction, Term::Reflection];

    #[test]
    fn two_viewpoints_two_terms_is_the_papers_4n_passes_and_three_alpha_clears() {
        for n in 1..=4 {
            let p = plan(n, 2, &BOTH, Variant::Multipass);
            assert_eq!(
                (p.count("prime"), p.count("layer"), p.count("alpha-clear")),
                (1, 4 * n, 3),
                "{p}"
            );
            // One rendering instance holds the environment and every lens pass: no barriers
            // between blending passes.
            assert_eq!(p.rendering_instances(), 1, "{p}");
        }
    }

    #[test]
    fn one_viewpoint_is_2n_passes_and_one_clear() {
        for n in 1..=4 {
            let p = plan(n, 1, &BOTH, Variant::Multipass);
            assert_eq!(
                (p.count("prime"), p.count("layer"), p.count("alpha-clear")),
                (1, 2 * n, 1)
            );
        }
    }

    #[test]
    fn a_mirror_at_a_sample_is_n_passes_and_no_clear() {
        for n in 1..=4 {
            let p = plan(n, 1, &[Term::Reflection], Variant::Multipass);
            assert_eq!(
                (p.count("prime"), p.count("layer"), p.count("alpha-clear")),
                (1, n, 0)
            );
        }
    }

    #[test]
    fn single_pass_is_one_lens_draw() {
        for viewpoints in 1..=2 {
            let p = plan(3, viewpoints, &BOTH, Variant::SinglePass);
            assert_eq!(p.count("single-pass"), 1);
            assert_eq!(p.draws("single-pass"), 1);
            assert_eq!(
                p.count("layer") + p.count("alpha-clear") + p.count("prime"),
                0
            );
        }
    }

    #[test]
    fn a_zero_weight_viewpoint_and_empty_layers_are_skipped() {
        let mut shape = FrameShape::synthetic(64, 64, 3, 2, &BOTH);
        shape.viewpoint_weights = vec![1.0, 0.0];
        shape.lenses[0].empty[0][1] = true;
        let p = frame_graph(&shape, Variant::Multipass, TargetFormat::Rgba8)
            .unwrap()
            .0
            .compile()
            .unwrap();
        // One viewpoint × two terms × (3 − 1 empty) layers, one clear between the two groups.
        assert_eq!((p.count("layer"), p.count("alpha-clear")), (4, 1), "{p}");
        assert_eq!(p.culled.len(), 2, "{p}");
    }

    #[test]
    fn a_lens_with_both_faces_culls_nothing_in_any_pass() {
        for variant in [Variant::Multipass, Variant::SinglePass] {
            for faces in [LensFaces::Front, LensFaces::Both] {
                let mut shape = FrameShape::synthetic(64, 64, 2, 2, &BOTH);
                shape.lenses[0].faces = faces;
                let (graph, _) = frame_graph(&shape, variant, TargetFormat::Rgba8).unwrap();
                let lens_culls: Vec<(String, Cull)> = graph
                    .passes()
                    .iter()
                    .filter_map(|pass| match &pass.kind {
                        PassKind::Draw { cull, .. } if pass.category != "environment" => {
                            Some((pass.name.clone(), *cull))
                        }
                        _ => None,
                    })
                    .collect();
                let expected = match faces {
                    LensFaces::Front => Cull::Back,
                    LensFaces::Both => Cull::None,
                };
                assert!(!lens_culls.is_empty());
                assert!(
                    lens_culls.iter().all(|(_, cull)| *cull == expected),
                    "{variant:?} {faces:?}: {lens_culls:?}"
                );
            }
        }
    }

    fn plan_blended(
        layers: usize,
        viewpoints: usize,
        terms: &[Term],
        blend: BlendScheme,
    ) -> FramePlan {
        let shape = FrameShape::synthetic(64, 64, layers, viewpoints, terms);
        frame_graph_blended(
            &shape,
            Variant::Multipass,
            blend,
            TargetFormat::Rgba32f,
            Output::Readback,
        )
        .unwrap()
        .0
        .compile()
        .unwrap()
    }

    /// Each scheme's pass, barrier and rendering-instance counts for n = 1…4 layers and G =
    /// viewpoints × terms groups, derived by hand from the scheme's description.
    #[test]
    fn each_scheme_has_the_passes_it_is_described_with() {
        for n in 1..=4 {
            for viewpoints in 1..=2 {
                for terms in [&BOTH[..], &[Term::Reflection][..]] {
                    let g = viewpoints * terms.len();
                    let count = |p: &FramePlan| {
                        (
                            p.count("layer"),
                            p.count("alpha-clear"),
                            p.count("scratch-clear"),
                            p.count("group-sum"),
                        )
                    };
                    let front = plan_blended(n, viewpoints, terms, BlendScheme::FrontToBack);
                    assert_eq!(count(&front), (g * n, g - 1, 0, 0), "{front}");
                    assert_eq!((front.rendering_instances(), front.barrier_count()), (1, 3));
                    // Per group a clear of the scratch image, its layers and an accumulate pass.
                    let back = plan_blended(n, viewpoints, terms, BlendScheme::BackToFront);
                    assert_eq!(count(&back), (g * n, 0, g, g), "{back}");
                    assert_eq!(back.rendering_instances(), 1 + 2 * g, "{back}");
                    // Per group its own cleared image; one sum of all of them.
                    let targets = plan_blended(n, viewpoints, terms, BlendScheme::GroupTargets);
                    assert_eq!(count(&targets), (g * n, 0, g, 1), "{targets}");
                    assert_eq!(targets.rendering_instances(), 2 + g, "{targets}");
                    // One rendering instance per layer pass, alternating images (a lone layer
                    // pass renders straight into the framebuffer, in the prime's instance).
                    let shader = plan_blended(n, viewpoints, terms, BlendScheme::Programmable);
                    assert_eq!(count(&shader), (g * n, 0, 0, 0), "{shader}");
                    let instances = if g * n == 1 { 1 } else { 1 + g * n };
                    assert_eq!(shader.rendering_instances(), instances, "{shader}");
                    // No pass samples the image it renders into.
                    for step in &shader.steps {
                        if let PassKind::Draw {
                            colour, sampled, ..
                        } = &step.pass.kind
                        {
                            assert!(!sampled.contains(&colour.image), "{shader}");
                        }
                    }
                }
            }
        }
    }

    /// Back-to-front composites each group's layers farthest first; the others nearest first.
    #[test]
    fn back_to_front_reverses_the_layer_order() {
        let layer_order = |blend| -> Vec<String> {
            plan_blended(3, 1, &[Term::Reflection], blend)
                .steps
                .iter()
                .filter(|s| s.pass.category == "layer")
                .map(|s| s.pass.name.rsplit('/').next().unwrap_or("").to_owned())
                .collect()
        };
        assert_eq!(
            layer_order(BlendScheme::BackToFront),
            ["layer2", "layer1", "layer0"]
        );
        for blend in [
            BlendScheme::FrontToBack,
            BlendScheme::GroupTargets,
            BlendScheme::Programmable,
        ] {
            assert_eq!(
                layer_order(blend),
                ["layer0", "layer1", "layer2"],
                "{blend:?}"
            );
        }
    }

    /// The programmable scheme resets α (the alpha clear) exactly where a group begins, and a
    /// last group whose layers are all zero still ends in an alpha clear.
    #[test]
    fn programmable_resets_alpha_at_group_boundaries() {
        let mut shape = FrameShape::synthetic(64, 64, 2, 2, &BOTH);
        let resets = |shape: &FrameShape| -> Vec<(String, bool)> {
            let plan = frame_graph_blended(
                shape,
                Variant::Multipass,
                BlendScheme::Programmable,
                TargetFormat::Rgba32f,
                Output::Readback,
            )
            .unwrap()
            .0
            .compile()
            .unwrap();
            plan.steps
                .iter()
                .filter_map(|s| match &s.pass.kind {
                    PassKind::Draw { draws, .. } => draws.first().and_then(|d| match d {
                        Draw::ProgrammableLayer { reset_alpha, .. } => {
                            Some((s.pass.name.clone(), *reset_alpha))
                        }
                        Draw::LensZero { .. } if s.pass.category == "alpha-clear" => {
                            Some((s.pass.name.clone(), true))
                        }
                        _ => None,
                    }),
                    _ => None,
                })
                .collect()
        };
        let all = resets(&shape);
        let reset: Vec<&str> = all
            .iter()
            .filter(|(_, r)| *r)
            .map(|(n, _)| n.as_str())
            .collect();
        assert_eq!(
            reset,
            ["lens/v0/R/layer0", "lens/v1/T/layer0", "lens/v1/R/layer0"],
            "{all:?}"
        );
        // Viewpoint 1's layers all zero: its two groups draw nothing, and α still ends cleared.
        shape.lenses[0].empty[1] = vec![true, true];
        let all = resets(&shape);
        assert_eq!(
            all.last().map(|(n, _)| n.as_str()),
            Some("lens/v1/T/alpha-clear"),
            "{all:?}"
        );
    }

    #[test]
    fn the_single_pass_takes_only_front_to_back() {
        let shape = FrameShape::synthetic(64, 64, 2, 2, &BOTH);
        for blend in BlendScheme::ALL {
            let result = frame_graph_blended(
                &shape,
                Variant::SinglePass,
                blend,
                TargetFormat::Rgba8,
                Output::Readback,
            );
            assert_eq!(
                result.is_ok(),
                blend == BlendScheme::FrontToBack,
                "{blend:?}"
            );
        }
    }

    /// The plans `lensmap passes` prints (its defaults: 640×480, RGBA8), n = 1…4, for one and two
    /// viewpoints, a glass (both terms) and a mirror (reflection only) lens, both variants and
    /// every blending scheme, as
    /// text against the golden files in `render/golden/` (read and checked by hand when written;
    /// the counts above check the same plans independently). Trailing spaces are not compared.
    /// `LENSMAP_BLESS=1` rewrites the files after a deliberate change, to be read before
    /// committing.
    #[test]
    fn plans_match_the_golden_text() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/render/golden");
        let bless = std::env::var("LENSMAP_BLESS").is_ok_and(|v| v == "1");
        let trimmed = |text: &str| -> String {
            text.lines()
                .map(|l| format!("{}\n", l.trim_end()))
                .collect()
        };
        let mut mismatches = Vec::new();
        let compositings = [
            (Variant::Multipass, BlendScheme::FrontToBack),
            (Variant::SinglePass, BlendScheme::FrontToBack),
            (Variant::Multipass, BlendScheme::BackToFront),
            (Variant::Multipass, BlendScheme::GroupTargets),
            (Variant::Multipass, BlendScheme::Programmable),
        ];
        for (variant, blend) in compositings {
            for viewpoints in 1..=2 {
                for (material, terms) in [("glass", &BOTH[..]), ("mirror", &[Term::Reflection][..])]
                {
                    let mut text = String::new();
                    for n in 1..=4 {
                        let shape = FrameShape::synthetic(640, 480, n, viewpoints, terms);
                        let plan = frame_graph_blended(
                            &shape,
                            variant,
                            blend,
                            TargetFormat::Rgba8,
                            Output::Readback,
                        )
                        .unwrap()
                        .0
                        .compile()
                        .unwrap();
                        text.push_str(&format!("# n = {n}\n{plan}"));
                    }
                    // The paper's scheme keeps its files' names; the others add theirs.
                    let scheme = match blend {
                        BlendScheme::FrontToBack => String::new(),
                        other => format!("-{}", other.name()),
                    };
                    let name = format!(
                        "{}{scheme}-{viewpoints}-viewpoint-{material}.txt",
                        variant.name()
                    );
                    let path = dir.join(&name);
                    if bless {
                        std::fs::create_dir_all(&dir).unwrap();
                        std::fs::write(&path, trimmed(&text)).unwrap();
                    }
                    let golden = std::fs::read_to_string(&path).unwrap_or_default();
                    if trimmed(&golden) != trimmed(&text) {
                        mismatches.push(format!("{name}:\n{text}"));
                    }
                }
            }
        }
        assert!(
            mismatches.is_empty(),
            "plans differ from their golden text (LENSMAP_BLESS=1 rewrites them):\n{}",
            mismatches.join("\n")
        );
    }
}
