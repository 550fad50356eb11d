//! Compute work's Vulkan objects, owned: the pipelines of a shader's entry points over one set
//! layout and push-constant range ([`ComputePipelines`], typed by the shader's generated entry
//! enum in [`Kernels`]), timestamp query pools ([`QueryPool`]), and a ring of command buffers
//! from a pool of their own with the timeline that says which submissions completed
//! ([`CommandRing`]). Each destroys what it made, so no error path destroys anything by hand.
//! [`Pipeline`] and [`QueryPoolRef`] are the handles recording takes.

use std::{marker::PhantomData, sync::Arc};

use ash::vk;
use lensmap_shaders::{EntryPoint, Shader};

use super::{
    Gpu, GpuError, Semaphores, Timeline, VkContext,
    context::Shared,
    descriptors::{Binding, SetLayout},
};

/// A compute pipeline and its layout, for recording (null by default: a planned dispatch's).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pipeline {
    pub(crate) pipeline: vk::Pipeline,
    pub(crate) layout: vk::PipelineLayout,
}

/// The compute pipelines of some entry points over one set layout and push constants, owned.
pub struct ComputePipelines {
    shared: Arc<Shared>,
    set_layout: SetLayout,
    layout: vk::PipelineLayout,
    pipelines: Vec<vk::Pipeline>,
}

impl Drop for ComputePipelines {
    fn drop(&mut self) {
        // SAFETY: the owner waited for every submission that used them; null handles (a
        // failed construction) are ignored by vkDestroy*. The set layout drops after.
        unsafe {
            for &pipeline in &self.pipelines {
                self.shared.device.destroy_pipeline(pipeline, None);
            }
            self.shared
                .device
                .destroy_pipeline_layout(self.layout, None);
        }
    }
}

impl ComputePipelines {
    /// The pipelines of `shaders` (in order), binding `set` at set 0 and `push_bytes` bytes of
    /// push constants.
    pub(crate) fn new(
        gpu: &Gpu,
        shaders: &[Shader],
        set: Vec<Binding>,
        push_bytes: u32,
    ) -> Result<ComputePipelines, GpuError> {
        let mut made = ComputePipelines {
            shared: gpu.shared.clone(),
            set_layout: SetLayout::new(gpu, set)?,
            layout: vk::PipelineLayout::null(),
            pipelines: Vec::with_capacity(shaders.len()),
        };
        let push = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: push_bytes,
        }];
        let set_layouts = [made.set_layout.handle];
        // SAFETY: the create info lives until return; Drop destroys the layout.
        made.layout = unsafe {
            gpu.device().create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&set_layouts)
                    .push_constant_ranges(&push[..usize::from(push_bytes > 0)]),
                None,
            )
        }
        .vk("vkCreatePipelineLayout")?;
        for shader in shaders {
            let pipeline = gpu.create_compute_pipeline(shader, made.layout)?;
            made.pipelines.push(pipeline);
        }
        Ok(made)
    }

    /// Pipeline `index` of the shaders it was made of.
    pub fn pipeline(&self, index: usize) -> Pipeline {
        Pipeline {
            pipeline: self.pipelines.get(index).copied().unwrap_or_default(),
            layout: self.layout,
        }
    }

    /// Its set 0's layout.
    pub(crate) fn set_layout(&self) -> &SetLayout {
        &self.set_layout
    }

    /// Whether they were made on `gpu`'s device.
    pub fn made_on(&self, gpu: &Gpu) -> bool {
        self.shared.device.handle() == gpu.device().handle()
    }
}

/// The pipelines of every entry point of one shader file (`E`, its generated entry enum) over
/// its generated set 0 and push constants `C`.
pub struct Kernels<E: EntryPoint> {
    pipelines: ComputePipelines,
    _entries: PhantomData<E>,
}

impl<E: EntryPoint> Kernels<E> {
    /// Every entry point of `E`'s file, binding `set` (its generated `SETS[0]`) with push
    /// constants `C`.
    pub fn new<C>(gpu: &Gpu, set: &[lensmap_shaders::Binding]) -> Result<Kernels<E>, GpuError> {
        let shaders: Vec<Shader> = E::ALL.iter().map(|e| e.shader()).collect();
        Ok(Kernels {
            pipelines: ComputePipelines::new(
                gpu,
                &shaders,
                Binding::of_shader(set),
                std::mem::size_of::<C>() as u32,
            )?,
            _entries: PhantomData,
        })
    }

    /// The pipeline of `entry`.
    pub fn pipeline(&self, entry: E) -> Pipeline {
        self.pipelines.pipeline(entry.index())
    }

    /// Its set 0's layout.
    pub(crate) fn set_layout(&self) -> &SetLayout {
        self.pipelines.set_layout()
    }
}

/// A timestamp query pool, owned.
pub struct QueryPool {
    shared: Arc<Shared>,
    handle: vk::QueryPool,
    count: u32,
}

/// A query pool's handle, for recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueryPoolRef(pub(crate) vk::QueryPool);

impl Drop for QueryPool {
    fn drop(&mut self) {
        // SAFETY: made on this device; the submission that used it was waited for.
        unsafe { self.shared.device.destroy_query_pool(self.handle, None) };
    }
}

impl QueryPool {
    /// A pool of `count` timestamp queries.
    pub fn timestamps(gpu: &Gpu, count: u32) -> Result<QueryPool, GpuError> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(count);
        // SAFETY: valid create info; Drop destroys the pool.
        let handle =
            unsafe { gpu.device().create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
        Ok(QueryPool {
            shared: gpu.shared.clone(),
            handle,
            count,
        })
    }

    /// Its handle, for recording.
    pub fn handle(&self) -> QueryPoolRef {
        QueryPoolRef(self.handle)
    }

    /// Its queries.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// Every query's ticks, waiting for them (the caller masks them to the queue's valid bits).
    pub fn ticks(&self) -> Result<Vec<u64>, GpuError> {
        let mut ticks = vec![0u64; self.count as usize];
        // SAFETY: every query was written by a submission the caller waits for (WAIT).
        unsafe {
            self.shared.device.get_query_pool_results(
                self.handle,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("vkGetQueryPoolResults")?;
        Ok(ticks)
    }
}

/// Command buffers from a pool of their own, reused round robin once their last submission
/// completed, and the timeline that says which did; with the last submission of another timeline
/// (a renderer's frames) that recorded work naming what the ring's owner keeps.
pub struct CommandRing {
    shared: Arc<Shared>,
    pool: vk::CommandPool,
    timeline: Timeline,
    ring: Vec<(vk::CommandBuffer, u64)>,
    /// The value the last submission signals.
    submitted: u64,
    /// Another timeline whose submissions recorded the owner's work, and the last value.
    external: Option<(Arc<Timeline>, u64)>,
    /// Submissions kept in flight before the oldest is waited for.
    in_flight: usize,
}

impl Drop for CommandRing {
    fn drop(&mut self) {
        let _ = self.wait_all();
        // SAFETY: every submission of its command buffers completed (or the device is lost);
        // they are freed with the pool.
        unsafe { self.shared.device.destroy_command_pool(self.pool, None) };
    }
}

impl CommandRing {
    /// A ring of up to `in_flight` command buffers on `gpu`'s queue.
    pub fn new(gpu: &Gpu, in_flight: usize) -> Result<CommandRing, GpuError> {
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(gpu.vulkan().queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let timeline = Timeline::new(gpu)?;
        // SAFETY: a valid create info for the queue's family; destroyed in Drop.
        let pool =
            unsafe { gpu.device().create_command_pool(&info, None) }.vk("vkCreateCommandPool")?;
        Ok(CommandRing {
            shared: gpu.shared.clone(),
            pool,
            timeline,
            ring: Vec::new(),
            submitted: 0,
            external: None,
            in_flight: in_flight.max(1),
        })
    }

    /// Records `record` and submits it without waiting; returns the value its completion
    /// signals.
    pub(crate) fn submit(
        &mut self,
        gpu: &Gpu,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
    ) -> Result<u64, GpuError> {
        let slot = (self.submitted as usize) % self.in_flight;
        if self.ring.len() <= slot {
            let info = vk::CommandBufferAllocateInfo::default()
                .command_pool(self.pool)
                .level(vk::CommandBufferLevel::PRIMARY)
                .command_buffer_count(1);
            // SAFETY: the pool belongs to this device and is used by this ring's owner alone.
            let made = unsafe { self.shared.device.allocate_command_buffers(&info) }
                .vk("vkAllocateCommandBuffers")?;
            self.ring.push((made[0], 0));
        }
        let (cb, last) = self.ring[slot];
        self.timeline.wait(last)?;
        let value = self.submitted + 1;
        gpu.record_submit(
            cb,
            record,
            Semaphores {
                timeline: &self.timeline,
                value,
                waits: &[],
                signals: &[],
            },
        )?;
        self.submitted = value;
        self.ring[slot].1 = value;
        Ok(value)
    }

    /// Blocks until submission `value` completed.
    pub fn wait(&self, value: u64) -> Result<(), GpuError> {
        self.timeline.wait(value)
    }

    /// Blocks until every submission completed, the other timeline's that recorded the
    /// owner's work included.
    pub fn wait_all(&self) -> Result<(), GpuError> {
        if let Some((timeline, value)) = &self.external {
            timeline.wait(*value)?;
        }
        self.timeline.wait(self.submitted)
    }

    /// Notes that submission `value` of `timeline` recorded the owner's work: [`Self::wait_all`]
    /// waits for it too.
    pub fn used_until(&mut self, timeline: Arc<Timeline>, value: u64) {
        match &mut self.external {
            Some((held, last)) if Arc::ptr_eq(held, &timeline) => *last = (*last).max(value),
            other => {
                // Another timeline (a new renderer): the old one's work must be done first.
                if let Some((held, last)) = other.take() {
                    let _ = held.wait(last);
                }
                *other = Some((timeline, value));
            }
        }
    }
}
