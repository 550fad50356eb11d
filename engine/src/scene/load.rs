//! Turning a parsed scene file into a [`Scene`]: every value checked, assets loaded, meshes built
//! and moved to world space. Each failure is one [`SceneError`] naming the field and a fix.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Affine3A, Mat3, Vec2, Vec3};

use super::camera::{Camera, ViewSpace};
use super::environment::{Environment, LatLongMap, PointLight};
use super::error::SceneError;
use super::file::{
    CameraSpec, CircleSpec, DiffuseSpec, EnvironmentSpec, MaterialSpec, ObjectSpec, ScaleSpec,
    SceneFile, TransformSpec, ViewSpaceSpec,
};
use super::image_file::load_linear_rgb;
use super::material::{ImageTexture, Material, Texture};
use super::mesh::{MeshProblem, TriangleMesh};
use super::teapot::TeapotPart;
use super::{LayerSpec, LensObject, Scene, SceneObject, obj, shapes, teapot};

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
}

type Result<T> = std::result::Result<T, SceneError>;

/// Parses and checks a scene. `origin` is the scene file's path (messages name it; relative asset
/// paths start from its folder).
pub(crate) fn scene_from_toml(text: &str, origin: &Path) -> Result<Scene> {
    let parsed: SceneFile =
        toml::from_str(text).map_err(|e| SceneError::from_toml(origin, text, &e))?;
    let base = origin.parent().map_or_else(PathBuf::new, Path::to_path_buf);
    let loader = Loader { file: origin, base };
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

    /// An asset path resolved against the scene file's folder.
    fn resolve(&self, path: &str) -> PathBuf {
        let path = Path::new(path);
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            self.base.join(path)
        }
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
        let camera = self.camera(&file.camera)?;
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
            Some(spec) => self.view_space(spec)?,
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
        })
    }

    fn finite(&self, field: &str, value: f32) -> Result<f32> {
        if value.is_finite() {
            Ok(value)
        } else {
            Err(self.error(
                field,
                format!("{value} is not a finite number"),
                "give a finite number",
            ))
        }
    }

    fn positive(&self, field: &str, value: f32, unit: &str) -> Result<f32> {
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(self.error(
                field,
                format!("{value} is not a positive number"),
                format!("give a value > 0 ({unit})"),
            ))
        }
    }

    fn finite_vec3(&self, field: &str, value: [f32; 3]) -> Result<Vec3> {
        let v = Vec3::from_array(value);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(
                field,
                format!("{value:?} has a non-finite component"),
                "give three finite numbers",
            ))
        }
    }

    /// A finite position within [`MAX_SCENE_METRES`] of the origin.
    fn point(&self, field: &str, value: [f32; 3]) -> Result<Vec3> {
        let v = self.finite_vec3(field, value)?;
        self.within_scene(field, v)?;
        Ok(v)
    }

    /// `position` lies within [`MAX_SCENE_METRES`] of the origin along every axis.
    fn within_scene(&self, field: &str, position: Vec3) -> Result<()> {
        if position.abs().max_element() <= MAX_SCENE_METRES {
            Ok(())
        } else {
            Err(self.error(
                field,
                format!(
                    "{position} lies {:.3e} m from the origin along an axis, farther than {MAX_SCENE_METRES:e} m",
                    position.abs().max_element()
                ),
                format!("keep the scene within {MAX_SCENE_METRES:e} m of the origin (units are metres)"),
            ))
        }
    }

    /// Every finite vertex of `mesh` within [`MAX_SCENE_METRES`] of the origin; `what` says
    /// whose vertices they are. Non-finite vertices are left to [`TriangleMesh::check`].
    fn mesh_within_scene(&self, field: &str, mesh: &TriangleMesh, what: &str) -> Result<()> {
        let far = |p: &Vec3| p.is_finite() && p.abs().max_element() > MAX_SCENE_METRES;
        match mesh.positions.iter().position(far) {
            None => Ok(()),
            Some(vertex) => Err(self.error(
                field,
                format!(
                    "{what} vertex {vertex} (0-based) lies {:.3e} m from the origin along an axis, farther than {MAX_SCENE_METRES:e} m",
                    mesh.positions[vertex].abs().max_element()
                ),
                format!("keep the scene within {MAX_SCENE_METRES:e} m of the origin (units are metres): use smaller sizes, scale or translate"),
            )),
        }
    }

    /// A linear rgb colour ≥ 0, and ≤ `max` when given (an albedo or reflectance), else ≤
    /// [`MAX_RADIANCE`] (a radiance or intensity).
    fn colour(&self, field: &str, value: [f32; 3], max: Option<f32>) -> Result<Vec3> {
        let v = Vec3::from_array(value);
        let limit = max.unwrap_or(MAX_RADIANCE);
        let in_range = v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= limit;
        if in_range {
            return Ok(v);
        }
        let fix = match max {
            Some(max) => format!("give three numbers in [0, {max}] (linear rgb)"),
            None => format!("give three finite numbers in [0, {MAX_RADIANCE:e}] (linear rgb)"),
        };
        Err(self.error(field, format!("{value:?} is out of range"), fix))
    }

    /// Checks a built-in shape's triangle count against [`MAX_SHAPE_TRIANGLES`] before it is
    /// built; `field` names the count that sets it.
    fn triangle_budget(&self, field: &str, triangles: u64) -> Result<()> {
        if triangles <= MAX_SHAPE_TRIANGLES {
            Ok(())
        } else {
            Err(self.error(
                field,
                format!("makes {triangles} triangles, more than the {MAX_SHAPE_TRIANGLES} one shape may have"),
                "give fewer subdivisions or segments",
            ))
        }
    }

    fn count(&self, field: &str, value: u32, min: u32, max: u32) -> Result<u32> {
        if (min..=max).contains(&value) {
            Ok(value)
        } else {
            Err(self.error(
                field,
                format!("{value} is out of range"),
                format!("give a whole number in [{min}, {max}]"),
            ))
        }
    }

    fn camera(&self, spec: &CameraSpec) -> Result<Camera> {
        let position = self.point("camera.position", spec.position)?;
        let look_at = self.point("camera.look_at", spec.look_at)?;
        let up = self.finite_vec3("camera.up", spec.up)?;
        let vfov = spec.vfov_degrees;
        if !(vfov.is_finite() && vfov > 0.0 && vfov < 180.0) {
            return Err(self.error(
                "camera.vfov_degrees",
                format!("{vfov}° is not a field of view"),
                "give degrees in (0, 180), e.g. 45",
            ));
        }
        for (field, value) in [("camera.width", spec.width), ("camera.height", spec.height)] {
            if value == 0 {
                return Err(self.error(
                    field,
                    "the resolution is zero",
                    "give at least 1 pixel, e.g. width = 640, height = 480",
                ));
            }
        }
        if spec.supersampling == 0 {
            return Err(self.error(
                "camera.supersampling",
                "k = 0 gives no samples per pixel",
                "give k ≥ 1 (k×k samples per pixel, 1 = none)",
            ));
        }
        let camera = Camera {
            position,
            look_at,
            up: up.normalize_or_zero(),
            vfov_radians: vfov.to_radians(),
            width: spec.width,
            height: spec.height,
            supersampling: spec.supersampling,
        };
        self.check_view("camera", &camera)?;
        Ok(camera)
    }

    /// A camera must look somewhere, with an up direction not along the view direction.
    fn check_view(&self, field: &str, camera: &Camera) -> Result<()> {
        let view = camera.look_at - camera.position;
        if view.length() <= CAMERA_EPSILON {
            let what = if field == "camera" {
                "camera.look_at".to_owned()
            } else {
                field.to_owned()
            };
            return Err(self.error(
                what,
                format!(
                    "the position {} equals look_at {}",
                    camera.position, camera.look_at
                ),
                "move the position or look_at so that they differ",
            ));
        }
        if camera.up.length() <= CAMERA_EPSILON
            || view.normalize().cross(camera.up).length() <= CAMERA_EPSILON
        {
            let what = if field == "camera" {
                "camera.up".to_owned()
            } else {
                field.to_owned()
            };
            return Err(self.error(what, format!("up {} is zero or parallel to the view direction {}", camera.up, view.normalize()), "give an up direction that is not along look_at − position, e.g. [0, 1, 0] or [0, 0, -1] when looking straight down"));
        }
        Ok(())
    }

    fn environment(&self, spec: &EnvironmentSpec) -> Result<Environment> {
        match (&spec.constant, &spec.latlong) {
            (Some(colour), None) => Ok(Environment::Constant(self.colour(
                "environment.constant",
                *colour,
                None,
            )?)),
            (None, Some(latlong)) => {
                let scale = spec_scale(self, latlong.scale)?;
                let path = self.resolve(&latlong.path);
                let image = load_linear_rgb(&path).map_err(|problem| {
                    self.error("environment.latlong.path", format!("{}: {problem}", path.display()), "give a readable lat-long EXR with finite, non-negative radiance (relative paths start at the scene file's folder)")
                })?;
                let brightest = image
                    .texels
                    .iter()
                    .map(|t| t.max_element())
                    .fold(0.0, f32::max);
                if brightest * scale > MAX_RADIANCE {
                    let field = if brightest > MAX_RADIANCE {
                        "environment.latlong.path"
                    } else {
                        "environment.latlong.scale"
                    };
                    return Err(self.error(
                        field,
                        format!(
                            "{}: the brightest texel {brightest:e} times scale {scale} is beyond the {MAX_RADIANCE:e} a radiance may be",
                            path.display()
                        ),
                        "give a smaller scale, or divide the image's texels",
                    ));
                }
                Ok(Environment::LatLong(LatLongMap {
                    width: image.width,
                    height: image.height,
                    texels: image.texels.into_iter().map(|t| t * scale).collect(),
                }))
            }
            _ => Err(self.error(
                "environment",
                "needs exactly one of constant or latlong",
                "write either constant = [r, g, b] or latlong = { path = \"sky.exr\" }",
            )),
        }
    }

    fn materials(&self, specs: &[MaterialSpec]) -> Result<(Vec<Material>, HashMap<String, usize>)> {
        let mut index = HashMap::new();
        let mut materials = Vec::with_capacity(specs.len());
        for (i, spec) in specs.iter().enumerate() {
            let field = format!("materials[{i}]");
            if spec.name.trim().is_empty() {
                return Err(self.error(
                    format!("{field}.name"),
                    "the name is empty",
                    "give the material a name",
                ));
            }
            if index.insert(spec.name.clone(), i).is_some() {
                return Err(self.error(
                    format!("{field}.name"),
                    format!("the name \"{}\" is used twice", spec.name),
                    "give every material its own name",
                ));
            }
            let material = match (&spec.glass, &spec.mirror, &spec.diffuse) {
                (Some(glass), None, None) => {
                    let ior = glass.ior;
                    if !(ior.is_finite() && ior > 0.0) {
                        return Err(self.error(
                            format!("{field}.glass.ior"),
                            format!("index of refraction {ior} is not > 0"),
                            "give the glass's index of refraction, e.g. 1.5",
                        ));
                    }
                    let absorption = Vec3::from_array(glass.absorption);
                    if !(absorption.is_finite()
                        && absorption.min_element() > 0.0
                        && absorption.max_element() <= 1.0)
                    {
                        return Err(self.error(format!("{field}.glass.absorption"), format!("{:?} is outside (0, 1]", glass.absorption), "give the transmittance per metre per channel in (0, 1] (1 = clear glass)"));
                    }
                    Material::Glass { ior, absorption }
                }
                (None, Some(mirror), None) => Material::Mirror {
                    reflectance: self.colour(
                        &format!("{field}.mirror.reflectance"),
                        mirror.reflectance,
                        Some(1.0),
                    )?,
                },
                (None, None, Some(diffuse)) => {
                    self.diffuse(&format!("{field}.diffuse"), diffuse)?
                }
                _ => {
                    return Err(self.error(
                        &field,
                        format!(
                            "material \"{}\" needs exactly one of glass, mirror or diffuse",
                            spec.name
                        ),
                        "keep one of glass = { ... }, mirror = { ... }, diffuse = { ... }",
                    ));
                }
            };
            materials.push(material);
        }
        Ok((materials, index))
    }

    fn diffuse(&self, field: &str, spec: &DiffuseSpec) -> Result<Material> {
        let texture = match (&spec.checker, &spec.image) {
            (Some(checker), None) => Some(Texture::Checker {
                a: self.colour(&format!("{field}.checker.a"), checker.a, Some(1.0))?,
                b: self.colour(&format!("{field}.checker.b"), checker.b, Some(1.0))?,
                scale: self.positive(
                    &format!("{field}.checker.scale"),
                    checker.scale,
                    "squares per uv unit",
                )?,
            }),
            (None, Some(image)) => {
                let path = self.resolve(image);
                let image = load_linear_rgb(&path).map_err(|problem| {
                    self.error(format!("{field}.image"), format!("{}: {problem}", path.display()), "give a readable PNG or EXR with finite, non-negative texels (relative paths start at the scene file's folder)")
                })?;
                Some(Texture::Image(ImageTexture {
                    width: image.width,
                    height: image.height,
                    texels: image.texels,
                }))
            }
            (None, None) => None,
            (Some(_), Some(_)) => {
                return Err(self.error(field, "has both checker and image", "keep one texture"));
            }
        };
        let colour = match spec.colour {
            Some(colour) => self.colour(&format!("{field}.colour"), colour, Some(1.0))?,
            None if texture.is_some() => Vec3::ONE,
            None => {
                return Err(self.error(field, "has neither colour nor a texture", "add colour = [r, g, b] (albedo in [0, 1]), checker = { ... } or image = \"file.png\""));
            }
        };
        Ok(Material::Diffuse { colour, texture })
    }

    fn objects(
        &self,
        specs: &[ObjectSpec],
        materials: &[Material],
        material_index: &HashMap<String, usize>,
    ) -> Result<Vec<SceneObject>> {
        let mut names = HashMap::new();
        let mut objects = Vec::with_capacity(specs.len());
        for (i, spec) in specs.iter().enumerate() {
            let field = format!("objects[{i}]");
            if spec.name.trim().is_empty() {
                return Err(self.error(
                    format!("{field}.name"),
                    "the name is empty",
                    "give the object a name",
                ));
            }
            if names.insert(spec.name.clone(), i).is_some() {
                return Err(self.error(
                    format!("{field}.name"),
                    format!("the name \"{}\" is used twice", spec.name),
                    "give every object its own name",
                ));
            }
            let Some(&material) = material_index.get(&spec.material) else {
                let known: Vec<&str> = material_index.keys().map(String::as_str).collect();
                return Err(self.error(
                    format!("{field}.material"),
                    format!("no material is named \"{}\"", spec.material),
                    format!("name one of the [[materials]]: {}", sorted_list(known)),
                ));
            };
            debug_assert!(material < materials.len());
            let mut mesh = self.mesh(&field, spec)?;
            self.mesh_within_scene(
                &format!("{field}.{}", mesh_field(spec)),
                &mesh,
                "the mesh's",
            )?;
            if spec.inside_out {
                mesh.flip();
            }
            let transform = self.transform(&format!("{field}.transform"), &spec.transform)?;
            mesh.transform(&transform);
            self.mesh_within_scene(
                &format!("{field}.transform"),
                &mesh,
                "the transformed mesh's",
            )?;
            if let Err(problem) = mesh.check() {
                return Err(self.error(
                    format!("{field}.transform"),
                    format!("the transformed mesh is broken: {problem}"),
                    "use a smaller or non-degenerate transform",
                ));
            }
            objects.push(SceneObject {
                name: spec.name.clone(),
                mesh,
                material,
            });
        }
        Ok(objects)
    }

    /// The object's mesh in its local frame.
    fn mesh(&self, field: &str, spec: &ObjectSpec) -> Result<TriangleMesh> {
        let kinds = [
            spec.obj.is_some(),
            spec.plane.is_some(),
            spec.cuboid.is_some(),
            spec.sphere.is_some(),
            spec.cylinder.is_some(),
            spec.torus.is_some(),
            spec.teapot.is_some(),
        ];
        if kinds.iter().filter(|&&k| k).count() != 1 {
            return Err(self.error(
                field,
                format!("object \"{}\" needs exactly one mesh", spec.name),
                "keep one of obj, plane, box, sphere, cylinder, torus, teapot",
            ));
        }
        if let Some(obj) = &spec.obj {
            return self.obj_mesh(
                &format!("{field}.obj"),
                obj.path.as_str(),
                obj.smooth_normals,
                obj.drop_degenerate,
            );
        }
        let mesh = if let Some(plane) = &spec.plane {
            let f = format!("{field}.plane");
            let size = Vec2::new(
                self.positive(&format!("{f}.size"), plane.size[0], "metres")?,
                self.positive(&format!("{f}.size"), plane.size[1], "metres")?,
            );
            let subdivisions = self.count(
                &format!("{f}.subdivisions"),
                plane.subdivisions,
                1,
                MAX_SEGMENTS,
            )?;
            self.triangle_budget(
                &format!("{f}.subdivisions"),
                2 * u64::from(subdivisions).pow(2),
            )?;
            shapes::plane(size, subdivisions)
        } else if let Some(cuboid) = &spec.cuboid {
            let f = format!("{field}.box.size");
            let size = [0, 1, 2].map(|k| self.positive(&f, cuboid.size[k], "metres"));
            let [x, y, z] = size;
            shapes::cuboid(Vec3::new(x?, y?, z?))
        } else if let Some(sphere) = &spec.sphere {
            let f = format!("{field}.sphere");
            let radius = self.positive(&format!("{f}.radius"), sphere.radius, "metres")?;
            let segments =
                self.count(&format!("{f}.segments"), sphere.segments, 3, MAX_SEGMENTS)?;
            let rings = self.count(&format!("{f}.rings"), sphere.rings, 2, MAX_SEGMENTS)?;
            self.triangle_budget(
                &format!("{f}.segments"),
                2 * u64::from(segments) * u64::from(rings),
            )?;
            shapes::sphere(radius, segments, rings)
        } else if let Some(cylinder) = &spec.cylinder {
            let f = format!("{field}.cylinder");
            shapes::cylinder(
                self.positive(&format!("{f}.radius"), cylinder.radius, "metres")?,
                self.positive(&format!("{f}.height"), cylinder.height, "metres")?,
                self.count(&format!("{f}.segments"), cylinder.segments, 3, MAX_SEGMENTS)?,
                cylinder.caps,
            )
        } else if let Some(torus) = &spec.torus {
            let f = format!("{field}.torus");
            let major =
                self.positive(&format!("{f}.major_radius"), torus.major_radius, "metres")?;
            let minor =
                self.positive(&format!("{f}.minor_radius"), torus.minor_radius, "metres")?;
            if minor >= major {
                return Err(self.error(
                    format!("{f}.minor_radius"),
                    format!("{minor} ≥ major_radius {major} makes the tube intersect itself"),
                    "give minor_radius < major_radius",
                ));
            }
            let major_segments = self.count(
                &format!("{f}.major_segments"),
                torus.major_segments,
                3,
                MAX_SEGMENTS,
            )?;
            let minor_segments = self.count(
                &format!("{f}.minor_segments"),
                torus.minor_segments,
                3,
                MAX_SEGMENTS,
            )?;
            self.triangle_budget(
                &format!("{f}.major_segments"),
                2 * u64::from(major_segments) * u64::from(minor_segments),
            )?;
            shapes::torus(major, minor, major_segments, minor_segments)
        } else if let Some(teapot) = &spec.teapot {
            let f = format!("{field}.teapot");
            let level = self.count(
                &format!("{f}.tessellation"),
                teapot.tessellation,
                1,
                MAX_TESSELLATION,
            )?;
            let parts = match &teapot.parts {
                None => TeapotPart::ALL.to_vec(),
                Some(names) if names.is_empty() => {
                    return Err(self.error(
                        format!("{f}.parts"),
                        "the list of parts is empty",
                        "name at least one part, or remove parts for the whole teapot",
                    ));
                }
                Some(names) => names
                    .iter()
                    .enumerate()
                    .map(|(k, name)| {
                        TeapotPart::from_name(name).ok_or_else(|| {
                            let known: Vec<&str> =
                                TeapotPart::ALL.iter().map(|p| p.name()).collect();
                            self.error(
                                format!("{f}.parts[{k}]"),
                                format!("\"{name}\" is not a teapot part"),
                                format!("name parts among {}", known.join(", ")),
                            )
                        })
                    })
                    .collect::<Result<Vec<_>>>()?,
            };
            teapot::teapot_parts(level, &parts)
        } else {
            return Err(self.error(
                field,
                "has no mesh",
                "add one of obj, plane, box, sphere, cylinder, torus, teapot",
            ));
        };
        Ok(mesh)
    }

    fn obj_mesh(
        &self,
        field: &str,
        path: &str,
        smooth_normals: bool,
        drop_degenerate: bool,
    ) -> Result<TriangleMesh> {
        let resolved = self.resolve(path);
        let path_field = format!("{field}.path");
        if let Err(e) = std::fs::metadata(&resolved) {
            return Err(self.error(
                &path_field,
                format!("cannot read {} ({e})", resolved.display()),
                format!(
                    "check the path (relative paths start at the scene file's folder, {})",
                    display_dir(&self.base)
                ),
            ));
        }
        let mut mesh = obj::load_obj(&resolved, smooth_normals).map_err(|e| {
            self.error(
                &path_field,
                format!("{}: not a readable OBJ ({e})", resolved.display()),
                "export the mesh as a Wavefront OBJ with v/vn/vt/f records",
            )
        })?;
        // Before the check: a huge triangle's area overflows and would be called degenerate.
        self.mesh_within_scene(&path_field, &mesh, &format!("{}:", resolved.display()))?;
        let fix = "remove those triangles from the OBJ, or set drop_degenerate = true to have them dropped";
        match mesh.check() {
            Ok(()) => {}
            Err(MeshProblem::Degenerate { .. }) if drop_degenerate => {
                mesh.drop_degenerate();
                mesh.check().map_err(|problem| {
                    self.error(
                        &path_field,
                        format!("{}: {problem}", resolved.display()),
                        fix,
                    )
                })?;
            }
            Err(problem @ MeshProblem::Degenerate { .. }) => {
                return Err(self.error(
                    &path_field,
                    format!("{}: {problem}", resolved.display()),
                    fix,
                ));
            }
            Err(
                problem @ (MeshProblem::NonFinitePosition { .. }
                | MeshProblem::NonFiniteAttribute { .. }),
            ) => {
                return Err(self.error(&path_field, format!("{}: {problem}", resolved.display()), "replace the NaN/inf values in the OBJ's v, vn or vt records with finite numbers"));
            }
            Err(problem) => {
                return Err(self.error(
                    &path_field,
                    format!("{}: {problem}", resolved.display()),
                    "export the mesh again as a triangulated OBJ with faces",
                ));
            }
        }
        mesh.repair_normals();
        Ok(mesh)
    }

    /// M = T · Rz · Ry · Rx · S (scale first, then rotate about x, y, z in turn, then translate).
    fn transform(&self, field: &str, spec: &TransformSpec) -> Result<Affine3A> {
        let translate = self.finite_vec3(&format!("{field}.translate"), spec.translate)?;
        let rotate = self.finite_vec3(&format!("{field}.rotate_degrees"), spec.rotate_degrees)?;
        let scale = match spec.scale {
            ScaleSpec::Uniform(s) => Vec3::splat(s),
            ScaleSpec::PerAxis(s) => Vec3::from_array(s),
        };
        if !(scale.is_finite() && scale.abs().min_element() > 0.0) {
            return Err(self.error(
                format!("{field}.scale"),
                format!("{scale} has a zero or non-finite factor"),
                "give non-zero finite scale factors",
            ));
        }
        let rotation = Mat3::from_rotation_z(rotate.z.to_radians())
            * Mat3::from_rotation_y(rotate.y.to_radians())
            * Mat3::from_rotation_x(rotate.x.to_radians());
        Ok(Affine3A::from_mat3_translation(
            rotation * Mat3::from_diagonal(scale),
            translate,
        ))
    }

    fn lenses(
        &self,
        file: &SceneFile,
        objects: &[SceneObject],
        materials: &[Material],
    ) -> Result<Vec<LensObject>> {
        let object_index: HashMap<&str, usize> = objects
            .iter()
            .enumerate()
            .map(|(i, o)| (o.name.as_str(), i))
            .collect();
        let mut owner: Vec<Option<usize>> = vec![None; objects.len()];
        let mut lenses: Vec<LensObject> = Vec::new();
        for (l, spec) in file.lenses.iter().enumerate() {
            let field = format!("lenses[{l}]");
            if spec.name.trim().is_empty() {
                return Err(self.error(
                    format!("{field}.name"),
                    "the name is empty",
                    "give the lens object a name",
                ));
            }
            if lenses.iter().any(|lens| lens.name == spec.name) {
                return Err(self.error(
                    format!("{field}.name"),
                    format!("the name \"{}\" is used twice", spec.name),
                    "give every lens object its own name",
                ));
            }
            if spec.objects.is_empty() {
                return Err(self.error(
                    format!("{field}.objects"),
                    "the lens has no objects",
                    "name the glass or mirror [[objects]] that form it",
                ));
            }
            let mut members = Vec::with_capacity(spec.objects.len());
            for (k, name) in spec.objects.iter().enumerate() {
                let member_field = format!("{field}.objects[{k}]");
                let Some(&object) = object_index.get(name.as_str()) else {
                    return Err(self.error(
                        member_field,
                        format!("no object is named \"{name}\""),
                        format!(
                            "name one of the [[objects]]: {}",
                            sorted_list(object_index.keys().copied().collect())
                        ),
                    ));
                };
                if !materials[objects[object].material].is_lens() {
                    return Err(self.error(member_field, format!("object \"{name}\" is diffuse, but a lens is made of glass or mirror objects"), "give the object a glass or mirror material, or leave it out of the lens"));
                }
                if let Some(other) = owner[object] {
                    return Err(self.error(
                        member_field,
                        format!(
                            "object \"{name}\" is already part of lens \"{}\"",
                            file.lenses[other].name
                        ),
                        "put each object in one lens only",
                    ));
                }
                owner[object] = Some(l);
                members.push(object);
            }
            let mut layers = Vec::with_capacity(spec.layers.len());
            for (k, layer) in spec.layers.iter().enumerate() {
                let layer_field = format!("{field}.layers[{k}]");
                let positive = |v: f32| v.is_finite() && v > 0.0;
                let parsed = match (
                    layer.sphere,
                    layer.cylinder,
                    layer.box_half_extents,
                    layer.ellipsoid,
                ) {
                    (Some(r), None, None, None) if positive(r) => LayerSpec::Sphere(r),
                    (None, Some(r), None, None) if positive(r) => LayerSpec::Cylinder(r),
                    (None, None, Some(h), None) if h.iter().all(|v| positive(*v)) => {
                        LayerSpec::Box(Vec3::from(h))
                    }
                    (None, None, None, Some(r)) if r.iter().all(|v| positive(*v)) => {
                        LayerSpec::Ellipsoid(Vec3::from(r))
                    }
                    _ => {
                        return Err(self.error(
                            layer_field,
                            "a layer needs exactly one of sphere, cylinder, box, ellipsoid with positive finite sizes",
                            "write e.g. { sphere = 3.0 }, { cylinder = 6.0 }, { box = [8, 4, 8] } or { ellipsoid = [2, 1, 2] } (metres)",
                        ));
                    }
                };
                layers.push(parsed);
            }
            lenses.push(LensObject {
                name: spec.name.clone(),
                objects: members,
                layers,
            });
        }
        // Glass and mirror objects that no lens names become lenses of their own.
        for (i, object) in objects.iter().enumerate() {
            if owner[i].is_none() && materials[object.material].is_lens() {
                if lenses.iter().any(|lens| lens.name == object.name) {
                    return Err(self.error(format!("objects[{i}]"), format!("glass/mirror object \"{}\" is in no lens, and a lens with its name already exists", object.name), "add the object to a [[lenses]] entry"));
                }
                lenses.push(LensObject {
                    name: object.name.clone(),
                    objects: vec![i],
                    layers: Vec::new(),
                });
            }
        }
        Ok(lenses)
    }

    fn view_space(&self, spec: &ViewSpaceSpec) -> Result<ViewSpace> {
        match (&spec.circle, &spec.list) {
            (Some(circle), None) => self.circle(circle),
            (None, Some(list)) => {
                if list.is_empty() {
                    return Err(self.error("view_space.list", "the list of viewpoints is empty", "give at least one position [x, y, z]"));
                }
                if list.len() > MAX_VIEWPOINT_SAMPLES as usize {
                    return Err(self.error("view_space.list", format!("{} viewpoint samples, more than the {MAX_VIEWPOINT_SAMPLES} a view space may have", list.len()), "give fewer samples"));
                }
                let positions = list
                    .iter()
                    .enumerate()
                    .map(|(i, p)| self.finite_vec3(&format!("view_space.list[{i}]"), *p))
                    .collect::<Result<Vec<_>>>()?;
                Ok(ViewSpace::List(positions))
            }
            _ => Err(self.error("view_space", "needs exactly one of circle or list", "write circle = { centre, radius, height, start_degrees, step_degrees, count } or list = [[x, y, z], ...]")),
        }
    }

    fn circle(&self, spec: &CircleSpec) -> Result<ViewSpace> {
        let f = "view_space.circle";
        if spec.count == 0 {
            return Err(self.error(
                format!("{f}.count"),
                "a view space with 0 viewpoint samples",
                "give count ≥ 1 (e.g. 45 samples 8° apart close the circle)",
            ));
        }
        if spec.count > MAX_VIEWPOINT_SAMPLES {
            return Err(self.error(
                format!("{f}.count"),
                format!("{} viewpoint samples, more than the {MAX_VIEWPOINT_SAMPLES} a view space may have", spec.count),
                "give fewer samples (45 samples 8° apart close the circle)",
            ));
        }
        let step = self.finite(&format!("{f}.step_degrees"), spec.step_degrees)?;
        if step == 0.0 && spec.count > 1 {
            return Err(self.error(
                format!("{f}.step_degrees"),
                "0° steps put every sample at the same place",
                "give a non-zero step, e.g. 8",
            ));
        }
        Ok(ViewSpace::Circle {
            centre: self.finite_vec3(&format!("{f}.centre"), spec.centre)?,
            radius: self.positive(&format!("{f}.radius"), spec.radius, "metres")?,
            height: self.finite(&format!("{f}.height"), spec.height)?,
            start_radians: self
                .finite(&format!("{f}.start_degrees"), spec.start_degrees)?
                .to_radians(),
            step_radians: step.to_radians(),
            count: spec.count,
        })
    }
}

/// The field of an object's mesh that sets its size: what a mesh too large is reported at.
fn mesh_field(spec: &ObjectSpec) -> &'static str {
    if spec.obj.is_some() {
        "obj.path"
    } else if spec.plane.is_some() {
        "plane.size"
    } else if spec.cuboid.is_some() {
        "box.size"
    } else if spec.sphere.is_some() {
        "sphere.radius"
    } else if spec.cylinder.is_some() {
        "cylinder"
    } else if spec.torus.is_some() {
        "torus.major_radius"
    } else {
        "teapot"
    }
}

/// Checks a lat-long scale factor.
fn spec_scale(loader: &Loader<'_>, scale: f32) -> Result<f32> {
    if scale.is_finite() && scale >= 0.0 {
        Ok(scale)
    } else {
        Err(loader.error(
            "environment.latlong.scale",
            format!("{scale} is not a finite number ≥ 0"),
            "give a radiance multiplier ≥ 0 (1 = as stored)",
        ))
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
