//! The spherical Delaunay triangulation of a 2D view space: its samples' directions from the
//! view space's centre, triangulated once per scene, and where a camera direction falls in it
//! (reflection-space IBR §3.4: the three samples of the enclosing spherical triangle, weighted
//! by ratios of spherical triangle areas).
//!
//! For points on a sphere the Delaunay triangles are the faces of their convex hull: a face's
//! plane cuts the sphere in the triangle's circumcircle, and every other point lies on the
//! centre's side of it. A patch or a cap does not surround the centre, so the hull of its
//! directions alone would close the region with faces "across the hole", whose circumcircles
//! hold more than a hemisphere. Adding the centre to the hull removes exactly those: the faces
//! of hull(directions ∪ {centre}) not incident to the centre are the Delaunay triangles of the
//! region the samples span (within their spherical convex hull), and for samples surrounding the
//! centre they are the whole hull. Faces whose circumcircle is more than
//! [`MAX_CIRCUMRADIUS_SPACINGS`] times the samples' spacing are left out too: they would close a
//! hole the samples surround (above a ring, behind a cap past a hemisphere) or add a sliver
//! along a row that curves away from its great circle. Written here rather than taken from a
//! crate because the hull must keep these rules and be deterministic; the predicates are the
//! `robust` crate's exact ones, so co-circular samples (the four corners of every cell of an
//! azimuth × elevation patch) never disagree with themselves: each cell gets one diagonal,
//! chosen by insertion order.

use glam::DVec3;
use robust::{Coord3D, orient3d};
use rustc_hash::FxHashMap;

use crate::scene::Scene;

/// Angle between two directions, robust near 0 and π (atan2 of the cross and dot products).
pub fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Triangles smaller than this (steradians) are left out: three samples on one great circle up
/// to rounding (the samples of a patch's meridian), a face that spans no region.
pub const MIN_TRIANGLE_AREA: f64 = 1e-12;

/// Triangles whose circumcircle's angular radius is more than this many times the view space's
/// spacing (the largest angle from a sample to its nearest other sample) are left out: they span
/// a hole the samples surround (above a ring of samples, behind a cap past a hemisphere) or a
/// sliver along a row that curves away from its great circle, not the region the samples cover.
/// A cell of a patch or a Fibonacci cap has a circumradius under one spacing.
pub const MAX_CIRCUMRADIUS_SPACINGS: f64 = 2.0;

/// A weight below this (of 1) is dropped and the rest renormalized: a direction this close to an
/// edge blends its two samples, this close to a sample that sample alone.
pub const NEGLIGIBLE_WEIGHT: f64 = 1e-6;

/// The triangulated region of a 2D view space.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereTriangulation {
    /// Unit directions of the samples, in sample order.
    directions: Vec<DVec3>,
    /// Triangles (sample indices), counter-clockwise seen from outside the sphere, in the order
    /// the hull made them.
    triangles: Vec<[usize; 3]>,
    /// The region's boundary: edges on one triangle only, `(a, b)` in that triangle's order.
    boundary: Vec<[usize; 2]>,
    /// The largest, over samples, of each sample's angle to its nearest other sample, radians.
    spacing_radians: f64,
}

/// Where a direction falls in a [`SphereTriangulation`].
#[derive(Clone, Debug, PartialEq)]
pub struct Location {
    /// `(sample, weight)`: the one, two or three samples of the point used, weights summing to
    /// 1, largest first (ties by index).
    pub weights: Vec<(usize, f64)>,
    /// Whether the direction lies in no triangle: then `weights` are those of the nearest point
    /// of the region (on its boundary).
    pub outside: bool,
    /// The angle from the direction to the region, radians: 0 inside, else to the nearest point
    /// of the boundary.
    pub outside_radians: f64,
}

fn coord(p: DVec3) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// Exact orientation: negative when `p` lies on the side of plane (a, b, c) from which a, b, c
/// appear counter-clockwise ("above"), positive below, zero on the plane.
fn orient(a: DVec3, b: DVec3, c: DVec3, p: DVec3) -> f64 {
    orient3d(coord(a), coord(b), coord(c), coord(p))
}

/// The spherical excess (area on the unit sphere) of triangle (a, b, c), signed by orientation
/// (positive counter-clockwise seen from outside): Van Oosterom and Strackee's formula.
fn signed_area(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let triple = a.dot(b.cross(c));
    2.0 * triple.atan2(1.0 + a.dot(b) + b.dot(c) + c.dot(a))
}

impl SphereTriangulation {
    /// Triangulates the directions from `centre` to `positions`. `None` when they span no
    /// spherical triangle: fewer than three samples, or all of them (with the centre) on one
    /// plane, i.e. on one great circle. The caller checks that no two samples share a direction
    /// (a duplicate is never a vertex of the hull, so it would get no weight).
    pub fn new(positions: &[DVec3], centre: DVec3) -> Option<SphereTriangulation> {
        let directions: Vec<DVec3> = positions
            .iter()
            .map(|p| (*p - centre).normalize_or_zero())
            .collect();
        if directions.len() < 3
            || directions
                .iter()
                .any(|d| *d == DVec3::ZERO || !d.is_finite())
        {
            return None;
        }
        let faces: Vec<[usize; 3]> = Hull::new(&directions)?
            .faces
            .into_iter()
            .flatten()
            .collect();
        let origin = directions.len();
        let spacing_radians = nearest_neighbour_spacing(&directions, &faces);
        let triangles: Vec<[usize; 3]> = faces
            .into_iter()
            .filter(|f| {
                !f.contains(&origin)
                    && orient(
                        directions[f[0]],
                        directions[f[1]],
                        directions[f[2]],
                        DVec3::ZERO,
                    ) > 0.0
                    && signed_area(directions[f[0]], directions[f[1]], directions[f[2]])
                        > MIN_TRIANGLE_AREA
                    && circumradius(directions[f[0]], directions[f[1]], directions[f[2]])
                        <= MAX_CIRCUMRADIUS_SPACINGS * spacing_radians
            })
            .collect();
        if triangles.is_empty() {
            return None;
        }
        let mut edges: FxHashMap<(usize, usize), usize> = FxHashMap::default();
        for t in &triangles {
            for k in 0..3 {
                edges.insert((t[k], t[(k + 1) % 3]), 0);
            }
        }
        let boundary = triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| [t[k], t[(k + 1) % 3]]))
            .filter(|[a, b]| !edges.contains_key(&(*b, *a)))
            .collect();
        Some(SphereTriangulation {
            spacing_radians,
            directions,
            triangles,
            boundary,
        })
    }

    /// The triangulation of `scene`'s view space (all its samples about its centre), `None` for
    /// a 1D view space (a circle) or one that spans no spherical triangle.
    pub fn of_scene(scene: &Scene) -> Option<SphereTriangulation> {
        if !scene.view_space.is_surface() {
            return None;
        }
        let centre = scene.view_space.centre(scene.camera.look_at).as_dvec3();
        let samples: Vec<DVec3> = scene
            .view_space
            .samples()
            .iter()
            .map(|p| p.as_dvec3())
            .collect();
        SphereTriangulation::new(&samples, centre)
    }

    /// The triangles, as sample indices counter-clockwise seen from outside the sphere.
    pub fn triangles(&self) -> &[[usize; 3]] {
        &self.triangles
    }

    /// The region's boundary edges (each on one triangle only).
    pub fn boundary(&self) -> &[[usize; 2]] {
        &self.boundary
    }

    /// The samples that share a triangle edge with `sample`, in index order (empty for a sample
    /// no triangle uses).
    pub fn neighbours(&self, sample: usize) -> Vec<usize> {
        let mut out: Vec<usize> = self
            .triangles
            .iter()
            .filter(|t| t.contains(&sample))
            .flat_map(|t| t.iter().copied())
            .filter(|&s| s != sample)
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The largest, over samples, of each sample's angle to its nearest other sample, radians.
    pub fn spacing_radians(&self) -> f64 {
        self.spacing_radians
    }

    /// The total area of the region, steradians.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                signed_area(
                    self.directions[t[0]],
                    self.directions[t[1]],
                    self.directions[t[2]],
                )
            })
            .sum()
    }

    /// Where the direction `direction` (any length > 0) falls: the triangle holding it with
    /// spherical barycentric weights (the area of the sub-triangle opposite each vertex over
    /// their sum), or, outside every triangle, the nearest point of the region's boundary with
    /// its two (or one) samples weighted by arc length. Weights under [`NEGLIGIBLE_WEIGHT`] are
    /// dropped. `None` for a zero or non-finite direction.
    pub fn locate(&self, direction: DVec3) -> Option<Location> {
        let v = direction.normalize_or_zero();
        if v == DVec3::ZERO || !v.is_finite() {
            return None;
        }
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.directions[i]);
            // Inside: on the inner side of each edge's great circle (or on it).
            let inside = [(a, b), (b, c), (c, a)]
                .iter()
                .all(|(p, q)| v.dot(p.cross(*q)) >= -1e-12);
            if !inside {
                continue;
            }
            let areas = [
                signed_area(v, b, c).max(0.0),
                signed_area(a, v, c).max(0.0),
                signed_area(a, b, v).max(0.0),
            ];
            return Some(Location {
                weights: normalized(t.iter().copied().zip(areas)),
                outside: false,
                outside_radians: 0.0,
            });
        }
        let (weights, radians) = self.nearest_on_boundary(v);
        Some(Location {
            weights,
            outside: true,
            outside_radians: radians,
        })
    }

    /// The nearest point of the boundary to unit direction `v`: its samples' weights and its
    /// angle from `v`. Ties go to the earlier edge.
    fn nearest_on_boundary(&self, v: DVec3) -> (Vec<(usize, f64)>, f64) {
        let mut best: Option<(f64, Vec<(usize, f64)>)> = None;
        for &[i, j] in &self.boundary {
            let (a, b) = (self.directions[i], self.directions[j]);
            let span = angle(a, b);
            let normal = a.cross(b).normalize_or_zero();
            // The nearest point of the great circle; none when v is (up to rounding) its pole,
            // where every point of it is 90° away and the ends decide.
            let residual = v - v.dot(normal) * normal;
            let projected = if residual.length() > 1e-9 {
                residual.normalize()
            } else {
                DVec3::ZERO
            };
            // The projection lies on the arc (shorter than π) when it is on the inner side of
            // both ends: a → p and p → b turn the same way as a → b.
            let on_arc = projected != DVec3::ZERO
                && normal.dot(a.cross(projected)) >= 0.0
                && normal.dot(projected.cross(b)) >= 0.0;
            let (point, weights) = if on_arc {
                let to_b = angle(projected, b) / span;
                (projected, vec![(i, to_b), (j, 1.0 - to_b)])
            } else if angle(v, a) <= angle(v, b) {
                (a, vec![(i, 1.0)])
            } else {
                (b, vec![(j, 1.0)])
            };
            let distance = angle(v, point);
            if best.as_ref().is_none_or(|(d, _)| distance < *d) {
                best = Some((distance, weights));
            }
        }
        match best {
            Some((distance, weights)) => (normalized(weights.into_iter()), distance),
            // A triangulation always has a boundary unless it closes the sphere, and then every
            // direction is in a triangle; kept total for rounding at the very edge.
            None => (vec![(self.triangles[0][0], 1.0)], 0.0),
        }
    }
}

/// The angular radius of the circumcircle of the unit directions a, b, c: the angle from the
/// normal of their plane to any of them.
fn circumradius(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let normal = (b - a).cross(c - a).normalize_or_zero();
    angle(normal, a).min(angle(-normal, a))
}

/// The largest, over samples, of each sample's angle to its nearest other sample. A sample's
/// nearest neighbour is always joined to it by a Delaunay edge, so the hull's edges (the centre's
/// left out) hold every nearest pair: O(faces), not O(samples²).
fn nearest_neighbour_spacing(directions: &[DVec3], faces: &[[usize; 3]]) -> f64 {
    let mut nearest = vec![f64::INFINITY; directions.len()];
    for f in faces {
        for k in 0..3 {
            let (i, j) = (f[k], f[(k + 1) % 3]);
            if i < directions.len() && j < directions.len() {
                let a = angle(directions[i], directions[j]);
                nearest[i] = nearest[i].min(a);
                nearest[j] = nearest[j].min(a);
            }
        }
    }
    nearest
        .into_iter()
        .filter(|a| a.is_finite())
        .fold(0.0, f64::max)
}

/// Weights divided by their sum, negligible ones dropped, largest first (ties by index).
fn normalized(weights: impl Iterator<Item = (usize, f64)>) -> Vec<(usize, f64)> {
    let weights: Vec<(usize, f64)> = weights.collect();
    let total: f64 = weights.iter().map(|(_, w)| w).sum();
    let mut kept: Vec<(usize, f64)> = weights
        .into_iter()
        .map(|(i, w)| (i, w / total))
        .filter(|(_, w)| *w >= NEGLIGIBLE_WEIGHT)
        .collect();
    let kept_total: f64 = kept.iter().map(|(_, w)| w).sum();
    for (_, w) in &mut kept {
        *w /= kept_total;
    }
    kept.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    kept
}

/// The convex hull of unit directions and the origin (index `directions.len()`), built
/// incrementally in index order with exact predicates.
struct Hull {
    /// Faces counter-clockwise from outside; `None` once removed.
    faces: Vec<Option<[usize; 3]>>,
}

impl Hull {
    /// `None` when every point lies on one plane.
    fn new(directions: &[DVec3]) -> Option<Hull> {
        let mut points = directions.to_vec();
        points.push(DVec3::ZERO);
        let n = points.len();
        // The first tetrahedron: point 0, the first point other than it, the first not on their
        // line (by a non-zero cross product; a near-collinear pick still gives an exact
        // orientation below), the first not on their plane (exactly).
        let i0 = 0;
        let i1 = (1..n).find(|&k| points[k] != points[i0])?;
        let i2 = (i1 + 1..n).find(|&k| {
            (points[k] - points[i0])
                .cross(points[i1] - points[i0])
                .length_squared()
                > 0.0
        })?;
        let i3 = (2..n)
            .find(|&k| k != i2 && orient(points[i0], points[i1], points[i2], points[k]) != 0.0)?;
        // Counter-clockwise from outside: the fourth point below each face.
        let (b, c) = if orient(points[i0], points[i1], points[i2], points[i3]) > 0.0 {
            (i1, i2)
        } else {
            (i2, i1)
        };
        let mut hull = Hull { faces: Vec::new() };
        let mut edges: FxHashMap<(usize, usize), usize> = FxHashMap::default();
        for face in [[i0, b, c], [i0, c, i3], [i0, i3, b], [b, i3, c]] {
            hull.add(face, &mut edges);
        }
        for p in (0..n).filter(|k| ![i0, i1, i2, i3].contains(k)) {
            let visible: Vec<usize> = hull
                .faces
                .iter()
                .enumerate()
                .filter_map(|(f, face)| {
                    let [a, b, c] = (*face)?;
                    (orient(points[a], points[b], points[c], points[p]) < 0.0).then_some(f)
                })
                .collect();
            if visible.is_empty() {
                continue;
            }
            let is_visible = |f: usize| visible.binary_search(&f).is_ok();
            let mut horizon = Vec::new();
            for &f in &visible {
                let Some(face) = hull.faces[f] else { continue };
                for k in 0..3 {
                    let (u, v) = (face[k], face[(k + 1) % 3]);
                    if edges.get(&(v, u)).is_some_and(|&g| !is_visible(g)) {
                        horizon.push((u, v));
                    }
                }
            }
            for &f in &visible {
                if let Some(face) = hull.faces[f].take() {
                    for k in 0..3 {
                        edges.remove(&(face[k], face[(k + 1) % 3]));
                    }
                }
            }
            for (u, v) in horizon {
                hull.add([u, v, p], &mut edges);
            }
        }
        Some(hull)
    }

    fn add(&mut self, face: [usize; 3], edges: &mut FxHashMap<(usize, usize), usize>) {
        let index = self.faces.len();
        for k in 0..3 {
            edges.insert((face[k], face[(k + 1) % 3]), index);
        }
        self.faces.push(Some(face));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The direction at `azimuth` degrees about +y (from +z towards +x) and `elevation` degrees
    /// above the horizontal.
    fn direction(azimuth: f64, elevation: f64) -> DVec3 {
        let (a, e) = (azimuth.to_radians(), elevation.to_radians());
        DVec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
    }

    fn patch(azimuths: &[f64], elevations: &[f64]) -> Vec<DVec3> {
        elevations
            .iter()
            .flat_map(|&e| azimuths.iter().map(move |&a| direction(a, e)))
            .collect()
    }

    /// The 12 vertices of an icosahedron (the reflection-space IBR paper's view samples).
    fn icosahedron() -> Vec<DVec3> {
        let g = (1.0 + 5f64.sqrt()) / 2.0;
        let mut v = Vec::new();
        for (s, t) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
            v.push(DVec3::new(0.0, s, t * g));
            v.push(DVec3::new(s, t * g, 0.0));
            v.push(DVec3::new(t * g, 0.0, s));
        }
        v.into_iter().map(|p| p.normalize()).collect()
    }

    #[test]
    fn a_patch_is_covered_once_with_no_face_across_the_hole() {
        let samples = patch(&[-10.0, 0.0, 10.0], &[0.0, 10.0, 20.0]);
        let t = SphereTriangulation::new(&samples, DVec3::ZERO).unwrap();
        // A 3 × 3 grid: 4 cells of 2 triangles. The great circle through the top row's ends
        // runs poleward of its middle sample (by 0.28°): the hull has a sliver face there, whose
        // circumcircle (the 20° latitude circle, 70° in radius) is far past twice the 10°
        // spacing, so it is left out, and the bottom row lies on the equator (no face).
        assert_eq!(t.triangles().len(), 8, "{:?}", t.triangles());
        assert!((t.spacing_radians() - 10f64.to_radians()).abs() < 1e-9);
        // The region: the spherical quad of the corners less the top row's sliver.
        let corners = [samples[0], samples[2], samples[8], samples[6]];
        let hull_area = signed_area(corners[0], corners[1], corners[2])
            + signed_area(corners[0], corners[2], corners[3]);
        let sliver = signed_area(samples[6], samples[7], samples[8]).abs();
        assert!(sliver > 0.0);
        assert!(
            (t.area() - (hull_area - sliver)).abs() < 1e-12,
            "{} vs {hull_area} − {sliver}",
            t.area()
        );
        // 8 boundary edges round the outside, every sample on a triangle.
        assert_eq!(t.boundary().len(), 8, "{:?}", t.boundary());
        for s in 0..9 {
            assert!(!t.neighbours(s).is_empty(), "sample {s}");
        }
        // The centre sample touches its 4 grid neighbours and one or two diagonals.
        let centre = t.neighbours(4);
        for n in [1, 3, 5, 7] {
            assert!(centre.contains(&n), "{centre:?}");
        }
    }

    #[test]
    fn samples_round_the_centre_close_the_sphere() {
        let t = SphereTriangulation::new(&icosahedron(), DVec3::ZERO).unwrap();
        assert_eq!(t.triangles().len(), 20);
        assert!(t.boundary().is_empty());
        assert!((t.area() - 4.0 * std::f64::consts::PI).abs() < 1e-9);
        for s in 0..12 {
            assert_eq!(t.neighbours(s).len(), 5);
        }
        // Every direction is inside.
        for k in 0..200 {
            let d = direction(k as f64 * 37.0, (k as f64 * 13.0) % 180.0 - 90.0);
            let at = t.locate(d).unwrap();
            assert!(!at.outside, "{d}");
            assert!(at.weights.len() <= 3);
        }
    }

    #[test]
    fn barycentric_weights_reproduce_the_direction() {
        let samples = patch(&[-10.0, 0.0, 10.0], &[0.0, 10.0, 20.0]);
        let t = SphereTriangulation::new(&samples, DVec3::ZERO).unwrap();
        // At a sample: that sample alone.
        let at = t.locate(samples[4] * 3.0).unwrap();
        assert_eq!(at.weights, vec![(4, 1.0)]);
        // On an edge (halfway along the bottom row's great circle): its two samples, about
        // halves (area ratios, not arc lengths: the third vertex shapes them slightly).
        let mid = (samples[0] + samples[1]).normalize();
        let at = t.locate(mid).unwrap();
        assert_eq!(at.weights.len(), 2, "{at:?}");
        assert_eq!(
            [
                at.weights[0].0.min(at.weights[1].0),
                at.weights[0].0.max(at.weights[1].0)
            ],
            [0, 1]
        );
        assert!((at.weights[0].1 - 0.5).abs() < 0.02, "{at:?}");
        assert!(!at.outside);
        // Inside a triangle: three samples whose weighted sum points near the direction, and
        // the weights sum to 1.
        let inside = direction(-3.0, 4.0);
        let at = t.locate(inside).unwrap();
        assert_eq!(at.weights.len(), 3, "{at:?}");
        let total: f64 = at.weights.iter().map(|w| w.1).sum();
        assert!((total - 1.0).abs() < 1e-12);
        let mix: DVec3 = at.weights.iter().map(|&(i, w)| w * samples[i]).sum();
        assert!(
            angle(mix, inside) < 0.3f64.to_radians(),
            "{}",
            angle(mix, inside).to_degrees()
        );
        // Continuity across an interior edge: both sides give nearly the same weights (area
        // ratios of the two triangles agree on their shared edge to second order in its size).
        let left = t.locate(direction(-5.0, 10.0 - 1e-7)).unwrap();
        let right = t.locate(direction(-5.0, 10.0 + 1e-7)).unwrap();
        let weight_of =
            |l: &Location, s: usize| l.weights.iter().find(|w| w.0 == s).map_or(0.0, |w| w.1);
        for s in 0..9 {
            assert!(
                (weight_of(&left, s) - weight_of(&right, s)).abs() < 2e-3,
                "{left:?} {right:?}"
            );
        }
    }

    #[test]
    fn outside_takes_the_nearest_point_of_the_region() {
        let samples = patch(&[-10.0, 0.0, 10.0], &[0.0, 10.0, 20.0]);
        let t = SphereTriangulation::new(&samples, DVec3::ZERO).unwrap();
        // 5° below the bottom row, between samples 0 and 1: their great circle is the equator.
        let at = t.locate(direction(-5.0, -5.0)).unwrap();
        assert!(at.outside);
        assert!(
            (at.outside_radians - 5f64.to_radians()).abs() < 1e-9,
            "{at:?}"
        );
        assert_eq!(at.weights.len(), 2);
        assert!((at.weights[0].1 - 0.5).abs() < 1e-9, "{at:?}");
        // Far beyond a corner: the corner sample alone.
        let at = t.locate(direction(40.0, -30.0)).unwrap();
        assert!(at.outside);
        assert_eq!(at.weights, vec![(2, 1.0)]);
        // Straight up, above the top row.
        let at = t.locate(DVec3::Y).unwrap();
        assert!(
            at.outside && at.outside_radians > 60f64.to_radians(),
            "{at:?}"
        );
    }

    #[test]
    fn a_ring_leaves_its_hole_open() {
        // 12 columns all round, 0–30° of elevation: the band, not the cap above it.
        let azimuths: Vec<f64> = (0..12).map(|i| i as f64 * 30.0).collect();
        let samples = patch(&azimuths, &[0.0, 15.0, 30.0]);
        let t = SphereTriangulation::new(&samples, DVec3::ZERO).unwrap();
        let up = t.locate(DVec3::Y).unwrap();
        assert!(up.outside, "{up:?}");
        assert!(
            (up.outside_radians.to_degrees() - 60.0).abs() < 1.0,
            "{up:?}"
        );
        let band = t.locate(direction(5.0, 10.0)).unwrap();
        assert!(!band.outside && band.weights.len() == 3, "{band:?}");
        // The band is 24 cells of two triangles.
        assert_eq!(t.triangles().len(), 48);
    }

    #[test]
    fn an_edge_longer_than_a_third_of_the_circle_keeps_far_points_outside() {
        // Three samples far apart: a direction beyond one end of the long edge is nearest to
        // that end, not "on" the edge.
        let samples = [
            direction(-75.0, 0.0),
            direction(75.0, 0.0),
            direction(0.0, 30.0),
        ];
        let t = SphereTriangulation::new(&samples, DVec3::ZERO).unwrap();
        let far = t.locate(direction(-165.0, 0.0)).unwrap();
        assert!(far.outside);
        assert!(
            (far.outside_radians.to_degrees() - 90.0).abs() < 1e-6,
            "{far:?}"
        );
        assert_eq!(far.weights, vec![(0, 1.0)]);
    }

    #[test]
    fn samples_on_one_great_circle_span_no_triangle() {
        let equator = patch(&[0.0, 10.0, 20.0, 30.0], &[0.0]);
        assert!(SphereTriangulation::new(&equator, DVec3::ZERO).is_none());
        assert!(SphereTriangulation::new(&equator[..2], DVec3::ZERO).is_none());
        // A small circle is not a great circle: it spans its cap.
        let ring = patch(&[0.0, 90.0, 180.0, 270.0], &[30.0]);
        let t = SphereTriangulation::new(&ring, DVec3::ZERO).unwrap();
        assert_eq!(t.triangles().len(), 2);
        assert!(
            SphereTriangulation::new(&[DVec3::X, DVec3::Y, DVec3::ZERO], DVec3::ZERO).is_none()
        );
    }

    #[test]
    fn the_triangulation_is_deterministic_and_delaunay() {
        // A Fibonacci cap of 40 samples, 50° round +z.
        let samples: Vec<DVec3> = (0..40)
            .map(|i| {
                let z = 1.0 - (1.0 - 50f64.to_radians().cos()) * (i as f64 + 0.5) / 40.0;
                let phi = i as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
                let r = (1.0 - z * z).sqrt();
                DVec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        let a = SphereTriangulation::new(&samples, DVec3::ZERO).unwrap();
        let b = SphereTriangulation::new(&samples, DVec3::ZERO).unwrap();
        assert_eq!(a, b);
        // Empty circumcircles: every other sample on the centre's side of each face's plane.
        for t in a.triangles() {
            let [p, q, r] = t.map(|i| samples[i]);
            for (k, s) in samples.iter().enumerate() {
                if !t.contains(&k) {
                    assert!(
                        orient(p, q, r, *s) >= 0.0,
                        "sample {k} inside the circumcircle of {t:?}"
                    );
                }
            }
        }
        // Euler: a triangulated disc of V vertices with B on its boundary has 2V − B − 2 faces.
        let v = 40;
        let boundary = a.boundary().len();
        assert_eq!(a.triangles().len(), 2 * v - boundary - 2);
    }
}
