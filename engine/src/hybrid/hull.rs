//! The convex-hull split (PEM paper §4): a view-independent pre-pass marks the lens triangles
//! that lie on the convex hull of the lens geometry. No ray leaving such a triangle's front side
//! can meet a lens object again, so it can never show a self-reflection, and a lens object
//! layered by bounce draws it with the distant layer only (its local layer masked).
//!
//! The test is exact for the question the split asks: a triangle lies on the hull when every
//! lens vertex (of every lens object, since the local layer holds first-bounce hits on any of
//! them) is behind or on its plane. That plane then supports the whole point set, which is what
//! "a face of the convex hull" means, so no hull has to be built: a mesh's vertices against its
//! triangles' planes, with an early exit at the first vertex in front (most inner triangles
//! exit within a few vertices).

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::scene::TriangleMesh;

/// A vertex counts as in front of a plane when it is more than this fraction of the lens
/// geometry's bounding-box diagonal in front: f32 positions of coplanar neighbours (a flat patch
/// of a mesh) scatter about 1e-7 of their magnitude off each other's planes, and a reflection off
/// geometry 1e-5 of the object's size in front of the plane is a grazing sliver no frame shows.
pub const IN_FRONT_FRACTION: f64 = 1e-5;

/// Per triangle of `mesh`, whether it lies on the convex hull of `points` (the lens geometry,
/// `mesh`'s vertices among them): every point behind or on its plane, within
/// [`IN_FRONT_FRACTION`] of the points' bounding-box diagonal. A degenerate triangle (no normal)
/// or one with a vertex index out of range is not on the hull.
pub fn hull_triangles(mesh: &TriangleMesh, points: &[Vec3]) -> Vec<bool> {
    let (lo, hi) = points.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p.as_dvec3()), hi.max(p.as_dvec3())),
    );
    let diagonal = (hi - lo).length();
    if !diagonal.is_finite() {
        return vec![false; mesh.triangles.len()];
    }
    let tolerance = IN_FRONT_FRACTION * diagonal;
    let points: Vec<DVec3> = points.iter().map(|p| p.as_dvec3()).collect();
    mesh.triangles
        .par_iter()
        .map(|triangle| {
            let Some([a, b, c]) = corners(mesh, triangle) else {
                return false;
            };
            let normal = (b - a).cross(c - a).normalize_or_zero();
            normal != DVec3::ZERO && points.iter().all(|&p| normal.dot(p - a) <= tolerance)
        })
        .collect()
}

/// The corners of `triangle` in f64, or `None` where an index is out of range.
fn corners(mesh: &TriangleMesh, triangle: &[u32; 3]) -> Option<[DVec3; 3]> {
    let corner = |i: u32| mesh.positions.get(i as usize).map(|p| p.as_dvec3());
    Some([
        corner(triangle[0])?,
        corner(triangle[1])?,
        corner(triangle[2])?,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube's 12 triangles, counter-clockwise seen from outside.
    fn cube() -> TriangleMesh {
        let positions: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .collect();
        let quads = [
            [0, 2, 3, 1], // z = 0, normal −z
            [4, 5, 7, 6], // z = 1, normal +z
            [0, 1, 5, 4], // y = 0, normal −y
            [2, 6, 7, 3], // y = 1, normal +y
            [0, 4, 6, 2], // x = 0, normal −x
            [1, 3, 7, 5], // x = 1, normal +x
        ];
        let triangles = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        TriangleMesh {
            normals: vec![Vec3::Z; positions.len()],
            positions,
            uvs: Vec::new(),
            triangles,
        }
    }

    #[test]
    fn every_face_of_a_cube_is_on_its_hull() {
        let mesh = cube();
        // The face normals really point outwards (else the test would pass for the wrong reason).
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            let centroid = (a + b + c) / 3.0;
            assert!((b - a).cross(c - a).dot(centroid - Vec3::splat(0.5)) > 0.0);
        }
        assert_eq!(hull_triangles(&mesh, &mesh.positions), vec![true; 12]);
    }

    #[test]
    fn a_point_in_front_takes_a_face_off_the_hull_and_a_second_object_counts() {
        let mesh = cube();
        // A second lens object's vertex just above the top face (z = 1): only the top face's two
        // triangles see it. One 1e-6 above (inside the tolerance) changes nothing.
        let mut points = mesh.positions.clone();
        points.push(Vec3::new(0.5, 0.5, 1.0 + 1e-6));
        assert_eq!(hull_triangles(&mesh, &points), vec![true; 12]);
        points.push(Vec3::new(0.5, 0.5, 1.01));
        let on_hull = hull_triangles(&mesh, &points);
        assert_eq!(on_hull.iter().filter(|&&h| !h).count(), 2);
        assert!(!on_hull[2] && !on_hull[3]);
    }

    #[test]
    fn an_inward_face_is_not_on_the_hull_and_degenerate_ones_are_refused() {
        let mut mesh = cube();
        // A triangle inside the cube facing +x: the face at x = 1 lies in front of it.
        let base = mesh.positions.len() as u32;
        mesh.positions.extend([
            Vec3::new(0.5, 0.2, 0.2),
            Vec3::new(0.5, 0.8, 0.2),
            Vec3::new(0.5, 0.2, 0.8),
        ]);
        mesh.triangles.push([base, base + 1, base + 2]);
        // Degenerate (repeated vertex) and out of range.
        mesh.triangles.push([0, 0, 1]);
        mesh.triangles.push([0, 1, 99]);
        let on_hull = hull_triangles(&mesh, &mesh.positions);
        assert_eq!(&on_hull[..12], &[true; 12]);
        assert_eq!(&on_hull[12..], &[false, false, false]);
    }

    #[test]
    fn non_finite_points_mark_nothing() {
        let mesh = cube();
        let mut points = mesh.positions.clone();
        points.push(Vec3::new(f32::NAN, 0.0, 0.0));
        assert_eq!(hull_triangles(&mesh, &points), vec![false; 12]);
    }
}
