//! Recording the GPU tessellation's passes ([`super::tessellate`]): binding each pass with its
//! set and constants, dispatching it over a count the previous pass wrote, the barriers between
//! them, and the optional timestamps that split the device's time between the stages.

use ash::vk;
use lensmap_shaders::{DrawConstants, TessellateConstants, TexgenConstants, TracerConstants};

use super::tessellate::{GpuStageMs, control};
use super::{
    COMPUTE_TO_TRANSFER, COUNTERS, Dependency, TRANSFER_TO_COMPUTE, TRANSFER_TO_HOST, WORKGROUP,
    barrier,
};
use crate::gpu::{Gpu, GpuError, VkContext};
use crate::render::descriptors::{Binding, create_set_layout};

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

/// The compute pipelines of one shader file's entry points over one set layout, with push
/// constants: the tessellation's, texgen's and the draw list's passes.
pub(super) struct ComputePasses {
    device: ash::Device,
    pub(super) set_layout: vk::DescriptorSetLayout,
    /// The layout and pipelines (copied into the work that records them).
    pub(super) handles: ComputeHandles,
}

/// The handles of [`ComputePasses`] that recording needs, owned by the passes.
#[derive(Clone)]
pub(super) struct ComputeHandles {
    pub(super) layout: vk::PipelineLayout,
    pipelines: Vec<vk::Pipeline>,
    entries: &'static [&'static str],
}

impl ComputeHandles {
    /// The pipeline of entry point `name` (the first for a name it does not have: a typo fails
    /// the tests, which run every pass).
    pub(super) fn pipeline(&self, name: &str) -> vk::Pipeline {
        let index = self.entries.iter().position(|&e| e == name).unwrap_or(0);
        self.pipelines[index]
    }
}

impl Drop for ComputePasses {
    fn drop(&mut self) {
        // SAFETY: the owner waited for every submission that used them.
        unsafe {
            for &pipeline in &self.handles.pipelines {
                self.device.destroy_pipeline(pipeline, None);
            }
            self.device
                .destroy_pipeline_layout(self.handles.layout, None);
            self.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

impl ComputePasses {
    /// The pipelines of `entries` of `shaders/wgsl/{file}.wgsl`, binding `bindings` at set 0
    /// and push constants `C`.
    pub(super) fn new<C>(
        gpu: &Gpu,
        file: &str,
        entries: &'static [&'static str],
        bindings: &[Binding],
    ) -> Result<ComputePasses, GpuError> {
        let mut passes = ComputePasses {
            device: gpu.device().clone(),
            set_layout: create_set_layout(gpu, bindings)?,
            handles: ComputeHandles {
                layout: vk::PipelineLayout::null(),
                pipelines: Vec::new(),
                entries,
            },
        };
        passes.handles.layout = super::compute_layout::<C>(gpu, passes.set_layout)?;
        for entry in entries {
            let shader =
                lensmap_shaders::shader(file, entry).ok_or_else(|| GpuError::BadUpload {
                    what: format!("{file}.wgsl"),
                    problem: format!("entry point {entry} was not compiled"),
                })?;
            let pipeline = gpu.create_compute_pipeline(&shader, passes.handles.layout)?;
            passes.handles.pipelines.push(pipeline);
        }
        Ok(passes)
    }
}

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
    pub(super) passes: &'a ComputeHandles,
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
                self.passes.pipeline(name),
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

/// One tessellation, ready to record into any command buffer: the handles of its passes,
/// buffers and sets and every constant, taken from the tracer when it was prepared. The tracer
/// keeps what they name alive until every submission that may hold the work completed
/// ([`super::GpuTracer::used_until`]).
pub(super) struct TessellationWork {
    pub(super) device: ash::Device,
    /// The tessellation's, texgen's and the draw list's passes.
    pub(super) passes: [ComputeHandles; 3],
    /// The tracer's level pass and layout.
    pub(super) level_paths: (vk::Pipeline, vk::PipelineLayout),
    /// The level pass's set, the tessellation's, texgen's (when asked for) and the draw list's.
    pub(super) sets: [vk::DescriptorSet; 4],
    /// The shared control, wanted and tracer-counter buffers.
    pub(super) scratch: [vk::Buffer; 3],
    /// The part's draw arguments and its host copy of the counts.
    pub(super) part: [vk::Buffer; 2],
    /// Input vertices, triangles and base edges.
    pub(super) input: [u32; 3],
    pub(super) levels: u32,
    /// The control words it starts from: how many of them it writes (the frame's budget word
    /// included, or left as the object before left it).
    pub(super) first: ([u32; control::WORDS], usize),
    pub(super) tracer_constants: TracerConstants,
    pub(super) constants: TessellateConstants,
    pub(super) texgen: Option<TexgenConstants>,
    pub(super) draw: DrawConstants,
    /// Whether a frame that recorded it was submitted (it runs once).
    pub(super) recorded: std::sync::atomic::AtomicBool,
}

/// Every earlier command (the tracer's last tessellation on the shared buffers, a frame's draws
/// of a part about to be rewritten) before this submission's transfers and passes.
const EARLIER_TO_THIS: Dependency = (
    vk::PipelineStageFlags2::ALL_COMMANDS,
    vk::AccessFlags2::MEMORY_WRITE,
    vk::PipelineStageFlags2::from_raw(
        vk::PipelineStageFlags2::TRANSFER.as_raw()
            | vk::PipelineStageFlags2::COMPUTE_SHADER.as_raw(),
    ),
    vk::AccessFlags2::from_raw(
        vk::AccessFlags2::MEMORY_READ.as_raw() | vk::AccessFlags2::MEMORY_WRITE.as_raw(),
    ),
);

impl TessellationWork {
    /// Records every level, the T-junction removal, texgen and the draw list, then the copy of
    /// the counts to the part's host buffer, into `cb`, with the stages timed by `timestamps`.
    pub(super) fn record_timed(&self, cb: vk::CommandBuffer, timestamps: Option<&Timestamps>) {
        let device = &self.device;
        let [tracer_set, set, texgen_set, draw_set] = self.sets;
        let [control, wanted, counters] = self.scratch;
        let [args, counts] = self.part;
        let [vertex_count, triangle_count, edge_count] = self.input;
        let (first, written) = &self.first;
        let levels = self.levels;
        let recorder = Recorder {
            device,
            cb,
            passes: &self.passes[0],
            set,
            constants: &self.constants,
            control,
            timestamps,
            bound: std::cell::Cell::new(false),
        };
        // SAFETY: every handle is live until the submission completes (the tracer waits for
        // every submission that may hold a work before freeing what it names, and a part
        // outlives the frames that draw it); a barrier separates every pass from the next, and
        // the copies from the passes.
        unsafe {
            barrier(device, cb, EARLIER_TO_THIS);
            device.cmd_update_buffer(cb, control, 0, bytemuck::cast_slice(&first[..*written]));
            device.cmd_fill_buffer(cb, wanted, 0, 4 * u64::from(vertex_count).max(1), 0);
            device.cmd_fill_buffer(cb, counters, 0, vk::WHOLE_SIZE, 0);
            if let Some(timestamps) = timestamps {
                device.cmd_reset_query_pool(cb, timestamps.pool, 0, 4 * levels + 4);
            }
            barrier(device, cb, TRANSFER_TO_COMPUTE);
            recorder.groups("cs_begin", vertex_count.max(edge_count));
            recorder.groups("cs_classify", triangle_count);
            for level in 0..levels {
                // The level's new vertices, by the tracer's pass (its own layout and set).
                recorder.stamp(4 * level);
                let (level_paths, layout) = self.level_paths;
                bind_compute(
                    device,
                    cb,
                    (level_paths, layout, tracer_set),
                    bytemuck::bytes_of(&self.tracer_constants),
                );
                recorder.dispatch_indirect(control::DISPATCH_TRACE);
                recorder.bound.set(false);
                recorder.stamp(4 * level + 1);
                recorder.stamp(4 * level + 2);
                for name in ["cs_decide", "cs_count"] {
                    recorder.indirect(name, control::DISPATCH_ELEMENTS);
                }
                recorder.indirect("cs_scan_blocks", control::DISPATCH_BLOCKS);
                recorder.single("cs_scan_top");
                for name in ["cs_apply", "cs_emit"] {
                    recorder.indirect(name, control::DISPATCH_ELEMENTS);
                }
                recorder.single("cs_advance");
                recorder.stamp(4 * level + 3);
            }
            recorder.stamp(4 * levels);
            recorder.single("cs_leaves_begin");
            recorder.indirect("cs_leaf_count", control::DISPATCH_ELEMENTS);
            recorder.indirect("cs_scan_blocks", control::DISPATCH_BLOCKS);
            recorder.single("cs_scan_top");
            recorder.indirect("cs_leaf_emit", control::DISPATCH_ELEMENTS);
            recorder.stamp(4 * levels + 1);
            recorder.stamp(4 * levels + 2);
            if let Some(constants) = &self.texgen {
                let texgen = &self.passes[1];
                bind_compute(
                    device,
                    cb,
                    (texgen.pipeline("cs_texgen"), texgen.layout, texgen_set),
                    bytemuck::bytes_of(constants),
                );
                // Over every vertex: cs_leaves_begin set the trace arguments so.
                recorder.dispatch_indirect(control::DISPATCH_TRACE);
            }
            recorder.stamp(4 * levels + 3);
            self.record_draw_list(&recorder, draw_set);
            barrier(device, cb, COMPUTE_TO_TRANSFER);
            let words = 4 * control::WORDS as u64;
            let copies = [
                (control, 0, words),
                (counters, words, 4 * COUNTERS as u64),
                (args, words + 16, 60),
            ];
            for (source, at, bytes) in copies {
                let region = vk::BufferCopy {
                    src_offset: 0,
                    dst_offset: at,
                    size: bytes,
                };
                device.cmd_copy_buffer(cb, source, counts, &[region]);
            }
            barrier(device, cb, TRANSFER_TO_HOST);
        }
    }

    /// The draw list's passes: the index buffer and the indirect draws.
    ///
    /// # Safety
    /// `recorder.cb` is recording.
    unsafe fn record_draw_list(&self, recorder: &Recorder<'_>, draw_set: vk::DescriptorSet) {
        let (device, cb, pass) = (recorder.device, recorder.cb, &self.passes[2]);
        // SAFETY: as the caller says; the pipelines, layout and set are live.
        unsafe {
            bind_compute(
                device,
                cb,
                (pass.pipeline("cs_draw_begin"), pass.layout, draw_set),
                bytemuck::bytes_of(&self.draw),
            );
            for &name in super::resident::PASSES {
                device.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pass.pipeline(name));
                match name {
                    "cs_draw_begin" | "cs_scan_top" | "cs_draw_args" => {
                        device.cmd_dispatch(cb, 1, 1, 1);
                        barrier(device, cb, COMPUTE_TO_COMPUTE);
                    }
                    "cs_scan_blocks" => recorder.dispatch_indirect(control::DISPATCH_BLOCKS),
                    _ => recorder.dispatch_indirect(control::DISPATCH_ELEMENTS),
                }
            }
        }
    }
}

impl crate::render::DeviceWork for TessellationWork {
    fn record(&self, cb: vk::CommandBuffer) {
        self.record_timed(cb, None);
    }

    fn pending(&self) -> bool {
        !self.recorded.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn submitted(&self) {
        self.recorded
            .store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

/// Binds a compute `pipeline` with its layout's one set and push constants.
///
/// # Safety
/// `cb` is recording; the handles are live and of one layout.
unsafe fn bind_compute(
    device: &ash::Device,
    cb: vk::CommandBuffer,
    (pipeline, layout, set): (vk::Pipeline, vk::PipelineLayout, vk::DescriptorSet),
    constants: &[u8],
) {
    // SAFETY: as the caller says.
    unsafe {
        device.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
        device.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::COMPUTE, layout, 0, &[set], &[]);
        device.cmd_push_constants(cb, layout, vk::ShaderStageFlags::COMPUTE, 0, constants);
    }
}
