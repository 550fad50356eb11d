//! Adaptive tessellation of a lens object's mesh (hybrid-rendering paper §5, "Adaptive
//! Tessellation", Figures 5 and 6).
//!
//! Ray tracing only at a lens object's vertices misses ray-path changes between them, so a
//! triangle whose vertices' samples *differ* (the caller decides: path topology, or outgoing
//! directions more than 3° apart) is split at the midpoints of its edges, recursively, until the
//! samples agree or its screen-projected edges are shorter than `t` subpixels. Only the long
//! edges get midpoints: 1-to-4 when all three edges are long, 1-to-3 and 1-to-2 when only some
//! are. Midpoints lie on the flat input triangle (linear interpolation of positions, normals and
//! texture coordinates, normals renormalized), so area and orientation are preserved exactly up
//! to rounding.
//!
//! The per-vertex work (ray tracing in the runtime) is the caller's [`VertexOracle`]. Each vertex
//! is evaluated exactly once: input vertices of front-facing triangles are evaluated up front
//! (vertices whose triangles are all back-facing never are, unless the oracle asks for back
//! faces too: [`VertexOracle::evaluates_back_faces`]), and every midpoint is created once
//! through an **edge hash table** keyed by the sorted vertex-index pair, so a neighbour that splits
//! the same edge reuses the midpoint and its sample. Subdivision proceeds level by level and the
//! new vertices of each level are handed to [`VertexOracle::evaluate_batch`] together, which a
//! runtime can evaluate in parallel.
//!
//! **Parallel and deterministic.** Each level runs in two phases: the split decisions of all
//! active triangles are made in parallel (they only read the evaluations), then the midpoints are
//! created in one ordered pass over the decisions (the edge table is an `FxHashMap`, not
//! SipHash), so a midpoint's index is the same whatever the thread count. Front-facing tests,
//! screen projections and T-junction removal (per leaf, reading the finished edge table) are
//! parallel too, and their results are gathered in input order: the output is identical for
//! any number of threads.
//!
//! **T-junction removal** follows the paper: once subdivision stops, the edge hash is queried
//! recursively along each edge of every leaf triangle, which yields all vertices a more finely
//! subdivided neighbour placed on that edge. A leaf with such extra vertices is a convex polygon
//! whose vertices all lie on its three sides; it is re-triangulated without new vertices by
//! clipping ears, always the ear with the shortest closing chord, and only ears whose two
//! neighbours do not lie on a common side of the leaf. That rule is exact (it uses which sides a
//! vertex lies on, not floating-point tests) and guarantees that no output triangle is degenerate
//! and that no vertex lies on a chord, so the result is watertight and free of T-junctions, with
//! every triangle wound like its source triangle.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use crate::scene::TriangleMesh;

/// The default screen-space edge threshold `t`, in subpixels (the runtime's `--t`).
pub const DEFAULT_T: f32 = 3.0;

/// The default [`TessellationOptions::max_depth`]: 12 levels shrink an edge 4096-fold, enough to
/// take a 2000-subpixel input edge below half a subpixel.
pub const DEFAULT_MAX_DEPTH: u32 = 12;

/// The default [`TessellationOptions::max_vertices`]: some 16 million vertex rays (a few seconds
/// on two cores), fifteen times what the paper's setting needs (teapot-room at 1920×1440
/// subpixels, t = 3: ~130,000 vertices), so it only bounds runaway requests such as t = 1e-6.
pub const DEFAULT_MAX_VERTICES: usize = 2_000_000;

/// How finely [`tessellate`] subdivides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TessellationOptions {
    /// Screen-space edge threshold in subpixels (pixels × supersampling factor per axis): a
    /// triangle whose vertices differ is split until its projected edges are shorter than `t`.
    /// Finite and positive; the paper uses 3 and 5.
    pub t: f32,
    /// Safety cap on the subdivision depth of any input triangle (0 = never split). Subdivision
    /// normally stops at `t` well before this; the cap only bounds work for an oracle whose
    /// screen projection misbehaves. Triangles stopped by it report [`StopReason::MaxDepth`].
    pub max_depth: u32,
    /// Budget of output vertices (each is ray traced): once the mesh holds this many, no
    /// triangle is split further and the rest report [`StopReason::Budget`] — the tessellation
    /// degrades to a coarser one instead of running away. Splits are taken in a fixed order, so
    /// where the budget ends does not depend on the thread count.
    pub max_vertices: usize,
}

impl Default for TessellationOptions {
    fn default() -> Self {
        TessellationOptions {
            t: DEFAULT_T,
            max_depth: DEFAULT_MAX_DEPTH,
            max_vertices: DEFAULT_MAX_VERTICES,
        }
    }
}

impl TessellationOptions {
    /// The one check of `t`: finite and positive.
    pub fn validate(&self) -> Result<(), crate::options::OptionError> {
        crate::options::OptionError::require(
            self.t.is_finite() && self.t > 0.0,
            crate::options::names::T,
            self.t,
            "give a positive number of subpixels, e.g. 3",
        )
    }
}

/// A vertex of the tessellated surface as handed to the [`VertexOracle`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceVertex {
    /// Index of this vertex in the output mesh (input vertices keep their index).
    pub index: u32,
    /// World-space position in metres; on the flat input triangle for midpoints.
    pub position: Vec3,
    /// Unit shading normal: the input normal, or for a midpoint the renormalized sum of its
    /// edge's endpoint normals.
    pub normal: Vec3,
    /// Texture coordinate, linearly interpolated; `None` when the input mesh has none.
    pub uv: Option<Vec2>,
}

/// What the oracle computed at one vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexEvaluation<S> {
    /// The caller's per-vertex data (in the runtime: the two ray paths and their outgoing rays).
    pub sample: S,
    /// Whether the vertex is directly visible from the viewpoint. A triangle whose three vertices
    /// are all invisible is not subdivided further.
    pub visible: bool,
}

/// The caller's per-vertex evaluator and camera: what makes two vertices "different", where a
/// point lands on screen and which triangles face the camera.
pub trait VertexOracle {
    /// Per-vertex data, computed once per vertex.
    type Sample;

    /// Computes the sample at one vertex (in the runtime: ray traces it).
    fn evaluate(&self, vertex: &SurfaceVertex) -> Self::Sample;

    /// Whether the vertex is directly visible from the viewpoint (a visibility ray query).
    /// Everything is visible unless overridden.
    fn visible(&self, vertex: &SurfaceVertex) -> bool {
        let _ = vertex;
        true
    }

    /// Evaluates a batch of new vertices; must return one evaluation per vertex, in order, or
    /// the error that stopped it (a GPU's). The default calls [`VertexOracle::evaluate`] and
    /// [`VertexOracle::visible`] in sequence; a runtime may override it to evaluate in parallel,
    /// or on a GPU.
    fn evaluate_batch(
        &self,
        vertices: &[SurfaceVertex],
    ) -> Result<Vec<VertexEvaluation<Self::Sample>>, TessellationError> {
        Ok(vertices
            .iter()
            .map(|vertex| VertexEvaluation {
                sample: self.evaluate(vertex),
                visible: self.visible(vertex),
            })
            .collect())
    }

    /// Whether two vertices' samples are different enough that the triangle between them must be
    /// subdivided (the paper: different path topology, or outgoing rays more than 3° apart, for
    /// either shading term).
    fn differ(&self, a: &Self::Sample, b: &Self::Sample) -> bool;

    /// Projected position of a world-space point in subpixels (pixel × supersampling), or `None`
    /// when it cannot be projected (behind the camera). An edge with an endpoint that has no
    /// projection, or a non-finite one, counts as short: its length on screen is unknown.
    fn screen(&self, position: Vec3) -> Option<Vec2>;

    /// Whether the input triangle with these world-space corners (counter-clockwise seen from its
    /// front) faces the camera. Only front-facing triangles are evaluated and subdivided. Asked
    /// once per input triangle: the pieces of a flat triangle face the same way. For a pinhole
    /// camera at `eye` this is [`faces_eye`].
    fn front_facing(&self, corners: [Vec3; 3]) -> bool;

    /// Whether back-facing input triangles are evaluated and subdivided like front-facing ones
    /// (they still count as back-facing in [`TessellationStats`]). An open surface can be seen
    /// from behind (the inside of the teapot through the gap between lid and rim), so its back
    /// faces must be shaded; a closed one cannot from outside, and skipping its back faces saves
    /// their vertices. The default says no.
    fn evaluates_back_faces(&self) -> bool {
        false
    }

    /// Whether the triangle with these world-space corners is certainly outside the view (all
    /// corners beyond one frustum plane): such a triangle covers no pixel and is not split. The
    /// default says no.
    fn outside_view(&self, corners: [Vec3; 3]) -> bool {
        let _ = corners;
        false
    }
}

/// The front-facing test for a pinhole camera at `eye`: the eye is strictly on the front side of
/// the triangle's plane, `(eye − a) · ((b − a) × (c − a)) > 0`.
pub fn faces_eye(corners: [Vec3; 3], eye: Vec3) -> bool {
    let [a, b, c] = corners;
    (eye - a).dot((b - a).cross(c - a)) > 0.0
}

/// Where an output vertex came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum VertexOrigin {
    /// The input vertex of this index (the same index in the output).
    Input(u32),
    /// The midpoint of the edge between these two output vertices (smaller index first).
    Midpoint([u32; 2]),
}

/// Why a triangle of the adaptive tessellation (a leaf) was not split further.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StopReason {
    /// The input triangle faces away from the camera; kept as it is.
    BackFacing,
    /// The input triangle repeats a vertex index; kept as it is.
    Degenerate,
    /// All three vertices are invisible from the viewpoint.
    Occluded,
    /// The triangle lies wholly outside the view frustum: it covers no pixel.
    OffScreen,
    /// No pair of its vertices' samples differ.
    Similar,
    /// Its vertices differ, but every projected edge is shorter than `t` (or not projectable).
    Small,
    /// Its vertices differ and some edge is long, but it is at the depth cap.
    MaxDepth,
    /// It would have been split, but the mesh reached [`TessellationOptions::max_vertices`].
    Budget,
}

/// Where an output triangle came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriangleRecord {
    /// Index of the input triangle it lies in.
    pub source: u32,
    /// Corners of the adaptive-tessellation leaf it belongs to: the triangle itself, or the leaf
    /// that T-junction removal re-triangulated into it and its siblings.
    pub leaf: [u32; 3],
    /// Subdivision depth of the leaf (0 = the input triangle itself).
    pub depth: u32,
    /// Why the leaf was not split further.
    pub stop: StopReason,
}

/// Counts from one [`tessellate`] call.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TessellationStats {
    /// Triangles in the input mesh.
    pub input_triangles: usize,
    /// Input triangles that face the camera (and were considered for subdivision, as back-facing
    /// ones are too when the oracle [evaluates back faces](VertexOracle::evaluates_back_faces)).
    pub front_facing_triangles: usize,
    /// Input triangles that face away (kept, apart from T-junction removal on shared edges).
    pub back_facing_triangles: usize,
    /// Triangles in the output mesh.
    pub output_triangles: usize,
    /// Vertices in the output mesh.
    pub output_vertices: usize,
    /// Calls of the oracle's per-vertex evaluation: each evaluated vertex counts once.
    pub vertices_evaluated: usize,
    /// Midpoints created (new vertices).
    pub midpoints_created: usize,
    /// Midpoint requests answered by the edge hash table (a neighbour had split the edge).
    pub midpoints_reused: usize,
    /// 1-to-2 splits (one long edge).
    pub splits_1_to_2: usize,
    /// 1-to-3 splits (two long edges).
    pub splits_1_to_3: usize,
    /// 1-to-4 splits (three long edges).
    pub splits_1_to_4: usize,
    /// Deepest subdivision level of any leaf.
    pub max_depth_reached: u32,
    /// Leaves stopped by the depth cap although their vertices differ and an edge is long.
    pub stopped_at_max_depth: usize,
    /// Leaves not split because the vertex budget was spent ([`StopReason::Budget`]).
    pub stopped_by_budget: usize,
    /// Leaves not split because all three vertices are invisible.
    pub occluded_leaves: usize,
    /// Leaves re-triangulated to remove T-junctions.
    pub t_junction_leaves: usize,
    /// Extra edge vertices those leaves absorbed, summed over the leaves.
    pub t_junction_vertices: usize,
}

/// The result of [`tessellate`]: the watertight output mesh and what each part came from.
#[derive(Clone, Debug)]
pub struct Tessellation<S> {
    /// Output mesh: the input vertices first (same indices), then the midpoints; normals and
    /// texture coordinates interpolated; triangles counter-clockwise like their sources.
    pub mesh: TriangleMesh,
    /// Where each output vertex came from (same order as `mesh.positions`).
    pub origins: Vec<VertexOrigin>,
    /// The oracle's evaluation of each output vertex (same order); `None` for input vertices
    /// whose triangles are all back-facing (or degenerate), which are never evaluated. Kept apart
    /// from `origins` so that the builder's table is handed over, not copied: at 3×3
    /// supersampling the teapot's is 125k evaluations, 25 MB, and zipping it into one record per
    /// vertex took 14–16 ms of a frame.
    pub evaluations: Vec<Option<VertexEvaluation<S>>>,
    /// One record per output triangle (same order as `mesh.triangles`).
    pub triangles: Vec<TriangleRecord>,
    /// Counts.
    pub stats: TessellationStats,
}

/// Why [`tessellate`] refused its input.
#[derive(Debug, thiserror::Error)]
pub enum TessellationError {
    /// `t` is zero, negative or not finite.
    #[error("tessellation threshold t = {0} subpixels must be finite and positive")]
    InvalidThreshold(f32),
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} names vertex {vertex}, but the mesh has {count} vertices")]
    IndexOutOfRange {
        /// Index of the triangle (0-based).
        triangle: usize,
        /// The vertex index it names.
        vertex: u32,
        /// Number of vertices in the mesh.
        count: usize,
    },
    /// A vertex position, normal or texture coordinate is NaN or infinite.
    #[error("vertex {vertex} (0-based) has a NaN or infinite position, normal or uv")]
    NonFinite {
        /// Index of the first such vertex.
        vertex: usize,
    },
    /// Normals or texture coordinates are present but not one per vertex.
    #[error("the mesh has {positions} positions but {normals} normals and {uvs} uvs")]
    AttributeLength {
        /// Number of positions.
        positions: usize,
        /// Number of normals (0 = generate).
        normals: usize,
        /// Number of uvs (0 = none).
        uvs: usize,
    },
    /// The output would need more vertices than a `u32` index can name.
    #[error(
        "the tessellation needs more than {} vertices; raise t or lower max_depth",
        u32::MAX
    )]
    TooManyVertices,
    /// An option of the frame is out of range (the options were not validated).
    #[error(transparent)]
    Option(#[from] crate::options::OptionError),
    /// [`VertexOracle::evaluate_batch`] returned the wrong number of evaluations.
    #[error("the vertex oracle returned {returned} evaluations for {asked} vertices")]
    OracleBatchLength {
        /// Vertices in the batch.
        asked: usize,
        /// Evaluations returned.
        returned: usize,
    },
    /// The GPU's vertex pass failed (the device was lost or out of memory).
    #[error("the GPU vertex tracer failed: {0}")]
    Gpu(#[from] crate::gpu::GpuError),
}

/// Adaptively tessellates `mesh` (world space, counter-clockwise triangles) for the camera and
/// sample criterion of `oracle`, then removes T-junctions. See the module documentation.
///
/// Input normals are used when present (one per vertex; generated from the faces when the mesh
/// has none); texture coordinates are carried along when present. Triangles that repeat a vertex
/// index are passed through unchanged.
pub fn tessellate<O>(
    mesh: &TriangleMesh,
    oracle: &O,
    options: &TessellationOptions,
) -> Result<Tessellation<O::Sample>, TessellationError>
where
    O: VertexOracle + Sync,
    O::Sample: Send + Sync,
{
    if options.validate().is_err() {
        return Err(TessellationError::InvalidThreshold(options.t));
    }
    validate(mesh)?;
    let mut builder = Builder::new(mesh, oracle, *options)?;
    let leaves = builder.subdivide(mesh)?;
    Ok(builder.finish(leaves))
}

/// Checks indices, finiteness and attribute lengths.
pub(crate) fn validate(mesh: &TriangleMesh) -> Result<(), TessellationError> {
    let count = mesh.positions.len();
    let normals_ok = mesh.normals.is_empty() || mesh.normals.len() == count;
    let uvs_ok = mesh.uvs.is_empty() || mesh.uvs.len() == count;
    if !normals_ok || !uvs_ok {
        return Err(TessellationError::AttributeLength {
            positions: count,
            normals: mesh.normals.len(),
            uvs: mesh.uvs.len(),
        });
    }
    for (triangle, corners) in mesh.triangles.iter().enumerate() {
        if let Some(&vertex) = corners.iter().find(|&&v| v as usize >= count) {
            return Err(TessellationError::IndexOutOfRange {
                triangle,
                vertex,
                count,
            });
        }
    }
    let bad = (0..count).find(|&i| {
        !mesh.positions[i].is_finite()
            || mesh.normals.get(i).is_some_and(|n| !n.is_finite())
            || mesh.uvs.get(i).is_some_and(|uv| !uv.is_finite())
    });
    match bad {
        Some(vertex) => Err(TessellationError::NonFinite { vertex }),
        None => Ok(()),
    }
}

/// A triangle of the adaptive tessellation that is not split further.
struct Leaf {
    corners: [u32; 3],
    source: u32,
    depth: u32,
    stop: StopReason,
}

/// A front-facing triangle awaiting the split decision at the current level.
struct Active {
    corners: [u32; 3],
    source: u32,
}

/// A step of [`Builder::edge_vertices`]' walk down an edge's midpoints.
enum EdgeStep {
    Edge(u32, u32),
    Emit(u32),
}

/// What to do with an active triangle.
enum Decision {
    Stop(StopReason),
    /// Split the edges marked long: `[ab, bc, ca]`.
    Split([bool; 3]),
}

/// The output triangles of a run of leaves and what T-junction removal did there.
#[derive(Default)]
struct LeafPieces {
    triangles: Vec<[u32; 3]>,
    records: Vec<TriangleRecord>,
    t_junction_leaves: usize,
    t_junction_vertices: usize,
}

/// The growing output mesh, the edge hash table and the per-vertex evaluations.
struct Builder<'o, O: VertexOracle + Sync> {
    oracle: &'o O,
    options: TessellationOptions,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Option<Vec<Vec2>>,
    origins: Vec<VertexOrigin>,
    evaluations: Vec<Option<VertexEvaluation<O::Sample>>>,
    /// Screen positions of evaluated vertices (`None`: not projectable).
    screens: Vec<Option<Vec2>>,
    /// The edge hash table: sorted vertex pair → midpoint vertex.
    midpoints: FxHashMap<(u32, u32), u32>,
    /// Vertices created or marked since the last batch evaluation.
    pending: Vec<u32>,
    /// Unit geometric normals of the input triangles (fallback for opposing vertex normals).
    face_normals: Vec<Vec3>,
    stats: TessellationStats,
}

impl<'o, O> Builder<'o, O>
where
    O: VertexOracle + Sync,
    O::Sample: Send + Sync,
{
    fn new(
        mesh: &TriangleMesh,
        oracle: &'o O,
        options: TessellationOptions,
    ) -> Result<Self, TessellationError> {
        let count = mesh.positions.len();
        if count >= u32::MAX as usize {
            return Err(TessellationError::TooManyVertices);
        }
        let normals = if mesh.normals.len() == count {
            mesh.normals.clone()
        } else {
            mesh.accumulated_face_normals()
        };
        let face_normals: Vec<Vec3> = (0..mesh.triangles.len())
            .map(|t| mesh.triangle_normal(t).normalize_or_zero())
            .collect();
        Ok(Builder {
            oracle,
            options,
            positions: mesh.positions.clone(),
            normals: normals.into_iter().map(|n| n.normalize_or_zero()).collect(),
            uvs: (mesh.uvs.len() == count && count > 0).then(|| mesh.uvs.clone()),
            origins: (0..count as u32).map(VertexOrigin::Input).collect(),
            evaluations: (0..count).map(|_| None).collect(),
            screens: vec![None; count],
            midpoints: FxHashMap::default(),
            pending: Vec::new(),
            face_normals,
            stats: TessellationStats {
                input_triangles: mesh.triangles.len(),
                ..TessellationStats::default()
            },
        })
    }

    /// Classifies the input triangles, then splits level by level until no triangle needs it.
    /// Returns the leaves in input-triangle order.
    fn subdivide(&mut self, mesh: &TriangleMesh) -> Result<Vec<Leaf>, TessellationError> {
        let mut leaves = Vec::new();
        let mut active = Vec::new();
        let mut marked = vec![false; self.positions.len()];
        // Which input triangles face the camera: asked in parallel, used in order.
        let facing: Vec<Option<bool>> = mesh
            .triangles
            .par_iter()
            .map(|&[a, b, c]| {
                (a != b && b != c && c != a).then(|| {
                    self.oracle
                        .front_facing([a, b, c].map(|v| self.positions[v as usize]))
                })
            })
            .collect();
        for (source, (&corners, facing)) in mesh.triangles.iter().zip(facing).enumerate() {
            let source = source as u32;
            let stop = match facing {
                None => Some(StopReason::Degenerate),
                Some(false) => {
                    self.stats.back_facing_triangles += 1;
                    (!self.oracle.evaluates_back_faces()).then_some(StopReason::BackFacing)
                }
                Some(true) => {
                    self.stats.front_facing_triangles += 1;
                    None
                }
            };
            match stop {
                Some(stop) => leaves.push(Leaf {
                    corners,
                    source,
                    depth: 0,
                    stop,
                }),
                None => {
                    for v in corners {
                        if !marked[v as usize] {
                            marked[v as usize] = true;
                            self.pending.push(v);
                        }
                    }
                    active.push(Active { corners, source });
                }
            }
        }
        let mut depth = 0;
        while !active.is_empty() {
            self.evaluate_pending()?;
            // Phase one, in parallel: every decision reads only finished evaluations.
            let decisions: Vec<Decision> = active
                .par_iter()
                .map(|triangle| self.decide(triangle.corners, depth))
                .collect();
            // Phase two, in order: midpoints get the same indices at any thread count.
            let mut next = Vec::new();
            for (triangle, decision) in active.into_iter().zip(decisions) {
                match decision {
                    Decision::Stop(stop) => {
                        self.stats.max_depth_reached = self.stats.max_depth_reached.max(depth);
                        match stop {
                            StopReason::MaxDepth => self.stats.stopped_at_max_depth += 1,
                            StopReason::Occluded => self.stats.occluded_leaves += 1,
                            _ => {}
                        }
                        leaves.push(Leaf {
                            corners: triangle.corners,
                            source: triangle.source,
                            depth,
                            stop,
                        });
                    }
                    // A split adds at most three vertices: none once they would pass the budget.
                    Decision::Split(_) if self.positions.len() + 3 > self.options.max_vertices => {
                        self.stats.stopped_by_budget += 1;
                        self.stats.max_depth_reached = self.stats.max_depth_reached.max(depth);
                        leaves.push(Leaf {
                            corners: triangle.corners,
                            source: triangle.source,
                            depth,
                            stop: StopReason::Budget,
                        });
                    }
                    Decision::Split(long) => self.split(&triangle, long, &mut next)?,
                }
            }
            active = next;
            depth += 1;
        }
        // Stable: keeps creation order within each source triangle.
        leaves.par_sort_by_key(|leaf| leaf.source);
        Ok(leaves)
    }

    /// Evaluates the pending vertices in one batch and projects them.
    fn evaluate_pending(&mut self) -> Result<(), TessellationError> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let batch: Vec<SurfaceVertex> = self
            .pending
            .iter()
            .map(|&index| SurfaceVertex {
                index,
                position: self.positions[index as usize],
                normal: self.normals[index as usize],
                uv: self.uvs.as_ref().map(|uvs| uvs[index as usize]),
            })
            .collect();
        let evaluations = self.oracle.evaluate_batch(&batch)?;
        if evaluations.len() != batch.len() {
            return Err(TessellationError::OracleBatchLength {
                asked: batch.len(),
                returned: evaluations.len(),
            });
        }
        self.stats.vertices_evaluated += batch.len();
        let screens: Vec<Option<Vec2>> = batch
            .par_iter()
            .map(|vertex| {
                self.oracle
                    .screen(vertex.position)
                    .filter(|p| p.is_finite())
            })
            .collect();
        for ((vertex, evaluation), screen) in batch.iter().zip(evaluations).zip(screens) {
            let i = vertex.index as usize;
            self.evaluations[i] = Some(evaluation);
            self.screens[i] = screen;
        }
        self.pending.clear();
        Ok(())
    }

    /// The paper's criteria, in order: occlusion, sample difference, screen size, depth cap.
    fn decide(&self, corners: [u32; 3], depth: u32) -> Decision {
        let [a, b, c] = corners.map(|v| self.evaluations[v as usize].as_ref());
        // Every corner of an active triangle was evaluated before its level; a missing one would
        // be a bug here, and not splitting is the safe answer.
        let (Some(a), Some(b), Some(c)) = (a, b, c) else {
            debug_assert!(false, "active triangle with an unevaluated corner");
            return Decision::Stop(StopReason::Similar);
        };
        if !(a.visible || b.visible || c.visible) {
            return Decision::Stop(StopReason::Occluded);
        }
        if self
            .oracle
            .outside_view(corners.map(|v| self.positions[v as usize]))
        {
            return Decision::Stop(StopReason::OffScreen);
        }
        let differ = |x: &VertexEvaluation<O::Sample>, y: &VertexEvaluation<O::Sample>| {
            self.oracle.differ(&x.sample, &y.sample)
        };
        if !(differ(a, b) || differ(b, c) || differ(c, a)) {
            return Decision::Stop(StopReason::Similar);
        }
        let long = [0, 1, 2].map(|i| self.edge_is_long(corners[i], corners[(i + 1) % 3]));
        if !long.contains(&true) {
            return Decision::Stop(StopReason::Small);
        }
        if depth >= self.options.max_depth {
            return Decision::Stop(StopReason::MaxDepth);
        }
        Decision::Split(long)
    }

    /// Whether the projected edge is at least `t` subpixels long; unprojectable edges are short.
    fn edge_is_long(&self, u: u32, w: u32) -> bool {
        match (self.screens[u as usize], self.screens[w as usize]) {
            (Some(p), Some(q)) => p.distance(q) >= self.options.t,
            _ => false,
        }
    }

    /// Splits a triangle's long edges at their midpoints and pushes the children (wound like
    /// the parent) onto `next`.
    fn split(
        &mut self,
        triangle: &Active,
        long: [bool; 3],
        next: &mut Vec<Active>,
    ) -> Result<(), TessellationError> {
        let source = triangle.source;
        let long_count = long.iter().filter(|&&l| l).count();
        // Rotate the corners (keeping the winding) so that the long edges come first: for one
        // long edge it is ab, for two the short one is ca.
        let rotation = match long_count {
            1 => long.iter().position(|&l| l).unwrap_or(0),
            2 => (long.iter().position(|&l| !l).unwrap_or(2) + 1) % 3,
            _ => 0,
        };
        let [a, b, c] = [0, 1, 2].map(|i| triangle.corners[(i + rotation) % 3]);
        // Pushed in place: a split is the hot path of phase two, which runs serially.
        let mut push = |corners: [u32; 3]| next.push(Active { corners, source });
        match long_count {
            1 => {
                self.stats.splits_1_to_2 += 1;
                let ab = self.midpoint(a, b, source)?;
                push([a, ab, c]);
                push([ab, b, c]);
            }
            2 => {
                self.stats.splits_1_to_3 += 1;
                let ab = self.midpoint(a, b, source)?;
                let bc = self.midpoint(b, c, source)?;
                // The quad a, ab, bc, c is cut along its shorter diagonal.
                let p = |v: u32| self.positions[v as usize];
                push([ab, b, bc]);
                if p(a).distance_squared(p(bc)) <= p(ab).distance_squared(p(c)) {
                    push([a, ab, bc]);
                    push([a, bc, c]);
                } else {
                    push([a, ab, c]);
                    push([ab, bc, c]);
                }
            }
            _ => {
                self.stats.splits_1_to_4 += 1;
                let ab = self.midpoint(a, b, source)?;
                let bc = self.midpoint(b, c, source)?;
                let ca = self.midpoint(c, a, source)?;
                push([a, ab, ca]);
                push([ab, b, bc]);
                push([ca, bc, c]);
                push([ab, bc, ca]);
            }
        }
        Ok(())
    }

    /// The midpoint of edge (u, w) from the edge hash table, created (and queued for
    /// evaluation) on first request.
    fn midpoint(&mut self, u: u32, w: u32, source: u32) -> Result<u32, TessellationError> {
        let key = (u.min(w), u.max(w));
        if let Some(&m) = self.midpoints.get(&key) {
            self.stats.midpoints_reused += 1;
            return Ok(m);
        }
        let index = u32::try_from(self.positions.len())
            .ok()
            .filter(|&i| i < u32::MAX)
            .ok_or(TessellationError::TooManyVertices)?;
        let (lo, hi) = (key.0 as usize, key.1 as usize);
        self.positions
            .push((self.positions[lo] + self.positions[hi]) * 0.5);
        let normal = (self.normals[lo] + self.normals[hi])
            .try_normalize()
            .unwrap_or(self.face_normals[source as usize]);
        self.normals.push(normal);
        if let Some(uvs) = &mut self.uvs {
            uvs.push((uvs[lo] + uvs[hi]) * 0.5);
        }
        self.origins.push(VertexOrigin::Midpoint([key.0, key.1]));
        self.evaluations.push(None);
        self.screens.push(None);
        self.midpoints.insert(key, index);
        self.pending.push(index);
        self.stats.midpoints_created += 1;
        Ok(index)
    }

    /// Every vertex that the edge hash table places strictly inside edge (u, w), in order from
    /// u to w (the paper's recursive query).
    fn edge_vertices(&self, u: u32, w: u32, out: &mut Vec<u32>, stack: &mut Vec<EdgeStep>) {
        stack.clear();
        stack.push(EdgeStep::Edge(u, w));
        while let Some(step) = stack.pop() {
            match step {
                EdgeStep::Emit(m) => out.push(m),
                EdgeStep::Edge(x, y) => {
                    if let Some(&m) = self.midpoints.get(&(x.min(y), x.max(y))) {
                        stack.push(EdgeStep::Edge(m, y));
                        stack.push(EdgeStep::Emit(m));
                        stack.push(EdgeStep::Edge(x, m));
                    }
                }
            }
        }
    }

    /// The output triangles of some leaves: each leaf as it is, or re-triangulated through the
    /// vertices that finer neighbours placed on its sides (the paper's T-junction removal).
    fn remove_t_junctions(&self, leaves: &[Leaf]) -> LeafPieces {
        let mut out = LeafPieces::default();
        let mut polygon = Vec::new();
        let mut sides = Vec::new();
        let mut stack = Vec::new();
        for leaf in leaves {
            let record = TriangleRecord {
                source: leaf.source,
                leaf: leaf.corners,
                depth: leaf.depth,
                stop: leaf.stop,
            };
            if leaf.stop == StopReason::Degenerate {
                out.triangles.push(leaf.corners);
                out.records.push(record);
                continue;
            }
            polygon.clear();
            sides.clear();
            for i in 0..3 {
                let (u, w) = (leaf.corners[i], leaf.corners[(i + 1) % 3]);
                // Corner i lies on side i (u→w) and on the previous side.
                polygon.push(u);
                sides.push(side_bit(i) | side_bit((i + 2) % 3));
                let start = polygon.len();
                self.edge_vertices(u, w, &mut polygon, &mut stack);
                sides.resize(polygon.len(), side_bit(i));
                out.t_junction_vertices += polygon.len() - start;
            }
            if polygon.len() == 3 {
                out.triangles.push(leaf.corners);
                out.records.push(record);
                continue;
            }
            out.t_junction_leaves += 1;
            let before = out.triangles.len();
            triangulate_boundary(&polygon, &sides, &self.positions, &mut out.triangles);
            let pieces = out.triangles.len() - before;
            out.records.extend(std::iter::repeat_n(record, pieces));
        }
        out
    }

    /// Removes T-junctions and assembles the output: leaves in parallel chunks, each reading
    /// the finished edge table, gathered in leaf order.
    fn finish(mut self, leaves: Vec<Leaf>) -> Tessellation<O::Sample> {
        /// Leaves per parallel task: large enough that a task outweighs its scheduling.
        const LEAVES_PER_TASK: usize = 1024;
        let chunks: Vec<LeafPieces> = leaves
            .par_chunks(LEAVES_PER_TASK)
            .map(|chunk| self.remove_t_junctions(chunk))
            .collect();
        let count = chunks.iter().map(|c| c.triangles.len()).sum();
        let mut triangles = Vec::with_capacity(count);
        let mut records = Vec::with_capacity(count);
        for chunk in chunks {
            triangles.extend(chunk.triangles);
            records.extend(chunk.records);
            self.stats.t_junction_leaves += chunk.t_junction_leaves;
            self.stats.t_junction_vertices += chunk.t_junction_vertices;
        }
        self.stats.output_triangles = triangles.len();
        self.stats.output_vertices = self.positions.len();
        Tessellation {
            mesh: TriangleMesh {
                positions: self.positions,
                normals: self.normals,
                uvs: self.uvs.unwrap_or_default(),
                triangles,
            },
            origins: self.origins,
            evaluations: self.evaluations,
            triangles: records,
            stats: self.stats,
        }
    }
}

/// The bit for side `i` of a leaf (0: ab, 1: bc, 2: ca).
fn side_bit(i: usize) -> u8 {
    1 << i
}

/// Triangulates a leaf whose sides carry extra vertices, without new vertices.
///
/// `polygon` lists the leaf's boundary counter-clockwise (corner a, the vertices on ab, corner
/// b, …); `sides[i]` has a bit for each leaf side vertex i lies on (two for a corner). Three
/// boundary points are collinear exactly when they share a side, and a vertex lies on the chord
/// between two others only if those two share a side; so the ear (p, v, q) is clipped only when
/// p and q share no side, which rules out both degenerate triangles and vertices on the chord.
/// Among those ears the one with the shortest chord goes first (ties: the earliest vertex), which
/// keeps the triangles reasonably shaped. Output triangles are wound like the polygon.
fn triangulate_boundary(
    polygon: &[u32],
    sides: &[u8],
    positions: &[Vec3],
    out: &mut Vec<[u32; 3]>,
) {
    let n = polygon.len();
    let mut prev: Vec<usize> = (0..n).map(|i| (i + n - 1) % n).collect();
    let mut next: Vec<usize> = (0..n).map(|i| (i + 1) % n).collect();
    let mut alive = vec![true; n];
    let mut stamp = vec![0u32; n];
    let mut heap = BinaryHeap::new();
    let ear = |v: usize, prev: &[usize], next: &[usize], stamp: &[u32]| {
        let (p, q) = (prev[v], next[v]);
        (sides[p] & sides[q] == 0).then(|| {
            let chord =
                positions[polygon[p] as usize].distance_squared(positions[polygon[q] as usize]);
            // Non-negative floats order like their bit patterns.
            Reverse((chord.to_bits(), v, stamp[v]))
        })
    };
    heap.extend((0..n).filter_map(|v| ear(v, &prev, &next, &stamp)));
    let mut remaining = n;
    while remaining > 3 {
        let Some(Reverse((_, v, s))) = heap.pop() else {
            break;
        };
        if !alive[v] || s != stamp[v] {
            continue;
        }
        let (p, q) = (prev[v], next[v]);
        out.push([polygon[p], polygon[v], polygon[q]]);
        alive[v] = false;
        next[p] = q;
        prev[q] = p;
        remaining -= 1;
        for u in [p, q] {
            stamp[u] += 1;
            heap.extend(ear(u, &prev, &next, &stamp));
        }
    }
    let Some(first) = (0..n).find(|&v| alive[v]) else {
        return;
    };
    if remaining > 3 {
        // Unreachable: a convex polygon whose vertices are not all collinear always has a valid
        // ear. Fan the rest so that the surface at least stays covered.
        debug_assert!(false, "no valid ear among {remaining} vertices");
        let mut v = next[first];
        while next[v] != first {
            out.push([polygon[first], polygon[v], polygon[next[v]]]);
            v = next[v];
        }
        return;
    }
    out.push([polygon[prev[first]], polygon[first], polygon[next[first]]]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use std::collections::HashMap;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// An orthographic camera looking down −z: screen = scale · (x, y); front = +z normal.
    struct Flat {
        scale: Vec2,
        differ: bool,
        visible: bool,
        back_faces: bool,
        evaluations: AtomicUsize,
    }

    impl Flat {
        fn new(scale: f32, differ: bool) -> Self {
            Flat {
                scale: Vec2::splat(scale),
                differ,
                visible: true,
                back_faces: false,
                evaluations: AtomicUsize::new(0),
            }
        }
    }

    impl VertexOracle for Flat {
        type Sample = Vec3;
        fn evaluate(&self, vertex: &SurfaceVertex) -> Vec3 {
            self.evaluations.fetch_add(1, Ordering::Relaxed);
            vertex.position
        }
        fn visible(&self, _: &SurfaceVertex) -> bool {
            self.visible
        }
        fn differ(&self, _: &Vec3, _: &Vec3) -> bool {
            self.differ
        }
        fn screen(&self, position: Vec3) -> Option<Vec2> {
            Some(position.truncate() * self.scale)
        }
        fn front_facing(&self, corners: [Vec3; 3]) -> bool {
            faces_eye(corners, corners[0] + Vec3::Z)
        }
        fn evaluates_back_faces(&self) -> bool {
            self.back_faces
        }
    }

    fn mesh(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> TriangleMesh {
        let mut mesh = TriangleMesh {
            positions: positions.iter().map(|&p| Vec3::from(p)).collect(),
            triangles: triangles.to_vec(),
            ..TriangleMesh::default()
        };
        mesh.generate_smooth_normals();
        mesh
    }

    /// The right triangle with unit legs along x and y, facing +z.
    fn unit_triangle() -> TriangleMesh {
        mesh(
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            &[[0, 1, 2]],
        )
    }

    /// The unit triangle and a neighbour folded under it (facing −z), sharing edge 1–2.
    fn folded_pair() -> TriangleMesh {
        mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.2, 0.2, -0.5],
            ],
            &[[0, 1, 2], [1, 3, 2]],
        )
    }

    fn area(mesh: &TriangleMesh) -> f64 {
        mesh.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    fn options(t: f32) -> TessellationOptions {
        TessellationOptions {
            t,
            ..TessellationOptions::default()
        }
    }

    #[test]
    fn always_differ_on_one_triangle_matches_the_closed_form() {
        // Right isosceles triangle with legs of 16 subpixels: the hypotenuse (22.6) needs
        // d = ⌈log2(22.6 / t)⌉ halvings; every split is 1-to-4 while all edges are long.
        let input = unit_triangle();
        // The split is uniform exactly when legs and hypotenuse fall below t at the same level.
        for (t, depth) in [(3.0f32, 3u32), (12.0, 1), (1.0, 5), (0.5, 6), (25.0, 0)] {
            let oracle = Flat::new(16.0, true);
            let out = tessellate(&input, &oracle, &options(t)).unwrap();
            let side = 1usize << depth;
            assert_eq!(out.stats.output_triangles, side * side, "t = {t}");
            assert_eq!(out.stats.splits_1_to_4, (side * side - 1) / 3);
            assert_eq!(out.stats.splits_1_to_2 + out.stats.splits_1_to_3, 0);
            assert_eq!(out.stats.vertices_evaluated, (side + 1) * (side + 2) / 2);
            assert_eq!(out.stats.max_depth_reached, depth);
            assert_eq!(out.stats.t_junction_leaves, 0);
            assert_eq!(
                oracle.evaluations.load(Ordering::Relaxed),
                out.stats.vertices_evaluated
            );
            assert!((area(&out.mesh) - 0.5).abs() < 1e-6);
        }
    }

    #[test]
    fn never_differ_keeps_the_mesh() {
        let input = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            &[[0, 1, 2], [0, 2, 3]],
        );
        let out = tessellate(&input, &Flat::new(100.0, false), &options(1.0)).unwrap();
        assert_eq!(out.mesh.triangles, input.triangles);
        assert_eq!(out.stats.vertices_evaluated, 4);
        assert!(out.triangles.iter().all(|r| r.stop == StopReason::Similar));
    }

    #[test]
    fn one_and_two_long_edges_give_1_to_2_and_1_to_3_splits() {
        // t = 3 at scale 1: ab = 5 is long, ac = bc ≈ 2.55 are short.
        let input = mesh(
            &[[0.0, 0.0, 0.0], [5.0, 0.0, 0.0], [2.5, 0.5, 0.0]],
            &[[0, 1, 2]],
        );
        let out = tessellate(&input, &Flat::new(1.0, true), &options(3.0)).unwrap();
        assert_eq!(out.stats.splits_1_to_2, 1);
        assert_eq!(out.stats.splits_1_to_3 + out.stats.splits_1_to_4, 0);
        assert_eq!(out.mesh.triangles.len(), 2);
        // ab = 4 and bc = 5 long, ca = 2 short.
        let input = mesh(
            &[[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
            &[[1, 2, 0]],
        );
        let out = tessellate(&input, &Flat::new(1.0, true), &options(3.0)).unwrap();
        assert_eq!(out.stats.splits_1_to_3, 1);
        assert_eq!(out.stats.splits_1_to_4, 0);
        assert!((area(&out.mesh) - 4.0).abs() < 1e-5);
        for tri in &out.mesh.triangles {
            let [a, b, c] = tri.map(|i| out.mesh.positions[i as usize]);
            assert!((b - a).cross(c - a).z > 0.0, "winding kept");
        }
    }

    #[test]
    fn a_back_facing_neighbour_is_refanned_without_evaluating_its_own_vertex() {
        // Triangle 0 faces +z, triangle 1 is folded under and faces −z; they share edge 1–2.
        let input = folded_pair();
        let oracle = Flat::new(8.0, true);
        let out = tessellate(&input, &oracle, &options(3.0)).unwrap();
        assert_eq!(out.stats.back_facing_triangles, 1);
        assert!(out.evaluations[3].is_none());
        assert_eq!(out.stats.vertices_evaluated, out.evaluations.len() - 1);
        assert_eq!(out.stats.t_junction_leaves, 1);
        // The shared edge (8√2 ≈ 11.3 subpixels) was halved twice: three extra vertices, so the
        // back-facing triangle becomes a fan of four.
        let back: Vec<_> = out.triangles.iter().filter(|r| r.source == 1).collect();
        assert_eq!(back.len(), 4);
        assert!(back.iter().all(|r| r.stop == StopReason::BackFacing));
        assert!((area(&out.mesh) - area(&input)).abs() < 1e-6);
    }

    #[test]
    fn an_oracle_that_evaluates_back_faces_gets_them_evaluated_and_split() {
        // The folded mesh of the test above, for an open surface: the back-facing triangle is
        // treated like a front-facing one (its own vertex evaluated, split where its vertices
        // differ), and still counted as back-facing.
        let input = folded_pair();
        let oracle = Flat {
            back_faces: true,
            ..Flat::new(8.0, true)
        };
        let out = tessellate(&input, &oracle, &options(3.0)).unwrap();
        assert_eq!(
            (
                out.stats.back_facing_triangles,
                out.stats.front_facing_triangles
            ),
            (1, 1)
        );
        assert!(out.evaluations.iter().all(Option::is_some));
        assert_eq!(out.stats.vertices_evaluated, out.evaluations.len());
        assert_eq!(
            oracle.evaluations.load(Ordering::Relaxed),
            out.evaluations.len()
        );
        let back: Vec<_> = out.triangles.iter().filter(|r| r.source == 1).collect();
        assert!(back.len() > 4, "the back face is split: {}", back.len());
        assert!(back.iter().all(|r| r.stop != StopReason::BackFacing));
        assert!((area(&out.mesh) - area(&input)).abs() < 1e-6);
    }

    #[test]
    fn occluded_triangles_are_evaluated_but_not_split() {
        let input = unit_triangle();
        let mut oracle = Flat::new(100.0, true);
        oracle.visible = false;
        let out = tessellate(&input, &oracle, &options(3.0)).unwrap();
        assert_eq!(out.stats.vertices_evaluated, 3);
        assert_eq!(out.stats.occluded_leaves, 1);
        assert_eq!(out.triangles[0].stop, StopReason::Occluded);
    }

    #[test]
    fn max_depth_caps_subdivision() {
        let input = unit_triangle();
        let opts = TessellationOptions {
            t: 1.0,
            max_depth: 2,
            ..TessellationOptions::default()
        };
        let out = tessellate(&input, &Flat::new(1e6, true), &opts).unwrap();
        assert_eq!(out.stats.max_depth_reached, 2);
        assert_eq!(out.stats.output_triangles, 16);
        assert_eq!(out.stats.stopped_at_max_depth, 16);
    }

    /// The vertex budget stops splitting where it runs out, deterministically, and the result is
    /// still a valid (watertight, T-junction-free) tessellation: every leaf is counted.
    #[test]
    fn the_vertex_budget_bounds_the_mesh() {
        let input = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
            ],
            &[[0, 1, 2], [1, 3, 2]],
        );
        let unbounded = tessellate(&input, &Flat::new(1e3, true), &options(1.0)).unwrap();
        let budget = unbounded.mesh.positions.len() / 10;
        let bounded_options = TessellationOptions {
            max_vertices: budget,
            ..options(1.0)
        };
        let out = tessellate(&input, &Flat::new(1e3, true), &bounded_options).unwrap();
        assert!(
            out.mesh.positions.len() <= budget,
            "{} > {budget}",
            out.mesh.positions.len()
        );
        assert!(out.stats.stopped_by_budget > 0);
        assert!(out.triangles.iter().any(|t| t.stop == StopReason::Budget));
        // Area is preserved: the leaves still tile the input.
        let area = |m: &TriangleMesh| -> f32 {
            m.triangles
                .iter()
                .map(|&[a, b, c]| {
                    let p = |i: u32| m.positions[i as usize];
                    0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length()
                })
                .sum()
        };
        assert!((area(&out.mesh) - 1.0).abs() < 1e-5);
        let again = tessellate(&input, &Flat::new(1e3, true), &bounded_options).unwrap();
        assert_eq!(out.mesh, again.mesh);
    }

    #[test]
    fn bad_input_is_an_error() {
        let input = unit_triangle();
        let oracle = Flat::new(1.0, true);
        for t in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(matches!(
                tessellate(&input, &oracle, &options(t)),
                Err(TessellationError::InvalidThreshold(_))
            ));
        }
        let mut broken = input.clone();
        broken.triangles.push([0, 1, 7]);
        assert!(matches!(
            tessellate(&broken, &oracle, &options(3.0)),
            Err(TessellationError::IndexOutOfRange {
                triangle: 1,
                vertex: 7,
                ..
            })
        ));
        let mut broken = input.clone();
        broken.positions[2].x = f32::NAN;
        assert!(matches!(
            tessellate(&broken, &oracle, &options(3.0)),
            Err(TessellationError::NonFinite { vertex: 2 })
        ));
        let mut broken = input;
        broken.uvs = vec![Vec2::ZERO];
        assert!(matches!(
            tessellate(&broken, &oracle, &options(3.0)),
            Err(TessellationError::AttributeLength { .. })
        ));
    }

    #[test]
    fn a_short_batch_is_an_error() {
        struct Short;
        impl VertexOracle for Short {
            type Sample = ();
            fn evaluate(&self, _: &SurfaceVertex) {}
            fn evaluate_batch(
                &self,
                _: &[SurfaceVertex],
            ) -> Result<Vec<VertexEvaluation<()>>, TessellationError> {
                Ok(Vec::new())
            }
            fn differ(&self, _: &(), _: &()) -> bool {
                true
            }
            fn screen(&self, _: Vec3) -> Option<Vec2> {
                None
            }
            fn front_facing(&self, _: [Vec3; 3]) -> bool {
                true
            }
        }
        let input = unit_triangle();
        assert!(matches!(
            tessellate(&input, &Short, &options(3.0)),
            Err(TessellationError::OracleBatchLength {
                asked: 3,
                returned: 0
            })
        ));
    }

    #[test]
    fn points_behind_the_camera_stop_subdivision() {
        struct Behind;
        impl VertexOracle for Behind {
            type Sample = ();
            fn evaluate(&self, _: &SurfaceVertex) {}
            fn differ(&self, _: &(), _: &()) -> bool {
                true
            }
            fn screen(&self, position: Vec3) -> Option<Vec2> {
                (position.x < 0.5).then_some(position.truncate() * 100.0)
            }
            fn front_facing(&self, _: [Vec3; 3]) -> bool {
                true
            }
        }
        let input = unit_triangle();
        let out = tessellate(&input, &Behind, &options(3.0)).unwrap();
        assert!(out.stats.max_depth_reached < DEFAULT_MAX_DEPTH);
        assert_eq!(out.stats.stopped_at_max_depth, 0);
        assert!((area(&out.mesh) - 0.5).abs() < 1e-6);
    }

    /// Random leaves with 0–5 extra vertices per side at random positions along it.
    #[test]
    fn boundary_triangulation_is_valid_for_every_side_count() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        for ab in 0..6 {
            for bc in 0..6 {
                for ca in 0..6 {
                    let corners: [Vec3; 3] = std::array::from_fn(|_| {
                        Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), 0.0)
                    });
                    let corners =
                        if (corners[1] - corners[0]).cross(corners[2] - corners[0]).z < 0.0 {
                            [corners[0], corners[2], corners[1]]
                        } else {
                            corners
                        };
                    let mut positions = Vec::new();
                    let mut sides = Vec::new();
                    for (i, count) in [ab, bc, ca].into_iter().enumerate() {
                        let (u, w) = (corners[i], corners[(i + 1) % 3]);
                        positions.push(u);
                        sides.push(side_bit(i) | side_bit((i + 2) % 3));
                        let mut ts: Vec<f32> =
                            (0..count).map(|_| rng.gen_range(0.05..0.95)).collect();
                        ts.sort_by(f32::total_cmp);
                        positions.extend(ts.iter().map(|&s| u.lerp(w, s)));
                        sides.resize(positions.len(), side_bit(i));
                    }
                    let polygon: Vec<u32> = (0..positions.len() as u32).collect();
                    let mut out = Vec::new();
                    triangulate_boundary(&polygon, &sides, &positions, &mut out);
                    assert_eq!(out.len(), polygon.len() - 2, "sides {ab} {bc} {ca}");
                    let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
                    let mut total = 0.0f64;
                    for &[x, y, z] in &out {
                        let [p, q, r] = [x, y, z].map(|i| positions[i as usize]);
                        let cross = (q - p).cross(r - p).z;
                        assert!(cross > 0.0, "ccw, non-degenerate");
                        assert_eq!(sides[x as usize] & sides[y as usize] & sides[z as usize], 0);
                        total += 0.5 * f64::from(cross);
                        for (s, e) in [(x, y), (y, z), (z, x)] {
                            *edges.entry((s, e)).or_default() += 1;
                        }
                    }
                    let [a, b, c] = corners;
                    let expected = 0.5 * f64::from((b - a).cross(c - a).z);
                    assert!((total - expected).abs() < 1e-5 * expected.max(1e-3));
                    // Boundary edges once forward; chords once each way.
                    let n = polygon.len() as u32;
                    for (&(s, e), &count) in &edges {
                        assert_eq!(count, 1);
                        let boundary = e == (s + 1) % n;
                        assert!(boundary || edges.get(&(e, s)) == Some(&1), "chord {s}-{e}");
                    }
                    assert_eq!(
                        (0..n)
                            .filter(|&s| edges.contains_key(&(s, (s + 1) % n)))
                            .count(),
                        n as usize
                    );
                }
            }
        }
    }

    #[test]
    fn uvs_and_normals_are_interpolated() {
        let mut input = unit_triangle();
        input.normals = vec![Vec3::Z, Vec3::X, Vec3::Z];
        input.uvs = vec![Vec2::ZERO, Vec2::X, Vec2::Y];
        let out = tessellate(&input, &Flat::new(4.0, true), &options(3.0)).unwrap();
        assert_eq!(out.mesh.uvs.len(), out.mesh.positions.len());
        for (i, origin) in out.origins.iter().enumerate() {
            if let VertexOrigin::Midpoint([u, w]) = *origin {
                let (u, w) = (u as usize, w as usize);
                assert_eq!(out.mesh.uvs[i], (out.mesh.uvs[u] + out.mesh.uvs[w]) * 0.5);
                let n = (out.mesh.normals[u] + out.mesh.normals[w]).normalize();
                assert!(out.mesh.normals[i].abs_diff_eq(n, 1e-6));
                // uv = xy on this triangle, so interpolation is exact.
                assert!(out.mesh.uvs[i].abs_diff_eq(out.mesh.positions[i].truncate(), 1e-6));
            }
        }
    }
}
