//! The GPU tessellation as compute work: every pass it runs, in order, with the buffers each
//! reads and writes (from naga's analysis of its entry point), declared once for both uses: a
//! plan with no device ([`planned_part`], what `lensmap passes --gpu-parts` prints) and a frame
//! or a submission of the tracer's own ([`declare`] bound to the buffers, sets and constants).
//!
//! The passes: the control words written and the wanted flags and counters cleared; the
//! classification of the input triangles; per level the level's new vertices traced (the
//! tracer's level pass), the split decisions, their prefix sum and the new triangles; the leaves
//! and the T-junction removal; texgen; the draw list (indices and indirect draws); the counts
//! copied to the part's host buffer, which the host reads once the submission is done.

use std::sync::Arc;

use lensmap_shaders::{drawlist, tessellate, texgen, tracer};

use super::buffers::{CONTROL_WORDS, COUNTERS, InputMesh, Scratch};
use crate::gpu::{Buffer, DescriptorSet, GpuError, Kernels, Pipeline, QueryPoolRef};
use crate::graph::Access;
use crate::render::compute::{
    Command, ComputeWork, Dispatch, DispatchSize, WorkBuilder, WorkPassKind, WorkShape,
};
use crate::render::{DeviceLensPart, PartShape};

/// Words of a part's host copy of its counts: the tessellation's control words, the tracer's
/// counters (padded to four), the three indirect draws.
pub(super) const COUNT_WORDS: usize = CONTROL_WORDS + 4 + 15;

/// Bytes of the three indirect draws.
pub(super) const ARGS_BYTES: u64 = 60;

const _: () = assert!(COUNTERS <= 4);

/// One binding of a pass's set: its number, the work's name for the buffer, and the buffer
/// (bound works; `None` in a plan, and for a binding that is no buffer, such as the driver's
/// acceleration structure).
pub(super) struct SetEntry<'a> {
    pub(super) binding: u32,
    pub(super) name: String,
    pub(super) buffer: Option<&'a Buffer>,
}

/// What a tessellation's sets point at, by the work's names: the shared buffers (`scratch`),
/// scene object `object`'s input, hull flags and shells, and the part's outputs.
pub(super) struct TessellationBuffers<'a> {
    /// The shared buffers (`None` in a plan).
    pub(super) scratch: Option<&'a Scratch>,
    /// The object's input mesh.
    pub(super) input: Option<&'a InputMesh>,
    /// The object's hull flags and texgen shells.
    pub(super) hull: Option<&'a Buffer>,
    pub(super) shells: Option<&'a Buffer>,
    /// The part's outputs: its data, indices, draws and host counts.
    pub(super) part: Option<&'a DeviceLensPart>,
    /// The tracer's own buffers at bindings 0 to 4 of the level pass (the walk's two, the
    /// triangles, the materials, the Schlick table), with their names (`None` for the driver's
    /// acceleration structure).
    pub(super) geometry: [(Option<&'a Buffer>, &'static str); 5],
    /// The scene object.
    pub(super) object: usize,
    /// The part's name.
    pub(super) part_name: &'a str,
}

impl<'a> TessellationBuffers<'a> {
    fn shared(&self, name: &str, pick: fn(&Scratch) -> &Buffer) -> (String, Option<&'a Buffer>) {
        (format!("tessellation {name}"), self.scratch.map(pick))
    }

    fn object_buffer(
        &self,
        name: &str,
        buffer: Option<&'a Buffer>,
    ) -> (String, Option<&'a Buffer>) {
        (format!("object{} {name}", self.object), buffer)
    }

    fn output(&self, index: usize) -> (String, Option<&'a Buffer>) {
        let names = DeviceLensPart::buffer_names(self.part_name);
        let buffer = self.part.map(|p| [&p.data, &p.indices, &p.args][index]);
        (names[index].clone(), buffer)
    }

    /// The part's host copy of its counts.
    fn counts(&self) -> (String, Option<&'a Buffer>) {
        (
            format!("{} counts", self.part_name),
            self.part.map(|p| &p.counts),
        )
    }

    fn entries(list: Vec<(u32, (String, Option<&'a Buffer>))>) -> Vec<SetEntry<'a>> {
        list.into_iter()
            .map(|(binding, (name, buffer))| SetEntry {
                binding,
                name,
                buffer,
            })
            .collect()
    }

    /// The tessellation passes' set (tessellate.wgsl).
    pub(super) fn tessellation(&self) -> Vec<SetEntry<'a>> {
        use tessellate::binding as b;
        Self::entries(vec![
            (b::VERTICES, self.shared("vertices", |s| &s.vertices)),
            (b::RECORDS, self.shared("records", |s| &s.records)),
            (b::CONTROL, self.shared("control", |s| &s.control)),
            (b::WANTED, self.shared("wanted", |s| &s.wanted)),
            (b::TRIS, self.shared("triangles", |s| &s.triangles)),
            (b::EDGE_ENDS, self.shared("edge ends", |s| &s.edge_ends)),
            (b::EDGE_STATE, self.shared("edge state", |s| &s.edge_state)),
            (b::COUNTS, self.shared("counts", |s| &s.counts)),
            (b::BLOCK_SUMS, self.shared("block sums", |s| &s.block_sums)),
            (b::OUTPUT, self.shared("output", |s| &s.output)),
            (
                b::INPUT_VERTICES,
                self.object_buffer("input vertices", self.input.map(|i| &i.vertices)),
            ),
            (
                b::INPUT_TRIANGLES,
                self.object_buffer("input triangles", self.input.map(|i| &i.triangles)),
            ),
            (
                b::BASE_EDGES,
                self.object_buffer("base edges", self.input.map(|i| &i.edges)),
            ),
        ])
    }

    /// The tracer's level pass's set (vertex_paths.wgsl, after the walk's and the geometry's).
    pub(super) fn level_paths(&self) -> Vec<SetEntry<'a>> {
        use tracer::binding as b;
        let mut list: Vec<(u32, (String, Option<&'a Buffer>))> = self
            .geometry
            .iter()
            .enumerate()
            .map(|(binding, &(buffer, name))| (binding as u32, (name.to_string(), buffer)))
            .collect();
        list.extend([
            (b::VERTICES, self.shared("vertices", |s| &s.vertices)),
            (b::RECORDS, self.shared("records", |s| &s.records)),
            (b::COUNTERS, self.shared("tracer counters", |s| &s.counters)),
            (b::CONTROL, self.shared("control", |s| &s.control)),
            (b::WANTED, self.shared("wanted", |s| &s.wanted)),
        ]);
        Self::entries(list)
    }

    /// Texgen's set (texgen.wgsl), writing the part's data.
    pub(super) fn texgen(&self) -> Vec<SetEntry<'a>> {
        use texgen::binding as b;
        Self::entries(vec![
            (b::VERTICES, self.shared("vertices", |s| &s.vertices)),
            (b::RECORDS, self.shared("records", |s| &s.records)),
            (b::WANTED, self.shared("wanted", |s| &s.wanted)),
            (b::SHELLS, self.object_buffer("shells", self.shells)),
            (b::LENS_DATA, self.output(0)),
            (b::CONTROL, self.shared("control", |s| &s.control)),
        ])
    }

    /// The draw list's set (drawlist.wgsl), writing the part's indices and draws.
    pub(super) fn draw_list(&self) -> Vec<SetEntry<'a>> {
        use drawlist::binding as b;
        Self::entries(vec![
            (b::CONTROL, self.shared("control", |s| &s.control)),
            (b::OUTPUT, self.shared("output", |s| &s.output)),
            (b::TRIS, self.shared("triangles", |s| &s.triangles)),
            (b::VERTICES, self.shared("vertices", |s| &s.vertices)),
            (b::HULL, self.object_buffer("hull", self.hull)),
            (b::COUNTS, self.shared("counts", |s| &s.counts)),
            (b::BLOCK_SUMS, self.shared("block sums", |s| &s.block_sums)),
            (b::INDICES, self.output(1)),
            (b::ARGS, self.output(2)),
        ])
    }
}

/// What a bound tessellation's passes record with.
pub(super) struct Bound<'a> {
    pub(super) tessellation: &'a Kernels<tessellate::Entry>,
    pub(super) texgen: &'a Kernels<texgen::Entry>,
    pub(super) draw_list: &'a Kernels<drawlist::Entry>,
    /// The tracer's level pass.
    pub(super) level_paths: Pipeline,
    /// The level pass's set, the tessellation's, texgen's (when it runs) and the draw list's.
    pub(super) sets: [DescriptorSet; 4],
    /// The push constants' bytes ([`crate::render::compute::push_constants`]): the level
    /// pass's `TracerConstants`, the tessellation's `TessellateConstants`, texgen's
    /// `TexgenConstants` (when it runs) and the draw list's `DrawConstants`.
    pub(super) tracer_constants: Arc<[u8]>,
    pub(super) constants: Arc<[u8]>,
    pub(super) texgen_constants: Option<Arc<[u8]>>,
    pub(super) draw_constants: Arc<[u8]>,
    /// The control words the tessellation starts from, the first `written` of them written.
    pub(super) first: [u32; CONTROL_WORDS],
    pub(super) written: usize,
    /// Input vertices, triangles and base edges.
    pub(super) input: [u32; 3],
    /// The timestamps of a timed tessellation.
    pub(super) timestamps: Option<QueryPoolRef>,
}

/// What a tessellation's passes are: its levels, whether texgen runs, and its buffers.
pub(super) struct Tessellation<'a> {
    /// Levels (the depth cap + 1).
    pub(super) levels: u32,
    /// Whether texgen runs (and writes the part's data).
    pub(super) texgen: bool,
    pub(super) buffers: TessellationBuffers<'a>,
}

/// What a tessellation's work's shape depends on: its buffers' names (the scene object's and
/// the part's), its levels, whether texgen runs and whether it is timed.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(super) struct ShapeKey {
    object: usize,
    part: String,
    levels: u32,
    texgen: bool,
    timed: bool,
}

impl Tessellation<'_> {
    /// The key of the shape its declaration makes, recorded with `bound`.
    pub(super) fn shape_key(&self, bound: &Bound<'_>) -> ShapeKey {
        ShapeKey {
            object: self.buffers.object,
            part: self.buffers.part_name.to_string(),
            levels: self.levels,
            texgen: self.texgen,
            timed: bound.timestamps.is_some(),
        }
    }
}

/// The work's buffers for a set's entries: binding `b` → the work's buffer (`None` where the
/// entry has no name of a buffer: the acceleration structure).
fn slots(builder: &mut WorkBuilder, entries: &[SetEntry<'_>]) -> Vec<Option<usize>> {
    let len = entries
        .iter()
        .map(|e| e.binding as usize + 1)
        .max()
        .unwrap_or(0);
    let mut slots = vec![None; len];
    for entry in entries {
        if !entry.name.is_empty() {
            slots[entry.binding as usize] = Some(builder.buffer(&entry.name, entry.buffer));
        }
    }
    slots
}

/// The size of a dispatch over the elements counted at control word `word` (indirect).
fn indirect(control: usize, word: u32) -> DispatchSize {
    DispatchSize::Indirect {
        buffer: control,
        offset: 4 * u64::from(word),
    }
}

/// What the passes of one tessellation are declared with: the builder, the bound recording
/// (`None` in a plan), and the work's buffers behind the tessellation's and the level pass's
/// sets.
struct Passes<'w, 'b> {
    builder: &'w mut WorkBuilder,
    bound: Option<&'w Bound<'b>>,
    tessellation: Vec<Option<usize>>,
    level: Vec<Option<usize>>,
    control: usize,
}

impl Passes<'_, '_> {
    /// A tessellation pass of `entry` over `size`.
    fn pass(&mut self, name: &dyn std::fmt::Display, entry: tessellate::Entry, size: DispatchSize) {
        let bound = self.bound.map(|b| {
            (
                b.tessellation.pipeline(entry),
                b.sets[1],
                b.constants.clone(),
            )
        });
        self.builder.dispatch(Dispatch {
            name,
            entry,
            buffers: &self.tessellation,
            size,
            bound,
        });
    }

    /// Timestamp `query`, where the tessellation is timed.
    fn stamp(&mut self, query: u32) {
        if let Some(pool) = self.bound.and_then(|b| b.timestamps) {
            self.builder.pass(
                format_args!("timestamp {query}"),
                WorkPassKind::Timestamp,
                Vec::new,
                || Command::Timestamp { pool, query },
            );
        }
    }

    /// The dispatch over the elements counted at control word `word`.
    fn indirect(&self, word: u32) -> DispatchSize {
        indirect(self.control, word)
    }

    /// The host's writes before the passes: the control words, the wanted flags, the tracer's
    /// counters (and the timestamps' reset).
    fn transfers(&mut self, counters: usize, levels: u32) {
        let (control, bound) = (self.control, self.bound);
        let wanted = self.tessellation[tessellate::binding::WANTED as usize].unwrap_or_default();
        let transfer = |slot: usize| move || vec![(slot, Access::TransferWrite)];
        self.builder
            .pass("control", WorkPassKind::Transfer, transfer(control), || {
                Command::Update {
                    buffer: control,
                    words: bound.map_or_else(Vec::new, |b| b.first[..b.written].to_vec()),
                }
            });
        self.builder
            .pass("wanted", WorkPassKind::Transfer, transfer(wanted), || {
                Command::Fill {
                    buffer: wanted,
                    bytes: bound.map(|b| 4 * u64::from(b.input[0]).max(1)),
                    value: 0,
                }
            });
        self.builder.pass(
            "tracer counters",
            WorkPassKind::Transfer,
            transfer(counters),
            || Command::Fill {
                buffer: counters,
                bytes: None,
                value: 0,
            },
        );
        if let Some(pool) = bound.and_then(|b| b.timestamps) {
            let count = 4 * levels + 4;
            self.builder
                .pass("timestamps", WorkPassKind::Timestamp, Vec::new, || {
                    Command::ResetTimestamps { pool, count }
                });
        }
    }

    /// Level `l`: its new vertices traced (the tracer's level pass), its decisions, their
    /// prefix sum and the next level's triangles.
    fn level(&mut self, l: u32) {
        use tessellate::Entry as E;
        self.stamp(4 * l);
        let bound = self
            .bound
            .map(|b| (b.level_paths, b.sets[0], b.tracer_constants.clone()));
        self.builder.dispatch(Dispatch {
            name: &format_args!("level {l} trace"),
            entry: tracer::Entry::CsLevelPaths,
            buffers: &self.level,
            size: self.indirect(tessellate::CONTROL_DISPATCH_TRACE),
            bound,
        });
        self.stamp(4 * l + 1);
        self.stamp(4 * l + 2);
        let elements = self.indirect(tessellate::CONTROL_DISPATCH_ELEMENTS);
        let blocks = self.indirect(tessellate::CONTROL_DISPATCH_BLOCKS);
        let single = DispatchSize::Groups(1);
        for (name, entry, size) in [
            ("cs_decide", E::CsDecide, elements),
            ("cs_count", E::CsCount, elements),
            ("cs_scan_blocks", E::CsScanBlocks, blocks),
            ("cs_scan_top", E::CsScanTop, single),
            ("cs_apply", E::CsApply, elements),
            ("cs_emit", E::CsEmit, elements),
            ("cs_advance", E::CsAdvance, single),
        ] {
            self.pass(&format_args!("level {l} {name}"), entry, size);
        }
        self.stamp(4 * l + 3);
    }

    /// The leaves and the T-junction removal.
    fn leaves(&mut self) {
        use tessellate::Entry as E;
        let elements = self.indirect(tessellate::CONTROL_DISPATCH_ELEMENTS);
        let blocks = self.indirect(tessellate::CONTROL_DISPATCH_BLOCKS);
        let single = DispatchSize::Groups(1);
        for (name, entry, size) in [
            ("cs_leaves_begin", E::CsLeavesBegin, single),
            ("cs_leaf_count", E::CsLeafCount, elements),
            ("leaves cs_scan_blocks", E::CsScanBlocks, blocks),
            ("leaves cs_scan_top", E::CsScanTop, single),
            ("cs_leaf_emit", E::CsLeafEmit, elements),
        ] {
            self.pass(&name, entry, size);
        }
    }

    /// Texgen over every vertex (cs_leaves_begin set the trace arguments so), writing the
    /// part's data.
    fn texgen(&mut self, buffers: &TessellationBuffers<'_>) {
        let set = buffers.texgen();
        let slots = slots(self.builder, &set);
        let bound = self.bound.and_then(|b| {
            let constants = b.texgen_constants.clone()?;
            let pipeline = b.texgen.pipeline(texgen::Entry::CsTexgen);
            Some((pipeline, b.sets[2], constants))
        });
        self.builder.dispatch(Dispatch {
            name: &"cs_texgen",
            entry: texgen::Entry::CsTexgen,
            buffers: &slots,
            size: self.indirect(tessellate::CONTROL_DISPATCH_TRACE),
            bound,
        });
    }
}

/// Declares a tessellation's passes into `builder`, recording with `bound` (a plan: `None`).
pub(super) fn declare(
    builder: &mut WorkBuilder,
    work: &Tessellation<'_>,
    bound: Option<&Bound<'_>>,
) {
    let buffers = &work.buffers;
    let tessellation = slots(builder, &buffers.tessellation());
    let level = slots(builder, &buffers.level_paths());
    let control = tessellation[tessellate::binding::CONTROL as usize].unwrap_or_default();
    let counters = level[tracer::binding::COUNTERS as usize].unwrap_or_default();
    let mut passes = Passes {
        builder,
        bound,
        tessellation,
        level,
        control,
    };
    passes.transfers(counters, work.levels);
    let wg = tessellate::WORKGROUP;
    let groups = |n: u32| DispatchSize::Groups(n.div_ceil(wg));
    let [vertices, triangles, edges] = bound.map_or([0; 3], |b| b.input);
    let begin = groups(vertices.max(edges));
    passes.pass(&"cs_begin", tessellate::Entry::CsBegin, begin);
    let classify = groups(triangles);
    passes.pass(&"cs_classify", tessellate::Entry::CsClassify, classify);
    for l in 0..work.levels {
        passes.level(l);
    }
    let last = 4 * work.levels;
    passes.stamp(last);
    passes.leaves();
    passes.stamp(last + 1);
    passes.stamp(last + 2);
    if work.texgen {
        passes.texgen(buffers);
    }
    passes.stamp(last + 3);
    declare_draw_list(passes.builder, buffers, bound);
    declare_counts(passes.builder, buffers, control, counters);
}

/// The work of a tessellation's passes recorded with `bound`, its shape taken from `shapes`
/// where an earlier declaration made it (only the commands are made), kept there otherwise. A
/// kept shape the declaration does not match is an internal error (a key that misses what the
/// shape depends on: a bug). A new shape drops those of parts no longer `held` (outputs
/// made anew once the buffers grew or the shells changed), so that the shapes stay as many as
/// the parts.
pub(super) fn declare_bound(
    shapes: &mut rustc_hash::FxHashMap<ShapeKey, Arc<WorkShape>>,
    work: &Tessellation<'_>,
    bound: &Bound<'_>,
    held: impl Fn(usize, &str) -> bool,
) -> Result<ComputeWork, GpuError> {
    let key = work.shape_key(bound);
    if let Some(shape) = shapes.get(&key) {
        let mut builder = WorkBuilder::bound_to(shape.clone());
        declare(&mut builder, work, Some(bound));
        return builder.finish();
    }
    let mut builder = WorkBuilder::bound();
    declare(&mut builder, work, Some(bound));
    let made = builder.finish()?;
    shapes.retain(|kept, _| held(kept.object, &kept.part));
    shapes.insert(key, made.shape.clone());
    Ok(made)
}

/// The draw list's passes: the index buffer and the indirect draws of the part.
fn declare_draw_list(
    builder: &mut WorkBuilder,
    buffers: &TessellationBuffers<'_>,
    bound: Option<&Bound<'_>>,
) {
    let set = buffers.draw_list();
    let draw = slots(builder, &set);
    let control = draw[drawlist::binding::CONTROL as usize].unwrap_or_default();
    use drawlist::Entry as E;
    let elements = indirect(control, tessellate::CONTROL_DISPATCH_ELEMENTS);
    let blocks = indirect(control, tessellate::CONTROL_DISPATCH_BLOCKS);
    let single = DispatchSize::Groups(1);
    for (name, entry, size) in [
        ("cs_draw_begin", E::CsDrawBegin, single),
        ("cs_draw_count", E::CsDrawCount, elements),
        ("draw cs_scan_blocks", E::CsScanBlocks, blocks),
        ("draw cs_scan_top", E::CsScanTop, single),
        ("cs_draw_args", E::CsDrawArgs, single),
        ("cs_draw_emit", E::CsDrawEmit, elements),
    ] {
        builder.dispatch(Dispatch {
            name: &name,
            entry,
            buffers: &draw,
            size,
            bound: bound.map(|b| {
                (
                    b.draw_list.pipeline(entry),
                    b.sets[3],
                    b.draw_constants.clone(),
                )
            }),
        });
    }
}

/// The counts copied into the part's host buffer (the control words, the tracer's counters, the
/// draws), which the host reads once the submission is done.
fn declare_counts(
    builder: &mut WorkBuilder,
    buffers: &TessellationBuffers<'_>,
    control: usize,
    counters: usize,
) {
    let (name, buffer) = buffers.counts();
    let counts = builder.buffer(&name, buffer);
    let (draws_name, draws_buffer) = buffers.output(2);
    let draws = builder.buffer(&draws_name, draws_buffer);
    let words = 4 * CONTROL_WORDS as u64;
    for (label, from, at, bytes) in [
        ("counts: control", control, 0, words),
        (
            "counts: tracer counters",
            counters,
            words,
            4 * COUNTERS as u64,
        ),
        ("counts: draws", draws, words + 16, ARGS_BYTES),
    ] {
        let uses = || {
            vec![
                (from, Access::TransferRead),
                (counts, Access::TransferWrite),
            ]
        };
        builder.pass(label, WorkPassKind::Transfer, uses, || Command::Copy {
            from,
            to: counts,
            regions: vec![(0, at, bytes)],
        });
    }
    builder.pass(
        "counts: host",
        WorkPassKind::HostRead,
        || vec![(counts, Access::HostRead)],
        || Command::HostRead,
    );
}

/// Part `name` of scene object `object` as a plan with no device sees it: the passes of its
/// tessellation of `levels` levels (texgen too when `texgen`), for `lensmap passes --gpu-parts`.
pub fn planned_part(name: &str, object: usize, levels: u32, texgen: Texgen) -> PartShape {
    let mut builder = WorkBuilder::planned();
    let work = Tessellation {
        levels,
        texgen: texgen == Texgen::On,
        buffers: TessellationBuffers {
            scratch: None,
            input: None,
            hull: None,
            shells: None,
            part: None,
            geometry: [
                (None, "tracer nodes"),
                (None, "tracer triangles"),
                (None, "tracer materials"),
                (None, "tracer roots"),
                (None, "tracer schlick"),
            ],
            object,
            part_name: name,
        },
    };
    declare(&mut builder, &work, None);
    PartShape {
        name: name.into(),
        work: Some(std::sync::Arc::new(builder.shape())),
    }
}

/// Whether a tessellation gives its vertices texture coordinates (a frame drawn from the
/// device's buffers does; one read back for the wireframe alone need not).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Texgen {
    /// Texgen runs, writing the part's data.
    On,
    /// No texgen.
    Off,
}
