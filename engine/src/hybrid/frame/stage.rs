//! The vertex stage of a frame, chosen once per frame: what traces each lens object's vertices,
//! tessellates it where ray paths differ and gives its vertices their texture coordinates into
//! the layered EMs. [`CpuStage`] does all of it on the CPU (the paper's reference
//! implementation); the GPU's two stages are in `device.rs`. The tessellation's logic itself is
//! behind [`crate::hybrid::tessellate::VertexOracle`]; a stage decides where it runs and what it
//! hands the compositor.

use std::time::Instant;

use super::{HybridStats, view::LensJob};
use crate::{
    hybrid::{
        paths::{PathOracle, VertexPaths},
        tessellate::{
            Tessellation, TessellationError, TessellationOptions, VertexEvaluation, faces_eye,
            tessellate,
        },
        texgen::{LensMesh, texgen},
    },
    render::LensObject,
    scene::TriangleMesh,
};

/// What makes a frame's lens objects: traced, tessellated and given texture coordinates, on the
/// CPU ([`CpuStage`]), on the GPU and read back ([`super::GpuReadBack`]), or on the GPU and left
/// there for the frame to draw ([`super::GpuResident`]).
pub trait VertexStage {
    /// Which stage this is: a frame made by another stage is another frame (the GPU's f32
    /// paths are not the CPU's, and a resident frame is drawn from one tracer's buffers).
    fn key(&self) -> StageKey;

    /// Called once per frame before its first lens object (the resident stage makes the
    /// device's buffers hold every lens object of the frame then).
    fn begin(&self, job: &FrameJob<'_>) -> Result<(), TessellationError> {
        let _ = job;
        Ok(())
    }

    /// Lens object `job` as the frame draws it, its vertices taken from `budget` (the frame's,
    /// shared by its lens objects in order) and its costs added to `stats`.
    fn lens(
        &self,
        job: &LensJob<'_>,
        budget: &mut VertexBudget,
        stats: &mut HybridStats,
    ) -> Result<BuiltLens, TessellationError>;
}

/// What a frame is made of before its lens objects are built: the scene, the options and the
/// lens objects' jobs, in the scene's order (for [`VertexStage::begin`]).
pub struct FrameJob<'a> {
    /// The scene.
    pub(super) scene: &'a crate::hybrid::HybridScene,
    /// The frame's options.
    pub(super) options: &'a super::HybridOptions,
    /// Per lens object its job.
    pub(super) lenses: &'a [LensJob<'a>],
}

/// Which vertex stage made a frame, and on which tracer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StageKey {
    /// On the CPU.
    Cpu,
    /// On the GPU tracer `tracer` ([`crate::hybrid::gpu::GpuTracer::id`]), read back.
    GpuReadBack {
        /// The tracer's identity.
        tracer: u64,
    },
    /// On the GPU tracer `tracer`, drawn where it left the meshes.
    GpuResident {
        /// The tracer's identity.
        tracer: u64,
    },
}

impl StageKey {
    /// Whether the vertices are traced on a GPU.
    pub fn on_gpu(self) -> bool {
        self != StageKey::Cpu
    }
}

/// One lens object as a stage made it for a frame.
pub struct BuiltLens {
    /// What the compositor draws.
    pub(super) object: LensObject,
    /// Per triangle of `object` (empty for one drawn from the device's buffers), its
    /// subdivision depth (saturated at 255).
    pub(super) depths: Vec<u8>,
}

/// A frame's vertex budget, shared by its lens objects in order.
pub struct VertexBudget {
    /// What the objects before left, as the host counted it.
    pub(super) left: usize,
    /// Whether an object was tessellated on the device with no count read back: the device
    /// keeps the budget left from then on.
    pub(super) on_device: bool,
}

impl VertexBudget {
    /// The whole budget of a frame, `max_vertices`.
    pub(super) fn new(max_vertices: usize) -> VertexBudget {
        VertexBudget {
            left: max_vertices,
            on_device: false,
        }
    }

    /// `options` with the vertices left for `mesh` (at least its own: a mesh is never cut).
    pub(super) fn options_for(
        &self,
        options: &TessellationOptions,
        mesh: &TriangleMesh,
    ) -> TessellationOptions {
        TessellationOptions {
            max_vertices: self.left.max(mesh.positions.len()),
            ..*options
        }
    }
}

/// The paper's vertex stage: every lens vertex ray traced on the CPU (in parallel), the
/// tessellation and texgen on the CPU.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuStage;

impl VertexStage for CpuStage {
    fn key(&self) -> StageKey {
        StageKey::Cpu
    }

    fn lens(
        &self,
        job: &LensJob<'_>,
        budget: &mut VertexBudget,
        stats: &mut HybridStats,
    ) -> Result<BuiltLens, TessellationError> {
        let CpuLens {
            mesh,
            samples,
            depths,
        } = tessellate_on_cpu(job, budget, stats)?;
        let start = Instant::now();
        let scene = job.scene;
        let object = texgen(
            scene.trace(),
            job.lens.index(),
            &scene.lenses()[job.lens.index()],
            mesh,
            &samples,
            &job.classes,
            job.blend,
            job.options.precision,
        );
        stats.texgen_ms += start.elapsed().as_secs_f64() * 1e3;
        Ok(BuiltLens { object, depths })
    }
}

/// A lens object tessellated on the CPU: its mesh and each vertex's ray paths.
pub(super) struct CpuLens {
    /// The merged mesh of its scene objects inside the view.
    pub(super) mesh: LensMesh,
    /// Per vertex of `mesh`, its ray paths (`None` where it was never evaluated).
    pub(super) samples: Vec<Option<VertexEvaluation<VertexPaths>>>,
    /// Per triangle of `mesh`, its subdivision depth.
    pub(super) depths: Vec<u8>,
}

/// Lens object `job` tessellated on the CPU, every vertex traced there: each of its scene objects
/// inside the view, merged into one mesh.
pub(super) fn tessellate_on_cpu(
    job: &LensJob<'_>,
    budget: &mut VertexBudget,
    stats: &mut HybridStats,
) -> Result<CpuLens, TessellationError> {
    let mut merged = MergedLens::default();
    let mut samples: Vec<Option<VertexEvaluation<VertexPaths>>> = Vec::new();
    for &object in &job.objects {
        let mesh = &job.scene.scene().objects[object].mesh;
        let oracle = job.oracle(object);
        let start = Instant::now();
        let tessellation = tessellate(mesh, &oracle, &budget.options_for(&job.tessellation, mesh))?;
        count_tessellation(
            Counted {
                mesh,
                tessellation: &tessellation,
                oracle: &oracle,
                start,
                texgen_ms: 0.0,
            },
            budget,
            stats,
        );
        let evaluations = merged.add(job, object, tessellation);
        // Moved, not copied, for a lens object of one scene object (the common case).
        if samples.is_empty() {
            samples = evaluations;
        } else {
            samples.extend(evaluations);
        }
    }
    let (mesh, depths) = merged.finish(job, stats);
    Ok(CpuLens {
        mesh,
        samples,
        depths,
    })
}

/// One scene object's tessellation, read back, to count.
pub(super) struct Counted<'a, S> {
    /// The input mesh.
    pub(super) mesh: &'a TriangleMesh,
    /// Its tessellation.
    pub(super) tessellation: &'a Tessellation<S>,
    /// The oracle that traced it (its rays and tracing time).
    pub(super) oracle: &'a PathOracle<'a>,
    /// When the tessellation began.
    pub(super) start: Instant,
    /// The share of its time that was texgen (on the GPU, in the same submission), ms.
    pub(super) texgen_ms: f64,
}

/// Spends `counted`'s vertices from `budget` and adds its costs and counts to `stats`: its ray
/// tracing (the oracle's batches, inside the tessellation), texgen, and the rest as the
/// tessellation's.
pub(super) fn count_tessellation<S>(
    counted: Counted<'_, S>,
    budget: &mut VertexBudget,
    stats: &mut HybridStats,
) {
    let Counted {
        mesh,
        tessellation,
        oracle,
        start,
        texgen_ms,
    } = counted;
    budget.left = budget
        .left
        .saturating_sub(tessellation.mesh.positions.len());
    stats.stopped_by_budget += tessellation.stats.stopped_by_budget;
    let elapsed = start.elapsed().as_secs_f64() * 1e3;
    let traced_ms = oracle.traced_ms();
    stats.trace_ms += traced_ms;
    stats.texgen_ms += texgen_ms;
    stats.tessellation_ms += (elapsed - traced_ms - texgen_ms).max(0.0);
    stats.counters += oracle.counters();
    stats.triangles_in += mesh.triangles.len();
    stats.triangles_out += tessellation.mesh.triangles.len();
    stats.vertices_traced += tessellation.stats.vertices_evaluated;
}

/// A lens object's scene objects' tessellations merged into one mesh, with each triangle's
/// depth and, for the convex-hull split, whether it lies on the hull facing the eye.
#[derive(Default)]
pub(super) struct MergedLens {
    positions: Vec<glam::Vec3>,
    triangles: Vec<[u32; 3]>,
    depths: Vec<u8>,
    on_hull: Vec<bool>,
}

impl MergedLens {
    /// Appends scene object `object`'s `tessellation`; returns its vertices' evaluations.
    pub(super) fn add<S>(
        &mut self,
        job: &LensJob<'_>,
        object: usize,
        tessellation: Tessellation<S>,
    ) -> Vec<Option<VertexEvaluation<S>>> {
        self.depths.extend(
            tessellation
                .triangles
                .iter()
                .map(|record| u8::try_from(record.depth).unwrap_or(u8::MAX)),
        );
        if job.hull_split {
            self.on_hull.extend(facing_hull(job, object, &tessellation));
        }
        // Moved, not copied, for a lens object of one scene object (the common case).
        if self.positions.is_empty() {
            self.positions = tessellation.mesh.positions;
            self.triangles = tessellation.mesh.triangles;
        } else {
            let base = self.positions.len() as u32;
            self.positions.extend(&tessellation.mesh.positions);
            self.triangles.extend(
                tessellation
                    .mesh
                    .triangles
                    .iter()
                    .map(|t| t.map(|i| i + base)),
            );
        }
        tessellation.evaluations
    }

    /// The merged mesh with the convex-hull split's triangles last (counted in `stats`), and
    /// each triangle's depth.
    pub(super) fn finish(
        mut self,
        job: &LensJob<'_>,
        stats: &mut HybridStats,
    ) -> (LensMesh, Vec<u8>) {
        let hull_triangles = if job.hull_split {
            hull_last(&mut self.triangles, &mut self.depths, &self.on_hull)
        } else {
            0
        };
        stats.hull_triangles += hull_triangles;
        let mesh = LensMesh {
            positions: self.positions,
            triangles: self.triangles,
            faces: job.faces,
            hull_triangles,
        };
        (mesh, self.depths)
    }
}

/// Per output triangle of `tessellation` (of scene object `object`), whether the convex-hull
/// split draws it with the distant layer only: its input triangle lies on the hull of the lens
/// geometry and it faces the camera (a back face of an open mesh, drawn from behind, looks into
/// the object and may well reflect it; one of a closed mesh is culled, and not counted).
fn facing_hull<'a, S>(
    job: &'a LensJob<'_>,
    object: usize,
    tessellation: &'a Tessellation<S>,
) -> impl Iterator<Item = bool> + 'a {
    let hull = job.scene.hull_triangles(object);
    let eye = job.view.screen.eye.as_vec3();
    let positions = &tessellation.mesh.positions;
    tessellation
        .triangles
        .iter()
        .zip(&tessellation.mesh.triangles)
        .map(move |(record, triangle)| {
            hull.get(record.source as usize).copied().unwrap_or(false)
                && faces_eye(triangle.map(|i| positions[i as usize]), eye)
        })
}

/// Moves the triangles `on_hull` marks (parallel to `triangles` and `depths`) after the others,
/// keeping each part's order, and returns how many there are: the compositor draws a lens
/// object's last [`LensObject::hull_triangles`](crate::render::LensObject::hull_triangles)
/// without its local layer.
pub(super) fn hull_last(
    triangles: &mut Vec<[u32; 3]>,
    depths: &mut Vec<u8>,
    on_hull: &[bool],
) -> usize {
    let hull = |t: usize| on_hull.get(t).copied().unwrap_or(false);
    let order: Vec<usize> = (0..triangles.len())
        .filter(|&t| !hull(t))
        .chain((0..triangles.len()).filter(|&t| hull(t)))
        .collect();
    *triangles = order.iter().map(|&t| triangles[t]).collect();
    // One depth per triangle, gathered with them (`MergedLens::add`).
    debug_assert_eq!(depths.len(), order.len());
    *depths = order
        .iter()
        .map(|&t| depths.get(t).copied().unwrap_or(0))
        .collect();
    (0..triangles.len()).filter(|&t| hull(t)).count()
}
