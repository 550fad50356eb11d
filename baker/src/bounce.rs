//! Layers by bounce (the PEM paper §4, "Layered EMs") for a reflector: a **local** layer on the
//! volume-minimising axis-aligned bounding ellipsoid of the lens objects its first bounces see,
//! and a **distant** layer on a box fitted to the environment its first bounces reach through
//! them.
//!
//! **The ellipsoid.** The paper centres it on the object's centroid and finds the axis scales of
//! least volume "using brute force optimization"; so does lensmap. With radii `s·(u, v, 1)` the
//! smallest `s` that holds every vertex is `max √((x/u)² + (y/v)² + z²)`, so the volume
//! `u·v·s³` is a function of the two ratios alone: searched on a 65 × 65 grid of
//! log-ratios over [e⁻⁴, e⁴], then three times on a 17 × 17 grid around the best,
//! each a quarter as wide (a resolution of 1.7e-4 in log-ratio, a volume within ~1e-7 of the grid's
//! optimum). Deterministic, and exact about containment: every vertex lies in the ellipsoid.
//!
//! **The box.** The paper aligns the box with the surface the object rests on and sets the other
//! sides to the average distance of the environment. lensmap fits each of the six faces on its
//! own: every distant hit goes to the face its direction from the EM origin reaches first, and a
//! face sits at the mean distance of its hits along its axis (ten rounds); so a floor gets its
//! own face at its own height, and the box need not be centred on the EM origin.

use glam::DVec3;
use lensmap::{
    layers::LayerShell,
    scene::{Camera, Scene},
    trace::{
        Bounces, GreedyOptions, Interface, TraceError, TraceOptions, compile_records,
        world::TraceScene,
    },
};

/// A lens object whose extent along an axis is below this fraction of its largest is flat: it
/// cannot see itself, and no ellipsoid of finite volume bounds it tightly.
pub const FLAT_FRACTION: f64 = 1e-3;

/// The smallest lens object layers by bounce fit, metres (largest extent).
pub const MIN_EXTENT_METRES: f64 = 1e-4;

/// The largest, metres: beyond it the f32 cube-map directions lose the detail (as
/// [`lensmap::layers::bake::MAX_EM_ORIGIN_METRES`]).
pub const MAX_EXTENT_METRES: f64 = 1e5;

/// The distant box's half extent where the first bounces reach no environment surface, metres.
pub const FAR_BOX_METRES: f64 = 100.0;

/// Why layers by bounce cannot be fitted.
#[derive(Debug, thiserror::Error)]
pub enum BounceError {
    /// A lens object with a glass surface.
    #[error(
        "lens object \"{lens}\": layers by bounce are a reflector's, and object \"{object}\" is glass; give it distance layers"
    )]
    NotAReflector {
        /// The lens object.
        lens: String,
        /// Its glass object.
        object: String,
    },
    /// Too flat, too small or too large to bound with an ellipsoid.
    #[error("lens object \"{lens}\": {problem}; give it distance layers")]
    Degenerate {
        /// The lens object.
        lens: String,
        /// What is wrong, with the extents.
        problem: String,
    },
    /// Tracing the first bounces failed.
    #[error(transparent)]
    Trace(#[from] TraceError),
}

/// The two shells of lens object `lens` (EM origin `origin`) by bounce, fitted to its first
/// bounces from `cameras`: the local ellipsoid, then the distant box.
pub fn place_by_bounce(
    scene: &Scene,
    trace: &TraceScene,
    lens: usize,
    origin: DVec3,
    cameras: &[Camera],
) -> Result<[LayerShell; 2], BounceError> {
    let name = trace.lenses[lens].name.clone();
    for &object in &trace.lenses[lens].objects {
        if let Some(Interface::Dielectric { .. }) = trace.interface(object) {
            return Err(BounceError::NotAReflector {
                lens: name,
                object: trace.object_names[object].clone(),
            });
        }
    }
    let options = TraceOptions {
        greedy: GreedyOptions {
            bounces: Bounces::First,
            ..GreedyOptions::default()
        },
        ..TraceOptions::default()
    };
    let mut seen = vec![false; trace.lenses.len()];
    seen[lens] = true;
    let mut distant = Vec::new();
    for camera in cameras {
        let set = compile_records(trace, camera, &options)?;
        let Some(records) = set.lenses.get(lens) else {
            continue;
        };
        for record in &records.records {
            if let Some(local) = record.local {
                seen[local.lens] = true;
            }
            if let Some(hit) = records.hits_of(record).first() {
                let ray = record.outgoing_ray;
                distant.push(ray.origin + hit.distance * ray.direction - origin);
            }
        }
    }
    let vertices: Vec<DVec3> = (0..trace.lenses.len())
        .filter(|&l| seen[l])
        .flat_map(|l| scene.lenses[l].objects.iter())
        .flat_map(|&o| scene.objects[o].mesh.positions.iter())
        .map(|p| p.as_dvec3() - origin)
        .collect();
    let radii = bounding_ellipsoid(&vertices).map_err(|problem| BounceError::Degenerate {
        lens: name,
        problem,
    })?;
    let (offset, half_extents) = room_box(&distant);
    Ok([
        LayerShell::Ellipsoid {
            centre: origin,
            radii,
        },
        LayerShell::Box {
            centre: origin + offset,
            half_extents,
        },
    ])
}

/// The radii of the least-volume axis-aligned ellipsoid centred on the origin that holds every
/// point (module docs); the problem, in words, for points too flat, too small or too large.
pub fn bounding_ellipsoid(points: &[DVec3]) -> Result<DVec3, String> {
    if let Some(bad) = points.iter().find(|p| !p.is_finite()) {
        return Err(format!("a vertex lies at {bad}, not a finite point"));
    }
    let extent = points.iter().fold(DVec3::ZERO, |m, p| m.max(p.abs()));
    let largest = extent.max_element();
    if !largest.is_finite() || largest > MAX_EXTENT_METRES {
        return Err(format!(
            "it reaches {largest} m from its centroid, beyond the {MAX_EXTENT_METRES} m an ellipsoid's maps keep detail at"
        ));
    }
    if largest < MIN_EXTENT_METRES {
        return Err(format!(
            "it spans {largest} m from its centroid, below the {MIN_EXTENT_METRES} m an ellipsoid can be fitted to"
        ));
    }
    if extent.min_element() < FLAT_FRACTION * largest {
        return Err(format!(
            "it is flat (extents {:.3e}, {:.3e}, {:.3e} m from its centroid): a flat reflector cannot see itself",
            extent.x, extent.y, extent.z
        ));
    }
    // Scaled to the largest extent, so the search does not depend on units.
    let scaled: Vec<DVec3> = points.iter().map(|p| *p / largest).collect();
    let scale_for = |u: f64, v: f64| {
        scaled
            .iter()
            .map(|p| (p.x / u).powi(2) + (p.y / v).powi(2) + p.z * p.z)
            .fold(0.0, f64::max)
            .sqrt()
    };
    let volume = |(a, b): (f64, f64)| {
        let (u, v) = (a.exp(), b.exp());
        u * v * scale_for(u, v).powi(3)
    };
    let mut best = (0.0, 0.0);
    let mut best_volume = volume(best);
    let (mut half_width, mut steps) = (4.0, 32);
    for _ in 0..4 {
        let centre = best;
        for i in -steps..=steps {
            for j in -steps..=steps {
                let candidate = (
                    centre.0 + half_width * f64::from(i) / f64::from(steps),
                    centre.1 + half_width * f64::from(j) / f64::from(steps),
                );
                let candidate_volume = volume(candidate);
                if candidate_volume < best_volume {
                    (best, best_volume) = (candidate, candidate_volume);
                }
            }
        }
        half_width *= 2.0 / f64::from(steps);
        steps = 8;
    }
    let (u, v) = (best.0.exp(), best.1.exp());
    let s = scale_for(u, v);
    Ok(DVec3::new(u * s, v * s, s) * largest)
}

/// The distant box about the origin for `points` (relative to it): its centre's offset from the
/// origin and its half extents (module docs). With no points, a cube of half edge
/// [`FAR_BOX_METRES`].
pub fn room_box(points: &[DVec3]) -> (DVec3, DVec3) {
    if points.is_empty() {
        return (DVec3::ZERO, DVec3::splat(FAR_BOX_METRES));
    }
    let mean = points.iter().map(|p| p.length()).sum::<f64>() / points.len() as f64;
    // Face distances from the origin: [axis][0 = negative side, 1 = positive side].
    let mut faces = [[mean.max(1e-3); 2]; 3];
    for _ in 0..10 {
        let mut sums = [[0.0f64; 2]; 3];
        let mut counts = [[0usize; 2]; 3];
        for p in points {
            let reach = |axis: usize| {
                let side = usize::from(p[axis] >= 0.0);
                (p[axis].abs() / faces[axis][side], side)
            };
            let (axis, side) = (0..3)
                .map(|axis| (axis, reach(axis)))
                .max_by(|a, b| a.1.0.total_cmp(&b.1.0))
                .map(|(axis, (_, side))| (axis, side))
                .unwrap_or((0, 1));
            sums[axis][side] += p[axis].abs();
            counts[axis][side] += 1;
        }
        for axis in 0..3 {
            for side in 0..2 {
                if counts[axis][side] > 0 {
                    faces[axis][side] = (sums[axis][side] / counts[axis][side] as f64).max(1e-3);
                }
            }
        }
    }
    let low = DVec3::new(faces[0][0], faces[1][0], faces[2][0]);
    let high = DVec3::new(faces[0][1], faces[1][1], faces[2][1]);
    ((high - low) * 0.5, (high + low) * 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on an axis-aligned ellipsoid's surface (a Fibonacci set).
    fn on_ellipsoid(radii: DVec3, n: usize) -> Vec<DVec3> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - y * y).sqrt();
                let phi = golden * i as f64;
                DVec3::new(r * phi.cos(), y, r * phi.sin()) * radii
            })
            .collect()
    }

    #[test]
    fn the_ellipsoid_of_an_ellipsoid_is_itself() {
        let radii = DVec3::new(0.8, 0.3, 0.5);
        let fitted = bounding_ellipsoid(&on_ellipsoid(radii, 4000)).unwrap();
        // Containment is exact; the volume is within the grid's resolution of the truth.
        assert!(
            (fitted / radii - DVec3::ONE).abs().max_element() < 2e-3,
            "{fitted}"
        );
    }

    #[test]
    fn every_point_is_inside_and_a_box_gets_the_known_optimum() {
        // A box's 8 corners: the least-volume axis-aligned ellipsoid through them has radii √3
        // times the half extents (volume (4/3)π·3√3·abc, by symmetry and AM-GM).
        let half = DVec3::new(1.0, 0.2, 0.6);
        let corners: Vec<DVec3> = (0..8)
            .map(|i| {
                half * DVec3::new(
                    if i & 1 == 0 { -1.0 } else { 1.0 },
                    if i & 2 == 0 { -1.0 } else { 1.0 },
                    if i & 4 == 0 { -1.0 } else { 1.0 },
                )
            })
            .collect();
        let radii = bounding_ellipsoid(&corners).unwrap();
        for c in &corners {
            assert!((*c / radii).length_squared() <= 1.0 + 1e-12);
        }
        let expected = half * 3f64.sqrt();
        assert!(
            (radii / expected - DVec3::ONE).abs().max_element() < 2e-3,
            "{radii}"
        );
    }

    #[test]
    fn degenerate_meshes_are_refused_in_words() {
        let flat = [DVec3::new(1.0, 0.0, 0.5), DVec3::new(-1.0, 0.0, -0.5)];
        assert!(bounding_ellipsoid(&flat).unwrap_err().contains("flat"));
        let tiny = on_ellipsoid(DVec3::splat(1e-6), 50);
        assert!(bounding_ellipsoid(&tiny).unwrap_err().contains("below"));
        let huge = on_ellipsoid(DVec3::splat(1e7), 50);
        assert!(bounding_ellipsoid(&huge).unwrap_err().contains("beyond"));
        let not_finite = [DVec3::new(f64::NAN, 1.0, 1.0), DVec3::ONE];
        assert!(bounding_ellipsoid(&not_finite).is_err());
    }

    #[test]
    fn a_room_box_finds_its_walls_and_floor() {
        // Points on the faces of a room from x ∈ [−3, 5], y ∈ [−1, 4], z ∈ [−2, 2].
        let (low, high) = (DVec3::new(-3.0, -1.0, -2.0), DVec3::new(5.0, 4.0, 2.0));
        let mut points = Vec::new();
        for i in 0..20 {
            for j in 0..20 {
                let (a, b) = ((i as f64 + 0.5) / 20.0, (j as f64 + 0.5) / 20.0);
                let lerp = |axis: usize, t: f64| low[axis] + (high[axis] - low[axis]) * t;
                for side in [low, high] {
                    points.push(DVec3::new(side.x, lerp(1, a), lerp(2, b)));
                    points.push(DVec3::new(lerp(0, a), side.y, lerp(2, b)));
                    points.push(DVec3::new(lerp(0, a), lerp(1, b), side.z));
                }
            }
        }
        let (offset, half) = room_box(&points);
        assert!(
            (offset - (high + low) * 0.5).abs().max_element() < 1e-9,
            "{offset}"
        );
        assert!(
            (half - (high - low) * 0.5).abs().max_element() < 1e-9,
            "{half}"
        );
        assert_eq!(room_box(&[]).1, DVec3::splat(FAR_BOX_METRES));
    }
}
