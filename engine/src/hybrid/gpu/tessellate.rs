//! The adaptive tessellation on the GPU (`shaders/wgsl/tessellate.wgsl`): the CPU tessellator's
//! rules ([`crate::hybrid::tessellate`]) level by level in compute passes, the vertex paths
//! traced by the tracer's level pass between them, every record kept on the GPU, all in one
//! submission. The mesh and its records are then read back once.
//!
//! Determinism: midpoint, edge and triangle indices come from stable prefix sums over each
//! level's triangles (in the CPU's order), and a midpoint belongs to the lowest-indexed triangle
//! that asks for it (an atomic minimum, whose result does not depend on the order the atomics
//! land in); so the output is identical run to run, and a midpoint gets the index the CPU gives
//! it where the decisions agree.
//!
//! Capacity: the buffers hold a fixed number of vertices (and six triangles and five edges per
//! vertex), grown fourfold and the frame redone whenever a frame would pass them before the
//! vertex budget, up to the budget or what the device can dispatch. Past the budget, splits stop
//! as on the CPU ([`StopReason::Budget`]).

use ash::vk;
use glam::Vec3;
use lensmap_shaders::{TessellateConstants, TexgenConstants};
use rustc_hash::FxHashMap;

use super::assemble::{Readback, assemble};
use super::recorder::{Recorder, Timestamps};
use super::texgen::{self, TexgenRequest};
use super::{
    COMPUTE_TO_TRANSFER, GpuTracer, PathSettings, STORAGE, TRANSFER_TO_COMPUTE, TRANSFER_TO_HOST,
    WORKGROUP, barrier, storage,
};
use crate::gpu::{Buffer, BufferUsage, Gpu, GpuError};
use crate::hybrid::paths::{ScreenCamera, VertexPaths};
use crate::hybrid::tessellate::{Tessellation, TessellationError, TessellationOptions};
use crate::render::TermVertices;
use crate::render::descriptors::{Binding, DescriptorPool, Resource, create_set_layout, write_set};
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

/// The passes of tessellate.wgsl, in the order [`PASSES`] names them.
const PASSES: [&str; 12] = [
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

/// Index of `name` in [`PASSES`] (a typo fails the tests, which run every pass).
pub(super) fn pass(name: &str) -> usize {
    PASSES.iter().position(|&p| p == name).unwrap_or(0)
}

/// The tessellation's pipelines on one device.
pub(super) struct TessellationPasses {
    device: ash::Device,
    set_layout: vk::DescriptorSetLayout,
    pub(super) layout: vk::PipelineLayout,
    pub(super) pipelines: Vec<vk::Pipeline>,
}

impl Drop for TessellationPasses {
    fn drop(&mut self) {
        // SAFETY: the owner waited for every submission that used them.
        unsafe {
            for &pipeline in &self.pipelines {
                self.device.destroy_pipeline(pipeline, None);
            }
            self.device.destroy_pipeline_layout(self.layout, None);
            self.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

impl TessellationPasses {
    pub(super) fn new(gpu: &Gpu) -> Result<TessellationPasses, GpuError> {
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
        let set_layout = create_set_layout(gpu, TESSELLATE_SET)?;
        let mut passes = TessellationPasses {
            device: gpu.device().clone(),
            set_layout,
            layout: vk::PipelineLayout::null(),
            pipelines: Vec::new(),
        };
        passes.layout = super::compute_layout::<TessellateConstants>(gpu, set_layout)?;
        for entry in PASSES {
            let shader = lensmap_shaders::shader("tessellate", entry).ok_or_else(|| {
                GpuError::BadUpload {
                    what: "tessellate.wgsl".into(),
                    problem: format!("entry point {entry} was not compiled"),
                }
            })?;
            let pipeline = gpu.create_compute_pipeline(&shader, passes.layout)?;
            passes.pipelines.push(pipeline);
        }
        Ok(passes)
    }
}

/// A scene object's mesh as the passes read it, resident: its vertices with the normals the CPU
/// tessellator uses, its triangles with their edges, and its edges.
pub(super) struct InputMesh {
    vertices: Buffer,
    triangles: Buffer,
    edges: Buffer,
    vertex_count: u32,
    triangle_count: u32,
    edge_count: u32,
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

/// The frame's buffers for up to `vertices` vertices (and the derived triangles and edges).
pub(super) struct Scratch {
    vertices_capacity: u64,
    triangles_capacity: u64,
    edges_capacity: u64,
    vertices: Buffer,
    records: Buffer,
    control: Buffer,
    wanted: Buffer,
    triangles: Buffer,
    edge_ends: Buffer,
    edge_state: Buffer,
    counts: Buffer,
    block_sums: Buffer,
    output: Buffer,
    /// The tracer's counters (tracer.wgsl `COUNTER_*`).
    counters: Buffer,
    /// Texgen's output, the lens pass's data (grown as a request needs).
    lens_data: Option<Buffer>,
    /// Texgen's layer shells (host-visible, rewritten each frame, grown as needed).
    shells: Option<Buffer>,
    /// Host copies: the control words and tracer counters, then the mesh (grown as needed).
    readback: Option<Buffer>,
}

impl Scratch {
    fn new(gpu: &Gpu, vertices: u64, input: &InputMesh) -> Result<Scratch, GpuError> {
        let triangles = TRIANGLES_PER_VERTEX * vertices + u64::from(input.triangle_count);
        let edges = EDGES_PER_VERTEX * vertices + u64::from(input.edge_count);
        let outputs = 2 * vertices + 2 * u64::from(input.triangle_count);
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
            lens_data: None,
            shells: None,
            readback: None,
        })
    }

    /// Whether it holds `input` in full (every input vertex, triangle and edge, and a split).
    fn holds(&self, input: &InputMesh) -> bool {
        self.vertices_capacity > u64::from(input.vertex_count) + 3
            && self.triangles_capacity
                >= TRIANGLES_PER_VERTEX * self.vertices_capacity + u64::from(input.triangle_count)
            && self.edges_capacity
                >= EDGES_PER_VERTEX * self.vertices_capacity + u64::from(input.edge_count)
    }

    /// Makes the lens data buffer hold at least `bytes`; refused past the device's
    /// `maxStorageBufferRange`.
    fn ensure_lens_data(&mut self, gpu: &Gpu, bytes: u64) -> Result<(), GpuError> {
        let range = u64::from(gpu.properties().limits.max_storage_buffer_range);
        if bytes > range {
            return Err(GpuError::BadUpload {
                what: "the GPU texgen's lens data".into(),
                problem: format!(
                    "{bytes} bytes for this many vertices and layers, past the device's maxStorageBufferRange of {range}; trace on the CPU or lower the vertex budget"
                ),
            });
        }
        if self.lens_data.as_ref().is_none_or(|b| b.size < bytes) {
            self.lens_data = None;
            self.lens_data = Some(Buffer::new(
                gpu,
                "tessellation lens data",
                bytes,
                BufferUsage::Device,
            )?);
        }
        Ok(())
    }

    /// Writes texgen's shells into their buffer, made or grown first where it is too small.
    fn write_shells(&mut self, gpu: &Gpu, words: &[[f32; 4]]) -> Result<(), GpuError> {
        let bytes: &[u8] = bytemuck::cast_slice(words);
        if self
            .shells
            .as_ref()
            .is_none_or(|b| b.size < bytes.len() as u64)
        {
            self.shells = None;
            self.shells = Some(Buffer::new(
                gpu,
                "texgen shells",
                bytes.len() as u64,
                BufferUsage::Storage,
            )?);
        }
        match &mut self.shells {
            Some(buffer) => buffer.write(0, bytes, "texgen shells"),
            None => Ok(()),
        }
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

/// The descriptor pools of a tessellation's sets: the tracer's level pass, the tessellation's
/// passes, texgen.
pub(super) struct Pools<'a> {
    pub(super) tracer: &'a DescriptorPool,
    pub(super) tessellation: &'a DescriptorPool,
    pub(super) texgen: &'a DescriptorPool,
}

/// The largest capacity, in vertices, the device can dispatch and bind: every per-triangle pass
/// within `maxComputeWorkGroupCount[0]` workgroups, every buffer (texgen's lens data too, when
/// asked for) within `maxStorageBufferRange`, vertex indices below 2³¹.
fn device_capacity(gpu: &Gpu, input: &InputMesh, texgen: Option<&TexgenRequest<'_>>) -> u64 {
    let limits = gpu.properties().limits;
    let groups = u64::from(limits.max_compute_work_group_count[0]);
    let range = u64::from(limits.max_storage_buffer_range);
    // Every count is a u32 in the passes.
    let words = u64::from(u32::MAX);
    let triangles = (groups * u64::from(WORKGROUP))
        .min(range / TRIANGLE_BYTES)
        .min(words);
    let by_triangles =
        triangles.saturating_sub(u64::from(input.triangle_count)) / TRIANGLES_PER_VERTEX;
    by_triangles
        .min(range / RECORD_BYTES)
        .min(
            (range / EDGE_STATE_BYTES)
                .min(words)
                .saturating_sub(u64::from(input.edge_count))
                / EDGES_PER_VERTEX,
        )
        .min(1 << 31)
        .min(texgen.map_or(u64::MAX, |t| range / (16 * t.arrays())))
}

impl GpuTracer {
    /// Tessellates scene object `object` (`mesh`) from `request.camera` on the GPU, tracing
    /// every vertex there, and reads the mesh and its records back.
    ///
    /// `object` names `mesh` within the tracer's scene: the copy kept resident for it is reused
    /// while its vertex and triangle counts match, so a mesh that changes must come under
    /// another index. Splits stop at the vertex budget as on the CPU (`Budget` leaves); the
    /// device's limits stop them the same way, and only a device that cannot hold the input
    /// mesh and one split is an error.
    pub fn tessellate(
        &self,
        gpu: &Gpu,
        (object, mesh): (usize, &TriangleMesh),
        request: &GpuTessellationRequest<'_>,
    ) -> Result<GpuTessellation, TessellationError> {
        self.check_device(gpu)?;
        let options = request.options;
        if options.validate().is_err() {
            return Err(TessellationError::InvalidThreshold(options.t));
        }
        if options.max_depth > GPU_MAX_DEPTH {
            return Err(crate::options::OptionError::new(
                "max_depth",
                options.max_depth,
                "the GPU tessellation subdivides at most 30 levels deep; give 30 or less, or tessellate on the CPU",
            )
            .into());
        }
        let mut pass = self.pass.lock().unwrap_or_else(|e| e.into_inner());
        let state = &mut *pass;
        let stale = state.meshes.get(&object).is_some_and(|m| {
            m.vertex_count as usize != mesh.positions.len()
                || m.triangle_count as usize != mesh.triangles.len()
        });
        if stale {
            state.meshes.remove(&object);
        }
        let input = match state.meshes.entry(object) {
            std::collections::hash_map::Entry::Occupied(held) => held.into_mut(),
            std::collections::hash_map::Entry::Vacant(slot) => {
                slot.insert(InputMesh::new(gpu, mesh)?)
            }
        };
        let input = &*input;
        let least = u64::from(input.vertex_count) + 4;
        let device = device_capacity(gpu, input, request.texgen.as_ref());
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
        // A spent budget still gets buffers for the input (and refuses every split).
        let budget = (options.max_vertices as u64).max(u64::from(input.vertex_count));
        let ceiling = budget.min(device).max(least);
        let held = state
            .tessellation
            .as_ref()
            .filter(|s| s.holds(input) && s.vertices_capacity <= device)
            .map(|s| s.vertices_capacity);
        let mut capacity = held.unwrap_or(FIRST_CAPACITY.max(least).min(ceiling));
        loop {
            if state.tessellation.as_ref().map(|s| s.vertices_capacity) != Some(capacity)
                || held.is_none()
            {
                // The old buffers go before the new ones are made.
                state.tessellation = None;
                state.tessellation = Some(Scratch::new(gpu, capacity, input)?);
            }
            let scratch = state
                .tessellation
                .as_mut()
                .ok_or_else(|| GpuError::BadUpload {
                    what: "the GPU tessellation".into(),
                    problem: "its buffers were not made".into(),
                })?;
            if let Some(texgen) = &request.texgen {
                scratch.ensure_lens_data(gpu, capacity * texgen.arrays() * 16)?;
            }
            let pools = Pools {
                tracer: &state.pool,
                tessellation: &state.tessellation_pool,
                texgen: &state.texgen_pool,
            };
            let start = std::time::Instant::now();
            let (words, stage_ms) =
                self.run_levels(gpu, (&pools, scratch, input), request, capacity.min(budget))?;
            let submission_ms = start.elapsed().as_secs_f64() * 1e3;
            if words[control::BUDGET] > 0 && capacity < ceiling {
                // The buffers, not the budget, stopped the splits: again with larger ones.
                capacity = (capacity * 4).min(ceiling);
                continue;
            }
            let mut made =
                self.read_mesh(gpu, (scratch, input, mesh), request.texgen.as_ref(), &words)?;
            made.stage_ms = stage_ms;
            made.submission_ms = submission_ms;
            return Ok(made);
        }
    }
}

/// The tessellation passes' constants for `request` over `scratch` and `input`.
fn tessellate_constants(
    request: &GpuTessellationRequest<'_>,
    scratch: &Scratch,
    input: &InputMesh,
    vertex_capacity: u64,
) -> TessellateConstants {
    let camera = request.camera;
    TessellateConstants {
        view_proj: camera.view_proj.to_cols_array_2d(),
        eye: camera.eye.as_vec3().to_array(),
        t: request.options.t,
        cos_threshold: request.cos_threshold,
        max_depth: request.options.max_depth,
        vertex_capacity: vertex_capacity as u32,
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
fn first_control(input: &InputMesh) -> [u32; control::WORDS] {
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
    /// The tracer's level pass's set and the tessellation's, over `scratch` and `input`.
    fn sets(
        &self,
        gpu: &Gpu,
        pools: &Pools<'_>,
        scratch: &Scratch,
        input: &InputMesh,
    ) -> Result<(vk::DescriptorSet, vk::DescriptorSet), GpuError> {
        let passes = &self.tessellation;
        let (pool, tessellation_pool) = (pools.tracer, pools.tessellation);
        pool.reset()?;
        tessellation_pool.reset()?;
        let tracer_set = pool.allocate(self.set_layout, 1)?[0];
        let tracer_resources: Vec<Resource> = [
            &self.nodes,
            &self.triangles,
            &self.materials,
            &self.roots,
            &self.schlick,
            &scratch.vertices,
            &scratch.records,
            &scratch.counters,
            &scratch.control,
            &scratch.wanted,
        ]
        .iter()
        .map(|b| Resource::Buffer(b.handle))
        .collect();
        write_set(gpu, tracer_set, super::TRACER_SET, &tracer_resources);
        let set = tessellation_pool.allocate(passes.set_layout, 1)?[0];
        let resources: Vec<Resource> = [
            &scratch.vertices,
            &scratch.records,
            &scratch.control,
            &scratch.wanted,
            &scratch.triangles,
            &scratch.edge_ends,
            &scratch.edge_state,
            &scratch.counts,
            &scratch.block_sums,
            &scratch.output,
            &input.vertices,
            &input.triangles,
            &input.edges,
        ]
        .iter()
        .map(|b| Resource::Buffer(b.handle))
        .collect();
        write_set(gpu, set, TESSELLATE_SET, &resources);
        Ok((tracer_set, set))
    }

    /// The texgen pass's set over `scratch` and the request's shells (written into `scratch`),
    /// and its constants.
    fn texgen_set(
        &self,
        gpu: &Gpu,
        pool: &DescriptorPool,
        scratch: &mut Scratch,
        (input, request): (&InputMesh, &TexgenRequest<'_>),
    ) -> Result<(vk::DescriptorSet, TexgenConstants), GpuError> {
        scratch.write_shells(gpu, &request.shell_words())?;
        let (Some(data), Some(shells)) = (&scratch.lens_data, &scratch.shells) else {
            return Err(GpuError::BadUpload {
                what: "the GPU texgen".into(),
                problem: "its buffers were not made".into(),
            });
        };
        pool.reset()?;
        let set = pool.allocate(self.texgen.set_layout, 1)?[0];
        let resources: Vec<Resource> = [
            &scratch.vertices,
            &scratch.records,
            &scratch.wanted,
            shells,
            data,
            &scratch.control,
        ]
        .iter()
        .map(|b| Resource::Buffer(b.handle))
        .collect();
        write_set(gpu, set, texgen::TEXGEN_SET, &resources);
        let constants = request.constants(input.vertex_count, scratch.vertices_capacity as u32);
        Ok((set, constants))
    }

    /// Records and runs every level and the T-junction removal in one submission; returns the
    /// control words, then the tracer's three counters.
    fn run_levels(
        &self,
        gpu: &Gpu,
        (pools, scratch, input): (&Pools<'_>, &mut Scratch, &InputMesh),
        request: &GpuTessellationRequest<'_>,
        vertex_capacity: u64,
    ) -> Result<(Vec<u32>, Option<GpuStageMs>), GpuError> {
        let passes = &self.tessellation;
        let (tracer_set, set) = self.sets(gpu, pools, scratch, input)?;
        let texgen = match &request.texgen {
            Some(texgen) => Some(self.texgen_set(gpu, pools.texgen, scratch, (input, texgen))?),
            None => None,
        };
        let tracer_constants = self.constants(request.camera, request.settings);
        let constants = tessellate_constants(request, scratch, input, vertex_capacity);
        let first = first_control(input);
        let levels = request.options.max_depth + 1;
        let timed = self.timed.load(std::sync::atomic::Ordering::Relaxed);
        let timestamps = match self.timestamp_bits {
            bits if bits > 0 && timed => Some(Timestamps::new(gpu, levels)?),
            _ => None,
        };
        let readback = scratch
            .readback(gpu, 4 * (control::WORDS as u64 + 4))?
            .handle;
        let device = gpu.device();
        let scratch = &*scratch;
        gpu.submit_and_wait(|cb| {
            let recorder = Recorder {
                device,
                cb,
                passes,
                set,
                constants: &constants,
                control: scratch.control.handle,
                timestamps: timestamps.as_ref(),
                bound: std::cell::Cell::new(false),
            };
            // SAFETY: every handle is live until the wait returns; a barrier separates every
            // pass from the next, and the copies from the passes.
            unsafe {
                device.cmd_update_buffer(cb, recorder.control, 0, bytemuck::cast_slice(&first));
                device.cmd_fill_buffer(
                    cb,
                    scratch.wanted.handle,
                    0,
                    4 * u64::from(input.vertex_count).max(1),
                    0,
                );
                device.cmd_fill_buffer(cb, scratch.counters.handle, 0, vk::WHOLE_SIZE, 0);
                if let Some(timestamps) = &timestamps {
                    device.cmd_reset_query_pool(cb, timestamps.pool, 0, 4 * levels + 4);
                }
                barrier(device, cb, TRANSFER_TO_COMPUTE);
                recorder.groups("cs_begin", input.vertex_count.max(input.edge_count));
                recorder.groups("cs_classify", input.triangle_count);
                for level in 0..levels {
                    // The level's new vertices, by the tracer's pass (its own layout and set).
                    recorder.stamp(4 * level);
                    device.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, self.level_paths);
                    device.cmd_bind_descriptor_sets(
                        cb,
                        vk::PipelineBindPoint::COMPUTE,
                        self.layout,
                        0,
                        &[tracer_set],
                        &[],
                    );
                    device.cmd_push_constants(
                        cb,
                        self.layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        bytemuck::bytes_of(&tracer_constants),
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
                if let Some((texgen_set, texgen_constants)) = &texgen {
                    let layout = self.texgen.layout;
                    device.cmd_bind_pipeline(
                        cb,
                        vk::PipelineBindPoint::COMPUTE,
                        self.texgen.pipeline,
                    );
                    device.cmd_bind_descriptor_sets(
                        cb,
                        vk::PipelineBindPoint::COMPUTE,
                        layout,
                        0,
                        &[*texgen_set],
                        &[],
                    );
                    device.cmd_push_constants(
                        cb,
                        layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        bytemuck::bytes_of(texgen_constants),
                    );
                    // Over every vertex: cs_leaves_begin set the trace arguments so.
                    recorder.dispatch_indirect(control::DISPATCH_TRACE);
                }
                recorder.stamp(4 * levels + 3);
                barrier(device, cb, COMPUTE_TO_TRANSFER);
                let words = 4 * control::WORDS as u64;
                device.cmd_copy_buffer(cb, recorder.control, readback, &[copy(0, 0, words)]);
                device.cmd_copy_buffer(
                    cb,
                    scratch.counters.handle,
                    readback,
                    &[copy(0, words, 4 * super::COUNTERS as u64)],
                );
                barrier(device, cb, TRANSFER_TO_HOST);
            }
            Ok(())
        })?;
        let bytes = scratch.read_back();
        let words: &[u32] = bytemuck::cast_slice(&bytes[..4 * (control::WORDS + super::COUNTERS)]);
        let period = gpu.properties().limits.timestamp_period;
        let stage_ms = match &timestamps {
            Some(timestamps) => Some(timestamps.read(self.timestamp_bits, period)?),
            None => None,
        };
        Ok((words.to_vec(), stage_ms))
    }

    /// Reads the finished mesh back (a second, short submission: the sizes are known now) and
    /// builds the CPU tessellator's result from it.
    fn read_mesh(
        &self,
        gpu: &Gpu,
        (scratch, input, mesh): (&mut Scratch, &InputMesh, &TriangleMesh),
        texgen: Option<&TexgenRequest<'_>>,
        words: &[u32],
    ) -> Result<GpuTessellation, TessellationError> {
        let vertex_count = u64::from(words[control::VERTICES]);
        let triangle_count = u64::from(words[control::LEVEL_HI]);
        let output_count = u64::from(words[control::OUTPUT]);
        let output_capacity = scratch.output.size / OUTPUT_BYTES;
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
        if let (Some(texgen), Some(data)) = (texgen, &scratch.lens_data) {
            let stride = 16 * scratch.vertices_capacity;
            for array in 0..texgen.arrays() {
                parts.push((data.handle, array * stride, 16 * vertex_count));
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
            // SAFETY: the passes finished (the last submission was waited for); the copies
            // stay within both buffers.
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
        let counters = TraceCounters {
            primary_rays: u64::from(words[control::WORDS]),
            secondary_rays: u64::from(words[control::WORDS + 1]),
            shadow_rays: 0,
            triangle_tests: u64::from(words[control::WORDS + 2]),
        };
        let tessellation = assemble(
            mesh,
            Readback {
                vertices: vertex_words,
                records: record_words,
                wanted,
                triangles,
                output,
            },
            words,
            &counters,
        );
        let terms = texgen.map(|request| {
            let arrays: Vec<&[[f32; 4]]> = (5..parts.len())
                .map(|i| bytemuck::cast_slice(slice(i)))
                .collect();
            texgen::term_vertices(request, &arrays)
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
