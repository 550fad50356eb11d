//! Ray-path models through a lens object: the paper's two-term greedy paths and the full ray tree.
//!
//! At the first hit on a lens object the paper (§3) starts two paths, one with an initial
//! reflection and one with an initial refraction, and propagates each by following the child with
//! the larger Fresnel coefficient until it leaves the lens object. `F` multiplies the Fresnel
//! coefficients along a path and `G` the transparency attenuation `absorption^distance` of the glass
//! traversed. A mirror generates only the reflection term. [`trace_greedy_paths`] does this against
//! any [`LensGeometry`] (a BVH, or an analytic sphere in tests).
//!
//! The full ray tree ([`RayTree`]) instead follows both children at every interface through the
//! whole scene, down to a maximum depth or a contribution cutoff: the ground truth the greedy
//! model approximates.

use glam::DVec3;

use super::Ray;
use super::bvh::SurfaceHit;
use super::classes::ClassTerm;
use super::fresnel::{self, Real, Vector3};
use super::schlick_table::SchlickTable;
use super::stats::TraceCounters;

/// One term of a lens object's shading: the paper's two greedy terms `T·F_T·G_T + R·F_R·G_R`,
/// or one term of a path-class model ([`super::classes`]). The compositor sums the terms of a
/// lens object, each through its own F·G and outgoing directions, in this type's order
/// (refraction before reflection, then the classes by length and events).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Term {
    /// The path that starts with a refraction at the first lens hit (`T·F_T·G_T`).
    Refraction,
    /// The path that starts with a reflection at the first lens hit (`R·F_R·G_R`).
    Reflection,
    /// One class (or prefix with a greedy tail) of a path-class model.
    Class(ClassTerm),
}

impl Term {
    /// Short name used in pass names and tables (`T`, `R`; a class's events, `TRT`, with `+`
    /// after a prefix whose path goes on greedily).
    pub fn name(self) -> String {
        match self {
            Term::Refraction => "T".to_owned(),
            Term::Reflection => "R".to_owned(),
            Term::Class(class) => class.name(),
        }
    }
}

/// As in scene and JSON files: `refraction`, `reflection`, or the class's name.
impl serde::Serialize for Term {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self {
            Term::Refraction => serializer.serialize_str("refraction"),
            Term::Reflection => serializer.serialize_str("reflection"),
            Term::Class(class) => serializer.serialize_str(&class.name()),
        }
    }
}

/// Optical behaviour of a lens surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Interface {
    /// A smooth dielectric surrounded by air.
    Dielectric {
        /// Index of refraction of the inside (> 0).
        ior: f64,
        /// Per-channel transmittance of one metre of the medium, each in [0, 1].
        absorption: DVec3,
    },
    /// A mirror: reflection only, weighted per channel by Schlick's Fresnel.
    Mirror {
        /// Reflectance at normal incidence per channel, each in [0, 1].
        reflectance: DVec3,
    },
}

/// What a path-model query needs from a lens object.
pub trait LensGeometry {
    /// Closest hit of `ray` on this lens object at a distance > 0, skipping primitive `exclude`
    /// (the one the ray starts on). Adds triangle tests to `counters` (not the ray: the caller
    /// counts rays).
    fn closest_hit(
        &self,
        ray: &Ray,
        exclude: Option<u32>,
        counters: &mut TraceCounters,
    ) -> Option<SurfaceHit>;

    /// The interface of scene object `object` (an object of this lens).
    fn interface(&self, object: usize) -> Interface;
}

/// Limits of the greedy path propagation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GreedyOptions {
    /// Most interfaces one path may meet, the first hit included (≥ 1). A path that reaches the
    /// cap is truncated: its weight becomes 0.
    pub max_interfaces: u32,
    /// Where a path stops.
    pub bounces: Bounces,
}

impl Default for GreedyOptions {
    fn default() -> Self {
        GreedyOptions {
            max_interfaces: 16,
            bounces: Bounces::UntilLeaving,
        }
    }
}

/// Where a greedy path stops.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Bounces {
    /// Where its ray leaves the lens object: what the object shows of itself is traced (the
    /// hybrid-rendering paper's model).
    #[default]
    UntilLeaving,
    /// At the first interface, whatever its ray meets next: a reflector's first bounce. What it
    /// shows of itself is then its local layer's to hold (the PEM paper's layers by bounce).
    First,
}

/// How [`scatter_with`] evaluates the Fresnel coefficients at an interface.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum FresnelLookup<'a> {
    /// Mirrors: Schlick's approximation evaluated; glass: exact dielectric Fresnel.
    #[default]
    Exact,
    /// Schlick's approximation with its fifth-order term looked up in the table: mirrors per
    /// channel, glass with `R₀ = ((n − 1)/(n + 1))²` ([`fresnel::dielectric_schlick`]).
    SchlickTable(&'a SchlickTable),
}

impl<'a> From<Option<&'a SchlickTable>> for FresnelLookup<'a> {
    /// The table's lookup, or [`FresnelLookup::Exact`] without one.
    fn from(table: Option<&'a SchlickTable>) -> Self {
        table.map_or(FresnelLookup::Exact, FresnelLookup::SchlickTable)
    }
}

/// One greedy ray path from the first lens hit to where it leaves the lens object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GreedyRayPath {
    /// Which term the path belongs to.
    pub term: Term,
    /// `F`: product of the Fresnel coefficients along the path, per channel, in [0, 1].
    pub fresnel: DVec3,
    /// `G`: product of `absorption^distance` over the glass traversed, per channel, in [0, 1].
    pub attenuation: DVec3,
    /// The ray leaving the lens object (origin on its last interface, unit direction).
    pub outgoing_ray: Ray,
    /// Number of interfaces met, the first hit included.
    pub interfaces: u32,
    /// Distance travelled inside glass in metres.
    pub glass_distance: f64,
    /// True when the path hit the interface cap before leaving (its weight is then 0).
    pub truncated: bool,
    /// The greedy choice at each interface after the first: bit i set when the path reflected at
    /// interface i + 2. With `interfaces` it is the path's "topology" (paper §4.1): two paths
    /// differ when either differs.
    pub reflections: u32,
}

impl GreedyRayPath {
    /// `F·G` per channel: the factor the radiance along the outgoing ray is multiplied by.
    pub fn weight(&self) -> DVec3 {
        if self.truncated {
            DVec3::ZERO
        } else {
            self.fresnel * self.attenuation
        }
    }
}

/// The two paths started at a first lens hit. A mirror (or total internal reflection at the
/// first hit) has no refraction path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwoTermPaths {
    /// The path starting with a refraction, if light is transmitted at the first hit.
    pub refraction: Option<GreedyRayPath>,
    /// The path starting with a reflection.
    pub reflection: GreedyRayPath,
}

impl TwoTermPaths {
    /// The path of `term`, if present (none for a path class: these are the greedy terms).
    pub fn get(&self, term: Term) -> Option<&GreedyRayPath> {
        match term {
            Term::Refraction => self.refraction.as_ref(),
            Term::Reflection => Some(&self.reflection),
            Term::Class(_) => None,
        }
    }
}

/// The children a ray spawns at one interface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scattering {
    /// Reflected ray (origin offset to the incident side) and its Fresnel coefficient.
    pub reflection: (Ray, DVec3),
    /// Refracted ray (origin offset to the far side) and its Fresnel coefficient; `None` for a
    /// mirror or under total internal reflection.
    pub refraction: Option<(Ray, f64)>,
}

impl Scattering {
    /// The greedy child: the one with the larger Fresnel coefficient (refraction on a tie).
    pub fn greedy_child(&self) -> (Ray, DVec3) {
        match self.refraction {
            Some((ray, transmittance)) if !self.greedy_reflects() => {
                (ray, DVec3::splat(transmittance))
            }
            _ => self.reflection,
        }
    }

    /// Whether the greedy child is the reflection.
    pub fn greedy_reflects(&self) -> bool {
        match self.refraction {
            Some((_, transmittance)) => transmittance < self.reflection.1.max_element(),
            None => true,
        }
    }
}

/// Splits a ray arriving along `direction` at `hit` into its reflected and refracted children.
///
/// Which side is inside comes from the face normal (`direction · n > 0` means the ray leaves the
/// medium). The interpolated normal drives Fresnel and the directions; where it would send a child
/// to the wrong side of the face, the face normal is used instead.
pub fn scatter(interface: Interface, direction: DVec3, hit: &SurfaceHit) -> Scattering {
    scatter_in::<f64>(interface, direction, hit)
}

/// [`scatter`] with the Fresnel coefficients, the child directions and the origin offsets
/// computed in precision `R` (inputs rounded to it; results stored in f64, which holds them
/// exactly): f64 is `scatter`; f32 measures what single precision would cost.
pub fn scatter_in<R: Real>(interface: Interface, direction: DVec3, hit: &SurfaceHit) -> Scattering {
    scatter_with::<R>(interface, direction, hit, FresnelLookup::Exact)
}

/// [`scatter_in`] with the Fresnel coefficients evaluated as `fresnel` says.
pub fn scatter_with<R: Real>(
    interface: Interface,
    direction: DVec3,
    hit: &SurfaceHit,
    fresnel: FresnelLookup<'_>,
) -> Scattering {
    let entering = hit.is_front_facing(direction);
    let face = if entering {
        hit.geometric_normal
    } else {
        -hit.geometric_normal
    };
    let shading = if entering {
        hit.shading_normal
    } else {
        -hit.shading_normal
    };
    let about = |normal| Surface {
        hit,
        face,
        normal,
        entering,
    };
    let scattering = scatter_about::<R>(interface, direction, about(shading), fresnel);
    let reflection_ok = scattering.reflection.0.direction.dot(face) > 0.0;
    let refraction_ok = scattering
        .refraction
        .is_none_or(|(ray, _)| ray.direction.dot(face) < 0.0);
    if reflection_ok && refraction_ok {
        scattering
    } else {
        scatter_about::<R>(interface, direction, about(face), fresnel)
    }
}

/// Where a ray scatters: the hit, its face normal and the normal Fresnel and the directions use
/// (both on the incident side), and whether the ray enters the medium.
struct Surface<'a> {
    hit: &'a SurfaceHit,
    face: DVec3,
    normal: DVec3,
    entering: bool,
}

fn scatter_about<R: Real>(
    interface: Interface,
    direction: DVec3,
    surface: Surface<'_>,
    lookup: FresnelLookup<'_>,
) -> Scattering {
    let Surface {
        hit,
        face,
        normal,
        entering,
    } = surface;
    let vector = <R::Vec3 as Vector3>::of;
    let (direction, normal) = (vector(direction), vector(normal));
    let cos_incident = -direction.dot(normal);
    let reflected = Ray::new(
        offset_origin_in::<R>(hit.position, face),
        fresnel::reflect(direction, normal).to_dvec3(),
    );
    match interface {
        Interface::Mirror { reflectance } => Scattering {
            reflection: (
                reflected,
                match lookup {
                    FresnelLookup::Exact => fresnel::schlick(vector(reflectance), cos_incident),
                    FresnelLookup::SchlickTable(table) => {
                        fresnel::schlick_by(vector(reflectance), cos_incident, |c| {
                            table.fifth_power(c)
                        })
                    }
                }
                .to_dvec3(),
            ),
            refraction: None,
        },
        Interface::Dielectric { ior, .. } => {
            let (ior, one) = (R::of(ior), R::ONE);
            let (eta_incident, eta_transmitted) = if entering { (one, ior) } else { (ior, one) };
            let split = match lookup {
                FresnelLookup::Exact => {
                    fresnel::dielectric(cos_incident, eta_incident, eta_transmitted)
                }
                FresnelLookup::SchlickTable(table) => {
                    fresnel::dielectric_schlick(cos_incident, eta_incident, eta_transmitted, |c| {
                        table.fifth_power(c)
                    })
                }
            };
            let refraction = (!split.total_internal_reflection).then(|| {
                let refracted = fresnel::refract(
                    direction,
                    normal,
                    eta_incident / eta_transmitted,
                    split.cos_transmitted,
                );
                (
                    Ray::new(
                        offset_origin_in::<R>(hit.position, -face),
                        refracted.to_dvec3(),
                    ),
                    split.transmittance.to_f64(),
                )
            });
            Scattering {
                reflection: (reflected, DVec3::splat(split.reflectance.to_f64())),
                refraction,
            }
        }
    }
}

/// Moves a new ray's origin a hair off the surface towards `side`, so it cannot re-hit the
/// surface it starts on through rounding (f64: 1e-9 of the coordinate magnitude, at least 1 nm).
pub fn offset_origin(position: DVec3, side: DVec3) -> DVec3 {
    offset_origin_in::<f64>(position, side)
}

/// [`offset_origin`] in precision `R`, by `max(1e-9, 128 ulps of R)` of the coordinate
/// magnitude: 1e-9 in f64; 1.5e-5 in f32, whose hit positions are rounded to ~6e-8 of the
/// magnitude and would re-hit a neighbouring triangle from 1e-9 (below an f32 ulp: no move).
pub fn offset_origin_in<R: Real>(position: DVec3, side: DVec3) -> DVec3 {
    let vector = <R::Vec3 as Vector3>::of;
    let position = vector(position);
    let magnitude = position.abs().max_element().max(R::ONE);
    let offset = R::of(1e-9).max(R::of(128.0) * R::EPSILON);
    (position + vector(side) * (offset * magnitude)).to_dvec3()
}

/// Traces the two greedy paths started by `incoming` at its first hit `first_hit` on `lens`.
///
/// Counts one secondary ray per path segment traced against the lens object.
pub fn trace_greedy_paths(
    lens: &impl LensGeometry,
    incoming: &Ray,
    first_hit: &SurfaceHit,
    options: GreedyOptions,
    counters: &mut TraceCounters,
) -> TwoTermPaths {
    trace_greedy_paths_in::<f64>(
        lens,
        incoming,
        first_hit,
        options,
        FresnelLookup::Exact,
        counters,
    )
}

/// [`trace_greedy_paths`] with the scattering ([`scatter_with`]), the products of F and G and the
/// glass distance computed in precision `R`, and the Fresnel coefficients evaluated as `fresnel`
/// says: f64 and [`FresnelLookup::Exact`] is `trace_greedy_paths`; f32 measures what single
/// precision would cost, a table what Schlick through a 1D texture would. The intersections are `lens`'s: give it a geometry that
/// intersects in `R` too (e.g. [`super::bvh::MeshBvh::closest_hit_in`]) for a path wholly in `R`.
pub fn trace_greedy_paths_in<R: Real>(
    lens: &impl LensGeometry,
    incoming: &Ray,
    first_hit: &SurfaceHit,
    options: GreedyOptions,
    fresnel: FresnelLookup<'_>,
    counters: &mut TraceCounters,
) -> TwoTermPaths {
    let interface = lens.interface(first_hit.object);
    let scattering = scatter_with::<R>(interface, incoming.direction, first_hit, fresnel);
    let mut start = |term, (ray, coefficient): (Ray, DVec3)| {
        let mut path = GreedyRayPath {
            term,
            fresnel: coefficient,
            attenuation: DVec3::ONE,
            outgoing_ray: ray,
            interfaces: 1,
            glass_distance: 0.0,
            truncated: false,
            reflections: 0,
        };
        if options.bounces == Bounces::UntilLeaving {
            let exclude = first_hit.primitive;
            propagate_greedy::<R>(lens, &mut path, exclude, options, fresnel, counters);
        }
        path
    };
    let reflection = start(Term::Reflection, scattering.reflection);
    let refraction = scattering
        .refraction
        .map(|(ray, transmittance)| start(Term::Refraction, (ray, DVec3::splat(transmittance))));
    TwoTermPaths {
        refraction,
        reflection,
    }
}

/// Follows the greedy child from `path.outgoing_ray` until the ray misses the lens object.
fn propagate_greedy<R: Real>(
    lens: &impl LensGeometry,
    path: &mut GreedyRayPath,
    mut exclude: u32,
    options: GreedyOptions,
    fresnel: FresnelLookup<'_>,
    counters: &mut TraceCounters,
) {
    loop {
        counters.secondary_rays += 1;
        let Some(hit) = lens.closest_hit(&path.outgoing_ray, Some(exclude), counters) else {
            return;
        };
        let interface = lens.interface(hit.object);
        if !hit.is_front_facing(path.outgoing_ray.direction) {
            // Leaving the medium: the segment just travelled was inside it.
            if let Interface::Dielectric { absorption, .. } = interface {
                path.attenuation = product::<R>(
                    path.attenuation,
                    transmittance_in::<R>(absorption, hit.distance),
                );
                path.glass_distance = (R::of(path.glass_distance) + R::of(hit.distance)).to_f64();
            }
        }
        if path.interfaces >= options.max_interfaces.max(1) {
            path.truncated = true;
            return;
        }
        let scattering = scatter_with::<R>(interface, path.outgoing_ray.direction, &hit, fresnel);
        if scattering.greedy_reflects() && path.interfaces <= 32 {
            path.reflections |= 1 << (path.interfaces - 1);
        }
        path.interfaces += 1;
        let (ray, coefficient) = scattering.greedy_child();
        path.fresnel = product::<R>(path.fresnel, coefficient);
        path.outgoing_ray = ray;
        exclude = hit.primitive;
    }
}

/// `absorption^distance` per channel (each channel's transmittance per metre, raised to the
/// distance in metres).
pub fn transmittance(absorption: DVec3, distance: f64) -> DVec3 {
    transmittance_in::<f64>(absorption, distance)
}

/// [`transmittance`] in precision `R`.
pub fn transmittance_in<R: Real>(absorption: DVec3, distance: f64) -> DVec3 {
    let distance = R::of(distance);
    let [x, y, z] = <R::Vec3 as Vector3>::of(absorption)
        .components()
        .map(|a| a.max(R::ZERO).powf(distance));
    R::Vec3::new(x, y, z).to_dvec3()
}

/// The per-channel product `a · b` in precision `R`.
fn product<R: Real>(a: DVec3, b: DVec3) -> DVec3 {
    (<R::Vec3 as Vector3>::of(a) * <R::Vec3 as Vector3>::of(b)).to_dvec3()
}

/// Limits of the full ray tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayTreeOptions {
    /// Most interfaces along any branch (≥ 1).
    pub max_depth: u32,
    /// A child whose accumulated weight (largest channel of F·G) falls below this is not traced.
    pub cutoff: f64,
}

impl Default for RayTreeOptions {
    fn default() -> Self {
        RayTreeOptions {
            max_depth: 12,
            cutoff: 1e-3,
        }
    }
}

/// What the full ray tree needs from the scene: closest hits against everything, and the shading
/// of what is not a lens surface.
pub trait RayTree {
    /// Opaque id of a surface, to skip the one a ray starts on.
    type SurfaceId: Copy;

    /// Closest hit of `ray` over the whole scene, skipping `exclude`; the interface is `None` for a
    /// non-lens (environment) surface. Counts the ray as a secondary ray.
    fn trace_closest(
        &self,
        ray: &Ray,
        exclude: Option<Self::SurfaceId>,
        counters: &mut TraceCounters,
    ) -> Option<(SurfaceHit, Self::SurfaceId, Option<Interface>)>;

    /// Radiance leaving an environment surface at `hit` back along `ray`.
    fn shade_environment(&self, ray: &Ray, hit: &SurfaceHit, counters: &mut TraceCounters)
    -> DVec3;

    /// Radiance of the environment at infinity along `direction`.
    fn background(&self, direction: DVec3) -> DVec3;

    /// Radiance arriving back along `ray` through the full ray tree, where `weight` is the
    /// accumulated F·G of the branch so far (for the cutoff) and `depth` the interfaces met.
    fn trace_tree(
        &self,
        ray: &Ray,
        exclude: Option<Self::SurfaceId>,
        weight: DVec3,
        depth: u32,
        options: RayTreeOptions,
        counters: &mut TraceCounters,
    ) -> DVec3 {
        let Some((hit, id, interface)) = self.trace_closest(ray, exclude, counters) else {
            return self.background(ray.direction);
        };
        let Some(interface) = interface else {
            return self.shade_environment(ray, &hit, counters);
        };
        self.tree_interface(ray, &hit, id, interface, weight, depth, options, counters)
            .0
            .iter()
            .sum()
    }

    /// Both children at a lens interface `hit` (with id `id`) reached along `ray`: returns the
    /// radiance through the refracted child (already multiplied by its F·G) and through the
    /// reflected child, as `[refraction, reflection]`, plus the count of children traced.
    #[allow(clippy::too_many_arguments)]
    fn tree_interface(
        &self,
        ray: &Ray,
        hit: &SurfaceHit,
        id: Self::SurfaceId,
        interface: Interface,
        weight: DVec3,
        depth: u32,
        options: RayTreeOptions,
        counters: &mut TraceCounters,
    ) -> ([DVec3; 2], u32) {
        let mut result = [DVec3::ZERO; 2];
        let mut children = 0;
        if depth + 1 > options.max_depth.max(1) {
            return (result, children);
        }
        let scattering = scatter(interface, ray.direction, hit);
        let attenuation = match interface {
            Interface::Dielectric { absorption, .. } if !hit.is_front_facing(ray.direction) => {
                transmittance(absorption, hit.distance)
            }
            _ => DVec3::ONE,
        };
        let branch_weight = weight * attenuation;
        let mut follow = |slot: usize, child: &Ray, coefficient: DVec3| {
            let child_weight = branch_weight * coefficient;
            if child_weight.max_element() >= options.cutoff {
                children += 1;
                let radiance =
                    self.trace_tree(child, Some(id), child_weight, depth + 1, options, counters);
                result[slot] = attenuation * coefficient * radiance;
            }
        };
        if let Some((child, coefficient)) = scattering.refraction {
            follow(0, &child, DVec3::splat(coefficient));
        }
        let (child, coefficient) = scattering.reflection;
        follow(1, &child, coefficient);
        (result, children)
    }
}
