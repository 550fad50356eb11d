//! Camera paths: the camera poses (position and look-at point) of a sequence of frames, for
//! recording frames headless or driving a viewer: an orbit around the scene camera's look-at
//! point, or a path file.
//!
//! A path file is TOML, a list of poses, at least one:
//!
//! ```toml
//! [[poses]]
//! position = [0.0, 1.2, 3.0]   # metres
//! look_at = [0.0, 0.5, 0.0]
//!
//! [[poses]]
//! position = [1.0, 1.2, 2.8]
//! look_at = [0.0, 0.5, 0.0]
//! ```
//!
//! Each pose replaces the position and look-at point of the scene's camera (its field of view,
//! up vector and image size stay) and must make a camera the scene's rules accept: finite, within
//! 1e6 m of the origin, the position apart from the look-at point. A bad file is refused in the
//! scene-error style: one line naming the file, the field (`poses[2].look_at`) and the fix.

use std::path::Path;

use glam::Vec3;
use serde::Deserialize;

use super::{Camera, Scene, SceneError};
use crate::trace::image::validate_camera;

/// Where the camera is and what it looks at in one frame.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPose {
    /// The eye, metres.
    pub position: Vec3,
    /// The point the camera looks at, metres.
    pub look_at: Vec3,
}

/// The poses of a sequence of frames, at least one.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    /// In frame order.
    pub poses: Vec<CameraPose>,
}

/// A path file as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PathFile {
    poses: Vec<CameraPose>,
}

impl CameraPath {
    /// `frames` poses around the vertical through the scene camera's look-at point, a full turn
    /// at the camera's own distance and height, starting at the scene camera and turning by
    /// 360°/`frames` a frame ([`Camera::orbited`]). No poses for `frames` = 0.
    pub fn orbit(scene: &Scene, frames: usize) -> CameraPath {
        let poses = (0..frames)
            .map(|i| {
                let camera = scene.camera.orbited(360.0 * i as f32 / frames as f32);
                CameraPose {
                    position: camera.position,
                    look_at: camera.look_at,
                }
            })
            .collect();
        CameraPath { poses }
    }

    /// Reads a path file for cameras like `base` (see the module documentation).
    pub fn load(path: &Path, base: &Camera) -> Result<CameraPath, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::Read {
            file: path.to_path_buf(),
            problem: format!("cannot read the camera path file ({e})"),
            fix: "check the path; a path file lists [[poses]] with position and look_at".into(),
        })?;
        CameraPath::from_toml_str(&text, path, base)
    }

    /// Parses a path file's text; `origin` is the file messages name.
    pub fn from_toml_str(
        text: &str,
        origin: &Path,
        base: &Camera,
    ) -> Result<CameraPath, SceneError> {
        let file: PathFile =
            toml::from_str(text).map_err(|e| SceneError::from_toml(origin, text, &e))?;
        if file.poses.is_empty() {
            return Err(SceneError::invalid(
                origin,
                "poses",
                "the path has no poses",
                "add at least one [[poses]] table with position and look_at",
            ));
        }
        let path = CameraPath { poses: file.poses };
        for (i, camera) in path.cameras(base).enumerate() {
            validate_camera(&camera).map_err(|error| {
                SceneError::invalid(
                    origin,
                    format!("poses[{i}]"),
                    error,
                    "give a finite position and look_at within 1e6 m of the origin, apart from each other",
                )
            })?;
        }
        Ok(path)
    }

    /// The cameras of the path: `base` with each pose's position and look-at point.
    pub fn cameras<'a>(&'a self, base: &'a Camera) -> impl Iterator<Item = Camera> + 'a {
        self.poses.iter().map(|pose| Camera {
            position: pose.position,
            look_at: pose.look_at,
            ..*base
        })
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use glam::Vec3;

    use super::CameraPath;
    use crate::scene::Scene;

    fn scene() -> Scene {
        Scene::load_named("glass-sphere").expect("built in")
    }

    #[test]
    fn an_orbit_turns_once_around_the_look_at_point_at_the_cameras_distance_and_height() {
        let scene = scene();
        let camera = scene.camera;
        let path = CameraPath::orbit(&scene, 8);
        assert_eq!(path.poses.len(), 8);
        assert_eq!(path.poses[0].position, camera.position);
        let offset = camera.position - camera.look_at;
        let radius = offset.truncate().with_y(offset.z).length();
        for (i, pose) in path.poses.iter().enumerate() {
            let d = pose.position - pose.look_at;
            assert_eq!(pose.look_at, camera.look_at);
            assert!((d.y - offset.y).abs() < 1e-5, "{i}: height {d}");
            assert!(
                (Vec3::new(d.x, 0.0, d.z).length() - radius).abs() < 1e-4,
                "{i}: radius"
            );
            // 45° a frame: the angle to the first pose's offset, in the horizontal plane.
            let horizontal = |v: Vec3| Vec3::new(v.x, 0.0, v.z).normalize();
            let cos = horizontal(d).dot(horizontal(offset));
            let expected = (45.0f32 * i as f32).to_radians().cos();
            assert!(
                (cos - expected).abs() < 1e-4,
                "{i}: cos {cos} vs {expected}"
            );
        }
        assert!(CameraPath::orbit(&scene, 0).poses.is_empty());
    }

    #[test]
    fn a_path_file_gives_its_poses_on_the_base_camera() {
        let scene = scene();
        let text = "[[poses]]\nposition = [0.0, 1.0, 3.0]\nlook_at = [0.0, 0.5, 0.0]\n\n\
                    [[poses]]\nposition = [1.0, 1.0, 3.0]\nlook_at = [0.0, 0.5, 0.0]\n";
        let path = CameraPath::from_toml_str(text, Path::new("p.toml"), &scene.camera).unwrap();
        let cameras: Vec<_> = path.cameras(&scene.camera).collect();
        assert_eq!(cameras.len(), 2);
        assert_eq!(cameras[1].position, Vec3::new(1.0, 1.0, 3.0));
        assert_eq!(cameras[1].look_at, Vec3::new(0.0, 0.5, 0.0));
        assert_eq!(cameras[1].vfov_radians, scene.camera.vfov_radians);
        assert_eq!(cameras[1].width, scene.camera.width);
    }

    #[test]
    fn bad_path_files_are_refused_naming_file_field_and_fix() {
        let scene = scene();
        let refused = |text: &str| {
            CameraPath::from_toml_str(text, Path::new("p.toml"), &scene.camera)
                .expect_err(text)
                .to_string()
        };
        let cases = [
            ("poses = []", "poses", "no poses"),
            (
                "[[poses]]\nposition = [0.0, 1.0, 3.0]\nlook = [0.0, 0.0, 0.0]\n",
                "poses",
                "unknown field",
            ),
            (
                "[[poses]]\nposition = [0.0, 1.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\n\
                 [[poses]]\nposition = [0.0, 1.0, 3.0]\nlook_at = [0.0, 2e7, 0.0]\n",
                "poses[1]",
                "1e6",
            ),
            (
                "[[poses]]\nposition = [0.0, nan, 3.0]\nlook_at = [0.0, 0.0, 0.0]\n",
                "poses[0]",
                "not finite",
            ),
            (
                "[[poses]]\nposition = [1.0, 1.0, 1.0]\nlook_at = [1.0, 1.0, 1.0]\n",
                "poses[0]",
                "",
            ),
        ];
        for (text, field, words) in cases {
            let message = refused(text);
            assert!(
                message.starts_with("p.toml")
                    && message.contains(field)
                    && message.contains(words)
                    && message.lines().count() == 1,
                "{text:?}: {message}"
            );
        }
    }
}
