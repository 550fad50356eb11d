//! Work counters of the reference ray tracer: rays by kind and ray–triangle tests.
//!
//! Each worker counts into its own [`TraceCounters`]; counts are summed afterwards, so totals do
//! not depend on the thread count.

use serde::Serialize;
use std::ops::AddAssign;

/// How much work a render or a query did. All fields are plain counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TraceCounters {
    /// Camera rays (one per supersample).
    pub primary_rays: u64,
    /// Closest-hit and all-hit queries after the camera ray: path segments through lens objects,
    /// outgoing rays, full-tree children, record continuation rays.
    pub secondary_rays: u64,
    /// Shadow (occlusion) rays towards point lights.
    pub shadow_rays: u64,
    /// Ray–triangle intersection tests performed inside BVH traversal.
    pub triangle_tests: u64,
}

impl TraceCounters {
    /// Every ray query: primary + secondary + shadow.
    pub fn all_rays(&self) -> u64 {
        self.primary_rays + self.secondary_rays + self.shadow_rays
    }

    /// Rays along light paths (primary + secondary), excluding shadow rays: the paper's count of
    /// "ray queries" when comparing the full ray tree with the greedy paths.
    pub fn path_rays(&self) -> u64 {
        self.primary_rays + self.secondary_rays
    }

    /// Mean triangle tests per ray (0 when no rays were traced).
    pub fn triangle_tests_per_ray(&self) -> f64 {
        let rays = self.all_rays();
        if rays == 0 {
            0.0
        } else {
            self.triangle_tests as f64 / rays as f64
        }
    }
}

impl AddAssign for TraceCounters {
    fn add_assign(&mut self, other: Self) {
        self.primary_rays += other.primary_rays;
        self.secondary_rays += other.secondary_rays;
        self.shadow_rays += other.shadow_rays;
        self.triangle_tests += other.triangle_tests;
    }
}

/// Statistics of one reference render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RenderStats {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Supersamples per pixel along each axis (k for k×k).
    pub supersampling: u32,
    /// Work counters summed over the whole image.
    pub counters: TraceCounters,
    /// Wall-clock time of the render in seconds (excluding scene loading and BVH builds).
    pub seconds: f64,
    /// Under path classes, the throughput they keep of every camera ray's first lens object
    /// (zero under the other models).
    pub class_share: super::ClassShare,
}

impl RenderStats {
    /// Total rays traced per second, in millions (0 when the time is 0).
    pub fn mrays_per_second(&self) -> f64 {
        if self.seconds > 0.0 {
            self.counters.all_rays() as f64 / self.seconds / 1e6
        } else {
            0.0
        }
    }

    /// Total rays per image pixel.
    pub fn rays_per_pixel(&self) -> f64 {
        let pixels = u64::from(self.width) * u64::from(self.height);
        if pixels == 0 {
            0.0
        } else {
            self.counters.all_rays() as f64 / pixels as f64
        }
    }
}
