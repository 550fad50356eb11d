//! One hybrid frame on the CPU: trace and tessellate every lens object from the real camera,
//! generate the layered-EM texture coordinates (`texgen`), pick the viewpoint samples,
//! and assemble the [`FrameInput`] the compositor renders. Timed per stage like the paper's
//! table. A frame equal to the last one is reused whole.

use std::{
    sync::{
        Arc, Mutex,
        atomic::{AtomicU64, Ordering},
    },
    time::Instant,
};

use glam::{DVec3, Mat4, Vec2, Vec3};
use rayon::prelude::*;

pub use super::paths::VertexPrecision;
use super::{
    gpu::{GpuPaths, TexgenRequest},
    paths::{PathOracle, ScreenCamera, VertexPaths},
    scene::HybridScene,
    sky::SkyDome,
    tessellate::{TessellationError, TessellationOptions, VertexEvaluation, faces_eye, tessellate},
    texgen::{self, LensMesh, texgen},
    viewpoints::{self, ViewSpaceFit, ViewpointBlend},
};
pub use crate::trace::schlick_table::FresnelModel;
use crate::{
    layers::{LayerShell, Layering},
    options::OptionError,
    render::{
        DeviceLensPart, DeviceWork, EnvironmentMesh, FrameInput, LensFaces, LensObject,
        ResidentLens, TermVertices,
    },
    scene::Camera,
    trace::{
        schlick_table::SchlickTable,
        stats::TraceCounters,
        world::{LensBvh, TraceScene},
    },
};

/// Everything a hybrid frame depends on besides the (immutable) scene and trace structures: a
/// frame with an equal key is the same frame.
#[derive(Clone, Debug, PartialEq)]
struct FrameKey {
    camera: Camera,
    options: HybridOptions,
    vertex_exact: bool,
    /// Whether the vertices were traced on a GPU (its f32 paths are another frame), and then
    /// whether the frame is drawn from the device's buffers and the tracer whose buffers they
    /// are (another tracer, perhaps on another device, must not draw them).
    on_gpu: Option<(bool, u64)>,
    /// Per lens object: EM origins, shells and the identity of every map (`Arc` address).
    layers: Vec<LayersKey>,
    /// The rest of the scene a frame draws: the environment meshes (`Arc` addresses), the sky
    /// dome (its identity), the viewpoint samples and which lens faces are drawn. Callers may
    /// change these public fields; a changed one is another frame.
    environment: Vec<usize>,
    sky: Option<usize>,
    viewpoints: Vec<DVec3>,
    faces: Vec<LensFaces>,
    /// The glossy objects drawn from radiance maps: the reconstruction and, per object, the
    /// addresses of its mesh and of every map ([`super::glossy::GlossyScene::key`]).
    glossy: Option<super::glossy::GlossyKey>,
}

/// What identifies one lens object's layered EMs in a [`FrameKey`]: per layer its EM origin,
/// the shells, per viewpoint sample the address of every map, and how rays are split between
/// the layers (the paths and the convex-hull split depend on it).
type LayersKey = (Vec<DVec3>, Vec<LayerShell>, Vec<Vec<usize>>, Layering);

impl FrameKey {
    fn new(
        scene: &HybridScene,
        camera: &Camera,
        options: &HybridOptions,
        vertex_exact: bool,
        on_gpu: Option<(bool, u64)>,
    ) -> Self {
        FrameKey {
            camera: *camera,
            options: *options,
            vertex_exact,
            on_gpu,
            layers: scene
                .lenses
                .iter()
                .map(|l| {
                    let maps = l
                        .maps
                        .iter()
                        .map(|v| v.iter().map(|m| Arc::as_ptr(m) as usize).collect())
                        .collect();
                    (l.em_origins.clone(), l.shells.clone(), maps, l.layering)
                })
                .collect(),
            environment: scene
                .environment
                .iter()
                .map(|m| Arc::as_ptr(m) as usize)
                .collect(),
            sky: scene.sky.as_ref().map(SkyDome::identity),
            viewpoints: scene.viewpoints().to_vec(),
            faces: scene.faces.clone(),
            glossy: scene.glossy.as_ref().map(super::glossy::GlossyScene::key),
        }
    }
}

/// The last frame a [`HybridScene`] built (none at first), reused while nothing it depends on
/// changed.
#[derive(Default)]
pub(super) struct FrameCache(Mutex<Option<CachedFrame>>);

/// The last frame a [`HybridScene`] built, with the identity that tells a caller holding its
/// upload that nothing changed.
struct CachedFrame {
    key: FrameKey,
    /// Shared with the caller that uploads it: caching a frame copies nothing.
    frame: Arc<FrameInput>,
    /// Per lens object of `frame`, each triangle's subdivision depth (parallel to its
    /// `triangles`).
    depths: Vec<Vec<u8>>,
    stats: HybridStats,
    identity: u64,
}

/// Identities of built frames, unique in the process (0 is never used).
static FRAME_IDENTITY: AtomicU64 = AtomicU64::new(1);

/// A frame from [`HybridScene::frame_unless`].
#[derive(Debug)]
pub enum BuiltFrame {
    /// The frame the caller already holds (same identity): nothing to build or upload.
    Unchanged(HybridStats),
    /// A frame to upload, with its identity.
    New(Arc<FrameInput>, HybridStats, u64),
}

/// The paper's angle threshold: outgoing rays further apart than this make vertices differ.
pub const DEFAULT_ANGLE_DEGREES: f64 = 3.0;

/// Per-frame options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HybridOptions {
    /// Adaptive tessellation: the threshold t in subpixels (one default, one check, in
    /// [`TessellationOptions`]) and the depth cap.
    pub tessellation: TessellationOptions,
    /// Outgoing rays further apart than this (radians) make vertices differ (paper: 3°); in
    /// (0, π).
    pub angle_radians: f64,
    /// Footprint coarsening, in subpixels; 0 (the default) turns it off. A lens object whose
    /// screen footprint (the longer side of its projected bounding box) spans fewer subpixels
    /// than this is tessellated with `t × footprint / extent` (at most 8 t): a distant or tiny
    /// object gets proportionally fewer vertices. Changes the image where it applies.
    pub footprint_subpixels: f32,
    /// The float type of the per-vertex stages (vertex paths, texgen): f64 (the default), or
    /// f32 to measure what single precision would cost.
    pub precision: VertexPrecision,
    /// Which viewpoint samples a frame blends: the view space's own rule (the default), or
    /// fewer, to measure what the blend is worth.
    pub viewpoint_blending: ViewpointBlending,
    /// How the vertex paths evaluate Fresnel: exactly (the default: Schlick for mirrors, exact
    /// dielectric Fresnel for glass), or Schlick with its fifth-order term looked up in a 1D
    /// table per vertex (the PEM paper's 1D texture).
    pub fresnel: FresnelModel,
    /// The convex-hull split (PEM paper §4): a lens object layered by bounce draws its triangles
    /// on the convex hull of the lens geometry (facing the camera) with the distant layer only,
    /// since they cannot show self-reflections ([`crate::hybrid::hull`]). On by default; no
    /// effect on lens objects layered by distance.
    pub hull_split: bool,
    /// Where the lens vertices are ray traced: on the CPU, on the GPU, or as the device suits.
    pub tracer: VertexTracer,
    /// How the GPU tracer finds a ray's hits.
    pub traversal: super::gpu::Traversal,
    /// What the GPU tracer computes in: f32 (the default, every device), or f64, the CPU
    /// oracle's precision (devices with `shaderFloat64`). `precision` is the CPU's.
    pub gpu_precision: VertexPrecision,
}

/// Where a frame's lens vertices are ray traced (`--tracer`). The library's default is the CPU,
/// so that a caller's frames do not change with the device; the command line's is `auto`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum VertexTracer {
    /// On the CPU, in the frame's [`VertexPrecision`]: the paper's reference implementation.
    #[default]
    Cpu,
    /// On the GPU, in f32, by the compute pass of [`crate::hybrid::gpu`] (the CPU oracle's rules);
    /// only through a [`crate::runner::FrameRunner`], which owns the device.
    Gpu,
    /// The GPU on a hardware device, the CPU on a CPU device (lavapipe), where the CPU path is
    /// measured faster (`docs/results.md#gpu-frames`); the CPU without a device, or where the
    /// device cannot hold the scene's geometry.
    Auto,
}

impl VertexTracer {
    /// The name `--tracer` takes.
    pub fn name(self) -> &'static str {
        match self {
            VertexTracer::Cpu => "cpu",
            VertexTracer::Gpu => "gpu",
            VertexTracer::Auto => "auto",
        }
    }

    /// Whether this choice traces on `gpu` (for `auto`: whether it is not a CPU device).
    pub fn on_gpu(self, gpu: &crate::gpu::Gpu) -> bool {
        match self {
            VertexTracer::Cpu => false,
            VertexTracer::Gpu => true,
            VertexTracer::Auto => !gpu.is_cpu_device(),
        }
    }
}

/// Which viewpoint samples a frame blends.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ViewpointBlending {
    /// The view space's rule: the two nearest samples along a 1D view space, the three of the
    /// triangle holding the camera in a 2D one ([`ViewSpaceBlender::blend`](crate::hybrid::ViewSpaceBlender::blend)).
    #[default]
    ViewSpace,
    /// The two samples nearest in angle, weighted by relative angle ([`viewpoints::blend`]),
    /// in any view space.
    TwoNearest,
    /// The nearest sample alone.
    Nearest,
}

impl Default for HybridOptions {
    fn default() -> Self {
        HybridOptions {
            tessellation: TessellationOptions::default(),
            angle_radians: DEFAULT_ANGLE_DEGREES.to_radians(),
            footprint_subpixels: 0.0,
            precision: VertexPrecision::F64,
            viewpoint_blending: ViewpointBlending::ViewSpace,
            fresnel: FresnelModel::Exact,
            hull_split: true,
            tracer: VertexTracer::Cpu,
            traversal: super::gpu::Traversal::Auto,
            gpu_precision: VertexPrecision::F32,
        }
    }
}

/// The most footprint coarsening multiplies `t` by.
pub const MAX_FOOTPRINT_COARSENING: f32 = 8.0;

impl HybridOptions {
    /// The defaults with tessellation threshold `t` (subpixels).
    pub fn with_t(t: f32) -> HybridOptions {
        HybridOptions {
            tessellation: TessellationOptions {
                t,
                ..TessellationOptions::default()
            },
            ..HybridOptions::default()
        }
    }

    /// Checks every option: `t` ([`TessellationOptions::validate`]), the footprint (finite,
    /// ≥ 0), the angle in (0°, 180°) and the Fresnel table's size ([`FresnelModel::validate`]).
    pub fn validate(&self) -> Result<(), OptionError> {
        self.tessellation.validate()?;
        self.fresnel.validate()?;
        OptionError::require(
            self.footprint_subpixels.is_finite() && self.footprint_subpixels >= 0.0,
            crate::options::names::FOOTPRINT,
            self.footprint_subpixels,
            "give a number of subpixels ≥ 0 (0 turns footprint coarsening off), e.g. 64",
        )?;
        // The check is on the radians the oracle uses (an angle that underflows to 0 is out);
        // the message shows degrees as the user wrote them, at f32 precision so that the trip
        // through radians does not show (`-3`, not `-3.0000000000000004`).
        let radians = self.angle_radians;
        OptionError::require(
            radians.is_finite() && radians > 0.0 && radians < std::f64::consts::PI,
            crate::options::names::ANGLE,
            radians.to_degrees() as f32,
            "give an angle in (0, 180), e.g. 3",
        )
    }
}

/// What one frame cost, in the paper's categories.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HybridStats {
    /// Ray tracing at vertices (visibility and both paths), ms.
    pub trace_ms: f64,
    /// Adaptive tessellation, excluding the ray tracing it asks for, ms.
    pub tessellation_ms: f64,
    /// Texture coordinate generation, ms.
    pub texgen_ms: f64,
    /// The rest of building the frame on the CPU (far plane, sky dome, viewpoint blend, the
    /// frustum test, gathering the lens meshes), ms.
    pub assemble_ms: f64,
    /// Rays and triangle tests of the vertex tracing.
    pub counters: TraceCounters,
    /// Lens triangles before and after tessellation.
    pub triangles_in: usize,
    /// Lens triangles after tessellation.
    pub triangles_out: usize,
    /// Vertices ray traced.
    pub vertices_traced: usize,
    /// Lens objects skipped because their bounds lie wholly outside the view frustum: neither
    /// traced nor tessellated nor drawn.
    pub lenses_outside_view: usize,
    /// Leaves left unsplit because the frame's vertex budget
    /// ([`TessellationOptions::max_vertices`], shared by all lens objects in order) was spent.
    pub stopped_by_budget: usize,
    /// Lens objects tessellated with a coarser `t` because their screen footprint is smaller
    /// than [`HybridOptions::footprint_subpixels`].
    pub lenses_coarsened: usize,
    /// Whether the camera's direction lies outside the view space the samples cover (2D: in no
    /// triangle of its triangulation; see [`ViewSpaceFit::outside`]); the frame then blends the
    /// samples of the nearest point of the region.
    pub outside_view_space: bool,
    /// Viewpoint samples the frame blends (1 to 3), each with its own layered EMs.
    pub viewpoints_blended: usize,
    /// Radiance maps the glossy pass reads (warped, or turned, and blended): per glossy object,
    /// its view samples blended (1 to 3) times its lobes.
    pub glossy_maps: usize,
    /// Lens triangles (after tessellation) drawn with the distant layer only by the convex-hull
    /// split ([`HybridOptions::hull_split`]): on the hull of the lens geometry and facing the
    /// camera, in lens objects layered by bounce.
    pub hull_triangles: usize,
    /// Whether the lens vertices were traced on the GPU ([`HybridOptions::tracer`]).
    pub traced_on_gpu: bool,
    /// Whether the lens objects were drawn where the GPU tessellation left them: the vertex,
    /// triangle, ray and budget counts above are then the device's, added once the frame was
    /// done ([`crate::runner::FrameRunner`]; for a frame into a host's image, with the next
    /// frame: [`crate::runner::HostFrame::previous`]), and `trace_ms` is the time to prepare the
    /// tessellation's work, which the frame records (its device time is in the frame's
    /// execution).
    pub counted_on_device: bool,
    /// With the GPU tracer [timing its stages](crate::hybrid::gpu::GpuTracer::time_stages): the
    /// device time of the tessellation's split passes and T-junction removal, summed over the
    /// lens objects (`trace_ms` and `texgen_ms` are then the device time of those passes, and,
    /// for a frame read back, `tessellation_ms` the rest: these passes, the submission, the
    /// read-back and rebuilding the mesh on the CPU; timing waits for each tessellation). `None`
    /// otherwise.
    pub gpu_split_ms: Option<f64>,
    /// Whether the frame was reused whole from the previous one (same camera, options and
    /// layered EMs): no vertex traced, tessellated or given texture coordinates.
    pub reused: bool,
}

impl HybridScene {
    /// Builds the frame for `camera` (its resolution × supersampling is the framebuffer size).
    /// A frame equal to the previous one (same camera, options and layered EMs) is copied from
    /// it rather than traced again (`stats.reused`).
    pub fn frame(
        &self,
        camera: &Camera,
        options: &HybridOptions,
    ) -> Result<(FrameInput, HybridStats), TessellationError> {
        match self.frame_unless(camera, options, 0)? {
            // The cache keeps its share: the caller gets its own copy.
            BuiltFrame::New(frame, stats, _) => Ok((Arc::unwrap_or_clone(frame), stats)),
            // Identity 0 is never held.
            BuiltFrame::Unchanged(_) => unreachable!("no frame has identity 0"),
        }
    }

    /// Forgets the last frame, so that the next one is built from scratch even for the same
    /// camera: what timing a full frame needs.
    pub fn forget_frame(&self) {
        if let Ok(mut cache) = self.cache.0.lock() {
            *cache = None;
        }
    }

    /// The frame for `camera`, or [`BuiltFrame::Unchanged`] when it is the frame of identity
    /// `held` (one this scene built before, which the caller still holds): a still camera then
    /// costs no CPU stage at all. Otherwise as [`HybridScene::frame`], with the new frame's
    /// identity.
    ///
    /// The cache is keyed by everything a frame depends on that may change: the camera, the
    /// options, each lens object's EM origin, shells and maps (by `Arc` identity), the
    /// environment meshes, the sky dome, the viewpoint samples and the drawn faces. The scene
    /// description and its trace structures are treated as fixed once built (call
    /// [`HybridScene::forget_frame`] after changing them).
    pub fn frame_unless(
        &self,
        camera: &Camera,
        options: &HybridOptions,
        held: u64,
    ) -> Result<BuiltFrame, TessellationError> {
        self.frame_unless_on(camera, options, held, None)
    }

    /// [`HybridScene::frame_unless`] with `gpu` at hand: the lens vertices are traced there when
    /// [`HybridOptions::tracer`] says so ([`VertexTracer::on_gpu`]). `gpu`'s tracer must be made
    /// from this scene's trace structures and the options' Fresnel table. Without a device,
    /// `auto` traces on the CPU and `gpu` is an error.
    pub fn frame_unless_on(
        &self,
        camera: &Camera,
        options: &HybridOptions,
        held: u64,
        gpu: Option<GpuPaths<'_>>,
    ) -> Result<BuiltFrame, TessellationError> {
        let gpu = match (options.tracer, gpu) {
            (VertexTracer::Gpu, None) => return Err(gpu_without_device().into()),
            (tracer, Some(device)) if tracer.on_gpu(device.gpu) => Some(device),
            _ => None,
        };
        let key = FrameKey::new(
            self,
            camera,
            options,
            false,
            gpu.map(|g| (g.resident, g.tracer.id())),
        );
        if let Ok(cache) = self.cache.0.lock()
            && let Some(cached) = cache.as_ref()
            && cached.key == key
        {
            let stats = HybridStats {
                reused: true,
                trace_ms: 0.0,
                tessellation_ms: 0.0,
                texgen_ms: 0.0,
                assemble_ms: 0.0,
                counters: TraceCounters::default(),
                vertices_traced: 0,
                ..cached.stats
            };
            return Ok(if cached.identity == held {
                BuiltFrame::Unchanged(stats)
            } else {
                BuiltFrame::New(Arc::clone(&cached.frame), stats, cached.identity)
            });
        }
        let (frame, stats, depths) = self.build_frame(camera, options, false, gpu)?;
        let frame = Arc::new(frame);
        let identity = FRAME_IDENTITY.fetch_add(1, Ordering::Relaxed);
        if let Ok(mut cache) = self.cache.0.lock() {
            *cache = Some(CachedFrame {
                key,
                frame: Arc::clone(&frame),
                depths,
                stats,
                identity,
            });
        }
        Ok(BuiltFrame::New(frame, stats, identity))
    }

    /// The frame with *perfect information at each vertex*: every lens object tessellated as
    /// [`HybridScene::frame`] does, but drawn as an opaque mesh whose vertex colours are the
    /// exact two-term radiance there (each term's `F·G` times the reference tracer's radiance
    /// along the vertex's outgoing ray), interpolated across each triangle. What it misses
    /// against the reference is what the tessellation's vertices cannot carry, whatever the
    /// layered EMs: the error budget's tessellation share (`lensmap bench bake`).
    pub fn vertex_exact_frame(
        &self,
        camera: &Camera,
        options: &HybridOptions,
    ) -> Result<(FrameInput, HybridStats), TessellationError> {
        if options.tracer == VertexTracer::Gpu {
            return Err(gpu_without_device().into());
        }
        let (frame, stats, _) = self.build_frame(camera, options, true, None)?;
        Ok((frame, stats))
    }

    /// The tessellation wireframe of the last frame [`HybridScene::frame`] or
    /// [`HybridScene::frame_unless`] built or reused: per lens object (TraceScene order) its
    /// tessellated mesh as drawn and each triangle's subdivision depth, what the hybrid-rendering
    /// paper's Figure 5 colours. `None` before any frame, after [`HybridScene::forget_frame`],
    /// or when the frame cache is unusable (a thread panicked holding it).
    /// [`HybridScene::vertex_exact_frame`] neither keeps nor replaces it.
    pub fn last_wireframe(&self) -> Option<Wireframe> {
        let cache = self.cache.0.lock().ok()?;
        let cached = cache.as_ref()?;
        Some(Wireframe {
            lenses: cached
                .frame
                .lenses
                .iter()
                .zip(&cached.depths)
                .map(|(lens, depths)| WireframeLens {
                    name: lens.name.clone(),
                    positions: lens.positions.clone(),
                    triangles: lens.triangles.clone(),
                    depths: depths.clone(),
                })
                .collect(),
        })
    }

    /// How `camera` sits in the view space of [`HybridScene::viewpoints`] about its centre
    /// ([`ViewSpaceBlender::fit`](crate::hybrid::ViewSpaceBlender::fit)): its nearest sample and whether it has left the space the
    /// samples cover (2D: its direction is in no triangle). `None` without viewpoint samples, or
    /// for a camera at the centre or not finite.
    pub fn view_space_fit(&self, camera: &Camera) -> Option<ViewSpaceFit> {
        self.view_space.fit(camera.position.as_dvec3())
    }

    /// Per lens object (TraceScene order), its name and the axis-aligned bounds `(min, max)` of
    /// all its scene objects' meshes, metres: where a viewer stops a camera short of a lens
    /// object. A lens object none of whose meshes has a vertex has no bounds and is left out.
    pub fn lens_bounds(&self) -> Vec<(String, Vec3, Vec3)> {
        self.trace
            .lenses
            .iter()
            .filter_map(|lens| {
                let (lo, hi) = lens
                    .objects
                    .iter()
                    .filter_map(|&object| self.scene.objects.get(object)?.mesh.bounds())
                    .reduce(|(lo, hi), (a, b)| (lo.min(a), hi.max(b)))?;
                Some((lens.name.clone(), lo, hi))
            })
            .collect()
    }

    /// The tessellation options of a lens object made of `objects`: `t` scaled up by footprint
    /// coarsening where its projected bounds span fewer than `footprint_subpixels` (never when
    /// a corner of its bounds is behind the eye: the footprint is then unknown).
    fn coarsened(
        &self,
        objects: &[usize],
        options: &HybridOptions,
        screen: &ScreenCamera,
    ) -> TessellationOptions {
        let mut tessellation = options.tessellation;
        if options.footprint_subpixels <= 0.0 || objects.is_empty() {
            return tessellation;
        }
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for &object in objects {
            let Some((a, b)) = self.scene.objects[object].mesh.bounds() else {
                continue;
            };
            for corner in box_corners((a, b)) {
                let Some(p) = screen.project(corner) else {
                    return tessellation;
                };
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        let extent = (hi - lo).max_element();
        if extent.is_finite() && extent < options.footprint_subpixels {
            let scale =
                (options.footprint_subpixels / extent.max(1e-3)).min(MAX_FOOTPRINT_COARSENING);
            tessellation.t *= scale;
        }
        tessellation
    }

    /// What the camera fixes before any lens object is traced: the framebuffer, the projection
    /// (its far plane just past the farthest scene point, so nothing the reference sees is
    /// clipped, and past the sky dome beyond it when there is one) and the sky dome's mesh.
    fn view(&self, camera: &Camera) -> FrameView {
        let k = camera.supersampling.max(1);
        let (width, height) = (camera.width * k, camera.height * k);
        let farthest = self
            .scene
            .objects
            .iter()
            .filter_map(|o| o.mesh.bounds())
            .flat_map(box_corners)
            .map(|corner| corner.distance(camera.position))
            .fold(1.0f32, f32::max);
        let sky = self.sky.as_ref().map(|sky| {
            let radius = SkyDome::radius_beyond(farthest);
            (sky.mesh(camera.position, radius), radius)
        });
        let far = sky.as_ref().map_or(farthest, |(_, radius)| *radius);
        let view_proj = camera.view_proj(0.05, 1.01 * far + 1.0);
        FrameView {
            width,
            height,
            view_proj,
            screen: ScreenCamera {
                eye: camera.position.as_dvec3(),
                view_proj,
                subpixels: Vec2::new(width as f32, height as f32),
            },
            sky: sky.map(|(mesh, _)| mesh),
            fresnel: None,
        }
    }

    /// The viewpoint samples (indices into [`HybridScene::viewpoints`]) a frame seen by
    /// `camera` blends by `blending` and their weights, summing to 1, largest first
    /// ([`ViewSpaceBlender::blend`](crate::hybrid::ViewSpaceBlender::blend): two along a 1D view space, up to three in a 2D one, the
    /// nearest point of the region for a camera outside it).
    /// EMs shared by every viewpoint sample (projected ones) need no blending: one sample,
    /// weight 1, half the compositing work. Sample 0 with weight 1 when there is no sample or
    /// the camera sits at its look-at point.
    pub fn viewpoint_blend(&self, camera: &Camera, blending: ViewpointBlending) -> ViewpointBlend {
        self.placed(camera, blending).0
    }

    /// [`HybridScene::viewpoint_blend`] and whether the camera is outside the view space, with
    /// one point location for the view space's own blending.
    fn placed(&self, camera: &Camera, blending: ViewpointBlending) -> (ViewpointBlend, bool) {
        let position = camera.position.as_dvec3();
        let view_space = &self.view_space;
        let placed = view_space.place(position);
        let outside = placed.as_ref().is_some_and(|(_, outside)| *outside);
        let blend = match blending {
            ViewpointBlending::ViewSpace => placed.map(|(blend, _)| blend),
            ViewpointBlending::TwoNearest | ViewpointBlending::Nearest => {
                viewpoints::blend(view_space.positions(), view_space.centre(), position)
            }
        };
        let blend = blend.unwrap_or(ViewpointBlend {
            samples: vec![(0, 1.0)],
        });
        let blend = if self.lenses.iter().all(|l| l.maps.len() == 1)
            || blending == ViewpointBlending::Nearest
        {
            ViewpointBlend {
                samples: vec![(blend.samples[0].0, 1.0)],
            }
        } else {
            blend
        };
        (blend, outside)
    }

    /// Lens object `lens_index` (`lens`) tessellated from the frame's camera: each of its scene
    /// objects inside the view, traced at every vertex, merged into one mesh. Takes its vertices
    /// from `vertex_budget` (the frame's, shared by the lens objects in order) and adds its costs
    /// to `stats`.
    fn tessellate_lens(
        &self,
        (lens_index, lens): (usize, &LensBvh),
        view: &FrameView,
        options: &HybridOptions,
        (vertex_budget, gpu, with_texgen): (&mut VertexBudget, Option<GpuPaths<'_>>, bool),
        stats: &mut HybridStats,
    ) -> Result<TessellatedLens, TessellationError> {
        let layers = &self.lenses[lens_index];
        // On the GPU, texgen runs in the tessellation's submission, object by object.
        let texgen_request = (with_texgen && gpu.is_some()).then(|| TexgenRequest {
            shells: &layers.shells,
            em_origins: &layers.em_origins,
            refraction: texgen::has_refraction(&self.trace, lens_index),
        });
        // Drawn where the GPU leaves it: a texgen'd frame on a resident tracer.
        let resident = gpu.is_some_and(|g| g.resident) && texgen_request.is_some();
        let mut parts = Vec::new();
        let mut terms: Option<Vec<TermVertices>> = None;
        let mut positions: Vec<Vec3> = Vec::new();
        let mut triangles: Vec<[u32; 3]> = Vec::new();
        let mut samples: Vec<Option<VertexEvaluation<VertexPaths>>> = Vec::new();
        let mut depths: Vec<u8> = Vec::new();
        let mut on_hull: Vec<bool> = Vec::new();
        let faces = self.faces.get(lens_index).copied().unwrap_or_default();
        let hull_split = options.hull_split && !self.lenses[lens_index].layering.is_distance();
        let visible_objects: Vec<usize> = lens
            .objects
            .iter()
            .copied()
            .filter(|&object| {
                !self.scene.objects[object]
                    .mesh
                    .bounds()
                    .is_some_and(|bounds| box_outside_view(bounds, &view.view_proj))
            })
            .collect();
        // A lens object wholly outside the view keeps its (empty) place in the frame, so that
        // frame lens i is still trace lens i; an empty lens object records no pass.
        if visible_objects.is_empty() {
            stats.lenses_outside_view += 1;
        }
        let mut tessellation_options = self.coarsened(&visible_objects, options, &view.screen);
        if tessellation_options.t != options.tessellation.t {
            stats.lenses_coarsened += 1;
        }
        for &object in &visible_objects {
            let mesh = &self.scene.objects[object].mesh;
            let oracle = PathOracle::new(
                &self.trace,
                lens_index,
                object,
                view.screen,
                options.angle_radians,
                faces,
            )
            .with_precision(options.precision)
            .with_bounces(self.lenses[lens_index].layering.bounces())
            .with_fresnel(view.fresnel.as_ref())
            .with_gpu(gpu);
            let start = Instant::now();
            tessellation_options.max_vertices = vertex_budget.left.max(mesh.positions.len());
            let on = (&oracle, object, &tessellation_options);
            let request = (texgen_request, hull_split, &mut *vertex_budget);
            if resident && let Some(part) = self.tessellate_on_device(on, request, stats)? {
                parts.push(part);
                continue;
            }
            // On the GPU the whole tessellation runs there, every level's records kept on it,
            // and texgen with it; `texgen_ms` is that pass's device time when it is timed.
            let mut texgen_ms = 0.0;
            let tessellation =
                match oracle.tessellate_on_gpu(mesh, &tessellation_options, texgen_request) {
                    Some(made) => {
                        let made = made?;
                        texgen_ms = made.stage_ms.map_or(0.0, |stages| stages.texgen);
                        if let Some(stages) = made.stage_ms {
                            *stats.gpu_split_ms.get_or_insert(0.0) += stages.tessellation;
                        }
                        append_terms(&mut terms, made.terms);
                        made.tessellation
                    }
                    None => tessellate(mesh, &oracle, &tessellation_options)?,
                };
            vertex_budget.left = vertex_budget
                .left
                .saturating_sub(tessellation.mesh.positions.len());
            stats.stopped_by_budget += tessellation.stats.stopped_by_budget;
            let elapsed = start.elapsed().as_secs_f64() * 1e3;
            let counters = oracle.counters();
            // The oracle's batches run inside tessellate(); their share is ray tracing.
            let traced_ms = oracle.traced_ms();
            stats.trace_ms += traced_ms;
            stats.texgen_ms += texgen_ms;
            stats.tessellation_ms += (elapsed - traced_ms - texgen_ms).max(0.0);
            stats.counters += counters;
            stats.triangles_in += mesh.triangles.len();
            stats.triangles_out += tessellation.mesh.triangles.len();
            stats.vertices_traced += tessellation.stats.vertices_evaluated;
            depths.extend(
                tessellation
                    .triangles
                    .iter()
                    .map(|record| u8::try_from(record.depth).unwrap_or(u8::MAX)),
            );
            if hull_split {
                on_hull.extend(self.facing_hull(object, &tessellation, view));
            }
            // Moved, not copied, for a lens object of one scene object (the common case).
            if positions.is_empty() {
                positions = tessellation.mesh.positions;
                triangles = tessellation.mesh.triangles;
                samples = tessellation.evaluations;
            } else {
                let base = positions.len() as u32;
                positions.extend(&tessellation.mesh.positions);
                triangles.extend(
                    tessellation
                        .mesh
                        .triangles
                        .iter()
                        .map(|t| t.map(|i| i + base)),
                );
                samples.extend(tessellation.evaluations);
            }
        }
        let hull_triangles = if hull_split {
            hull_last(&mut triangles, &mut depths, &on_hull)
        } else {
            0
        };
        stats.hull_triangles += hull_triangles;
        if !parts.is_empty() {
            // Its terms with no per-vertex data: the device holds it.
            terms = texgen_request.as_ref().map(texgen::resident_terms);
        }
        Ok(TessellatedLens {
            parts,
            mesh: LensMesh {
                positions,
                triangles,
                faces,
                hull_triangles,
            },
            terms,
            samples,
            depths,
        })
    }

    /// Scene object `object`'s tessellation by `oracle` on its GPU, prepared for the frame to
    /// record and draw where it lies (`None` when the oracle traces on the CPU), with the
    /// convex-hull split when `hull_split`, its vertices taken from the frame's budget on the
    /// device; adds the time to prepare it to `stats` (its counts are the device's, read once the
    /// frame is done).
    fn tessellate_on_device(
        &self,
        (oracle, object, options): (&PathOracle<'_>, usize, &TessellationOptions),
        (texgen, hull_split, budget): (Option<TexgenRequest<'_>>, bool, &mut VertexBudget),
        stats: &mut HybridStats,
    ) -> Result<Option<ResidentPart>, TessellationError> {
        let mesh = &self.scene.objects[object].mesh;
        let hull = hull_split.then(|| self.hull_flags(object).as_slice());
        let Some(made) =
            oracle.tessellate_on_device(mesh, options, (texgen, hull, budget.on_device))
        else {
            return Ok(None);
        };
        let made = made?;
        // The device counts the frame's budget from here on.
        budget.on_device = true;
        if let Some(stages) = made.stage_ms {
            *stats.gpu_split_ms.get_or_insert(0.0) += stages.tessellation;
            stats.texgen_ms += stages.texgen;
        }
        stats.trace_ms += oracle.traced_ms();
        stats.triangles_in += mesh.triangles.len();
        Ok(Some((made.part, made.work)))
    }

    /// Makes the GPU tracer's buffers hold every lens object's scene objects at once before a
    /// frame drawn where its tessellations lie: each object's work, recorded later by the frame,
    /// names those buffers, so they must not be made again between two objects.
    fn prepare_device_frame(
        &self,
        device: GpuPaths<'_>,
        options: &HybridOptions,
    ) -> Result<(), TessellationError> {
        let mut objects = Vec::new();
        for (lens_index, lens) in self.trace.lenses.iter().enumerate() {
            let layers = &self.lenses[lens_index];
            let arrays = TexgenRequest {
                shells: &layers.shells,
                em_origins: &layers.em_origins,
                refraction: texgen::has_refraction(&self.trace, lens_index),
            }
            .arrays();
            for &object in &lens.objects {
                objects.push((object, &self.scene.objects[object].mesh, arrays));
            }
        }
        device
            .tracer
            .prepare_frame(device.gpu, &objects, &options.tessellation)
    }

    /// Per input triangle of scene object `object`, whether it lies on the convex hull of the
    /// lens geometry (computed once per object).
    fn hull_flags(&self, object: usize) -> &Vec<bool> {
        self.hull[object].get_or_init(|| {
            let points: Vec<Vec3> = self
                .trace
                .lenses
                .iter()
                .flat_map(|lens| &lens.objects)
                .flat_map(|&o| self.scene.objects[o].mesh.positions.iter().copied())
                .collect();
            super::hull::hull_triangles(&self.scene.objects[object].mesh, &points)
        })
    }

    /// Per output triangle of `tessellation` (of scene object `object`), whether the convex-hull
    /// split draws it with the distant layer only: its input triangle lies on the hull of the
    /// lens geometry and it faces the camera (a back face of an open mesh, drawn from behind,
    /// looks into the object and may well reflect it; one of a closed mesh is culled, and not
    /// counted).
    fn facing_hull<'a, S>(
        &'a self,
        object: usize,
        tessellation: &'a crate::hybrid::tessellate::Tessellation<S>,
        view: &FrameView,
    ) -> impl Iterator<Item = bool> + 'a {
        let hull = self.hull_flags(object);
        let eye = view.screen.eye.as_vec3();
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

    /// The frame for `camera`, its costs and, per lens object of a frame that is not
    /// `vertex_exact`, each triangle's subdivision depth (empty for a vertex-exact frame).
    fn build_frame(
        &self,
        camera: &Camera,
        options: &HybridOptions,
        vertex_exact: bool,
        gpu: Option<GpuPaths<'_>>,
    ) -> Result<(FrameInput, HybridStats, Vec<Vec<u8>>), TessellationError> {
        let start = Instant::now();
        let view = FrameView {
            fresnel: options.fresnel.table()?,
            ..self.view(camera)
        };
        let (blend, outside_view_space) = self.placed(camera, options.viewpoint_blending);
        let mut stats = HybridStats {
            outside_view_space,
            viewpoints_blended: blend.samples.len(),
            traced_on_gpu: gpu.is_some(),
            ..HybridStats::default()
        };
        // The vertex budget is the frame's: each lens object gets what the ones before left.
        if let Some(device) = gpu.filter(|g| g.resident && !vertex_exact) {
            self.prepare_device_frame(device, options)?;
        }
        let mut vertex_budget = VertexBudget {
            left: options.tessellation.max_vertices,
            on_device: false,
        };
        let mut lenses = Vec::new();
        let mut exact = Vec::new();
        let mut depths = Vec::new();
        for (lens_index, (lens, layers)) in self.trace.lenses.iter().zip(&self.lenses).enumerate() {
            let TessellatedLens {
                parts,
                mesh,
                terms,
                samples,
                depths: lens_depths,
            } = self.tessellate_lens(
                (lens_index, lens),
                &view,
                options,
                (&mut vertex_budget, gpu, !vertex_exact),
                &mut stats,
            )?;
            if vertex_exact {
                exact.push(Arc::new(vertex_radiance_mesh(
                    &self.trace,
                    lens_index,
                    mesh,
                    &samples,
                )));
                continue;
            }
            let start = Instant::now();
            let object = match terms {
                // Made on the GPU: assembled only (drawn from the device's buffers when resident).
                Some(terms) => LensObject {
                    resident: (!parts.is_empty()).then(|| resident_lens(parts)),
                    ..texgen::lens_object(lens.name.clone(), layers, mesh, terms, &blend)
                },
                None => texgen(
                    &self.trace,
                    lens_index,
                    layers,
                    mesh,
                    &samples,
                    &blend,
                    options.precision,
                ),
            };
            stats.texgen_ms += start.elapsed().as_secs_f64() * 1e3;
            lenses.push(object);
            depths.push(lens_depths);
        }
        stats.counted_on_device = lenses.iter().any(|l| l.resident.is_some());
        let (glossy, glossy_maps) = self
            .glossy
            .as_ref()
            .map_or_else(|| (Vec::new(), 0), |g| g.draws(view.screen.eye));
        stats.glossy_maps = glossy_maps;
        let frame = FrameInput {
            width: view.width,
            height: view.height,
            view_proj: view.view_proj,
            environment: self
                .environment
                .iter()
                .cloned()
                .chain(exact)
                .chain(view.sky)
                .collect(),
            glossy,
            lenses,
            viewpoint_weights: blend.samples.iter().map(|(_, w)| *w as f32).collect(),
        };
        stats.assemble_ms = (start.elapsed().as_secs_f64() * 1e3
            - stats.trace_ms
            - stats.tessellation_ms
            - stats.texgen_ms)
            .max(0.0);
        Ok((frame, stats, depths))
    }
}

/// Appends one scene object's terms (made on the GPU) to its lens object's, vertex after vertex.
fn append_terms(all: &mut Option<Vec<TermVertices>>, part: Option<Vec<TermVertices>>) {
    let Some(part) = part else { return };
    match all {
        None => *all = Some(part),
        Some(all) => {
            for (into, from) in all.iter_mut().zip(part) {
                into.fg.extend(from.fg);
                for (layer, directions) in into.directions.iter_mut().zip(from.directions) {
                    layer.extend(directions);
                }
            }
        }
    }
}

/// The GPU tracer asked of a frame built without a device.
fn gpu_without_device() -> OptionError {
    OptionError::new(
        crate::options::names::TRACER,
        VertexTracer::Gpu.name(),
        "this frame is built without a device, and the GPU tracer runs only through a frame runner, which owns one; give cpu or auto",
    )
}

/// What the camera fixes for a frame before any lens object is traced.
struct FrameView {
    /// Framebuffer width, subpixels (pixels × supersampling).
    width: u32,
    /// Framebuffer height, subpixels.
    height: u32,
    /// World → Vulkan clip space.
    view_proj: Mat4,
    /// The same projection for the vertex oracles.
    screen: ScreenCamera,
    /// The sky dome around the camera, drawn behind everything; `None` when the sky is black.
    sky: Option<Arc<EnvironmentMesh>>,
    /// The table the vertex paths look Schlick's fifth-order term up in; `None`: evaluated.
    fresnel: Option<SchlickTable>,
}

/// Moves the triangles `on_hull` marks (parallel to `triangles` and `depths`) after the others,
/// keeping each part's order, and returns how many there are: the compositor draws a lens
/// object's last [`LensObject::hull_triangles`](crate::render::LensObject::hull_triangles)
/// without its local layer.
fn hull_last(triangles: &mut Vec<[u32; 3]>, depths: &mut Vec<u8>, on_hull: &[bool]) -> usize {
    let hull = |t: usize| on_hull.get(t).copied().unwrap_or(false);
    let order: Vec<usize> = (0..triangles.len())
        .filter(|&t| !hull(t))
        .chain((0..triangles.len()).filter(|&t| hull(t)))
        .collect();
    *triangles = order.iter().map(|&t| triangles[t]).collect();
    // One depth per triangle, gathered with them (`tessellate_lens`).
    debug_assert_eq!(depths.len(), order.len());
    *depths = order
        .iter()
        .map(|&t| depths.get(t).copied().unwrap_or(0))
        .collect();
    (0..triangles.len()).filter(|&t| hull(t)).count()
}

/// A scene object's tessellation left on the device, and the work that makes it (`None`: made
/// already).
type ResidentPart = (Arc<DeviceLensPart>, Option<Arc<dyn DeviceWork>>);

/// A lens object drawn from its parts, each made by its work in the frame that draws it (or,
/// where one was made already, a timed tessellation, by their own submissions).
fn resident_lens(parts: Vec<ResidentPart>) -> ResidentLens {
    let works: Option<Vec<_>> = parts.iter().map(|(_, work)| work.clone()).collect();
    // All one way: the tracer times (and then submits) every tessellation of a frame or none.
    debug_assert!(works.is_some() || parts.iter().all(|(_, work)| work.is_none()));
    ResidentLens {
        parts: parts.into_iter().map(|(part, _)| part).collect(),
        works: works.unwrap_or_default(),
    }
}

/// A frame's vertex budget, shared by its lens objects in order.
struct VertexBudget {
    /// What the objects before left, as the host counted it.
    left: usize,
    /// Whether an object was tessellated on the device with no count read back: the device
    /// keeps the budget left from then on.
    on_device: bool,
}

/// A lens object tessellated for a frame: its mesh and each vertex's evaluation.
struct TessellatedLens {
    /// Its scene objects' tessellations left on the device, each with the work that makes it
    /// (the mesh is then empty).
    parts: Vec<ResidentPart>,
    mesh: LensMesh,
    /// Per term its F·G and directions per layer, made on the GPU with the mesh (`None`: the
    /// CPU's texgen makes them).
    terms: Option<Vec<TermVertices>>,
    /// Per vertex of `mesh`, its ray paths (`None` where it was never evaluated).
    samples: Vec<Option<VertexEvaluation<VertexPaths>>>,
    /// Per triangle of `mesh`, its subdivision depth (saturated at 255).
    depths: Vec<u8>,
}

/// The tessellation of a frame's lens objects, for drawing as a wireframe coloured by
/// subdivision depth (the hybrid-rendering paper's Figure 5); see
/// [`HybridScene::last_wireframe`].
#[derive(Clone, Debug, PartialEq)]
pub struct Wireframe {
    /// One entry per lens object of the frame, TraceScene order (a lens object outside the view
    /// has no triangles).
    pub lenses: Vec<WireframeLens>,
}

/// One lens object's tessellated mesh in a [`Wireframe`]: the mesh the frame draws.
#[derive(Clone, Debug, PartialEq)]
pub struct WireframeLens {
    /// The lens object's name.
    pub name: String,
    /// World-space vertex positions, metres.
    pub positions: Vec<Vec3>,
    /// Triangles, indices into `positions`, counter-clockwise seen from their front side.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle (same order as `triangles`), the subdivision depth of the tessellation leaf
    /// it belongs to: 0 for an input triangle left whole, one more per level of splitting
    /// (each level halves the split edges), saturated at 255.
    pub depths: Vec<u8>,
}

/// Whether the axis-aligned box `(lo, hi)` lies wholly outside the view of `view_proj`: its eight
/// corners outside the clip volume as the tessellation's triangle test decides
/// ([`super::paths::outside_clip_volume`]).
fn box_outside_view((lo, hi): (Vec3, Vec3), view_proj: &Mat4) -> bool {
    super::paths::outside_clip_volume(&box_corners((lo, hi)).map(|p| *view_proj * p.extend(1.0)))
}

/// The eight corners of the axis-aligned box `(lo, hi)`.
fn box_corners((lo, hi): (Vec3, Vec3)) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            [lo.x, hi.x][i & 1],
            [lo.y, hi.y][(i >> 1) & 1],
            [lo.z, hi.z][i >> 2],
        )
    })
}

/// A lens object's tessellated mesh as an opaque mesh coloured with the exact radiance at each
/// vertex (see [`HybridScene::vertex_exact_frame`]); black where a vertex has no path.
fn vertex_radiance_mesh(
    trace: &TraceScene,
    lens: usize,
    mesh: LensMesh,
    samples: &[Option<VertexEvaluation<VertexPaths>>],
) -> EnvironmentMesh {
    let options = crate::trace::TraceOptions::default();
    let colours = samples
        .par_iter()
        .map(|sample| {
            let mut counters = TraceCounters::default();
            let mut radiance = DVec3::ZERO;
            for path in sample.iter().flat_map(|s| s.sample.terms.iter().flatten()) {
                if path.fg != DVec3::ZERO {
                    radiance += path.fg
                        * trace.outgoing_radiance(&path.outgoing, lens, 1, &options, &mut counters);
                }
            }
            radiance.as_vec3()
        })
        .collect();
    EnvironmentMesh {
        positions: mesh.positions,
        colours,
        triangles: mesh.triangles,
        light_map: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{
        hybrid::{HybridSceneOptions, LayeredEms},
        layers::projected::ProjectedOptions,
        lightmap::LightMapOptions,
        scene::Scene,
    };
    use rand::{Rng, SeedableRng};

    /// The split's triangles go last, each part in its order, their depths with them.
    #[test]
    fn hull_last_keeps_each_part_in_order_and_the_depths_in_step() {
        let mut triangles: Vec<[u32; 3]> = (0..6).map(|t| [t, t + 1, t + 2]).collect();
        let mut depths: Vec<u8> = (10..16).collect();
        let on_hull = [true, false, true, false, false, true];
        assert_eq!(hull_last(&mut triangles, &mut depths, &on_hull), 3);
        let firsts: Vec<u32> = triangles.iter().map(|t| t[0]).collect();
        assert_eq!(firsts, [1, 3, 4, 0, 2, 5]);
        assert_eq!(depths, [11, 13, 14, 10, 12, 15]);
    }

    /// Built-in scene `name` as a hybrid scene made cheaply (8² texel projected EMs at one ray a
    /// texel, light maps of 1 texel a metre), and its camera at `width × height`, 1×1.
    fn small_hybrid(name: &str, width: u32, height: u32) -> (HybridScene, Camera) {
        let scene = Scene::load_named(name).expect("a built-in scene");
        let camera = scene.camera.with_resolution(width, height, 1);
        let options = HybridSceneOptions {
            ems: LayeredEms::Projected(ProjectedOptions {
                size: 8,
                supersampling: 1,
            }),
            light_maps: LightMapOptions {
                supersampling: 1,
                ..LightMapOptions::uniform(1.0)
            },
        };
        let (hybrid, _) = HybridScene::new(scene, options).expect("a hybrid scene");
        (hybrid, camera)
    }

    fn max_depth(wireframe: &Wireframe) -> u8 {
        wireframe
            .lenses
            .iter()
            .flat_map(|l| l.depths.iter().copied())
            .max()
            .unwrap_or(0)
    }

    /// The last frame's wireframe is its lens meshes, triangle for triangle, with one depth per
    /// triangle; a finer `t` splits deeper; a reused frame keeps it, forgetting drops it.
    #[test]
    fn wireframe_is_the_last_frames_tessellation() {
        let (hybrid, camera) = small_hybrid("teapot-room", 160, 120);
        assert!(hybrid.last_wireframe().is_none(), "no frame yet");
        let mut max_depths = Vec::new();
        for t in [20.0, 2.0] {
            let (frame, stats) = hybrid.frame(&camera, &HybridOptions::with_t(t)).unwrap();
            let wireframe = hybrid.last_wireframe().expect("a frame was built");
            assert_eq!(wireframe.lenses.len(), hybrid.trace.lenses.len());
            assert_eq!(frame.lenses.len(), wireframe.lenses.len());
            let mut triangles = 0;
            for (lens, drawn) in wireframe.lenses.iter().zip(&frame.lenses) {
                assert_eq!(lens.name, drawn.name);
                assert_eq!(lens.positions, drawn.positions);
                assert_eq!(lens.triangles, drawn.triangles);
                assert_eq!(lens.depths.len(), lens.triangles.len(), "{}", lens.name);
                triangles += lens.triangles.len();
            }
            assert_eq!(triangles, stats.triangles_out, "t = {t}");
            // No split at all leaves every triangle an input one at depth 0, and any split adds
            // triangles.
            assert_eq!(
                max_depth(&wireframe) == 0,
                stats.triangles_out == stats.triangles_in,
                "t = {t}: {stats:?}"
            );
            // A leaf at depth d holds at most 1/2^d of its input triangle's area (each split
            // child holds 1/4 or 1/2 of its parent's), and the pieces T-junction removal cuts
            // a leaf into hold less.
            for (lens, trace_lens) in wireframe.lenses.iter().zip(&hybrid.trace.lenses) {
                let largest_input = trace_lens
                    .objects
                    .iter()
                    .flat_map(|&o| {
                        let mesh = &hybrid.scene.objects[o].mesh;
                        (0..mesh.triangles.len()).map(|t| 0.5 * mesh.triangle_normal(t).length())
                    })
                    .fold(0.0f32, f32::max);
                for (triangle, &depth) in lens.triangles.iter().zip(&lens.depths) {
                    let [a, b, c] = triangle.map(|i| lens.positions[i as usize]);
                    let area = 0.5 * (b - a).cross(c - a).length();
                    let bound = largest_input / 2f32.powi(i32::from(depth));
                    assert!(
                        area <= bound * 1.001 + 1e-9,
                        "{}: area {area} at depth {depth} over {bound}",
                        lens.name
                    );
                }
            }
            max_depths.push(max_depth(&wireframe));
        }
        assert!(
            max_depths[1] > max_depths[0],
            "t = 2 splits deeper: {max_depths:?}"
        );

        let before = hybrid.last_wireframe();
        let (_, stats) = hybrid.frame(&camera, &HybridOptions::with_t(2.0)).unwrap();
        assert!(stats.reused);
        assert_eq!(
            hybrid.last_wireframe(),
            before,
            "a reused frame keeps its wireframe"
        );
        hybrid
            .vertex_exact_frame(&camera, &HybridOptions::with_t(20.0))
            .unwrap();
        assert_eq!(
            hybrid.last_wireframe(),
            before,
            "a vertex-exact frame is not cached"
        );
        hybrid.forget_frame();
        assert!(hybrid.last_wireframe().is_none());
    }

    /// Each lens object's bounds are the union of its meshes' vertices, here found by scanning
    /// them; the glass sphere's are its closed form.
    #[test]
    fn lens_bounds_enclose_every_vertex_of_each_lens_object() {
        let (hybrid, _) = small_hybrid("teapot-room", 16, 12);
        let bounds = hybrid.lens_bounds();
        let names: Vec<&str> = bounds.iter().map(|(name, _, _)| name.as_str()).collect();
        assert_eq!(names, ["teapot", "cup"]);
        for ((name, lo, hi), lens) in bounds.iter().zip(&hybrid.trace.lenses) {
            let mut expected = (Vec3::INFINITY, Vec3::NEG_INFINITY);
            for &object in &lens.objects {
                for &p in &hybrid.scene.objects[object].mesh.positions {
                    expected = (expected.0.min(p), expected.1.max(p));
                }
            }
            assert_eq!((*lo, *hi), expected, "{name}");
        }
        // The cup is two objects: its bounds are wider than either alone.
        let cup = &hybrid.trace.lenses[1];
        assert_eq!(cup.objects.len(), 2);
        let volume = |(lo, hi): (Vec3, Vec3)| (hi - lo).element_product();
        for &object in &cup.objects {
            let alone = hybrid.scene.objects[object].mesh.bounds().unwrap();
            assert!(volume((bounds[1].1, bounds[1].2)) > volume(alone));
        }

        let (sphere, _) = small_hybrid("glass-sphere", 16, 12);
        let bounds = sphere.lens_bounds();
        assert_eq!(bounds.len(), 1);
        let (name, lo, hi) = &bounds[0];
        assert_eq!(name, "sphere");
        // Radius 1 m about (0, 1.2, 0): poles and the equator's quarter points are vertices.
        assert!(
            (*lo - Vec3::new(-1.0, 0.2, -1.0)).abs().max_element() < 1e-5,
            "{lo}"
        );
        assert!(
            (*hi - Vec3::new(1.0, 2.2, 1.0)).abs().max_element() < 1e-5,
            "{hi}"
        );
    }

    /// The scene's camera sits on viewpoint sample 0; far above the circle it has left the view
    /// space; the frame's blend is the one `viewpoint_blend` reports.
    #[test]
    fn view_space_fit_and_blend_of_the_scene_camera() {
        let (hybrid, camera) = small_hybrid("glass-sphere", 16, 12);
        let fit = hybrid.view_space_fit(&camera).expect("a view space");
        assert_eq!(fit.nearest, 0);
        assert!(fit.nearest_radians < 1e-3, "{fit:?}");
        // Neighbouring samples are 8° apart round a circle 1.5 m above the look-at point at
        // 5 m: seen from it at elevation e = atan(1.5 / 5), cos θ = cos²e·cos 8° + sin²e.
        let e = (1.5f64 / 5.0).atan();
        let spacing = (e.cos().powi(2) * 8f64.to_radians().cos() + e.sin().powi(2)).acos();
        assert!(
            (fit.spacing_radians - spacing).abs() < 1e-6,
            "{fit:?} {spacing}"
        );
        assert!(!fit.outside);
        let above = Camera {
            position: camera.look_at + Vec3::new(0.0, 5.0, 0.5),
            ..camera
        };
        assert!(hybrid.view_space_fit(&above).unwrap().outside);
        let at_look_at = Camera {
            position: camera.look_at,
            ..camera
        };
        assert!(hybrid.view_space_fit(&at_look_at).is_none());

        let blend = hybrid.viewpoint_blend(&camera, ViewpointBlending::ViewSpace);
        assert_eq!(blend.samples, vec![(0, 1.0)], "projected EMs: one sample");
        let (frame, _) = hybrid.frame(&camera, &HybridOptions::default()).unwrap();
        let weights: Vec<f32> = blend.samples.iter().map(|(_, w)| *w as f32).collect();
        assert_eq!(frame.viewpoint_weights, weights);
    }

    /// The box test against brute force: a box reported outside has no sampled point inside the
    /// clip volume, and boxes with a point inside are never reported outside.
    #[test]
    fn boxes_outside_the_view_hold_no_visible_point() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(10);
        let camera = Camera {
            position: Vec3::new(0.0, 1.0, 4.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_radians: 0.8,
            width: 64,
            height: 48,
            supersampling: 1,
        };
        let view_proj = camera.view_proj(0.05, 100.0);
        let inside = |p: Vec3| {
            let c = view_proj * p.extend(1.0);
            c.x.abs() <= c.w && c.y.abs() <= c.w && c.z >= 0.0 && c.z <= c.w
        };
        let (mut outside_count, mut visible_count) = (0, 0);
        for _ in 0..400 {
            let centre = Vec3::new(
                rng.gen_range(-12.0..12.0),
                rng.gen_range(-12.0..12.0),
                rng.gen_range(-12.0..12.0),
            );
            let half = Vec3::new(
                rng.gen_range(0.01..2.0),
                rng.gen_range(0.01..2.0),
                rng.gen_range(0.01..2.0),
            );
            let (lo, hi) = (centre - half, centre + half);
            let any_inside = (0..2000).any(|_| {
                inside(Vec3::new(
                    rng.gen_range(lo.x..=hi.x),
                    rng.gen_range(lo.y..=hi.y),
                    rng.gen_range(lo.z..=hi.z),
                ))
            });
            if box_outside_view((lo, hi), &view_proj) {
                outside_count += 1;
                assert!(
                    !any_inside,
                    "box {lo} … {hi} reported outside holds a visible point"
                );
            } else if any_inside {
                visible_count += 1;
            }
        }
        assert!(
            outside_count > 50 && visible_count > 20,
            "{outside_count} {visible_count}"
        );
    }
}
