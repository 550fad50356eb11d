//! The flattened world the tracer works on: one BVH per lens object, one for the environment,
//! materials resolved per object.
//!
//! Lens objects are the scene's `lenses`, restricted to their glass and mirror objects; a glass or
//! mirror object that no lens names becomes a lens object of its own (so the reference image still
//! refracts through it). Everything else (diffuse objects) forms the environment.

use glam::{DVec3, Vec2, Vec3};

use super::bvh::{MeshBvh, SourceTriangle, SurfaceHit};
use super::fresnel::Real;
use super::path::{Interface, LensGeometry};
use super::stats::TraceCounters;
use super::{Ray, TraceError};
use crate::scene::{Environment, Material, PointLight, Scene, TriangleMesh};

/// One lens object: the scene objects ray traced as the local system, and their BVH.
#[derive(Debug)]
pub struct LensBvh {
    /// The lens object's name (the scene's, or the object's name for an implicit one).
    pub name: String,
    /// Scene object indices forming this lens object (glass and mirror objects only).
    pub objects: Vec<usize>,
    /// BVH over those objects' triangles.
    pub bvh: MeshBvh,
}

/// Which BVH a surface belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Part {
    /// The environment (every non-lens object).
    Environment,
    /// Lens object `i` (index into [`TraceScene::lenses`]).
    Lens(usize),
}

/// A surface hit in the whole world: which BVH, and which triangle in it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldHit {
    /// The intersection.
    pub hit: SurfaceHit,
    /// The BVH it belongs to.
    pub part: Part,
}

impl WorldHit {
    /// The id that excludes this surface from the next ray's query.
    pub fn surface(&self) -> SurfaceId {
        SurfaceId {
            part: self.part,
            primitive: self.hit.primitive,
        }
    }
}

/// One triangle of the world, to skip the surface a ray starts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SurfaceId {
    /// The BVH the triangle lies in.
    pub part: Part,
    /// Its index inside that BVH.
    pub primitive: u32,
}

/// A scene flattened for ray tracing.
#[derive(Debug)]
pub struct TraceScene {
    /// Lens objects, explicit ones first in scene order, then implicit ones.
    pub lenses: Vec<LensBvh>,
    /// BVH over all non-lens objects.
    pub environment: MeshBvh,
    /// Material of each scene object (cloned from the scene).
    pub(crate) object_materials: Vec<Material>,
    /// Scene object names, for messages and records.
    pub object_names: Vec<String>,
    /// Lens object of each scene object, `None` for environment objects.
    pub object_lens: Vec<Option<usize>>,
    /// Point lights.
    pub lights: Vec<PointLight>,
    /// The environment at infinity.
    pub background: Environment,
}

impl TraceScene {
    /// Flattens `scene`: resolves materials, assigns objects to lens objects or the environment and
    /// builds the BVHs (all in world space).
    pub fn new(scene: &Scene) -> Result<TraceScene, TraceError> {
        let object_count = scene.objects.len();
        let mut object_materials = Vec::with_capacity(object_count);
        for (index, object) in scene.objects.iter().enumerate() {
            let material = scene.materials.get(object.material).ok_or_else(|| {
                TraceError::InvalidScene(format!(
                    "object {index} ('{}') names material {}, but the scene has {} materials",
                    object.name,
                    object.material,
                    scene.materials.len()
                ))
            })?;
            object_materials.push(material.clone());
        }

        let mut object_lens: Vec<Option<usize>> = vec![None; object_count];
        let mut lens_members: Vec<(String, Vec<usize>)> = Vec::new();
        for lens in &scene.lenses {
            let mut members = Vec::new();
            for &object in &lens.objects {
                if object >= object_count {
                    return Err(TraceError::InvalidScene(format!(
                        "lens '{}' names object {object}, but the scene has {object_count} objects",
                        lens.name
                    )));
                }
                if !object_materials[object].is_lens() {
                    continue;
                }
                if let Some(other) = object_lens[object] {
                    return Err(TraceError::InvalidScene(format!(
                        "object '{}' belongs to two lens objects, '{}' and '{}'",
                        scene.objects[object].name, lens_members[other].0, lens.name
                    )));
                }
                object_lens[object] = Some(lens_members.len());
                members.push(object);
            }
            lens_members.push((lens.name.clone(), members));
        }
        for (object, material) in object_materials.iter().enumerate() {
            if material.is_lens() && object_lens[object].is_none() {
                object_lens[object] = Some(lens_members.len());
                lens_members.push((scene.objects[object].name.clone(), vec![object]));
            }
        }

        let lenses = lens_members
            .into_iter()
            .map(|(name, objects)| {
                let mut triangles = Vec::new();
                for &object in &objects {
                    push_triangles(&mut triangles, &scene.objects[object].mesh, object);
                }
                LensBvh {
                    name,
                    objects,
                    bvh: MeshBvh::build(&triangles),
                }
            })
            .collect();
        let mut environment_triangles = Vec::new();
        for (object, scene_object) in scene.objects.iter().enumerate() {
            if object_lens[object].is_none() {
                push_triangles(&mut environment_triangles, &scene_object.mesh, object);
            }
        }
        Ok(TraceScene {
            lenses,
            environment: MeshBvh::build(&environment_triangles),
            object_materials,
            object_names: scene.objects.iter().map(|o| o.name.clone()).collect(),
            object_lens,
            lights: scene.lights.clone(),
            background: scene.environment.clone(),
        })
    }

    /// The BVH of `part`.
    pub fn bvh(&self, part: Part) -> &MeshBvh {
        match part {
            Part::Environment => &self.environment,
            Part::Lens(index) => &self.lenses[index].bvh,
        }
    }

    /// The material of scene object `object`.
    pub fn material(&self, object: usize) -> &Material {
        &self.object_materials[object]
    }

    /// The optical interface of a glass or mirror object; `None` for a diffuse one.
    pub fn interface(&self, object: usize) -> Option<Interface> {
        match self.material(object) {
            Material::Glass { ior, absorption } => Some(Interface::Dielectric {
                ior: f64::from(*ior),
                absorption: absorption.as_dvec3(),
            }),
            Material::Mirror { reflectance } => Some(Interface::Mirror {
                reflectance: reflectance.as_dvec3(),
            }),
            Material::Diffuse { .. } | Material::Glossy(_) => None,
        }
    }

    /// Lens object `lens` as a [`LensGeometry`] for the path models.
    pub fn lens(&self, lens: usize) -> LensView<'_> {
        self.lens_in::<f64>(lens)
    }

    /// [`TraceScene::lens`] with its triangle tests in precision `R`.
    pub fn lens_in<R: Real>(&self, lens: usize) -> LensView<'_, R> {
        LensView {
            scene: self,
            lens,
            precision: std::marker::PhantomData,
        }
    }

    /// Closest hit over the environment and every lens object except `skip_lens`, skipping the
    /// surface `exclude`. Counts triangle tests only (callers count rays).
    pub fn closest_hit(
        &self,
        ray: &Ray,
        exclude: Option<SurfaceId>,
        skip_lens: Option<usize>,
        counters: &mut TraceCounters,
    ) -> Option<WorldHit> {
        self.closest_hit_within(ray, f64::INFINITY, exclude, skip_lens, counters)
    }

    /// [`TraceScene::closest_hit`] limited to distances ≤ `max_distance` (metres): a query that
    /// only asks what lies before a known point (a visibility test) traverses less.
    pub fn closest_hit_within(
        &self,
        ray: &Ray,
        max_distance: f64,
        exclude: Option<SurfaceId>,
        skip_lens: Option<usize>,
        counters: &mut TraceCounters,
    ) -> Option<WorldHit> {
        let mut best: Option<WorldHit> = None;
        let parts = std::iter::once(Part::Environment).chain(
            (0..self.lenses.len())
                .filter(|&i| Some(i) != skip_lens)
                .map(Part::Lens),
        );
        for part in parts {
            let max = best.map_or(max_distance, |b| b.hit.distance);
            let skip = exclude.filter(|e| e.part == part).map(|e| e.primitive);
            if let Some(hit) =
                self.bvh(part)
                    .closest_hit(ray, 0.0, max, skip, &mut counters.triangle_tests)
            {
                best = Some(WorldHit { hit, part });
            }
        }
        best
    }

    /// Closest hit on the environment alone.
    pub fn closest_environment_hit(
        &self,
        ray: &Ray,
        exclude: Option<SurfaceId>,
        counters: &mut TraceCounters,
    ) -> Option<WorldHit> {
        let skip = exclude
            .filter(|e| e.part == Part::Environment)
            .map(|e| e.primitive);
        self.environment
            .closest_hit(ray, 0.0, f64::INFINITY, skip, &mut counters.triangle_tests)
            .map(|hit| WorldHit {
                hit,
                part: Part::Environment,
            })
    }

    /// Radiance of the environment at infinity along `direction`, finite and ≥ 0.
    pub fn background_radiance(&self, direction: DVec3) -> DVec3 {
        sanitize(self.background.radiance(direction.as_vec3()).as_dvec3())
    }
}

/// A lens object seen through the [`LensGeometry`] trait, its triangle tests in precision `R`
/// (f64 unless told: [`MeshBvh::closest_hit_in`]).
#[derive(Clone, Copy, Debug)]
pub struct LensView<'a, R = f64> {
    scene: &'a TraceScene,
    lens: usize,
    precision: std::marker::PhantomData<R>,
}

impl<R: Real> LensGeometry for LensView<'_, R> {
    fn closest_hit(
        &self,
        ray: &Ray,
        exclude: Option<u32>,
        counters: &mut TraceCounters,
    ) -> Option<SurfaceHit> {
        self.scene.lenses[self.lens].bvh.closest_hit_in::<R>(
            ray,
            0.0,
            f64::INFINITY,
            exclude,
            &mut counters.triangle_tests,
        )
    }

    fn interface(&self, object: usize) -> Interface {
        // Lens BVHs hold only glass and mirror objects; a black mirror is the harmless fallback.
        self.scene.interface(object).unwrap_or(Interface::Mirror {
            reflectance: DVec3::ZERO,
        })
    }
}

/// Replaces NaN and infinite channels by 0 and clamps negatives to 0.
pub fn sanitize(value: DVec3) -> DVec3 {
    let clean = |c: f64| if c.is_finite() { c.max(0.0) } else { 0.0 };
    DVec3::new(clean(value.x), clean(value.y), clean(value.z))
}

fn push_triangles(out: &mut Vec<SourceTriangle>, mesh: &TriangleMesh, object: usize) {
    out.extend(
        mesh.triangles
            .iter()
            .filter_map(|triangle| source_triangle(mesh, triangle, object)),
    );
}

/// Triangle `triangle` of `mesh` (scene object `object`) as the BVH builds over it: missing
/// normals are zero (the face normal stands in), missing texture coordinates zero; `None` when an
/// index is out of range.
pub fn source_triangle(
    mesh: &TriangleMesh,
    triangle: &[u32; 3],
    object: usize,
) -> Option<SourceTriangle> {
    let vertex = |index: u32| -> Option<(Vec3, Vec3, Vec2)> {
        let i = index as usize;
        let position = *mesh.positions.get(i)?;
        let normal = mesh.normals.get(i).copied().unwrap_or(Vec3::ZERO);
        let uv = mesh.uvs.get(i).copied().unwrap_or(Vec2::ZERO);
        Some((position, normal, uv))
    };
    let (a, b, c) = (
        vertex(triangle[0])?,
        vertex(triangle[1])?,
        vertex(triangle[2])?,
    );
    Some(SourceTriangle {
        positions: [a.0, b.0, c.0],
        normals: [a.1, b.1, c.1],
        uvs: [a.2, b.2, c.2],
        object: object as u32,
    })
}
