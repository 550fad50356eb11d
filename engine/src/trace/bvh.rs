//! Triangle BVHs on obvhs with f64 intersection.
//!
//! obvhs builds a compressed-wide BVH (CwBvh) over slightly padded f32 triangle bounds and
//! traverses it with an f32 ray; every candidate triangle is then intersected in f64
//! (Möller–Trumbore with a tiny barycentric tolerance so shared edges never leak), so hit
//! distances, positions and normals carry f64 accuracy. Triangles are stored in BVH order (the
//! traversal callback's id indexes them directly). Triangle tests are counted inside the
//! traversal callback, since obvhs has no counters of its own.

use std::time::Duration;

use glam::{DVec2, DVec3, Vec2, Vec3, Vec3A};
use obvhs::{
    Boundable, BvhBuildParams, aabb::Aabb, cwbvh::CwBvh, cwbvh::builder::build_cwbvh, ray::RayHit,
};

use super::Ray;
use super::fresnel::{Real, Vector3};

/// Relative barycentric slack of the triangle test: a hit exactly on a shared edge belongs to both
/// triangles, so no ray slips between them.
const BARYCENTRIC_SLACK: f64 = 1e-10;

/// Hits at most this much (relative) farther than the nearest hit are one hit with it, and the
/// triangle of the lowest id among them wins: a ray through a shared vertex or edge meets every triangle around it at
/// one distance up to rounding, and which one it starts its next segment on must not depend on
/// the traversal order or the float type (the GPU's f32 tracer breaks ties the same way, by the
/// same ids). 1e-5 is far above f32's rounding of a distance (a few 1e-7) and far below any gap
/// between two surfaces of a scene (a glass wall of 2 mm at 10 m is 2e-4).
pub(crate) const TIE: f64 = 1e-5;

/// How far behind the real origin, in the BVH's scaled units, the f32 traversal ray starts.
/// obvhs's node test raises every box's entry distance to at least 1e-4 whatever the ray's own
/// start, so a ray starting at its origin would skip a box it leaves within 1e-4 of it: a camera
/// 1e-5 m from a 1 m glass cube would see through its face. Starting 1.5e-4 back, every box in
/// front of the real origin is left beyond that floor; the f64 triangle test still measures from
/// the real origin.
const TRAVERSAL_BACK_OFF: f64 = 1.5e-4;

/// One triangle handed to [`MeshBvh::build`], in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SourceTriangle {
    /// Vertex positions in metres.
    pub positions: [Vec3; 3],
    /// Vertex normals (need not be unit; zero vectors fall back to the face normal).
    pub normals: [Vec3; 3],
    /// Vertex texture coordinates (zeros when the mesh has none).
    pub uvs: [Vec2; 3],
    /// Index of the scene object the triangle belongs to.
    pub object: u32,
}

/// A triangle in BVH order with its f64 edges, precomputed for intersection and shading.
#[derive(Clone, Copy, Debug)]
pub(super) struct BvhTriangle {
    pub(super) v0: DVec3,
    pub(super) e1: DVec3,
    pub(super) e2: DVec3,
    /// Unit face normal, flipped to agree with the vertex normals.
    pub(super) geometric_normal: DVec3,
    pub(super) normals: [DVec3; 3],
    uvs: [DVec2; 3],
    pub(super) object: u32,
}

/// Padded f32 bounds of one triangle, the primitive obvhs builds over.
pub(super) struct PaddedBounds(Aabb);

impl Boundable for PaddedBounds {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// A ray–surface intersection with everything shading and path propagation need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Distance along the (unit-direction) ray in metres, > 0.
    pub distance: f64,
    /// Hit position in world space, on the triangle's plane.
    pub position: DVec3,
    /// Unit face normal, oriented to agree with the mesh's vertex normals ("outside").
    pub geometric_normal: DVec3,
    /// Unit interpolated vertex normal, on the same side as `geometric_normal`.
    pub shading_normal: DVec3,
    /// Interpolated texture coordinate.
    pub uv: DVec2,
    /// Scene object index.
    pub object: usize,
    /// Triangle index inside the BVH that was hit (to exclude it from the next ray's query).
    pub primitive: u32,
}

impl SurfaceHit {
    /// True when the ray arrives from the side the normals point to (`direction · n < 0`).
    pub fn is_front_facing(&self, direction: DVec3) -> bool {
        direction.dot(self.geometric_normal) < 0.0
    }
}

/// A triangle BVH over some of a scene's objects (one lens object, or the environment).
pub struct MeshBvh {
    bvh: Option<CwBvh>,
    pub(super) triangles: Vec<BvhTriangle>,
    /// The power of two that obvhs's f32 coordinates are world coordinates times, chosen to bring
    /// the largest coordinate into (16, 32] (scaling by a power of two commutes with rounding):
    /// obvhs's own checks (debug builds) allow an absolute 1e-5 of slack on node bounds, which the
    /// f32 rounding of an unscaled scene a few kilometres across overruns, a panic in
    /// `TraceScene::new`.
    scale: f64,
}

impl std::fmt::Debug for MeshBvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshBvh")
            .field("triangles", &self.triangles.len())
            .finish()
    }
}

impl MeshBvh {
    /// Builds a BVH over `triangles`. Degenerate (zero-area) and non-finite triangles are skipped:
    /// no ray can hit them meaningfully.
    pub fn build(triangles: &[SourceTriangle]) -> MeshBvh {
        let prepared: Vec<BvhTriangle> = triangles.iter().filter_map(prepare_triangle).collect();
        if prepared.is_empty() {
            return MeshBvh {
                bvh: None,
                triangles: prepared,
                scale: 1.0,
            };
        }
        let largest = prepared
            .iter()
            .flat_map(|t| [t.v0, t.v0 + t.e1, t.v0 + t.e2])
            .map(|v| v.abs().max_element())
            .fold(0.0, f64::max);
        let scale = if largest > 0.0 {
            2f64.powi(5 - largest.log2().ceil() as i32)
        } else {
            1.0
        };
        let bounds: Vec<PaddedBounds> = prepared
            .iter()
            .map(|triangle| padded_bounds(triangle, scale))
            .collect();
        let bvh = build_cwbvh(
            &bounds,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let ordered = bvh
            .primitive_indices
            .iter()
            .map(|&index| prepared[index as usize])
            .collect();
        MeshBvh {
            bvh: Some(bvh),
            triangles: ordered,
            scale,
        }
    }

    /// Number of (non-degenerate) triangles in the BVH.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// True when the BVH holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// Closest hit with distance in `(min_distance, max_distance)`, skipping triangle `exclude`
    /// (the one the ray starts on). Adds the triangle tests done to `triangle_tests`.
    pub fn closest_hit(
        &self,
        ray: &Ray,
        min_distance: f64,
        max_distance: f64,
        exclude: Option<u32>,
        triangle_tests: &mut u64,
    ) -> Option<SurfaceHit> {
        self.closest_hit_in::<f64>(ray, min_distance, max_distance, exclude, triangle_tests)
    }

    /// [`MeshBvh::closest_hit`] with the triangle test and the hit's attributes computed in
    /// precision `R` (the ray and the triangles rounded to it first): f64 is `closest_hit`; f32
    /// measures what single precision would cost. The f32 traversal stays the broad phase for
    /// both: its boxes are padded by 1e-5 of the coordinates' magnitude, far more than an f32
    /// triangle test's own rounding (~1e-7 relative), so it culls nothing either test would hit.
    pub fn closest_hit_in<R: Real>(
        &self,
        ray: &Ray,
        min_distance: f64,
        max_distance: f64,
        exclude: Option<u32>,
        triangle_tests: &mut u64,
    ) -> Option<SurfaceHit> {
        let bvh = self.bvh.as_ref()?;
        // The winner: the lowest id among the hits within TIE of the nearest hit so far. The
        // window only shrinks, so the result does not depend on the order hits are found in.
        let mut best: Option<(u32, f64, f64, f64)> = None;
        let mut nearest = f64::INFINITY;
        // Hits up to here may still win: the nearest hit so far plus the tie margin.
        let mut reach = max_distance;
        let mut tests = 0u64;
        let mut obvhs_hit = RayHit::none();
        bvh.ray_traverse(self.f32_ray(ray, max_distance), &mut obvhs_hit, |_, id| {
            tests += 1;
            if exclude == Some(id as u32) {
                return f32::INFINITY;
            }
            let Some((t, u, v)) = self.triangles[id].intersect::<R>(ray, min_distance, reach)
            else {
                return f32::INFINITY;
            };
            if t < nearest {
                nearest = t;
                reach = (t * (1.0 + TIE)).min(max_distance);
            }
            let wins = match best {
                None => true,
                Some((best_id, best_t, _, _)) => best_t > reach || (id as u32) < best_id,
            };
            if wins {
                best = Some((id as u32, t, u, v));
            }
            self.traversal_distance(reach)
        });
        *triangle_tests += tests;
        best.map(|(id, t, u, v)| self.triangles[id as usize].surface::<R>(id, t, u, v))
    }

    /// True when some triangle (other than `exclude`) lies within `(min_distance, max_distance)`
    /// along the ray: an occlusion query that stops at the first such triangle.
    pub fn occluded(
        &self,
        ray: &Ray,
        min_distance: f64,
        max_distance: f64,
        exclude: Option<u32>,
        triangle_tests: &mut u64,
    ) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let mut tests = 0u64;
        let missed = bvh.ray_traverse_miss(self.f32_ray(ray, max_distance), |_, id| {
            tests += 1;
            if exclude == Some(id as u32) {
                return f32::INFINITY;
            }
            match self.triangles[id].intersect::<f64>(ray, min_distance, max_distance) {
                Some(_) => 0.0,
                None => f32::INFINITY,
            }
        });
        *triangle_tests += tests;
        !missed
    }

    /// Every hit with distance in `(min_distance, max_distance)`, sorted by distance (ties by
    /// triangle), skipping triangle `exclude`.
    pub fn all_hits(
        &self,
        ray: &Ray,
        min_distance: f64,
        max_distance: f64,
        exclude: Option<u32>,
        triangle_tests: &mut u64,
    ) -> Vec<SurfaceHit> {
        let Some(bvh) = self.bvh.as_ref() else {
            return Vec::new();
        };
        let mut found: Vec<(u32, f64, f64, f64)> = Vec::new();
        let mut tests = 0u64;
        bvh.ray_traverse_anyhit(self.f32_ray(ray, max_distance), |_, id| {
            tests += 1;
            if exclude == Some(id as u32) {
                return;
            }
            if let Some((t, u, v)) =
                self.triangles[id].intersect::<f64>(ray, min_distance, max_distance)
            {
                found.push((id as u32, t, u, v));
            }
        });
        *triangle_tests += tests;
        found.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        found
            .into_iter()
            .map(|(id, t, u, v)| self.surface_hit(id, t, u, v))
            .collect()
    }

    fn surface_hit(&self, id: u32, t: f64, u: f64, v: f64) -> SurfaceHit {
        self.triangles[id as usize].surface::<f64>(id, t, u, v)
    }

    /// The f32 obvhs ray for traversal only: in the BVH's scaled coordinates, starting
    /// [`TRAVERSAL_BACK_OFF`] behind `ray`'s origin; exact distances come from the f64 triangle
    /// test.
    fn f32_ray(&self, ray: &Ray, max_distance: f64) -> obvhs::ray::Ray {
        let max = if max_distance.is_finite() {
            self.traversal_distance(max_distance * (1.0 + 1e-6) + 1e-6)
        } else {
            f32::INFINITY
        };
        let origin = ray.origin * self.scale - ray.direction * TRAVERSAL_BACK_OFF;
        obvhs::ray::Ray::new(
            Vec3A::from(origin.as_vec3()),
            Vec3A::from(ray.direction.as_vec3()),
            0.0,
            max,
        )
    }

    /// Distance `t` along a ray (world units of its direction) as its traversal ray measures it,
    /// rounded up so that pruning with it stays conservative.
    fn traversal_distance(&self, t: f64) -> f32 {
        round_up(t * self.scale + TRAVERSAL_BACK_OFF)
    }
}

impl SourceTriangle {
    /// The surface at barycentrics `(u, v)` (the weights of vertices 1 and 2; values outside the
    /// triangle extrapolate along its plane), with exactly the normals, texture coordinates and
    /// sides a ray hit there gets: what light maps shade. `None` for a degenerate or non-finite
    /// triangle (one the BVH leaves out). `primitive` is `u32::MAX` (no BVH id).
    pub fn surface_at(&self, u: f64, v: f64) -> Option<SurfaceHit> {
        prepare_triangle(self).map(|triangle| triangle.surface::<f64>(u32::MAX, 0.0, u, v))
    }
}

impl BvhTriangle {
    /// The hit at distance `t` and barycentrics `(u, v)` on this triangle (BVH id `id`), its
    /// position and normals interpolated in precision `R` (the triangle rounded to it; the unit
    /// face normal, computed once in f64, only rounded).
    #[inline]
    fn surface<R: Real>(&self, id: u32, t: f64, u: f64, v: f64) -> SurfaceHit {
        let (u_r, v_r) = (R::of(u), R::of(v));
        let w = R::ONE - u_r - v_r;
        let vector = <R::Vec3 as Vector3>::of;
        let position = vector(self.v0) + vector(self.e1) * u_r + vector(self.e2) * v_r;
        let interpolated = vector(self.normals[0]) * w
            + vector(self.normals[1]) * u_r
            + vector(self.normals[2]) * v_r;
        let geometric_normal = vector(self.geometric_normal);
        let shading_normal = if interpolated.length_squared() > R::of(1e-24) {
            let n = interpolated.normalize();
            // A shading normal on the wrong side of the face would flip inside and outside.
            if n.dot(geometric_normal) > R::ZERO {
                n
            } else {
                geometric_normal
            }
        } else {
            geometric_normal
        };
        let (u, v) = (u_r.to_f64(), v_r.to_f64());
        let uv = (1.0 - u - v) * self.uvs[0] + u * self.uvs[1] + v * self.uvs[2];
        SurfaceHit {
            distance: t,
            position: position.to_dvec3(),
            geometric_normal: geometric_normal.to_dvec3(),
            shading_normal: shading_normal.to_dvec3(),
            uv,
            object: self.object as usize,
            primitive: id,
        }
    }

    /// Möller–Trumbore in precision `R` (ray and triangle rounded to it): `(t, u, v)` with `t` in
    /// `(min_distance, max_distance)`. The barycentric slack is [`BARYCENTRIC_SLACK`], or 8 ulps
    /// of `R` where that is larger (f32), so shared edges stay closed in either precision.
    #[inline]
    fn intersect<R: Real>(
        &self,
        ray: &Ray,
        min_distance: f64,
        max_distance: f64,
    ) -> Option<(f64, f64, f64)> {
        let vector = <R::Vec3 as Vector3>::of;
        let (e1, e2) = (vector(self.e1), vector(self.e2));
        let direction = vector(ray.direction);
        let p = direction.cross(e2);
        let determinant = e1.dot(p);
        if determinant.abs().to_f64() < 1e-300 || determinant == R::ZERO {
            return None;
        }
        let slack = R::of(BARYCENTRIC_SLACK).max(R::of(8.0) * R::EPSILON);
        let inverse = R::ONE / determinant;
        let s = vector(ray.origin) - vector(self.v0);
        let u = s.dot(p) * inverse;
        if !(u >= -slack && u <= R::ONE + slack) {
            return None;
        }
        let q = s.cross(e1);
        let v = direction.dot(q) * inverse;
        if v < -slack || u + v > R::ONE + slack {
            return None;
        }
        let t = e2.dot(q) * inverse;
        let (t, u, v) = (t.to_f64(), u.to_f64(), v.to_f64());
        (t > min_distance && t < max_distance).then_some((t, u, v))
    }
}

fn prepare_triangle(source: &SourceTriangle) -> Option<BvhTriangle> {
    let [p0, p1, p2] = source.positions.map(|p| p.as_dvec3());
    if !(p0.is_finite() && p1.is_finite() && p2.is_finite()) {
        return None;
    }
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let face = e1.cross(e2);
    let scale = e1.length_squared().max(e2.length_squared());
    if face.length_squared() <= 1e-24 * scale * scale || scale == 0.0 {
        return None;
    }
    let mut geometric_normal = face.normalize();
    let normals = source.normals.map(|n| {
        let n = n.as_dvec3();
        if n.is_finite() { n } else { DVec3::ZERO }
    });
    let normal_sum = normals[0] + normals[1] + normals[2];
    if normal_sum.dot(geometric_normal) < 0.0 {
        geometric_normal = -geometric_normal;
    }
    let normals = normals.map(|n| {
        if n.length_squared() > 1e-24 {
            n.normalize()
        } else {
            geometric_normal
        }
    });
    let uvs = source.uvs.map(|uv| {
        let uv = uv.as_dvec2();
        if uv.is_finite() { uv } else { DVec2::ZERO }
    });
    Some(BvhTriangle {
        v0: p0,
        e1,
        e2,
        geometric_normal,
        normals,
        uvs,
        object: source.object,
    })
}

/// f32 bounds, in world coordinates times `scale` (a power of two), grown by a relative margin
/// (at least 1e-5 m), so the f32 traversal never culls a triangle the f64 test would hit (the
/// f32 ray origin is rounded).
pub(super) fn padded_bounds(triangle: &BvhTriangle, scale: f64) -> PaddedBounds {
    let vertices = [
        triangle.v0,
        triangle.v0 + triangle.e1,
        triangle.v0 + triangle.e2,
    ]
    .map(|v| v * scale);
    let min = vertices[0].min(vertices[1]).min(vertices[2]);
    let max = vertices[0].max(vertices[1]).max(vertices[2]);
    let magnitude = min.abs().max(max.abs()).max_element().max(scale);
    let pad = DVec3::splat(magnitude * 1e-5);
    PaddedBounds(Aabb::new(
        Vec3A::from((min - pad).as_vec3()),
        Vec3A::from((max + pad).as_vec3()),
    ))
}

/// The smallest f32 not below `t` (t ≥ 0), so pruning with it stays conservative.
fn round_up(t: f64) -> f32 {
    let rounded = t as f32;
    if f64::from(rounded) >= t || !rounded.is_finite() {
        rounded
    } else {
        f32::from_bits(rounded.to_bits() + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn random_triangles(rng: &mut Pcg64, count: usize) -> Vec<SourceTriangle> {
        (0..count)
            .map(|i| {
                let centre = Vec3::new(
                    rng.gen_range(-5.0..5.0),
                    rng.gen_range(-5.0..5.0),
                    rng.gen_range(-5.0..5.0),
                );
                let mut corner = || {
                    centre
                        + Vec3::new(
                            rng.gen_range(-0.5..0.5),
                            rng.gen_range(-0.5..0.5),
                            rng.gen_range(-0.5..0.5),
                        )
                };
                SourceTriangle {
                    positions: [corner(), corner(), corner()],
                    normals: [Vec3::ZERO; 3],
                    uvs: [Vec2::ZERO; 3],
                    object: i as u32,
                }
            })
            .collect()
    }

    #[test]
    fn closest_hit_matches_brute_force() {
        let mut rng = Pcg64::seed_from_u64(7);
        let triangles = random_triangles(&mut rng, 400);
        let bvh = MeshBvh::build(&triangles);
        let prepared: Vec<BvhTriangle> = triangles.iter().filter_map(prepare_triangle).collect();
        assert_eq!(bvh.triangle_count(), prepared.len());
        let mut tests = 0;
        let mut hits = 0;
        for _ in 0..500 {
            let origin = DVec3::new(
                rng.gen_range(-8.0..8.0),
                rng.gen_range(-8.0..8.0),
                rng.gen_range(-8.0..8.0),
            );
            let target = DVec3::new(
                rng.gen_range(-4.0..4.0),
                rng.gen_range(-4.0..4.0),
                rng.gen_range(-4.0..4.0),
            );
            let ray = Ray::new(origin, target - origin);
            let brute = prepared
                .iter()
                .filter_map(|t| {
                    t.intersect::<f64>(&ray, 0.0, f64::INFINITY)
                        .map(|h| (h.0, t.object))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let found = bvh.closest_hit(&ray, 0.0, f64::INFINITY, None, &mut tests);
            match (brute, found) {
                (None, None) => {}
                (Some((t, object)), Some(hit)) => {
                    hits += 1;
                    assert_eq!(t, hit.distance);
                    assert_eq!(object as usize, hit.object);
                    assert!((hit.position - ray.at(t)).length() < 1e-12);
                }
                other => panic!("brute force and BVH disagree: {other:?}"),
            }
            let all = bvh.all_hits(&ray, 0.0, f64::INFINITY, None, &mut tests);
            let brute_count = prepared
                .iter()
                .filter(|t| t.intersect::<f64>(&ray, 0.0, f64::INFINITY).is_some())
                .count();
            assert_eq!(all.len(), brute_count);
            assert!(all.windows(2).all(|w| w[0].distance <= w[1].distance));
            assert_eq!(
                bvh.occluded(&ray, 0.0, f64::INFINITY, None, &mut tests),
                brute.is_some()
            );
        }
        assert!(hits > 50, "too few hits to mean anything: {hits}");
        assert!(tests > 0);
    }

    #[test]
    fn empty_and_degenerate_meshes_never_hit() {
        let degenerate = SourceTriangle {
            positions: [Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
            normals: [Vec3::Z; 3],
            uvs: [Vec2::ZERO; 3],
            object: 0,
        };
        let nan = SourceTriangle {
            positions: [Vec3::NAN, Vec3::X, Vec3::Y],
            ..degenerate
        };
        let bvh = MeshBvh::build(&[degenerate, nan]);
        assert!(bvh.is_empty());
        let ray = Ray::new(DVec3::new(0.5, 0.0, 1.0), DVec3::NEG_Z);
        let mut tests = 0;
        assert!(
            bvh.closest_hit(&ray, 0.0, f64::INFINITY, None, &mut tests)
                .is_none()
        );
        assert!(!bvh.occluded(&ray, 0.0, f64::INFINITY, None, &mut tests));
    }

    #[test]
    fn single_triangle_hit_has_interpolated_attributes_and_excludes_itself() {
        let triangle = SourceTriangle {
            positions: [Vec3::ZERO, Vec3::X, Vec3::Y],
            // Vertex normals point down: the face normal is flipped to agree.
            normals: [Vec3::NEG_Z; 3],
            uvs: [Vec2::ZERO, Vec2::X, Vec2::Y],
            object: 3,
        };
        let bvh = MeshBvh::build(&[triangle]);
        let ray = Ray::new(DVec3::new(0.25, 0.5, 2.0), DVec3::NEG_Z);
        let mut tests = 0;
        let hit = bvh
            .closest_hit(&ray, 0.0, f64::INFINITY, None, &mut tests)
            .expect("hit");
        assert_eq!(hit.distance, 2.0);
        assert_eq!(hit.geometric_normal, DVec3::NEG_Z);
        assert_eq!(hit.shading_normal, DVec3::NEG_Z);
        assert!((hit.uv - DVec2::new(0.25, 0.5)).length() < 1e-15);
        assert_eq!(hit.object, 3);
        assert!(!hit.is_front_facing(ray.direction));
        assert!(
            bvh.closest_hit(&ray, 0.0, f64::INFINITY, Some(hit.primitive), &mut tests)
                .is_none()
        );
        assert!(bvh.closest_hit(&ray, 0.0, 1.5, None, &mut tests).is_none());
        // The third query is culled by the box: its range ends before the triangle.
        assert_eq!(tests, 2);
    }
}
