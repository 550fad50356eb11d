//! The adaptive tessellation on the GPU (`shaders/wgsl/tessellate.wgsl`): the CPU tessellator's
//! rules ([`crate::hybrid::tessellate`]) level by level in compute passes, the vertex paths
//! traced by the tracer's level pass between them, every record kept on the GPU, then texgen and
//! the draw list, all in one command buffer. A frame records it and draws the result where it
//! lies ([`GpuTracer::tessellate_on_device`], [`super::resident`]); [`GpuTracer::tessellate`]
//! submits it, waits for it and reads the mesh and its records back once.
//!
//! Determinism: midpoint, edge and triangle indices come from stable prefix sums over each
//! level's triangles (in the CPU's order), and a midpoint belongs to the lowest-indexed triangle
//! that asks for it (an atomic minimum, whose result does not depend on the order the atomics
//! land in); so the output is identical run to run, and a midpoint gets the index the CPU gives
//! it where the decisions agree.
//!
//! Capacity: the buffers hold a fixed number of vertices (and six triangles and five edges per
//! vertex), shared by the scene objects. Where a tessellation's counts say they, not the vertex
//! budget, stopped its splits, they grow fourfold, up to the budget or what the device can
//! dispatch, for the next tessellation: at once for one read back (it is made again), with the
//! next frame for one drawn where it lies (a single frame of the runner is made again). Past the
//! budget, splits stop as on the CPU ([`StopReason::Budget`]).

use std::sync::Arc;

use ash::vk;
use glam::Vec3;
use lensmap_shaders::{DrawConstants, TessellateConstants};
use rustc_hash::FxHashMap;

use super::assemble::{Readback, assemble};
use super::recorder::{ComputePasses, TessellationWork, Timestamps};
use super::resident;
use super::texgen::{self, TexgenRequest};
use super::{
    GpuTracer, PassState, PathSettings, STORAGE, TRANSFER_TO_HOST, WORKGROUP, barrier, storage,
};
use crate::gpu::{Buffer, BufferUsage, Gpu, GpuError};
use crate::hybrid::paths::{ScreenCamera, VertexPaths};
use crate::hybrid::tessellate::{Tessellation, TessellationError, TessellationOptions};
use crate::render::descriptors::{Binding, Resource};
use crate::render::{DeviceLensPart, TermVertices};
use crate::scene::TriangleMesh;
use crate::trace::stats::TraceCounters;

/// Storage buffers bound at set 0 of every tessellation pass, in binding order.
pub(super) const TESSELLATE_SET: &[Binding] = &[STORAGE; 13];

/// The deepest subdivision the GPU walks: an edge's split tree then has at most 31 levels, what
/// the edge walk's stack of 64 entries holds (tessellate.wgsl `WALK_STACK`).
pub const GPU_MAX_DEPTH: u32 = 30;

/// "No vertex / edge" (tessellate.wgsl `NONE`).
const NONE: u32 = u32::MAX;

/// Control words (tessellate.wgsl `CONTROL_*`, `STAT_*`).
/// (LEVEL_LO, 0, and VERTEX_LO, 3, start at 0.)
pub(super) mod control {
    pub const LEVEL_HI: usize = 1;
    pub const NEXT_HI: usize = 2;
    pub const VERTEX_HI: usize = 4;
    pub const VERTICES: usize = 5;
    pub const NEXT_VERTICES: usize = 6;
    pub const EDGES: usize = 7;
    pub const NEXT_EDGES: usize = 8;
    pub const SCAN_N: usize = 9;
    pub const OUTPUT: usize = 11;
    pub const DISPATCH_TRACE: usize = 12;
    pub const DISPATCH_ELEMENTS: usize = 15;
    pub const DISPATCH_BLOCKS: usize = 18;
    pub const INPUT_VERTICES: usize = 21;
    pub const FRONT: usize = 24;
    pub const BACK: usize = 25;
    pub const SPLITS: usize = 26;
    pub const CREATED: usize = 29;
    pub const REQUESTS: usize = 30;
    pub const MAX_DEPTH_REACHED: usize = 31;
    pub const AT_MAX_DEPTH: usize = 32;
    pub const BUDGET: usize = 33;
    pub const OCCLUDED: usize = 34;
    pub const T_JUNCTION_LEAVES: usize = 35;
    pub const T_JUNCTION_VERTICES: usize = 36;
    /// The frame's vertex budget left (kept between a frame's objects).
    pub const FRAME_BUDGET: usize = 38;
    /// This object's budget: the frame's left, or its input vertices if more.
    pub const OBJECT_BUDGET: usize = 39;
    /// Words in the buffer.
    pub const WORDS: usize = 40;
}

/// Elements per block of the prefix sum (tessellate.wgsl `SCAN_BLOCK`).
const SCAN_BLOCK: u64 = 256;

/// Triangles (of every level) and edges the buffers hold per vertex of capacity.
const TRIANGLES_PER_VERTEX: u64 = 6;
const EDGES_PER_VERTEX: u64 = 5;

/// The first capacity tried, in vertices: the paper's setting (teapot-room at 1920×1440
/// subpixels, t = 3) needs some 130,000.
const FIRST_CAPACITY: u64 = 1 << 17;

/// Bytes per element of the buffers.
const VERTEX_BYTES: u64 = 32;
const RECORD_BYTES: u64 = super::RECORD_BYTES;
const TRIANGLE_BYTES: u64 = 32;
const EDGE_END_BYTES: u64 = 8;
const EDGE_STATE_BYTES: u64 = 16;
const COUNT_BYTES: u64 = 16;
const OUTPUT_BYTES: u64 = 16;

/// The passes of tessellate.wgsl.
const PASSES: &[&str] = &[
    "cs_begin",
    "cs_classify",
    "cs_decide",
    "cs_count",
    "cs_scan_blocks",
    "cs_scan_top",
    "cs_apply",
    "cs_emit",
    "cs_advance",
    "cs_leaves_begin",
    "cs_leaf_count",
    "cs_leaf_emit",
];

/// The tessellation's pipelines on one device; refused where the device binds fewer storage
/// buffers per stage than they do.
pub(super) fn tessellation_passes(gpu: &Gpu) -> Result<ComputePasses, GpuError> {
    let limit = gpu
        .properties()
        .limits
        .max_per_stage_descriptor_storage_buffers;
    if (limit as usize) < TESSELLATE_SET.len() {
        return Err(GpuError::BadUpload {
            what: "the GPU tessellation".into(),
            problem: format!(
                "it binds {} storage buffers, past the device's maxPerStageDescriptorStorageBuffers of {limit}; tessellate on the CPU",
                TESSELLATE_SET.len()
            ),
        });
    }
    ComputePasses::new::<TessellateConstants>(gpu, "tessellate", PASSES, TESSELLATE_SET)
}

/// A scene object's mesh as the passes read it, resident: its vertices with the normals the CPU
/// tessellator uses, its triangles with their edges, and its edges.
pub(super) struct InputMesh {
    pub(super) vertices: Buffer,
    pub(super) triangles: Buffer,
    pub(super) edges: Buffer,
    pub(super) vertex_count: u32,
    pub(super) triangle_count: u32,
    pub(super) edge_count: u32,
}

impl InputMesh {
    /// Uploads `mesh` (validated as [`crate::hybrid::tessellate::tessellate`] validates it).
    fn new(gpu: &Gpu, mesh: &TriangleMesh) -> Result<InputMesh, TessellationError> {
        crate::hybrid::tessellate::validate(mesh)?;
        let count = mesh.positions.len();
        let normals = if mesh.normals.len() == count {
            mesh.normals.clone()
        } else {
            mesh.accumulated_face_normals()
        };
        // The floats as bits, the origins (none: an input vertex) as integers (tessellate.wgsl).
        let bits = |v: Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits(), NONE];
        let vertices: Vec<[u32; 4]> = mesh
            .positions
            .iter()
            .zip(&normals)
            .flat_map(|(&p, n)| [bits(p), bits(n.normalize_or_zero())])
            .collect();
        let mut edge_ids: FxHashMap<(u32, u32), u32> = FxHashMap::default();
        let mut edges: Vec<[u32; 2]> = Vec::new();
        let mut triangles: Vec<[u32; 4]> = Vec::with_capacity(2 * mesh.triangles.len());
        for &[a, b, c] in &mesh.triangles {
            let degenerate = a == b || b == c || c == a;
            let mut ids = [NONE; 3];
            if !degenerate {
                for (side, (u, w)) in [(a, b), (b, c), (c, a)].into_iter().enumerate() {
                    ids[side] = *edge_ids.entry((u.min(w), u.max(w))).or_insert_with(|| {
                        edges.push([u, w]);
                        edges.len() as u32 - 1
                    });
                }
            }
            triangles.push([a, b, c, 0]);
            triangles.push([ids[0], ids[1], ids[2], 0]);
        }
        let too_many = |what: &str| GpuError::BadUpload {
            what: "the GPU tessellation".into(),
            problem: format!("the mesh has more {what} than a u32 names"),
        };
        Ok(InputMesh {
            vertices: storage(gpu, "tessellation input vertices", &vertices)?,
            triangles: storage(gpu, "tessellation input triangles", &triangles)?,
            edges: storage(gpu, "tessellation base edges", &edges)?,
            vertex_count: u32::try_from(count).map_err(|_| too_many("vertices"))?,
            triangle_count: u32::try_from(mesh.triangles.len())
                .map_err(|_| too_many("triangles"))?,
            edge_count: edges.len() as u32,
        })
    }
}

/// What the shared buffers must hold for the objects tessellated so far: the most input vertices
/// (and room for a split), input triangles (edges at most three times as many) and texgen arrays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Extent {
    least: u64,
    reserve: u64,
    arrays: u64,
}

impl Extent {
    fn of(input: &InputMesh, arrays: u64) -> Extent {
        Extent {
            least: u64::from(input.vertex_count) + 4,
            reserve: u64::from(input.triangle_count).max(u64::from(input.edge_count).div_ceil(3)),
            arrays,
        }
    }

    /// The larger of each.
    fn max(self, other: Extent) -> Extent {
        Extent {
            least: self.least.max(other.least),
            reserve: self.reserve.max(other.reserve),
            arrays: self.arrays.max(other.arrays),
        }
    }
}

/// The frame's buffers for up to `vertices` vertices (and the derived triangles and edges).
pub(super) struct Scratch {
    pub(super) vertices_capacity: u64,
    pub(super) triangles_capacity: u64,
    pub(super) edges_capacity: u64,
    pub(super) vertices: Buffer,
    pub(super) records: Buffer,
    pub(super) control: Buffer,
    pub(super) wanted: Buffer,
    pub(super) triangles: Buffer,
    pub(super) edge_ends: Buffer,
    pub(super) edge_state: Buffer,
    pub(super) counts: Buffer,
    pub(super) block_sums: Buffer,
    pub(super) output: Buffer,
    /// The tracer's counters (tracer.wgsl `COUNTER_*`).
    pub(super) counters: Buffer,
    /// The host copy of a mesh read back (grown as needed).
    pub(super) readback: Option<Buffer>,
}

impl Scratch {
    /// Buffers for `vertices` vertices and an input of up to `reserve` triangles (its edges at
    /// most three times as many).
    fn new(gpu: &Gpu, vertices: u64, reserve: u64) -> Result<Scratch, GpuError> {
        let triangles = TRIANGLES_PER_VERTEX * vertices + reserve;
        let edges = EDGES_PER_VERTEX * vertices + 3 * reserve;
        let outputs = 2 * vertices + 2 * reserve;
        let device = |name: &str, bytes: u64| Buffer::new(gpu, name, bytes, BufferUsage::Device);
        Ok(Scratch {
            vertices_capacity: vertices,
            triangles_capacity: triangles,
            edges_capacity: edges,
            vertices: device("tessellation vertices", vertices * VERTEX_BYTES)?,
            records: device("tessellation records", vertices * RECORD_BYTES)?,
            control: device("tessellation control", 4 * control::WORDS as u64)?,
            wanted: device("tessellation wanted", 4 * vertices)?,
            triangles: device("tessellation triangles", triangles * TRIANGLE_BYTES)?,
            edge_ends: device("tessellation edge ends", edges * EDGE_END_BYTES)?,
            edge_state: device("tessellation edge state", edges * EDGE_STATE_BYTES)?,
            counts: device("tessellation counts", triangles * COUNT_BYTES)?,
            block_sums: device(
                "tessellation block sums",
                triangles.div_ceil(SCAN_BLOCK) * COUNT_BYTES,
            )?,
            output: device("tessellation output", outputs * OUTPUT_BYTES)?,
            counters: device("tessellation tracer counters", 4 * super::COUNTERS as u64)?,
            readback: None,
        })
    }

    /// Whether it holds every input of `extent` in full (its vertices, triangles and edges, and
    /// a split).
    fn holds(&self, extent: &Extent) -> bool {
        self.vertices_capacity >= extent.least
            && self.triangles_capacity
                >= TRIANGLES_PER_VERTEX * self.vertices_capacity + extent.reserve
            && self.edges_capacity >= EDGES_PER_VERTEX * self.vertices_capacity + 3 * extent.reserve
    }

    /// Vertices the buffers hold.
    pub(super) fn vertices_capacity(&self) -> u64 {
        self.vertices_capacity
    }

    /// Output triangles the buffers hold.
    pub(super) fn output_capacity(&self) -> u64 {
        self.output.size / OUTPUT_BYTES
    }

    /// The level pass's buffers after the geometry's (tracer.wgsl bindings 5 to 9).
    pub(super) fn tracer_resources(&self) -> Vec<Resource> {
        [
            &self.vertices,
            &self.records,
            &self.counters,
            &self.control,
            &self.wanted,
        ]
        .iter()
        .map(|b| Resource::Buffer(b.handle))
        .collect()
    }

    /// The tessellation's buffers over `input` (tessellate.wgsl bindings).
    pub(super) fn tessellation_resources(&self, input: &InputMesh) -> Vec<Resource> {
        [
            &self.vertices,
            &self.records,
            &self.control,
            &self.wanted,
            &self.triangles,
            &self.edge_ends,
            &self.edge_state,
            &self.counts,
            &self.block_sums,
            &self.output,
            &input.vertices,
            &input.triangles,
            &input.edges,
        ]
        .iter()
        .map(|b| Resource::Buffer(b.handle))
        .collect()
    }

    /// Texgen's buffers, writing into `data` (texgen.wgsl bindings).
    pub(super) fn texgen_resources(&self, shells: &Buffer, data: &Buffer) -> Vec<Resource> {
        [
            &self.vertices,
            &self.records,
            &self.wanted,
            shells,
            data,
            &self.control,
        ]
        .iter()
        .map(|b| Resource::Buffer(b.handle))
        .collect()
    }

    /// The draw list's buffers (drawlist.wgsl bindings).
    pub(super) fn draw_resources(
        &self,
        hull: &Buffer,
        (indices, args): (&Buffer, &Buffer),
    ) -> Vec<Resource> {
        [
            &self.control,
            &self.output,
            &self.triangles,
            &self.vertices,
            hull,
            &self.counts,
            &self.block_sums,
            indices,
            args,
        ]
        .iter()
        .map(|b| Resource::Buffer(b.handle))
        .collect()
    }

    /// What the last copy to the host buffer left there (empty before the first).
    fn read_back(&self) -> &[u8] {
        self.readback.as_ref().map(|b| b.read()).unwrap_or_default()
    }

    /// A host buffer of at least `bytes`.
    fn readback(&mut self, gpu: &Gpu, bytes: u64) -> Result<&Buffer, GpuError> {
        if self.readback.as_ref().is_some_and(|b| b.size < bytes) {
            self.readback = None;
        }
        match &mut self.readback {
            Some(buffer) => Ok(buffer),
            slot => Ok(slot.insert(Buffer::new(
                gpu,
                "tessellation readback",
                bytes.next_power_of_two(),
                BufferUsage::Readback,
            )?)),
        }
    }
}

/// What a tessellation needs besides its mesh: the camera and paths, the paper's criterion and
/// the options.
pub struct GpuTessellationRequest<'a> {
    /// The frame's camera.
    pub camera: &'a ScreenCamera,
    /// The lens object and scene object, and where paths stop.
    pub settings: &'a PathSettings,
    /// cos of the paper's angle threshold.
    pub cos_threshold: f32,
    /// Whether back-facing triangles are subdivided too (an open mesh).
    pub back_faces: bool,
    /// t, the depth cap (at most [`GPU_MAX_DEPTH`]) and the vertex budget.
    pub options: &'a TessellationOptions,
    /// Texture coordinates too, for these layers (in the same submission), or not.
    pub texgen: Option<TexgenRequest<'a>>,
    /// Per input triangle whether it lies on the convex hull of the lens geometry: the draw
    /// list puts those facing the eye last (`None`: no convex-hull split).
    pub hull: Option<&'a [bool]>,
    /// Whether the vertex budget continues on the device from the tessellation submitted before
    /// (the frame's previous scene object, whose vertices the host never counted) instead of
    /// starting at `options.max_vertices`.
    pub continue_budget: bool,
}

/// What a tessellation left on the device for a frame adds to one read back.
#[derive(Clone, Copy, Debug)]
pub struct DeviceExtras<'a> {
    /// Texture coordinates too, for these layers.
    pub texgen: Option<TexgenRequest<'a>>,
    /// Per input triangle whether it lies on the convex hull of the lens geometry (`None`: no
    /// convex-hull split).
    pub hull: Option<&'a [bool]>,
    /// Whether the vertex budget continues from the frame's previous tessellation, which the
    /// host never counted ([`GpuTessellationRequest::continue_budget`]).
    pub continue_budget: bool,
}

/// A tessellation left on the device: its work for a frame to record, or its submission, not
/// waited for (unless timed).
pub struct DeviceTessellation {
    /// The buffers a frame draws it from.
    pub part: Arc<DeviceLensPart>,
    /// The compute work that makes them, for the frame that draws them to record before its
    /// lens passes (`None`: submitted already, as a timed tessellation is).
    pub work: Option<Arc<dyn crate::render::DeviceWork>>,
    /// Its stages' device time (`None` unless the tracer [times them](GpuTracer::time_stages):
    /// it then waits for the submission).
    pub stage_ms: Option<GpuStageMs>,
    /// Wall time of recording and submitting it (and of waiting, when timed), ms.
    pub submission_ms: f64,
    /// The tracer's timeline value its completion signals.
    submitted: u64,
}

/// Where a GPU tessellation's time went on the device, by timestamps, ms.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuStageMs {
    /// The levels' vertex-path passes.
    pub trace: f64,
    /// The levels' split passes and the T-junction removal.
    pub tessellation: f64,
    /// The texgen pass.
    pub texgen: f64,
}

/// A tessellation made on the GPU, read back.
pub struct GpuTessellation {
    /// Wall time of its main submission (every pass, recorded, run and waited for), ms: all but
    /// the read-back and rebuilding the mesh on the CPU.
    pub submission_ms: f64,
    /// Its stages' device time (`None` unless the tracer [times them](GpuTracer::time_stages)
    /// and the queue has timestamps).
    pub stage_ms: Option<GpuStageMs>,
    /// The mesh, its origins, records and stats, as the CPU tessellator gives them.
    pub tessellation: Tessellation<VertexPaths>,
    /// The rays and triangle tests of its vertex paths.
    pub counters: TraceCounters,
    /// Per term its F·G and each layer's directions, when texgen was asked for.
    pub terms: Option<Vec<TermVertices>>,
}

/// The largest capacity, in vertices, the device can dispatch and bind with room for an input of
/// `reserve` triangles (and three times as many edges): every per-triangle pass within
/// `maxComputeWorkGroupCount[0]` workgroups, every buffer (texgen's lens data of `arrays`
/// arrays too; 0 without texgen) within `maxStorageBufferRange`, vertex indices below 2³¹.
fn device_capacity(gpu: &Gpu, reserve: u64, arrays: u64) -> u64 {
    let limits = gpu.properties().limits;
    let groups = u64::from(limits.max_compute_work_group_count[0]);
    let range = u64::from(limits.max_storage_buffer_range);
    // Every count is a u32 in the passes.
    let words = u64::from(u32::MAX);
    let triangles = (groups * u64::from(WORKGROUP))
        .min(range / TRIANGLE_BYTES)
        .min(words);
    let by_triangles = triangles.saturating_sub(reserve) / TRIANGLES_PER_VERTEX;
    by_triangles
        .min(range / RECORD_BYTES)
        .min(
            (range / EDGE_STATE_BYTES)
                .min(words)
                .saturating_sub(3 * reserve)
                / EDGES_PER_VERTEX,
        )
        .min(1 << 31)
        .min(range.checked_div(16 * arrays).unwrap_or(u64::MAX))
}

impl GpuTracer {
    /// Tessellates scene object `object` (`mesh`) from `request.camera` on the GPU, tracing
    /// every vertex there, waits for it and reads the mesh and its records back.
    ///
    /// `object` names `mesh` within the tracer's scene: the copy kept resident for it is reused
    /// while its vertex and triangle counts match, so a mesh that changes must come under
    /// another index. Splits stop at the vertex budget as on the CPU (`Budget` leaves); the
    /// device's limits stop them the same way, and only a device that cannot hold the input
    /// mesh and one split is an error. Buffers that stop splits before the budget are grown
    /// fourfold and the tessellation made again.
    pub fn tessellate(
        &self,
        gpu: &Gpu,
        (object, mesh): (usize, &TriangleMesh),
        request: &GpuTessellationRequest<'_>,
    ) -> Result<GpuTessellation, TessellationError> {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            let start = std::time::Instant::now();
            let made =
                self.submit_tessellation(gpu, &mut pass, (object, mesh), (request, false))?;
            pass.submissions.wait(made.submitted)?;
            let submission_ms = start.elapsed().as_secs_f64() * 1e3;
            if resident::read_counts(&made.part).capped_by_buffers && self.grow_locked(&mut pass) {
                continue;
            }
            let mut read = self.read_mesh(gpu, (&mut pass, object, mesh), &made.part, request)?;
            read.stage_ms = made.stage_ms;
            read.submission_ms = submission_ms;
            return Ok(read);
        }
    }

    /// [`Self::tessellate`] left on the device: the work that makes the mesh, the lens pass's
    /// data (when `request.texgen` asks) and the draw list, for the frame that draws the returned
    /// part to record first (timed, it is submitted and waited for here instead). Its counts are read once that frame
    /// is done ([`super::read_counts`]); where they say the buffers stopped splits before the
    /// budget, [`Self::grow`] gives the next tessellation larger ones.
    pub fn tessellate_on_device(
        &self,
        gpu: &Gpu,
        (object, mesh): (usize, &TriangleMesh),
        request: &GpuTessellationRequest<'_>,
    ) -> Result<DeviceTessellation, TessellationError> {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        let start = std::time::Instant::now();
        let mut made = self.submit_tessellation(gpu, &mut pass, (object, mesh), (request, true))?;
        made.submission_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(made)
    }

    /// Makes the buffers hold every scene object a frame is about to tessellate on the device,
    /// `objects` with the texgen arrays of each (made or grown now, at the frame's start), so
    /// that they are never made again between two of its objects: each object's work, recorded
    /// later by the frame, names them.
    pub fn prepare_frame(
        &self,
        gpu: &Gpu,
        objects: &[(usize, &TriangleMesh, u64)],
        options: &TessellationOptions,
    ) -> Result<(), TessellationError> {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        let state = &mut *pass;
        let mut last = None;
        for &(object, mesh, arrays) in objects {
            self.keep_input(gpu, state, (object, mesh))?;
            let extent = Extent::of(&state.objects[&object].input, arrays);
            state.extent = state.extent.max(extent);
            last = Some((object, arrays));
        }
        let Some((object, arrays)) = last else {
            return Ok(());
        };
        // The extent holds every object's needs: the buffers are sized for them all now.
        self.ensure_buffers(gpu, state, (object, arrays), (options.max_vertices, false))
    }

    /// Whether `part` is one of this tracer's outputs (a frame's counts grow the tracer that
    /// made its parts).
    pub fn made(&self, part: &Arc<DeviceLensPart>) -> bool {
        let pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        pass.objects
            .values()
            .any(|object| object.outputs.iter().any(|o| Arc::ptr_eq(&o.part, part)))
    }

    /// Asks for buffers four times larger (up to what the device holds) for the next
    /// tessellation, which makes them once every submission that uses the old ones completed;
    /// whether they will grow.
    pub fn grow(&self) -> bool {
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        self.grow_locked(&mut pass)
    }

    fn grow_locked(&self, state: &mut PassState) -> bool {
        let Some(scratch) = &state.tessellation else {
            return false;
        };
        let grown = (scratch.vertices_capacity * 4).min(state.device_limit);
        if grown <= scratch.vertices_capacity {
            return false;
        }
        state.capacity = grown;
        true
    }

    /// Scene object `object`'s input kept resident: uploaded unless it is, again where its mesh
    /// changed (after every submission that used the old one).
    fn keep_input(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        (object, mesh): (usize, &TriangleMesh),
    ) -> Result<(), TessellationError> {
        let stale = state.objects.get(&object).is_some_and(|o| {
            o.input.vertex_count as usize != mesh.positions.len()
                || o.input.triangle_count as usize != mesh.triangles.len()
        });
        if stale {
            state.submissions.wait_all()?;
            state.objects.remove(&object);
        }
        if let std::collections::hash_map::Entry::Vacant(slot) = state.objects.entry(object) {
            slot.insert(resident::ObjectState::new(gpu, InputMesh::new(gpu, mesh)?)?);
        }
        Ok(())
    }

    /// Makes the shared buffers hold scene object `object`'s input (made, or grown as asked,
    /// after every submission that used the old ones completed); an error where the device
    /// cannot hold the input and one split.
    fn ensure_buffers(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        (object, arrays): (usize, u64),
        (max_vertices, continue_budget): (usize, bool),
    ) -> Result<(), TessellationError> {
        let input = &state.objects[&object].input;
        let least = u64::from(input.vertex_count) + 4;
        let mine = Extent::of(input, arrays);
        // What the buffers hold only grows: every object tessellated so far fits.
        state.extent = state.extent.max(mine);
        let extent = state.extent;
        let device = device_capacity(gpu, extent.reserve, extent.arrays);
        if device < least {
            return Err(GpuError::BadUpload {
                what: "the GPU tessellation".into(),
                problem: format!(
                    "the device holds at most {device} vertices, too few for the mesh's {}; tessellate on the CPU",
                    input.vertex_count
                ),
            }
            .into());
        }
        state.device_limit = device;
        // The buffers are kept while they hold every input so far (grown only by `grow`); the
        // first are sized for the paper's setting, or the budget when smaller.
        let budget = (max_vertices as u64).max(extent.least);
        let wanted = match state.capacity {
            0 => FIRST_CAPACITY.min(budget),
            grown => grown,
        }
        .max(extent.least)
        .min(device);
        // Kept while they hold the inputs and no growth was asked for since they were made.
        let fits = state.tessellation.as_ref().is_some_and(|s| {
            s.holds(&extent)
                && s.vertices_capacity <= device
                && s.vertices_capacity == state.capacity
        });
        if fits {
            return Ok(());
        }
        if continue_budget {
            // The frame's earlier objects' work, not recorded yet, names these buffers, and
            // the budget word they carry: the frame must be prepared first (prepare_frame).
            return Err(GpuError::BadUpload {
                what: "the GPU tessellation".into(),
                problem: "its buffers would be made again between two objects of one frame; the frame was not prepared for all its objects".into(),
            }
            .into());
        }
        // Nothing submitted may still use the old buffers, nor the sets that point at them.
        state.submissions.wait_all()?;
        state.tessellation = None;
        state.tessellation = Some(Scratch::new(gpu, wanted, extent.reserve)?);
        state.capacity = wanted;
        for held in state.objects.values_mut() {
            held.forget_sets();
        }
        Ok(())
    }

    /// The work of one tessellation of `held`'s input into its output `at`, over `scratch`
    /// with the object's `sets`.
    fn work(
        &self,
        gpu: &Gpu,
        (scratch, held, at, sets): (
            &Scratch,
            &resident::ObjectState,
            usize,
            (vk::DescriptorSet, vk::DescriptorSet),
        ),
        request: &GpuTessellationRequest<'_>,
    ) -> TessellationWork {
        let options = request.options;
        let (input, outputs) = (&held.input, &held.outputs[at]);
        let levels = options.max_depth + 1;
        let mut first = first_control(input);
        // The budget word is the host's for the frame's first object (or where the host counts
        // the budget), else what the object before left on the device.
        let written = if request.continue_budget {
            control::FRAME_BUDGET
        } else {
            first[control::FRAME_BUDGET] = u32::try_from(options.max_vertices).unwrap_or(u32::MAX);
            control::FRAME_BUDGET + 1
        };
        let part = &outputs.part;
        TessellationWork {
            device: gpu.device().clone(),
            passes: [
                self.tessellation.handles.clone(),
                self.texgen.handles.clone(),
                self.draw_list.handles.clone(),
            ],
            level_paths: (self.level_paths, self.layout),
            sets: [
                sets.0,
                sets.1,
                outputs.texgen_set.unwrap_or_default(),
                outputs.draw_set,
            ],
            scratch: [
                scratch.control.handle,
                scratch.wanted.handle,
                scratch.counters.handle,
            ],
            part: [part.args.handle, part.counts.handle],
            input: [input.vertex_count, input.triangle_count, input.edge_count],
            levels,
            first: (first, written),
            tracer_constants: self.constants(request.camera, request.settings),
            constants: tessellate_constants(request, scratch, input),
            texgen: match (&request.texgen, outputs.texgen_set) {
                (Some(texgen), Some(_)) => Some(texgen.constants(input.vertex_count, part.stride)),
                _ => None,
            },
            draw: DrawConstants {
                eye: request.camera.eye.as_vec3().to_array(),
                hull_split: u32::from(request.hull.is_some()),
            },
            recorded: std::sync::atomic::AtomicBool::new(false),
        }
    }

    /// Records and submits one tessellation (the caller holds the pass state).
    fn submit_tessellation(
        &self,
        gpu: &Gpu,
        state: &mut PassState,
        (object, mesh): (usize, &TriangleMesh),
        (request, on_device): (&GpuTessellationRequest<'_>, bool),
    ) -> Result<DeviceTessellation, TessellationError> {
        self.check_device(gpu)?;
        let options = request.options;
        if options.validate().is_err() {
            return Err(TessellationError::InvalidThreshold(options.t));
        }
        if options.max_depth > GPU_MAX_DEPTH {
            return Err(crate::options::OptionError::new(
                crate::options::names::MAX_DEPTH,
                options.max_depth,
                "the GPU tessellation subdivides at most 30 levels deep; give 30 or less, or tessellate on the CPU",
            )
            .into());
        }
        self.keep_input(gpu, state, (object, mesh))?;
        let arrays = request.texgen.as_ref().map_or(0, TexgenRequest::arrays);
        let budget = (options.max_vertices, request.continue_budget);
        self.ensure_buffers(gpu, state, (object, arrays), budget)?;
        let hull: Vec<u32> = request
            .hull
            .map(|flags| flags.iter().map(|&f| u32::from(f)).collect())
            .unwrap_or_default();
        let shells = request.texgen.as_ref().map(TexgenRequest::shell_words);
        let held = state
            .objects
            .get_mut(&object)
            .ok_or_else(|| GpuError::BadUpload {
                what: "the GPU tessellation".into(),
                problem: "its mesh was not kept".into(),
            })?;
        if held.changes(&hull, shells.as_deref()) {
            state.submissions.wait_all()?;
            held.write_inputs(gpu, &hull, shells.as_deref())?;
        }
        let Some(scratch) = state.tessellation.as_ref() else {
            return Err(GpuError::BadUpload {
                what: "the GPU tessellation".into(),
                problem: "its buffers were not made".into(),
            }
            .into());
        };
        let geometry = self.geometry_resources();
        held.ensure_sets(
            gpu,
            (
                (self.set_layout, self.walk.bindings(), &geometry),
                self.tessellation.set_layout,
            ),
            scratch,
        )?;
        let sets = held.sets.ok_or_else(|| GpuError::BadUpload {
            what: "the GPU tessellation".into(),
            problem: "its sets were not made".into(),
        })?;
        let arrays = request.texgen.as_ref().map_or(0, TexgenRequest::arrays);
        let at = held.free_outputs(
            gpu,
            (self.texgen.set_layout, self.draw_list.set_layout),
            scratch,
            arrays,
        )?;
        let held = &*held;
        let part = held.outputs[at].part.clone();
        let work = self.work(gpu, (scratch, held, at, sets), request);
        let levels = options.max_depth + 1;
        let timed = self.timed.load(std::sync::atomic::Ordering::Relaxed);
        if on_device && !timed {
            // Recorded by the frame that draws the part, as a compute pass of its graph.
            return Ok(DeviceTessellation {
                part,
                work: Some(Arc::new(work)),
                stage_ms: None,
                submission_ms: 0.0,
                submitted: 0,
            });
        }
        let timestamps = match self.timestamp_bits {
            bits if bits > 0 && timed => Some(Timestamps::new(gpu, levels)?),
            _ => None,
        };
        let submitted = state.submissions.submit(gpu, |cb| {
            work.record_timed(cb, timestamps.as_ref());
            Ok(())
        })?;
        let stage_ms = match &timestamps {
            Some(timestamps) => {
                state.submissions.wait(submitted)?;
                let period = gpu.properties().limits.timestamp_period;
                Some(timestamps.read(self.timestamp_bits, period)?)
            }
            None => None,
        };
        Ok(DeviceTessellation {
            part,
            work: None,
            stage_ms,
            submission_ms: 0.0,
            submitted,
        })
    }
}

/// The tessellation passes' constants for `request` over `scratch` and `input`.
pub(super) fn tessellate_constants(
    request: &GpuTessellationRequest<'_>,
    scratch: &Scratch,
    input: &InputMesh,
) -> TessellateConstants {
    let camera = request.camera;
    TessellateConstants {
        view_proj: camera.view_proj.to_cols_array_2d(),
        eye: camera.eye.as_vec3().to_array(),
        t: request.options.t,
        cos_threshold: request.cos_threshold,
        max_depth: request.options.max_depth,
        vertex_capacity: scratch.vertices_capacity as u32,
        edge_capacity: scratch.edges_capacity as u32,
        triangle_capacity: scratch.triangles_capacity as u32,
        input_vertices: input.vertex_count,
        input_triangles: input.triangle_count,
        base_edges: input.edge_count,
        back_faces: u32::from(request.back_faces),
        ..bytemuck::Zeroable::zeroed()
    }
}

/// The control words a frame starts from: level 0 is the input triangles, its vertices the
/// input vertices.
pub(super) fn first_control(input: &InputMesh) -> [u32; control::WORDS] {
    let mut words = [0u32; control::WORDS];
    let (vertices, triangles, edges) = (input.vertex_count, input.triangle_count, input.edge_count);
    words[control::LEVEL_HI] = triangles;
    words[control::NEXT_HI] = triangles;
    words[control::VERTEX_HI] = vertices;
    words[control::VERTICES] = vertices;
    words[control::NEXT_VERTICES] = vertices;
    words[control::EDGES] = edges;
    words[control::NEXT_EDGES] = edges;
    words[control::SCAN_N] = triangles;
    words[control::INPUT_VERTICES] = vertices;
    let dispatches = [
        (control::DISPATCH_TRACE, vertices.div_ceil(WORKGROUP)),
        (control::DISPATCH_ELEMENTS, triangles.div_ceil(WORKGROUP)),
        (
            control::DISPATCH_BLOCKS,
            triangles.div_ceil(SCAN_BLOCK as u32),
        ),
    ];
    for (at, groups) in dispatches {
        words[at..at + 3].copy_from_slice(&[groups, 1, 1]);
    }
    words
}

impl GpuTracer {
    /// Reads the finished mesh of `part`'s tessellation back (a second, short submission: the
    /// sizes are known now) and builds the CPU tessellator's result from it. The tessellation's
    /// submission was waited for, and nothing was submitted since (the caller holds the state).
    fn read_mesh(
        &self,
        gpu: &Gpu,
        (state, object, mesh): (&mut PassState, usize, &TriangleMesh),
        part: &DeviceLensPart,
        request: &GpuTessellationRequest<'_>,
    ) -> Result<GpuTessellation, TessellationError> {
        let words = resident::count_words(part);
        let (Some(scratch), Some(held)) = (state.tessellation.as_mut(), state.objects.get(&object))
        else {
            return Err(GpuError::BadUpload {
                what: "the GPU tessellation".into(),
                problem: "its buffers were not kept".into(),
            }
            .into());
        };
        let input = &held.input;
        let vertex_count = u64::from(words[control::VERTICES]);
        let triangle_count = u64::from(words[control::LEVEL_HI]);
        let output_count = u64::from(words[control::OUTPUT]);
        let output_capacity = scratch.output_capacity();
        if output_count > output_capacity || vertex_count > scratch.vertices_capacity {
            return Err(GpuError::BadUpload {
                what: "the GPU tessellation".into(),
                problem: format!(
                    "it made {output_count} triangles and {vertex_count} vertices, past its buffers' {output_capacity} and {}",
                    scratch.vertices_capacity
                ),
            }
            .into());
        }
        let n_in = u64::from(input.vertex_count);
        // (source, offset in it, bytes): the mesh, then each array of the lens data.
        let mut parts = vec![
            (scratch.vertices.handle, 0, vertex_count * VERTEX_BYTES),
            (scratch.records.handle, 0, vertex_count * RECORD_BYTES),
            (scratch.wanted.handle, 0, 4 * n_in),
            (scratch.triangles.handle, 0, triangle_count * TRIANGLE_BYTES),
            (scratch.output.handle, 0, output_count * OUTPUT_BYTES),
        ];
        if let Some(texgen) = &request.texgen {
            let stride = 16 * u64::from(part.stride);
            for array in 0..texgen.arrays() {
                parts.push((part.data.handle, array * stride, 16 * vertex_count));
            }
        }
        let mut offsets = Vec::with_capacity(parts.len());
        let mut total = 0u64;
        for &(_, _, bytes) in &parts {
            offsets.push(total);
            total += bytes.next_multiple_of(16);
        }
        let readback = scratch.readback(gpu, total.max(16))?.handle;
        let device = gpu.device();
        gpu.submit_and_wait(|cb| {
            // SAFETY: the passes finished (their submission was waited for); the copies stay
            // within both buffers.
            unsafe {
                for (&(source, from, bytes), &offset) in parts.iter().zip(&offsets) {
                    if bytes > 0 {
                        device.cmd_copy_buffer(cb, source, readback, &[copy(from, offset, bytes)]);
                    }
                }
                barrier(device, cb, TRANSFER_TO_HOST);
            }
            Ok(())
        })?;
        let bytes = scratch.read_back();
        let slice = |i: usize| -> &[u32] {
            bytemuck::cast_slice(&bytes[offsets[i] as usize..(offsets[i] + parts[i].2) as usize])
        };
        let (vertex_words, record_words, wanted, triangles, output) =
            (slice(0), slice(1), slice(2), slice(3), slice(4));
        let counters = resident::read_counts(part).counters;
        let tessellation = assemble(
            mesh,
            Readback {
                vertices: vertex_words,
                records: record_words,
                wanted,
                triangles,
                output,
            },
            &words,
            &counters,
        );
        let terms = request.texgen.as_ref().map(|texgen| {
            let arrays: Vec<&[[f32; 4]]> = (5..parts.len())
                .map(|i| bytemuck::cast_slice(slice(i)))
                .collect();
            texgen::term_vertices(texgen, &arrays)
        });
        Ok(GpuTessellation {
            submission_ms: 0.0,
            stage_ms: None,
            tessellation,
            counters,
            terms,
        })
    }
}

/// A region of a buffer copy.
fn copy(src_offset: u64, dst_offset: u64, size: u64) -> vk::BufferCopy {
    vk::BufferCopy {
        src_offset,
        dst_offset,
        size,
    }
}
