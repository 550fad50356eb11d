//! The CPU reference ray tracer: obvhs BVHs, the paper's ray-path models, Fresnel, attenuation,
//! reference images and intersection records.

pub mod bvh;
pub mod fresnel;
pub mod path;
pub mod stats;

use glam::DVec3;

/// A ray in world space, f64: `origin + t · direction` for t ≥ 0, `direction` a unit vector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point in metres.
    pub origin: DVec3,
    /// Unit direction.
    pub direction: DVec3,
}

impl Ray {
    /// A ray from `origin` along `direction` (normalized here; must be non-zero and finite).
    pub fn new(origin: DVec3, direction: DVec3) -> Ray {
        Ray {
            origin,
            direction: direction.normalize(),
        }
    }

    /// The point at distance `t` along the ray.
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.direction
    }
}
