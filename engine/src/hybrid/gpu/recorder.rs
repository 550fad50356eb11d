//! Recording the GPU tessellation's passes ([`super::tessellate`]): binding each pass with its
//! set and constants, dispatching it over a count the previous pass wrote, the barriers between
//! them, and the optional timestamps that split the device's time between the stages.

use ash::vk;
use lensmap_shaders::TessellateConstants;

use super::tessellate::{GpuStageMs, TessellationPasses, pass};
use super::{Dependency, WORKGROUP, barrier};
use crate::gpu::{Gpu, GpuError, VkContext};

/// A compute → compute (and indirect-argument) dependency: every pass reads what the one before
/// wrote, and the dispatch sizes it wrote.
pub(super) const COMPUTE_TO_COMPUTE: Dependency = (
    vk::PipelineStageFlags2::COMPUTE_SHADER,
    vk::AccessFlags2::SHADER_STORAGE_WRITE,
    vk::PipelineStageFlags2::from_raw(
        vk::PipelineStageFlags2::COMPUTE_SHADER.as_raw()
            | vk::PipelineStageFlags2::DRAW_INDIRECT.as_raw(),
    ),
    vk::AccessFlags2::from_raw(
        vk::AccessFlags2::SHADER_STORAGE_READ.as_raw()
            | vk::AccessFlags2::SHADER_STORAGE_WRITE.as_raw()
            | vk::AccessFlags2::INDIRECT_COMMAND_READ.as_raw(),
    ),
);

/// A timestamp query pool for one tessellation: four queries per level (its trace pass, then its
/// split passes, each begun and ended), then four for the T-junction removal and texgen.
pub(super) struct Timestamps {
    device: ash::Device,
    pub(super) pool: vk::QueryPool,
    levels: u32,
}

impl Drop for Timestamps {
    fn drop(&mut self) {
        // SAFETY: made on this device; the submission that used it was waited for.
        unsafe { self.device.destroy_query_pool(self.pool, None) };
    }
}

impl Timestamps {
    pub(super) fn new(gpu: &Gpu, levels: u32) -> Result<Timestamps, GpuError> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(4 * levels + 4);
        // SAFETY: valid create info; Drop destroys the pool.
        let pool =
            unsafe { gpu.device().create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
        Ok(Timestamps {
            device: gpu.device().clone(),
            pool,
            levels,
        })
    }

    /// Writes timestamp `query` once every command before it is done.
    ///
    /// # Safety
    /// `cb` is recording.
    pub(super) unsafe fn write(&self, cb: vk::CommandBuffer, query: u32) {
        // SAFETY: as the caller says; the pool was reset in this command buffer.
        unsafe {
            self.device.cmd_write_timestamp2(
                cb,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                query,
            )
        };
    }

    /// The stages' device time from the written timestamps (`valid_bits` of each, `period` ns a
    /// tick).
    pub(super) fn read(&self, valid_bits: u32, period: f32) -> Result<GpuStageMs, GpuError> {
        let mut ticks = vec![0u64; 4 * self.levels as usize + 4];
        // SAFETY: every query was written by the submission waited for.
        unsafe {
            self.device.get_query_pool_results(
                self.pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("vkGetQueryPoolResults")?;
        let mask = if valid_bits >= 64 {
            u64::MAX
        } else {
            (1u64 << valid_bits) - 1
        };
        let ms = |from: usize| {
            (ticks[from + 1].wrapping_sub(ticks[from]) & mask) as f64 * f64::from(period) * 1e-6
        };
        let mut stages = GpuStageMs::default();
        for level in 0..self.levels as usize {
            stages.trace += ms(4 * level);
            stages.tessellation += ms(4 * level + 2);
        }
        let last = 4 * self.levels as usize;
        stages.tessellation += ms(last);
        stages.texgen = ms(last + 2);
        Ok(stages)
    }
}

/// Records the tessellation's passes into one command buffer.
pub(super) struct Recorder<'a> {
    pub(super) device: &'a ash::Device,
    pub(super) cb: vk::CommandBuffer,
    pub(super) passes: &'a TessellationPasses,
    pub(super) set: vk::DescriptorSet,
    pub(super) constants: &'a TessellateConstants,
    pub(super) control: vk::Buffer,
    pub(super) timestamps: Option<&'a Timestamps>,
    /// Whether the tessellation's set and constants are bound (pipelines of one layout keep
    /// them; the tracer's pass between levels, of another layout, does not).
    pub(super) bound: std::cell::Cell<bool>,
}

impl Recorder<'_> {
    /// Writes timestamp `query`, where the queue has timestamps.
    ///
    /// # Safety
    /// `cb` is recording.
    pub(super) unsafe fn stamp(&self, query: u32) {
        if let Some(timestamps) = self.timestamps {
            // SAFETY: as the caller says.
            unsafe { timestamps.write(self.cb, query) };
        }
    }

    /// Binds pass `name`, and the tessellation's set and constants unless they are bound.
    ///
    /// # Safety
    /// `cb` is recording.
    pub(super) unsafe fn bind(&self, name: &str) {
        let (device, cb, layout) = (self.device, self.cb, self.passes.layout);
        // SAFETY: the caller says `cb` is recording; the pipeline, set and layout are live.
        unsafe {
            device.cmd_bind_pipeline(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                self.passes.pipelines[pass(name)],
            );
            if self.bound.replace(true) {
                return;
            }
            device.cmd_bind_descriptor_sets(
                cb,
                vk::PipelineBindPoint::COMPUTE,
                layout,
                0,
                &[self.set],
                &[],
            );
            device.cmd_push_constants(
                cb,
                layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                bytemuck::bytes_of(self.constants),
            );
        }
    }

    /// Dispatches the bound pass with the arguments at control word `word`, then a barrier.
    ///
    /// # Safety
    /// `cb` is recording and a compute pipeline is bound.
    pub(super) unsafe fn dispatch_indirect(&self, word: usize) {
        // SAFETY: as the caller says; the control buffer holds the arguments.
        unsafe {
            self.device
                .cmd_dispatch_indirect(self.cb, self.control, 4 * word as u64);
            barrier(self.device, self.cb, COMPUTE_TO_COMPUTE);
        }
    }

    /// Pass `name` over the elements counted at control word `word`.
    ///
    /// # Safety
    /// `cb` is recording.
    pub(super) unsafe fn indirect(&self, name: &str, word: usize) {
        // SAFETY: as the caller says.
        unsafe {
            self.bind(name);
            self.dispatch_indirect(word);
        }
    }

    /// Pass `name` over `n` elements (a count known when recording).
    ///
    /// # Safety
    /// `cb` is recording.
    pub(super) unsafe fn groups(&self, name: &str, n: u32) {
        // SAFETY: as the caller says.
        unsafe {
            self.bind(name);
            self.device
                .cmd_dispatch(self.cb, n.div_ceil(WORKGROUP), 1, 1);
            barrier(self.device, self.cb, COMPUTE_TO_COMPUTE);
        }
    }

    /// Pass `name` in one invocation.
    ///
    /// # Safety
    /// `cb` is recording.
    pub(super) unsafe fn single(&self, name: &str) {
        // SAFETY: as the caller says.
        unsafe {
            self.bind(name);
            self.device.cmd_dispatch(self.cb, 1, 1, 1);
            barrier(self.device, self.cb, COMPUTE_TO_COMPUTE);
        }
    }
}
