//! Glossy surfaces in the reference ray tracer (the reflection-space IBR paper's objects): a
//! Lambertian base and a normalized Phong lobe, optionally under a Fresnel clear coat, integrated
//! against everything the surface sees by Monte Carlo with importance sampling of the lobes
//! (one sample of the lobes' mixture per direction: multiple importance sampling with the balance
//! heuristic), and against the point lights exactly.
//!
//! With ωo towards the viewer, n the shading normal turned towards it, r the mirror direction of
//! ωo about n, and F the coat's exact dielectric Fresnel reflectance at cos θo (0 without a coat):
//!
//! ```text
//! f(ωi) = (1 − F)·(kd/π + ks·(m + 2)/2π·max(0, ωi·r)^m) + F·(c + 2)/2π·max(0, ωi·r)^c
//! ```
//!
//! The (m + 2)/2π normalization makes a lobe reflect all of a uniform environment at normal
//! incidence (∫ cos^m α cos θ dω = 2π/(m + 2) when r = n) and less where the horizon cuts it.
//! Fresnel taken at the view angle, as the paper's car paint does, keeps every lobe radially
//! symmetric about its axis, which is what the reflection-space warps assume.
//!
//! A sampled direction sees the background, a lens object's two greedy terms, or an environment
//! surface's diffuse shading under the point lights (for a glossy one, its diffuse base: there is
//! no second glossy bounce).
//!
//! Determinism: each shading point's generator is seeded from its ray's bits and
//! [`TraceOptions::glossy_seed`], so an image is the same at any thread count, and two seeds give
//! independent estimates.

use std::f64::consts::{FRAC_1_PI, TAU};
use std::hash::Hasher;

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::Ray;
use super::bvh::SurfaceHit;
use super::fresnel::{dielectric, reflect};
use super::shade::{Receiver, TraceOptions};
use super::stats::TraceCounters;
use super::world::{Part, SurfaceId, TraceScene, sanitize};
use crate::scene::Glossy;

/// How far off a glossy surface its rays start, relative to the coordinates' magnitude.
const ORIGIN_OFFSET: f64 = 1e-6;

/// A glossy pixel's Monte Carlo estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlossyEstimate {
    /// Outgoing radiance towards the viewer: the point lights' exact part plus the mean of the
    /// sampled part.
    pub radiance: DVec3,
    /// Standard error of the sampled part's mean, per channel (the sample standard deviation
    /// over √N).
    pub standard_error: DVec3,
}

/// The BRDF at one shading point, for one viewing direction.
#[derive(Clone, Copy, Debug)]
pub struct Lobes {
    /// Shading normal, towards the viewer.
    normal: DVec3,
    /// Mirror direction of the viewing direction about the normal: the Phong lobes' axis.
    mirror: DVec3,
    /// `(1 − F)·kd/π`.
    diffuse: DVec3,
    /// `(1 − F)·ks`, and the base's Phong exponent.
    specular: (DVec3, f64),
    /// `F`, and the coat's Phong exponent.
    coat: (f64, f64),
    /// Probabilities of sampling the diffuse lobe, the base's Phong lobe and the coat's.
    choice: [f64; 3],
}

impl Lobes {
    /// `brdf` seen from `toward_viewer` (unit) at a point with shading normal `normal` (unit, on
    /// the viewer's side).
    pub fn new(brdf: &Glossy, normal: DVec3, toward_viewer: DVec3) -> Lobes {
        let cos_view = normal.dot(toward_viewer).clamp(0.0, 1.0);
        let fresnel = brdf.coat.map_or(0.0, |coat| {
            dielectric(cos_view, 1.0, f64::from(coat.ior)).reflectance
        });
        let base = 1.0 - fresnel;
        let kd = brdf.diffuse.as_dvec3() * base;
        let ks = brdf.specular.as_dvec3() * base;
        let weights = [kd.element_sum() / 3.0, ks.element_sum() / 3.0, fresnel];
        let total: f64 = weights.iter().sum();
        let choice = if total > 0.0 {
            weights.map(|w| w / total)
        } else {
            [1.0, 0.0, 0.0]
        };
        Lobes {
            normal,
            mirror: reflect(-toward_viewer, normal),
            diffuse: kd * FRAC_1_PI,
            specular: (ks, f64::from(brdf.exponent)),
            coat: (fresnel, brdf.coat.map_or(1.0, |c| f64::from(c.exponent))),
            choice,
        }
    }

    /// f(ωi), per channel.
    pub fn eval(&self, incoming: DVec3) -> DVec3 {
        if incoming.dot(self.normal) <= 0.0 {
            return DVec3::ZERO;
        }
        let cos_alpha = incoming.dot(self.mirror).max(0.0);
        let lobe = |exponent: f64| (exponent + 2.0) / TAU * cos_alpha.powf(exponent);
        self.diffuse
            + self.specular.0 * lobe(self.specular.1)
            + DVec3::splat(self.coat.0 * lobe(self.coat.1))
    }

    /// The density of [`Lobes::sample`] at `incoming` (solid angle).
    pub fn pdf(&self, incoming: DVec3) -> f64 {
        let cos_theta = incoming.dot(self.normal).max(0.0);
        let cos_alpha = incoming.dot(self.mirror).max(0.0);
        let phong = |exponent: f64| (exponent + 1.0) / TAU * cos_alpha.powf(exponent);
        self.choice[0] * cos_theta * FRAC_1_PI
            + self.choice[1] * phong(self.specular.1)
            + self.choice[2] * phong(self.coat.1)
    }

    /// A direction drawn from the mixture of the lobes' densities (cosine-weighted about the
    /// normal, cos^m α about the mirror direction); it may point below the surface.
    pub fn sample(&self, rng: &mut impl Rng) -> DVec3 {
        let pick: f64 = rng.r#gen();
        let (u, v): (f64, f64) = (rng.r#gen(), rng.r#gen());
        if pick < self.choice[0] {
            around(self.normal, u.sqrt(), v)
        } else {
            let exponent = if pick < self.choice[0] + self.choice[1] {
                self.specular.1
            } else {
                self.coat.1
            };
            around(self.mirror, u.powf(1.0 / (exponent + 1.0)), v)
        }
    }
}

impl Lobes {
    /// The mean of `samples` (≥ 1) draws of f·cos θ·L/pdf and its standard error, per channel:
    /// `arriving(direction)` gives L for a direction above both the shading normal and `face`;
    /// a direction below either counts 0.
    pub(crate) fn estimate(
        &self,
        rng: &mut impl Rng,
        samples: u32,
        face: DVec3,
        mut arriving: impl FnMut(DVec3) -> DVec3,
    ) -> (DVec3, DVec3) {
        let samples = samples.max(1);
        let (mut mean, mut squares) = (DVec3::ZERO, DVec3::ZERO);
        for k in 0..samples {
            let direction = self.sample(rng);
            let cosine = direction.dot(self.normal);
            let mut value = DVec3::ZERO;
            if cosine > 0.0 && direction.dot(face) > 0.0 {
                let pdf = self.pdf(direction);
                if pdf > 0.0 {
                    value = sanitize(self.eval(direction) * arriving(direction) * (cosine / pdf));
                }
            }
            // Welford's running mean and sum of squared deviations, per channel.
            let delta = value - mean;
            mean += delta / f64::from(k + 1);
            squares += delta * (value - mean);
        }
        let n = f64::from(samples);
        let variance = if samples > 1 {
            squares / (n - 1.0)
        } else {
            DVec3::ZERO
        };
        (mean, (variance / n).max(DVec3::ZERO).map(f64::sqrt))
    }
}

/// The unit direction at cosine `cos_theta` from `axis` and azimuth `2π·v`.
fn around(axis: DVec3, cos_theta: f64, v: f64) -> DVec3 {
    let (tangent, bitangent) = axis.any_orthonormal_pair();
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = TAU * v;
    (tangent * phi.cos() + bitangent * phi.sin()) * sin_theta + axis * cos_theta
}

/// A generator seeded from `values`' bits and `seed`: the same values, the same samples, on any
/// thread.
pub(crate) fn generator(values: impl IntoIterator<Item = f64>, seed: u64) -> Pcg64Mcg {
    let mut hasher = rustc_hash::FxHasher::default();
    for value in values {
        hasher.write_u64(value.to_bits());
    }
    hasher.write_u64(seed);
    Pcg64Mcg::seed_from_u64(hasher.finish())
}

impl TraceScene {
    /// Radiance leaving glossy surface `hit` (of material `brdf`) towards the origin of `ray`:
    /// the point lights exactly, everything else by [`TraceOptions::glossy_samples`] samples.
    pub fn shade_glossy(
        &self,
        ray: &Ray,
        hit: &SurfaceHit,
        brdf: &Glossy,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> GlossyEstimate {
        let toward_viewer = -ray.direction;
        let side = if hit.is_front_facing(ray.direction) {
            1.0
        } else {
            -1.0
        };
        let face = hit.geometric_normal * side;
        let lobes = Lobes::new(brdf, hit.shading_normal * side, toward_viewer);
        // Off the surface by 1e-6 of the coordinates' magnitude, not the lens paths' 1e-9: a
        // camera ray through a vertex of a curved mesh meets the hit triangle's plane a few
        // nanometres inside its neighbours' (within the triangle test's slack), and from 1e-9
        // above it a ray leaving the surface would hit a neighbour.
        let magnitude = hit.position.abs().max_element().max(1.0);
        let origin = hit.position + face * (ORIGIN_OFFSET * magnitude);
        let exclude = SurfaceId {
            part: Part::Environment,
            primitive: hit.primitive,
        };
        let receiver = Receiver {
            position: hit.position,
            origin,
            normal: lobes.normal,
            face,
            primitive: hit.primitive,
        };
        let mut radiance = DVec3::ZERO;
        self.for_each_light(&receiver, counters, |direction, irradiance| {
            radiance += lobes.eval(direction) * irradiance;
        });
        // What the sampled directions see shades glossy surfaces by their diffuse base.
        let seen_options = TraceOptions {
            glossy_samples: 0,
            ..*options
        };
        let bits = ray
            .origin
            .to_array()
            .into_iter()
            .chain(ray.direction.to_array());
        let mut rng = generator(bits, options.glossy_seed);
        let (mean, standard_error) =
            lobes.estimate(&mut rng, options.glossy_samples, face, |direction| {
                let ray = Ray { origin, direction };
                self.radiance_along(&ray, Some(exclude), &seen_options, counters)
            });
        GlossyEstimate {
            radiance: sanitize(radiance + mean),
            standard_error,
        }
    }

    /// Radiance arriving back along `ray`, which leaves a glossy surface (`exclude`, if on one): the
    /// background, a lens object's greedy terms (under `options`, whose glossy surfaces are
    /// shaded diffusely), or an environment surface's diffuse shading.
    pub(crate) fn radiance_along(
        &self,
        ray: &Ray,
        exclude: Option<SurfaceId>,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> DVec3 {
        counters.secondary_rays += 1;
        match self.closest_hit(ray, exclude, None, counters) {
            None => self.background_radiance(ray.direction),
            Some(seen) => match seen.part {
                Part::Lens(lens) => {
                    let [refraction, reflection] =
                        self.lens_terms(lens, ray, &seen.hit, 1, options, counters);
                    refraction + reflection
                }
                Part::Environment => self.shade_diffuse(ray, &seen.hit, counters),
            },
        }
    }
}
