//! Criterion benchmarks of the hybrid frame's two CPU stages on teapot-room from the demo's novel
//! camera (640×480, t = 3): ray tracing the glass teapot's vertices, and the adaptive
//! tessellation alone (its vertex samples replayed from a table, so no ray is traced), each at
//! 1 thread and at every thread of the machine; and the same vertices traced by the GPU's
//! vertex-path pass.
//!
//! `cargo bench -p lensmap --bench hybrid`

use criterion::{BatchSize, Criterion, criterion_main};
use glam::{Vec2, Vec3};
use lensmap::hybrid::gpu::TracerWalk;
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{
        DEFAULT_ANGLE_DEGREES, HybridScene, LayeredEms,
        gpu::{GpuTracer, GpuTraversal, PathSettings},
        paths::{PathOracle, ScreenCamera, VertexPaths, VertexPrecision},
        tessellate::{
            SurfaceVertex, TessellationError, TessellationOptions, VertexEvaluation, VertexOracle,
            tessellate,
        },
    },
    layers::projected::ProjectedOptions,
    render::LensFaces,
    runner::novel_camera,
    scene::Scene,
    trace::{Bounces, GreedyOptions},
};

/// The teapot-room scene, its novel camera as the tessellation sees it, and the glass teapot.
struct Setup {
    hybrid: HybridScene,
    screen: ScreenCamera,
    lens: usize,
    object: usize,
    faces: LensFaces,
}

fn setup() -> Setup {
    let scene = Scene::load_named("teapot-room").expect("built-in scene");
    let camera = novel_camera(&scene);
    let (hybrid, _) = HybridScene::new(
        scene,
        LayeredEms::Projected(ProjectedOptions::with_size(16)).into(),
    )
    .expect("projected EMs");
    // The lens object with the most triangles: the teapot.
    let (lens, object) = hybrid
        .trace()
        .lenses
        .iter()
        .enumerate()
        .flat_map(|(lens, l)| l.objects.iter().map(move |&object| (lens, object)))
        .max_by_key(|&(_, object)| hybrid.scene().objects[object].mesh.triangles.len())
        .expect("teapot-room has lens objects");
    let screen = ScreenCamera {
        eye: camera.position.as_dvec3(),
        view_proj: camera.view_proj(0.05, 100.0),
        subpixels: Vec2::new(camera.width as f32, camera.height as f32),
    };
    let faces = HybridScene::lens_faces(hybrid.scene(), hybrid.trace())[lens];
    Setup {
        hybrid,
        screen,
        lens,
        object,
        faces,
    }
}

impl Setup {
    fn oracle(&self) -> PathOracle<'_> {
        PathOracle::new(
            self.hybrid.trace(),
            self.lens,
            self.object,
            self.screen,
            DEFAULT_ANGLE_DEGREES.to_radians(),
            self.faces,
        )
    }
}

/// Replays the path oracle's answers by vertex index (the tessellation numbers its vertices the
/// same way every run): the tessellation's own work, without the ray tracing.
struct Replay<'a> {
    paths: &'a PathOracle<'a>,
    table: Vec<Option<VertexEvaluation<VertexPaths>>>,
}

impl Replay<'_> {
    fn get(&self, vertex: &SurfaceVertex) -> VertexEvaluation<VertexPaths> {
        self.table[vertex.index as usize]
            .clone()
            .expect("the replayed tessellation asks for the vertices it asked for before")
    }
}

impl VertexOracle for Replay<'_> {
    type Sample = VertexPaths;
    fn evaluate(&self, vertex: &SurfaceVertex) -> VertexPaths {
        self.get(vertex).sample
    }
    fn evaluate_batch(
        &self,
        vertices: &[SurfaceVertex],
    ) -> Result<Vec<VertexEvaluation<VertexPaths>>, TessellationError> {
        Ok(vertices.iter().map(|v| self.get(v)).collect())
    }
    fn differ(&self, a: &VertexPaths, b: &VertexPaths) -> bool {
        self.paths.differ(a, b)
    }
    fn screen(&self, position: Vec3) -> Option<Vec2> {
        self.paths.screen(position)
    }
    fn front_facing(&self, corners: [Vec3; 3]) -> bool {
        self.paths.front_facing(corners)
    }
    fn evaluates_back_faces(&self) -> bool {
        self.paths.evaluates_back_faces()
    }
    fn outside_view(&self, corners: [Vec3; 3]) -> bool {
        self.paths.outside_view(corners)
    }
}

fn benches(c: &mut Criterion) {
    let setup = setup();
    let mesh = &setup.hybrid.scene().objects[setup.object].mesh;
    let options = TessellationOptions::default();
    let oracle = setup.oracle();
    let traced = tessellate(mesh, &oracle, &options).expect("teapot tessellates");
    let vertices: Vec<SurfaceVertex> = traced
        .mesh
        .positions
        .iter()
        .zip(&traced.mesh.normals)
        .enumerate()
        .filter(|(i, _)| traced.evaluations[*i].is_some())
        .map(|(index, (&position, &normal))| SurfaceVertex {
            index: index as u32,
            position,
            normal,
            uv: None,
        })
        .collect();
    let replay = Replay {
        paths: &oracle,
        table: traced.evaluations.clone(),
    };
    let all = rayon::current_num_threads();
    let mut thread_counts = vec![1, all];
    thread_counts.dedup();
    for threads in thread_counts {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        let mut group = c.benchmark_group(format!("teapot-room t=3, {threads} threads"));
        group.sample_size(20);
        group.bench_function(format!("trace {} vertices", vertices.len()), |b| {
            b.iter_batched(
                || setup.oracle(),
                |oracle| pool.install(|| oracle.evaluate_batch(&vertices)),
                BatchSize::SmallInput,
            )
        });
        group.bench_function(
            format!(
                "tessellate {} triangles (samples replayed)",
                mesh.triangles.len()
            ),
            |b| b.iter(|| pool.install(|| tessellate(mesh, &replay, &options).expect("valid"))),
        );
        group.finish();
    }
    gpu_bench(c, &setup, &vertices);
}

/// The same vertices traced by the GPU's vertex-path pass (`hybrid::gpu`), on the device
/// `LENSMAP_DEVICE` names (the first otherwise): one submission that uploads them, traces and
/// reads the records back; with the tracer's BVH walk in f32 and in f64 (where the device has
/// shaderFloat64), and with the driver's acceleration structures (where it has ray queries).
fn gpu_bench(c: &mut Criterion, setup: &Setup, vertices: &[SurfaceVertex]) {
    let gpu = match Gpu::new(&GpuOptions::from_env()) {
        Ok(gpu) => gpu,
        Err(e) => {
            eprintln!("no GPU, the GPU vertex pass is not measured: {e}");
            return;
        }
    };
    let variants = [
        (GpuTraversal::Bvh, VertexPrecision::F32, true),
        (
            GpuTraversal::Bvh,
            VertexPrecision::F64,
            gpu.shader_float64(),
        ),
        (
            GpuTraversal::Driver,
            VertexPrecision::F32,
            gpu.ray_queries(),
        ),
    ];
    let tracers: Vec<GpuTracer> = variants
        .into_iter()
        .filter(|&(.., offered)| offered)
        .map(|(walk, precision, _)| {
            GpuTracer::new(
                &gpu,
                setup.hybrid.trace(),
                None,
                TracerWalk {
                    traversal: walk,
                    precision,
                },
            )
            .expect("the tracer uploads")
        })
        .collect();
    let settings = PathSettings {
        lens: setup.lens,
        object: setup.object,
        bounces: Bounces::UntilLeaving,
        max_interfaces: GreedyOptions::default().max_interfaces,
        classes: lensmap::trace::classes::ClassList::GREEDY,
    };
    let input: Vec<(Vec3, Vec3)> = vertices.iter().map(|v| (v.position, v.normal)).collect();
    let mut group = c.benchmark_group(format!("teapot-room t=3, {}", gpu.device_id()));
    group.sample_size(20);
    for tracer in &tracers {
        let name = format!(
            "GPU pass ({} walk, {}): trace {} vertices",
            tracer.traversal().name(),
            tracer.precision().name(),
            input.len()
        );
        group.bench_function(name, |b| {
            b.iter(|| {
                tracer
                    .trace_vertices(&gpu, &setup.screen, &settings, &input)
                    .expect("the pass runs")
            })
        });
    }
    group.finish();
}

// The macro's generated function has no doc comment to carry.
#[allow(missing_docs)]
mod group {
    criterion::criterion_group!(hybrid, super::benches);
}
use group::hybrid;
criterion_main!(hybrid);
