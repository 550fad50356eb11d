//! The pinhole camera (primary rays and the Vulkan view-projection matrix) and the view space:
//! the viewpoint samples at which layered environment maps are baked.

use glam::{Mat4, Vec3};

/// A pinhole camera in a right-handed, y-up world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (metres).
    pub position: Vec3,
    /// The point the camera looks at; differs from `position`.
    pub look_at: Vec3,
    /// Approximate up direction (unit); not parallel to `look_at − position`.
    pub up: Vec3,
    /// Vertical field of view in radians, in (0, π).
    pub vfov_radians: f32,
    /// Image width in pixels, ≥ 1.
    pub width: u32,
    /// Image height in pixels, ≥ 1.
    pub height: u32,
    /// Supersampling factor k (k×k samples per pixel), ≥ 1.
    pub supersampling: u32,
}

impl Camera {
    /// Width over height.
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height.max(1) as f32
    }

    /// The orthonormal camera frame `(right, true_up, forward)`; forward points from the eye to
    /// `look_at`, right = forward × up.
    pub fn frame(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.look_at - self.position).normalize_or_zero();
        let right = forward.cross(self.up).normalize_or_zero();
        let true_up = right.cross(forward);
        (right, true_up, forward)
    }

    /// The ray through image point (x, y) in pixel units: (0, 0) is the top-left corner of the
    /// image, (width, height) the bottom-right, pixel centres at +0.5. Returns the eye position
    /// and the unit direction.
    pub fn primary_ray(&self, x: f32, y: f32) -> (Vec3, Vec3) {
        let (right, true_up, forward) = self.frame();
        let tan_half = (0.5 * self.vfov_radians).tan();
        let ndc_x = 2.0 * x / self.width as f32 - 1.0;
        let ndc_y = 1.0 - 2.0 * y / self.height as f32;
        let direction =
            forward + right * (ndc_x * tan_half * self.aspect()) + true_up * (ndc_y * tan_half);
        (self.position, direction.normalize_or_zero())
    }

    /// World → Vulkan clip space: right-handed world, x right, **y down** in NDC (top row of the
    /// image at y = −1, as [`Camera::primary_ray`] has it), depth 0 at `near` and 1 at `far`
    /// (metres, 0 < near < far).
    pub fn view_proj(&self, near: f32, far: f32) -> Mat4 {
        let view = glam::camera::rh::view::look_at_mat4(self.position, self.look_at, self.up);
        let projection = glam::camera::rh::proj::vulkan::perspective(
            self.vfov_radians,
            self.aspect(),
            near,
            far,
        );
        projection * view
    }

    /// The same camera moved to `position`, still looking at `look_at`.
    pub fn with_position(&self, position: Vec3) -> Camera {
        Camera { position, ..*self }
    }

    /// The same camera turned by `degrees` about the vertical through its look-at point (a step
    /// of a camera moving around the scene).
    pub fn orbited(&self, degrees: f32) -> Camera {
        let rotation = glam::Quat::from_rotation_y(degrees.to_radians());
        Camera {
            position: self.look_at + rotation * (self.position - self.look_at),
            ..*self
        }
    }

    /// The same camera with an image of `width × height` pixels, each supersampled
    /// `supersampling × supersampling`.
    pub fn with_resolution(&self, width: u32, height: u32, supersampling: u32) -> Camera {
        Camera {
            width,
            height,
            supersampling,
            ..*self
        }
    }
}

/// The viewpoint samples of the view space, each a camera position looking at the camera's
/// `look_at`.
#[derive(Clone, Debug, PartialEq)]
pub enum ViewSpace {
    /// A 1D circle about the vertical line through `centre`: sample i is at angle
    /// a = start + i·step measured about +y from the +z axis towards +x, position
    /// `centre + (radius·sin a, height, radius·cos a)`.
    Circle {
        /// Centre of the circle's axis (metres).
        centre: Vec3,
        /// Circle radius in metres, > 0.
        radius: f32,
        /// Height of the circle above `centre.y` in metres.
        height: f32,
        /// Angle of sample 0 in radians.
        start_radians: f32,
        /// Angle between consecutive samples in radians.
        step_radians: f32,
        /// Number of samples, ≥ 1.
        count: u32,
    },
    /// Explicit positions (metres), at least one. Triangulated on the sphere of directions
    /// from the camera's look-at point when they span a spherical triangle (a 2D view space);
    /// blended two at a time like a circle when they all lie on one great circle or are fewer
    /// than three.
    List(Vec<Vec3>),
    /// A 2D patch on the sphere of radius `radius` about `centre`: `elevation_count` rows ×
    /// `azimuth_count` columns, evenly spaced from the first to the last angle of each range
    /// (both included). Sample `row·azimuth_count + column` is at azimuth a (about +y, from +z
    /// towards +x) and elevation e (above the horizontal): position
    /// `centre + radius·(cos e·sin a, sin e, cos e·cos a)`.
    Patch {
        /// Centre of the sphere (metres): the scene point the view space surrounds.
        centre: Vec3,
        /// Sphere radius in metres, > 0.
        radius: f32,
        /// First and last azimuth, radians, first < last, span ≤ 2π.
        azimuth_radians: [f32; 2],
        /// Columns, ≥ 2.
        azimuth_count: u32,
        /// First and last elevation, radians, in [−π/2, π/2], first < last.
        elevation_radians: [f32; 2],
        /// Rows, ≥ 2.
        elevation_count: u32,
    },
    /// A 2D cap on the sphere of radius `radius` about `centre`: `count` samples of a Fibonacci
    /// (golden-angle) spiral within `half_angle_radians` of `axis`, sample i at polar angle
    /// acos(1 − (1 − cos θ)·(i + ½)/count) and azimuth i·π(3 − √5) about the axis.
    Cap {
        /// Centre of the sphere (metres).
        centre: Vec3,
        /// Sphere radius in metres, > 0.
        radius: f32,
        /// The cap's axis, unit length.
        axis: Vec3,
        /// The cap's angular radius θ, radians, in (0, π] (π: the whole sphere).
        half_angle_radians: f32,
        /// Number of samples, ≥ 3.
        count: u32,
    },
}

impl ViewSpace {
    /// The viewpoint sample positions, in order.
    pub fn samples(&self) -> Vec<Vec3> {
        match self {
            ViewSpace::Circle {
                centre,
                radius,
                height,
                start_radians,
                step_radians,
                count,
            } => (0..*count)
                .map(|i| {
                    let angle = start_radians + i as f32 * step_radians;
                    *centre + Vec3::new(radius * angle.sin(), *height, radius * angle.cos())
                })
                .collect(),
            ViewSpace::List(positions) => positions.clone(),
            ViewSpace::Patch {
                centre,
                radius,
                azimuth_radians: [a0, a1],
                azimuth_count,
                elevation_radians: [e0, e1],
                elevation_count,
            } => {
                let along = |first: f32, last: f32, count: u32, i: u32| {
                    first + (last - first) * i as f32 / (count - 1).max(1) as f32
                };
                (0..*elevation_count)
                    .flat_map(|row| {
                        let e = along(*e0, *e1, *elevation_count, row);
                        (0..*azimuth_count).map(move |column| {
                            let a = along(*a0, *a1, *azimuth_count, column);
                            *centre
                                + *radius * Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
                        })
                    })
                    .collect()
            }
            ViewSpace::Cap {
                centre,
                radius,
                axis,
                half_angle_radians,
                count,
            } => {
                // An orthonormal frame about the axis, the same for every load.
                let (u, v) = axis.any_orthonormal_pair();
                let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
                let drop = 1.0 - half_angle_radians.cos();
                (0..*count)
                    .map(|i| {
                        let z = 1.0 - drop * (i as f32 + 0.5) / *count as f32;
                        let r = (1.0 - z * z).max(0.0).sqrt();
                        let phi = i as f32 * golden;
                        *centre + *radius * (z * *axis + r * (phi.cos() * u + phi.sin() * v))
                    })
                    .collect()
            }
        }
    }

    /// Whether the view space is 2D: its samples are triangulated on the sphere of directions
    /// about [`ViewSpace::centre`] and a frame blends the three of the triangle holding the
    /// camera. A circle is 1D: its samples are blended two at a time along it.
    pub fn is_surface(&self) -> bool {
        !matches!(self, ViewSpace::Circle { .. })
    }

    /// The scene point whose sphere of directions the view space lies on: a patch's or cap's
    /// centre, else `look_at` (the camera's).
    pub fn centre(&self, look_at: Vec3) -> Vec3 {
        match self {
            ViewSpace::Patch { centre, .. } | ViewSpace::Cap { centre, .. } => *centre,
            ViewSpace::Circle { .. } | ViewSpace::List(_) => look_at,
        }
    }

    /// Number of viewpoint samples.
    pub fn len(&self) -> usize {
        match self {
            ViewSpace::Circle { count, .. } => *count as usize,
            ViewSpace::List(positions) => positions.len(),
            ViewSpace::Patch {
                azimuth_count,
                elevation_count,
                ..
            } => (*azimuth_count as usize) * (*elevation_count as usize),
            ViewSpace::Cap { count, .. } => *count as usize,
        }
    }

    /// Whether there are no samples (never true for a loaded scene).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            position: Vec3::new(1.0, 2.0, 6.0),
            look_at: Vec3::new(-0.5, 0.5, 0.0),
            up: Vec3::Y,
            vfov_radians: 50f32.to_radians(),
            width: 320,
            height: 200,
            supersampling: 3,
        }
    }

    #[test]
    fn the_centre_ray_is_the_look_direction() {
        let c = camera();
        let (origin, direction) = c.primary_ray(160.0, 100.0);
        assert_eq!(origin, c.position);
        let expected = (c.look_at - c.position).normalize();
        assert!(direction.distance(expected) < 1e-6);
    }

    #[test]
    fn corner_rays_span_the_field_of_view() {
        // The top-edge centre ray makes half the vertical fov with the look direction.
        let c = camera();
        let forward = (c.look_at - c.position).normalize();
        let (_, top) = c.primary_ray(160.0, 0.0);
        let angle = top.dot(forward).acos();
        assert!((angle - 25f32.to_radians()).abs() < 1e-5);
        // Top of the image is up in the world.
        assert!(top.y > forward.y);
        // Left edge: tan(h/2) = aspect · tan(v/2), pointing to the camera's left.
        let (_, left) = c.primary_ray(0.0, 100.0);
        let expected = (1.6 * 25f32.to_radians().tan()).atan();
        assert!((left.dot(forward).acos() - expected).abs() < 1e-5);
        let (right, _, _) = c.frame();
        assert!(left.dot(right) < 0.0);
        assert!(right.cross(forward).dot(Vec3::Y) > 0.9 * right.cross(forward).length());
    }

    #[test]
    fn view_proj_maps_look_at_to_the_centre_and_the_top_edge_to_minus_one() {
        let c = camera();
        let m = c.view_proj(0.1, 100.0);
        let centre = m.project_point3(c.look_at);
        assert!(centre.x.abs() < 1e-5 && centre.y.abs() < 1e-5, "{centre}");
        assert!(centre.z > 0.0 && centre.z < 1.0);
        // A point along the ray through the top-edge centre pixel lands on NDC y = −1.
        let (origin, top) = c.primary_ray(160.0, 0.0);
        let ndc = m.project_point3(origin + top * 5.0);
        assert!((ndc.y + 1.0).abs() < 1e-4 && ndc.x.abs() < 1e-4, "{ndc}");
        // And the ray through pixel (x, y) lands on NDC (2x/w − 1, 2y/h − 1).
        let (origin, ray) = c.primary_ray(40.0, 150.0);
        let ndc = m.project_point3(origin + ray * 3.0);
        assert!((ndc.x - (80.0 / 320.0 - 1.0)).abs() < 1e-4, "{ndc}");
        assert!((ndc.y - (300.0 / 200.0 - 1.0)).abs() < 1e-4, "{ndc}");
        // Depth: near → 0, far → 1.
        let forward = (c.look_at - c.position).normalize();
        assert!(m.project_point3(c.position + forward * 0.1).z.abs() < 1e-5);
        assert!((m.project_point3(c.position + forward * 100.0).z - 1.0).abs() < 1e-4);
    }

    #[test]
    fn circle_samples_have_count_radius_and_spacing() {
        let view = ViewSpace::Circle {
            centre: Vec3::new(1.0, 0.5, -2.0),
            radius: 4.0,
            height: 1.5,
            start_radians: 0.0,
            step_radians: 8f32.to_radians(),
            count: 45,
        };
        let samples = view.samples();
        assert_eq!(samples.len(), 45);
        assert_eq!(view.len(), 45);
        for (i, p) in samples.iter().enumerate() {
            let offset = *p - Vec3::new(1.0, 0.5, -2.0);
            assert!((offset.y - 1.5).abs() < 1e-6);
            assert!((Vec3::new(offset.x, 0.0, offset.z).length() - 4.0).abs() < 1e-5);
            let angle = offset.x.atan2(offset.z).rem_euclid(std::f32::consts::TAU);
            assert!(
                (angle - (8.0 * i as f32).to_radians()).abs() < 1e-4,
                "sample {i}"
            );
        }
        // Sample 0 is on +z from the centre.
        assert!(samples[0].distance(Vec3::new(1.0, 2.0, 2.0)) < 1e-6);
        // Chords between neighbours: 2 r sin(4°).
        let chord = samples[0].distance(samples[1]);
        assert!((chord - 8.0 * 4f32.to_radians().sin()).abs() < 1e-5);
    }
}
