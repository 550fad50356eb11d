//! Loading the camera and the view space: a camera that looks somewhere with a usable up
//! direction, and viewpoint samples on a circle, in a list, on a patch or a cap of a sphere.

use super::{CAMERA_EPSILON, Loader, MAX_VIEWPOINT_SAMPLES, Result};

/// Two samples of a 2D view space whose directions from its centre are closer than this
/// (radians, about 0.006°) are the same direction.
pub const SAME_DIRECTION_RADIANS: f64 = 1e-4;
use crate::scene::camera::{Camera, ViewSpace};
use crate::scene::file::{CameraSpec, CapSpec, CircleSpec, PatchSpec, ViewSpaceSpec};

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

    pub(super) fn view_space(&self, spec: &ViewSpaceSpec, camera: &Camera) -> Result<ViewSpace> {
        let view_space = match (&spec.circle, &spec.list, &spec.patch, &spec.cap) {
            (Some(circle), None, None, None) => self.circle(circle)?,
            (None, None, Some(patch), None) => self.patch(patch, camera)?,
            (None, None, None, Some(cap)) => self.cap(cap, camera)?,
            (None, Some(list), None, None) => {
                if list.is_empty() {
                    return Err(self.error("view_space.list", "the list of viewpoints is empty", "give at least one position [x, y, z]"));
                }
                self.within_sample_limit("view_space.list", list.len() as u64, format!("{} viewpoint samples", list.len()), "give fewer samples")?;
                let positions = list
                    .iter()
                    .enumerate()
                    .map(|(i, p)| self.finite_vec3(&format!("view_space.list[{i}]"), *p))
                    .collect::<Result<Vec<_>>>()?;
                ViewSpace::List(positions)
            }
            _ => return Err(self.error("view_space", "needs exactly one of circle, list, patch or cap", "write one of [view_space.circle], list = [[x, y, z], ...], [view_space.patch] or [view_space.cap] (tools/scenes/README.md)")),
        };
        if view_space.is_surface() {
            self.distinct_directions(&view_space, camera)?;
        }
        Ok(view_space)
    }

    /// No two samples of a 2D view space in the same direction from its centre: the
    /// triangulation could give one of them no weight. Directions closer than
    /// [`SAME_DIRECTION_RADIANS`] count as one. Costs one dot product per pair.
    fn distinct_directions(&self, view_space: &ViewSpace, camera: &Camera) -> Result<()> {
        let centre = view_space.centre(camera.look_at);
        let directions: Vec<glam::DVec3> = view_space
            .samples()
            .iter()
            .map(|p| (*p - centre).as_dvec3().normalize_or_zero())
            .collect();
        let cos_limit = SAME_DIRECTION_RADIANS.cos();
        for (i, a) in directions.iter().enumerate() {
            if let Some(j) = (i + 1..directions.len()).find(|&j| a.dot(directions[j]) >= cos_limit)
            {
                return Err(self.error(
                    "view_space",
                    format!("samples {i} and {j} lie in the same direction from the centre {centre}"),
                    "give distinct samples (a patch reaching ±90° of elevation puts a whole row on the pole; a patch spanning 360° of azimuth repeats its first column)",
                ));
            }
        }
        Ok(())
    }

    /// `count` samples (`what` says how they were counted) within [`MAX_VIEWPOINT_SAMPLES`],
    /// else an error naming `field` with `fix`.
    fn within_sample_limit(
        &self,
        field: impl std::fmt::Display,
        count: u64,
        what: String,
        fix: &str,
    ) -> Result<()> {
        if count > u64::from(MAX_VIEWPOINT_SAMPLES) {
            return Err(self.error(
                field,
                format!("{what}, more than the {MAX_VIEWPOINT_SAMPLES} a view space may have"),
                fix,
            ));
        }
        Ok(())
    }

    pub(super) fn patch(&self, spec: &PatchSpec, camera: &Camera) -> Result<ViewSpace> {
        let f = "view_space.patch";
        let centre = match spec.centre {
            Some(c) => self.finite_vec3(&format!("{f}.centre"), c)?,
            None => camera.look_at,
        };
        let radius = self.positive(&format!("{f}.radius"), spec.radius, "metres")?;
        let range = |field: &str, [first, last]: [f32; 2], count: u32| {
            let field = format!("{f}.{field}_degrees");
            let first = self.finite(&field, first)?;
            let last = self.finite(&field, last)?;
            if first >= last {
                return Err(self.error(
                    &field,
                    format!("[{first}, {last}] is empty"),
                    "give [first, last] with first < last, e.g. [-10, 10]",
                ));
            }
            if count < 2 {
                let count_field = field.replace("_degrees", "_count");
                return Err(self.error(
                    count_field,
                    format!("{count} sample(s) across; a patch needs at least 2 × 2"),
                    "give a count ≥ 2 (for one row of samples use [view_space.circle])",
                ));
            }
            self.within_sample_limit(
                field.replace("_degrees", "_count"),
                u64::from(count),
                format!("{count} samples across"),
                "give fewer samples",
            )?;
            Ok((first.to_radians(), last.to_radians()))
        };
        let (a0, a1) = range("azimuth", spec.azimuth_degrees, spec.azimuth_count)?;
        let (e0, e1) = range("elevation", spec.elevation_degrees, spec.elevation_count)?;
        let [first, last] = spec.azimuth_degrees;
        if last - first > 360.0 {
            return Err(self.error(
                format!("{f}.azimuth_degrees"),
                format!(
                    "[{first}, {last}] spans {}°, more than the circle",
                    last - first
                ),
                "give a span of at most 360° (a closed ring of n columns spans 360·(n − 1)/n°)",
            ));
        }
        let [bottom, top] = spec.elevation_degrees;
        if bottom < -90.0 || top > 90.0 {
            return Err(self.error(
                format!("{f}.elevation_degrees"),
                format!("[{bottom}, {top}] leaves [−90, 90]"),
                "give elevations in [-90, 90] (90 is straight above the centre)",
            ));
        }
        let samples = u64::from(spec.azimuth_count) * u64::from(spec.elevation_count);
        self.within_sample_limit(
            f,
            samples,
            format!(
                "{} × {} = {samples} viewpoint samples",
                spec.azimuth_count, spec.elevation_count
            ),
            "give fewer samples",
        )?;
        Ok(ViewSpace::Patch {
            centre,
            radius,
            azimuth_radians: [a0, a1],
            azimuth_count: spec.azimuth_count,
            elevation_radians: [e0, e1],
            elevation_count: spec.elevation_count,
        })
    }

    pub(super) fn cap(&self, spec: &CapSpec, camera: &Camera) -> Result<ViewSpace> {
        let f = "view_space.cap";
        let centre = match spec.centre {
            Some(c) => self.finite_vec3(&format!("{f}.centre"), c)?,
            None => camera.look_at,
        };
        let radius = self.positive(&format!("{f}.radius"), spec.radius, "metres")?;
        let axis = match spec.axis {
            Some(a) => self.finite_vec3(&format!("{f}.axis"), a)?,
            None => camera.position - centre,
        };
        if axis.length() <= CAMERA_EPSILON {
            let field = if spec.axis.is_some() {
                format!("{f}.axis")
            } else {
                format!("{f}.centre")
            };
            return Err(self.error(
                field,
                "the cap's axis is zero (the camera sits on the centre when no axis is given)",
                "give a non-zero axis [x, y, z], or a centre away from the camera",
            ));
        }
        let half_angle =
            self.finite(&format!("{f}.half_angle_degrees"), spec.half_angle_degrees)?;
        if !(half_angle > 0.0 && half_angle <= 180.0) {
            return Err(self.error(
                format!("{f}.half_angle_degrees"),
                format!("{half_angle}° is not a cap's angular radius"),
                "give degrees in (0, 180] (180 covers the whole sphere)",
            ));
        }
        if spec.count < 3 {
            return Err(self.error(
                format!("{f}.count"),
                format!("{} sample(s) span no spherical triangle", spec.count),
                "give count ≥ 3",
            ));
        }
        self.within_sample_limit(
            format!("{f}.count"),
            u64::from(spec.count),
            format!("{} viewpoint samples", spec.count),
            "give fewer samples",
        )?;
        Ok(ViewSpace::Cap {
            centre,
            radius,
            axis: axis.normalize(),
            half_angle_radians: half_angle.to_radians(),
            count: spec.count,
        })
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
        self.within_sample_limit(
            format!("{f}.count"),
            u64::from(spec.count),
            format!("{} viewpoint samples", spec.count),
            "give fewer samples (45 samples 8° apart close the circle)",
        )?;
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
