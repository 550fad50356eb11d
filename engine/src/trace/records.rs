//! Intersection records for the baker (paper §4.1, Figure 4).
//!
//! For every supersample of a viewpoint's image and every lens object the camera ray meets, the
//! greedy paths of both terms are traced to where they leave the lens object (under
//! [`PathModel::Classes`], one path per class term instead, each a record of its own term). A record keeps the
//! image position, the term, `F·G`, the outgoing ray and **every** front-facing hit of that ray on
//! the rest of the world, nearest first, not just the first (ray continuation, Figure 4c), each
//! with the radiance leaving that surface towards the lens.
//!
//! Incoming rays continue through whatever is in front (Figure 4b): each lens object is
//! intersected with the camera ray on its own, so a lens object occluded by another (or by
//! environment geometry) still gets records, marked `visible = false`.

use std::ops::Range;

use glam::{DVec3, Vec2};
use rayon::prelude::*;

use super::image::{camera_ray, subsample_position, validate_camera};
use super::path::GreedyOptions;
use super::path::{Bounces, GreedyRayPath, Term};
use super::shade::{PathModel, TraceOptions};
use super::stats::TraceCounters;
use super::world::{Part, SurfaceId, TraceScene};
use super::{Ray, TraceError};
use crate::scene::Camera;

/// One front-facing surface along an outgoing ray.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct EnvironmentHit {
    /// Scene object index of the surface.
    pub object: usize,
    /// Lens object index when the surface belongs to another lens object, `None` for the
    /// environment.
    pub lens: Option<usize>,
    /// Distance from the outgoing ray's origin in metres (> 0).
    pub distance: f64,
    /// Radiance leaving the surface back along the outgoing ray (its shading: diffuse, or a
    /// glossy surface's estimate; or the two-term value of the other lens object), linear, ≥ 0.
    pub radiance: DVec3,
}

/// One incoming supersample ray's term through one lens object.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct IntersectionRecord {
    /// Image position of the supersample in pixels ((0, 0) the top-left corner of the image).
    pub image_position: Vec2,
    /// The term the path belongs to.
    pub term: Term,
    /// `F` along the path, per channel.
    pub fresnel: DVec3,
    /// `G` along the path, per channel.
    pub attenuation: DVec3,
    /// The ray where the path leaves the lens object.
    pub outgoing_ray: Ray,
    /// Range of this record's hits in [`LensRecords::hits`], nearest first.
    pub hits: Range<usize>,
    /// Radiance of the environment at infinity along the outgoing ray (what it sees past every
    /// hit).
    pub background: DVec3,
    /// True when this lens object is the first thing the camera ray hits.
    pub visible: bool,
    /// True when the path hit the interface cap (its `F·G` counts as 0).
    pub truncated: bool,
    /// Records of first-bounce paths ([`Bounces::First`]) only: the lens object (this one or
    /// another) when one is the nearest thing along the outgoing ray, with the radiance it sends
    /// back along it (its greedy two-term value): the PEM paper's local layer. The ray's `hits`
    /// then hold the environment alone, seen through every lens object (its distant layer).
    pub local: Option<LocalHit>,
}

/// A lens object seen along a first-bounce ray (see [`IntersectionRecord::local`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct LocalHit {
    /// Lens object index in [`TraceScene::lenses`].
    pub lens: usize,
    /// Distance from the outgoing ray's origin, metres (> 0).
    pub distance: f64,
    /// Radiance leaving it back along the ray, linear, ≥ 0.
    pub radiance: DVec3,
}

impl IntersectionRecord {
    /// `F·G` per channel (0 for a truncated path).
    pub fn weight(&self) -> DVec3 {
        if self.truncated {
            DVec3::ZERO
        } else {
            self.fresnel * self.attenuation
        }
    }
}

/// All records of one lens object, in image order (rows, then pixels, then supersamples, then
/// refraction before reflection).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct LensRecords {
    /// Lens object index in [`TraceScene::lenses`].
    pub lens: usize,
    /// Lens object name.
    pub name: String,
    /// The records.
    pub records: Vec<IntersectionRecord>,
    /// Hits of all records, referenced by [`IntersectionRecord::hits`].
    pub hits: Vec<EnvironmentHit>,
}

impl LensRecords {
    /// The hits of `record` (a record of this set), nearest first.
    pub fn hits_of(&self, record: &IntersectionRecord) -> &[EnvironmentHit] {
        self.hits.get(record.hits.clone()).unwrap_or(&[])
    }
}

/// Records of one viewpoint: one set per lens object, and the work done.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RecordSet {
    /// One entry per lens object of the scene, in [`TraceScene::lenses`] order.
    pub lenses: Vec<LensRecords>,
    /// Work counters.
    pub counters: TraceCounters,
}

/// What [`compile_records`] mixes into [`TraceOptions::glossy_seed`].
const RECORDS_GLOSSY_SEED: u64 = 0x7265_636f_7264_7321;

/// Compiles the intersection records of `scene` seen by `camera` (its size and k×k
/// supersampling), with the greedy path limits of `options`, on the current rayon pool.
/// Deterministic whatever the thread count.
pub fn compile_records(
    scene: &TraceScene,
    camera: &Camera,
    options: &TraceOptions,
) -> Result<RecordSet, TraceError> {
    validate_camera(camera)?;
    // Glossy surfaces along the outgoing rays are estimated with another seed than a reference
    // render's: the same rays would otherwise carry the same Monte Carlo noise as the reference
    // the records are judged against, and flatter it.
    let options = &TraceOptions {
        glossy_seed: options.glossy_seed ^ RECORDS_GLOSSY_SEED,
        ..*options
    };
    let rows: Vec<(Vec<LensRecords>, TraceCounters)> = (0..camera.height)
        .into_par_iter()
        .map(|y| record_row(scene, camera, options, y))
        .collect();
    let mut set = RecordSet {
        lenses: scene
            .lenses
            .iter()
            .enumerate()
            .map(|(lens, l)| LensRecords {
                lens,
                name: l.name.clone(),
                ..LensRecords::default()
            })
            .collect(),
        counters: TraceCounters::default(),
    };
    for (row, counters) in rows {
        set.counters += counters;
        for (target, part) in set.lenses.iter_mut().zip(row) {
            let offset = target.hits.len();
            target.hits.extend(part.hits);
            target
                .records
                .extend(part.records.into_iter().map(|mut record| {
                    record.hits = record.hits.start + offset..record.hits.end + offset;
                    record
                }));
        }
    }
    Ok(set)
}

fn record_row(
    scene: &TraceScene,
    camera: &Camera,
    options: &TraceOptions,
    y: u32,
) -> (Vec<LensRecords>, TraceCounters) {
    let mut counters = TraceCounters::default();
    let mut lenses: Vec<LensRecords> = (0..scene.lenses.len())
        .map(|lens| LensRecords {
            lens,
            ..LensRecords::default()
        })
        .collect();
    let k = camera.supersampling.max(1);
    for x in 0..camera.width {
        for j in 0..k {
            for i in 0..k {
                let (sx, sy) = subsample_position(x, y, i, j, k);
                let ray = camera_ray(camera, sx, sy);
                counters.primary_rays += 1;
                let first = scene.closest_hit(&ray, None, None, &mut counters);
                for (lens, out) in lenses.iter_mut().enumerate() {
                    // Continuation: the camera ray against this lens object alone.
                    let hit = if let Some(first) = first.filter(|f| f.part == Part::Lens(lens)) {
                        Some(first.hit)
                    } else {
                        counters.secondary_rays += 1;
                        scene.lenses[lens].bvh.closest_hit(
                            &ray,
                            0.0,
                            f64::INFINITY,
                            None,
                            &mut counters.triangle_tests,
                        )
                    };
                    let Some(hit) = hit else {
                        continue;
                    };
                    let start = RecordStart {
                        lens,
                        primitive: hit.primitive,
                        image_position: Vec2::new(sx as f32, sy as f32),
                        visible: first.is_some_and(|f| f.part == Part::Lens(lens)),
                    };
                    for path in record_paths(scene, options, lens, &ray, &hit, &mut counters) {
                        push_record(scene, options, &start, &path, out, &mut counters);
                    }
                }
            }
        }
    }
    (lenses, counters)
}

/// What a record keeps of a path through a lens object: its term, `F`, `G`, the ray leaving and
/// whether it stopped at the interface cap (its weight then 0).
struct RecordPath {
    term: Term,
    fresnel: DVec3,
    attenuation: DVec3,
    outgoing_ray: Ray,
    truncated: bool,
}

/// The paths lens object `lens` hit by `ray` at `hit` records under `options.model`: its two
/// greedy paths, or under path classes one path per class term of its interface that has its
/// sequence there (a first-bounce record set is the greedy paths' whatever the model says).
fn record_paths(
    scene: &TraceScene,
    options: &TraceOptions,
    lens: usize,
    ray: &Ray,
    hit: &super::bvh::SurfaceHit,
    counters: &mut TraceCounters,
) -> Vec<RecordPath> {
    if let (PathModel::Classes(set), Bounces::UntilLeaving, Some(interface)) = (
        options.model,
        options.greedy.bounces,
        scene.interface(hit.object),
    ) {
        let geometry = scene.lens(lens);
        return set
            .terms(interface)
            .into_iter()
            .filter_map(|term| {
                super::classes::trace_term(&geometry, ray, hit, term, counters).map(|path| {
                    RecordPath {
                        term: Term::Class(term),
                        fresnel: path.fresnel,
                        attenuation: path.attenuation,
                        outgoing_ray: path.outgoing_ray,
                        truncated: false,
                    }
                })
            })
            .collect();
    }
    let paths = scene.greedy_paths(lens, ray, hit, options.greedy, counters);
    [Term::Refraction, Term::Reflection]
        .into_iter()
        .filter_map(|term| paths.get(term))
        .map(|path: &GreedyRayPath| RecordPath {
            term: path.term,
            fresnel: path.fresnel,
            attenuation: path.attenuation,
            outgoing_ray: path.outgoing_ray,
            truncated: path.truncated,
        })
        .collect()
}

/// Where a record's path starts: its lens object, the triangle the camera ray hit, the
/// supersample's image position and whether the lens object is what the camera sees there.
struct RecordStart {
    lens: usize,
    primitive: u32,
    image_position: Vec2,
    visible: bool,
}

fn push_record(
    scene: &TraceScene,
    options: &TraceOptions,
    start: &RecordStart,
    path: &RecordPath,
    out: &mut LensRecords,
    counters: &mut TraceCounters,
) {
    let first = out.hits.len();
    let ray = path.outgoing_ray;
    let (local, seen_lenses): (_, Vec<usize>) = match options.greedy.bounces {
        Bounces::UntilLeaving => (
            None,
            (0..scene.lenses.len())
                .filter(|&i| i != start.lens)
                .collect(),
        ),
        Bounces::First => (local_hit(scene, options, start, &ray, counters), Vec::new()),
    };
    for hit in outgoing_hits(scene, &ray, &seen_lenses, counters) {
        let radiance = match hit.1 {
            Part::Environment => scene.shade_surface(&ray, &hit.0, options, counters),
            // As the reference under the same model shades it: the greedy terms, or the classes.
            Part::Lens(other) => {
                let [t, r] = scene.lens_terms(other, &ray, &hit.0, 2, options, counters);
                t + r
            }
        };
        out.hits.push(EnvironmentHit {
            object: hit.0.object,
            lens: match hit.1 {
                Part::Lens(other) => Some(other),
                Part::Environment => None,
            },
            distance: hit.0.distance,
            radiance,
        });
    }
    out.records.push(IntersectionRecord {
        image_position: start.image_position,
        term: path.term,
        fresnel: path.fresnel,
        attenuation: path.attenuation,
        outgoing_ray: ray,
        hits: first..out.hits.len(),
        background: scene.background_radiance(ray.direction),
        visible: start.visible,
        truncated: path.truncated,
        local,
    });
}

/// The lens object a first-bounce ray `ray` (leaving `start`'s triangle) meets before any
/// environment surface, with the radiance it sends back: its greedy two-term value, traced
/// until the paths leave it.
fn local_hit(
    scene: &TraceScene,
    options: &TraceOptions,
    start: &RecordStart,
    ray: &Ray,
    counters: &mut TraceCounters,
) -> Option<LocalHit> {
    counters.secondary_rays += 1;
    let exclude = SurfaceId {
        part: Part::Lens(start.lens),
        primitive: start.primitive,
    };
    let hit = scene.closest_hit(ray, Some(exclude), None, counters)?;
    let Part::Lens(lens) = hit.part else {
        return None;
    };
    let continued = TraceOptions {
        greedy: GreedyOptions {
            bounces: Bounces::UntilLeaving,
            ..options.greedy
        },
        ..*options
    };
    let [t, r] = scene.greedy_terms(lens, ray, &hit.hit, 2, &continued, counters);
    Some(LocalHit {
        lens,
        distance: hit.hit.distance,
        radiance: t + r,
    })
}

/// Every front-facing hit of `ray` on the environment and on the lens objects `lenses`,
/// nearest first; coincident hits on one object (a shared edge) are kept once.
fn outgoing_hits(
    scene: &TraceScene,
    ray: &Ray,
    lenses: &[usize],
    counters: &mut TraceCounters,
) -> Vec<(super::bvh::SurfaceHit, Part)> {
    counters.secondary_rays += 1;
    let parts = std::iter::once(Part::Environment).chain(lenses.iter().map(|&i| Part::Lens(i)));
    let mut hits = Vec::new();
    for part in parts {
        for hit in
            scene
                .bvh(part)
                .all_hits(ray, 0.0, f64::INFINITY, None, &mut counters.triangle_tests)
        {
            if hit.is_front_facing(ray.direction) {
                hits.push((hit, part));
            }
        }
    }
    hits.sort_by(|a, b| {
        a.0.distance
            .total_cmp(&b.0.distance)
            .then(a.0.object.cmp(&b.0.object))
            .then(a.0.primitive.cmp(&b.0.primitive))
    });
    let tolerance = |d: f64| 1e-9 * d.abs().max(1.0);
    hits.dedup_by(|later, earlier| {
        later.0.object == earlier.0.object
            && (later.0.distance - earlier.0.distance).abs() <= tolerance(earlier.0.distance)
    });
    hits
}
