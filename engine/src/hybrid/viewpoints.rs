//! Viewpoint blending (hybrid-rendering paper §5): a frame away from a pre-rendered viewpoint
//! sample blends the layered EMs of the two closest samples, weighted by their relative distance
//! to the actual viewpoint. Distance here is the angle between the directions from the look-at
//! point to the camera and to the sample, the natural metric of a view space circling an object.

use glam::DVec3;

/// Angles below this (radians) mean the camera sits on a sample: one viewpoint, weight 1.
pub const ON_SAMPLE_RADIANS: f64 = 1e-6;

/// The samples a frame blends and their weights (summing to 1, nearest first).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewpointBlend {
    /// `(sample index, weight)`, one or two entries.
    pub samples: Vec<(usize, f64)>,
}

/// Angle between two directions, robust near 0 and π (atan2 of the cross and dot products).
pub fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Picks the two samples nearest to `camera` (by angle about `look_at`) and weights them by
/// relative angular distance: w_a = θ_b / (θ_a + θ_b), w_b = θ_a / (θ_a + θ_b). One sample with
/// weight 1 when the camera is within [`ON_SAMPLE_RADIANS`] of it, or when there is one sample.
/// Returns `None` for an empty view space or a camera at the look-at point.
pub fn blend(samples: &[DVec3], look_at: DVec3, camera: DVec3) -> Option<ViewpointBlend> {
    let view = camera - look_at;
    if samples.is_empty() || view.length_squared() == 0.0 || !view.is_finite() {
        return None;
    }
    let mut by_angle: Vec<(usize, f64)> = samples
        .iter()
        .enumerate()
        .map(|(i, s)| (i, angle(view, *s - look_at)))
        .filter(|(_, a)| a.is_finite())
        .collect();
    // Ties broken by index, so the result does not depend on the sort's stability.
    by_angle.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    let (nearest, theta_a) = *by_angle.first()?;
    match by_angle.get(1) {
        Some(&(second, theta_b)) if theta_a > ON_SAMPLE_RADIANS => {
            let total = theta_a + theta_b;
            Some(ViewpointBlend {
                samples: vec![(nearest, theta_b / total), (second, theta_a / total)],
            })
        }
        _ => Some(ViewpointBlend {
            samples: vec![(nearest, 1.0)],
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(count: usize, step_degrees: f64) -> Vec<DVec3> {
        (0..count)
            .map(|i| {
                let a = (i as f64 * step_degrees).to_radians();
                DVec3::new(4.0 * a.cos(), 0.0, 4.0 * a.sin())
            })
            .collect()
    }

    #[test]
    fn on_a_sample_is_one_viewpoint() {
        let samples = circle(45, 8.0);
        let b = blend(&samples, DVec3::ZERO, samples[3]).unwrap();
        assert_eq!(b.samples, vec![(3, 1.0)]);
    }

    #[test]
    fn between_two_samples_weights_by_relative_angle() {
        // A camera 2° past sample 5 (at 40°) towards sample 6 (48°): weights 6/8 and 2/8.
        let samples = circle(45, 8.0);
        let a = 42f64.to_radians();
        let camera = DVec3::new(4.0 * a.cos(), 0.0, 4.0 * a.sin());
        let b = blend(&samples, DVec3::ZERO, camera).unwrap();
        assert_eq!(b.samples.len(), 2);
        assert_eq!((b.samples[0].0, b.samples[1].0), (5, 6));
        assert!((b.samples[0].1 - 0.75).abs() < 1e-9, "{b:?}");
        assert!((b.samples[0].1 + b.samples[1].1 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn distance_from_the_centre_does_not_matter_only_direction() {
        let samples = circle(45, 8.0);
        let near = blend(
            &samples,
            DVec3::ZERO,
            samples[7] * 0.5 + DVec3::new(0.1, 0.0, 0.0),
        )
        .unwrap();
        let far = blend(
            &samples,
            DVec3::ZERO,
            samples[7] * 2.0 + DVec3::new(0.2, 0.0, 0.0),
        )
        .unwrap();
        assert_eq!(near.samples[0].0, far.samples[0].0);
    }

    #[test]
    fn degenerate_inputs_are_none() {
        assert!(blend(&[], DVec3::ZERO, DVec3::X).is_none());
        assert!(blend(&[DVec3::X], DVec3::ZERO, DVec3::ZERO).is_none());
        assert_eq!(
            blend(&[DVec3::X], DVec3::ZERO, DVec3::Y).unwrap().samples,
            vec![(0, 1.0)]
        );
    }
}
