//! Viewpoint blending. Along a 1D view space (hybrid-rendering paper §5) a frame away from a
//! pre-rendered viewpoint sample blends the layered EMs of the two closest samples, weighted by
//! their relative distance to the actual viewpoint. Distance here is the angle between the
//! directions from the view space's centre to the camera and to the sample, the natural metric
//! of a view space circling an object. In a 2D view space (reflection-space IBR §3.4) the
//! samples are triangulated on the sphere of directions ([`super::sphere`]) and a frame blends
//! the three samples of the triangle holding the camera by spherical barycentric weights.

use glam::DVec3;

use super::sphere::{SphereTriangulation, angle};

/// Which viewpoint samples a frame blends.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum ViewpointBlending {
    /// The view space's rule: the two nearest samples along a 1D view space, the three of the
    /// triangle holding the camera in a 2D one ([`ViewSpaceBlender::blend`]).
    #[default]
    ViewSpace,
    /// The two samples nearest in angle, weighted by relative angle ([`blend`]),
    /// in any view space.
    TwoNearest,
    /// The nearest sample alone.
    Nearest,
}

/// Angles below this (radians) mean the camera sits on a sample: one viewpoint, weight 1.
pub const ON_SAMPLE_RADIANS: f64 = 1e-6;

/// The samples a frame blends and their weights (summing to 1, largest first; along a circle the
/// larger weight is the nearer sample's).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewpointBlend {
    /// `(sample index, weight)`, one to three entries.
    pub samples: Vec<(usize, f64)>,
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

/// Whether a camera is still inside the view space its samples cover. In a 1D view space: how
/// far it is from the nearest sample compared with how far the samples are from each other, all
/// as angles about the centre (the metric of [`blend`]). In a 2D one: whether a triangle holds
/// its direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewSpaceFit {
    /// Index of the sample nearest to the camera in angle (ties go to the lower index); along a
    /// circle the first of [`blend`]'s samples.
    pub nearest: usize,
    /// The camera's angle to the nearest sample, radians in [0, π].
    pub nearest_radians: f64,
    /// The view space's sampling density: the largest, over samples, of each sample's angle to
    /// its nearest other sample, radians in [0, π]; 0 for a single sample.
    pub spacing_radians: f64,
    /// Whether the camera has left the view space: `nearest_radians > spacing_radians` (it is
    /// farther from every sample than neighbouring samples are from each other, so a blend mixes
    /// distant samples), or `nearest_radians >` [`ON_SAMPLE_RADIANS`] when the spacing is 0 (a
    /// single sample). In a 2D view space: its direction lies in no triangle.
    pub outside: bool,
    /// How far outside, radians: in a 2D view space the angle to the nearest point of the
    /// triangulated region, in a 1D one `nearest_radians − spacing_radians`; 0 inside.
    pub outside_radians: f64,
    /// Whether the view space is 2D (triangulated).
    pub surface: bool,
}

/// How `camera` sits in the view space of `samples` about `look_at` (positions in metres; see
/// [`ViewSpaceFit`]). Samples whose angle is undefined (not finite) are left out, as in
/// [`blend`]. Costs one angle per pair of samples.
///
/// Returns `None` for no usable sample, a camera at the look-at point, or a camera or look-at
/// point that is not finite.
pub fn view_space_fit(samples: &[DVec3], look_at: DVec3, camera: DVec3) -> Option<ViewSpaceFit> {
    fit_with_spacing(samples, look_at, camera, spacing(samples, look_at))
}

/// The largest, over samples, of each sample's angle to its nearest other sample about
/// `centre` (see [`ViewSpaceFit::spacing_radians`]); samples whose angle is undefined are left
/// out. Costs one angle per pair of samples.
fn spacing(samples: &[DVec3], centre: DVec3) -> f64 {
    let directions: Vec<DVec3> = samples
        .iter()
        .map(|s| *s - centre)
        .filter(|d| d.is_finite())
        .collect();
    directions
        .iter()
        .enumerate()
        .filter_map(|(i, &d)| {
            directions
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, &e)| angle(d, e))
                .filter(|a| a.is_finite())
                .min_by(f64::total_cmp)
        })
        .fold(0.0, f64::max)
}

/// [`view_space_fit`] with the view space's spacing already known.
fn fit_with_spacing(
    samples: &[DVec3],
    look_at: DVec3,
    camera: DVec3,
    spacing_radians: f64,
) -> Option<ViewSpaceFit> {
    let view = camera - look_at;
    if samples.is_empty() || view.length_squared() == 0.0 || !view.is_finite() {
        return None;
    }
    let (nearest, nearest_radians) = samples
        .iter()
        .map(|s| *s - look_at)
        .enumerate()
        .filter(|(_, d)| d.is_finite())
        .map(|(i, d)| (i, angle(view, d)))
        .filter(|(_, a)| a.is_finite())
        .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))?;
    let outside = nearest_radians > spacing_radians.max(ON_SAMPLE_RADIANS);
    Some(ViewSpaceFit {
        nearest,
        nearest_radians,
        spacing_radians,
        outside,
        outside_radians: if outside {
            nearest_radians - spacing_radians
        } else {
            0.0
        },
        surface: false,
    })
}

/// The viewpoint samples of a scene with the shape a frame blends them by: a 1D view space
/// (two samples at a time, [`blend`]) or a triangulated 2D one (three, [`SphereTriangulation`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSpaceBlender {
    positions: Vec<DVec3>,
    centre: DVec3,
    /// [`ViewSpaceFit::spacing_radians`], computed once.
    spacing_radians: f64,
    triangulation: Option<SphereTriangulation>,
}

impl ViewSpaceBlender {
    /// The samples at `positions` about `centre`, triangulated when `surface` asks for a 2D
    /// view space and they span a spherical triangle. Otherwise (a circle; or fewer than three
    /// samples, or all on one great circle: the documented fallback) they are blended as a 1D
    /// view space.
    pub fn new(positions: Vec<DVec3>, centre: DVec3, surface: bool) -> ViewSpaceBlender {
        let triangulation = if surface {
            SphereTriangulation::new(&positions, centre)
        } else {
            None
        };
        // A 2D view space has its spacing from the triangulation's edges (O(faces)); a 1D one
        // costs one angle per pair of samples, once.
        let spacing_radians = match &triangulation {
            Some(t) => t.spacing_radians(),
            None => spacing(&positions, centre),
        };
        ViewSpaceBlender {
            spacing_radians,
            positions,
            centre,
            triangulation,
        }
    }

    /// The triangulation of a 2D view space, `None` for a 1D one.
    pub fn triangulation(&self) -> Option<&SphereTriangulation> {
        self.triangulation.as_ref()
    }

    /// The sample positions, metres.
    pub fn positions(&self) -> &[DVec3] {
        &self.positions
    }

    /// The view space's centre, metres.
    pub fn centre(&self) -> DVec3 {
        self.centre
    }

    /// The samples a frame seen from `camera` blends and their weights, summing to 1, largest
    /// first: in a 2D view space the triangle holding the camera's direction (three samples;
    /// two on an edge, one at a sample), outside every triangle the nearest point of the
    /// region; in a 1D one the two nearest samples ([`blend`]). `None` without samples or for a
    /// camera at the centre or not finite.
    pub fn blend(&self, camera: DVec3) -> Option<ViewpointBlend> {
        self.place(camera).map(|(blend, _)| blend)
    }

    /// [`ViewSpaceBlender::blend`] and whether the camera is outside the view space
    /// ([`ViewSpaceFit::outside`]), from one point location: what a frame needs of the view
    /// space.
    pub fn place(&self, camera: DVec3) -> Option<(ViewpointBlend, bool)> {
        match &self.triangulation {
            Some(t) => {
                let location = t.locate(camera - self.centre)?;
                let blend = ViewpointBlend {
                    samples: location.weights,
                };
                Some((blend, location.outside))
            }
            None => {
                let blend = blend(&self.positions, self.centre, camera)?;
                let fit =
                    fit_with_spacing(&self.positions, self.centre, camera, self.spacing_radians)?;
                Some((blend, fit.outside))
            }
        }
    }

    /// How `camera` sits in the view space (see [`ViewSpaceFit`]).
    pub fn fit(&self, camera: DVec3) -> Option<ViewSpaceFit> {
        let fit = fit_with_spacing(&self.positions, self.centre, camera, self.spacing_radians)?;
        let Some(t) = &self.triangulation else {
            return Some(fit);
        };
        let location = t.locate(camera - self.centre)?;
        Some(ViewSpaceFit {
            outside: location.outside,
            outside_radians: location.outside_radians,
            surface: true,
            ..fit
        })
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

    /// The point at `azimuth` degrees round the circle of [`circle`] and `elevation` degrees
    /// above its plane, 4 m from the centre.
    fn on_sphere(azimuth: f64, elevation: f64) -> DVec3 {
        let (a, e) = (azimuth.to_radians(), elevation.to_radians());
        4.0 * DVec3::new(e.cos() * a.cos(), e.sin(), e.cos() * a.sin())
    }

    #[test]
    fn between_samples_on_the_circle_is_inside() {
        let samples = circle(45, 8.0);
        // Halfway between two samples (4° from both) is the farthest a camera on the circle gets.
        for azimuth in [4.0, 356.0] {
            let fit = view_space_fit(&samples, DVec3::ZERO, on_sphere(azimuth, 0.0)).unwrap();
            assert!(
                (fit.nearest_radians - 4f64.to_radians()).abs() < 1e-9,
                "{fit:?}"
            );
            assert!(!fit.outside, "{azimuth}°: {fit:?}");
        }
        for azimuth in [0.0, 3.0, 4.5, 42.0, 181.5, 357.0] {
            let fit = view_space_fit(&samples, DVec3::ZERO, on_sphere(azimuth, 0.0)).unwrap();
            assert!(
                (fit.spacing_radians - 8f64.to_radians()).abs() < 1e-9,
                "{fit:?}"
            );
            let nearest = (azimuth / 8.0).round() as usize % 45;
            assert_eq!(fit.nearest, nearest, "{azimuth}°");
            let blended = blend(&samples, DVec3::ZERO, on_sphere(azimuth, 0.0)).unwrap();
            assert_eq!(fit.nearest, blended.samples[0].0, "the blend's nearest");
            let expected = (azimuth - 8.0 * (azimuth / 8.0).round()).abs().to_radians();
            assert!((fit.nearest_radians - expected).abs() < 1e-9, "{fit:?}");
            assert!(!fit.outside, "{azimuth}°: {fit:?}");
        }
    }

    #[test]
    fn above_the_circle_is_outside() {
        let samples = circle(45, 8.0);
        // 15° above sample 5: 15° from it, more from every other sample, spacing 8°.
        let fit = view_space_fit(&samples, DVec3::ZERO, on_sphere(40.0, 15.0)).unwrap();
        assert_eq!(fit.nearest, 5);
        assert!(
            (fit.nearest_radians - 15f64.to_radians()).abs() < 1e-9,
            "{fit:?}"
        );
        assert!(fit.outside, "{fit:?}");
        // 7° above it is still inside; the distance from the centre does not matter.
        let fit = view_space_fit(&samples, DVec3::ZERO, 3.0 * on_sphere(40.0, 7.0)).unwrap();
        assert!(!fit.outside, "{fit:?}");
        // Straight above the circle's centre: 90° from every sample.
        let fit = view_space_fit(&samples, DVec3::ZERO, DVec3::new(0.0, 2.0, 0.0)).unwrap();
        assert!((fit.nearest_radians - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(fit.outside);
    }

    #[test]
    fn spacing_is_the_sparsest_samples_gap() {
        // Samples at 0°, 10°, 20° and 50°: the sample at 50° is 30° from its nearest.
        let samples: Vec<DVec3> = [0.0, 10.0, 20.0, 50.0]
            .iter()
            .map(|&a| on_sphere(a, 0.0))
            .collect();
        let look_at = DVec3::ZERO;
        // In the gap: 13° from the sample at 20°, inside the 30° spacing.
        let fit = view_space_fit(&samples, look_at, on_sphere(33.0, 0.0)).unwrap();
        assert!(
            (fit.spacing_radians - 30f64.to_radians()).abs() < 1e-9,
            "{fit:?}"
        );
        assert_eq!(fit.nearest, 2);
        assert!(
            (fit.nearest_radians - 13f64.to_radians()).abs() < 1e-9,
            "{fit:?}"
        );
        assert!(!fit.outside);
        // 40° past the last sample, beyond the sparsest gap.
        let fit = view_space_fit(&samples, look_at, on_sphere(90.0, 0.0)).unwrap();
        assert_eq!(fit.nearest, 3);
        assert!(fit.outside, "{fit:?}");
    }

    #[test]
    fn a_single_sample_fits_only_a_camera_on_it() {
        let look_at = DVec3::new(0.0, 1.0, 0.0);
        let sample = [DVec3::new(0.0, 2.5, 5.0)];
        let on = view_space_fit(&sample, look_at, look_at + 2.0 * (sample[0] - look_at)).unwrap();
        assert_eq!((on.nearest, on.spacing_radians), (0, 0.0));
        assert!(on.nearest_radians <= ON_SAMPLE_RADIANS, "{on:?}");
        assert!(!on.outside);
        let off = view_space_fit(&sample, look_at, DVec3::new(0.5, 2.5, 5.0)).unwrap();
        assert_eq!(off.spacing_radians, 0.0);
        assert!(off.nearest_radians > 0.05);
        assert!(off.outside, "{off:?}");
    }

    #[test]
    fn degenerate_view_space_fits_are_none() {
        let samples = circle(45, 8.0);
        assert!(view_space_fit(&[], DVec3::ZERO, DVec3::X).is_none());
        assert!(view_space_fit(&samples, DVec3::ZERO, DVec3::ZERO).is_none());
        assert!(view_space_fit(&samples, DVec3::ZERO, DVec3::new(f64::NAN, 0.0, 1.0)).is_none());
        assert!(view_space_fit(&samples, DVec3::splat(f64::INFINITY), DVec3::X).is_none());
        assert!(view_space_fit(&[DVec3::splat(f64::NAN)], DVec3::ZERO, DVec3::X).is_none());
        // A sample that is not finite is left out; the rest still fit.
        let mut broken = samples.clone();
        broken[1] = DVec3::new(f64::INFINITY, 0.0, 0.0);
        // Samples 0 and 2 are 16° apart but each still has a neighbour 8° away: the spacing is
        // the nearest-neighbour angle, which a single gap does not change.
        let fit = view_space_fit(&broken, DVec3::ZERO, on_sphere(6.0, 0.0)).unwrap();
        assert!(
            (fit.spacing_radians - 8f64.to_radians()).abs() < 1e-9,
            "{fit:?}"
        );
        assert_eq!(fit.nearest, 0);
        assert!(
            (fit.nearest_radians - 6f64.to_radians()).abs() < 1e-9,
            "{fit:?}"
        );
        assert!(!fit.outside);
        let fit = view_space_fit(&broken, DVec3::ZERO, on_sphere(10.0, 0.0)).unwrap();
        assert_eq!(fit.nearest, 2, "sample 1 is left out");
    }

    /// A 3 × 3 patch of samples 10° apart about the origin, 4 m out, from azimuth −10° and
    /// elevation 0°.
    fn patch() -> Vec<DVec3> {
        (0..3)
            .flat_map(|row| {
                (0..3).map(move |col| on_sphere(-10.0 + 10.0 * col as f64, 10.0 * row as f64))
            })
            .collect()
    }

    #[test]
    fn a_surface_blends_three_samples_a_circle_two() {
        let samples = patch();
        let surface = ViewSpaceBlender::new(samples.clone(), DVec3::ZERO, true);
        assert!(surface.triangulation().is_some());
        let inside = on_sphere(-4.0, 3.0);
        let blend = surface.blend(inside).unwrap();
        assert_eq!(blend.samples.len(), 3, "{blend:?}");
        let fit = surface.fit(inside).unwrap();
        assert!(
            fit.surface && !fit.outside && fit.outside_radians == 0.0,
            "{fit:?}"
        );
        // At a sample, one; the weights sum to 1 and come largest first.
        assert_eq!(surface.blend(samples[4]).unwrap().samples, vec![(4, 1.0)]);
        let total: f64 = blend.samples.iter().map(|s| s.1).sum();
        assert!((total - 1.0).abs() < 1e-12);
        assert!(blend.samples.windows(2).all(|w| w[0].1 >= w[1].1));
        // 15° above the top row (elevation 20°): outside, blending the nearest point of the
        // region, on an arc next to the top row's middle sample 7 (the arcs bulge poleward, so
        // it is a little nearer than 7 itself, 15°).
        let above = on_sphere(0.0, 35.0);
        let fit = surface.fit(above).unwrap();
        assert!(fit.outside, "{fit:?}");
        let degrees = fit.outside_radians.to_degrees();
        assert!(degrees < 15.0 && degrees > 14.99, "{degrees}");
        let top = surface.blend(above).unwrap().samples;
        assert!(top[0].0 == 7 && top[0].1 > 0.9, "{top:?}");
        // The same samples as a 1D view space: the two nearest.
        let line = ViewSpaceBlender::new(samples.clone(), DVec3::ZERO, false);
        assert!(line.triangulation().is_none());
        assert_eq!(line.blend(inside).unwrap().samples.len(), 2);
        assert!(!line.fit(inside).unwrap().surface);
    }

    #[test]
    fn samples_on_a_great_circle_fall_back_to_the_line() {
        // A 2D view space whose samples all lie on the equator: blended two at a time.
        let samples = circle(8, 10.0);
        let blender = ViewSpaceBlender::new(samples.clone(), DVec3::ZERO, true);
        assert!(blender.triangulation().is_none());
        let camera = on_sphere(15.0, 0.0);
        assert_eq!(blender.blend(camera), blend(&samples, DVec3::ZERO, camera));
        assert_eq!(
            blender.fit(camera),
            view_space_fit(&samples, DVec3::ZERO, camera)
        );
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
