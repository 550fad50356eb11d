//! Loading the objects: each one's mesh (an OBJ file or a built-in shape, within its triangle
//! budget), its material and its transform to world space, checked before and after it moves.

use std::collections::HashMap;

use glam::{Affine3A, Mat3, Vec2, Vec3};

use super::{Loader, MAX_SEGMENTS, MAX_TESSELLATION, Result, display_dir, sorted_list};
use crate::scene::file::{ObjectSpec, ScaleSpec, TransformSpec};
use crate::scene::material::Material;
use crate::scene::mesh::{MeshProblem, TriangleMesh};
use crate::scene::teapot::{self, TeapotPart};
use crate::scene::{SceneObject, obj, shapes};

impl Loader<'_> {
    pub(super) fn objects(
        &self,
        specs: &[ObjectSpec],
        materials: &[Material],
        material_index: &HashMap<String, usize>,
    ) -> Result<Vec<SceneObject>> {
        let mut names = HashMap::new();
        let mut objects = Vec::with_capacity(specs.len());
        for (i, spec) in specs.iter().enumerate() {
            let field = format!("objects[{i}]");
            let used = names.insert(spec.name.clone(), i).is_some();
            self.check_name(&field, &spec.name, used, "object")?;
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
    pub(super) fn mesh(&self, field: &str, spec: &ObjectSpec) -> Result<TriangleMesh> {
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

    pub(super) fn obj_mesh(
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
        let obj = obj::load_obj(&resolved, smooth_normals).map_err(|e| {
            self.error(
                &path_field,
                format!("{}: not a readable OBJ ({e})", resolved.display()),
                "export the mesh as a Wavefront OBJ with v/vn/vt/f records",
            )
        })?;
        self.warnings
            .borrow_mut()
            .extend(obj.warnings.iter().map(|w| {
                format!(
                    "{}: {path_field}: {}: {w}",
                    self.file.display(),
                    resolved.display()
                )
            }));
        let mut mesh = obj.mesh;
        // A problem with a triangle names the OBJ line of its face.
        let line_of = |problem: &MeshProblem| match problem {
            MeshProblem::Degenerate { first, .. } => obj
                .lines
                .get(*first)
                .map_or_else(String::new, |line| format!(" (a face on line {line})")),
            _ => String::new(),
        };
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
                    format!("{}: {problem}{}", resolved.display(), line_of(&problem)),
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
    pub(super) fn transform(&self, field: &str, spec: &TransformSpec) -> Result<Affine3A> {
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
