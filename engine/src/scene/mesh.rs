//! Indexed triangle meshes and the operations the loaders need: affine transforms (positions and
//! inverse-transpose normals), vertex welding, smooth normal generation and validation.

use std::collections::HashMap;

use glam::{Affine3A, Mat3, Vec2, Vec3};

/// An indexed triangle mesh. Scene meshes are in world space (metres) after loading.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex unit normals (same length as `positions`).
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates (u right, v up, as in OBJ), either empty or the same length
    /// as `positions`.
    pub uvs: Vec<Vec2>,
    /// Triangles as vertex indices; counter-clockwise seen from outside, so the geometric normal
    /// `(b − a) × (c − a)` points out of the front face.
    pub triangles: Vec<[u32; 3]>,
}

/// What [`TriangleMesh::check`] found wrong with a mesh.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshProblem {
    /// The mesh has no triangles.
    Empty,
    /// A vertex position is NaN or infinite.
    NonFinitePosition {
        /// Index of the first such vertex.
        vertex: usize,
        /// How many vertices are affected.
        count: usize,
    },
    /// A normal or uv is NaN or infinite.
    NonFiniteAttribute {
        /// Index of the first such vertex.
        vertex: usize,
    },
    /// A triangle names a vertex that does not exist.
    IndexOutOfRange {
        /// Index of the first such triangle.
        triangle: usize,
    },
    /// Triangles with zero area (repeated or collinear vertices).
    Degenerate {
        /// Index of the first degenerate triangle.
        first: usize,
        /// How many triangles are degenerate.
        count: usize,
    },
    /// The attribute arrays disagree in length with `positions`.
    AttributeLength,
}

impl std::fmt::Display for MeshProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MeshProblem::Empty => write!(f, "the mesh has no triangles"),
            MeshProblem::NonFinitePosition { vertex, count } => write!(
                f,
                "{count} vertex position(s) are NaN or infinite, the first is vertex {vertex} (0-based)"
            ),
            MeshProblem::NonFiniteAttribute { vertex } => write!(
                f,
                "a normal or texture coordinate is NaN or infinite at vertex {vertex} (0-based)"
            ),
            MeshProblem::IndexOutOfRange { triangle } => {
                write!(
                    f,
                    "triangle {triangle} (0-based) names a vertex that does not exist"
                )
            }
            MeshProblem::Degenerate { first, count } => write!(
                f,
                "{count} degenerate (zero-area) triangle(s), the first is triangle {first} (0-based)"
            ),
            MeshProblem::AttributeLength => {
                write!(
                    f,
                    "normals or texture coordinates do not match the vertex count"
                )
            }
        }
    }
}

/// Relative area below which a triangle counts as degenerate: `|e1 × e2| ≤ ε · max|e|²`.
const DEGENERATE_RELATIVE_AREA: f32 = 1e-7;

impl TriangleMesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corner positions of triangle `t`.
    pub fn triangle_positions(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }

    /// Geometric (unnormalized) normal of triangle `t`: `(b − a) × (c − a)`, twice the area.
    pub fn triangle_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangle_positions(t);
        (b - a).cross(c - a)
    }

    /// Axis-aligned bounds `(min, max)`; `None` for a mesh without vertices.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), &p| (lo.min(p), hi.max(p))),
        )
    }

    /// Total surface area in square metres.
    pub fn area(&self) -> f32 {
        (0..self.triangles.len())
            .map(|t| 0.5 * self.triangle_normal(t).length())
            .sum()
    }

    /// Whether triangle `t` has zero area relative to its edge lengths.
    pub fn is_degenerate(&self, t: usize) -> bool {
        let [i, j, k] = self.triangles[t];
        if i == j || j == k || i == k {
            return true;
        }
        let [a, b, c] = self.triangle_positions(t);
        let longest = (b - a)
            .length_squared()
            .max((c - b).length_squared())
            .max((a - c).length_squared());
        let cross = (b - a).cross(c - a).length();
        // Written so that a NaN area also counts as degenerate.
        cross.partial_cmp(&(DEGENERATE_RELATIVE_AREA * longest))
            != Some(std::cmp::Ordering::Greater)
    }

    /// Checks the mesh: finite positions and attributes, indices in range, no zero-area triangles.
    pub fn check(&self) -> Result<(), MeshProblem> {
        if self.triangles.is_empty() {
            return Err(MeshProblem::Empty);
        }
        if self.normals.len() != self.positions.len()
            || !(self.uvs.is_empty() || self.uvs.len() == self.positions.len())
        {
            return Err(MeshProblem::AttributeLength);
        }
        let bad: Vec<usize> = (0..self.positions.len())
            .filter(|&i| !self.positions[i].is_finite())
            .collect();
        if let Some(&vertex) = bad.first() {
            return Err(MeshProblem::NonFinitePosition {
                vertex,
                count: bad.len(),
            });
        }
        if let Some(vertex) = (0..self.positions.len()).find(|&i| {
            !self.normals[i].is_finite() || self.uvs.get(i).is_some_and(|uv| !uv.is_finite())
        }) {
            return Err(MeshProblem::NonFiniteAttribute { vertex });
        }
        let n = self.positions.len();
        if let Some(triangle) = self
            .triangles
            .iter()
            .position(|tri| tri.iter().any(|&i| i as usize >= n))
        {
            return Err(MeshProblem::IndexOutOfRange { triangle });
        }
        let degenerate: Vec<usize> = (0..self.triangles.len())
            .filter(|&t| self.is_degenerate(t))
            .collect();
        if let Some(&first) = degenerate.first() {
            return Err(MeshProblem::Degenerate {
                first,
                count: degenerate.len(),
            });
        }
        Ok(())
    }

    /// Removes zero-area triangles (see [`TriangleMesh::is_degenerate`]); returns how many.
    pub fn drop_degenerate(&mut self) -> usize {
        let before = self.triangles.len();
        let keep: Vec<bool> = (0..before).map(|t| !self.is_degenerate(t)).collect();
        let mut index = 0;
        self.triangles.retain(|_| {
            index += 1;
            keep[index - 1]
        });
        before - self.triangles.len()
    }

    /// Applies an affine transform: positions by `m`, normals by the inverse transpose of its
    /// linear part (renormalized). A transform that mirrors (negative determinant) also reverses
    /// the winding so that counter-clockwise stays the outward front face.
    pub fn transform(&mut self, m: &Affine3A) {
        let linear = Mat3::from(m.matrix3);
        let normal_matrix = linear.inverse().transpose();
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        for n in &mut self.normals {
            *n = (normal_matrix * *n).normalize_or_zero();
        }
        if linear.determinant() < 0.0 {
            for tri in &mut self.triangles {
                tri.swap(1, 2);
            }
        }
    }

    /// Turns the mesh inside out: reverses every triangle and negates every normal (a room seen
    /// from inside).
    pub fn flip(&mut self) {
        for tri in &mut self.triangles {
            tri.swap(1, 2);
        }
        for n in &mut self.normals {
            *n = -*n;
        }
    }

    /// Appends another mesh (attributes must agree: both with uvs or both without, else uvs are
    /// dropped).
    pub fn append(&mut self, other: &TriangleMesh) {
        let base = self.positions.len() as u32;
        let keep_uvs = (self.uvs.len() == self.positions.len() || self.positions.is_empty())
            && other.uvs.len() == other.positions.len()
            && !other.uvs.is_empty();
        self.positions.extend_from_slice(&other.positions);
        self.normals.extend_from_slice(&other.normals);
        if keep_uvs {
            self.uvs.extend_from_slice(&other.uvs);
        } else {
            self.uvs.clear();
        }
        self.triangles
            .extend(other.triangles.iter().map(|tri| tri.map(|i| i + base)));
    }

    /// Angle-weighted face normals summed at each vertex: the smooth normal of the surface
    /// around it. Vertices without a non-degenerate triangle get zero.
    pub fn accumulated_face_normals(&self) -> Vec<Vec3> {
        let mut sums = vec![Vec3::ZERO; self.positions.len()];
        for tri in &self.triangles {
            let p = tri.map(|i| self.positions[i as usize]);
            let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            if face == Vec3::ZERO {
                continue;
            }
            for corner in 0..3 {
                let e1 = (p[(corner + 1) % 3] - p[corner]).normalize_or_zero();
                let e2 = (p[(corner + 2) % 3] - p[corner]).normalize_or_zero();
                let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
                sums[tri[corner] as usize] += face * angle;
            }
        }
        sums
    }

    /// Replaces all normals by smooth angle-weighted vertex normals (see
    /// [`TriangleMesh::accumulated_face_normals`]); an isolated vertex gets +y.
    pub fn generate_smooth_normals(&mut self) {
        self.normals = self
            .accumulated_face_normals()
            .into_iter()
            .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
            .collect();
    }

    /// Replaces normals that are zero, too short or not finite by the smooth generated normal,
    /// and renormalizes the rest. Returns how many were replaced.
    pub fn repair_normals(&mut self) -> usize {
        if self.normals.len() != self.positions.len() {
            self.generate_smooth_normals();
            return self.positions.len();
        }
        let bad: Vec<usize> = (0..self.normals.len())
            .filter(|&i| {
                let n = self.normals[i];
                !n.is_finite() || n.length_squared() < 1e-12
            })
            .collect();
        if !bad.is_empty() {
            let smooth = self.accumulated_face_normals();
            for &i in &bad {
                self.normals[i] = smooth[i].try_normalize().unwrap_or(Vec3::Y);
            }
        }
        for n in &mut self.normals {
            *n = n.try_normalize().unwrap_or(Vec3::Y);
        }
        bad.len()
    }

    /// Merges vertices closer than `tolerance` metres (positions only; uvs are dropped because
    /// welded vertices may disagree). Normals of merged vertices are summed then renormalized.
    /// Triangles that collapse (two corners merged) are removed.
    pub fn weld(&mut self, tolerance: f32) {
        let cell = tolerance.max(f32::MIN_POSITIVE);
        let key = |p: Vec3| {
            let q = (p / cell).floor();
            (q.x as i64, q.y as i64, q.z as i64)
        };
        let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        let mut remap = vec![0u32; self.positions.len()];
        let mut positions: Vec<Vec3> = Vec::new();
        let mut normal_sums: Vec<Vec3> = Vec::new();
        for (i, &p) in self.positions.iter().enumerate() {
            let (kx, ky, kz) = key(p);
            let found = (-1..=1)
                .flat_map(|dx| {
                    (-1..=1).flat_map(move |dy| (-1..=1).map(move |dz| (kx + dx, ky + dy, kz + dz)))
                })
                .filter_map(|cell| grid.get(&cell))
                .flatten()
                .copied()
                .find(|&j| positions[j as usize].distance(p) <= tolerance);
            let j = found.unwrap_or_else(|| {
                let j = positions.len() as u32;
                positions.push(p);
                normal_sums.push(Vec3::ZERO);
                grid.entry((kx, ky, kz)).or_default().push(j);
                j
            });
            remap[i] = j;
            if let Some(n) = self.normals.get(i).filter(|n| n.is_finite()) {
                normal_sums[j as usize] += *n;
            }
        }
        self.positions = positions;
        self.normals = normal_sums;
        self.uvs.clear();
        self.triangles = self
            .triangles
            .iter()
            .map(|tri| tri.map(|i| remap[i as usize]))
            .filter(|[a, b, c]| a != b && b != c && a != c)
            .collect();
        self.repair_normals();
    }
    /// Whether the surface is closed and consistently oriented: with vertices identified by their
    /// positions quantized to 0.1 mm (so that meshes made of patches with duplicated seam
    /// vertices count as one surface), every directed edge is used by exactly one triangle and
    /// its reverse by exactly one other. An open mesh (a boundary, such as the Newell teapot's
    /// rim) can be seen from behind; a closed one only from inside. Two positions that round
    /// apart although they are the same to within 0.1 mm make a mesh count as open, never the
    /// reverse.
    pub fn is_closed(&self) -> bool {
        let quantize = |p: Vec3| {
            let q = (p * 1e4).round();
            (q.x as i64, q.y as i64, q.z as i64)
        };
        let mut edges: HashMap<_, u32> = HashMap::new();
        for tri in &self.triangles {
            for e in 0..3 {
                let a = quantize(self.positions[tri[e] as usize]);
                let b = quantize(self.positions[tri[(e + 1) % 3] as usize]);
                *edges.entry((a, b)).or_default() += 1;
            }
        }
        !edges.is_empty()
            && edges
                .iter()
                .all(|(&(a, b), &count)| count == 1 && edges.get(&(b, a)) == Some(&1))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::{Quat, Vec3A};

    /// Enclosed volume by the divergence theorem (positive when the front faces point out).
    pub(crate) fn signed_volume(mesh: &TriangleMesh) -> f64 {
        mesh.triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| mesh.positions[i as usize].as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    fn quad() -> TriangleMesh {
        TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            normals: vec![Vec3::Z; 4],
            uvs: vec![],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn transformed_normals_stay_perpendicular_to_transformed_tangents() {
        // A sheared, non-uniformly scaled, rotated frame: the normal must stay perpendicular to
        // both transformed edge directions (tangents), computed independently from the positions.
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, 3.0),
            Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 0.7),
            Vec3::new(1.0, 2.0, 3.0),
        ) * Affine3A::from_cols(Vec3A::X, Vec3A::new(0.4, 1.0, 0.0), Vec3A::Z, Vec3A::ZERO);
        let mut mesh = quad();
        mesh.transform(&m);
        for t in 0..2 {
            let [a, b, c] = mesh.triangle_positions(t);
            for &i in &mesh.triangles[t] {
                let n = mesh.normals[i as usize];
                assert!((n.length() - 1.0).abs() < 1e-5);
                assert!(n.dot((b - a).normalize()).abs() < 1e-5);
                assert!(n.dot((c - a).normalize()).abs() < 1e-5);
                // And it agrees with the winding (front face outward).
                assert!(n.dot(mesh.triangle_normal(t)) > 0.0);
            }
        }
    }

    #[test]
    fn mirroring_transform_keeps_winding_outward() {
        let mut mesh = quad();
        mesh.transform(&Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
        for t in 0..2 {
            let n = mesh.normals[mesh.triangles[t][0] as usize];
            assert!(n.dot(mesh.triangle_normal(t)) > 0.0);
        }
    }

    #[test]
    fn check_finds_nan_and_degenerate_triangles() {
        let mut mesh = quad();
        assert_eq!(mesh.check(), Ok(()));
        mesh.positions.push(Vec3::new(2.0, 0.0, 0.0));
        mesh.normals.push(Vec3::Z);
        mesh.triangles.push([0, 1, 4]); // collinear
        assert_eq!(
            mesh.check(),
            Err(MeshProblem::Degenerate { first: 2, count: 1 })
        );
        assert_eq!(mesh.drop_degenerate(), 1);
        assert_eq!(mesh.check(), Ok(()));
        mesh.positions[3].x = f32::NAN;
        assert_eq!(
            mesh.check(),
            Err(MeshProblem::NonFinitePosition {
                vertex: 3,
                count: 1
            })
        );
    }

    #[test]
    fn weld_merges_coincident_vertices() {
        let mut mesh = quad();
        // The same quad with split vertices.
        mesh.positions = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::ZERO,
            Vec3::new(1.0, 1.0, 1e-7),
            Vec3::Y,
        ];
        mesh.normals = vec![Vec3::Z; 6];
        mesh.triangles = vec![[0, 1, 2], [3, 4, 5]];
        mesh.weld(1e-5);
        assert_eq!(mesh.positions.len(), 4);
        assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(mesh.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    }
}
