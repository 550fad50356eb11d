//! Ray-path classes: fixed event sequences through a lens object, beyond the papers' two greedy
//! terms.
//!
//! A class is the complete sequence of events of a path through a lens object, from its first
//! hit until its ray misses the object: `R` (reflected at the first hit and gone), `TT`
//! (refracted in, refracted out), `TRT` (one internal reflection), `TRRT`, …; `R`, `RR`, … for
//! mirrors. A path that leaves and meets the object again (a spout in front of a body) goes on
//! with its sequence, as the greedy paths do. The classes partition the paths of the object's
//! local ray tree: every path has exactly one sequence, so a set of classes counts no light
//! twice, and what it leaves out is the light of the sequences not listed. Where an event is
//! impossible (total internal reflection where the class says refract), or the ray leaves
//! before the sequence ends or meets the object after it, that path has another sequence and
//! carries nothing in this class.
//!
//! Fixed classes keep ray trees coherent from one vertex to the next (what adaptive
//! tessellation needs, the reason the hybrid-rendering paper chose greedy paths) while
//! recovering the light the greedy choice drops: the weaker child carries 10–25 % of the light
//! near a glass ball's rim.

use glam::DVec3;

use super::Ray;
use super::bvh::SurfaceHit;
use super::path::{Interface, LensGeometry, RayTreeOptions, scatter, transmittance};
use super::stats::TraceCounters;

/// The longest class: 32 events (one bit each).
pub const MAX_EVENTS: u32 = 32;

/// The most classes one set holds.
pub const MAX_CLASSES: usize = 16;

/// What a path does at one interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// Reflects (`R`).
    Reflect,
    /// Refracts through (`T`).
    Refract,
}

/// A fixed event sequence through a lens object (see the module).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PathClass {
    /// Events, 1 to [`MAX_EVENTS`].
    len: u8,
    /// Bit i set when event i (0-based) is a reflection.
    reflections: u32,
}

impl PathClass {
    /// The class of `events` (1 to [`MAX_EVENTS`] of them).
    pub fn new(events: &[Event]) -> Option<PathClass> {
        if events.is_empty() || events.len() > MAX_EVENTS as usize {
            return None;
        }
        let reflections = events
            .iter()
            .enumerate()
            .filter(|(_, e)| **e == Event::Reflect)
            .fold(0u32, |bits, (i, _)| bits | 1 << i);
        Some(PathClass {
            len: events.len() as u8,
            reflections,
        })
    }

    /// `prefix` (none for the empty sequence) followed by `event`; `None` past [`MAX_EVENTS`].
    pub fn then(prefix: Option<PathClass>, event: Event) -> Option<PathClass> {
        let (len, reflections) = prefix.map_or((0, 0), |p| (p.len, p.reflections));
        (u32::from(len) < MAX_EVENTS).then(|| PathClass {
            len: len + 1,
            reflections: match event {
                Event::Reflect => reflections | 1 << len,
                Event::Refract => reflections,
            },
        })
    }

    /// Its `i`-th event (0-based), if it has one.
    fn event(self, i: u32) -> Option<Event> {
        (i < u32::from(self.len)).then(|| {
            if self.reflections & (1 << i) != 0 {
                Event::Reflect
            } else {
                Event::Refract
            }
        })
    }

    /// Reads a class written in `R` and `T` (`"TRRT"`); `None` for anything else.
    pub fn parse(text: &str) -> Option<PathClass> {
        let events: Option<Vec<Event>> = text
            .chars()
            .map(|c| match c {
                'R' => Some(Event::Reflect),
                'T' => Some(Event::Refract),
                _ => None,
            })
            .collect();
        PathClass::new(&events?)
    }

    /// Its events in order.
    pub fn events(self) -> impl Iterator<Item = Event> {
        (0..u32::from(self.len)).filter_map(move |i| self.event(i))
    }

    /// Number of interfaces the class's path meets.
    pub fn events_len(self) -> u32 {
        u32::from(self.len)
    }

    /// Whether the class starts with a reflection (the papers' `R` term's family).
    pub fn starts_reflected(self) -> bool {
        self.reflections & 1 != 0
    }

    /// Its name, `R`, `TT`, `TRRT`, ….
    pub fn name(self) -> String {
        self.events()
            .map(|e| match e {
                Event::Reflect => 'R',
                Event::Refract => 'T',
            })
            .collect()
    }

    /// The `i`-th class of glass in the canonical order `R, TT, TRT, TR²T, …` (0-based).
    pub fn glass(i: usize) -> Option<PathClass> {
        match i {
            0 => PathClass::new(&[Event::Reflect]),
            _ => {
                let mut events = vec![Event::Refract];
                events.extend(std::iter::repeat_n(Event::Reflect, i - 1));
                events.push(Event::Refract);
                PathClass::new(&events)
            }
        }
    }

    /// The `i`-th class of a mirror in the canonical order `R, RR, RRR, …` (0-based).
    pub fn mirror(i: usize) -> Option<PathClass> {
        PathClass::new(&vec![Event::Reflect; i + 1])
    }
}

/// Which classes a lens object's shading sums: the first N of the canonical order of its
/// material, or a list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClassSet {
    /// The first N (1 to [`MAX_CLASSES`]) classes: `R, TT, TRT, …` for glass, `R, RR, …` for
    /// mirrors.
    First(u8),
    /// These classes (1 to [`MAX_CLASSES`], distinct), for every material; a class a mirror
    /// cannot follow (one with a `T`) carries nothing there.
    List {
        /// The classes; the first `len` are used.
        classes: [PathClass; MAX_CLASSES],
        /// How many.
        len: u8,
    },
    /// The local tree expanded to D events (1 to [`MAX_EXPANDED_DEPTH`]), greedy below: one
    /// term per sequence of D events, each followed by the greedy choice until it leaves, and
    /// one per complete sequence shorter than D. Depth 1 is the papers' two greedy terms. The
    /// terms have distinct first events, so no light is counted twice.
    Expanded(u8),
}

/// The deepest expansion [`ClassSet::Expanded`] takes (2 + 4 + 8 = 14 terms for glass).
pub const MAX_EXPANDED_DEPTH: u8 = 3;

/// One term of a lens object's shading: a complete class, or a prefix whose path goes on by the
/// greedy choice ([`ClassSet::Expanded`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ClassTerm {
    /// The class, or the prefix.
    pub class: PathClass,
    /// Whether the path goes on greedily after `class`'s events.
    pub greedy_tail: bool,
}

impl ClassTerm {
    /// Its name: the class's events (`TRT`), with `+` after a prefix whose path goes on
    /// greedily (`TR+`).
    pub fn name(self) -> String {
        let mut name = self.class.name();
        if self.greedy_tail {
            name.push('+');
        }
        name
    }
}

/// A lens object's class terms as a value that copies (at most [`MAX_CLASSES`]; none: the two
/// greedy terms), as the GPU's passes take them: what their control words hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClassList {
    terms: [ClassTerm; MAX_CLASSES],
    len: u8,
}

impl Default for ClassList {
    fn default() -> Self {
        ClassList::GREEDY
    }
}

impl ClassList {
    /// No classes: the two greedy terms.
    pub const GREEDY: ClassList = ClassList {
        terms: [ClassTerm {
            class: PathClass {
                len: 1,
                reflections: 1,
            },
            greedy_tail: false,
        }; MAX_CLASSES],
        len: 0,
    };

    /// The list of `terms`; `None` past [`MAX_CLASSES`] (which no [`ClassSet`] gives).
    pub fn new(terms: &[ClassTerm]) -> Option<ClassList> {
        if terms.len() > MAX_CLASSES {
            return None;
        }
        let mut list = ClassList::GREEDY;
        list.terms[..terms.len()].copy_from_slice(terms);
        list.len = terms.len() as u8;
        Some(list)
    }

    /// Its terms, in order.
    pub fn terms(&self) -> &[ClassTerm] {
        &self.terms[..usize::from(self.len)]
    }

    /// Two words per term, as the GPU's control words hold them: its events (bits 0–7) and
    /// whether its path goes on greedily (bit 8), then its reflections (bit i for event i).
    pub fn words(&self) -> impl Iterator<Item = u32> + '_ {
        self.terms().iter().flat_map(|t| {
            [
                u32::from(t.class.len) | u32::from(t.greedy_tail) << 8,
                t.class.reflections,
            ]
        })
    }
}

impl ClassSet {
    /// Reads `N` (a count) or a comma-separated list such as `R,TT,TRT,TRRT`.
    pub fn parse(text: &str) -> Result<ClassSet, String> {
        let text = text.trim();
        if let Some(depth) = text.strip_prefix("greedy:") {
            return match depth.parse::<u8>() {
                Ok(d) if (1..=MAX_EXPANDED_DEPTH).contains(&d) => Ok(ClassSet::Expanded(d)),
                _ => Err(format!(
                    "'{text}': give greedy:D with D from 1 to {MAX_EXPANDED_DEPTH} (the tree expanded to D events, greedy below)"
                )),
            };
        }
        if let Ok(count) = text.parse::<usize>() {
            return if (1..=MAX_CLASSES).contains(&count) {
                Ok(ClassSet::First(count as u8))
            } else {
                Err(format!(
                    "{count} classes: give 1 to {MAX_CLASSES} (the first N of R, TT, TRT, … for glass; of R, RR, … for mirrors)"
                ))
            };
        }
        let mut classes = [PathClass::new(&[Event::Reflect]).expect("R"); MAX_CLASSES];
        let mut len = 0usize;
        for word in text.split(',').map(str::trim) {
            let class = PathClass::parse(word).ok_or_else(|| {
                format!(
                    "'{word}' is not a path class: write one in R and T, 1 to {MAX_EVENTS} events (R, TT, TRT, …)"
                )
            })?;
            if classes[..len].contains(&class) {
                return Err(format!(
                    "'{word}' is listed twice: each path belongs to one class, so list each once"
                ));
            }
            if len == MAX_CLASSES {
                return Err(format!(
                    "more than {MAX_CLASSES} classes: list at most {MAX_CLASSES}"
                ));
            }
            classes[len] = class;
            len += 1;
        }
        Ok(ClassSet::List {
            classes,
            len: len as u8,
        })
    }

    /// The terms for a lens object whose first hit is a surface of `interface` (which chooses
    /// the canonical order of [`ClassSet::First`]).
    pub fn terms(&self, interface: Interface) -> Vec<ClassTerm> {
        let complete = |class| ClassTerm {
            class,
            greedy_tail: false,
        };
        match *self {
            ClassSet::First(n) => (0..usize::from(n))
                .filter_map(|i| match interface {
                    Interface::Dielectric { .. } => PathClass::glass(i),
                    Interface::Mirror { .. } => PathClass::mirror(i),
                })
                .map(complete)
                .collect(),
            ClassSet::List { classes, len } => classes[..usize::from(len)]
                .iter()
                .copied()
                .map(complete)
                .collect(),
            ClassSet::Expanded(depth) => {
                // Both events whatever the first surface: a lens may join mirrors and glass,
                // and a sequence a mirror cannot follow costs nothing (no ray is traced).
                let events = [Event::Reflect, Event::Refract];
                // Every sequence of 1 to `depth` events: the shorter ones complete, those of
                // `depth` events with greedy tails.
                let mut sequences: Vec<Vec<Event>> = vec![Vec::new()];
                let mut terms = Vec::new();
                for length in 1..=depth {
                    sequences = sequences
                        .iter()
                        .flat_map(|s| events.iter().map(move |e| [s.as_slice(), &[*e]].concat()))
                        .collect();
                    for sequence in &sequences {
                        if let Some(class) = PathClass::new(sequence) {
                            terms.push(ClassTerm {
                                class,
                                greedy_tail: length == depth,
                            });
                        }
                    }
                }
                terms
            }
        }
    }

    /// Its name: the count, or the list (`R,TT,TRT`).
    pub fn name(&self) -> String {
        match *self {
            ClassSet::First(n) => n.to_string(),
            ClassSet::Expanded(depth) => format!("greedy:{depth}"),
            ClassSet::List { classes, len } => classes[..usize::from(len)]
                .iter()
                .map(|c| c.name())
                .collect::<Vec<_>>()
                .join(","),
        }
    }
}

/// One class's path through a lens object, from its first hit to where its ray leaves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassPath {
    /// The path's whole sequence: the class, or a prefix and its greedy tail.
    pub class: PathClass,
    /// `F`: the product of the Fresnel coefficients of its events, per channel.
    pub fresnel: DVec3,
    /// `G`: the product of `absorption^distance` over the glass traversed, per channel.
    pub attenuation: DVec3,
    /// The ray leaving the lens object (origin on its last interface, unit direction).
    pub outgoing_ray: Ray,
    /// Distance travelled inside glass, metres.
    pub glass_distance: f64,
}

impl ClassPath {
    /// `F·G` per channel: what the radiance along the outgoing ray is multiplied by.
    pub fn weight(&self) -> DVec3 {
        self.fresnel * self.attenuation
    }
}

/// The path of `class` started by `incoming` at its first hit `first_hit` on `lens`, or `None`
/// where the path has another sequence (an impossible event, or the ray leaving before the
/// sequence ends or meeting the object after it). Counts one secondary ray per segment traced
/// against the lens object.
pub fn trace_class(
    lens: &impl LensGeometry,
    incoming: &Ray,
    first_hit: &SurfaceHit,
    class: PathClass,
    counters: &mut TraceCounters,
) -> Option<ClassPath> {
    let term = ClassTerm {
        class,
        greedy_tail: false,
    };
    trace_term(lens, incoming, first_hit, term, counters)
}

/// Most interfaces a greedy tail meets in all: the greedy paths' default
/// ([`super::path::GreedyOptions::max_interfaces`], which the tails do not read); a path that
/// reaches it carries nothing.
const MAX_TAIL_INTERFACES: u32 = 16;

/// The path of `term` started by `incoming` at `first_hit` on `lens`: for a complete class,
/// [`trace_class`]; for a prefix, its events and then the greedy choice (the child with the
/// larger Fresnel coefficient) until the ray leaves, or `None` where the prefix cannot be
/// followed or the path leaves before it ends.
pub fn trace_term(
    lens: &impl LensGeometry,
    incoming: &Ray,
    first_hit: &SurfaceHit,
    term: ClassTerm,
    counters: &mut TraceCounters,
) -> Option<ClassPath> {
    let prefix = term.class;
    let mut path = ClassPath {
        class: prefix,
        fresnel: DVec3::ONE,
        attenuation: DVec3::ONE,
        outgoing_ray: *incoming,
        glass_distance: 0.0,
    };
    let mut taken: Option<PathClass> = None;
    let mut hit = *first_hit;
    loop {
        let scattering = scatter(
            lens.interface(hit.object),
            path.outgoing_ray.direction,
            &hit,
        );
        let done = taken.map_or(0, PathClass::events_len);
        let (event, (ray, coefficient)) = match prefix.event(done) {
            Some(Event::Reflect) => (Event::Reflect, scattering.reflection),
            Some(Event::Refract) => {
                let (ray, t) = scattering.refraction?;
                (Event::Refract, (ray, DVec3::splat(t)))
            }
            None if scattering.greedy_reflects() => (Event::Reflect, scattering.reflection),
            None => (Event::Refract, scattering.greedy_child()),
        };
        let sequence = PathClass::then(taken, event)?;
        taken = Some(sequence);
        path.fresnel *= coefficient;
        path.outgoing_ray = ray;
        counters.secondary_rays += 1;
        let next = next_interface(lens, &ray, hit.primitive, counters);
        let whole_prefix = sequence.events_len() >= prefix.events_len();
        let Some(next) = next else {
            // Left: the path is the term's if it went through the whole prefix (a shorter
            // sequence is another class).
            return whole_prefix.then_some(ClassPath {
                class: sequence,
                ..path
            });
        };
        // A complete class must leave after its last event; a tail stops at the cap.
        let cap = if term.greedy_tail {
            MAX_TAIL_INTERFACES
        } else {
            prefix.events_len()
        };
        if sequence.events_len() >= cap {
            return None;
        }
        if !next.is_front_facing(ray.direction)
            && let Interface::Dielectric { absorption, .. } = lens.interface(next.object)
        {
            path.attenuation *= transmittance(absorption, next.distance);
            path.glass_distance += next.distance;
        }
        hit = next;
    }
}

/// The nearest hit of a ray spawned at a lens surface closer than this (relative to the
/// coordinates' magnitude, at least 1 m) is a crack or an overlap of the mesh where the ray starts,
/// not another interface: a UV sphere's seam, whose two columns of vertices differ by an f32
/// rounding of sin 2π (1e-7), gives a ray spawned at a seam vertex such a hit. A path class
/// counts its events exactly, so a spurious one would move the path to another class (the
/// greedy terms merely bend). Ten times the f32 rounding of a unit coordinate (1.2e-7).
const CRACK: f64 = 1.2e-6;

/// The next interface `ray` (spawned on primitive `from`) meets on `lens`: its nearest hit,
/// skipping hits within [`CRACK`] of where it starts (each skipped one counted as a ray).
fn next_interface(
    lens: &impl LensGeometry,
    ray: &Ray,
    from: u32,
    counters: &mut TraceCounters,
) -> Option<SurfaceHit> {
    let crack = CRACK * ray.origin.abs().max_element().max(1.0);
    let (mut ray, mut exclude, mut travelled) = (*ray, from, 0.0);
    // A handful of slivers at most meet at one point; past them the hit stands.
    for _ in 0..4 {
        let mut next = lens.closest_hit(&ray, Some(exclude), counters)?;
        if travelled + next.distance >= crack {
            next.distance += travelled;
            return Some(next);
        }
        travelled += next.distance;
        ray = Ray {
            origin: next.position,
            ..ray
        };
        exclude = next.primitive;
        counters.secondary_rays += 1;
    }
    let mut next = lens.closest_hit(&ray, Some(exclude), counters)?;
    next.distance += travelled;
    Some(next)
}

/// `Σ F·G` per channel over every path of the local ray tree of `lens` from `first_hit`: the
/// share of the light arriving along `incoming` that leaves the object at all (1 for clear glass,
/// less where glass absorbs or where branches end past `limits.max_depth` events or below
/// `limits.cutoff`). The classes' share of it is what a class set keeps; the rest it drops.
pub fn local_throughput(
    lens: &impl LensGeometry,
    incoming: &Ray,
    first_hit: &SurfaceHit,
    limits: RayTreeOptions,
    counters: &mut TraceCounters,
) -> DVec3 {
    let mut sum = DVec3::ZERO;
    local_tree(
        lens,
        incoming,
        first_hit,
        limits,
        counters,
        &mut |_, weight| {
            sum += weight;
        },
    );
    sum
}

/// Calls `leaf(class, F·G)` for every path of the local ray tree of `lens` from `first_hit`
/// that leaves the object within `limits` (both children at every interface; a branch below
/// `limits.cutoff` or past `limits.max_depth` events is not followed): the classes that carry
/// light there, for ranking them ([`rank_classes`]).
pub fn local_tree(
    lens: &impl LensGeometry,
    incoming: &Ray,
    first_hit: &SurfaceHit,
    limits: RayTreeOptions,
    counters: &mut TraceCounters,
    leaf: &mut impl FnMut(PathClass, DVec3),
) {
    /// One interface of the walk: where it is, how the path got there (none at the first
    /// hit), and its weight so far.
    struct Node<'a> {
        direction: DVec3,
        hit: &'a SurfaceHit,
        events: Option<PathClass>,
        weight: DVec3,
    }
    fn branch(
        lens: &impl LensGeometry,
        node: Node<'_>,
        limits: RayTreeOptions,
        counters: &mut TraceCounters,
        leaf: &mut impl FnMut(PathClass, DVec3),
    ) {
        let scattering = scatter(lens.interface(node.hit.object), node.direction, node.hit);
        let refraction = scattering
            .refraction
            .map(|(ray, t)| (Event::Refract, (ray, DVec3::splat(t))));
        let children = [Some((Event::Reflect, scattering.reflection)), refraction];
        for (event, (ray, coefficient)) in children.into_iter().flatten() {
            let mut weight = node.weight * coefficient;
            if weight.max_element() < limits.cutoff {
                continue;
            }
            let Some(events) = PathClass::then(node.events, event) else {
                continue;
            };
            counters.secondary_rays += 1;
            let Some(next) = lens.closest_hit(&ray, Some(node.hit.primitive), counters) else {
                leaf(events, weight);
                continue;
            };
            if events.events_len() >= limits.max_depth.clamp(1, MAX_EVENTS) {
                continue;
            }
            if !next.is_front_facing(ray.direction)
                && let Interface::Dielectric { absorption, .. } = lens.interface(next.object)
            {
                weight *= transmittance(absorption, next.distance);
            }
            let child = Node {
                direction: ray.direction,
                hit: &next,
                events: Some(events),
                weight,
            };
            branch(lens, child, limits, counters, leaf);
        }
    }
    let root = Node {
        direction: incoming.direction,
        hit: first_hit,
        events: None,
        weight: DVec3::ONE,
    };
    branch(lens, root, limits, counters, leaf);
}

/// The classes that carry light, ranked by their share of the summed throughput (`Σ F·G`, the
/// mean of the channels) over `rays`, each with that share (summed in a fixed order: the same
/// rays give the same bits): the data for choosing a class list for a lens object whose paths
/// are not the canonical order's (an open mesh lets `TRRR` out; a mirror's concavities keep
/// `RRR…`).
pub fn rank_classes<'a>(
    lens: &impl LensGeometry,
    rays: impl IntoIterator<Item = (&'a Ray, &'a SurfaceHit)>,
    limits: RayTreeOptions,
) -> Vec<(PathClass, f64)> {
    let mut shares: std::collections::BTreeMap<PathClass, f64> = Default::default();
    let mut counters = TraceCounters::default();
    for (ray, hit) in rays {
        local_tree(
            lens,
            ray,
            hit,
            limits,
            &mut counters,
            &mut |class, weight| {
                *shares.entry(class).or_default() += weight.element_sum() / 3.0;
            },
        );
    }
    let total: f64 = shares.values().sum();
    let mut ranked: Vec<(PathClass, f64)> = shares
        .into_iter()
        .map(|(class, share)| (class, if total > 0.0 { share / total } else { 0.0 }))
        .collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    ranked
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes_are_named_parsed_and_ordered_canonically() {
        let glass: Vec<String> = (0..5)
            .map(|i| PathClass::glass(i).unwrap().name())
            .collect();
        assert_eq!(glass, ["R", "TT", "TRT", "TRRT", "TRRRT"]);
        let mirror: Vec<String> = (0..3)
            .map(|i| PathClass::mirror(i).unwrap().name())
            .collect();
        assert_eq!(mirror, ["R", "RR", "RRR"]);
        assert_eq!(
            PathClass::parse("TRRT").unwrap(),
            PathClass::glass(3).unwrap()
        );
        assert!(PathClass::parse("").is_none() && PathClass::parse("TXT").is_none());
        assert!(PathClass::parse(&"R".repeat(33)).is_none());
        assert!(!PathClass::glass(3).unwrap().starts_reflected());
        let set = ClassSet::parse("R, TT,TRT").unwrap();
        assert_eq!(set.name(), "R,TT,TRT");
        assert_eq!(ClassSet::parse("4").unwrap(), ClassSet::First(4));
        assert!(ClassSet::parse("0").is_err() && ClassSet::parse("17").is_err());
        assert!(ClassSet::parse("R,R").unwrap_err().contains("twice"));
        assert!(ClassSet::parse("R,Q").unwrap_err().contains("'Q'"));
        let mirror = Interface::Mirror {
            reflectance: DVec3::ONE,
        };
        let names = |set: ClassSet, interface| -> Vec<String> {
            set.terms(interface)
                .iter()
                .map(|t| format!("{}{}", t.class.name(), if t.greedy_tail { "*" } else { "" }))
                .collect()
        };
        assert_eq!(names(ClassSet::First(2), mirror), ["R", "RR"]);
        let glass = Interface::Dielectric {
            ior: 1.5,
            absorption: DVec3::ONE,
        };
        assert_eq!(
            names(ClassSet::parse("greedy:1").unwrap(), glass),
            ["R*", "T*"]
        );
        assert_eq!(
            names(ClassSet::Expanded(2), glass),
            ["R", "T", "RR*", "RT*", "TR*", "TT*"]
        );
        assert_eq!(ClassSet::Expanded(3).terms(mirror).len(), 14);
        assert_eq!(ClassSet::Expanded(3).terms(glass).len(), 14);
        assert!(ClassSet::parse("greedy:4").is_err() && ClassSet::parse("greedy:0").is_err());
    }
}
