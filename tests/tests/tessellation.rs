//! Adaptive tessellation invariants (hybrid-rendering paper §5, Figures 5 and 6) on random jittered
//! grids, random closed meshes and the Newell teapot, for t ∈ {0.5, 1, 3, 5} and several oracles:
//! always-differ, never-differ, hash-based differ, a reflected-direction field with a 3° threshold
//! and a topology flag, and always-differ with part of the mesh occluded.
//!
//! Every invariant is checked geometrically, independently of the tessellator's bookkeeping:
//! watertight (interior edges shared by exactly two oppositely wound triangles; the output's
//! boundary covers exactly the input's boundary), no vertex strictly inside an edge, area
//! preserved to 1e-5 relative, triangles on and wound like their source triangles, termination
//! (each leaf stopped for a reason the oracle confirms) and each vertex evaluated exactly once.

use std::collections::{HashMap, HashSet};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Mat4, Vec2, Vec3};
use lensmap::hybrid::tessellate::{
    StopReason, SurfaceVertex, Tessellation, TessellationOptions, VertexOracle, faces_eye,
    tessellate,
};
use lensmap::scene::teapot::teapot;
use lensmap::scene::{Camera as SceneCamera, TriangleMesh};
use lensmap_tests::mesh_checks::check_surface;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// The tessellation thresholds t tested, in subpixels.
const THRESHOLDS: [f32; 4] = [0.5, 1.0, 3.0, 5.0];

/// The scene's pinhole camera and its Vulkan view-projection, projecting to subpixels.
struct Camera {
    eye: Vec3,
    view_projection: Mat4,
    subpixels: Vec2,
}

impl Camera {
    /// Looks at the origin from `eye` with a 32 × 32 pixel image at 2 × 2 supersampling; a
    /// sphere of radius `radius` about the origin spans about 60 % of the image.
    fn new(eye: Vec3, radius: f32) -> Self {
        let camera = SceneCamera {
            position: eye,
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_radians: 2.0 * (radius / 0.6 / eye.length()).atan(),
            width: 32,
            height: 32,
            supersampling: 2,
        };
        Camera {
            eye,
            view_projection: camera.view_proj(0.01, 100.0),
            subpixels: Vec2::new(camera.width as f32, camera.height as f32)
                * camera.supersampling as f32,
        }
    }

    fn project(&self, p: Vec3) -> Option<Vec2> {
        let clip = self.view_projection * p.extend(1.0);
        (clip.w > 1e-6).then(|| {
            let ndc = clip.truncate().truncate() / clip.w;
            (ndc + Vec2::ONE) * 0.5 * self.subpixels
        })
    }
}

/// Which differ criterion an [`Oracle`] applies.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Criterion {
    Always,
    Never,
    /// A pseudo-random quarter of vertex pairs differ (symmetric hash of the two positions).
    Hash,
    /// Reflected view direction about the shading normal: differ above 3°, or when one vertex
    /// is grazing (n·v < 0.2) and the other is not (a "topology" change).
    Direction,
    /// Always differ, but vertices below y = −0.2 are occluded.
    AlwaysOccludedBelow,
}

const CRITERIA: [Criterion; 5] = [
    Criterion::Always,
    Criterion::Never,
    Criterion::Hash,
    Criterion::Direction,
    Criterion::AlwaysOccludedBelow,
];

#[derive(Clone, Debug)]
struct Sample {
    hash: u64,
    reflected: Vec3,
    grazing: bool,
}

/// The test oracle: a pinhole camera, one criterion, and a log of every evaluation.
struct Oracle {
    camera: Camera,
    criterion: Criterion,
    evaluated: Mutex<Vec<(u32, Vec3)>>,
    visibility_queries: AtomicUsize,
}

impl Oracle {
    fn new(camera: Camera, criterion: Criterion) -> Self {
        Oracle {
            camera,
            criterion,
            evaluated: Mutex::new(Vec::new()),
            visibility_queries: AtomicUsize::new(0),
        }
    }
}

fn mix(mut x: u64) -> u64 {
    x ^= x >> 33;
    x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
    x ^= x >> 33;
    x = x.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
    x ^ (x >> 33)
}

impl VertexOracle for Oracle {
    type Sample = Sample;

    fn evaluate(&self, vertex: &SurfaceVertex) -> Sample {
        self.evaluated
            .lock()
            .unwrap()
            .push((vertex.index, vertex.position));
        let p = vertex.position;
        let hash = mix(u64::from(p.x.to_bits())
            ^ mix(u64::from(p.y.to_bits()) ^ mix(u64::from(p.z.to_bits()))));
        let view = (p - self.camera.eye).normalize();
        let n = vertex.normal;
        Sample {
            hash,
            reflected: view - 2.0 * view.dot(n) * n,
            grazing: -view.dot(n) < 0.2,
        }
    }

    fn visible(&self, vertex: &SurfaceVertex) -> bool {
        self.visibility_queries.fetch_add(1, Ordering::Relaxed);
        self.criterion != Criterion::AlwaysOccludedBelow || vertex.position.y > -0.2
    }

    fn differ(&self, a: &Sample, b: &Sample) -> bool {
        match self.criterion {
            Criterion::Always | Criterion::AlwaysOccludedBelow => true,
            Criterion::Never => false,
            Criterion::Hash => mix(a.hash.min(b.hash) ^ mix(a.hash.max(b.hash))) & 3 == 0,
            Criterion::Direction => {
                a.grazing != b.grazing || a.reflected.dot(b.reflected) < 3.0f32.to_radians().cos()
            }
        }
    }

    fn screen(&self, position: Vec3) -> Option<Vec2> {
        self.camera.project(position)
    }

    fn front_facing(&self, corners: [Vec3; 3]) -> bool {
        faces_eye(corners, self.camera.eye)
    }
}

/// An n × n grid over [−1, 1]² in the xy plane, each inner vertex jittered by up to 0.3 cells in
/// x and y and 0.1 in z, each quad cut along a random diagonal. Open: its rim is its boundary.
fn jittered_grid(n: u32, rng: &mut Pcg64) -> TriangleMesh {
    let cell = 2.0 / n as f32;
    let mut mesh = TriangleMesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let inner = i > 0 && j > 0 && i < n && j < n;
            let jitter = if inner {
                Vec3::new(
                    rng.gen_range(-0.3..0.3) * cell,
                    rng.gen_range(-0.3..0.3) * cell,
                    rng.gen_range(-0.1..0.1),
                )
            } else {
                Vec3::ZERO
            };
            mesh.positions
                .push(Vec3::new(-1.0 + i as f32 * cell, -1.0 + j as f32 * cell, 0.0) + jitter);
        }
    }
    let index = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            let [a, b, c, d] = [
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            ];
            if rng.gen_bool(0.5) {
                mesh.triangles.extend([[a, b, c], [a, c, d]]);
            } else {
                mesh.triangles.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    mesh.generate_smooth_normals();
    mesh
}

/// An icosahedron subdivided `levels` times (shared midpoints), projected onto the unit sphere
/// and then each vertex's radius jittered by up to ±`jitter`. Closed, counter-clockwise outward.
fn jittered_icosphere(levels: u32, jitter: f32, rng: &mut Pcg64) -> TriangleMesh {
    let phi = (1.0 + 5.0f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, phi, 0.0],
        [1.0, phi, 0.0],
        [-1.0, -phi, 0.0],
        [1.0, -phi, 0.0],
        [0.0, -1.0, phi],
        [0.0, 1.0, phi],
        [0.0, -1.0, -phi],
        [0.0, 1.0, -phi],
        [phi, 0.0, -1.0],
        [phi, 0.0, 1.0],
        [-phi, 0.0, -1.0],
        [-phi, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| Vec3::from(p).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push(((positions[a as usize] + positions[b as usize]) * 0.5).normalize());
                positions.len() as u32 - 1
            })
        };
        let mut finer = Vec::new();
        for [a, b, c] in triangles {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            finer.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    for p in &mut positions {
        *p *= 1.0 + rng.gen_range(-jitter..=jitter);
    }
    let mut mesh = TriangleMesh {
        positions,
        triangles,
        ..TriangleMesh::default()
    };
    mesh.generate_smooth_normals();
    mesh
}

/// The Newell teapot (`level` quads per patch side), centred and scaled to a unit bounding
/// sphere.
fn unit_teapot(level: u32) -> TriangleMesh {
    let mut mesh = teapot(level);
    let (lo, hi) = mesh.bounds().expect("the teapot has vertices");
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    for p in &mut mesh.positions {
        *p = (*p - centre) / radius;
    }
    mesh
}

/// What one case measured, for the summary line.
struct CaseStats {
    input: usize,
    output: usize,
    evaluated: usize,
}

/// Tessellates `input` with `oracle` at `t` and checks every invariant.
fn check_case(name: &str, input: &TriangleMesh, oracle: &Oracle, t: f32) -> CaseStats {
    let options = TessellationOptions {
        t,
        ..TessellationOptions::default()
    };
    let case = format!("{name}, {:?}, t = {t}", oracle.criterion);
    let out: Tessellation<Sample> = match tessellate(input, oracle, &options) {
        Ok(out) => out,
        Err(e) => panic!("{case}: {e}"),
    };
    let mesh = &out.mesh;
    let stats = &out.stats;
    assert_eq!(mesh.triangles.len(), out.triangles.len(), "{case}");
    assert_eq!(mesh.triangles.len(), stats.output_triangles, "{case}");
    assert_eq!(stats.input_triangles, input.triangles.len(), "{case}");
    assert_eq!(
        &mesh.positions[..input.positions.len()],
        &input.positions[..],
        "{case}"
    );
    assert_eq!(mesh.normals.len(), mesh.positions.len(), "{case}");
    assert!(
        mesh.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4),
        "{case}"
    );

    let component = check_surface(&case, input, &out);

    // Termination: each leaf stopped for a reason the oracle confirms.
    let sample = |v: u32| out.evaluations[v as usize].as_ref();
    for (tri, record) in mesh.triangles.iter().zip(&out.triangles) {
        let source = input.triangles[record.source as usize];
        let front = oracle.front_facing(source.map(|v| input.positions[v as usize]));
        assert_eq!(front, record.stop != StopReason::BackFacing, "{case}");
        assert!(record.depth <= options.max_depth, "{case}");
        if !front {
            continue;
        }
        let leaf: Vec<_> = record
            .leaf
            .iter()
            .map(|&v| sample(v).unwrap_or_else(|| panic!("{case}: vertex {v} not evaluated")))
            .collect();
        let differ = (0..3).any(|i| oracle.differ(&leaf[i].sample, &leaf[(i + 1) % 3].sample));
        match record.stop {
            StopReason::Occluded => assert!(leaf.iter().all(|e| !e.visible), "{case}"),
            StopReason::Similar => assert!(!differ, "{case}"),
            StopReason::Small => {
                assert!(differ, "{case}");
                // Every edge of the leaf, and so of each piece of it, is under t on screen.
                for corners in [record.leaf, *tri] {
                    for i in 0..3 {
                        let ends = [corners[i], corners[(i + 1) % 3]]
                            .map(|v| oracle.screen(mesh.positions[v as usize]));
                        if let [Some(p), Some(q)] = ends {
                            assert!(p.distance(q) < t * 1.001 + 1e-3, "{case}: long edge");
                        }
                    }
                }
            }
            StopReason::MaxDepth => assert_eq!(record.depth, options.max_depth, "{case}"),
            StopReason::Budget => assert!(
                out.mesh.positions.len() + 3 > options.max_vertices,
                "{case}: a budget stop below the budget"
            ),
            // The test oracles see everything (the default outside_view).
            StopReason::BackFacing | StopReason::Degenerate | StopReason::OffScreen => {
                panic!("{case}: {record:?}")
            }
        }
    }
    assert_eq!(
        stats.stopped_at_max_depth, 0,
        "{case}: t alone should stop subdivision"
    );

    // Evaluation reuse: one evaluation per vertex of a front-facing triangle, none elsewhere,
    // and no position (within a connected part) evaluated twice.
    let evaluated = oracle.evaluated.lock().unwrap();
    assert_eq!(evaluated.len(), stats.vertices_evaluated, "{case}");
    assert_eq!(
        oracle.visibility_queries.load(Ordering::Relaxed),
        stats.vertices_evaluated,
        "{case}"
    );
    let mut seen_index = HashSet::new();
    let mut seen_position = HashSet::new();
    for &(index, position) in evaluated.iter() {
        assert!(
            seen_index.insert(index),
            "{case}: vertex {index} evaluated twice"
        );
        assert_eq!(mesh.positions[index as usize], position, "{case}");
        let key = (
            component[index as usize],
            position.to_array().map(f32::to_bits),
        );
        assert!(
            seen_position.insert(key),
            "{case}: position {position} evaluated twice"
        );
    }
    let front_vertices: HashSet<u32> = mesh
        .triangles
        .iter()
        .zip(&out.triangles)
        .filter(|(_, r)| r.stop != StopReason::BackFacing)
        .flat_map(|(tri, _)| tri.iter().copied())
        .collect();
    for (v, evaluation) in out.evaluations.iter().enumerate() {
        let v = v as u32;
        assert_eq!(evaluation.is_some(), seen_index.contains(&v), "{case}");
        if front_vertices.contains(&v) {
            assert!(
                evaluation.is_some(),
                "{case}: vertex {v} of a front triangle"
            );
        }
    }
    let input_front_vertices: HashSet<u32> = input
        .triangles
        .iter()
        .filter(|tri| oracle.front_facing(tri.map(|v| input.positions[v as usize])))
        .flat_map(|tri| tri.iter().copied())
        .collect();
    for v in 0..input.positions.len() as u32 {
        assert_eq!(
            out.evaluations[v as usize].is_some(),
            input_front_vertices.contains(&v),
            "{case}: input vertex {v}"
        );
    }
    CaseStats {
        input: input.triangles.len(),
        output: mesh.triangles.len(),
        evaluated: stats.vertices_evaluated,
    }
}

/// Runs every criterion and threshold on one mesh seen from `eye`, printing a summary line each.
fn check_mesh(name: &str, mesh: &TriangleMesh, eye: Vec3) {
    for criterion in CRITERIA {
        for t in THRESHOLDS {
            let oracle = Oracle::new(Camera::new(eye, 1.0), criterion);
            let s = check_case(name, mesh, &oracle, t);
            println!(
                "{name:>14} {criterion:>20?} t={t:<3} triangles {:>4} -> {:>6}, vertices evaluated {:>6}",
                s.input, s.output, s.evaluated
            );
        }
    }
}

fn random_eye(rng: &mut Pcg64, distance: f32) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        );
        if v.length() > 0.2 && v.length() <= 1.0 {
            return v.normalize() * distance;
        }
    }
}

#[test]
fn jittered_grids_stay_watertight_for_every_threshold_and_oracle() {
    let mut rng = Pcg64::seed_from_u64(1);
    for (seed, n) in [(0, 5), (1, 7)] {
        let mesh = jittered_grid(n, &mut rng);
        // Oblique views from the front side (some jittered triangles face away).
        let eye = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), 3.0);
        check_mesh(&format!("grid{seed}"), &mesh, eye);
    }
}

#[test]
fn random_closed_meshes_stay_closed_for_every_threshold_and_oracle() {
    let mut rng = Pcg64::seed_from_u64(2);
    for (seed, levels, jitter) in [(0, 1, 0.0), (1, 1, 0.15), (2, 2, 0.08)] {
        let mesh = jittered_icosphere(levels, jitter, &mut rng);
        let eye = random_eye(&mut rng, 3.0);
        check_mesh(&format!("icosphere{seed}"), &mesh, eye);
    }
}

/// Runs `work` on a rayon pool of `threads` threads.
fn with_threads<R: Send>(threads: usize, work: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
        .install(work)
}

/// The invariants hold whatever the thread count (the tessellator runs its phases in parallel).
#[test]
fn the_teapot_stays_watertight_for_every_threshold_and_oracle() {
    let mesh = unit_teapot(2);
    for threads in [1, 4] {
        with_threads(threads, || {
            check_mesh(
                &format!("teapot, {threads} threads"),
                &mesh,
                Vec3::new(1.6, 1.4, 2.2),
            )
        });
    }
}

#[test]
fn tessellation_is_deterministic() {
    let mut rng = Pcg64::seed_from_u64(3);
    let mesh = jittered_icosphere(1, 0.1, &mut rng);
    let eye = random_eye(&mut rng, 3.0);
    let run = || {
        let oracle = Oracle::new(Camera::new(eye, 1.0), Criterion::Direction);
        let out = tessellate(
            &mesh,
            &oracle,
            &TessellationOptions {
                t: 1.0,
                max_depth: 12,
                ..TessellationOptions::default()
            },
        )
        .expect("valid input");
        (out.mesh, out.stats)
    };
    let first = with_threads(1, run);
    // Identical output at every thread count, and from run to run.
    for threads in [1, 2, 3, 8] {
        let other = with_threads(threads, run);
        assert_eq!(first.0, other.0, "{threads} threads");
        assert_eq!(first.1, other.1, "{threads} threads");
    }
    assert!(
        first.1.splits_1_to_2 + first.1.splits_1_to_3 > 0,
        "{:?}",
        first.1
    );
    assert!(first.1.t_junction_leaves > 0, "{:?}", first.1);
}

/// Coarser t means fewer triangles; the always-differ oracle always splits at least as much as
/// any other.
#[test]
fn finer_thresholds_give_more_triangles() {
    let mesh = unit_teapot(2);
    let eye = Vec3::new(1.6, 1.4, 2.2);
    let count = |criterion, t| {
        let oracle = Oracle::new(Camera::new(eye, 1.0), criterion);
        let out = tessellate(
            &mesh,
            &oracle,
            &TessellationOptions {
                t,
                max_depth: 12,
                ..TessellationOptions::default()
            },
        )
        .expect("valid input");
        out.stats.output_triangles
    };
    for criterion in [Criterion::Always, Criterion::Direction] {
        let counts: Vec<usize> = THRESHOLDS.iter().map(|&t| count(criterion, t)).collect();
        assert!(
            counts.windows(2).all(|w| w[0] >= w[1]),
            "{criterion:?}: {counts:?}"
        );
    }
    for t in THRESHOLDS {
        assert!(count(Criterion::Always, t) >= count(Criterion::Direction, t));
        assert_eq!(count(Criterion::Never, t), mesh.triangles.len());
    }
}
