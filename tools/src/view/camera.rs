//! The viewer's camera moves (orbit, look, fly, zoom, snap) and the guard every move passes:
//! a camera never enters a lens object, and one inside a layer shell is told so.

use glam::{Quat, Vec3};
use lensmap::{hybrid::HybridScene, scene::Camera};

/// The closest the camera comes to its look-at point, metres.
const MIN_DISTANCE: f32 = 0.05;
/// The steepest an orbit or look goes towards the up vector, degrees: at 90° the view
/// direction would be parallel to it and the camera's frame undefined.
const MAX_PITCH_DEGREES: f32 = 85.0;

/// A move's outcome.
#[derive(Debug, PartialEq)]
pub enum Moved {
    /// The camera moved.
    To(Camera),
    /// The move was refused (the camera stays), with the reason for the overlay.
    Stopped(String),
}

/// The camera after orbiting `yaw` degrees about the up vector through the look-at point and
/// `pitch` degrees towards it (a left drag).
pub fn orbit(camera: &Camera, yaw: f32, pitch: f32) -> Camera {
    let offset = camera.position - camera.look_at;
    let offset = turn(offset, camera.up, yaw, pitch);
    Camera {
        position: camera.look_at + offset,
        ..*camera
    }
}

/// The camera after turning its view `yaw` degrees about the up vector and `pitch` degrees up,
/// standing still (a right drag).
pub fn look(camera: &Camera, yaw: f32, pitch: f32) -> Camera {
    let view = camera.look_at - camera.position;
    // The view turns like an orbit of the look-at point about the eye, pitch reversed.
    let view = turn(view, camera.up, yaw, -pitch);
    Camera {
        look_at: camera.position + view,
        ..*camera
    }
}

/// The camera moved `forward` and `right` metres, look-at point and all (WASD).
pub fn fly(camera: &Camera, forward: f32, right: f32) -> Camera {
    let view = (camera.look_at - camera.position).normalize_or_zero();
    let side = view.cross(camera.up).normalize_or_zero();
    let step = view * forward + side * right;
    Camera {
        position: camera.position + step,
        look_at: camera.look_at + step,
        ..*camera
    }
}

/// The camera moved towards its look-at point by `factor` of the distance (< 1 closer), never
/// nearer than [`MIN_DISTANCE`] (the wheel).
pub fn zoom(camera: &Camera, factor: f32) -> Camera {
    let offset = camera.position - camera.look_at;
    let distance = (offset.length() * factor).max(MIN_DISTANCE);
    Camera {
        position: camera.look_at + offset.normalize_or_zero() * distance,
        ..*camera
    }
}

/// `offset` turned `yaw` degrees about `up` and `pitch` degrees towards it, the pitch clamped
/// so that it never comes within `90° − MAX_PITCH_DEGREES` of `up` or of its opposite.
fn turn(offset: Vec3, up: Vec3, yaw: f32, pitch: f32) -> Vec3 {
    let up = up.normalize_or_zero();
    let length = offset.length();
    let direction = offset.normalize_or_zero();
    let elevation = direction.dot(up).clamp(-1.0, 1.0).asin().to_degrees();
    let pitch = (elevation + pitch).clamp(-MAX_PITCH_DEGREES, MAX_PITCH_DEGREES) - elevation;
    let yawed = Quat::from_axis_angle(up, yaw.to_radians()) * direction;
    let axis = up.cross(yawed).normalize_or_zero();
    // Rotating about up × direction turns the direction towards up for positive angles.
    let pitched = Quat::from_axis_angle(axis, -pitch.to_radians()) * yawed;
    pitched * length
}

/// Whether `camera` may be shown in `scene`: `Stopped` when its eye would be inside a lens
/// object's bounds or the camera is not a camera (non-finite, at its look-at point, looking
/// along its up vector); otherwise the camera, and the layer shells it is inside (by lens
/// object name and layer number), which the overlay names.
pub fn guard(scene: &HybridScene, camera: Camera) -> (Moved, Vec<String>) {
    let view = camera.look_at - camera.position;
    let finite = camera.position.is_finite() && camera.look_at.is_finite();
    if !finite || view.length() < MIN_DISTANCE * 0.5 {
        return (
            Moved::Stopped("stopped: the camera would reach its look-at point".into()),
            Vec::new(),
        );
    }
    if view
        .normalize()
        .cross(camera.up.normalize_or_zero())
        .length()
        < 1e-3
    {
        return (
            Moved::Stopped("stopped: the view would be parallel to the up vector".into()),
            Vec::new(),
        );
    }
    for (name, lo, hi) in scene.lens_bounds() {
        if camera.position.cmpgt(lo).all() && camera.position.cmplt(hi).all() {
            return (
                Moved::Stopped(format!(
                    "stopped at lens object \"{name}\": the camera would enter its bounds"
                )),
                Vec::new(),
            );
        }
    }
    let eye = camera.position.as_dvec3();
    let mut inside = Vec::new();
    for (lens, layers) in scene.trace().lenses.iter().zip(scene.lenses()) {
        for (i, shell) in layers.shells.iter().enumerate() {
            if shell.contains(eye) {
                inside.push(format!("{} layer {}", lens.name, i + 1));
            }
        }
    }
    (Moved::To(camera), inside)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            position: Vec3::new(0.0, 1.0, 4.0),
            look_at: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            vfov_radians: 0.8,
            width: 64,
            height: 48,
            supersampling: 1,
        }
    }

    #[test]
    fn orbit_keeps_the_distance_and_turns_by_the_angle() {
        let c = camera();
        let o = orbit(&c, 90.0, 0.0);
        assert!(((o.position - o.look_at).length() - 4.0).abs() < 1e-5);
        // 90° about +y takes +z to +x.
        assert!(
            (o.position - Vec3::new(4.0, 1.0, 0.0)).length() < 1e-5,
            "{o:?}"
        );
        let up = orbit(&c, 0.0, 30.0);
        let elevation = (up.position - up.look_at).normalize().y.asin().to_degrees();
        assert!((elevation - 30.0).abs() < 1e-3, "{elevation}");
        // The pitch is clamped short of the pole, so the camera stays a camera.
        let pole = orbit(&c, 0.0, 400.0);
        let elevation = (pole.position - pole.look_at)
            .normalize()
            .y
            .asin()
            .to_degrees();
        assert!((elevation - MAX_PITCH_DEGREES).abs() < 1e-3, "{elevation}");
    }

    #[test]
    fn look_turns_the_view_about_the_eye() {
        let c = camera();
        let l = look(&c, 90.0, 0.0);
        assert_eq!(l.position, c.position);
        // Looking along −z, turned 90° about +y: along −x.
        let view = (l.look_at - l.position).normalize();
        assert!((view - Vec3::NEG_X).length() < 1e-5, "{view}");
    }

    #[test]
    fn fly_and_zoom_move_as_said() {
        let c = camera();
        let f = fly(&c, 1.0, 0.5);
        assert!(
            (f.position - Vec3::new(0.5, 1.0, 3.0)).length() < 1e-5,
            "{f:?}"
        );
        assert_eq!(f.look_at - f.position, c.look_at - c.position);
        let z = zoom(&c, 0.5);
        assert!(((z.position - z.look_at).length() - 2.0).abs() < 1e-5);
        let close = zoom(&c, 0.0);
        assert!(((close.position - close.look_at).length() - MIN_DISTANCE).abs() < 1e-6);
    }
}
