//! The adaptive tessellation on the GPU (`shaders/wgsl/tessellate.wgsl`) against the CPU
//! tessellator, on every lens object of the three built-in scenes at t = 3 and t = 5:
//! - watertight and free of T-junctions, area preserved, every triangle on and wound like its
//!   source triangle (the geometric checks the CPU tessellator's tests make,
//!   `lensmap_tests::mesh_checks`);
//! - a vertex count within 10 % of the CPU's (the GPU traces in f32, the CPU in f64, so a few
//!   vertices on path boundaries decide differently);
//! - identical output run to run, bit for bit;
//! - the vertex budget stops splitting as on the CPU, and a depth cap past the GPU's walk is an
//!   option error;
//! - texgen on the GPU (`shaders/wgsl/texgen.wgsl`) against the shells' own f64 intersection on
//!   the same paths, for every kind of shell, and F·G exactly the records'.

use glam::{DVec2, DVec3, Vec2, Vec3};
use lensmap::gpu::Gpu;
use lensmap::hybrid::gpu::{
    GPU_MAX_DEPTH, GpuTessellationRequest, GpuTracer, GpuTraversal, PathSettings, TexgenRequest,
};
use lensmap::hybrid::paths::{PathOracle, ScreenCamera, VertexPaths, VertexPrecision};
use lensmap::hybrid::tessellate::{
    StopReason, Tessellation, TessellationError, TessellationOptions, tessellate,
};
use lensmap::layers::LayerShell;
use lensmap::render::LensFaces;
use lensmap::scene::{BUILTIN_SCENES, Scene, TriangleMesh};
use lensmap::trace::{Bounces, GreedyOptions, Interface, Term, TraceScene};
use lensmap_tests::fixtures::{built_in_scene, gpu_tracer};
use lensmap_tests::mesh_checks::{check_surface, check_topology};
use lensmap_tests::{assert_clean, gpu};
use std::collections::HashMap;

/// The paper's angle threshold.
const ANGLE_DEGREES: f64 = 3.0;

/// `mesh` with coincident vertices (within 1e-6 m) merged (the first one's normal kept): the built-in meshes
/// have seams, where a midpoint on one side lies on the other side's edge, which the geometric
/// T-junction check cannot tell from a real one. Both tessellators then run on the welded mesh,
/// without the triangles welding collapses (at a sphere's poles).
fn welded(mesh: &TriangleMesh) -> TriangleMesh {
    let mut first: HashMap<[i64; 3], u32> = HashMap::new();
    let remap: Vec<u32> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            // Seams differ by rounding: vertices within 1e-6 m are one.
            let key = p.to_array().map(|x| (f64::from(x) * 1e6).round() as i64);
            *first.entry(key).or_insert(i as u32)
        })
        .collect();
    TriangleMesh {
        triangles: mesh
            .triangles
            .iter()
            .map(|t| t.map(|v| remap[v as usize]))
            .filter(|[a, b, c]| a != b && b != c && c != a)
            .collect(),
        ..mesh.clone()
    }
}

/// Built-in scene `name` at 160×120 with 2×2 supersampling, its trace structures, a GPU tracer
/// holding them, and its camera as the tessellation sees it.
fn on_gpu(gpu: &Gpu, name: &str) -> (Scene, TraceScene, GpuTracer, ScreenCamera) {
    let scene = built_in_scene(name, 160, 120, 2);
    let trace = TraceScene::new(&scene).expect("the scene traces");
    let tracer = gpu_tracer(
        gpu,
        &trace,
        GpuTraversal::Bvh,
        VertexPrecision::F32,
        "the tracer uploads",
    );
    let camera = &scene.camera;
    let screen = ScreenCamera {
        eye: camera.position.as_dvec3(),
        view_proj: camera.view_proj(0.05, 1000.0),
        subpixels: Vec2::new(2.0 * camera.width as f32, 2.0 * camera.height as f32),
    };
    (scene, trace, tracer, screen)
}

/// Everything of a tessellation that must repeat bit for bit.
fn fingerprint(t: &Tessellation<VertexPaths>) -> (Vec<[u32; 3]>, Vec<[u32; 3]>, String) {
    let positions = t
        .mesh
        .positions
        .iter()
        .map(|p| p.to_array().map(f32::to_bits))
        .collect();
    (
        positions,
        t.mesh.triangles.clone(),
        format!("{:?}{:?}{:?}", t.triangles, t.evaluations, t.stats),
    )
}

#[test]
fn gpu_tessellation_is_watertight_close_to_the_cpu_and_repeatable() {
    let gpu = gpu();
    for name in BUILTIN_SCENES {
        let (scene, trace, tracer, screen) = on_gpu(&gpu, name);
        let (mut splits, mut t_junction_leaves) = (0, 0);
        for (lens, lens_bvh) in trace.lenses.iter().enumerate() {
            for &object in &lens_bvh.objects {
                let mesh = &scene.objects[object].mesh;
                let settings = PathSettings {
                    lens,
                    object,
                    bounces: Bounces::UntilLeaving,
                    max_interfaces: GreedyOptions::default().max_interfaces,
                    classes: lensmap::trace::classes::ClassList::GREEDY,
                };
                for t in [3.0, 5.0] {
                    let case = format!("{name}, object {object}, t = {t}");
                    let options = TessellationOptions {
                        t,
                        ..TessellationOptions::default()
                    };
                    let oracle = PathOracle::new(
                        &trace,
                        lens,
                        object,
                        screen,
                        ANGLE_DEGREES.to_radians(),
                        LensFaces::Front,
                    );
                    let cpu = tessellate(mesh, &oracle, &options).expect("the CPU tessellates");
                    let request = GpuTessellationRequest {
                        camera: &screen,
                        settings: &settings,
                        cos_threshold: ANGLE_DEGREES.to_radians().cos() as f32,
                        back_faces: false,
                        options: &options,
                        texgen: None,
                        hull: None,
                        continue_budget: false,
                    };
                    let run = || {
                        tracer
                            .tessellate(&gpu, object, mesh, &request)
                            .expect("the GPU tessellates")
                    };
                    let first = run();
                    let (on_gpu, counters) = (first.tessellation, first.counters);
                    let again = run().tessellation;
                    let (c, g) = (&cpu.stats, &on_gpu.stats);
                    eprintln!(
                        "{case}: vertices CPU {} GPU {}, triangles {} / {}, splits {}/{}/{} vs {}/{}/{}, T-junction leaves {} / {}, depth {} / {}",
                        c.output_vertices,
                        g.output_vertices,
                        c.output_triangles,
                        g.output_triangles,
                        c.splits_1_to_2,
                        c.splits_1_to_3,
                        c.splits_1_to_4,
                        g.splits_1_to_2,
                        g.splits_1_to_3,
                        g.splits_1_to_4,
                        c.t_junction_leaves,
                        g.t_junction_leaves,
                        c.max_depth_reached,
                        g.max_depth_reached,
                    );
                    check_topology(&format!("{case} (CPU)"), mesh, &cpu);
                    check_topology(&case, mesh, &on_gpu);
                    if name == "glass-sphere" {
                        // A closed mesh once its seams are welded: the geometric checks too.
                        let closed = welded(mesh);
                        let cpu =
                            tessellate(&closed, &oracle, &options).expect("the CPU tessellates");
                        check_surface(&format!("{case}, welded (CPU)"), &closed, &cpu);
                        let on_gpu = tracer
                            .tessellate(&gpu, usize::MAX, &closed, &request)
                            .expect("the GPU tessellates")
                            .tessellation;
                        check_surface(&format!("{case}, welded"), &closed, &on_gpu);
                    }
                    splits += g.splits_1_to_2 + g.splits_1_to_3 + g.splits_1_to_4;
                    t_junction_leaves += g.t_junction_leaves;
                    let ratio = g.output_vertices as f64 / c.output_vertices as f64;
                    assert!((0.9..=1.1).contains(&ratio), "{case}: {c:?} {g:?}");
                    assert_eq!(g.front_facing_triangles, c.front_facing_triangles, "{case}");
                    assert_eq!(g.vertices_evaluated as u64, counters.primary_rays, "{case}");
                    assert_eq!(g.output_triangles, on_gpu.mesh.triangles.len(), "{case}");
                    assert!(
                        fingerprint(&on_gpu) == fingerprint(&again),
                        "{case}: two GPU runs differ"
                    );
                }
            }
        }
        assert!(
            splits > 0 && t_junction_leaves > 0,
            "{name}: the scene subdivides and removes T-junctions"
        );
        assert_clean(&gpu);
    }
}

#[test]
fn the_gpu_tessellation_keeps_the_vertex_budget_and_refuses_a_deeper_cap() {
    let gpu = gpu();
    let (scene, trace, tracer, screen) = on_gpu(&gpu, "glass-sphere");
    let object = trace.lenses[0].objects[0];
    let mesh = &scene.objects[object].mesh;
    let settings = PathSettings {
        lens: 0,
        object,
        bounces: Bounces::UntilLeaving,
        max_interfaces: GreedyOptions::default().max_interfaces,
        classes: lensmap::trace::classes::ClassList::GREEDY,
    };
    let budget = mesh.positions.len() + 200;
    let options = TessellationOptions {
        t: 1.0,
        max_vertices: budget,
        ..TessellationOptions::default()
    };
    let request = GpuTessellationRequest {
        camera: &screen,
        settings: &settings,
        cos_threshold: ANGLE_DEGREES.to_radians().cos() as f32,
        back_faces: false,
        options: &options,
        texgen: None,
        hull: None,
        continue_budget: false,
    };
    let capped = tracer
        .tessellate(&gpu, object, mesh, &request)
        .expect("the GPU tessellates")
        .tessellation;
    let stats = &capped.stats;
    assert!(stats.stopped_by_budget > 0, "{stats:?}");
    assert!(
        capped.mesh.positions.len() <= budget && capped.mesh.positions.len() + 3 > budget,
        "{} vertices against a budget of {budget}",
        capped.mesh.positions.len()
    );
    let budget_leaves = capped
        .triangles
        .iter()
        .filter(|r| r.stop == StopReason::Budget)
        .count();
    assert!(budget_leaves > 0);
    check_topology("glass-sphere under a budget", mesh, &capped);

    // A spent budget (a lens object after others took it all): no split, no error.
    let spent = TessellationOptions {
        max_vertices: 0,
        ..options
    };
    let unsplit = tracer
        .tessellate(
            &gpu,
            object,
            mesh,
            &GpuTessellationRequest {
                options: &spent,
                ..request
            },
        )
        .expect("a spent budget only stops the splits")
        .tessellation;
    assert_eq!(unsplit.mesh.positions.len(), mesh.positions.len());
    assert!(unsplit.stats.stopped_by_budget > 0);
    check_topology("glass-sphere with a spent budget", mesh, &unsplit);
    let zero_t = TessellationOptions { t: 0.0, ..options };
    assert!(matches!(
        tracer.tessellate(
            &gpu,
            object,
            mesh,
            &GpuTessellationRequest {
                options: &zero_t,
                ..request
            },
        ),
        Err(TessellationError::InvalidThreshold(_))
    ));

    let deep = TessellationOptions {
        max_depth: GPU_MAX_DEPTH + 1,
        ..options
    };
    let refused = tracer.tessellate(
        &gpu,
        object,
        mesh,
        &GpuTessellationRequest {
            options: &deep,
            ..request
        },
    );
    assert!(
        matches!(&refused, Err(TessellationError::Option(e)) if e.to_string().contains("max_depth")),
        "{:?}",
        refused.err()
    );
    assert_clean(&gpu);
}

/// Every kind of layer shell around a lens object of centre `c` and size `r`: sphere, ellipsoid,
/// box, capped and unbounded cylinders, a quad impostor.
fn every_shell(c: DVec3, r: f64) -> Vec<LayerShell> {
    vec![
        LayerShell::Sphere {
            centre: c,
            radius: 2.0 * r,
        },
        LayerShell::Ellipsoid {
            centre: c + DVec3::new(0.1, 0.0, 0.05) * r,
            radii: DVec3::new(3.0, 2.0, 2.5) * r,
        },
        LayerShell::Box {
            centre: c + DVec3::new(0.0, 0.2, 0.0) * r,
            half_extents: DVec3::new(3.0, 2.0, 4.0) * r,
        },
        LayerShell::Cylinder {
            centre: c,
            axis: DVec3::new(1.0, 2.0, 0.5).normalize(),
            radius: 3.0 * r,
            half_height: Some(4.0 * r),
        },
        LayerShell::Cylinder {
            centre: c,
            axis: DVec3::Y,
            radius: 2.5 * r,
            half_height: None,
        },
        LayerShell::quad_facing(
            c + DVec3::new(0.0, 0.0, -5.0 * r),
            DVec3::new(0.0, 0.3, 1.0),
            DVec2::new(3.0 * r, 3.0 * r),
        ),
    ]
}

#[test]
fn gpu_texgen_matches_every_shell_kind_in_f64() {
    let gpu = gpu();
    for name in BUILTIN_SCENES {
        let (scene, trace, tracer, screen) = on_gpu(&gpu, name);
        let object = trace.lenses[0].objects[0];
        let mesh = &scene.objects[object].mesh;
        let (lo, hi) = mesh.bounds().expect("a lens mesh");
        let (c, r) = (
            ((lo + hi) * 0.5).as_dvec3(),
            f64::from((hi - lo).length()) * 0.5,
        );
        let shells = every_shell(c, r);
        let em_origins: Vec<DVec3> = (0..shells.len())
            .map(|i| c + DVec3::new(0.0, 0.01 * i as f64, 0.0) * r)
            .collect();
        let refraction = trace
            .interface(object)
            .is_some_and(|i| matches!(i, Interface::Dielectric { .. }));
        let settings = PathSettings {
            lens: 0,
            object,
            bounces: Bounces::UntilLeaving,
            max_interfaces: GreedyOptions::default().max_interfaces,
            classes: lensmap::trace::classes::ClassList::GREEDY,
        };
        let options = TessellationOptions {
            t: 3.0,
            ..TessellationOptions::default()
        };
        let made = tracer
            .tessellate(
                &gpu,
                object,
                mesh,
                &GpuTessellationRequest {
                    camera: &screen,
                    settings: &settings,
                    cos_threshold: ANGLE_DEGREES.to_radians().cos() as f32,
                    back_faces: false,
                    options: &options,
                    texgen: Some(TexgenRequest {
                        shells: &shells,
                        em_origins: &em_origins,
                        refraction,
                        classes: &[],
                    }),
                    hull: None,
                    continue_budget: false,
                },
            )
            .expect("the GPU tessellates");
        let terms = made.terms.expect("texgen was asked for");
        let t = &made.tessellation;
        let expected_terms: Vec<Term> = [Term::Refraction, Term::Reflection]
            .into_iter()
            .filter(|&term| refraction || term == Term::Reflection)
            .collect();
        assert_eq!(
            terms.iter().map(|t| t.term).collect::<Vec<_>>(),
            expected_terms
        );
        let (mut compared, mut within, mut worst) = (0usize, 0usize, 0f64);
        for term in &terms {
            assert_eq!(term.fg.len(), t.mesh.positions.len(), "{name}");
            assert_eq!(term.directions.len(), shells.len(), "{name}");
            for (v, evaluation) in t.evaluations.iter().enumerate() {
                // The CPU texgen's rule: the term's path, else the reflection's weighing nothing.
                let path = evaluation.as_ref().and_then(|e| {
                    e.sample.get(term.term).copied().or(e
                        .sample
                        .get(Term::Reflection)
                        .copied()
                        .map(|mut p| {
                            p.fg = DVec3::ZERO;
                            p
                        }))
                });
                let fg = path.map_or(Vec3::ZERO, |p| p.fg.as_vec3());
                assert_eq!(term.fg[v], fg, "{name}: vertex {v}'s F·G");
                for (layer, (shell, &origin)) in shells.iter().zip(&em_origins).enumerate() {
                    let cpu = match path {
                        Some(p) => shell.texture_direction_for_ray(
                            origin,
                            p.outgoing.origin,
                            p.outgoing.direction,
                        ),
                        None => (t.mesh.positions[v].as_dvec3() - origin).normalize_or(DVec3::Z),
                    };
                    let error = (term.directions[layer][v].as_dvec3() - cpu).length()
                        / cpu.length().max(1e-9);
                    compared += 1;
                    within += usize::from(error <= 1e-4);
                    worst = worst.max(error);
                }
            }
        }
        let share = within as f64 / compared as f64;
        eprintln!(
            "{name}: {compared} directions (vertices × terms × {} shells): {:.4} % within 1e-4 of f64, worst {worst:.2e}",
            shells.len(),
            100.0 * share
        );
        assert!(compared > 10_000, "{name}: {compared}");
        assert!(share >= 0.999 && worst <= 1e-3, "{name}: {share} {worst}");
        assert_clean(&gpu);
    }
}
