//! The view samples of glossy objects' radiance maps (§3.1): unit directions from the object
//! towards the viewer, by default the 12 vertices of an icosahedron, "desirable because its
//! symmetry means that each viewpoint is handled in an unbiased manner", or its geodesic
//! subdivisions (42, 162, …); triangulated once ([`SphereTriangulation`]), and how a frame's view
//! direction picks and weights them under each [`Reconstruction`].

use glam::{DMat3, DVec3};

use crate::hybrid::sphere::SphereTriangulation;
use crate::hybrid::sphere::angle;

/// View samples of the default view space: the icosahedron's vertices.
pub const DEFAULT_VIEW_COUNT: usize = 12;

/// The geodesic view-sample counts: an icosahedron subdivided `level` times has
/// `10·4^level + 2` vertices (12, 42, 162, 642).
pub const GEODESIC_COUNTS: [usize; 4] = [12, 42, 162, 642];

/// How a frame reconstructs a radiance map from the samples: the paper's method and the two
/// baselines that show what its warp buys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reconstruction {
    /// The three samples of the spherical triangle holding the view, each warped into the
    /// view's reflection space, blended by spherical barycentric weights (§3.2–3.4).
    Warped,
    /// The nearest sample alone, unwarped: its map used as if it had been made for the current
    /// view (its content turns with the viewer).
    NearestUnwarped,
    /// The same three samples and weights as [`Reconstruction::Warped`], each unwarped.
    BlendedUnwarped,
}

impl Reconstruction {
    /// All three, the paper's first.
    pub const ALL: [Reconstruction; 3] = [
        Reconstruction::Warped,
        Reconstruction::NearestUnwarped,
        Reconstruction::BlendedUnwarped,
    ];

    /// The name the command line and the reports use.
    pub fn name(self) -> &'static str {
        match self {
            Reconstruction::Warped => "warped",
            Reconstruction::NearestUnwarped => "nearest-unwarped",
            Reconstruction::BlendedUnwarped => "blended-unwarped",
        }
    }

    /// The reconstruction named `name` ([`Reconstruction::name`]).
    pub fn from_name(name: &str) -> Option<Reconstruction> {
        Reconstruction::ALL.into_iter().find(|r| r.name() == name)
    }
}

/// One sample a frame uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewSlot {
    /// The sample's index.
    pub sample: usize,
    /// Its spherical barycentric weight (the slots' weights sum to 1).
    pub weight: f64,
    /// Turns a lookup direction of the current view into the sample's map: the identity when
    /// warped (the maps are indexed by world-space central directions, so the paper's
    /// `T_d⁻¹·T_s` warp is the lookup itself); unwarped, the rotation taking the current view
    /// direction to the sample's, so that the map is read as if made for the current view.
    pub rotation: DMat3,
}

/// The view samples of glossy objects' radiance maps, triangulated.
#[derive(Clone, Debug, PartialEq)]
pub struct GlossyViews {
    directions: Vec<DVec3>,
    triangulation: SphereTriangulation,
}

impl GlossyViews {
    /// The geodesic view space of `count` samples (one of [`GEODESIC_COUNTS`]); `None` for
    /// another count.
    pub fn geodesic(count: usize) -> Option<GlossyViews> {
        let level = GEODESIC_COUNTS.iter().position(|&c| c == count)?;
        GlossyViews::new(geodesic_directions(level as u32))
    }

    /// The samples along `directions` (made unit), triangulated; `None` when they span no
    /// spherical triangle.
    pub fn new(directions: Vec<DVec3>) -> Option<GlossyViews> {
        let directions: Vec<DVec3> = directions.iter().map(|d| d.normalize_or_zero()).collect();
        let triangulation = SphereTriangulation::new(&directions, DVec3::ZERO)?;
        Some(GlossyViews {
            directions,
            triangulation,
        })
    }

    /// The unit view directions, by sample.
    pub fn directions(&self) -> &[DVec3] {
        &self.directions
    }

    /// The spherical triangles.
    pub fn triangles(&self) -> &[[usize; 3]] {
        self.triangulation.triangles()
    }

    /// The samples a frame seen along `view` (from the object towards the viewer, of any
    /// non-zero length) uses under `reconstruction`: one to three slots, largest weight first.
    /// `None` for a zero or non-finite view.
    pub fn slots(&self, view: DVec3, reconstruction: Reconstruction) -> Option<Vec<ViewSlot>> {
        let view = view.normalize_or_zero();
        if view == DVec3::ZERO || !view.is_finite() {
            return None;
        }
        let weights = match reconstruction {
            Reconstruction::NearestUnwarped => {
                let nearest = (0..self.directions.len()).min_by(|&a, &b| {
                    angle(view, self.directions[a]).total_cmp(&angle(view, self.directions[b]))
                })?;
                vec![(nearest, 1.0)]
            }
            _ => self.triangulation.locate(view)?.weights,
        };
        Some(
            weights
                .into_iter()
                .map(|(sample, weight)| ViewSlot {
                    sample,
                    weight,
                    rotation: match reconstruction {
                        Reconstruction::Warped => DMat3::IDENTITY,
                        _ => rotation_between(view, self.directions[sample]),
                    },
                })
                .collect(),
        )
    }
}

/// The rotation about `from × to` taking unit `from` to unit `to` (the smallest one); about any
/// axis perpendicular to `from` when they are opposite.
pub fn rotation_between(from: DVec3, to: DVec3) -> DMat3 {
    let axis = from.cross(to);
    let sin = axis.length();
    let cos = from.dot(to);
    if sin < 1e-12 {
        if cos > 0.0 {
            return DMat3::IDENTITY;
        }
        return DMat3::from_axis_angle(from.any_orthonormal_vector(), std::f64::consts::PI);
    }
    DMat3::from_axis_angle(axis / sin, sin.atan2(cos))
}

/// The vertices of an icosahedron subdivided `level` times (each triangle into four, midpoints
/// pushed onto the sphere): `10·4^level + 2` unit directions, the icosahedron's 12 first.
pub fn geodesic_directions(level: u32) -> Vec<DVec3> {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut points: Vec<DVec3> = Vec::new();
    for (a, b) in [(-1.0, phi), (1.0, phi), (-1.0, -phi), (1.0, -phi)] {
        points.push(DVec3::new(0.0, a, b));
        points.push(DVec3::new(a, b, 0.0));
        points.push(DVec3::new(b, 0.0, a));
    }
    let mut points: Vec<DVec3> = points.into_iter().map(DVec3::normalize).collect();
    // The 20 faces: the triples whose three edges have the icosahedron's edge length (the
    // shortest distance between vertices).
    let edge = points[1..]
        .iter()
        .map(|p| p.distance(points[0]))
        .fold(f64::INFINITY, f64::min);
    let adjacent = |a: DVec3, b: DVec3| (a.distance(b) - edge).abs() < 1e-9;
    let mut faces = Vec::new();
    for i in 0..12 {
        for j in i + 1..12 {
            for k in j + 1..12 {
                if adjacent(points[i], points[j])
                    && adjacent(points[j], points[k])
                    && adjacent(points[i], points[k])
                {
                    faces.push([i, j, k]);
                }
            }
        }
    }
    for _ in 0..level {
        let mut midpoints: rustc_hash::FxHashMap<(usize, usize), usize> = Default::default();
        let mut midpoint = |a: usize, b: usize, points: &mut Vec<DVec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                points.push((points[a] + points[b]).normalize());
                points.len() - 1
            })
        };
        let mut finer = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = midpoint(a, b, &mut points);
            let bc = midpoint(b, c, &mut points);
            let ca = midpoint(c, a, &mut points);
            finer.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        faces = finer;
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geodesic_spheres_have_the_counts_and_triangles_euler_says() {
        for (level, &count) in GEODESIC_COUNTS[..3].iter().enumerate() {
            let views = GlossyViews::geodesic(count).expect("a geodesic view space");
            assert_eq!(views.directions().len(), count);
            assert_eq!(geodesic_directions(level as u32).len(), count);
            // A closed triangulated sphere: F = 2V − 4.
            assert_eq!(views.triangles().len(), 2 * count - 4, "level {level}");
        }
        assert!(GlossyViews::geodesic(13).is_none());
    }

    #[test]
    fn slots_weigh_like_the_paper_and_unwarp_by_rotation() {
        let views = GlossyViews::geodesic(12).unwrap();
        let [a, b, c] = views.triangles()[0].map(|i| views.directions()[i]);
        let inside = (a + 2.0 * b + 3.0 * c).normalize();
        let warped = views.slots(inside, Reconstruction::Warped).unwrap();
        assert_eq!(warped.len(), 3);
        assert!((warped.iter().map(|s| s.weight).sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(warped.iter().all(|s| s.rotation == DMat3::IDENTITY));
        let unwarped = views
            .slots(inside, Reconstruction::BlendedUnwarped)
            .unwrap();
        for (w, u) in warped.iter().zip(&unwarped) {
            assert_eq!((w.sample, w.weight), (u.sample, u.weight));
            let to = views.directions()[u.sample];
            assert!((u.rotation * inside - to).length() < 1e-12);
        }
        let nearest = views
            .slots(inside, Reconstruction::NearestUnwarped)
            .unwrap();
        assert_eq!(nearest.len(), 1);
        assert_eq!(nearest[0].sample, views.triangles()[0][2]);
        // On a sample: that sample alone.
        let on = views.slots(a, Reconstruction::Warped).unwrap();
        assert_eq!((on.len(), on[0].sample), (1, views.triangles()[0][0]));
    }
}
