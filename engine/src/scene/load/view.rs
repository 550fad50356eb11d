//! Loading the camera and the view space: a camera that looks somewhere with a usable up
//! direction, and viewpoint samples on a circle or in a list.

use super::{CAMERA_EPSILON, Loader, MAX_VIEWPOINT_SAMPLES, Result};
use crate::scene::camera::{Camera, ViewSpace};
use crate::scene::file::{CameraSpec, CircleSpec, ViewSpaceSpec};

impl Loader<'_> {
    pub(super) fn camera(&self, spec: &CameraSpec) -> Result<Camera> {
        let position = self.point("camera.position", spec.position)?;
        let look_at = self.point("camera.look_at", spec.look_at)?;
        let up = self.finite_vec3("camera.up", spec.up)?;
        let vfov = spec.vfov_degrees;
        if !(vfov.is_finite() && vfov > 0.0 && vfov < 180.0) {
            return Err(self.error(
                "camera.vfov_degrees",
                format!("{vfov}° is not a field of view"),
                "give degrees in (0, 180), e.g. 45",
            ));
        }
        for (field, value) in [("camera.width", spec.width), ("camera.height", spec.height)] {
            if value == 0 {
                return Err(self.error(
                    field,
                    "the resolution is zero",
                    "give at least 1 pixel, e.g. width = 640, height = 480",
                ));
            }
        }
        if spec.supersampling == 0 {
            return Err(self.error(
                "camera.supersampling",
                "k = 0 gives no samples per pixel",
                "give k ≥ 1 (k×k samples per pixel, 1 = none)",
            ));
        }
        let camera = Camera {
            position,
            look_at,
            up: up.normalize_or_zero(),
            vfov_radians: vfov.to_radians(),
            width: spec.width,
            height: spec.height,
            supersampling: spec.supersampling,
        };
        self.check_view("camera", &camera)?;
        Ok(camera)
    }

    /// A camera must look somewhere, with an up direction not along the view direction.
    pub(super) fn check_view(&self, field: &str, camera: &Camera) -> Result<()> {
        let view = camera.look_at - camera.position;
        if view.length() <= CAMERA_EPSILON {
            let what = if field == "camera" {
                "camera.look_at".to_owned()
            } else {
                field.to_owned()
            };
            return Err(self.error(
                what,
                format!(
                    "the position {} equals look_at {}",
                    camera.position, camera.look_at
                ),
                "move the position or look_at so that they differ",
            ));
        }
        if camera.up.length() <= CAMERA_EPSILON
            || view.normalize().cross(camera.up).length() <= CAMERA_EPSILON
        {
            let what = if field == "camera" {
                "camera.up".to_owned()
            } else {
                field.to_owned()
            };
            return Err(self.error(what, format!("up {} is zero or parallel to the view direction {}", camera.up, view.normalize()), "give an up direction that is not along look_at − position, e.g. [0, 1, 0] or [0, 0, -1] when looking straight down"));
        }
        Ok(())
    }

    pub(super) fn view_space(&self, spec: &ViewSpaceSpec) -> Result<ViewSpace> {
        match (&spec.circle, &spec.list) {
            (Some(circle), None) => self.circle(circle),
            (None, Some(list)) => {
                if list.is_empty() {
                    return Err(self.error("view_space.list", "the list of viewpoints is empty", "give at least one position [x, y, z]"));
                }
                if list.len() > MAX_VIEWPOINT_SAMPLES as usize {
                    return Err(self.error("view_space.list", format!("{} viewpoint samples, more than the {MAX_VIEWPOINT_SAMPLES} a view space may have", list.len()), "give fewer samples"));
                }
                let positions = list
                    .iter()
                    .enumerate()
                    .map(|(i, p)| self.finite_vec3(&format!("view_space.list[{i}]"), *p))
                    .collect::<Result<Vec<_>>>()?;
                Ok(ViewSpace::List(positions))
            }
            _ => Err(self.error("view_space", "needs exactly one of circle or list", "write circle = { centre, radius, height, start_degrees, step_degrees, count } or list = [[x, y, z], ...]")),
        }
    }

    pub(super) fn circle(&self, spec: &CircleSpec) -> Result<ViewSpace> {
        let f = "view_space.circle";
        if spec.count == 0 {
            return Err(self.error(
                format!("{f}.count"),
                "a view space with 0 viewpoint samples",
                "give count ≥ 1 (e.g. 45 samples 8° apart close the circle)",
            ));
        }
        if spec.count > MAX_VIEWPOINT_SAMPLES {
            return Err(self.error(
                format!("{f}.count"),
                format!("{} viewpoint samples, more than the {MAX_VIEWPOINT_SAMPLES} a view space may have", spec.count),
                "give fewer samples (45 samples 8° apart close the circle)",
            ));
        }
        let step = self.finite(&format!("{f}.step_degrees"), spec.step_degrees)?;
        if step == 0.0 && spec.count > 1 {
            return Err(self.error(
                format!("{f}.step_degrees"),
                "0° steps put every sample at the same place",
                "give a non-zero step, e.g. 8",
            ));
        }
        Ok(ViewSpace::Circle {
            centre: self.finite_vec3(&format!("{f}.centre"), spec.centre)?,
            radius: self.positive(&format!("{f}.radius"), spec.radius, "metres")?,
            height: self.finite(&format!("{f}.height"), spec.height)?,
            start_radians: self
                .finite(&format!("{f}.start_degrees"), spec.start_degrees)?
                .to_radians(),
            step_radians: step.to_radians(),
            count: spec.count,
        })
    }
}
