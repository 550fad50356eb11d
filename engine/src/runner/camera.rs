//! Cameras the runner's callers share: the novel viewpoint between two viewpoint samples that
//! the demo and the hybrid benchmark render.

use crate::scene::{Camera, Scene};

/// The demo's and the hybrid benchmark's novel viewpoint: halfway (in angle) between viewpoint
/// samples 2 and 3 of the scene's view space, at their mean distance from the look-at point, so
/// two samples are blended; the scene camera when the view space has fewer than four samples.
pub fn novel_camera(scene: &Scene) -> Camera {
    camera_between(scene, 2, 3).unwrap_or(scene.camera)
}

/// The scene camera halfway (in angle about the look-at point) between viewpoint samples `a`
/// and `b`, at their mean distance from it; `None` when the view space lacks either sample.
pub fn camera_between(scene: &Scene, a: usize, b: usize) -> Option<Camera> {
    let samples = scene.view_space.samples();
    let look_at = scene.camera.look_at;
    let (da, db) = (*samples.get(a)? - look_at, *samples.get(b)? - look_at);
    let direction = (da.normalize() + db.normalize()).normalize_or(da.normalize());
    Some(
        scene
            .camera
            .with_position(look_at + direction * 0.5 * (da.length() + db.length())),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_novel_camera_bisects_samples_2_and_3() {
        let scene = Scene::load_named("teapot-room").unwrap();
        let samples = scene.view_space.samples();
        let look_at = scene.camera.look_at;
        let camera = novel_camera(&scene);
        let (a, b, c) = (
            (samples[2] - look_at).normalize(),
            (samples[3] - look_at).normalize(),
            (camera.position - look_at).normalize(),
        );
        // Equal angles to both samples, in their plane, between them.
        assert!((c.dot(a) - c.dot(b)).abs() < 1e-6, "{c} {a} {b}");
        assert!(c.dot(a) > a.dot(b));
        let distance = 0.5 * ((samples[2] - look_at).length() + (samples[3] - look_at).length());
        assert!(((camera.position - look_at).length() - distance).abs() < 1e-4);
    }
}
