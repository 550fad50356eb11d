//! Shading: the diffuse environment under point lights, the environment at infinity, and the
//! radiance of a camera ray under either ray-path model.
//!
//! Environment surfaces are Lambertian: `L = albedo/π · Σ I·cos θ / d²` over the point lights
//! (intensity `I` in W/sr), two-sided (the normal is turned towards the viewer), with no ambient
//! term. Shadow rays test the **environment geometry only**: lens objects cast no shadows. The paper
//! shades the environment independently of the lens objects (its environment maps are images of
//! the environment alone, and the hybrid renderer draws the environment without the lens), so a
//! lens shadow would be a feature the hybrid image can never show.
//!
//! Along an outgoing ray that meets another lens object, that object is evaluated with the same
//! model (the two greedy terms, or the same path classes), up to
//! [`TraceOptions::max_lens_depth`] nested lens objects; deeper, the ray sees the environment
//! alone.

use glam::DVec3;

use super::Ray;
use super::bvh::SurfaceHit;
use super::classes::{self, ClassSet};
use super::path::{self, GreedyOptions, Interface, RayTree, RayTreeOptions, Term, TwoTermPaths};
use super::stats::TraceCounters;
use super::world::{Part, SurfaceId, TraceScene, WorldHit, sanitize};

/// A shading point as the point lights see it.
pub(crate) struct Receiver {
    /// Where it is.
    pub(crate) position: DVec3,
    /// Where its shadow rays start (off the surface, on the viewer's side).
    pub(crate) origin: DVec3,
    /// Its unit shading normal and face normal, on the viewer's side.
    pub(crate) normal: DVec3,
    pub(crate) face: DVec3,
    /// The triangle it lies on (its shadow rays skip it).
    pub(crate) primitive: u32,
}

/// Which ray-path model evaluates lens objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathModel {
    /// The paper's two-term greedy ray paths.
    Greedy,
    /// The full binary ray tree.
    Full,
    /// Fixed path classes ([`super::classes`]): the sum of one term per class.
    Classes(ClassSet),
}

impl PathModel {
    /// Its name as the command line takes it: `greedy`, `full`, or the class set (`4`,
    /// `R,TT,TRT`).
    pub fn name(&self) -> String {
        match self {
            PathModel::Greedy => "greedy".into(),
            PathModel::Full => "full".into(),
            PathModel::Classes(set) => set.name(),
        }
    }
}

impl serde::Serialize for PathModel {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.name())
    }
}

/// How much of a lens object's light a class set keeps, as throughput (`Σ F·G`, the mean of
/// the channels) summed over camera rays: the classes' paths against every path of the
/// object's local ray tree ([`super::classes::local_throughput`]). Zero under the other models.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ClassShare {
    /// `Σ F·G` of the classes' paths.
    pub kept: f64,
    /// `Σ F·G` of every path that leaves the object.
    pub throughput: f64,
}

impl ClassShare {
    /// The share of the throughput the classes drop, in [0, 1]; `None` over no lens ray.
    pub fn dropped(&self) -> Option<f64> {
        (self.throughput > 0.0).then(|| (1.0 - self.kept / self.throughput).clamp(0.0, 1.0))
    }
}

impl std::ops::AddAssign for ClassShare {
    fn add_assign(&mut self, other: Self) {
        self.kept += other.kept;
        self.throughput += other.throughput;
    }
}

/// Options of a reference render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceOptions {
    /// The ray-path model.
    pub model: PathModel,
    /// Limits of the greedy paths.
    pub greedy: GreedyOptions,
    /// Limits of the full ray tree.
    pub tree: RayTreeOptions,
    /// Greedy model: most lens objects evaluated along one camera ray (≥ 1); an outgoing ray
    /// beyond it sees the environment alone.
    pub max_lens_depth: u32,
    /// Directions sampled per shading point of a glossy surface ([`super::glossy`]); 0 shades
    /// glossy surfaces by their diffuse base under the point lights, which is what a sampled
    /// direction sees (so that glossy shading never recurses).
    pub glossy_samples: u32,
    /// Seed of the glossy surfaces' samples: two seeds give independent estimates.
    pub glossy_seed: u64,
}

/// Default of [`TraceOptions::glossy_samples`].
pub const DEFAULT_GLOSSY_SAMPLES: u32 = 256;

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            model: PathModel::Greedy,
            greedy: GreedyOptions::default(),
            tree: RayTreeOptions::default(),
            max_lens_depth: 3,
            glossy_samples: DEFAULT_GLOSSY_SAMPLES,
            glossy_seed: 0,
        }
    }
}

/// Radiance along one camera ray, split by term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSample {
    /// Total radiance (the two terms on a lens object, the environment elsewhere).
    pub radiance: DVec3,
    /// `T·F_T·G_T` (0 off the lens objects).
    pub refraction: DVec3,
    /// `R·F_R·G_R` (0 off the lens objects).
    pub reflection: DVec3,
    /// The lens object hit first, if any.
    pub lens: Option<usize>,
    /// The Monte Carlo standard error of `radiance`, per channel, where the ray meets a glossy
    /// surface first ([`super::glossy`]); 0 elsewhere (a glossy surface seen through a lens
    /// object is estimated too, but its error is not tracked).
    pub standard_error: DVec3,
    /// Whether the ray meets a glossy surface first (and it was sampled).
    pub glossy: bool,
    /// Under [`PathModel::Classes`], how much of the first lens object's throughput the
    /// classes keep along this ray; zero otherwise.
    pub class_share: ClassShare,
}

impl TraceScene {
    /// Lambertian radiance leaving environment surface `hit` towards the origin of `ray`, with
    /// shadow rays against the environment geometry.
    pub fn shade_diffuse(
        &self,
        ray: &Ray,
        hit: &SurfaceHit,
        counters: &mut TraceCounters,
    ) -> DVec3 {
        let albedo = sanitize(
            self.material(hit.object)
                .albedo(hit.uv.as_vec2())
                .as_dvec3(),
        );
        if albedo == DVec3::ZERO {
            return DVec3::ZERO;
        }
        let toward_viewer = if hit.is_front_facing(ray.direction) {
            1.0
        } else {
            -1.0
        };
        let face = hit.geometric_normal * toward_viewer;
        let normal = hit.shading_normal * toward_viewer;
        let receiver = Receiver {
            position: hit.position,
            origin: path::offset_origin(hit.position, face),
            normal,
            face,
            primitive: hit.primitive,
        };
        let mut irradiance = DVec3::ZERO;
        self.for_each_light(&receiver, counters, |_, arriving| irradiance += arriving);
        sanitize(albedo * irradiance * std::f64::consts::FRAC_1_PI)
    }

    /// Calls `arrive(direction, irradiance)` for each point light that reaches `receiver`
    /// unoccluded by the environment geometry, above both its normals: the light's unit
    /// direction and the irradiance `I·cos θ/d²` it gives (cos θ about the shading normal).
    pub(crate) fn for_each_light(
        &self,
        receiver: &Receiver,
        counters: &mut TraceCounters,
        mut arrive: impl FnMut(DVec3, DVec3),
    ) {
        for light in &self.lights {
            let to_light = light.position.as_dvec3() - receiver.position;
            let distance_squared = to_light.length_squared();
            if distance_squared <= 0.0 || !distance_squared.is_finite() {
                continue;
            }
            let distance = distance_squared.sqrt();
            let direction = to_light / distance;
            let cosine = receiver.normal.dot(direction);
            if cosine <= 0.0 || receiver.face.dot(direction) <= 0.0 {
                continue;
            }
            counters.shadow_rays += 1;
            let shadow = Ray {
                origin: receiver.origin,
                direction,
            };
            if self.environment.occluded(
                &shadow,
                0.0,
                distance,
                Some(receiver.primitive),
                &mut counters.triangle_tests,
            ) {
                continue;
            }
            arrive(
                direction,
                sanitize(light.intensity.as_dvec3()) * (cosine / distance_squared),
            );
        }
    }

    /// Radiance leaving environment surface `hit` towards the origin of `ray`: a glossy one's
    /// estimate ([`TraceScene::shade_glossy`]), else the Lambertian shading.
    pub fn shade_surface(
        &self,
        ray: &Ray,
        hit: &SurfaceHit,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> DVec3 {
        match self.material(hit.object) {
            crate::scene::Material::Glossy(glossy) if options.glossy_samples > 0 => {
                self.shade_glossy(ray, hit, glossy, options, counters)
                    .radiance
            }
            _ => self.shade_diffuse(ray, hit, counters),
        }
    }

    /// Radiance of one camera ray (counted as a primary ray) under `options`.
    pub fn trace_camera_ray(
        &self,
        ray: &Ray,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> CameraSample {
        counters.primary_rays += 1;
        let Some(world_hit) = self.closest_hit(ray, None, None, counters) else {
            let radiance = self.background_radiance(ray.direction);
            return CameraSample {
                radiance,
                refraction: DVec3::ZERO,
                reflection: DVec3::ZERO,
                lens: None,
                standard_error: DVec3::ZERO,
                glossy: false,
                class_share: ClassShare::default(),
            };
        };
        let Part::Lens(lens) = world_hit.part else {
            let hit = &world_hit.hit;
            let (radiance, standard_error, glossy) = match self.material(hit.object) {
                crate::scene::Material::Glossy(glossy) if options.glossy_samples > 0 => {
                    let estimate = self.shade_glossy(ray, hit, glossy, options, counters);
                    (estimate.radiance, estimate.standard_error, true)
                }
                _ => (self.shade_diffuse(ray, hit, counters), DVec3::ZERO, false),
            };
            return CameraSample {
                radiance,
                refraction: DVec3::ZERO,
                reflection: DVec3::ZERO,
                lens: None,
                standard_error,
                glossy,
                class_share: ClassShare::default(),
            };
        };
        let hit = &world_hit.hit;
        let ([refraction, reflection], class_share) = match options.model {
            PathModel::Full => (
                self.full_tree_terms(ray, &world_hit, options.tree, counters),
                ClassShare::default(),
            ),
            PathModel::Greedy => (
                self.greedy_terms(lens, ray, hit, 1, options, counters),
                ClassShare::default(),
            ),
            PathModel::Classes(set) => {
                let (terms, kept) = self.class_terms(lens, ray, hit, 1, set, options, counters);
                (terms, self.class_share(lens, ray, hit, kept))
            }
        };
        CameraSample {
            radiance: refraction + reflection,
            refraction,
            reflection,
            lens: Some(lens),
            standard_error: DVec3::ZERO,
            glossy: false,
            class_share,
        }
    }

    /// The two greedy paths of lens object `lens` hit by `ray` at `hit`.
    pub fn greedy_paths(
        &self,
        lens: usize,
        ray: &Ray,
        hit: &SurfaceHit,
        options: GreedyOptions,
        counters: &mut TraceCounters,
    ) -> TwoTermPaths {
        path::trace_greedy_paths(&self.lens(lens), ray, hit, options, counters)
    }

    /// `[T…, R…]` of lens object `lens` hit by `ray` at `hit` (the `depth`-th lens object along
    /// the camera ray, 1 for the first) under `options.model`: the two greedy terms, or the sums
    /// of the classes that start with a refraction and with a reflection. (The full tree is
    /// evaluated from the camera ray only; where a glossy surface's sample meets a lens object
    /// below it, the greedy terms stand in, as they always have.)
    pub fn lens_terms(
        &self,
        lens: usize,
        ray: &Ray,
        hit: &SurfaceHit,
        depth: u32,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> [DVec3; 2] {
        match options.model {
            PathModel::Classes(set) => {
                self.class_terms(lens, ray, hit, depth, set, options, counters)
                    .0
            }
            PathModel::Greedy | PathModel::Full => {
                self.greedy_terms(lens, ray, hit, depth, options, counters)
            }
        }
    }

    /// `[Σ T…, Σ R…]` of the classes of `set` on lens object `lens` hit by `ray` at `hit`, and
    /// `Σ F·G` of their paths (what they keep of the object's throughput).
    #[allow(clippy::too_many_arguments)]
    fn class_terms(
        &self,
        lens: usize,
        ray: &Ray,
        hit: &SurfaceHit,
        depth: u32,
        set: ClassSet,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> ([DVec3; 2], DVec3) {
        let geometry = self.lens(lens);
        let Some(interface) = self.interface(hit.object) else {
            return ([DVec3::ZERO; 2], DVec3::ZERO);
        };
        let mut terms = [DVec3::ZERO; 2];
        let mut kept = DVec3::ZERO;
        for term in set.terms(interface) {
            let Some(path) = classes::trace_term(&geometry, ray, hit, term, counters) else {
                continue;
            };
            let weight = path.weight();
            kept += weight;
            if weight == DVec3::ZERO {
                continue;
            }
            let radiance =
                self.outgoing_radiance(&path.outgoing_ray, lens, depth, options, counters);
            terms[usize::from(term.class.starts_reflected())] += sanitize(weight * radiance);
        }
        (terms, kept)
    }

    /// The share of lens object `lens`'s throughput along `ray` that paths of weight `kept`
    /// hold (see [`ClassShare`]). The local tree's rays are not counted: the share is a report,
    /// not the image's work (its time is in the render's, though).
    fn class_share(&self, lens: usize, ray: &Ray, hit: &SurfaceHit, kept: DVec3) -> ClassShare {
        // As deep as any term goes (32 events) and to a cutoff far below any term's weight, so
        // that no kept path is missing from the total.
        let limits = RayTreeOptions {
            max_depth: classes::MAX_EVENTS,
            cutoff: 1e-9,
        };
        let mut uncounted = TraceCounters::default();
        let throughput =
            classes::local_throughput(&self.lens(lens), ray, hit, limits, &mut uncounted);
        ClassShare {
            kept: kept.element_sum() / 3.0,
            throughput: throughput.element_sum() / 3.0,
        }
    }

    /// `[T·F_T·G_T, R·F_R·G_R]` of lens object `lens` hit by `ray` at `hit`, the lens being the
    /// `depth`-th lens object along the camera ray (1 for the first).
    pub fn greedy_terms(
        &self,
        lens: usize,
        ray: &Ray,
        hit: &SurfaceHit,
        depth: u32,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> [DVec3; 2] {
        let paths = self.greedy_paths(lens, ray, hit, options.greedy, counters);
        let mut terms = [DVec3::ZERO; 2];
        for (slot, term) in [Term::Refraction, Term::Reflection].into_iter().enumerate() {
            let Some(path) = paths.get(term) else {
                continue;
            };
            let weight = path.weight();
            if weight == DVec3::ZERO {
                continue;
            }
            let radiance =
                self.outgoing_radiance(&path.outgoing_ray, lens, depth, options, counters);
            terms[slot] = sanitize(weight * radiance);
        }
        terms
    }

    /// Radiance arriving back along an outgoing ray that has left lens object `from` (the
    /// `depth`-th lens object along the camera ray): the environment, the environment at infinity,
    /// or another lens object evaluated with the greedy model.
    pub fn outgoing_radiance(
        &self,
        ray: &Ray,
        from: usize,
        depth: u32,
        options: &TraceOptions,
        counters: &mut TraceCounters,
    ) -> DVec3 {
        counters.secondary_rays += 1;
        let nested = depth < options.max_lens_depth.max(1);
        let hit = if nested {
            self.closest_hit(ray, None, Some(from), counters)
        } else {
            self.closest_environment_hit(ray, None, counters)
        };
        match hit {
            None => self.background_radiance(ray.direction),
            Some(WorldHit {
                hit,
                part: Part::Environment,
            }) => self.shade_surface(ray, &hit, options, counters),
            Some(WorldHit {
                hit,
                part: Part::Lens(lens),
            }) => {
                let [t, r] = self.lens_terms(lens, ray, &hit, depth + 1, options, counters);
                t + r
            }
        }
    }

    /// `[refraction subtree, reflection subtree]` of the full ray tree at the first lens hit.
    fn full_tree_terms(
        &self,
        ray: &Ray,
        world_hit: &WorldHit,
        options: RayTreeOptions,
        counters: &mut TraceCounters,
    ) -> [DVec3; 2] {
        let Some(interface) = self.interface(world_hit.hit.object) else {
            return [DVec3::ZERO; 2];
        };
        let (terms, _) = self.tree_interface(
            ray,
            &world_hit.hit,
            world_hit.surface(),
            interface,
            DVec3::ONE,
            0,
            options,
            counters,
        );
        terms.map(sanitize)
    }
}

impl RayTree for TraceScene {
    type SurfaceId = SurfaceId;

    fn trace_closest(
        &self,
        ray: &Ray,
        exclude: Option<SurfaceId>,
        counters: &mut TraceCounters,
    ) -> Option<(SurfaceHit, SurfaceId, Option<Interface>)> {
        counters.secondary_rays += 1;
        let world_hit = self.closest_hit(ray, exclude, None, counters)?;
        let interface = match world_hit.part {
            Part::Environment => None,
            Part::Lens(_) => self.interface(world_hit.hit.object),
        };
        Some((world_hit.hit, world_hit.surface(), interface))
    }

    fn shade_environment(
        &self,
        ray: &Ray,
        hit: &SurfaceHit,
        counters: &mut TraceCounters,
    ) -> DVec3 {
        self.shade_diffuse(ray, hit, counters)
    }

    fn background(&self, direction: DVec3) -> DVec3 {
        self.background_radiance(direction)
    }
}
