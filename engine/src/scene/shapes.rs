//! Built-in shapes in their local frame (centred on the origin, y up, metres): plane, box, sphere,
//! cylinder and torus, each with unit outward normals, counter-clockwise outward triangles and
//! texture coordinates. Parameters are assumed valid (the loader checks them); counts are
//! clamped to their minimum so that no input can panic here.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use super::mesh::TriangleMesh;

/// One sample of a parametric surface: position, unit normal (outward), texture coordinate.
pub(crate) struct SurfacePoint {
    /// Position in the shape's local frame, metres.
    pub position: Vec3,
    /// Unit normal pointing out of the front side.
    pub normal: Vec3,
    /// Texture coordinate (u right, v up, as in OBJ).
    pub uv: Vec2,
}

/// Which side of a tessellated parametric surface is the front.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Winding {
    /// Each triangle is wound so that its geometric normal agrees with the sum of the surface
    /// normals at its corners.
    MatchNormals,
    /// ∂P/∂s × ∂P/∂t is the front (outward) side: robust on coarse grids where a triangle's
    /// corners have very different normals.
    Parametric,
}

/// Tessellates a parametric surface `(s, t) ∈ [0, 1]²` on a `columns × rows` grid of quads.
/// Each quad gives two triangles; a triangle that collapses (at a pole) is skipped, and each is
/// wound as `winding` says.
pub(crate) fn parametric_grid(
    columns: u32,
    rows: u32,
    winding: Winding,
    surface: impl Fn(f32, f32) -> SurfacePoint,
) -> TriangleMesh {
    let (columns, rows) = (columns.max(1), rows.max(1));
    let mut mesh = TriangleMesh::default();
    for j in 0..=rows {
        for i in 0..=columns {
            let point = surface(i as f32 / columns as f32, j as f32 / rows as f32);
            mesh.positions.push(point.position);
            mesh.normals.push(point.normal);
            mesh.uvs.push(point.uv);
        }
    }
    let index = |i: u32, j: u32| j * (columns + 1) + i;
    for j in 0..rows {
        for i in 0..columns {
            let corners = [
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            ];
            for tri in [
                [corners[0], corners[1], corners[2]],
                [corners[0], corners[2], corners[3]],
            ] {
                push_oriented(&mut mesh, tri, winding);
            }
        }
    }
    mesh
}

/// Adds a triangle unless it has zero area, wound as `winding` says (`tri` is in parametric
/// order).
fn push_oriented(mesh: &mut TriangleMesh, tri: [u32; 3], winding: Winding) {
    let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
    let face = (b - a).cross(c - a);
    let longest = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    if face.length() <= 1e-6 * longest {
        return;
    }
    let normal: Vec3 = tri.iter().map(|&i| mesh.normals[i as usize]).sum();
    if winding == Winding::Parametric || face.dot(normal) >= 0.0 {
        mesh.triangles.push(tri);
    } else {
        mesh.triangles.push([tri[0], tri[2], tri[1]]);
    }
}

/// A rectangle in the xz plane, normal +y, `size.x` along x and `size.y` along z, split into
/// `subdivisions²` quads. uv = (x/size.x + ½, ½ − z/size.y): u along +x, v along −z.
pub fn plane(size: Vec2, subdivisions: u32) -> TriangleMesh {
    parametric_grid(subdivisions, subdivisions, Winding::MatchNormals, |s, t| {
        SurfacePoint {
            position: Vec3::new((s - 0.5) * size.x, 0.0, (0.5 - t) * size.y),
            normal: Vec3::Y,
            uv: Vec2::new(s, t),
        }
    })
}

/// An axis-aligned box of edge lengths `size`, centred on the origin: six faces of two
/// triangles, flat normals, uv ∈ [0, 1]² on each face.
pub fn cuboid(size: Vec3) -> TriangleMesh {
    let half = size * 0.5;
    let mut mesh = TriangleMesh::default();
    // (outward axis, the face's u axis, the face's v axis): u × v = outward.
    let faces = [
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
    ];
    for (normal, u_axis, v_axis) in faces {
        let face = parametric_grid(1, 1, Winding::MatchNormals, |s, t| SurfacePoint {
            position: (normal + u_axis * (2.0 * s - 1.0) + v_axis * (2.0 * t - 1.0)) * half,
            normal,
            uv: Vec2::new(s, t),
        });
        mesh.append(&face);
    }
    mesh
}

/// A UV sphere of `radius` with `segments` around y (≥ 3) and `rings` from pole to pole (≥ 2).
/// uv = (φ / 2π, 1 − θ / π) with θ the polar angle from +y.
pub fn sphere(radius: f32, segments: u32, rings: u32) -> TriangleMesh {
    parametric_grid(
        segments.max(3),
        rings.max(2),
        Winding::MatchNormals,
        |s, t| {
            let (phi, theta) = (s * TAU, t * PI);
            let normal = Vec3::new(
                theta.sin() * phi.sin(),
                theta.cos(),
                theta.sin() * phi.cos(),
            );
            SurfacePoint {
                position: normal * radius,
                normal,
                uv: Vec2::new(s, 1.0 - t),
            }
        },
    )
}

/// A cylinder of `radius` about the y axis, y ∈ [−height/2, height/2], `segments` around (≥ 3);
/// smooth side normals, and flat caps with their own vertices when `caps` is true (closed).
/// Side uv = (φ / 2π, y / height + ½); cap uv = the xz position mapped to [0, 1]².
pub fn cylinder(radius: f32, height: f32, segments: u32, caps: bool) -> TriangleMesh {
    let segments = segments.max(3);
    let mut mesh = parametric_grid(segments, 1, Winding::MatchNormals, |s, t| {
        let phi = s * TAU;
        let normal = Vec3::new(phi.sin(), 0.0, phi.cos());
        SurfacePoint {
            position: normal * radius + Vec3::Y * (t - 0.5) * height,
            normal,
            uv: Vec2::new(s, t),
        }
    });
    if caps {
        for side in [1.0f32, -1.0] {
            let cap = parametric_grid(segments, 1, Winding::MatchNormals, |s, t| {
                let phi = s * TAU;
                let rim = Vec3::new(phi.sin(), 0.0, phi.cos()) * radius * (1.0 - t);
                SurfacePoint {
                    position: rim + Vec3::Y * side * 0.5 * height,
                    normal: Vec3::Y * side,
                    uv: Vec2::new(rim.x, -rim.z) / (2.0 * radius) + 0.5,
                }
            });
            mesh.append(&cap);
        }
    }
    mesh
}

/// A torus about the y axis: a tube of `minor_radius` swept around a circle of `major_radius` in
/// the xz plane; `major_segments` around y (≥ 3), `minor_segments` around the tube (≥ 3).
/// uv = (angle around y / 2π, angle around the tube / 2π).
pub fn torus(
    major_radius: f32,
    minor_radius: f32,
    major_segments: u32,
    minor_segments: u32,
) -> TriangleMesh {
    parametric_grid(
        major_segments.max(3),
        minor_segments.max(3),
        Winding::MatchNormals,
        |s, t| {
            let (phi, psi) = (s * TAU, t * TAU);
            let radial = Vec3::new(phi.sin(), 0.0, phi.cos());
            let normal = radial * psi.cos() + Vec3::Y * psi.sin();
            SurfacePoint {
                position: radial * major_radius + normal * minor_radius,
                normal,
                uv: Vec2::new(s, t),
            }
        },
    )
}

#[cfg(test)]
mod tests {
    use super::super::mesh::tests::signed_volume;
    use super::*;

    fn assert_unit_outward(mesh: &TriangleMesh, centre_of: impl Fn(Vec3, Vec3) -> Vec3) {
        assert_eq!(mesh.check(), Ok(()));
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            assert!((n.length() - 1.0).abs() < 1e-5, "normal {n} not unit");
            assert!(
                n.dot(*p - centre_of(*p, *n)) > 0.0,
                "normal {n} at {p} not outward"
            );
        }
        for t in 0..mesh.triangle_count() {
            let vertex_normal: Vec3 = mesh.triangles[t]
                .iter()
                .map(|&i| mesh.normals[i as usize])
                .sum();
            assert!(mesh.triangle_normal(t).dot(vertex_normal) > 0.0);
        }
    }

    #[test]
    fn sphere_vertices_lie_on_the_radius_and_the_mesh_is_closed() {
        let mesh = sphere(2.5, 24, 12);
        for p in &mesh.positions {
            assert!((p.length() - 2.5).abs() < 1e-5);
        }
        assert_unit_outward(&mesh, |_, _| Vec3::ZERO);
        assert!(mesh.is_closed());
        // Inscribed polyhedron: a little less than 4/3 π r³.
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 2.5f64.powi(3);
        let volume = signed_volume(&mesh);
        assert!(
            volume < exact && volume > 0.95 * exact,
            "{volume} vs {exact}"
        );
    }

    #[test]
    fn box_is_closed_with_the_right_volume() {
        let mesh = cuboid(Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(mesh.triangle_count(), 12);
        assert_unit_outward(&mesh, |_, _| Vec3::ZERO);
        assert!(mesh.is_closed());
        assert!((signed_volume(&mesh) - 6.0).abs() < 1e-5);
        let (lo, hi) = mesh.bounds().unwrap_or_default();
        assert_eq!(
            (lo, hi),
            (Vec3::new(-0.5, -1.0, -1.5), Vec3::new(0.5, 1.0, 1.5))
        );
    }

    #[test]
    fn cylinder_with_caps_is_closed() {
        let mesh = cylinder(0.5, 2.0, 32, true);
        // Cap normals point along ±y: measure them from the centre; side normals from the axis.
        assert_unit_outward(&mesh, |p, n| {
            if n.y.abs() > 0.5 {
                Vec3::ZERO
            } else {
                Vec3::new(0.0, p.y, 0.0)
            }
        });
        assert!(mesh.is_closed());
        let prism = 0.5 * 32.0 * 0.25 * (TAU / 32.0).sin() as f64 * 2.0;
        assert!((signed_volume(&mesh) - prism).abs() < 1e-4);
        assert!(!cylinder(0.5, 2.0, 32, false).is_closed());
    }

    #[test]
    fn torus_is_closed_with_pappus_volume() {
        let mesh = torus(2.0, 0.5, 64, 32);
        assert_unit_outward(&mesh, |p, _| Vec3::new(p.x, 0.0, p.z).normalize() * 2.0);
        assert!(mesh.is_closed());
        // Pappus: V = 2π R · π r².
        let exact = 2.0 * std::f64::consts::PI * 2.0 * std::f64::consts::PI * 0.25;
        let volume = signed_volume(&mesh);
        assert!((volume / exact - 1.0).abs() < 0.01, "{volume} vs {exact}");
    }

    #[test]
    fn plane_faces_up() {
        let mesh = plane(Vec2::new(4.0, 2.0), 3);
        assert_eq!(mesh.triangle_count(), 18);
        assert_unit_outward(&mesh, |p, _| p - Vec3::Y);
        assert!((mesh.area() - 8.0).abs() < 1e-5);
    }
}
