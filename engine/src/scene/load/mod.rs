//! Turning a parsed scene file into a [`Scene`]: every value checked, assets loaded, meshes built
//! and moved to world space. Each failure is one [`SceneError`] naming the field and a fix. The
//! loader's checks are split by what they load: plain values, the camera and view space, the
//! environment and materials, the objects and their meshes, and the lens objects.

mod lenses;
mod materials;
mod objects;
mod values;
mod view;

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::Scene;
use super::camera::ViewSpace;
use super::environment::{Environment, PointLight};
use super::error::SceneError;
use super::file::SceneFile;

/// Largest teapot tessellation level accepted (64 → 262k triangles).
const MAX_TESSELLATION: u32 = 64;
/// Largest segment count of the round shapes.
const MAX_SEGMENTS: u32 = 4096;
/// Most triangles one built-in shape may have (2 million: a few hundred MB with its BVH);
/// checked before the shape is built, so a large subdivision count is an error, not an abort.
pub const MAX_SHAPE_TRIANGLES: u64 = 2_000_000;
/// Most viewpoint samples a view space may have (each is a bake of every lens object).
pub const MAX_VIEWPOINT_SAMPLES: u32 = 10_000;
/// Farthest from the origin, in metres along any axis, that a vertex of an object, the camera,
/// its look-at point or a viewpoint sample may lie (the limit the ray tracer's cameras keep):
/// f32 positions there are still 6 cm apart, and every size, area and product the BVH, light-map
/// atlas and projection compute from them stays finite. Checked at load, naming the field, so a
/// huge number is an error and not a panic, a NaN or a message about an internal buffer later.
pub const MAX_SCENE_METRES: f32 = crate::trace::image::MAX_CAMERA_METRES;
/// Largest radiance (environment) or radiant intensity (lights) component accepted: far above
/// any physical value, and small enough that the sums the renderer forms from them (mip levels
/// average four texels) stay finite in f32, so a huge number is refused here, naming its field.
pub const MAX_RADIANCE: f32 = 1e30;
/// Smallest accepted distance between a camera and its look-at point, and the smallest sine of
/// the angle between the view direction and `up`.
const CAMERA_EPSILON: f32 = 1e-6;

/// The loading context: the scene file (for messages) and the folder relative paths start from.
struct Loader<'a> {
    file: &'a Path,
    base: PathBuf,
    /// The scene's warnings so far ([`Scene::warnings`]).
    warnings: std::cell::RefCell<Vec<String>>,
}

type Result<T> = std::result::Result<T, SceneError>;

/// Parses and checks a scene. `origin` is the scene file's path (messages name it; relative asset
/// paths start from its folder).
pub(crate) fn scene_from_toml(text: &str, origin: &Path) -> Result<Scene> {
    let parsed: SceneFile =
        toml::from_str(text).map_err(|e| SceneError::from_toml(origin, text, &e))?;
    let base = origin.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let loader = Loader {
        file: origin,
        base,
        warnings: Default::default(),
    };
    let parsed = match parsed.extends.clone() {
        Some(name) => loader.extended(&name, parsed, text)?,
        None => parsed,
    };
    loader.scene(parsed)
}

impl Loader<'_> {
    fn error(
        &self,
        field: impl std::fmt::Display,
        problem: impl std::fmt::Display,
        fix: impl std::fmt::Display,
    ) -> SceneError {
        SceneError::invalid(self.file, field, problem, fix)
    }

    /// Checks the name of `field` (`materials[2]`), an entry of a kind `what` names ("material"):
    /// not empty, and not `used` by an earlier entry.
    fn check_name(&self, field: &str, name: &str, used: bool, what: &str) -> Result<()> {
        if name.trim().is_empty() {
            return Err(self.error(
                format!("{field}.name"),
                "the name is empty",
                format!("give the {what} a name"),
            ));
        }
        if used {
            return Err(self.error(
                format!("{field}.name"),
                format!("the name \"{name}\" is used twice"),
                format!("give every {what} its own name"),
            ));
        }
        Ok(())
    }

    /// An asset path resolved against the scene file's folder.
    fn resolve(&self, path: &str) -> PathBuf {
        let path = Path::new(path);
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.base.join(path)
        }
    }

    /// The built-in scene `name` with every top-level key `file` (whose text is `text`) gives
    /// replacing the built-in's. The built-in scenes name no asset files, so no relative path
    /// changes meaning when a file in another folder extends one.
    fn extended(&self, name: &str, file: SceneFile, text: &str) -> Result<SceneFile> {
        let Some(source) = super::builtin_source(name) else {
            return Err(self.error(
                "extends",
                format!("\"{name}\" is not a built-in scene"),
                format!("give one of {}", super::builtin_names()),
            ));
        };
        let builtin: SceneFile = toml::from_str(source).map_err(|e| {
            SceneError::from_toml(Path::new(&format!("built-in scene {name}")), source, &e)
        })?;
        // The keys the file gives (it parsed as a scene file, so it parses as a table).
        let keys: toml::Table = toml::from_str(text).unwrap_or_default();
        let has = |key: &str| keys.contains_key(key);
        // Each top-level key the file gives replaces the built-in's whole.
        fn pick<T>(given: bool, file: T, builtin: T) -> T {
            if given { file } else { builtin }
        }
        Ok(SceneFile {
            extends: None,
            name: file.name,
            camera: pick(has("camera"), file.camera, builtin.camera),
            environment: pick(has("environment"), file.environment, builtin.environment),
            lights: pick(has("lights"), file.lights, builtin.lights),
            materials: pick(has("materials"), file.materials, builtin.materials),
            objects: pick(has("objects"), file.objects, builtin.objects),
            lenses: pick(has("lenses"), file.lenses, builtin.lenses),
            view_space: pick(has("view_space"), file.view_space, builtin.view_space),
        })
    }

    fn scene(&self, file: SceneFile) -> Result<Scene> {
        let name = match file.name.clone() {
            Some(name) if name.trim().is_empty() => {
                return Err(self.error(
                    "name",
                    "the scene name is empty",
                    "give a name or remove the field",
                ));
            }
            Some(name) => name,
            None => self
                .file
                .file_stem()
                .map_or_else(|| "scene".to_owned(), |s| s.to_string_lossy().into_owned()),
        };
        let Some(camera) = &file.camera else {
            return Err(self.error(
                "camera",
                "missing field `camera`",
                "add a [camera] table (the schema is in tools/scenes/README.md), or extend a built-in scene with extends = \"teapot-room\"",
            ));
        };
        let camera = self.camera(camera)?;
        let environment = match &file.environment {
            Some(spec) => self.environment(spec)?,
            None => Environment::Constant(Vec3::ZERO),
        };
        let lights = file
            .lights
            .iter()
            .enumerate()
            .map(|(i, light)| {
                let field = format!("lights[{i}]");
                Ok(PointLight {
                    position: self.finite_vec3(&format!("{field}.position"), light.position)?,
                    intensity: self.colour(&format!("{field}.intensity"), light.intensity, None)?,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        let (materials, material_index) = self.materials(&file.materials)?;
        let objects = self.objects(&file.objects, &materials, &material_index)?;
        let lenses = self.lenses(&file, &objects, &materials)?;
        let view_space = match &file.view_space {
            Some(spec) => self.view_space(spec, &camera)?,
            None => ViewSpace::List(vec![camera.position]),
        };
        for (i, sample) in view_space.samples().into_iter().enumerate() {
            self.within_scene(&format!("view_space sample {i}"), sample)?;
            self.check_view(
                &format!("view_space sample {i}"),
                &camera.with_position(sample),
            )?;
        }
        Ok(Scene {
            name,
            objects,
            materials,
            lights,
            environment,
            lenses,
            camera,
            view_space,
            warnings: self.warnings.take(),
        })
    }
}

/// `a, b, c` sorted, or `(none defined)`.
fn sorted_list(mut names: Vec<&str>) -> String {
    if names.is_empty() {
        return "(none defined)".to_owned();
    }
    names.sort_unstable();
    names.join(", ")
}

fn display_dir(dir: &Path) -> String {
    if dir.as_os_str().is_empty() {
        ".".to_owned()
    } else {
        dir.display().to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Environment, Material, Scene, Texture};
    use glam::{Vec2, Vec3};
    use std::path::PathBuf;

    fn temp_folder(test: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("lensmap-scene-load-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create a temporary folder");
        dir
    }

    const CAMERA: &str = "[camera]\nposition = [0, 1, 5]\nlook_at = [0, 1, 0]\nvfov_degrees = 45\nwidth = 8\nheight = 8\n";

    fn load(dir: &std::path::Path, text: &str) -> Scene {
        let path = dir.join("scene.toml");
        std::fs::write(&path, text).expect("write the scene");
        Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn obj_keeps_file_normals_and_uvs_and_is_transformed() {
        let dir = temp_folder("obj");
        std::fs::create_dir_all(dir.join("meshes")).expect("mkdir");
        // A unit quad in the xy plane facing +z, with a deliberately tilted file normal that must
        // survive (normals come from the file when present).
        let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                   vn 0 0 1\nvn 0 0.6 0.8\nf 1/1/1 2/2/1 3/3/2 4/4/1\n";
        std::fs::write(dir.join("meshes/quad.obj"), obj).expect("write the OBJ");
        let text = format!(
            "{CAMERA}[[materials]]\nname = \"m\"\ndiffuse = {{ colour = [0.5, 0.5, 0.5] }}\n\
             [[objects]]\nname = \"quad\"\nmaterial = \"m\"\nobj = {{ path = \"meshes/quad.obj\" }}\n\
             transform = {{ translate = [0, 0, -2], rotate_degrees = [0, 90, 0], scale = 2 }}\n"
        );
        let scene = load(&dir, &text);
        let mesh = &scene.objects[0].mesh;
        assert_eq!(mesh.triangle_count(), 2);
        assert_eq!(mesh.uvs.len(), mesh.positions.len());
        // Scaled by 2, turned 90° about y (+z → +x), moved to z = −2.
        let (lo, hi) = mesh.bounds().unwrap_or_default();
        assert!(lo.abs_diff_eq(Vec3::new(0.0, 0.0, -4.0), 1e-5), "{lo}");
        assert!(hi.abs_diff_eq(Vec3::new(0.0, 2.0, -2.0), 1e-5), "{hi}");
        assert!(mesh.normals.iter().any(|n| n.abs_diff_eq(Vec3::X, 1e-5)));
        assert!(
            mesh.normals
                .iter()
                .any(|n| n.abs_diff_eq(Vec3::new(0.8, 0.6, 0.0), 1e-5))
        );
    }

    #[test]
    fn png_textures_are_linearized_and_exr_environments_are_sampled() {
        let dir = temp_folder("images");
        // 2×1 sRGB PNG: 128 → 0.2158 linear, 255 → 1.
        let png = image::RgbImage::from_raw(2, 1, vec![128, 128, 128, 255, 255, 255]).expect("png");
        png.save(dir.join("t.png")).expect("write the PNG");
        // 4×2 lat-long EXR with distinct texels.
        let texels: Vec<f32> = (0..8).flat_map(|i| [i as f32, 0.5, 0.25]).collect();
        let exr = image::Rgb32FImage::from_raw(4, 2, texels).expect("exr");
        exr.save(dir.join("sky.exr")).expect("write the EXR");
        let text = format!(
            "{CAMERA}[environment]\nlatlong = {{ path = \"sky.exr\", scale = 2 }}\n\
             [[materials]]\nname = \"m\"\ndiffuse = {{ image = \"t.png\" }}\n"
        );
        let scene = load(&dir, &text);
        let Material::Diffuse {
            colour,
            texture: Some(Texture::Image(texture)),
        } = &scene.materials[0]
        else {
            panic!("{:?}", scene.materials[0]);
        };
        assert_eq!(*colour, Vec3::ONE);
        assert!(
            (texture.texels[0].x - 0.215_861).abs() < 1e-4,
            "{}",
            texture.texels[0]
        );
        assert!((texture.texels[1].x - 1.0).abs() < 1e-6);
        let Environment::LatLong(map) = &scene.environment else {
            panic!("{:?}", scene.environment);
        };
        // Texel (2, 1) at its centre, times the scale 2.
        let direction = super::super::lat_long_to_direction(Vec2::new(2.5 / 4.0, 1.5 / 2.0));
        let radiance = map.radiance(direction);
        assert!(
            radiance.abs_diff_eq(Vec3::new(12.0, 1.0, 0.5), 1e-4),
            "{radiance}"
        );
    }
}
