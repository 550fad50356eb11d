//! Compute work as passes of a pass graph. A [`ComputeWork`] is a list of passes (a dispatch, a
//! fill, an update, a copy, a timestamp, the host's read), each naming the buffers it uses and
//! how ([`WorkShape`]), with the commands that record it. The frame graph declares a work's
//! passes among its own ([`declare`]), so the graph places every barrier between them and
//! between them and the lens passes that draw what they made, and `lensmap passes` lists them; a
//! work submitted on its own ([`submit`], the GPU tracer's read-back and timed tessellations)
//! goes through a graph of its own. Nothing here knows what the work computes: the GPU
//! tessellation declares its passes with a [`WorkBuilder`], the same way for a plan without a
//! device (a shape alone) and for a frame (with the commands).

use std::sync::atomic::{AtomicBool, Ordering};

use ash::vk;
use lensmap_shaders::EntryPoint;

use super::vulkan::vk_access;
use crate::{
    gpu::{Buffer, CommandRing, DescriptorSet, Gpu, GpuError, Pipeline, QueryPoolRef},
    graph::{Access, Graph, Pass, PassKind, Plan},
};

/// The bytes of push constants `constants`, to share among the dispatches that push them.
pub fn push_constants<T: bytemuck::Pod>(constants: &T) -> std::sync::Arc<[u8]> {
    bytemuck::bytes_of(constants).into()
}

/// A buffer of a work, by name: two works (or two passes) that name one buffer use one buffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorkBuffer {
    /// Its name in the plan.
    pub name: String,
}

/// What one pass of a work does, as the plan shows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WorkPassKind {
    /// A compute dispatch.
    Dispatch,
    /// A fill, an update or a copy.
    Transfer,
    /// A timestamp (or the reset of a query pool's timestamps): no buffer.
    Timestamp,
    /// The host reads buffers once the submission completed: no command, the barrier alone.
    HostRead,
}

/// One pass of a work.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorkPass {
    /// Its name in the plan, unique within the work.
    pub name: String,
    /// What it does.
    pub kind: WorkPassKind,
    /// The buffers it uses (indices into [`WorkShape::buffers`]) and how.
    pub uses: Vec<(usize, Access)>,
}

/// Compute commands by kind: those a work declares ([`ComputeCommands::declared`]), or those a
/// frame recorded ([`super::FrameTimings::compute`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ComputeCommands {
    /// Dispatches.
    pub dispatches: usize,
    /// Fills, updates and copies.
    pub transfers: usize,
    /// Timestamps and their resets.
    pub timestamps: usize,
}

impl ComputeCommands {
    /// The commands `shape`'s passes record (a host's read records none).
    pub fn declared(shape: &WorkShape) -> ComputeCommands {
        let mut counts = ComputeCommands::default();
        for pass in &shape.passes {
            counts.add(pass.kind);
        }
        counts
    }

    fn add(&mut self, kind: WorkPassKind) {
        match kind {
            WorkPassKind::Dispatch => self.dispatches += 1,
            WorkPassKind::Transfer => self.transfers += 1,
            WorkPassKind::Timestamp => self.timestamps += 1,
            WorkPassKind::HostRead => {}
        }
    }
}

impl std::ops::AddAssign for ComputeCommands {
    fn add_assign(&mut self, other: ComputeCommands) {
        self.dispatches += other.dispatches;
        self.transfers += other.transfers;
        self.timestamps += other.timestamps;
    }
}

/// A work's passes and buffers: all a plan needs of it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WorkShape {
    /// Its buffers.
    pub buffers: Vec<WorkBuffer>,
    /// Its passes, in the order they run.
    pub passes: Vec<WorkPass>,
}

/// How many workgroups a dispatch runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DispatchSize {
    /// A count known when recording.
    Groups(u32),
    /// The three words at byte `offset` of buffer `buffer` (of the work), which an earlier pass
    /// wrote.
    Indirect {
        /// The work's buffer.
        buffer: usize,
        /// Byte offset of the arguments.
        offset: u64,
    },
}

/// A copy between two of a work's buffers: (source offset, destination offset, bytes).
pub type CopyRegion = (u64, u64, u64);

/// What records one pass of a work.
#[derive(Clone, Debug)]
pub enum Command {
    /// A compute dispatch of `pipeline` with its set 0 and push constants.
    Dispatch {
        /// The pipeline and its layout.
        pipeline: Pipeline,
        /// Its set 0.
        set: DescriptorSet,
        /// Its push constants' bytes (shared by the dispatches that push the same).
        constants: std::sync::Arc<[u8]>,
        /// Its size.
        size: DispatchSize,
    },
    /// Writes `words` at the start of the work's buffer `buffer`.
    Update {
        /// The work's buffer.
        buffer: usize,
        /// The words.
        words: Vec<u32>,
    },
    /// Fills the first `bytes` of the work's buffer `buffer` (the whole buffer: `None`) with
    /// `value`.
    Fill {
        /// The work's buffer.
        buffer: usize,
        /// Bytes filled (a multiple of 4).
        bytes: Option<u64>,
        /// The word written.
        value: u32,
    },
    /// Copies `regions` from buffer `from` to buffer `to` (the work's).
    Copy {
        /// The source.
        from: usize,
        /// The destination.
        to: usize,
        /// The regions.
        regions: Vec<CopyRegion>,
    },
    /// Resets queries 0 to `count` of `pool`.
    ResetTimestamps {
        /// The pool.
        pool: QueryPoolRef,
        /// Queries reset.
        count: u32,
    },
    /// Writes timestamp `query` of `pool` once every command before it is done.
    Timestamp {
        /// The pool.
        pool: QueryPoolRef,
        /// The query.
        query: u32,
    },
    /// The host's read: records nothing.
    HostRead,
}

/// Compute work: its shape, its buffers' handles and the commands of its passes. It is
/// recorded once: by the first frame that draws what it makes, or by [`submit`].
#[derive(Debug)]
pub struct ComputeWork {
    /// Its passes and buffers.
    pub shape: std::sync::Arc<WorkShape>,
    /// Per buffer of the shape, its handle.
    handles: Vec<vk::Buffer>,
    /// Per pass of the shape, its command.
    commands: Vec<Command>,
    /// Whether a submission recorded it (it runs once).
    recorded: AtomicBool,
}

impl ComputeWork {
    /// Whether no submission recorded it yet.
    pub fn pending(&self) -> bool {
        !self.recorded.load(Ordering::Relaxed)
    }

    /// Notes that a submission recorded it.
    pub(crate) fn submitted(&self) {
        self.recorded.store(true, Ordering::Relaxed);
    }
}

/// Declares a work pass by pass, its buffers by name. Made with [`WorkBuilder::planned`], it
/// keeps the shape alone (for a plan without a device); with [`WorkBuilder::bound`], each pass's
/// command too (every buffer must then be given its handle); with [`WorkBuilder::bound_to`], the
/// commands of a work whose shape an earlier declaration made (its names and uses are not made
/// again: a frame's tessellation declares the same ~100 passes every frame).
pub struct WorkBuilder {
    shape: WorkShape,
    /// The shape declared before, which the passes must match.
    known: Option<std::sync::Arc<WorkShape>>,
    /// A pass or buffer that did not match `known`.
    mismatch: Option<String>,
    handles: Vec<Option<vk::Buffer>>,
    commands: Option<Vec<Command>>,
}

/// A dispatch being declared: its entry point, set 0 (binding `b` is the work's buffer
/// `buffers[b]`, `None` for a binding that is no buffer), size and command.
pub struct Dispatch<'a, E> {
    /// The pass's name (made only where the shape is).
    pub name: &'a dyn std::fmt::Display,
    /// The entry point.
    pub entry: E,
    /// Per binding of set 0, the work's buffer it points at.
    pub buffers: &'a [Option<usize>],
    /// Its size.
    pub size: DispatchSize,
    /// Its pipeline, set and push constants, for a bound work.
    pub bound: Option<(Pipeline, DescriptorSet, std::sync::Arc<[u8]>)>,
}

impl WorkBuilder {
    /// A builder of a work's shape alone.
    pub fn planned() -> WorkBuilder {
        WorkBuilder {
            shape: WorkShape::default(),
            known: None,
            mismatch: None,
            handles: Vec::new(),
            commands: None,
        }
    }

    /// A builder of a work to record.
    pub fn bound() -> WorkBuilder {
        WorkBuilder {
            commands: Some(Vec::new()),
            ..WorkBuilder::planned()
        }
    }

    /// A builder of a work to record whose shape is `shape` (made by an earlier declaration of
    /// the same passes): [`WorkBuilder::finish`] fails where the passes declared differ from it.
    pub fn bound_to(shape: std::sync::Arc<WorkShape>) -> WorkBuilder {
        WorkBuilder {
            handles: vec![None; shape.buffers.len()],
            commands: Some(Vec::with_capacity(shape.passes.len())),
            known: Some(shape),
            ..WorkBuilder::planned()
        }
    }

    /// The work's buffer named `name` (declared at its first mention), bound to `buffer`.
    pub fn buffer(&mut self, name: &str, buffer: Option<&Buffer>) -> usize {
        let buffers = match &self.known {
            Some(known) => &known.buffers,
            None => &self.shape.buffers,
        };
        if let Some(at) = buffers.iter().position(|b| b.name == name) {
            if self.handles[at].is_none() {
                self.handles[at] = buffer.map(|b| b.handle);
            }
            return at;
        }
        if self.known.is_some() {
            self.mismatch
                .get_or_insert_with(|| format!("buffer {name} is not in the known shape"));
            return 0;
        }
        self.shape.buffers.push(WorkBuffer { name: name.into() });
        self.handles.push(buffer.map(|b| b.handle));
        self.shape.buffers.len() - 1
    }

    /// Adds a pass of `kind` using `uses`, recorded by `command` (made only for a bound work;
    /// the name and the uses only where the shape is made).
    pub fn pass(
        &mut self,
        name: impl std::fmt::Display,
        kind: WorkPassKind,
        uses: impl FnOnce() -> Vec<(usize, Access)>,
        command: impl FnOnce() -> Command,
    ) {
        match &self.known {
            Some(known) => {
                let at = self.commands.as_ref().map_or(0, Vec::len);
                // The kind always; the name and the uses too in a debug build (the tests'), which
                // is what making them costs a frame.
                let differs = match known.passes.get(at) {
                    Some(pass) if cfg!(debug_assertions) => {
                        pass.kind != kind || pass.name != name.to_string() || pass.uses != uses()
                    }
                    Some(pass) => pass.kind != kind,
                    None => true,
                };
                if differs {
                    self.mismatch.get_or_insert_with(|| {
                        format!("pass {at} ({name}) differs from the known shape")
                    });
                }
            }
            None => self.shape.passes.push(WorkPass {
                name: name.to_string(),
                kind,
                uses: uses(),
            }),
        }
        if let Some(commands) = &mut self.commands {
            commands.push(command());
        }
    }

    /// Adds a dispatch: the buffers it uses are those its entry point reads or writes (as
    /// naga's analysis of the shader says), and an indirect one's arguments.
    pub fn dispatch<E: EntryPoint>(&mut self, dispatch: Dispatch<'_, E>) {
        let Dispatch {
            name,
            entry,
            buffers,
            size,
            bound,
        } = dispatch;
        let uses = || {
            let mut uses: Vec<(usize, Access)> = entry
                .uses()
                .iter()
                .filter(|u| u.group == 0)
                .filter_map(|u| {
                    let buffer = (*buffers.get(u.binding as usize)?)?;
                    let access = match u.access {
                        lensmap_shaders::Access::Read => Access::ComputeRead,
                        lensmap_shaders::Access::Write | lensmap_shaders::Access::ReadWrite => {
                            Access::ComputeWrite
                        }
                    };
                    Some((buffer, access))
                })
                .collect();
            if let DispatchSize::Indirect { buffer, .. } = size {
                uses.push((buffer, Access::IndirectRead));
            }
            uses
        };
        self.pass(name, WorkPassKind::Dispatch, uses, || {
            let (pipeline, set, constants) = bound.unwrap_or_default();
            Command::Dispatch {
                pipeline,
                set,
                constants,
                size,
            }
        });
    }

    /// The shape declared (the known one, for [`WorkBuilder::bound_to`]).
    pub fn shape(self) -> WorkShape {
        match self.known {
            Some(known) => (*known).clone(),
            None => self.shape,
        }
    }

    /// The work declared; an error where it was not bound, or a buffer has no handle.
    pub fn finish(self) -> Result<ComputeWork, GpuError> {
        let unbound = |what: String| GpuError::Internal(format!("compute work: {what}"));
        if let Some(mismatch) = self.mismatch {
            return Err(unbound(mismatch));
        }
        let commands = self
            .commands
            .ok_or_else(|| unbound("declared as a plan alone; it has no commands".into()))?;
        let shape = match self.known {
            Some(known) if known.passes.len() == commands.len() => known,
            Some(known) => {
                return Err(unbound(format!(
                    "{} passes declared against a known shape of {}",
                    commands.len(),
                    known.passes.len()
                )));
            }
            None => std::sync::Arc::new(self.shape),
        };
        let handles = self
            .handles
            .iter()
            .zip(&shape.buffers)
            .map(|(handle, buffer)| {
                handle.ok_or_else(|| unbound(format!("buffer {} has no handle", buffer.name)))
            })
            .collect::<Result<_, _>>()?;
        Ok(ComputeWork {
            shape,
            handles,
            commands,
            recorded: AtomicBool::new(false),
        })
    }
}

/// Declares the passes of a work of shape `shape` in `graph`, each named `prefix` + its name and
/// recorded by the payload `payload(pass)`, its buffers the graph's of the same name (declared
/// kept, at their first mention). Every pass is a side effect: the work runs whether or not a
/// pass of the graph reads what it writes.
pub fn declare<D, P, C: Clone>(
    graph: &mut Graph<D, P, C>,
    shape: &WorkShape,
    prefix: &str,
    category: C,
    payload: impl Fn(usize) -> D,
) {
    let ids: Vec<_> = shape
        .buffers
        .iter()
        .map(|b| {
            graph
                .find_buffer(&b.name)
                .unwrap_or_else(|| graph.kept_buffer(&b.name, 0))
        })
        .collect();
    for (index, pass) in shape.passes.iter().enumerate() {
        let buffers: Vec<_> = pass.uses.iter().map(|&(b, a)| (ids[b], a)).collect();
        let kind = match pass.kind {
            WorkPassKind::HostRead => PassKind::HostRead {
                buffers: buffers.into_iter().map(|(b, _)| b).collect(),
            },
            _ => PassKind::Compute {
                dispatches: vec![payload(index)],
                buffers,
            },
        };
        graph.add_pass(Pass {
            name: format!("{prefix}{}", pass.name),
            category: category.clone(),
            side_effect: true,
            kind,
        });
    }
}

/// Records pass `pass` of `work` into `cb` (its barriers are the plan's, recorded before).
/// `recorded` counts the command.
pub(crate) fn record(
    gpu: &Gpu,
    cb: vk::CommandBuffer,
    work: &ComputeWork,
    pass: usize,
    recorded: &mut ComputeCommands,
) {
    let Some(command) = work.commands.get(pass) else {
        return;
    };
    recorded.add(match command {
        Command::Dispatch { .. } => WorkPassKind::Dispatch,
        Command::Update { .. } | Command::Fill { .. } | Command::Copy { .. } => {
            WorkPassKind::Transfer
        }
        Command::ResetTimestamps { .. } | Command::Timestamp { .. } => WorkPassKind::Timestamp,
        Command::HostRead => WorkPassKind::HostRead,
    });
    let device = gpu.device();
    let buffer = |b: usize| work.handles.get(b).copied().unwrap_or_default();
    // SAFETY: `cb` is recording outside any rendering instance; every handle the work names is
    // kept alive by its owner until the submissions that recorded it completed; the plan's
    // barriers order this command after the ones it depends on.
    unsafe {
        match command {
            Command::Dispatch {
                pipeline,
                set,
                constants,
                size,
            } => {
                device.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline.pipeline);
                device.cmd_bind_descriptor_sets(
                    cb,
                    vk::PipelineBindPoint::COMPUTE,
                    pipeline.layout,
                    0,
                    &[set.0],
                    &[],
                );
                if !constants.is_empty() {
                    device.cmd_push_constants(
                        cb,
                        pipeline.layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        constants,
                    );
                }
                match *size {
                    DispatchSize::Groups(groups) => device.cmd_dispatch(cb, groups, 1, 1),
                    DispatchSize::Indirect { buffer: b, offset } => {
                        device.cmd_dispatch_indirect(cb, buffer(b), offset)
                    }
                }
            }
            Command::Update { buffer: b, words } => {
                device.cmd_update_buffer(cb, buffer(*b), 0, bytemuck::cast_slice(words))
            }
            Command::Fill {
                buffer: b,
                bytes,
                value,
            } => device.cmd_fill_buffer(cb, buffer(*b), 0, bytes.unwrap_or(vk::WHOLE_SIZE), *value),
            Command::Copy { from, to, regions } => {
                let regions: Vec<vk::BufferCopy> = regions
                    .iter()
                    .filter(|(_, _, bytes)| *bytes > 0)
                    .map(|&(src_offset, dst_offset, size)| vk::BufferCopy {
                        src_offset,
                        dst_offset,
                        size,
                    })
                    .collect();
                if !regions.is_empty() {
                    device.cmd_copy_buffer(cb, buffer(*from), buffer(*to), &regions);
                }
            }
            Command::ResetTimestamps { pool, count } => {
                device.cmd_reset_query_pool(cb, pool.0, 0, *count)
            }
            Command::Timestamp { pool, query } => device.cmd_write_timestamp2(
                cb,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                pool.0,
                *query,
            ),
            Command::HostRead => {}
        }
    }
}

/// Records a step's buffer barriers (`(src, dst)` accesses) as one pipeline barrier of global
/// memory barriers, each pair once.
pub(crate) fn memory_barriers(
    gpu: &Gpu,
    cb: vk::CommandBuffer,
    accesses: impl IntoIterator<Item = (Access, Access)>,
) {
    let mut pairs: Vec<(Access, Access)> = Vec::new();
    for pair in accesses {
        if !pairs.contains(&pair) {
            pairs.push(pair);
        }
    }
    if pairs.is_empty() {
        return;
    }
    let barriers: Vec<vk::MemoryBarrier2> = pairs
        .iter()
        .map(|&(src, dst)| {
            let (src_stage, src_access) = vk_access(src);
            let (dst_stage, dst_access) = vk_access(dst);
            vk::MemoryBarrier2::default()
                .src_stage_mask(src_stage)
                .src_access_mask(src_access)
                .dst_stage_mask(dst_stage)
                .dst_access_mask(dst_access)
        })
        .collect();
    // SAFETY: `cb` is recording; a global memory barrier names no resource.
    unsafe {
        gpu.device().cmd_pipeline_barrier2(
            cb,
            &vk::DependencyInfo::default().memory_barriers(&barriers),
        )
    };
}

/// The plan of `works` run on their own, one after another: their passes with the barriers
/// between them.
pub fn plan(
    works: &[&ComputeWork],
) -> Result<Plan<(usize, usize), (), ()>, crate::graph::GraphError> {
    let mut graph: Graph<(usize, usize), (), ()> = Graph::new();
    for (index, work) in works.iter().enumerate() {
        declare(
            &mut graph,
            &work.shape,
            &format!("work{index}/"),
            (),
            |pass| (index, pass),
        );
    }
    graph.compile()
}

/// Records `works` into one command buffer of `ring` with the barriers their plan places, and
/// submits it without waiting; returns the value its completion signals.
pub fn submit(gpu: &Gpu, ring: &mut CommandRing, works: &[&ComputeWork]) -> Result<u64, GpuError> {
    let plan = plan(works).map_err(|error| GpuError::Internal(format!("compute work: {error}")))?;
    // A submission of its own: what it records is its plan's, counted by no frame.
    let mut recorded = ComputeCommands::default();
    let value = ring.submit(gpu, |cb| {
        for step in &plan.steps {
            memory_barriers(gpu, cb, step.buffer_barriers.iter().map(|b| (b.src, b.dst)));
            if let PassKind::Compute { dispatches, .. } = &step.pass.kind {
                for &(work, pass) in dispatches {
                    record(gpu, cb, works[work], pass, &mut recorded);
                }
            }
        }
        Ok(())
    })?;
    for work in works {
        work.submitted();
    }
    Ok(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Declares buffer `b` and one pass of each of `kinds` using it.
    fn declare(builder: &mut WorkBuilder, buffer: &str, kinds: &[WorkPassKind]) {
        let b = builder.buffer(buffer, None);
        for (i, &kind) in kinds.iter().enumerate() {
            builder.pass(
                format_args!("pass {i}"),
                kind,
                || vec![(b, Access::TransferWrite)],
                || Command::HostRead,
            );
        }
    }

    #[test]
    fn a_work_declared_against_a_known_shape_must_declare_that_shape() {
        use WorkPassKind::{Dispatch, Transfer};
        let mut planned = WorkBuilder::planned();
        declare(&mut planned, "b", &[Transfer, Dispatch]);
        let shape = std::sync::Arc::new(planned.shape());
        assert_eq!(shape.passes.len(), 2);
        assert_eq!(shape.passes[1].name, "pass 1");
        let finish = |buffer: &str, kinds: &[WorkPassKind]| {
            let mut builder = WorkBuilder::bound_to(shape.clone());
            declare(&mut builder, buffer, kinds);
            builder.finish().unwrap_err().to_string()
        };
        // The same passes: only the buffer's missing handle (no device here) is wrong.
        assert!(finish("b", &[Transfer, Dispatch]).contains("buffer b has no handle"));
        assert!(finish("b", &[Transfer, Transfer]).contains("pass 1 (pass 1) differs"));
        assert!(finish("b", &[Transfer]).contains("1 passes declared against a known shape of 2"));
        assert!(finish("c", &[Transfer, Dispatch]).contains("buffer c is not in the known shape"));
        // A pass that uses another buffer: seen in a debug build.
        if cfg!(debug_assertions) {
            let mut builder = WorkBuilder::bound_to(shape.clone());
            declare(&mut builder, "b", &[Transfer]);
            let other = builder.buffer("b", None);
            builder.pass(
                "pass 1",
                Dispatch,
                || vec![(other, Access::ComputeRead)],
                || Command::HostRead,
            );
            let error = builder.finish().unwrap_err().to_string();
            assert!(error.contains("pass 1 (pass 1) differs"), "{error}");
        }
    }
}
