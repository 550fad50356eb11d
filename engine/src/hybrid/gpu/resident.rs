//! A GPU tessellation kept on the device and drawn from there: each tessellation leaves a
//! [`DeviceLensPart`] (the lens pass's data, the indices and indirect draws its draw list wrote,
//! and a host copy of its counts) that a frame draws with no per-vertex data read back. The frame
//! declares the tessellation's passes in its own graph ([`super::work`]); the counts are read
//! once the frame is done ([`read_counts`]). Tessellations read back or timed are the tracer's
//! own submissions.
//!
//! Each scene object keeps its resident input mesh and its passes' descriptor sets over the
//! tracer's shared buffers, and a few sets of outputs, one per frame that may still draw one: an
//! output is reused once no frame holds its part (the `Arc` is the only reference left), so a
//! tessellation never writes what a pending frame reads. Whatever a recorded work names is kept
//! until the frames that recorded it are done ([`super::tracer::GpuTracer::used_until`]).

use std::sync::Arc;

use super::buffers::{InputMesh, Scratch, storage};
use super::work::{ARGS_BYTES, COUNT_WORDS, SetEntry};
use crate::gpu::descriptors::{DescriptorPool, Resource, SetLayout};
use crate::gpu::{Buffer, BufferUsage, DescriptorSet, Gpu, GpuError};
use crate::render::DeviceLensPart;
use crate::trace::stats::TraceCounters;

/// Words of the control buffer, as a part's counts hold them first.
const CONTROL_WORDS: usize = super::buffers::CONTROL_WORDS;

/// One set of a scene object's outputs and the sets of the passes that write them.
pub(super) struct Outputs {
    pub(super) part: Arc<DeviceLensPart>,
    /// The texgen pass's set (`None` when made without texgen), and the draw list's.
    pub(super) texgen_set: Option<DescriptorSet>,
    pub(super) draw_set: DescriptorSet,
    /// Arrays of lens data `part.data` holds (0 without texgen).
    arrays: u64,
    _pools: (DescriptorPool, DescriptorPool),
}

/// A scene object's resident state: its input mesh, its convex-hull flags and texgen shells, the
/// tracer's and the tessellation's sets over the shared buffers, and its outputs.
pub(super) struct ObjectState {
    pub(super) input: InputMesh,
    /// Per input triangle 1 on the hull of the lens geometry (one zero word without a split).
    pub(super) hull: Buffer,
    hull_words: Vec<u32>,
    /// Texgen's layer shells as last written.
    pub(super) shells: Option<(Buffer, Vec<[f32; 4]>)>,
    /// The level pass's set and the tessellation's, once made.
    pub(super) sets: Option<[DescriptorSet; 2]>,
    _pools: Option<(DescriptorPool, DescriptorPool)>,
    pub(super) outputs: Vec<Outputs>,
    /// How many outputs were made, for their names.
    made: usize,
}

/// The layouts the sets of an object's passes are made with.
pub(super) struct Layouts<'a> {
    pub(super) level_paths: &'a SetLayout,
    pub(super) tessellation: &'a SetLayout,
    pub(super) texgen: &'a SetLayout,
    pub(super) draw_list: &'a SetLayout,
}

/// The resources of a set's `entries` in binding order: each entry's buffer, or at binding 0
/// `first` where given (the level pass's walk, perhaps the driver's acceleration structure).
pub(super) fn resources(
    entries: &[SetEntry<'_>],
    first: Option<Resource>,
) -> Result<Vec<Resource>, GpuError> {
    let mut sorted: Vec<&SetEntry<'_>> = entries.iter().collect();
    sorted.sort_by_key(|e| e.binding);
    sorted
        .iter()
        .map(|entry| match (entry.binding, first) {
            (0, Some(walk)) => Ok(walk),
            _ => entry.buffer.map(Resource::buffer).ok_or_else(|| {
                GpuError::Internal(format!("the GPU tessellation: {} was not made", entry.name))
            }),
        })
        .collect()
}

/// A pool for one set of `layout`, and the set pointing at `resources`.
fn one_set(
    gpu: &Gpu,
    layout: &SetLayout,
    resources: &[Resource],
) -> Result<(DescriptorPool, DescriptorSet), GpuError> {
    let pool = DescriptorPool::new(gpu, &layout.bindings, 1)?;
    let set = pool.allocate_one(gpu, layout, resources)?;
    Ok((pool, set))
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
            made: 0,
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

    /// Makes the level pass's and the tessellation's sets, pointing at `level_paths` and
    /// `tessellation` in binding order (the caller makes them where `sets` is `None`: when the
    /// object or the shared buffers were made again).
    pub(super) fn make_sets(
        &mut self,
        gpu: &Gpu,
        layouts: &Layouts<'_>,
        level_paths: &[Resource],
        tessellation: &[Resource],
    ) -> Result<(), GpuError> {
        let (level_pool, level_set) = one_set(gpu, layouts.level_paths, level_paths)?;
        let (tessellation_pool, tessellation_set) =
            one_set(gpu, layouts.tessellation, tessellation)?;
        self.sets = Some([level_set, tessellation_set]);
        self._pools = Some((level_pool, tessellation_pool));
        Ok(())
    }

    /// The index of an output no frame holds (made where none is free) for `scratch`, with lens
    /// data for `arrays` arrays (0: no texgen), named by `name` from its index; `sets` makes its
    /// texgen and draw-list sets from the part.
    pub(super) fn free_outputs(
        &mut self,
        gpu: &Gpu,
        scratch: &Scratch,
        arrays: u64,
        name: impl Fn(usize) -> String,
        sets: impl FnOnce(&ObjectState, &DeviceLensPart) -> Result<OutputSets, GpuError>,
    ) -> Result<usize, GpuError> {
        let free = self
            .outputs
            .iter()
            .position(|o| Arc::strong_count(&o.part) == 1 && o.arrays == arrays);
        if let Some(at) = free {
            return Ok(at);
        }
        let capacity = scratch.vertices_capacity;
        let device = |label: &str, bytes: u64| Buffer::new(gpu, label, bytes, BufferUsage::Device);
        let part = DeviceLensPart {
            name: name(self.made),
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
        let OutputSets {
            texgen_set,
            draw_set,
            pools,
        } = sets(self, &part)?;
        self.made += 1;
        self.outputs.push(Outputs {
            part: Arc::new(part),
            texgen_set,
            draw_set,
            arrays,
            _pools: pools,
        });
        Ok(self.outputs.len() - 1)
    }
}

/// An output's texgen and draw-list sets, with their pools.
pub(super) struct OutputSets {
    pub(super) texgen_set: Option<DescriptorSet>,
    pub(super) draw_set: DescriptorSet,
    pub(super) pools: (DescriptorPool, DescriptorPool),
}

impl OutputSets {
    /// The sets of `texgen` (the texgen pass's entries, `None` without texgen) and `draw_list`.
    pub(super) fn new(
        gpu: &Gpu,
        layouts: &Layouts<'_>,
        texgen: Option<&[SetEntry<'_>]>,
        draw_list: &[SetEntry<'_>],
    ) -> Result<OutputSets, GpuError> {
        let (texgen_pool, texgen_set) = match texgen {
            Some(entries) => {
                let (pool, set) = one_set(gpu, layouts.texgen, &resources(entries, None)?)?;
                (pool, Some(set))
            }
            None => (DescriptorPool::new(gpu, &layouts.texgen.bindings, 1)?, None),
        };
        let (draw_pool, draw_set) = one_set(gpu, layouts.draw_list, &resources(draw_list, None)?)?;
        Ok(OutputSets {
            texgen_set,
            draw_set,
            pools: (texgen_pool, draw_pool),
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
    /// larger ones ([`super::tracer::GpuTracer::grow`]).
    pub capped_by_buffers: bool,
    /// The rays and triangle tests of its vertex paths.
    pub counters: TraceCounters,
}

/// The counts `part`'s tessellation wrote. Its submission must have completed (the frame that
/// drew the part is done, or the tracer waited for it).
pub fn read_counts(part: &DeviceLensPart) -> DeviceCounts {
    use lensmap_shaders::tessellate as t;
    let words = count_words(part);
    let tracer = CONTROL_WORDS;
    let args = CONTROL_WORDS + 4;
    let stopped = words[t::STAT_BUDGET as usize];
    DeviceCounts {
        vertices: words[t::CONTROL_VERTICES as usize],
        triangles: words[args] / 3,
        hull_triangles: words[args + 10] / 3,
        stopped_by_budget: stopped,
        capped_by_buffers: stopped > 0
            && u64::from(part.stride) < u64::from(words[t::CONTROL_OBJECT_BUDGET as usize]),
        counters: TraceCounters {
            primary_rays: u64::from(words[tracer + t::COUNTER_PRIMARY_RAYS as usize]),
            secondary_rays: u64::from(words[tracer + t::COUNTER_SECONDARY_RAYS as usize]),
            shadow_rays: 0,
            triangle_tests: u64::from(words[tracer + t::COUNTER_TRIANGLE_TESTS as usize]),
        },
    }
}
