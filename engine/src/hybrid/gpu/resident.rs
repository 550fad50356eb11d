//! A GPU tessellation kept on the device and drawn from there: the draw list's passes
//! (`shaders/wgsl/drawlist.wgsl`) turn the tessellation's output into an index buffer and
//! indirect draw arguments, and each tessellation leaves a [`DeviceLensPart`] (the lens pass's
//! data, the indices, the arguments and a host copy of its counts) that a frame draws with no
//! per-vertex data read back. The frame records the tessellation itself, as a compute pass of its
//! graph ([`super::recorder::TessellationWork`]); the counts are read once the frame is done
//! ([`read_counts`]). Tessellations read back or timed are the tracer's own submissions.
//!
//! Each scene object keeps its resident input mesh and its passes' descriptor sets over the
//! tracer's shared buffers, and a few sets of outputs, one per frame that may still draw one: an
//! output is reused once no frame holds its part (the `Arc` is the only reference left), so a
//! tessellation never writes what a pending frame reads. Whatever a recorded work names is kept
//! until the frames that recorded it are done ([`super::GpuTracer::used_until`]).

use std::sync::Arc;

use ash::vk;
use lensmap_shaders::DrawConstants;

use super::recorder::ComputePasses;
use super::tessellate::{InputMesh, Scratch, control};
use super::{COUNTERS, STORAGE, storage};
use crate::gpu::{Buffer, BufferUsage, Gpu, GpuError, Timeline, VkContext};
use crate::render::DeviceLensPart;
use crate::render::descriptors::{Binding, DescriptorPool, Resource};
use crate::trace::stats::TraceCounters;

/// Storage buffers bound at set 0 of the draw list's passes, in binding order (drawlist.wgsl).
pub(super) const DRAW_SET: &[Binding] = &[STORAGE; 9];

/// The draw list's passes, in the order they run (the scan's two between count and args).
pub(super) const PASSES: &[&str] = &[
    "cs_draw_begin",
    "cs_draw_count",
    "cs_scan_blocks",
    "cs_scan_top",
    "cs_draw_args",
    "cs_draw_emit",
];

/// Words of a part's host copy of its counts: the tessellation's control words, the tracer's
/// counters (padded to four), the three indirect draws.
pub(super) const COUNT_WORDS: usize = control::WORDS + 4 + 15;

/// Bytes of the three indirect draws.
const ARGS_BYTES: u64 = 60;

/// Submissions a tracer keeps in flight before it waits for the oldest.
const IN_FLIGHT: usize = 4;

/// The draw list's pipelines on one device.
pub(super) fn draw_list_passes(gpu: &Gpu) -> Result<ComputePasses, GpuError> {
    ComputePasses::new::<DrawConstants>(gpu, "drawlist", PASSES, DRAW_SET)
}

/// Command buffers the tessellations are recorded into, from a pool of their own, reused round
/// robin once their last submission completed, and the timeline that says which did.
pub(super) struct Submissions {
    device: ash::Device,
    pool: vk::CommandPool,
    timeline: Timeline,
    ring: Vec<(vk::CommandBuffer, u64)>,
    /// The value the last submission signals.
    submitted: u64,
    /// Another timeline whose submissions recorded this tracer's work (a renderer's frames,
    /// [`super::GpuTracer::used_until`]), and the last value of them.
    external: Option<(Arc<Timeline>, u64)>,
}

impl Drop for Submissions {
    fn drop(&mut self) {
        let _ = self.wait_all();
        // SAFETY: every submission of its command buffers completed (or the device is lost);
        // they are freed with the pool.
        unsafe { self.device.destroy_command_pool(self.pool, None) };
    }
}

impl Submissions {
    pub(super) fn new(gpu: &Gpu) -> Result<Submissions, GpuError> {
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(gpu.vulkan().queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let timeline = Timeline::new(gpu)?;
        // SAFETY: a valid create info for the queue's family; destroyed in Drop.
        let pool =
            unsafe { gpu.device().create_command_pool(&info, None) }.vk("vkCreateCommandPool")?;
        Ok(Submissions {
            device: gpu.device().clone(),
            pool,
            timeline,
            ring: Vec::new(),
            submitted: 0,
            external: None,
        })
    }

    /// Records `record` and submits it without waiting; returns the value its completion
    /// signals.
    pub(super) fn submit(
        &mut self,
        gpu: &Gpu,
        record: impl FnOnce(vk::CommandBuffer) -> Result<(), GpuError>,
    ) -> Result<u64, GpuError> {
        let slot = (self.submitted as usize) % IN_FLIGHT;
        if self.ring.len() <= slot {
            let info = vk::CommandBufferAllocateInfo::default()
                .command_pool(self.pool)
                .level(vk::CommandBufferLevel::PRIMARY)
                .command_buffer_count(1);
            // SAFETY: the pool belongs to this device and is used by this tracer alone (under
            // its pass lock).
            let made = unsafe { self.device.allocate_command_buffers(&info) }
                .vk("vkAllocateCommandBuffers")?;
            self.ring.push((made[0], 0));
        }
        let (cb, last) = self.ring[slot];
        self.timeline.wait(last)?;
        let value = self.submitted + 1;
        gpu.record_submit(cb, record, (&self.timeline, value), &[], &[])?;
        self.submitted = value;
        self.ring[slot].1 = value;
        Ok(value)
    }

    /// Blocks until submission `value` completed.
    pub(super) fn wait(&self, value: u64) -> Result<(), GpuError> {
        self.timeline.wait(value)
    }

    /// Blocks until every submission completed, the frames' that recorded this tracer's work
    /// included.
    pub(super) fn wait_all(&self) -> Result<(), GpuError> {
        if let Some((timeline, value)) = &self.external {
            timeline.wait(*value)?;
        }
        self.timeline.wait(self.submitted)
    }

    /// Notes that submission `value` of `timeline` recorded this tracer's work: what it names is
    /// kept until that completed.
    pub(super) fn used_until(&mut self, timeline: Arc<Timeline>, value: u64) {
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

/// One set of a scene object's outputs and the sets of the passes that write them.
pub(super) struct Outputs {
    pub(super) part: Arc<DeviceLensPart>,
    /// The texgen pass's set (`None` when made without texgen), and the draw list's.
    pub(super) texgen_set: Option<vk::DescriptorSet>,
    pub(super) draw_set: vk::DescriptorSet,
    /// Arrays of lens data `part.data` holds (0 without texgen).
    arrays: u64,
    _pools: (DescriptorPool, DescriptorPool),
}

/// A scene object's resident state: its input mesh, its convex-hull flags and texgen shells, the
/// tracer's and the tessellation's sets over the shared buffers, and its outputs.
pub(super) struct ObjectState {
    pub(super) input: InputMesh,
    /// Per input triangle 1 on the hull of the lens geometry (one zero word without a split).
    hull: Buffer,
    hull_words: Vec<u32>,
    /// Texgen's layer shells as last written.
    shells: Option<(Buffer, Vec<[f32; 4]>)>,
    /// The level pass's set and the tessellation's, once made.
    pub(super) sets: Option<(vk::DescriptorSet, vk::DescriptorSet)>,
    _pools: Option<(DescriptorPool, DescriptorPool)>,
    pub(super) outputs: Vec<Outputs>,
}

impl ObjectState {
    pub(super) fn new(gpu: &Gpu, input: InputMesh) -> Result<ObjectState, GpuError> {
        Ok(ObjectState {
            input,
            hull: storage::<u32>(gpu, "tessellation hull", &[])?,
            hull_words: Vec::new(),
            shells: None,
            sets: None,
            _pools: None,
            outputs: Vec::new(),
        })
    }

    /// Forgets the sets and outputs that point at the shared buffers (about to be replaced; no
    /// submission may be pending).
    pub(super) fn forget_sets(&mut self) {
        self.sets = None;
        self._pools = None;
        self.outputs.clear();
    }

    /// Whether the object's hull flags or shells differ from `hull` and `shells`: writing them
    /// then needs every submission that reads them done first.
    pub(super) fn changes(&self, hull: &[u32], shells: Option<&[[f32; 4]]>) -> bool {
        self.hull_words != hull
            || shells.is_some_and(|words| self.shells.as_ref().is_none_or(|(_, w)| w != words))
    }

    /// Writes the hull flags and shells where they changed (no submission may be pending: see
    /// [`Self::changes`]); the outputs, whose sets point at them, are made again.
    pub(super) fn write_inputs(
        &mut self,
        gpu: &Gpu,
        hull: &[u32],
        shells: Option<&[[f32; 4]]>,
    ) -> Result<(), GpuError> {
        if self.hull_words != hull {
            self.hull = storage(gpu, "tessellation hull", hull)?;
            self.hull_words = hull.to_vec();
            self.outputs.clear();
        }
        if let Some(words) = shells
            && self.shells.as_ref().is_none_or(|(_, w)| w != words)
        {
            self.shells = Some((storage(gpu, "texgen shells", words)?, words.to_vec()));
            self.outputs.clear();
        }
        Ok(())
    }

    /// Makes the level pass's and the tessellation's sets over `scratch` unless made.
    pub(super) fn ensure_sets(
        &mut self,
        gpu: &Gpu,
        (tracer, tessellation): (
            (vk::DescriptorSetLayout, &'static [Binding], &[Resource]),
            vk::DescriptorSetLayout,
        ),
        scratch: &Scratch,
    ) -> Result<(), GpuError> {
        if self.sets.is_some() {
            return Ok(());
        }
        let tracer_pool = DescriptorPool::new(gpu, tracer.1, 1)?;
        let tessellation_pool = DescriptorPool::new(gpu, super::tessellate::TESSELLATE_SET, 1)?;
        let mut tracer_resources = tracer.2.to_vec();
        tracer_resources.extend(scratch.tracer_resources());
        let tracer_set = tracer_pool.allocate_one(gpu, (tracer.0, tracer.1), &tracer_resources)?;
        let tessellation_set = tessellation_pool.allocate_one(
            gpu,
            (tessellation, super::tessellate::TESSELLATE_SET),
            &scratch.tessellation_resources(&self.input),
        )?;
        self.sets = Some((tracer_set, tessellation_set));
        self._pools = Some((tracer_pool, tessellation_pool));
        Ok(())
    }

    /// The index of an output no frame holds (made where none is free) for `scratch`, with lens data for
    /// `arrays` arrays (0: no texgen).
    pub(super) fn free_outputs(
        &mut self,
        gpu: &Gpu,
        (texgen, draw): (vk::DescriptorSetLayout, vk::DescriptorSetLayout),
        scratch: &Scratch,
        arrays: u64,
    ) -> Result<usize, GpuError> {
        let free = self
            .outputs
            .iter()
            .position(|o| Arc::strong_count(&o.part) == 1 && o.arrays == arrays);
        let at = match free {
            Some(at) => at,
            None => {
                let made = self.make_outputs(gpu, (texgen, draw), scratch, arrays)?;
                self.outputs.push(made);
                self.outputs.len() - 1
            }
        };
        Ok(at)
    }

    fn make_outputs(
        &self,
        gpu: &Gpu,
        (texgen, draw): (vk::DescriptorSetLayout, vk::DescriptorSetLayout),
        scratch: &Scratch,
        arrays: u64,
    ) -> Result<Outputs, GpuError> {
        let capacity = scratch.vertices_capacity();
        let device = |name: &str, bytes: u64| Buffer::new(gpu, name, bytes, BufferUsage::Device);
        let part = DeviceLensPart {
            data: device("lens part data", (16 * capacity * arrays).max(16))?,
            indices: device("lens part indices", 12 * scratch.output_capacity())?,
            args: device("lens part draws", ARGS_BYTES)?,
            stride: capacity as u32,
            counts: Buffer::new(
                gpu,
                "lens part counts",
                4 * COUNT_WORDS as u64,
                BufferUsage::Readback,
            )?,
        };
        let texgen_pool = DescriptorPool::new(gpu, super::texgen::TEXGEN_SET, 1)?;
        let draw_pool = DescriptorPool::new(gpu, DRAW_SET, 1)?;
        let texgen_set = match &self.shells {
            Some((shells, _)) if arrays > 0 => Some(texgen_pool.allocate_one(
                gpu,
                (texgen, super::texgen::TEXGEN_SET),
                &scratch.texgen_resources(shells, &part.data),
            )?),
            _ => None,
        };
        let draw_set = draw_pool.allocate_one(
            gpu,
            (draw, DRAW_SET),
            &scratch.draw_resources(&self.hull, (&part.indices, &part.args)),
        )?;
        Ok(Outputs {
            part: Arc::new(part),
            texgen_set,
            draw_set,
            arrays,
            _pools: (texgen_pool, draw_pool),
        })
    }
}

/// The raw words of `part`'s counts (see [`COUNT_WORDS`]); its submission must have completed.
pub(super) fn count_words(part: &DeviceLensPart) -> [u32; COUNT_WORDS] {
    let bytes = part.counts.read();
    let mut words = [0u32; COUNT_WORDS];
    let n = bytes.len().min(4 * COUNT_WORDS);
    bytemuck::cast_slice_mut::<u32, u8>(&mut words)[..n].copy_from_slice(&bytes[..n]);
    words
}

/// What a resident part's counts say, read once the frame that drew it is done.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceCounts {
    /// Vertices of the tessellation.
    pub vertices: u32,
    /// Triangles drawn (after the T-junction removal).
    pub triangles: u32,
    /// Of those, the convex-hull split's.
    pub hull_triangles: u32,
    /// Triangles whose splits the vertex budget or the buffers refused.
    pub stopped_by_budget: u32,
    /// Whether the buffers, not the budget, refused them: the next tessellation should have
    /// larger ones ([`super::GpuTracer::grow`]).
    pub capped_by_buffers: bool,
    /// The rays and triangle tests of its vertex paths.
    pub counters: TraceCounters,
}

/// The counts `part`'s tessellation wrote. Its submission must have completed (the frame that
/// drew the part is done, or the tracer waited for it).
pub fn read_counts(part: &DeviceLensPart) -> DeviceCounts {
    let words = count_words(part);
    let tracer = control::WORDS;
    let args = control::WORDS + 4;
    let stopped = words[control::BUDGET];
    DeviceCounts {
        vertices: words[control::VERTICES],
        triangles: words[args] / 3,
        hull_triangles: words[args + 10] / 3,
        stopped_by_budget: stopped,
        capped_by_buffers: stopped > 0
            && u64::from(part.stride) < u64::from(words[control::OBJECT_BUDGET]),
        counters: TraceCounters {
            primary_rays: u64::from(words[tracer]),
            secondary_rays: u64::from(words[tracer + 1]),
            shadow_rays: 0,
            triangle_tests: u64::from(words[tracer + 2]),
        },
    }
}

const _: () = assert!(COUNTERS <= 4);
