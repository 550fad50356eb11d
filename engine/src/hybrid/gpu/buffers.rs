//! The GPU tessellation's buffers: a scene object's input mesh kept resident ([`InputMesh`]), and
//! the buffers every tessellation shares, sized in vertices of capacity ([`Scratch`]), with the
//! sizes the shaders' layouts give and the device's limits on them.

use glam::Vec3;
use lensmap_shaders::tessellate;
use rustc_hash::FxHashMap;

use crate::gpu::{Buffer, BufferUsage, Gpu, GpuError};
use crate::hybrid::tessellate::TessellationError;
use crate::scene::TriangleMesh;
use crate::trace::classes::ClassList;

/// Bytes of one vertex of the tessellation (position, normal: two vec4).
pub(super) const VERTEX_BYTES: u64 = 32;
/// Bytes of one vertex record of `terms` terms (vertex_paths.wgsl `write_term`): its term
/// records, at least two (the greedy terms; one per path class), then the screen position.
pub(super) fn record_bytes(terms: usize) -> u64 {
    lensmap_shaders::tracer::TERM_RECORD_BYTES as u64 * terms.max(2) as u64 + 16
}
/// Bytes of one triangle of a level (two vec4 of words).
pub(super) const TRIANGLE_BYTES: u64 = 32;
/// Bytes of an edge's ends, and of its split state (tessellate.wgsl `EdgeState`).
pub(super) const EDGE_END_BYTES: u64 = 8;
pub(super) const EDGE_STATE_BYTES: u64 = tessellate::EDGE_STATE_BYTES as u64;
/// Bytes of one element's counts in a prefix sum, and of one output triangle.
pub(super) const COUNT_BYTES: u64 = 16;
pub(super) const OUTPUT_BYTES: u64 = 16;
/// Words of the control buffer, and the tracer's counters.
pub(super) const CONTROL_WORDS: usize = tessellate::CONTROL_WORDS as usize;
pub(super) const COUNTERS: usize = tessellate::COUNTERS as usize;

// The control words hold every class term a set may have (two words each), before the frame's
// budget word: a tessellation that continues the frame's budget writes the words before it.
const _: () = assert!(tessellate::MAX_CLASSES as usize == crate::trace::classes::MAX_CLASSES);
const _: () = assert!(
    tessellate::CONTROL_CLASS_WORDS + 2 * tessellate::MAX_CLASSES
        <= tessellate::CONTROL_FRAME_BUDGET
);

/// Writes path classes `classes` into control words `words` (their count, then two words each;
/// none: the two greedy terms).
pub(super) fn write_classes(words: &mut [u32; CONTROL_WORDS], classes: &ClassList) {
    words[tessellate::CONTROL_CLASSES as usize] = classes.terms().len() as u32;
    for (at, word) in (tessellate::CONTROL_CLASS_WORDS as usize..).zip(classes.words()) {
        words[at] = word;
    }
}

/// Triangles (of every level) and edges the buffers hold per vertex of capacity.
const TRIANGLES_PER_VERTEX: u64 = 6;
const EDGES_PER_VERTEX: u64 = 5;

/// "No vertex / edge" (tessellate.wgsl `NONE`).
const NONE: u32 = tessellate::NONE;

/// `data` as the bytes of a storage buffer (at least one element, so every binding is valid).
pub(super) fn storage<T: bytemuck::Pod>(
    gpu: &Gpu,
    name: &str,
    data: &[T],
) -> Result<Buffer, GpuError> {
    let bytes: &[u8] = bytemuck::cast_slice(data);
    let padded = if bytes.is_empty() {
        &[0u8; 16][..]
    } else {
        bytes
    };
    Buffer::with_data(gpu, name, padded, BufferUsage::Storage)
}

/// Refuses a buffer of `vec4s` vec4 past the device's `maxStorageBufferRange`.
pub(super) fn check_range(gpu: &Gpu, what: &str, vec4s: usize) -> Result<(), GpuError> {
    let range = u64::from(gpu.properties().limits.max_storage_buffer_range);
    let bytes = 16 * vec4s as u64;
    if bytes > range {
        return Err(GpuError::BadUpload {
            what: what.into(),
            problem: format!(
                "{bytes} bytes, past the device's maxStorageBufferRange of {range}; trace this scene on the CPU"
            ),
        });
    }
    Ok(())
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
    pub(super) fn new(gpu: &Gpu, mesh: &TriangleMesh) -> Result<InputMesh, TessellationError> {
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
/// (and room for a split), input triangles (edges at most three times as many), texgen arrays
/// and bytes of a vertex record.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Extent {
    pub(super) least: u64,
    pub(super) reserve: u64,
    pub(super) arrays: u64,
    pub(super) record_bytes: u64,
}

impl Extent {
    /// What `input` with texgen arrays `arrays` and path-class terms `classes` (0: greedy)
    /// needs.
    pub(super) fn of(input: &InputMesh, arrays: u64, classes: usize) -> Extent {
        Extent {
            least: u64::from(input.vertex_count) + 4,
            reserve: u64::from(input.triangle_count).max(u64::from(input.edge_count).div_ceil(3)),
            arrays,
            record_bytes: record_bytes(classes),
        }
    }

    /// The larger of each.
    pub(super) fn max(self, other: Extent) -> Extent {
        Extent {
            least: self.least.max(other.least),
            reserve: self.reserve.max(other.reserve),
            arrays: self.arrays.max(other.arrays),
            record_bytes: self.record_bytes.max(other.record_bytes),
        }
    }
}

/// The buffers every tessellation shares, for up to `vertices_capacity` vertices (and the
/// derived triangles and edges).
pub(super) struct Scratch {
    pub(super) vertices_capacity: u64,
    pub(super) triangles_capacity: u64,
    pub(super) edges_capacity: u64,
    /// Bytes of the largest vertex record the records hold `vertices_capacity` of.
    pub(super) record_bytes: u64,
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
    /// The tracer's counters (`COUNTER_*`).
    pub(super) counters: Buffer,
    /// The host copy of a mesh read back (grown as needed).
    pub(super) readback: Option<Buffer>,
}

impl Scratch {
    /// Buffers for `vertices` vertices of records of up to `record_bytes` and an input of up to
    /// `reserve` triangles (its edges at most three times as many).
    pub(super) fn new(
        gpu: &Gpu,
        vertices: u64,
        reserve: u64,
        record_bytes: u64,
    ) -> Result<Scratch, GpuError> {
        let triangles = TRIANGLES_PER_VERTEX * vertices + reserve;
        let edges = EDGES_PER_VERTEX * vertices + 3 * reserve;
        let outputs = 2 * vertices + 2 * reserve;
        let device = |name: &str, bytes: u64| Buffer::new(gpu, name, bytes, BufferUsage::Device);
        let scan_block = u64::from(tessellate::SCAN_BLOCK);
        Ok(Scratch {
            vertices_capacity: vertices,
            triangles_capacity: triangles,
            edges_capacity: edges,
            record_bytes,
            vertices: device("tessellation vertices", vertices * VERTEX_BYTES)?,
            records: device("tessellation records", vertices * record_bytes)?,
            control: device("tessellation control", 4 * CONTROL_WORDS as u64)?,
            wanted: device("tessellation wanted", 4 * vertices)?,
            triangles: device("tessellation triangles", triangles * TRIANGLE_BYTES)?,
            edge_ends: device("tessellation edge ends", edges * EDGE_END_BYTES)?,
            edge_state: device("tessellation edge state", edges * EDGE_STATE_BYTES)?,
            counts: device("tessellation counts", triangles * COUNT_BYTES)?,
            block_sums: device(
                "tessellation block sums",
                triangles.div_ceil(scan_block) * COUNT_BYTES,
            )?,
            output: device("tessellation output", outputs * OUTPUT_BYTES)?,
            counters: device("tessellation tracer counters", 4 * COUNTERS as u64)?,
            readback: None,
        })
    }

    /// Whether it holds every input of `extent` in full (its vertices, triangles and edges, and
    /// a split).
    pub(super) fn holds(&self, extent: &Extent) -> bool {
        self.vertices_capacity >= extent.least
            && self.record_bytes >= extent.record_bytes
            && self.triangles_capacity
                >= TRIANGLES_PER_VERTEX * self.vertices_capacity + extent.reserve
            && self.edges_capacity >= EDGES_PER_VERTEX * self.vertices_capacity + 3 * extent.reserve
    }

    /// Output triangles the buffers hold.
    pub(super) fn output_capacity(&self) -> u64 {
        self.output.size / OUTPUT_BYTES
    }

    /// What the last copy to the host buffer left there (empty before the first).
    pub(super) fn read_back(&self) -> &[u8] {
        self.readback.as_ref().map(|b| b.read()).unwrap_or_default()
    }

    /// A host buffer of at least `bytes`.
    pub(super) fn readback(&mut self, gpu: &Gpu, bytes: u64) -> Result<&Buffer, GpuError> {
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

/// The largest capacity, in vertices, the device can dispatch and bind for `extent`'s inputs:
/// room for `reserve` triangles (and three times as many edges), every per-triangle pass within
/// `maxComputeWorkGroupCount[0]` workgroups, every buffer (the records of `record_bytes`,
/// texgen's lens data of `arrays` arrays too; 0 without texgen) within `maxStorageBufferRange`,
/// vertex indices below 2³¹.
pub(super) fn device_capacity(gpu: &Gpu, extent: &Extent) -> u64 {
    let Extent {
        reserve,
        arrays,
        record_bytes,
        ..
    } = *extent;
    let limits = gpu.properties().limits;
    let groups = u64::from(limits.max_compute_work_group_count[0]);
    let range = u64::from(limits.max_storage_buffer_range);
    // Every count is a u32 in the passes.
    let words = u64::from(u32::MAX);
    let triangles = (groups * u64::from(tessellate::WORKGROUP))
        .min(range / TRIANGLE_BYTES)
        .min(words);
    let by_triangles = triangles.saturating_sub(reserve) / TRIANGLES_PER_VERTEX;
    by_triangles
        .min(range / record_bytes.max(1))
        .min(
            (range / EDGE_STATE_BYTES)
                .min(words)
                .saturating_sub(3 * reserve)
                / EDGES_PER_VERTEX,
        )
        .min(1 << 31)
        .min(range.checked_div(16 * arrays).unwrap_or(u64::MAX))
}
