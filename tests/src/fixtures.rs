//! Inputs the end-to-end tests share: a small scene file that a test breaks one field at a time,
//! scratch folders, built-in scenes at test sizes with projected layered EMs, a compositor test's
//! GPU, renderer and seeded random source, a smooth sky with a
//! closed form, and an exact glass sphere for the tracer's path kernel with the angle measure
//! its closed forms are compared in.

use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3, Vec2, Vec3};
use lensmap::gpu::Gpu;
use lensmap::hybrid::HybridScene;
use lensmap::hybrid::gpu::{GpuTracer, GpuTraversal, TracerWalk};
use lensmap::hybrid::paths::VertexPrecision;
use lensmap::layers::projected::ProjectedOptions;
use lensmap::render::Renderer;
use lensmap::runner::{EmSource, load_hybrid_scene};
use lensmap::scene::{
    Camera, Environment, LensObject, Material, Scene, SceneObject, TriangleMesh, ViewSpace,
};
use lensmap::trace::bvh::SurfaceHit;
use lensmap::trace::path::{Interface, LensGeometry};
use lensmap::trace::{Ray, TraceCounters, TraceScene};
use rand::SeedableRng;
use rand_pcg::Pcg64;

/// A small valid scene file: a 16×12 camera at 1×1 supersampling (its `width` on line 8), a
/// constant environment, one point light, a glass ball over a grey floor plane; no lens objects
/// and no view space, which a test appends where it needs them. Renders in a fraction of a
/// second. Tests break one thing in it with [`edit_scene`].
pub const SMALL_SCENE: &str = r#"
name = "small"

[camera]
position = [0, 1, 5]
look_at = [0, 1, 0]
vfov_degrees = 45
width = 16
height = 12
supersampling = 1

[environment]
constant = [0.1, 0.1, 0.1]

[[lights]]
position = [0, 5, 0]
intensity = [10, 10, 10]

[[materials]]
name = "glass"
glass = { ior = 1.5, absorption = [0.9, 0.9, 0.9] }

[[materials]]
name = "grey"
diffuse = { colour = [0.5, 0.5, 0.5] }

[[objects]]
name = "ball"
material = "glass"
sphere = { radius = 1, segments = 16, rings = 8 }

[[objects]]
name = "floor"
material = "grey"
plane = { size = [4, 4] }
"#;

/// `scene` with its first `from` replaced by `to`; fails the test if `scene` lacks `from`.
pub fn edit_scene(scene: &str, from: &str, to: &str) -> String {
    assert!(scene.contains(from), "the scene lacks {from:?}");
    scene.replacen(from, to, 1)
}

/// An empty scratch folder `lensmap-GROUP-NAME-PID` in the system's temporary folder (an
/// earlier one of that name is removed first).
pub fn temp_dir(group: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensmap-{group}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a scratch folder");
    dir
}

/// Built-in scene `name` with its camera at `width × height` pixels of `supersampling`²
/// subpixels.
pub fn built_in_scene(name: &str, width: u32, height: u32, supersampling: u32) -> Scene {
    let mut scene = Scene::load_named(name).expect("a built-in scene");
    scene.camera = scene.camera.with_resolution(width, height, supersampling);
    scene
}

/// `scene` ready to render, with projected layered EMs of `size`² texels per face at one ray
/// per texel.
pub fn with_projected_ems(scene: Scene, size: u32) -> HybridScene {
    let ems = EmSource::Projected(ProjectedOptions {
        size,
        supersampling: 1,
    });
    load_hybrid_scene(scene, &ems.into())
        .expect("the scene loads")
        .0
}

/// A scene of one lens object alone in a constant environment of radiance `sky` (no lights, no
/// view space, the object's layer shells left to the defaults): the object `name`, made of
/// `mesh` and `material`, seen by `camera`.
pub fn lens_alone(
    name: &str,
    mesh: TriangleMesh,
    material: Material,
    sky: Vec3,
    camera: Camera,
) -> Scene {
    Scene {
        name: name.to_owned(),
        objects: vec![SceneObject {
            name: name.to_owned(),
            mesh,
            material: 0,
        }],
        materials: vec![material],
        lights: Vec::new(),
        environment: Environment::Constant(sky),
        lenses: vec![LensObject {
            name: name.to_owned(),
            objects: vec![0],
            layers: Vec::new(),
            layering: lensmap::layers::Layering::Distance,
            terms: None,
        }],
        camera,
        view_space: ViewSpace::List(Vec::new()),
        warnings: Vec::new(),
    }
}

/// What a compositor test starts from: a GPU with the validation layer on ([`crate::gpu`]), a
/// renderer on it, and a random source seeded with `seed`.
pub fn compositor(seed: u64) -> (Gpu, Renderer, Pcg64) {
    let gpu = crate::gpu();
    let renderer = Renderer::new(&gpu).expect("a renderer");
    (gpu, renderer, Pcg64::seed_from_u64(seed))
}

/// The radiance of a smooth sky along `direction`: a low-order function of the direction (no
/// seam at u = 0), so that a sky dome's linear interpolation between its vertices is close to
/// exact.
pub fn smooth_sky(direction: Vec3) -> Vec3 {
    let d = direction.normalize();
    Vec3::new(0.45 + 0.35 * d.y, 0.5 + 0.3 * d.x, 0.55 + 0.25 * d.z)
}

/// Writes [`smooth_sky`] as a 256×128 lat-long float EXR at `path`.
pub fn write_smooth_sky(path: &Path) {
    let (w, h) = (256u32, 128u32);
    let mut data = Vec::with_capacity((w * h * 3) as usize);
    for j in 0..h {
        for i in 0..w {
            let uv = Vec2::new((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32);
            data.extend(smooth_sky(lensmap::scene::lat_long_to_direction(uv)).to_array());
        }
    }
    let image = image::Rgb32FImage::from_raw(w, h, data).expect("a 256×128 image");
    image::DynamicImage::ImageRgb32F(image)
        .save(path)
        .expect("the sky is written");
}

/// The angle between two directions, radians; accurate for tiny angles (`acos` of a dot
/// product is not: it bottoms out near 1.5e-8 rad).
pub fn angle_between(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// An exact sphere of glass for the tracer's path kernel: f64 intersections and exact normals
/// (no tessellation), so that the tracer's own arithmetic is all that differs from a closed
/// form.
#[derive(Clone, Copy, Debug)]
pub struct AnalyticSphere {
    /// Centre, metres.
    pub centre: DVec3,
    /// Radius, metres (> 0).
    pub radius: f64,
    /// Index of refraction of the glass.
    pub ior: f64,
    /// Per-channel transmittance of one metre of the glass, each in [0, 1].
    pub absorption: DVec3,
}

impl AnalyticSphere {
    /// Clear glass of index `ior`: radius `radius` around the origin, nothing absorbed.
    pub fn clear(radius: f64, ior: f64) -> AnalyticSphere {
        AnalyticSphere {
            centre: DVec3::ZERO,
            radius,
            ior,
            absorption: DVec3::ONE,
        }
    }
}

impl LensGeometry for AnalyticSphere {
    fn closest_hit(
        &self,
        ray: &Ray,
        _exclude: Option<u32>,
        _counters: &mut TraceCounters,
    ) -> Option<SurfaceHit> {
        // |o + t d − c|² = r² in the stable form: the product of the roots is c.
        let oc = ray.origin - self.centre;
        let b = oc.dot(ray.direction);
        let c = oc.length_squared() - self.radius * self.radius;
        let discriminant = b * b - c;
        if discriminant < 0.0 {
            return None;
        }
        let q = -b - b.signum() * discriminant.sqrt();
        let (near, far) = if q == 0.0 {
            (0.0, 0.0)
        } else {
            let (x, y) = (q, c / q);
            (x.min(y), x.max(y))
        };
        let t = [near, far].into_iter().find(|t| *t > 1e-9 * self.radius)?;
        let position = ray.at(t);
        let normal = (position - self.centre).normalize();
        Some(SurfaceHit {
            distance: t,
            position,
            geometric_normal: normal,
            shading_normal: normal,
            uv: DVec2::ZERO,
            object: 0,
            primitive: 0,
        })
    }

    fn interface(&self, _object: usize) -> Interface {
        Interface::Dielectric {
            ior: self.ior,
            absorption: self.absorption,
        }
    }
}

/// A GPU tracer of `trace` on `gpu` (no Schlick table) walking `traversal` in `precision`; the
/// panic says `what` failed.
pub fn gpu_tracer(
    gpu: &Gpu,
    trace: &TraceScene,
    traversal: GpuTraversal,
    precision: VertexPrecision,
    what: &str,
) -> GpuTracer {
    GpuTracer::new(
        gpu,
        trace,
        None,
        TracerWalk {
            traversal,
            precision,
        },
    )
    .unwrap_or_else(|e| panic!("{what}: {e}"))
}

/// The vertices of `mesh`'s triangles that face `eye`, with unit normals as the tessellation
/// hands them to its oracle.
pub fn front_facing_vertices(
    mesh: &TriangleMesh,
    eye: Vec3,
) -> Vec<lensmap::hybrid::tessellate::SurfaceVertex> {
    let normals = if mesh.normals.len() == mesh.positions.len() {
        mesh.normals.clone()
    } else {
        mesh.accumulated_face_normals()
    };
    let mut used = vec![false; mesh.positions.len()];
    for t in &mesh.triangles {
        if lensmap::hybrid::tessellate::faces_eye(t.map(|v| mesh.positions[v as usize]), eye) {
            t.iter().for_each(|&v| used[v as usize] = true);
        }
    }
    (0..mesh.positions.len())
        .filter(|&v| used[v])
        .map(|v| lensmap::hybrid::tessellate::SurfaceVertex {
            index: v as u32,
            position: mesh.positions[v],
            normal: normals[v].normalize_or_zero(),
            uv: None,
        })
        .collect()
}
