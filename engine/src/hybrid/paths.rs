//! Per-vertex ray paths from the actual camera (paper §5): for every vertex of a front-facing lens
//! triangle, a visibility query and the two greedy paths (initial refraction, initial reflection)
//! with their F·G, outgoing ray and topology. This is the [`VertexOracle`] the adaptive
//! tessellation asks; it evaluates each batch of new vertices in parallel (rayon) and in order.
//!
//! The paths are computed in f64 ([`VertexPrecision::F64`], the default). [`VertexPrecision::F32`]
//! runs the same code with every triangle test, Fresnel coefficient, direction and product in
//! f32, to measure what single precision would cost (`lensmap bench error`'s "CPU precision").

use std::sync::Mutex;

use glam::{DVec2, DVec3, Mat4, Vec2, Vec3};
use rayon::prelude::*;

use super::tessellate::{
    SurfaceVertex, TessellationError, VertexEvaluation, VertexOracle, faces_eye,
};
use crate::render::LensFaces;
use crate::trace::{
    Bounces, GreedyOptions, GreedyRayPath, Ray, Term,
    bvh::SurfaceHit,
    classes::{ClassList, ClassTerm, Event, MAX_CLASSES, trace_term},
    fresnel::{Real, Vector3},
    path::{FresnelLookup, trace_greedy_paths_in},
    schlick_table::SchlickTable,
    stats::TraceCounters,
    world::{Part, TraceScene, WorldHit},
};

/// The float type the per-vertex CPU stages compute in: the vertex paths (triangle tests,
/// Fresnel, directions, F·G) and texgen (the shell intersections). Vertex positions are f32
/// either way (they are the GPU's), and so are the F·G and directions handed to the GPU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VertexPrecision {
    /// Double precision: what lensmap renders with.
    #[default]
    F64,
    /// Single precision throughout the per-vertex stages, to measure what it would cost (what a
    /// GPU vertex tracer would compute in); secondary rays start 1.5e-5 (relative) off the
    /// surface instead of 1e-9, as f32 positions need.
    F32,
}

impl VertexPrecision {
    /// Short name for tables (`f64`, `f32`).
    pub fn name(self) -> &'static str {
        match self {
            VertexPrecision::F64 => "f64",
            VertexPrecision::F32 => "f32",
        }
    }
}

/// One term's greedy path at a vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TermPath {
    /// F·G per channel (0 for a path truncated at the interface cap).
    pub fg: DVec3,
    /// The ray leaving the lens object.
    pub outgoing: Ray,
    /// Interfaces met and the greedy choices: the path's topology.
    pub topology: (u32, u32),
}

/// The terms' paths at a vertex: the two greedy terms, or one per path class (`None`: no such
/// path, e.g. no refraction for a mirror or under total internal reflection at the first
/// interface, or a path of another sequence than the class's).
#[derive(Clone, Debug, PartialEq)]
pub struct VertexPaths {
    /// `[refraction, reflection]`: the greedy terms (both `None` under path classes).
    pub terms: [Option<TermPath>; 2],
    /// Under path classes, the path of each class term of the oracle's list, in its order;
    /// empty for the greedy terms.
    pub classes: Vec<Option<TermPath>>,
}

impl VertexPaths {
    /// The path of greedy term `term` (none for a path class: see [`VertexPaths::classes`]).
    pub fn get(&self, term: Term) -> Option<&TermPath> {
        match term {
            Term::Refraction => self.terms[0].as_ref(),
            Term::Reflection => self.terms[1].as_ref(),
            Term::Class(_) => None,
        }
    }
}

/// Whether two vertices' class paths (parallel lists) differ enough to split the edge between
/// them: each class's angle between its outgoing rays, weighted by its F·G (the larger of the
/// two vertices', its largest channel), against the angle threshold. A path at one vertex and
/// not the other, or of another topology, counts as the largest angle, π. A class that carries
/// little light (along a total-internal-reflection boundary, where it appears and vanishes)
/// thus splits only as far as the error it could make in the image, which its F·G bounds: a
/// class of weight 1 is held to the threshold as the greedy terms are; one below
/// threshold / π never splits.
pub(crate) fn classes_differ(
    a: &[Option<TermPath>],
    b: &[Option<TermPath>],
    threshold_radians: f64,
) -> bool {
    let weight = |p: &Option<TermPath>| p.map_or(0.0, |p| p.fg.max_element().max(0.0));
    a.len() != b.len()
        || a.iter().zip(b).any(|(p, q)| {
            let angle = match (p, q) {
                (Some(p), Some(q)) if p.topology == q.topology => p
                    .outgoing
                    .direction
                    .dot(q.outgoing.direction)
                    .clamp(-1.0, 1.0)
                    .acos(),
                (None, None) => 0.0,
                _ => std::f64::consts::PI,
            };
            weight(p).max(weight(q)) * angle > threshold_radians
        })
}

/// The camera as the tessellation sees it.
#[derive(Clone, Copy, Debug)]
pub struct ScreenCamera {
    /// Eye position.
    pub eye: DVec3,
    /// World → Vulkan clip space.
    pub view_proj: Mat4,
    /// Framebuffer size in subpixels (pixels × supersampling).
    pub subpixels: Vec2,
}

impl ScreenCamera {
    /// Where a world-space point lands, in subpixels; `None` at or behind the eye's plane, or
    /// for a non-finite projection.
    pub fn project(&self, position: Vec3) -> Option<Vec2> {
        let clip = self.view_proj * position.extend(1.0);
        if !clip.is_finite() || clip.w <= 1e-6 {
            return None;
        }
        let ndc = Vec2::new(clip.x, clip.y) / clip.w;
        Some((ndc + Vec2::ONE) * 0.5 * self.subpixels)
    }
}

/// |cos| between a vertex's normal and its eye ray below which the vertex is on the silhouette:
/// its paths start at the vertex with its normal turned to face the eye, whether or not the eye
/// ray happens to meet the vertex's own surface (which rounding decides there).
pub(crate) const GRAZING: f64 = 0.02;

/// Where a traced vertex's paths start and stop (the CPU oracle's options), for the GPU's passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathSettings {
    /// The lens object (TraceScene order).
    pub lens: usize,
    /// Scene object of the vertices.
    pub object: usize,
    /// Where the paths stop.
    pub bounces: Bounces,
    /// Most interfaces a path may meet.
    pub max_interfaces: u32,
    /// The path-class terms traced instead of the two greedy terms (none: greedy).
    pub classes: ClassList,
}

/// What a device's passes need of a [`PathOracle`] to trace and tessellate by its rules.
#[derive(Clone, Copy, Debug)]
pub struct OracleSettings {
    /// Where the paths start and stop.
    pub paths: PathSettings,
    /// The frame's camera.
    pub camera: ScreenCamera,
    /// cos of the angle threshold.
    pub cos_threshold: f32,
    /// Whether back-facing triangles are evaluated (an open mesh).
    pub back_faces: bool,
}

/// Ray traces the vertices of one scene object of one lens object.
pub struct PathOracle<'a> {
    trace: &'a TraceScene,
    lens: usize,
    object: usize,
    camera: ScreenCamera,
    /// cos of the largest angle between two vertices' outgoing rays before they count as different.
    cos_threshold: f64,
    /// Which faces are evaluated: both for an open mesh, whose inside the camera can see.
    faces: LensFaces,
    greedy: GreedyOptions,
    precision: VertexPrecision,
    /// The table Schlick's fifth-order term is looked up in; `None`: evaluated.
    fresnel: Option<&'a SchlickTable>,
    /// The path-class terms traced per vertex instead of the greedy terms; empty: greedy.
    classes: Vec<ClassTerm>,
    counters: Mutex<(TraceCounters, f64)>,
}

impl<'a> PathOracle<'a> {
    /// An oracle for scene object `object` of lens object `lens`; `angle_radians` is the paper's
    /// 3° outgoing-direction threshold; `faces` says whether back-facing triangles are evaluated
    /// too ([`LensFaces::Both`], for an open mesh).
    pub fn new(
        trace: &'a TraceScene,
        lens: usize,
        object: usize,
        camera: ScreenCamera,
        angle_radians: f64,
        faces: LensFaces,
    ) -> Self {
        PathOracle {
            trace,
            lens,
            object,
            camera,
            cos_threshold: angle_radians.cos(),
            faces,
            greedy: GreedyOptions::default(),
            precision: VertexPrecision::F64,
            fresnel: None,
            classes: Vec::new(),
            counters: Mutex::new((TraceCounters::default(), 0.0)),
        }
    }

    /// This oracle tracing one path per class term of `classes` at every vertex
    /// ([`crate::trace::classes::trace_term`], f64, exact Fresnel) instead of the two greedy
    /// terms (an empty list, the default). Its split test weights each class by its F·G
    /// ([`classes_differ`]).
    pub fn with_classes(self, classes: Vec<ClassTerm>) -> Self {
        PathOracle { classes, ..self }
    }

    /// This oracle computing its paths in `precision` (f64 unless told).
    pub fn with_precision(self, precision: VertexPrecision) -> Self {
        PathOracle { precision, ..self }
    }

    /// This oracle's paths stopping where `bounces` says (until they leave the lens object
    /// unless told; at the first bounce for a lens object layered by bounce).
    pub fn with_bounces(self, bounces: Bounces) -> Self {
        PathOracle {
            greedy: GreedyOptions {
                bounces,
                ..self.greedy
            },
            ..self
        }
    }

    /// This oracle looking Schlick's fifth-order term up in `table` (the PEM paper's 1D texture;
    /// mirrors and glass alike, [`FresnelLookup::SchlickTable`]), or evaluating Fresnel exactly
    /// (`None`, the default).
    pub fn with_fresnel(self, table: Option<&'a SchlickTable>) -> Self {
        PathOracle {
            fresnel: table,
            ..self
        }
    }

    /// Rays and triangle tests spent so far.
    pub fn counters(&self) -> TraceCounters {
        self.counters.lock().map(|c| c.0).unwrap_or_default()
    }

    /// What the GPU's passes need of this oracle: where its paths start and stop, its camera
    /// and its criterion.
    pub fn gpu_settings(&self) -> Result<OracleSettings, crate::gpu::GpuError> {
        let classes = ClassList::new(&self.classes).ok_or_else(|| {
            crate::gpu::GpuError::Internal(format!(
                "the GPU tracer: {} path classes, past the {MAX_CLASSES} a class set holds",
                self.classes.len()
            ))
        })?;
        Ok(OracleSettings {
            paths: PathSettings {
                lens: self.lens,
                object: self.object,
                bounces: self.greedy.bounces,
                max_interfaces: self.greedy.max_interfaces,
                classes,
            },
            camera: self.camera,
            cos_threshold: self.cos_threshold as f32,
            back_faces: self.evaluates_back_faces(),
        })
    }

    /// Adds `ms` of tracing time and `counters` to the oracle's: work it asked of a device.
    pub fn add_traced(&self, ms: f64, counters: TraceCounters) {
        if let Ok(mut guard) = self.counters.lock() {
            guard.1 += ms;
            guard.0 += counters;
        }
    }

    /// The scene it traces.
    pub fn trace_scene(&self) -> &TraceScene {
        self.trace
    }

    /// Wall time spent in vertex batches so far, ms.
    pub fn traced_ms(&self) -> f64 {
        self.counters.lock().map(|c| c.1).unwrap_or_default()
    }

    /// Traces one vertex in the oracle's precision: the eye ray (the visibility query, and the
    /// first hit when the vertex is visible), then the two greedy paths from the vertex.
    fn trace_vertex(
        &self,
        vertex: &SurfaceVertex,
        counters: &mut TraceCounters,
    ) -> (VertexPaths, bool) {
        match self.precision {
            VertexPrecision::F64 => self.trace_vertex_in::<f64>(vertex, counters),
            VertexPrecision::F32 => self.trace_vertex_in::<f32>(vertex, counters),
        }
    }

    /// [`PathOracle::trace_vertex`] with the eye ray, every triangle test and the paths in `R`.
    fn trace_vertex_in<R: Real>(
        &self,
        vertex: &SurfaceVertex,
        counters: &mut TraceCounters,
    ) -> (VertexPaths, bool) {
        let position = vertex.position.as_dvec3();
        let to_vertex =
            <R::Vec3 as Vector3>::of(position) - <R::Vec3 as Vector3>::of(self.camera.eye);
        let distance = to_vertex.length();
        let direction = if distance > R::ZERO {
            (to_vertex / distance).to_dvec3()
        } else {
            DVec3::NEG_Z
        };
        let distance = distance.to_f64();
        let eye_ray = Ray::new(self.camera.eye, direction);
        counters.primary_rays += 1;
        // Only what lies up to the vertex matters: the vertex itself, or an occluder.
        let tolerance = 1e-4 * distance.max(1.0);
        let first =
            closest_hit_within_in::<R>(self.trace, &eye_ray, distance + tolerance, counters);
        // Visible: nothing hit before the vertex. Whether the eye ray meets the vertex's own
        // surface or slips past it at a silhouette is up to rounding (f32 and f64, CPU and GPU
        // differ there); an occluder stands clear of it.
        let visible = first.is_none_or(|h| h.hit.distance >= distance - tolerance);
        let grazing = vertex
            .normal
            .as_dvec3()
            .normalize_or_zero()
            .dot(direction)
            .abs()
            < GRAZING;
        let on_vertex = !grazing
            && matches!(first, Some(h) if h.part == Part::Lens(self.lens)
                && (h.hit.distance - distance).abs() <= tolerance);
        let hit = match first {
            Some(h) if on_vertex => h.hit,
            // Occluded, or a silhouette the eye ray slips past: start the paths at the vertex
            // itself with its normal, turned to face the eye so the first interface is an entry.
            _ => {
                let mut normal = vertex.normal.as_dvec3().normalize_or(-direction);
                let facing = direction.dot(normal);
                if facing >= -1e-3 {
                    normal = (normal - (facing + 1e-3) * direction).normalize_or(-direction);
                }
                SurfaceHit {
                    distance,
                    position,
                    geometric_normal: normal,
                    shading_normal: normal,
                    uv: vertex.uv.map_or(DVec2::ZERO, |uv| uv.as_dvec2()),
                    object: self.object,
                    primitive: u32::MAX,
                }
            }
        };
        if !self.classes.is_empty() {
            // Path classes are traced in f64 with exact Fresnel (the options are checked so).
            let lens = self.trace.lens(self.lens);
            let classes = self
                .classes
                .iter()
                .map(|&term| {
                    trace_term(&lens, &eye_ray, &hit, term, counters).map(|path| TermPath {
                        fg: path.weight(),
                        outgoing: path.outgoing_ray,
                        topology: (
                            path.class.events_len(),
                            path.class.events().filter(|&e| e == Event::Reflect).count() as u32,
                        ),
                    })
                })
                .collect();
            let paths = VertexPaths {
                terms: [None, None],
                classes,
            };
            return (paths, visible);
        }
        let lens = self.trace.lens_in::<R>(self.lens);
        let fresnel = FresnelLookup::from(self.fresnel);
        let paths =
            trace_greedy_paths_in::<R>(&lens, &eye_ray, &hit, self.greedy, fresnel, counters);
        let term = |path: &GreedyRayPath| TermPath {
            fg: weight_in::<R>(path),
            outgoing: path.outgoing_ray,
            topology: (path.interfaces, path.reflections),
        };
        (
            VertexPaths {
                terms: [
                    paths.refraction.as_ref().map(term),
                    Some(term(&paths.reflection)),
                ],
                classes: Vec::new(),
            },
            visible,
        )
    }
}

impl PathOracle<'_> {
    /// Traces `vertices` on the CPU in parallel (rayon), in order, with the rays spent.
    fn trace_on_cpu(
        &self,
        vertices: &[SurfaceVertex],
    ) -> (Vec<VertexEvaluation<VertexPaths>>, TraceCounters) {
        let results: Vec<(VertexEvaluation<VertexPaths>, TraceCounters)> = vertices
            .par_iter()
            .map(|vertex| {
                let mut counters = TraceCounters::default();
                let (sample, visible) = self.trace_vertex(vertex, &mut counters);
                (VertexEvaluation { sample, visible }, counters)
            })
            .collect();
        let mut total = TraceCounters::default();
        for (_, counters) in &results {
            total += *counters;
        }
        (results.into_iter().map(|(e, _)| e).collect(), total)
    }
}

/// [`GreedyRayPath::weight`] (F·G, 0 for a truncated path) with the product in `R`.
fn weight_in<R: Real>(path: &GreedyRayPath) -> DVec3 {
    if path.truncated {
        DVec3::ZERO
    } else {
        (<R::Vec3 as Vector3>::of(path.fresnel) * <R::Vec3 as Vector3>::of(path.attenuation))
            .to_dvec3()
    }
}

/// [`TraceScene::closest_hit_within`] (no surface excluded, no lens object skipped) with every
/// triangle test in `R`: the environment first, then each lens object, each query cut at the
/// best distance so far.
fn closest_hit_within_in<R: Real>(
    trace: &TraceScene,
    ray: &Ray,
    max_distance: f64,
    counters: &mut TraceCounters,
) -> Option<WorldHit> {
    let parts = std::iter::once(Part::Environment).chain((0..trace.lenses.len()).map(Part::Lens));
    let mut best: Option<WorldHit> = None;
    for part in parts {
        let max = best.map_or(max_distance, |b| b.hit.distance);
        if let Some(hit) =
            trace
                .bvh(part)
                .closest_hit_in::<R>(ray, 0.0, max, None, &mut counters.triangle_tests)
        {
            best = Some(WorldHit { hit, part });
        }
    }
    best
}

impl VertexOracle for PathOracle<'_> {
    type Sample = VertexPaths;

    /// One vertex (its counters are not kept): batches are what the tessellation asks for.
    fn evaluate(&self, vertex: &SurfaceVertex) -> VertexPaths {
        self.trace_vertex(vertex, &mut TraceCounters::default()).0
    }

    fn evaluate_batch(
        &self,
        vertices: &[SurfaceVertex],
    ) -> Result<Vec<VertexEvaluation<VertexPaths>>, TessellationError> {
        let start = std::time::Instant::now();
        let (evaluations, counters) = self.trace_on_cpu(vertices);
        if let Ok(mut guard) = self.counters.lock() {
            guard.1 += start.elapsed().as_secs_f64() * 1e3;
            guard.0 += counters;
        }
        Ok(evaluations)
    }

    fn differ(&self, a: &VertexPaths, b: &VertexPaths) -> bool {
        if !self.classes.is_empty() {
            return classes_differ(&a.classes, &b.classes, self.cos_threshold.acos());
        }
        a.terms.iter().zip(&b.terms).any(|pair| match pair {
            (None, None) => false,
            (Some(p), Some(q)) => {
                p.topology != q.topology
                    || p.outgoing.direction.dot(q.outgoing.direction) < self.cos_threshold
            }
            _ => true,
        })
    }

    fn screen(&self, position: Vec3) -> Option<Vec2> {
        self.camera.project(position)
    }

    fn front_facing(&self, corners: [Vec3; 3]) -> bool {
        faces_eye(corners, self.camera.eye.as_vec3())
    }

    fn evaluates_back_faces(&self) -> bool {
        self.faces == LensFaces::Both
    }

    fn outside_view(&self, corners: [Vec3; 3]) -> bool {
        outside_clip_volume(&corners.map(|p| self.camera.view_proj * p.extend(1.0)))
    }
}

/// Whether clip-space points lie wholly outside the Vulkan view volume: all of them beyond one of
/// its side planes (−w ≤ x, y ≤ w) or its near plane (0 ≤ z). The far plane is not tested: the
/// runtime puts it past everything in the scene. Conservative: points that only straddle a
/// corner of the frustum count as visible.
pub(crate) fn outside_clip_volume(clip: &[glam::Vec4]) -> bool {
    let planes: [fn(&glam::Vec4) -> bool; 5] = [
        |c| c.x < -c.w,
        |c| c.x > c.w,
        |c| c.y < -c.w,
        |c| c.y > c.w,
        |c| c.z < 0.0,
    ];
    planes.iter().any(|outside| clip.iter().all(outside))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A class path of weight `fg` (every channel) leaving along the direction `degrees` from
    /// +z in the xz plane, of topology `topology`.
    fn path(fg: f64, degrees: f64, topology: Topology) -> Option<TermPath> {
        let a = degrees.to_radians();
        Some(TermPath {
            fg: DVec3::splat(fg),
            outgoing: Ray::new(DVec3::ZERO, DVec3::new(a.sin(), 0.0, a.cos())),
            topology: (topology.events, topology.reflections),
        })
    }

    /// A path's events and how many of them reflect.
    #[derive(Clone, Copy)]
    struct Topology {
        events: u32,
        reflections: u32,
    }

    /// The weighted split test against its closed form, weight × angle > threshold, at the
    /// paper's 3°: a class of weight 1 is held to the threshold, one of weight ½ to twice it;
    /// a path at one vertex only (or of another topology) is the angle π, so it splits above
    /// weight 3/180 and not below; the larger of the two weights counts, and the largest
    /// channel; any one class that differs splits the edge.
    #[test]
    fn a_class_splits_by_its_angle_weighted_by_its_fg() {
        let threshold = 3f64.to_radians();
        let tt = Topology {
            events: 2,
            reflections: 0,
        };
        let trt = Topology {
            events: 3,
            reflections: 1,
        };
        let tail = Topology {
            events: 4,
            reflections: 2,
        };
        let differ =
            |a: Option<TermPath>, b: Option<TermPath>| classes_differ(&[a], &[b], threshold);
        assert!(!differ(path(1.0, 0.0, tt), path(1.0, 2.9, tt)));
        assert!(differ(path(1.0, 0.0, tt), path(1.0, 3.1, tt)));
        assert!(!differ(path(0.5, 0.0, tt), path(0.5, 5.9, tt)));
        assert!(differ(path(0.5, 0.0, tt), path(0.5, 6.1, tt)));
        // The larger weight of the two.
        assert!(differ(path(0.01, 0.0, tt), path(0.5, 6.1, tt)));
        // Present at one vertex only: π × weight against 3°, i.e. weight 1/60.
        assert!(!differ(path(0.016, 0.0, tt), None));
        assert!(differ(path(0.017, 0.0, tt), None));
        assert!(!differ(None, None));
        // Another topology (a greedy tail's) is the angle π too.
        assert!(differ(path(0.5, 0.0, tt), path(0.5, 0.0, tail)));
        assert!(!differ(path(0.01, 0.0, tt), path(0.01, 0.0, tail)));
        // The largest channel.
        let mut red = path(0.01, 0.0, tt);
        if let Some(p) = red.as_mut() {
            p.fg.x = 1.0;
        }
        assert!(differ(red, path(0.01, 3.1, tt)));
        // One class of several.
        let quiet = [path(1.0, 0.0, tt), path(0.9, 1.0, trt)];
        let moved = [path(1.0, 0.0, tt), path(0.9, 5.0, trt)];
        assert!(!classes_differ(&quiet, &quiet, threshold));
        assert!(classes_differ(&quiet, &moved, threshold));
    }
}
