//! The builder of one lens object's passes: each method declares one kind of pass (the prime, a
//! group's layer passes, an alpha clear, a scratch clear, a sum of scratch images, the single
//! pass) with the attachments, depth use and culling that kind always has, so a blending scheme
//! ([`super::schemes`]) says only which passes it takes, in which order, into which image.

use crate::graph::{
    Blend, ColourAttachment, ColourMask, CompareOp, Cull, DepthAttachment, ImageId, LoadOp, Pass,
    PassKind, StoreOp,
};
use crate::index::{LayerIndex, LensIndex};
use crate::render::LensFaces;
use crate::render::program::{ShaderProgram, SinglePassProgram};
use crate::trace::Term;

use super::{Draw, FrameGraph, FrameResources, LensShape, PassCategory};

/// One (viewpoint, term) group of a lens object: its n layer passes, one viewpoint sample's
/// layered EM seen through one shading term, composited together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Group {
    /// The viewpoint sample.
    pub(super) viewpoint: usize,
    /// The term.
    pub(super) term: Term,
}

impl Group {
    /// The groups of a lens object in the order they are composited: per viewpoint sample (as
    /// many as there are), each term (refraction before reflection).
    pub(super) fn all(viewpoints: &[usize], terms: &[Term]) -> Vec<Group> {
        viewpoints
            .iter()
            .flat_map(|&viewpoint| terms.iter().map(move |&term| Group { viewpoint, term }))
            .collect()
    }
}

/// The colour image a lens pass renders into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Target {
    /// The framebuffer's colour target.
    Framebuffer,
    /// Scratch image k of the blending scheme.
    Scratch(usize),
}

/// Where a layer pass of the programmable scheme finds the pixel's current value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Current {
    /// In the framebuffer, the prime's zero: `src·(1 − 0) + 0 = src`, so the plain layer shader
    /// replaces it.
    Prime,
    /// In scratch image k, written by the previous layer pass of the same group.
    Scratch(u32),
    /// In scratch image k, written by the previous group's last layer pass: the shader takes its
    /// α as 0 first (the alpha clear).
    ScratchAfterGroup(u32),
}

/// How a lens pass uses the depth buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LensDepth {
    /// Nearer than what is there (`<`), writing the lens object's depth: the prime and the
    /// single pass.
    Write,
    /// The lens object's own pixels (`<=` the depth its prime wrote), depth kept: every pass
    /// after the prime.
    Test,
}

/// One draw pass of a lens object, before the builder adds its depth attachment and culling.
struct LensPass {
    name: String,
    category: PassCategory,
    program: ShaderProgram,
    colour: ColourAttachment,
    depth: LensDepth,
    sampled: Vec<ImageId>,
    draws: Vec<Draw>,
}

/// Declares the passes of lens object `index` into a frame graph.
pub(super) struct LensPasses<'a> {
    graph: &'a mut FrameGraph,
    resources: &'a FrameResources,
    lens: &'a LensShape,
    index: LensIndex,
    cull: Cull,
}

impl<'a> LensPasses<'a> {
    /// The builder of lens object `index` (of shape `lens`) in `graph`, whose images are
    /// `resources`.
    pub(super) fn new(
        graph: &'a mut FrameGraph,
        resources: &'a FrameResources,
        lens: &'a LensShape,
        index: LensIndex,
    ) -> LensPasses<'a> {
        let cull = match lens.faces {
            LensFaces::Front => Cull::Back,
            LensFaces::Both => Cull::None,
        };
        LensPasses {
            graph,
            resources,
            lens,
            index,
            cull,
        }
    }

    /// The lens object's shape.
    pub(super) fn lens(&self) -> &'a LensShape {
        self.lens
    }

    /// The prime: the lens object's pixels set to (0, 0, 0, 0), with its depth.
    pub(super) fn prime(&mut self) {
        self.add(LensPass {
            name: format!("{}/prime", self.lens.name),
            category: PassCategory::Prime,
            program: ShaderProgram::LensZero,
            colour: self.attach(Target::Framebuffer, LoadOp::Load, Blend::Replace),
            depth: LensDepth::Write,
            sampled: Vec::new(),
            draws: vec![Draw::LensZero { lens: self.index }],
        });
    }

    /// The single-pass draw, specialized as `program`, sampling every viewpoint's layered EM.
    pub(super) fn single_pass(&mut self, program: SinglePassProgram) {
        self.add(LensPass {
            name: format!("{}/single-pass", self.lens.name),
            category: PassCategory::SinglePass,
            program: ShaderProgram::LensSinglePass(program),
            colour: self.attach(Target::Framebuffer, LoadOp::Load, Blend::Replace),
            depth: LensDepth::Write,
            sampled: self.resources.layers[self.index.index()].clone(),
            draws: vec![Draw::SinglePass { lens: self.index }],
        });
    }

    /// The layer passes of `group` into `target` with `blend`, in the order the blend composites
    /// them: nearest first, except farthest first for back-to-front "over". A layer whose cube
    /// map is all zeros gets a pass without draws (the identity, culled by the graph).
    pub(super) fn layers(&mut self, group: Group, target: Target, blend: Blend) {
        let mut order: Vec<LayerIndex> = LayerIndex::all(self.lens.layer_count()).collect();
        if blend == Blend::BackToFrontOver {
            order.reverse();
        }
        for layer in order {
            let draws = if self.lens.empty[group.viewpoint][layer.index()] {
                Vec::new()
            } else {
                vec![self.layer_draw(group, layer)]
            };
            self.add(LensPass {
                name: format!("{}/layer{layer}", self.group_name(group)),
                category: PassCategory::Layer,
                program: ShaderProgram::LensLayer,
                colour: self.attach(target, LoadOp::Load, blend),
                depth: LensDepth::Test,
                sampled: vec![self.sampled_layers(group)],
                draws,
            });
        }
    }

    /// One layer pass of the programmable scheme into `target`, blending in the shader over the
    /// `current` value. It replaces every lens pixel: a scratch target's earlier contents are not
    /// loaded; the framebuffer keeps its other pixels.
    pub(super) fn programmable_layer(
        &mut self,
        group: Group,
        layer: LayerIndex,
        target: Target,
        current: Current,
    ) {
        let (program, draw, read) = match current {
            Current::Prime => (
                ShaderProgram::LensLayer,
                self.layer_draw(group, layer),
                None,
            ),
            Current::Scratch(read) | Current::ScratchAfterGroup(read) => (
                ShaderProgram::LensLayerProgrammable,
                Draw::ProgrammableLayer {
                    lens: self.index,
                    viewpoint: group.viewpoint,
                    term: group.term,
                    layer,
                    read,
                    reset_alpha: matches!(current, Current::ScratchAfterGroup(_)),
                },
                Some(self.resources.scratch[read as usize]),
            ),
        };
        let load = match target {
            Target::Framebuffer => LoadOp::Load,
            Target::Scratch(_) => LoadOp::DontCare,
        };
        self.add(LensPass {
            name: format!("{}/layer{layer}", self.group_name(group)),
            category: PassCategory::Layer,
            program,
            colour: self.attach(target, load, Blend::Replace),
            depth: LensDepth::Test,
            sampled: std::iter::once(self.sampled_layers(group))
                .chain(read)
                .collect(),
            draws: vec![draw],
        });
    }

    /// The alpha clear before `group`: the framebuffer's lens pixels keep their colour, α
    /// becomes 0 (the zero shader with write mask A).
    pub(super) fn alpha_clear(&mut self, group: Group) {
        let mut colour = self.attach(Target::Framebuffer, LoadOp::Load, Blend::Replace);
        colour.write_mask = ColourMask::A;
        self.add(LensPass {
            name: format!("{}/alpha-clear", self.group_name(group)),
            category: PassCategory::AlphaClear,
            program: ShaderProgram::LensZero,
            colour,
            depth: LensDepth::Test,
            sampled: Vec::new(),
            draws: vec![Draw::LensZero { lens: self.index }],
        });
    }

    /// The clear of scratch image `scratch` to zero before `group` is composited into it: a
    /// pass without draws that the graph keeps for its clear.
    pub(super) fn scratch_clear(&mut self, group: Group, scratch: usize) {
        self.add(LensPass {
            name: format!("{}/clear", self.group_name(group)),
            category: PassCategory::ScratchClear,
            program: ShaderProgram::LensZero,
            colour: self.attach(
                Target::Scratch(scratch),
                LoadOp::Clear([0.0; 4]),
                Blend::Replace,
            ),
            depth: LensDepth::Test,
            sampled: Vec::new(),
            draws: Vec::new(),
        });
    }

    /// Scratch image 0, where `group` was composited, added into the framebuffer's channels
    /// `mask`.
    pub(super) fn accumulate(&mut self, group: Group, mask: ColourMask) {
        let name = format!("{}/accumulate", self.group_name(group));
        self.sum_scratch(name, 1, mask);
    }

    /// Scratch images `0..groups`, one per group, summed into the framebuffer: colour added, α
    /// the last group's.
    pub(super) fn group_sum(&mut self, groups: usize) {
        let name = format!("{}/group-sum", self.lens.name);
        self.sum_scratch(name, groups, ColourMask::RGBA);
    }

    /// A full-screen pass adding scratch images `0..count` into the framebuffer's channels
    /// `mask`.
    fn sum_scratch(&mut self, name: String, count: usize, mask: ColourMask) {
        let mut colour = self.attach(Target::Framebuffer, LoadOp::Load, Blend::Add);
        colour.write_mask = mask;
        self.graph.add_pass(Pass {
            name,
            category: PassCategory::GroupSum,
            side_effect: false,
            kind: PassKind::Draw {
                program: ShaderProgram::GroupSum,
                colour,
                depth: None,
                cull: Cull::None,
                sampled: self.resources.scratch[..count].to_vec(),
                storage: Vec::new(),
                draws: vec![Draw::GroupSum {
                    groups: count as u32,
                }],
            },
        });
    }

    /// The pass name prefix of `group`: `lens/v0/T`.
    fn group_name(&self, group: Group) -> String {
        format!(
            "{}/v{}/{}",
            self.lens.name,
            group.viewpoint,
            group.term.name()
        )
    }

    /// The draw of one layer of `group`.
    fn layer_draw(&self, group: Group, layer: LayerIndex) -> Draw {
        Draw::Layer {
            lens: self.index,
            viewpoint: group.viewpoint,
            term: group.term,
            layer,
        }
    }

    /// The layered EM `group` samples: its viewpoint's cube-map array of this lens object.
    fn sampled_layers(&self, group: Group) -> ImageId {
        self.resources.layers[self.index.index()][group.viewpoint]
    }

    /// `target` as a stored colour attachment, all channels written.
    fn attach(&self, target: Target, load: LoadOp, blend: Blend) -> ColourAttachment {
        ColourAttachment {
            image: match target {
                Target::Framebuffer => self.resources.colour,
                Target::Scratch(k) => self.resources.scratch[k],
            },
            load,
            store: StoreOp::Store,
            blend,
            write_mask: ColourMask::RGBA,
        }
    }

    /// Adds `pass` with the lens object's culling and `pass.depth` on the depth target.
    fn add(&mut self, pass: LensPass) {
        let (test, write) = match pass.depth {
            LensDepth::Write => (CompareOp::Less, true),
            LensDepth::Test => (CompareOp::LessOrEqual, false),
        };
        self.graph.add_pass(Pass {
            name: pass.name,
            category: pass.category,
            side_effect: false,
            kind: PassKind::Draw {
                program: pass.program,
                colour: pass.colour,
                depth: Some(DepthAttachment {
                    image: self.resources.depth,
                    load: LoadOp::Load,
                    store: StoreOp::DontCare,
                    test: Some(test),
                    write,
                }),
                cull: self.cull,
                sampled: pass.sampled,
                // A resident lens object's parts, made this frame by its compute pass.
                storage: self.resources.parts[self.index.index()].clone(),
                draws: pass.draws,
            },
        });
    }
}
