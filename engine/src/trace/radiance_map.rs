//! Radiance environment maps of a glossy surface (the reflection-space IBR paper, §3): for one
//! view direction, the radiance a surface element at a point leaves towards the viewer, as a
//! function of one direction, stored as a cube map over that direction.
//!
//! - The **normal warp**'s map is indexed by the element's normal n.
//! - The **mirror warp**'s map is indexed by the mirror direction r of the view about the normal:
//!   n = (r + v)/|r + v|, singular at r = −v (grazing), where the map holds nothing.
//!
//! Each texel is the lighting integral of the BRDF ([`super::glossy::Lobes`]) at that normal,
//! estimated like the reference ray tracer's glossy pixels: importance-sampled directions and the
//! point lights exactly. The environment is seen from the object's bounding sphere: every ray
//! starts on the sphere (radius `radius` about `centre`) in its own direction, so the object never
//! shadows or reflects itself, as in the paper, whose maps are images of the environment alone.
//!
//! Alpha holds the texel's confidence, cos θo = n·v: the view's foreshortening of the element,
//! 0 where the element faces away (and at the mirror warp's singularity), which is where a blend
//! of several views' maps should trust this one least. The colour is premultiplied by it (as
//! every cube map in lensmap is), so that filtering across the edge of what the view sees and
//! blending several views weight each texel by its confidence: a blend is Σ wᵢ·rgbᵢ / Σ wᵢ·αᵢ
//! ([`crate::rsibr`]).

use glam::DVec3;
use rayon::prelude::*;

use super::Ray;
use super::glossy::{Lobes, generator};
use super::shade::TraceOptions;
use super::stats::TraceCounters;
use super::world::{TraceScene, sanitize};
use crate::cubemap::{CubeFace, CubeMap};
use crate::scene::Glossy;

/// Which direction a radiance map is indexed by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Warp {
    /// The surface normal (for lobes centred on it: Lambert).
    Normal,
    /// The mirror direction of the view (for lobes centred on it: Phong, the coat).
    Mirror,
}

/// What one radiance map is computed for.
#[derive(Clone, Copy, Debug)]
pub struct RadianceMapRequest {
    /// The point the surface elements are at (the object's centre).
    pub centre: DVec3,
    /// The radius of the sphere about `centre` that the rays start on (the object's bounding
    /// sphere).
    pub radius: f64,
    /// Unit direction from the object towards the viewer.
    pub view: DVec3,
    /// The BRDF, or the lobes of it this map holds.
    pub brdf: Glossy,
    /// The direction the map is indexed by.
    pub warp: Warp,
    /// Texels along a face's edge, rounded up to a power of two (a cube map's mip chain halves
    /// it).
    pub size: u32,
    /// Directions sampled per texel (at least 2).
    pub samples: u32,
    /// Seed of the samples.
    pub seed: u64,
}

/// A radiance map and its texels' standard errors.
#[derive(Clone, Debug)]
pub struct RadianceMap {
    /// Radiance times confidence (rgb) and confidence (alpha) per texel, premultiplied; mips
    /// box-filtered channel by channel.
    pub map: CubeMap,
    /// The standard error of each level-0 texel's radiance, not premultiplied (root mean square
    /// over channels), face by face.
    pub errors: [Vec<f32>; 6],
    /// Rays traced.
    pub counters: TraceCounters,
}

impl TraceScene {
    /// The radiance map `request` asks for, its texels on the current rayon pool (the same map
    /// at any thread count: each texel's samples are seeded from its direction and the seed).
    pub fn radiance_map(
        &self,
        request: &RadianceMapRequest,
        options: &TraceOptions,
    ) -> RadianceMap {
        let size = request.size.max(1).next_power_of_two();
        let edge = size as usize;
        let seen = TraceOptions {
            glossy_samples: 0,
            ..*options
        };
        let faces: Vec<(Vec<[f32; 4]>, Vec<f32>, TraceCounters)> = CubeFace::ALL
            .par_iter()
            .map(|&face| {
                let mut counters = TraceCounters::default();
                let mut texels = Vec::with_capacity(edge * edge);
                let mut errors = Vec::with_capacity(edge * edge);
                for i in 0..edge * edge {
                    let s = ((i % edge) as f64 + 0.5) / edge as f64;
                    let t = ((i / edge) as f64 + 0.5) / edge as f64;
                    let direction = face.direction(2.0 * s - 1.0, 2.0 * t - 1.0).normalize();
                    let (texel, error) =
                        self.radiance_texel(request, direction, &seen, &mut counters);
                    texels.push(texel);
                    errors.push(error);
                }
                (texels, errors, counters)
            })
            .collect();
        let mut counters = TraceCounters::default();
        let mut level0: [Vec<[f32; 4]>; 6] = Default::default();
        let mut errors: [Vec<f32>; 6] = Default::default();
        for (k, (texels, face_errors, face_counters)) in faces.into_iter().enumerate() {
            level0[k] = texels;
            errors[k] = face_errors;
            counters += face_counters;
        }
        RadianceMap {
            map: CubeMap::from_level0(size, level0),
            errors,
            counters,
        }
    }

    /// One texel: at `direction` (the normal, or the mirror direction), the radiance and
    /// confidence, and the radiance's standard error.
    fn radiance_texel(
        &self,
        request: &RadianceMapRequest,
        direction: DVec3,
        seen: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> ([f32; 4], f32) {
        let view = request.view;
        let normal = match request.warp {
            Warp::Normal => direction,
            Warp::Mirror => (direction + view).normalize_or_zero(),
        };
        // NaN-free: a zero normal (the mirror warp's singularity) gives 0.
        let confidence = normal.dot(view);
        if confidence <= 0.0 {
            return ([0.0; 4], 0.0);
        }
        let lobes = Lobes::new(&request.brdf, normal, view);
        let from_sphere = |direction: DVec3| Ray {
            origin: request.centre + direction * request.radius,
            direction,
        };
        let mut radiance = DVec3::ZERO;
        for light in &self.lights {
            let to_light = light.position.as_dvec3() - request.centre;
            let distance = to_light.length();
            if !(distance > request.radius && distance.is_finite()) {
                continue;
            }
            let toward = to_light / distance;
            let cosine = normal.dot(toward);
            if cosine <= 0.0 {
                continue;
            }
            counters.shadow_rays += 1;
            if self.environment.occluded(
                &from_sphere(toward),
                0.0,
                distance - request.radius,
                None,
                &mut counters.triangle_tests,
            ) {
                continue;
            }
            let irradiance = light.intensity.as_dvec3() * (cosine / (distance * distance));
            radiance += lobes.eval(toward) * irradiance;
        }
        let mut rng = generator(direction.to_array(), request.seed);
        let (mean, error) = lobes.estimate(&mut rng, request.samples.max(2), normal, |incoming| {
            self.radiance_along(&from_sphere(incoming), None, seen, counters)
        });
        let total = sanitize(radiance + mean) * confidence;
        (
            [
                total.x as f32,
                total.y as f32,
                total.z as f32,
                confidence as f32,
            ],
            ((error * error).element_sum() / 3.0).sqrt() as f32,
        )
    }
}
