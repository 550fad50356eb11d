//! The cameras a bake looks through: the K views of a sample (module docs of [`super`]), the
//! sample itself at the bake's resolution, and the viewpoints that place the layers.

use glam::{DQuat, DVec3, Vec3};
use lensmap::{
    hybrid::sphere::{SphereTriangulation, angle},
    scene::{Camera, Scene},
};

use super::options::{
    BakeOptions, PLACEMENT_SAMPLES, PLACEMENT_SCALE, SINGLE_SAMPLE_SPREAD_DEGREES,
};

/// The camera at view-space sample position `position`: the scene camera moved there, at the
/// bake's resolution.
pub(super) fn sample_camera(scene: &Scene, position: Vec3, options: &BakeOptions) -> Camera {
    scene.camera.with_position(position).with_resolution(
        options.width,
        options.height,
        options.supersampling,
    )
}

/// The K views of sample `sample` (module docs): spread along the view space's circle, or in a
/// 2D view space towards the sample's neighbours in its triangulation.
pub fn view_cameras(scene: &Scene, sample: usize, options: &BakeOptions) -> Vec<Camera> {
    let positions = scene.view_space.samples();
    let look_at = scene.camera.look_at.as_dvec3();
    let mut cameras = match surface_views(scene, &positions, sample, options) {
        Some(cameras) => cameras,
        None => line_views(scene, &positions, sample, options),
    };
    cameras.extend(raised_view(
        scene,
        positions[sample].as_dvec3() - look_at,
        options,
    ));
    cameras
}

/// In a 2D view space, the K views of sample `sample`: the sample itself, then K − 1 views a
/// third of the way (in angle about the view space's centre) towards neighbours in the
/// triangulation, chosen evenly round the sample by their bearing from it (measured from the
/// world's up, as seen from outside), so the views spread over the triangles the sample's maps
/// serve; one view per neighbour when the sample has fewer than K − 1. `None` for a 1D view
/// space or one that spans no triangle.
fn surface_views(
    scene: &Scene,
    positions: &[Vec3],
    sample: usize,
    options: &BakeOptions,
) -> Option<Vec<Camera>> {
    let triangulation = SphereTriangulation::of_scene(scene)?;
    let centre = scene.view_space.centre(scene.camera.look_at).as_dvec3();
    let points: Vec<DVec3> = positions.iter().map(|p| p.as_dvec3()).collect();
    let own = points[sample] - centre;
    let unit = own.normalize();
    // Bearings in the tangent plane at the sample, from the projection of +y (else +x).
    let reference = [DVec3::Y, DVec3::X]
        .into_iter()
        .map(|axis| axis - axis.dot(unit) * unit)
        .find(|r| r.length() > 1e-6)?
        .normalize();
    let side = unit.cross(reference);
    let mut neighbours: Vec<(f64, usize)> = triangulation
        .neighbours(sample)
        .into_iter()
        .map(|n| {
            let d = points[n] - centre;
            let t = d - d.dot(unit) * unit;
            (t.dot(side).atan2(t.dot(reference)), n)
        })
        .collect();
    neighbours.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let k = options.multi_view.max(1);
    let mut cameras = vec![sample_camera(scene, positions[sample], options)];
    if neighbours.is_empty() {
        return Some(cameras);
    }
    // Distinct neighbours only: a sample with fewer neighbours than K − 1 gets one view each.
    let views = (k - 1).min(neighbours.len());
    for j in 0..views {
        let n = neighbours[j * neighbours.len() / views].1;
        let towards = points[n] - centre;
        let axis = own.cross(towards).normalize_or_zero();
        if axis == DVec3::ZERO {
            continue;
        }
        let position = centre + DQuat::from_axis_angle(axis, angle(own, towards) / 3.0) * own;
        cameras.push(sample_camera(scene, position.as_vec3(), options));
    }
    Some(cameras)
}

/// Along a 1D view space, the K views of sample `sample`: rotated about the vertical through the
/// look-at point, evenly over ±½ of the angle to the nearest other sample.
fn line_views(
    scene: &Scene,
    positions: &[Vec3],
    sample: usize,
    options: &BakeOptions,
) -> Vec<Camera> {
    let look_at = scene.camera.look_at.as_dvec3();
    let own = positions[sample].as_dvec3() - look_at;
    let spacing = positions
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != sample)
        .map(|(_, p)| angle(own, p.as_dvec3() - look_at))
        .filter(|a| *a > 1e-9)
        .fold(f64::INFINITY, f64::min);
    let spacing = if spacing.is_finite() {
        spacing
    } else {
        SINGLE_SAMPLE_SPREAD_DEGREES.to_radians()
    };
    let k = options.multi_view.max(1);
    (0..k)
        .map(|j| {
            let offset = spacing * ((j as f64 + 0.5) / k as f64 - 0.5);
            let position = look_at + DQuat::from_rotation_y(offset) * own;
            sample_camera(scene, position.as_vec3(), options)
        })
        .collect()
}

/// The raised view of a sample `own` away from the look-at point, when the options ask for one:
/// up by `view_elevation_degrees` about the horizontal axis perpendicular to the direction to
/// the look-at point (a sample straight above or below it has none: then no raised view).
fn raised_view(scene: &Scene, own: DVec3, options: &BakeOptions) -> Option<Camera> {
    let elevation = options.view_elevation_degrees.to_radians();
    if elevation <= 0.0 {
        return None;
    }
    let look_at = scene.camera.look_at.as_dvec3();
    let axis = own.cross(DVec3::Y);
    if axis.length() <= 1e-9 * own.length() {
        return None;
    }
    let axis = axis.normalize();
    [-elevation, elevation]
        .map(|angle| look_at + DQuat::from_axis_angle(axis, angle) * own)
        .into_iter()
        .find(|p| p.y > look_at.y + own.y)
        .map(|position| sample_camera(scene, position.as_vec3(), options))
}

/// The viewpoints whose records place the layers: [`PLACEMENT_SAMPLES`] spread evenly over the
/// view space, at 1/[`PLACEMENT_SCALE`] of the bake's resolution, one sample per pixel.
pub fn placement_cameras(scene: &Scene, options: &BakeOptions) -> Vec<Camera> {
    let positions = scene.view_space.samples();
    let count = positions.len().min(PLACEMENT_SAMPLES);
    (0..count)
        .map(|i| positions[i * positions.len() / count])
        .map(|p| {
            scene.camera.with_position(p).with_resolution(
                (options.width / PLACEMENT_SCALE).max(1),
                (options.height / PLACEMENT_SCALE).max(1),
                1,
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::BakeFailure;

    #[test]
    fn views_in_a_patch_go_towards_triangulation_neighbours() {
        let scene = Scene::load_named(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../tools/scenes/glass-sphere-patch.toml"
        ))
        .unwrap();
        let centre = scene.view_space.centre(scene.camera.look_at).as_dvec3();
        let samples = scene.view_space.samples();
        let from = |p: Vec3| p.as_dvec3() - centre;
        let points: Vec<DVec3> = samples.iter().map(|p| p.as_dvec3()).collect();
        let triangulation = SphereTriangulation::new(&points, centre).unwrap();
        for k in [1, 3, 5] {
            let options = BakeOptions {
                multi_view: k,
                ..BakeOptions::default()
            };
            // The middle sample 4 has neighbours all round.
            let cameras = view_cameras(&scene, 4, &options);
            assert_eq!(cameras.len(), k);
            assert!(cameras[0].position.distance(samples[4]) < 1e-5);
            let neighbours = triangulation.neighbours(4);
            for camera in &cameras[1..] {
                // A third of the way to one neighbour, on the sphere, looking at the look-at point.
                let view = from(camera.position);
                assert!((view.length() - from(samples[4]).length()).abs() < 1e-4);
                let own = from(samples[4]);
                let towards = neighbours.iter().find(|&&n| {
                    (angle(own, view) - angle(own, from(samples[n])) / 3.0).abs() < 1e-5
                        && (angle(view, from(samples[n]))
                            - 2.0 * angle(own, from(samples[n])) / 3.0)
                            .abs()
                            < 1e-5
                });
                assert!(
                    towards.is_some(),
                    "K = {k}: {view} is a third of the way to no neighbour"
                );
                assert_eq!(camera.look_at, scene.camera.look_at);
            }
            // Distinct views.
            for (i, a) in cameras.iter().enumerate() {
                for b in &cameras[i + 1..] {
                    assert!(a.position.distance(b.position) > 1e-3);
                }
            }
        }
        // A corner sample has fewer neighbours than K − 1 = 8: one view each, none repeated.
        let nine = BakeOptions {
            multi_view: 9,
            ..BakeOptions::default()
        };
        let corner = view_cameras(&scene, 0, &nine);
        assert_eq!(corner.len(), 1 + triangulation.neighbours(0).len());
        for (i, a) in corner.iter().enumerate() {
            for b in &corner[i + 1..] {
                assert!(a.position.distance(b.position) > 1e-3);
            }
        }
    }

    #[test]
    fn views_spread_over_the_samples_share_of_the_circle() {
        let scene = Scene::load_named("glass-sphere").unwrap();
        let options = BakeOptions {
            multi_view: 3,
            ..BakeOptions::default()
        };
        let look_at = scene.camera.look_at.as_dvec3();
        let samples = scene.view_space.samples();
        let cameras = view_cameras(&scene, 5, &options);
        assert_eq!(cameras.len(), 3);
        // The middle view is the sample; the others rotated about the vertical through the
        // look-at point by ±1/3 of the angle s between neighbouring samples (as seen from the
        // look-at point), one on each side.
        assert!(cameras[1].position.distance(samples[5]) < 1e-5);
        let from = |p: Vec3| p.as_dvec3() - look_at;
        let s = angle(from(samples[5]), from(samples[6]));
        let own = from(samples[5]);
        for (camera, side) in [(&cameras[0], -1.0), (&cameras[2], 1.0)] {
            let want = look_at + DQuat::from_rotation_y(side * s / 3.0) * own;
            assert!(camera.position.as_dvec3().distance(want) < 1e-5);
            assert_eq!(camera.look_at, scene.camera.look_at);
        }
        // On opposite sides: towards sample 4 and towards sample 6.
        let towards =
            |camera: &Camera, p: Vec3| angle(from(camera.position), from(p)) < angle(own, from(p));
        assert!(towards(&cameras[0], samples[4]) != towards(&cameras[0], samples[6]));
        assert!(towards(&cameras[2], samples[4]) != towards(&cameras[2], samples[6]));
        assert!(towards(&cameras[0], samples[4]) != towards(&cameras[2], samples[4]));
        let one = BakeOptions {
            multi_view: 1,
            ..BakeOptions::default()
        };
        let single = view_cameras(&scene, 5, &one);
        assert!(single[0].position.distance(samples[5]) < 1e-5);
        // A raised view: the sample, 15° up about the horizontal axis, at the same distance.
        let raised = BakeOptions {
            view_elevation_degrees: 15.0,
            ..options
        };
        let with_raised = view_cameras(&scene, 5, &raised);
        assert_eq!(with_raised.len(), 4);
        assert_eq!(with_raised[..3], cameras[..]);
        let up = from(with_raised[3].position);
        assert!((angle(up, own).to_degrees() - 15.0).abs() < 1e-4);
        assert!((up.length() - own.length()).abs() < 1e-4);
        assert!(with_raised[3].position.y > samples[5].y);
        assert!(
            angle(up - own, glam::DVec3::Y) < angle(own, glam::DVec3::Y),
            "up, not sideways"
        );
        assert_ne!(raised.hash(), options.hash());
        for bad in [-1.0, 90.0, f64::NAN] {
            let e = BakeOptions {
                view_elevation_degrees: bad,
                ..options
            }
            .validate()
            .unwrap_err();
            assert!(
                matches!(&e, BakeFailure::Option(o) if o.option == crate::bake::names::VIEW_ELEVATION),
                "{e}"
            );
        }
    }
}
