//! Compiling a declared graph into a plan: validation, culling, render-pass instances and
//! barriers, and the plan's table.

use std::{collections::HashSet, fmt};

use super::{
    Access, BufferId, BufferInfo, BufferOrigin, DepthAttachment, Graph, GraphError, ImageId,
    ImageInfo, Layout, LoadOp, Origin, Pass, PassKind, StoreOp,
};

/// Why a declared pass is not in the plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CullReason {
    /// A draw pass with no draws and nothing to clear.
    EmptyDrawList,
    /// Nothing after it reads what it writes, and it has no side effect.
    OutputUnused,
}

impl fmt::Display for CullReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            CullReason::EmptyDrawList => "no draws",
            CullReason::OutputUnused => "output unused",
        })
    }
}

/// A layout transition and/or memory dependency on one image before a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Barrier {
    /// The image.
    pub image: ImageId,
    /// Layout before (Undefined discards the contents).
    pub old_layout: Layout,
    /// Layout after.
    pub new_layout: Layout,
    /// The access that must finish first.
    pub src: Access,
    /// The access that waits.
    pub dst: Access,
}

/// A memory dependency on one buffer before a step: an earlier use (`src`) must finish, and its
/// writes be visible, before the step's use (`dst`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferBarrier {
    /// The buffer.
    pub buffer: BufferId,
    /// The access that must finish first.
    pub src: Access,
    /// The access that waits.
    pub dst: Access,
}

/// A run of consecutive draw passes with the same attachments, recorded inside one
/// `vkCmdBeginRendering`/`vkCmdEndRendering`: blending within it is ordered by the rasterization
/// order guarantee, so it needs no barriers between its passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderingInstance {
    /// Colour attachment, its load op (from the first pass) and store op (Store if any pass stores).
    pub colour: (ImageId, LoadOp, StoreOp),
    /// Depth attachment likewise.
    pub depth: Option<(ImageId, LoadOp, StoreOp)>,
}

/// One live pass of the plan, in execution order.
#[derive(Clone, Debug, PartialEq)]
pub struct Step<D, P, C> {
    /// The pass.
    pub pass: Pass<D, P, C>,
    /// Barriers recorded before it (only on the first step of a rendering instance, or a readback).
    pub barriers: Vec<Barrier>,
    /// Buffer barriers recorded before it (on a compute step, a host read, or the first step of a
    /// rendering instance whose draws read what a compute pass wrote).
    pub buffer_barriers: Vec<BufferBarrier>,
    /// `Some` on the first step of a rendering instance: begin rendering before this step.
    pub begin: Option<RenderingInstance>,
    /// End rendering after this step.
    pub end: bool,
}

/// A compiled graph: what `render/` records, and what `lensmap passes` prints.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan<D, P, C> {
    /// The images, indexed by [`ImageId`].
    pub images: Vec<ImageInfo>,
    /// The buffers, indexed by `BufferId`.
    pub buffers: Vec<BufferInfo>,
    /// Live passes in order.
    pub steps: Vec<Step<D, P, C>>,
    /// Passes dropped, with why.
    pub culled: Vec<(String, CullReason)>,
}

impl<D, P, C: PartialEq> Plan<D, P, C> {
    /// Live passes of a category.
    pub fn count(&self, category: C) -> usize {
        self.steps
            .iter()
            .filter(|s| s.pass.category == category)
            .count()
    }

    /// Total draws of the live passes of a category.
    pub fn draws(&self, category: C) -> usize {
        self.steps
            .iter()
            .filter(|s| s.pass.category == category)
            .map(|s| s.pass.draw_count())
            .sum()
    }

    /// Number of `vkCmdBeginRendering` instances.
    pub fn rendering_instances(&self) -> usize {
        self.steps.iter().filter(|s| s.begin.is_some()).count()
    }

    /// Number of barriers.
    pub fn barrier_count(&self) -> usize {
        self.steps
            .iter()
            .map(|s| s.barriers.len() + s.buffer_barriers.len())
            .sum()
    }
}

/// Images a pass reads (their earlier contents matter to it) and writes.
fn reads_and_writes<D, P, C>(pass: &Pass<D, P, C>) -> (Vec<ImageId>, Vec<ImageId>) {
    match &pass.kind {
        PassKind::Draw {
            colour,
            depth,
            sampled,
            ..
        } => {
            let mut reads = sampled.clone();
            let mut writes = vec![colour.image];
            if colour.load == LoadOp::Load {
                reads.push(colour.image);
            }
            if let Some(d) = depth {
                if d.load == LoadOp::Load {
                    reads.push(d.image);
                }
                if d.write || d.load != LoadOp::Load {
                    writes.push(d.image);
                }
            }
            (reads, writes)
        }
        PassKind::Readback { image, .. } | PassKind::Export { image } => (vec![*image], Vec::new()),
        PassKind::Compute { .. } | PassKind::HostRead { .. } => (Vec::new(), Vec::new()),
    }
}

/// The buffers a pass uses and how, in its order.
fn buffer_uses<D, P, C>(pass: &Pass<D, P, C>) -> Vec<(BufferId, Access)> {
    match &pass.kind {
        PassKind::Draw { storage, .. } => storage
            .iter()
            .map(|&b| (b, Access::VertexStorageRead))
            .collect(),
        PassKind::Compute { buffers, .. } => buffers.clone(),
        PassKind::HostRead { buffers } => buffers.iter().map(|&b| (b, Access::HostRead)).collect(),
        PassKind::Readback { .. } | PassKind::Export { .. } => Vec::new(),
    }
}

/// The buffers a pass reads and writes.
fn buffer_reads_and_writes<D, P, C>(pass: &Pass<D, P, C>) -> (Vec<BufferId>, Vec<BufferId>) {
    let uses = buffer_uses(pass);
    let reads = uses
        .iter()
        .filter(|(_, a)| !matches!(a, Access::TransferWrite))
        .map(|(b, _)| *b)
        .collect();
    let writes = uses
        .iter()
        .filter(|(_, a)| a.writes())
        .map(|(b, _)| *b)
        .collect();
    (reads, writes)
}

/// Whether the pass fully redefines `image` (so earlier writers are not needed by it).
fn redefines<D, P, C>(pass: &Pass<D, P, C>, image: ImageId) -> bool {
    match &pass.kind {
        PassKind::Draw { colour, depth, .. } => {
            (colour.image == image && colour.load != LoadOp::Load)
                || depth.is_some_and(|d| d.image == image && d.load != LoadOp::Load)
        }
        PassKind::Readback { .. }
        | PassKind::Export { .. }
        | PassKind::Compute { .. }
        | PassKind::HostRead { .. } => false,
    }
}

/// Per declared pass: `None` while it is live, else why it was culled.
type Culling = Vec<Option<CullReason>>;

/// Where an image stands while the plan is scheduled: its layout, the last access and whether
/// that access wrote.
type ImageState = (Layout, Access, bool);

/// Where a buffer stands while the plan is scheduled: its last writer and its readers since.
#[derive(Clone, Debug, Default)]
struct BufferState {
    writer: Option<Access>,
    readers: Vec<Access>,
}

impl BufferState {
    /// The state of a buffer of `origin` before the frame.
    fn of(origin: BufferOrigin) -> BufferState {
        BufferState {
            writer: (origin == BufferOrigin::Kept).then_some(Access::Earlier),
            readers: Vec::new(),
        }
    }

    /// Uses the buffer by `access`, adding the barriers that use must wait behind: a read after
    /// a write (once per kind of reader), a write after reads (an execution dependency on each)
    /// or after a write.
    fn use_by(&mut self, buffer: BufferId, access: Access, barriers: &mut Vec<BufferBarrier>) {
        let mut wait = |src: Access| {
            let barrier = BufferBarrier {
                buffer,
                src,
                dst: access,
            };
            if !barriers.contains(&barrier) {
                barriers.push(barrier);
            }
        };
        if access.writes() {
            match (self.readers.is_empty(), self.writer) {
                (false, _) => self.readers.iter().for_each(|&r| wait(r)),
                (true, Some(writer)) => wait(writer),
                (true, None) => {}
            }
            self.writer = Some(access);
            self.readers.clear();
        } else if !self.readers.contains(&access) {
            if let Some(writer) = self.writer {
                wait(writer);
            }
            self.readers.push(access);
        }
    }
}

impl<D: Clone, P: Clone, C: Clone> Graph<D, P, C> {
    /// Validates the declaration and compiles it into a plan, in four phases: empty draw lists
    /// are culled, then passes whose outputs nobody reads; the live passes are checked for reads
    /// before writes; then they are grouped into rendering instances with their barriers.
    pub fn compile(&self) -> Result<Plan<D, P, C>, GraphError> {
        self.validate()?;
        let mut culled = self.cull_empty_draw_lists();
        self.cull_unread_outputs(&mut culled);
        self.check_reads_before_writes(&culled)?;
        let live: Vec<&Pass<D, P, C>> = self
            .passes
            .iter()
            .zip(&culled)
            .filter(|(_, c)| c.is_none())
            .map(|(p, _)| p)
            .collect();
        Ok(Plan {
            images: self.images.clone(),
            buffers: self.buffers.clone(),
            steps: self.schedule(&live),
            culled: self
                .passes
                .iter()
                .zip(culled)
                .filter_map(|(p, c)| c.map(|c| (p.name.clone(), c)))
                .collect(),
        })
    }

    /// Phase 1: a pass with no draws changes nothing unless it clears.
    fn cull_empty_draw_lists(&self) -> Culling {
        self.passes
            .iter()
            .map(|p| match &p.kind {
                PassKind::Draw {
                    draws,
                    colour,
                    depth,
                    ..
                } if draws.is_empty()
                    && colour.load == LoadOp::Load
                    && depth.is_none_or(|d| d.load == LoadOp::Load) =>
                {
                    Some(CullReason::EmptyDrawList)
                }
                PassKind::Compute { dispatches, .. } if dispatches.is_empty() => {
                    Some(CullReason::EmptyDrawList)
                }
                _ => None,
            })
            .collect()
    }

    /// Phase 2: reachability, walking back from the side effects: `needed` holds the images whose
    /// current contents a later live pass reads.
    fn cull_unread_outputs(&self, culled: &mut Culling) {
        let mut needed: HashSet<ImageId> = HashSet::new();
        let mut needed_buffers: HashSet<BufferId> = HashSet::new();
        for (index, pass) in self.passes.iter().enumerate().rev() {
            if culled[index].is_some() {
                continue;
            }
            let (reads, writes) = reads_and_writes(pass);
            let (buffer_reads, buffer_writes) = buffer_reads_and_writes(pass);
            let live = pass.side_effect
                || matches!(
                    pass.kind,
                    PassKind::Readback { .. } | PassKind::Export { .. } | PassKind::HostRead { .. }
                )
                || writes.iter().any(|w| needed.contains(w))
                || buffer_writes.iter().any(|w| needed_buffers.contains(w));
            if !live {
                culled[index] = Some(CullReason::OutputUnused);
                continue;
            }
            for w in &writes {
                if redefines(pass, *w) {
                    needed.remove(w);
                }
            }
            needed.extend(reads);
            needed_buffers.extend(buffer_reads);
        }
    }

    /// Phase 3: every image a live pass reads was imported or written by an earlier live pass
    /// (an external image's contents before the frame are its owner's: never read).
    fn check_reads_before_writes(&self, culled: &Culling) -> Result<(), GraphError> {
        let mut defined: HashSet<ImageId> = self
            .images
            .iter()
            .enumerate()
            .filter(|(_, i)| i.origin == Origin::Imported)
            .map(|(n, _)| ImageId(n as u32))
            .collect();
        for (pass, _) in self.passes.iter().zip(culled).filter(|(_, c)| c.is_none()) {
            let (reads, writes) = reads_and_writes(pass);
            if let Some(r) = reads.iter().find(|r| !defined.contains(r)) {
                return Err(GraphError::ReadBeforeWrite {
                    pass: pass.name.clone(),
                    image: self.images[r.0 as usize].name.clone(),
                });
            }
            defined.extend(writes);
        }
        Ok(())
    }

    /// Phase 4: the live passes as steps: consecutive draw passes on the same attachments become
    /// one rendering instance, and each instance or readback gets the barriers its images need.
    fn schedule(&self, live: &[&Pass<D, P, C>]) -> Vec<Step<D, P, C>> {
        let mut state: Vec<ImageState> = self
            .images
            .iter()
            .map(|i| match i.origin {
                Origin::Frame => (Layout::Undefined, Access::None, false),
                Origin::Imported => (Layout::ShaderRead, Access::None, false),
                // The owner may have written it just before: its first use waits for that.
                Origin::External => (Layout::External, Access::External, true),
            })
            .collect();
        let mut buffers: Vec<BufferState> = self
            .buffers
            .iter()
            .map(|b| BufferState::of(b.origin))
            .collect();
        let mut use_buffers = |pass: &Pass<D, P, C>, barriers: &mut Vec<BufferBarrier>| {
            for (buffer, access) in buffer_uses(pass) {
                if let Some(state) = buffers.get_mut(buffer.0 as usize) {
                    state.use_by(buffer, access, barriers);
                }
            }
        };
        let mut steps: Vec<Step<D, P, C>> = Vec::with_capacity(live.len());
        let mut index = 0;
        while index < live.len() {
            let pass = live[index];
            match &pass.kind {
                // A copy out, or the hand-back of an external image: one step whose barrier
                // moves the image to where its next user wants it.
                PassKind::Readback { image, .. } | PassKind::Export { image } => {
                    let (layout, access) = match pass.kind {
                        PassKind::Export { .. } => (Layout::External, Access::External),
                        _ => (Layout::TransferSrc, Access::TransferRead),
                    };
                    let mut barriers = Vec::new();
                    transition(
                        &mut state,
                        &mut barriers,
                        *image,
                        layout,
                        access,
                        false,
                        false,
                    );
                    steps.push(Step {
                        pass: pass.clone(),
                        barriers,
                        buffer_barriers: Vec::new(),
                        begin: None,
                        end: false,
                    });
                    index += 1;
                }
                // Compute or transfer work, and the host's reads: a step of its own, outside
                // rendering, behind the barriers its buffers need.
                PassKind::Compute { .. } | PassKind::HostRead { .. } => {
                    let mut buffer_barriers = Vec::new();
                    use_buffers(pass, &mut buffer_barriers);
                    steps.push(Step {
                        pass: pass.clone(),
                        barriers: Vec::new(),
                        buffer_barriers,
                        begin: None,
                        end: false,
                    });
                    index += 1;
                }
                PassKind::Draw { .. } => {
                    let last = instance_end(live, index);
                    let group = &live[index..=last];
                    let mut instance = rendering_instance(group, &mut state);
                    // Every buffer the instance's draws read waits, once, on its first step.
                    let mut buffer_barriers = Vec::new();
                    for pass in group {
                        use_buffers(pass, &mut buffer_barriers);
                    }
                    buffer_barriers.sort_by_key(|b| b.buffer);
                    if let Some(first) = instance.first_mut() {
                        first.buffer_barriers = buffer_barriers;
                    }
                    steps.extend(instance);
                    index = last + 1;
                }
            }
        }
        steps
    }

    fn validate(&self) -> Result<(), GraphError> {
        let mut names = HashSet::new();
        for pass in &self.passes {
            if !names.insert(pass.name.as_str()) {
                return Err(GraphError::DuplicatePass(pass.name.clone()));
            }
            let image = |id: ImageId| {
                self.images
                    .get(id.0 as usize)
                    .ok_or_else(|| GraphError::UnknownResource {
                        pass: pass.name.clone(),
                        kind: "image",
                        index: id.0,
                    })
            };
            match &pass.kind {
                PassKind::Draw {
                    colour,
                    depth,
                    sampled,
                    storage,
                    ..
                } => {
                    let c = image(colour.image)?;
                    if c.format.is_depth() {
                        return Err(GraphError::BadAttachment {
                            pass: pass.name.clone(),
                            image: c.name.clone(),
                            role: "colour",
                            format: c.format,
                        });
                    }
                    if let Some(d) = depth {
                        let info = image(d.image)?;
                        if !info.format.is_depth() {
                            return Err(GraphError::BadAttachment {
                                pass: pass.name.clone(),
                                image: info.name.clone(),
                                role: "depth",
                                format: info.format,
                            });
                        }
                    }
                    for s in sampled {
                        image(*s)?;
                    }
                    if let Some(b) = storage.iter().find(|b| b.0 as usize >= self.buffers.len()) {
                        return Err(GraphError::UnknownResource {
                            pass: pass.name.clone(),
                            kind: "buffer",
                            index: b.0,
                        });
                    }
                }
                PassKind::Compute { .. } | PassKind::HostRead { .. } => {
                    let uses = buffer_uses(pass);
                    if let Some((b, _)) = uses
                        .iter()
                        .find(|(b, _)| b.0 as usize >= self.buffers.len())
                    {
                        return Err(GraphError::UnknownResource {
                            pass: pass.name.clone(),
                            kind: "buffer",
                            index: b.0,
                        });
                    }
                }
                PassKind::Export { image: i } => {
                    let info = image(*i)?;
                    if info.origin != Origin::External {
                        return Err(GraphError::NotExternal {
                            pass: pass.name.clone(),
                            image: info.name.clone(),
                        });
                    }
                }
                PassKind::Readback { image: i, buffer } => {
                    image(*i)?;
                    if buffer.0 as usize >= self.buffers.len() {
                        return Err(GraphError::UnknownResource {
                            pass: pass.name.clone(),
                            kind: "buffer",
                            index: buffer.0,
                        });
                    }
                }
            }
        }
        Ok(())
    }
}

/// The index of the last pass of the rendering instance that the draw pass `live[first]` begins:
/// the instance extends while the next pass uses the same attachments and loads them.
fn instance_end<D, P, C>(live: &[&Pass<D, P, C>], first: usize) -> usize {
    let PassKind::Draw { colour, depth, .. } = &live[first].kind else {
        return first;
    };
    let mut last = first;
    while let Some(next) = live.get(last + 1) {
        match &next.kind {
            PassKind::Draw {
                colour: c,
                depth: d,
                ..
            } if c.image == colour.image
                && c.load == LoadOp::Load
                && d.map(|d| d.image) == depth.map(|d| d.image)
                && d.is_none_or(|d| d.load == LoadOp::Load) =>
            {
                last += 1
            }
            _ => break,
        }
    }
    last
}

/// The steps of one rendering instance (`group`: consecutive draw passes on the same attachments):
/// its load and store ops, and the barriers its attachments and sampled images need, all on the
/// first step.
fn rendering_instance<D: Clone, P: Clone, C: Clone>(
    group: &[&Pass<D, P, C>],
    state: &mut [ImageState],
) -> Vec<Step<D, P, C>> {
    let PassKind::Draw { colour, depth, .. } = &group[0].kind else {
        return Vec::new();
    };
    // An attachment is stored when any pass of the instance stores it.
    let store = |stores: Vec<StoreOp>| {
        if stores.contains(&StoreOp::Store) {
            StoreOp::Store
        } else {
            StoreOp::DontCare
        }
    };
    let colour_store = store(
        group
            .iter()
            .filter_map(|p| match &p.kind {
                PassKind::Draw { colour, .. } => Some(colour.store),
                _ => None,
            })
            .collect(),
    );
    let depth_store = store(
        group
            .iter()
            .filter_map(|p| match &p.kind {
                PassKind::Draw { depth, .. } => depth.map(|d: DepthAttachment| d.store),
                _ => None,
            })
            .collect(),
    );
    let instance = RenderingInstance {
        colour: (colour.image, colour.load, colour_store),
        depth: depth.map(|d| (d.image, d.load, depth_store)),
    };
    let mut barriers = Vec::new();
    transition(
        state,
        &mut barriers,
        colour.image,
        Layout::ColourAttachment,
        Access::ColourAttachment,
        true,
        colour.load != LoadOp::Load,
    );
    if let Some(d) = depth {
        let writes = group.iter().any(|p| match &p.kind {
            PassKind::Draw { depth, .. } => depth.is_some_and(|d| d.write),
            _ => false,
        }) || d.load != LoadOp::Load;
        transition(
            state,
            &mut barriers,
            d.image,
            Layout::DepthAttachment,
            Access::DepthAttachment,
            writes,
            d.load != LoadOp::Load,
        );
    }
    let mut sampled_all: Vec<ImageId> = group
        .iter()
        .flat_map(|p| match &p.kind {
            PassKind::Draw { sampled, .. } => sampled.clone(),
            _ => Vec::new(),
        })
        .collect();
    sampled_all.sort();
    sampled_all.dedup();
    for s in sampled_all {
        transition(
            state,
            &mut barriers,
            s,
            Layout::ShaderRead,
            Access::FragmentSample,
            false,
            false,
        );
    }
    let last = group.len() - 1;
    group
        .iter()
        .enumerate()
        .map(|(offset, p)| Step {
            pass: (*p).clone(),
            barriers: if offset == 0 {
                std::mem::take(&mut barriers)
            } else {
                Vec::new()
            },
            buffer_barriers: Vec::new(),
            begin: (offset == 0).then_some(instance),
            end: offset == last,
        })
        .collect()
}

/// Records the barrier (if any) that moves `image` to `layout` for `access`.
fn transition(
    state: &mut [ImageState],
    barriers: &mut Vec<Barrier>,
    image: ImageId,
    layout: Layout,
    access: Access,
    writes: bool,
    discard: bool,
) {
    let (old_layout, old_access, old_wrote) = state[image.0 as usize];
    let hazard = old_access != Access::None && (old_wrote || writes);
    if old_layout != layout || hazard {
        barriers.push(Barrier {
            image,
            // An external image leaves the layout its owner said it is in, even when its
            // contents are discarded: the owner's word is what the recorded barrier must match.
            old_layout: if discard && old_layout != Layout::External {
                Layout::Undefined
            } else {
                old_layout
            },
            new_layout: layout,
            src: old_access,
            dst: access,
        });
    }
    state[image.0 as usize] = (layout, access, writes);
}

impl<D, P, C> fmt::Display for Plan<D, P, C> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:>3}  {:<28} {:>5}  {:<17} {:<4}  {:<10} {:<14} barriers",
            "#", "pass", "draws", "blend", "mask", "depth", "rendering"
        )?;
        for (n, step) in self.steps.iter().enumerate() {
            let (blend, mask, depth) = match &step.pass.kind {
                PassKind::Draw { colour, depth, .. } => (
                    colour.blend.to_string(),
                    colour.write_mask.to_string(),
                    match depth {
                        Some(d) => format!(
                            "{}{}",
                            match d.test {
                                Some(super::CompareOp::Less) => "<",
                                Some(super::CompareOp::LessOrEqual) => "<=",
                                None => "-",
                            },
                            if d.write { " write" } else { "" }
                        ),
                        None => "none".into(),
                    },
                ),
                PassKind::Readback { .. } => ("copy".into(), "-".into(), "-".into()),
                PassKind::Export { .. } => ("hand back".into(), "-".into(), "-".into()),
                PassKind::Compute { buffers, .. } => {
                    let transfer = buffers
                        .iter()
                        .all(|(_, a)| matches!(a, Access::TransferRead | Access::TransferWrite));
                    let kind = if transfer { "transfer" } else { "compute" };
                    (kind.into(), "-".into(), "-".into())
                }
                PassKind::HostRead { .. } => ("host read".into(), "-".into(), "-".into()),
            };
            let rendering = match (&step.begin, step.end) {
                (Some(instance), true) => format!("begin {}+end", load_name(instance.colour.1)),
                (Some(instance), false) => format!("begin {}", load_name(instance.colour.1)),
                (None, true) => "end".into(),
                (None, false) => "".into(),
            };
            let barriers: Vec<String> = step
                .barriers
                .iter()
                .map(|b| {
                    format!(
                        "{}: {}->{}",
                        self.images[b.image.0 as usize].name, b.old_layout, b.new_layout
                    )
                })
                .chain(step.buffer_barriers.iter().map(|b| {
                    let name = self
                        .buffers
                        .get(b.buffer.0 as usize)
                        .map_or("?", |i| &i.name);
                    format!("{name}: {}->{}", b.src.name(), b.dst.name())
                }))
                .collect();
            writeln!(
                f,
                "{:>3}  {:<28} {:>5}  {:<17} {:<4}  {:<10} {:<14} {}",
                n,
                step.pass.name,
                step.pass.draw_count(),
                blend,
                mask,
                depth,
                rendering,
                barriers.join(", ")
            )?;
        }
        for (name, reason) in &self.culled {
            writeln!(f, "  -  {name:<28} culled: {reason}")?;
        }
        Ok(())
    }
}

fn load_name(load: LoadOp) -> &'static str {
    match load {
        LoadOp::Load => "load",
        LoadOp::Clear(_) => "clear",
        LoadOp::DontCare => "dontcare",
    }
}
