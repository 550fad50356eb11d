//! The scene model: scene files (TOML), meshes (OBJ read by lensmap, built-in shapes, the Newell
//! teapot), materials, lights, the environment at infinity, lens objects, the camera and the view
//! space. [`Scene::load`] parses and checks a file and builds every mesh in world space; anything
//! wrong is one [`SceneError`] line, `<file>: <field>: <what is wrong>; <fix>`.
//!
//! The scene file's schema, every field with its unit, range and default, is documented once, in
//! `tools/scenes/README.md`. Here, `file` holds its serde structs and `load` the checks that turn
//! them into a [`Scene`]. The built-in scenes are embedded at compile time.

mod camera;
mod environment;
mod error;
mod file;
mod identity;
mod image_file;
mod load;
mod material;
mod mesh;
mod obj;
mod path;
pub mod shapes;
pub mod teapot;

use std::path::{Path, PathBuf};

pub use camera::{Camera, ViewSpace};
pub use environment::{
    Environment, LatLongMap, PointLight, direction_to_lat_long, lat_long_to_direction,
};
pub use error::SceneError;
pub use material::{Coat, Glossy, ImageTexture, Material, Texture};
pub use mesh::{MeshProblem, TriangleMesh};
pub use path::{CameraPath, CameraPose};

/// The names of the built-in scenes with lens objects, in the order `lensmap` lists them.
pub const BUILTIN_SCENES: [&str; 3] = ["teapot-room", "glass-sphere", "mirror-teapot"];

/// The names of the built-in scenes of glossy objects alone (reflection-space IBR).
pub const GLOSSY_SCENES: [&str; 2] = ["glossy-studio", "glossy-room"];

/// Every built-in scene's name, lens scenes first, joined for a message.
pub fn builtin_names() -> String {
    let names: Vec<&str> = BUILTIN_SCENES
        .iter()
        .chain(&GLOSSY_SCENES)
        .copied()
        .collect();
    names.join(", ")
}

/// The built-in scene files' text, embedded at compile time.
const BUILTIN_SOURCES: [(&str, &str); 5] = [
    ("teapot-room", include_str!("../../scenes/teapot-room.toml")),
    (
        "glass-sphere",
        include_str!("../../scenes/glass-sphere.toml"),
    ),
    (
        "mirror-teapot",
        include_str!("../../scenes/mirror-teapot.toml"),
    ),
    (
        "glossy-studio",
        include_str!("../../scenes/glossy-studio.toml"),
    ),
    ("glossy-room", include_str!("../../scenes/glossy-room.toml")),
];

/// The text of built-in scene `name`, or `None` for an unknown name.
pub(crate) fn builtin_source(name: &str) -> Option<&'static str> {
    BUILTIN_SOURCES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, source)| *source)
}

/// A loaded scene: world-space meshes, materials, lights, the environment at infinity, the lens
/// objects, the camera and the view space.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// The scene's name (the file's `name`, else the file stem).
    pub name: String,
    /// Every object, in file order.
    pub objects: Vec<SceneObject>,
    /// Every material, in file order; objects refer to them by index.
    pub materials: Vec<Material>,
    /// Point lights.
    pub lights: Vec<PointLight>,
    /// Radiance from infinitely far away.
    pub environment: Environment,
    /// The lens objects (glass or mirror objects traced per vertex at run time), in file order,
    /// followed by one lens per glass or mirror object that no `[[lenses]]` entry names.
    pub lenses: Vec<LensObject>,
    /// The default camera.
    pub camera: Camera,
    /// The viewpoint samples for baking.
    pub view_space: ViewSpace,
    /// What loading accepted with a fallback, one line each naming the file and line (an OBJ's
    /// empty `usemtl`): a front end says them once.
    pub warnings: Vec<String>,
}

/// One object: a world-space mesh and its material.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    /// Unique name.
    pub name: String,
    /// The mesh in world space (metres).
    pub mesh: TriangleMesh,
    /// Index into [`Scene::materials`].
    pub material: usize,
}

/// A lens object: the glass or mirror objects that are ray traced together as one local system.
#[derive(Clone, Debug, PartialEq)]
pub struct LensObject {
    /// Unique name.
    pub name: String,
    /// Indices into [`Scene::objects`]; each object is in at most one lens, and all are glass or
    /// mirror.
    pub objects: Vec<usize>,
    /// The layered EM's shells, nearest first, centred on the lens object's centroid (its EM
    /// origin). Empty: the runtime places one sphere itself.
    pub layers: Vec<LayerSpec>,
    /// How a bake splits its rays between layers (`layering` in the scene file): by hit
    /// distance (the default), or by bounce, the PEM paper's local and distant layers, whose
    /// shells the baker fits (a reflector's, so `layers` is then empty).
    pub layering: crate::layers::Layering,
    /// The path classes a hybrid frame shades it with (`terms` in the scene file), unless the
    /// frame's options say otherwise ([`crate::hybrid::ShadingTerms`]); `None`: the papers' two
    /// greedy terms.
    pub terms: Option<crate::trace::classes::ClassSet>,
}

/// A layer shell of a lens object's layered EM, centred on the EM origin (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LayerSpec {
    /// A sphere of this radius.
    Sphere(f32),
    /// An infinite vertical (y-axis) cylinder of this radius.
    Cylinder(f32),
    /// An axis-aligned box with these half extents.
    Box(glam::Vec3),
    /// An axis-aligned ellipsoid with these radii.
    Ellipsoid(glam::Vec3),
}

impl Scene {
    /// Loads a scene file. Relative asset paths start at the file's folder.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::Read {
            file: path.to_path_buf(),
            problem: format!("cannot read the scene file ({e})"),
            fix: format!(
                "check the path, or name a built-in scene: {}",
                builtin_names()
            ),
        })?;
        Scene::from_toml_str(&text, path)
    }

    /// Parses a scene from TOML text. `origin` is the path of the file it came from: messages
    /// name it and relative asset paths start at its folder.
    pub fn from_toml_str(text: &str, origin: &Path) -> Result<Scene, SceneError> {
        load::scene_from_toml(text, origin)
    }

    /// The scene's bake identity: a hash of everything a bake depends on, the objects (names,
    /// world-space meshes, materials), the lights, the environment, the lens objects (with their
    /// layer specs), the view space and the camera's aim (look-at, up, field of view: the
    /// viewpoint samples look where the camera looks). Not the camera's position, resolution or
    /// supersampling, and not the name. The canonical encoding of [`crate::identity`] (values as
    /// bits, in a fixed order), so the same scene content gives the same hash on any build of the
    /// same [`crate::identity::IDENTITY_VERSION`].
    pub fn content_hash(&self) -> String {
        let Camera {
            look_at,
            up,
            vfov_radians,
            ..
        } = &self.camera;
        let mut encoder = crate::identity::Encoder::new("scene");
        encoder
            .value(&self.objects)
            .value(&self.materials)
            .value(&self.lights)
            .value(&self.environment)
            .value(&self.lenses)
            .value(&self.view_space)
            .value(look_at)
            .value(up)
            .value(vfov_radians);
        encoder.finish()
    }

    /// A built-in scene by name (see [`BUILTIN_SCENES`]), or `None` for an unknown name.
    pub fn builtin(name: &str) -> Option<Result<Scene, SceneError>> {
        let text = builtin_source(name)?;
        let origin = PathBuf::from(format!("engine/scenes/{name}.toml"));
        Some(Scene::from_toml_str(text, &origin))
    }

    /// A built-in scene if `name_or_path` names one, else the scene file at that path.
    pub fn load_named(name_or_path: &str) -> Result<Scene, SceneError> {
        if let Some(scene) = Scene::builtin(name_or_path) {
            return scene;
        }
        let path = Path::new(name_or_path);
        if !path.exists() {
            // "Did you mean": the built-in name nearest the one given, if it is near.
            let nearest = BUILTIN_SCENES
                .iter()
                .chain(&GLOSSY_SCENES)
                .map(|name| (strsim::damerau_levenshtein(name, name_or_path), *name))
                .min()
                .filter(|&(distance, _)| distance <= 3);
            let fix = match nearest {
                Some((_, name)) => format!(
                    "did you mean {name}? Name a built-in scene ({}) or the path of a scene .toml file",
                    builtin_names()
                ),
                None => format!(
                    "name a built-in scene ({}) or the path of a scene .toml file",
                    builtin_names()
                ),
            };
            return Err(SceneError::Read {
                file: path.to_path_buf(),
                problem: "not a built-in scene and no such file".to_owned(),
                fix,
            });
        }
        Scene::load(path)
    }

    /// The camera moved to viewpoint sample `i` of the view space (looking at the camera's
    /// `look_at`), or `None` when there is no such sample.
    pub fn camera_at_view(&self, i: usize) -> Option<Camera> {
        let position = *self.view_space.samples().get(i)?;
        Some(self.camera.with_position(position))
    }

    /// The material of object `object`.
    pub fn material_of(&self, object: usize) -> &Material {
        &self.materials[self.objects[object].material]
    }

    /// The lens (index into [`Scene::lenses`]) that object `object` belongs to, if any.
    pub fn lens_of_object(&self, object: usize) -> Option<usize> {
        self.lenses
            .iter()
            .position(|lens| lens.objects.contains(&object))
    }

    /// Total triangle count over all objects.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.triangle_count()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn load(name: &str) -> Scene {
        match Scene::builtin(name) {
            Some(Ok(scene)) => scene,
            Some(Err(e)) => panic!("{e}"),
            None => panic!("{name} is not built in"),
        }
    }

    #[test]
    fn the_glossy_scenes_load_with_two_glossy_objects_each() {
        for name in GLOSSY_SCENES {
            let scene = load(name);
            assert_eq!(scene.name, name);
            assert!(scene.lenses.is_empty());
            let glossy = crate::rsibr::glossy_objects(&scene);
            let names: Vec<&str> = glossy.iter().map(|g| g.name.as_str()).collect();
            assert_eq!(names, ["sphere", "teapot"], "{name}");
            for object in &glossy {
                // The maps' bounding spheres clear every other object.
                for other in scene.objects.iter().filter(|o| o.name != object.name) {
                    let nearest = other
                        .mesh
                        .positions
                        .iter()
                        .map(|p| p.as_dvec3().distance(object.centre))
                        .fold(f64::INFINITY, f64::min);
                    assert!(
                        nearest > object.radius,
                        "{name}: {} in {}",
                        other.name,
                        object.name
                    );
                }
            }
        }
    }

    #[test]
    fn every_builtin_scene_loads() {
        for name in BUILTIN_SCENES {
            let scene = load(name);
            assert_eq!(scene.name, name);
            assert!(!scene.lenses.is_empty());
            assert!(!scene.lights.is_empty());
            for object in &scene.objects {
                assert_eq!(object.mesh.check(), Ok(()), "{name}/{}", object.name);
                assert!(object.material < scene.materials.len());
            }
            for lens in &scene.lenses {
                for &o in &lens.objects {
                    assert!(scene.material_of(o).is_lens());
                }
            }
            // Sample 0 of every built-in view space is the default camera position.
            let first = scene.camera_at_view(0).map(|c| c.position);
            assert!(first.is_some_and(|p| p.distance(scene.camera.position) < 1e-3));
            assert!(scene.camera_at_view(scene.view_space.len()).is_none());
        }
        assert!(Scene::builtin("no-such-scene").is_none());
    }

    #[test]
    fn teapot_room_is_the_papers_scene() {
        let scene = load("teapot-room");
        let names: Vec<&str> = scene.lenses.iter().map(|l| l.name.as_str()).collect();
        assert_eq!(names, ["teapot", "cup"]);
        assert_eq!(scene.lenses[1].objects.len(), 2);
        // 45 viewpoints 8° apart, all at the same distance from the circle's axis.
        let samples = scene.view_space.samples();
        assert_eq!(samples.len(), 45);
        let chord = 2.0 * 2.6 * 4f32.to_radians().sin();
        for pair in samples.windows(2) {
            assert!((pair[0].distance(pair[1]) - chord).abs() < 1e-4);
        }
        let columns = scene
            .objects
            .iter()
            .filter(|o| o.name.starts_with("column"))
            .count();
        assert_eq!(columns, 8);
        let camera = scene.camera;
        assert_eq!(
            (camera.width, camera.height, camera.supersampling),
            (640, 480, 3)
        );
        let teapot = &scene.objects[scene.lenses[0].objects[0]].mesh;
        assert!((2000..8000).contains(&teapot.triangle_count()));
        // The teapot (scale 0.25) stands on the floor at the origin.
        let (lo, hi) = teapot.bounds().unwrap_or_default();
        assert!(
            lo.y.abs() < 1e-5 && (hi.y - 0.7875).abs() < 1e-4,
            "{lo} {hi}"
        );
        // The camera frames the teapot: its centre projects inside the image.
        let centre = camera.view_proj(0.1, 100.0).project_point3((lo + hi) * 0.5);
        assert!(centre.x.abs() < 0.5 && centre.y.abs() < 0.5, "{centre}");
    }

    #[test]
    fn glass_sphere_and_mirror_teapot_have_their_lenses() {
        let sphere = load("glass-sphere");
        assert!(matches!(
            sphere.material_of(sphere.lenses[0].objects[0]),
            Material::Glass { ior, .. } if (*ior - 1.5).abs() < 1e-6
        ));
        let mesh = &sphere.objects[sphere.lenses[0].objects[0]].mesh;
        for p in &mesh.positions {
            assert!((p.distance(Vec3::new(0.0, 1.2, 0.0)) - 1.0).abs() < 1e-5);
        }
        let mirror = load("mirror-teapot");
        assert_eq!(mirror.lenses.len(), 2);
        assert_eq!(mirror.view_space.len(), 100);
        assert!(
            mirror
                .lenses
                .iter()
                .all(|l| matches!(mirror.material_of(l.objects[0]), Material::Mirror { .. }))
        );
    }

    /// The camera of the test scenes, an inline table before any other table.
    const CAMERA: &str = "camera = { position = [0, 1, 5], look_at = [0, 1, 0], vfov_degrees = 45, width = 64, height = 48 }";

    /// The scene of `text`, said to come from `origin`; a test failure if it does not load.
    fn parse(text: &str, origin: &str) -> Scene {
        Scene::from_toml_str(text, Path::new(origin)).unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn minimal_scene_with_defaults() {
        let text = r#"
            [[materials]]
            name = "glass"
            glass = { ior = 1.33 }

            [[objects]]
            name = "drop"
            material = "glass"
            sphere = { radius = 0.5 }
            transform = { translate = [0, 1, 0], scale = [1, 2, 1] }
        "#;
        let scene = parse(&format!("{CAMERA}{text}"), "dir/minimal.toml");
        assert_eq!(scene.name, "minimal");
        assert_eq!(scene.camera.up, Vec3::Y);
        assert_eq!(scene.camera.supersampling, 1);
        assert_eq!(scene.environment, Environment::Constant(Vec3::ZERO));
        assert_eq!(
            scene.view_space,
            ViewSpace::List(vec![Vec3::new(0.0, 1.0, 5.0)])
        );
        // An unlisted glass object becomes a lens of its own.
        assert_eq!(
            scene.lenses,
            vec![LensObject {
                name: "drop".into(),
                objects: vec![0],
                layers: Vec::new(),
                layering: crate::layers::Layering::Distance,
                terms: None,
            }]
        );
        assert_eq!(scene.lens_of_object(0), Some(0));
        let (lo, hi) = scene.objects[0].mesh.bounds().unwrap_or_default();
        assert!((lo.y - 0.0).abs() < 1e-5 && (hi.y - 2.0).abs() < 1e-5);
        assert!(
            matches!(scene.materials[0], Material::Glass { absorption, .. } if absorption == Vec3::ONE)
        );
    }

    #[test]
    fn rotations_apply_x_then_y_then_z() {
        // A 1×1 plane (normal +y) turned 90° about x faces +z; then 90° about y faces +x.
        let text = r#"
            [[materials]]
            name = "grey"
            diffuse = { colour = [0.5, 0.5, 0.5] }
            [[objects]]
            name = "a"
            material = "grey"
            plane = { size = [1, 1] }
            transform = { rotate_degrees = [90, 0, 0] }
            [[objects]]
            name = "b"
            material = "grey"
            plane = { size = [1, 1] }
            transform = { rotate_degrees = [90, 90, 0] }
        "#;
        let scene = parse(&format!("{CAMERA}{text}"), "rot.toml");
        assert!(scene.objects[0].mesh.normals[0].distance(Vec3::Z) < 1e-6);
        assert!(scene.objects[1].mesh.normals[0].distance(Vec3::X) < 1e-6);
        assert!(scene.lenses.is_empty());
    }
}
