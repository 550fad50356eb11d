//! Direct images (hybrid-rendering paper §4.3, the alternative to inferring what no lens view
//! images): the environment seen directly from the lens object's centre, the EM origin, added
//! as extra equations on the texels the lens images leave unconstrained.
//!
//! For every level-0 texel of a layer, one ray leaves the EM origin through the texel centre and
//! finds the first surface in the layer's distance range (the rule projected EMs and the
//! targets split rays by, [`lensmap::layers::projected::layer_range`]); the direct value of the
//! texel is the projected EM's (the same rays, supersampled), premultiplied, α included.
//!
//! **Confidence.** A direct ray's hit is *near* the lens images when some intersection record
//! of the views lies within [`NEAR_TEXELS`] texels of it in direction (seen from the EM origin)
//! and within [`NEAR_DEPTH`] of its distance: there the lens images say what the texel must be
//! (through the frame's own interpolation, which the direct value knows nothing of), and the
//! direct equation gets confidence 0. Elsewhere it gets [`DIRECT_CONFIDENCE`]. A coarser texel
//! is far when all four of its children are, and its direct value is the projected EM's at that
//! level. Paper's variant for glass objects traces from the viewpoint with the lens object
//! removed; lensmap traces from the EM origin for both kinds, which sees the same surfaces
//! wherever the layer is far compared with the lens object's size.

use glam::DVec3;
use lensmap::{
    cubemap::{CubeFace, CubeMap, face::select_face},
    index::{LayerIndex, LensIndex},
    layers::{LayerShell, projected::layer_range},
    trace::{LensRecords, Ray, stats::TraceCounters, world::TraceScene},
};
use rayon::prelude::*;
use sprs::{CsMat, TriMat};

use crate::matrix::{Texel, TexelLayout};

/// Direction tolerance of "near", in level-0 texels.
pub const NEAR_TEXELS: i64 = 2;

/// Relative distance tolerance of "near".
pub const NEAR_DEPTH: f64 = 0.1;

/// Confidence of a direct equation far from the lens images (a lens pixel's is at most 1).
pub const DIRECT_CONFIDENCE: f64 = 0.5;

/// One layer's direct equations: a selection matrix (one row per far texel), the projected
/// values and the confidence, ready for [`crate::solve::Equations`].
pub struct DirectEquations {
    /// Rows × texel columns, one 1 per row.
    pub a: CsMat<f64>,
    /// Premultiplied RGBA per row.
    pub b: Vec<[f64; 4]>,
    /// Confidence per row.
    pub confidence: Vec<f64>,
}

/// Record hit distances from the EM origin, bucketed by the level-0 texel their direction falls
/// in: `buckets[face·size² + y·size + x]`.
fn record_buckets(origin: DVec3, size: u32, records: &[&LensRecords]) -> Vec<Vec<f64>> {
    let n = size as usize;
    let mut buckets = vec![Vec::new(); 6 * n * n];
    for set in records {
        for record in &set.records {
            let ray = record.outgoing_ray;
            for hit in set.hits_of(record) {
                let point = ray.origin + hit.distance * ray.direction;
                let offset = point - origin;
                let distance = offset.length();
                if distance > 0.0 && distance.is_finite() {
                    buckets[texel_of(offset, size)].push(distance);
                }
            }
        }
    }
    buckets
}

/// Index `face·size² + y·size + x` of the level-0 texel `direction` falls in.
fn texel_of(direction: DVec3, size: u32) -> usize {
    let c = select_face(direction);
    let clamp = |v: f64| ((v * size as f64).floor() as i64).clamp(0, size as i64 - 1) as usize;
    let n = size as usize;
    c.face.index() * n * n + clamp(c.t) * n + clamp(c.s)
}

/// One layer of one lens object, where its direct rays start and what splits them.
#[derive(Clone, Copy)]
pub struct DirectLayer<'a> {
    /// The scene's ray-tracing structures.
    pub trace: &'a TraceScene,
    /// The lens object (skipped by the direct rays).
    pub lens: LensIndex,
    /// Its EM origin.
    pub origin: DVec3,
    /// Its shells, nearest first.
    pub shells: &'a [LayerShell],
    /// The layer.
    pub layer: LayerIndex,
}

/// The direct equations of `at` for cube maps of `layout`, with direct values from `projected`
/// (that layer's projected EM at the layout's size), far from the hits of `records`.
pub fn direct_equations(
    at: &DirectLayer<'_>,
    layout: &TexelLayout,
    projected: &CubeMap,
    records: &[&LensRecords],
) -> DirectEquations {
    let DirectLayer {
        trace,
        lens,
        origin,
        shells,
        layer,
    } = *at;
    let (lens, layer) = (lens.index(), layer.index());
    let size = layout.size;
    let n = size as usize;
    let buckets = record_buckets(origin, size, records);
    // Level 0: is each texel's direct hit far from every record?
    let far0: Vec<bool> = (0..6 * n * n)
        .into_par_iter()
        .map(|index| {
            let face = CubeFace::ALL[index / (n * n)];
            let (x, y) = ((index % n) as i64, ((index / n) % n) as i64);
            let s = (x as f64 + 0.5) / n as f64;
            let t = (y as f64 + 0.5) / n as f64;
            let direction = face.direction(2.0 * s - 1.0, 2.0 * t - 1.0).normalize();
            let distances: Vec<f64> = shells
                .iter()
                .map(|shell| {
                    shell
                        .intersect(origin, direction)
                        .map_or(f64::INFINITY, |hit| hit.t)
                })
                .collect();
            let (start, end) = layer_range(&distances, layer);
            if start.partial_cmp(&end) != Some(std::cmp::Ordering::Less) {
                return false; // the layer holds nothing along this direction
            }
            let mut counters = TraceCounters::default();
            let ray = Ray::new(origin + start.min(1e12) * direction, direction);
            let depth = match trace.closest_hit(&ray, None, Some(lens), &mut counters) {
                Some(hit) if hit.hit.distance <= end - start => start + hit.hit.distance,
                // Nothing in range: the point where the layer's shell is, if finite.
                _ => distances[layer],
            };
            if !depth.is_finite() {
                return true; // at infinity: no record can be near
            }
            let (low, high) = (depth / (1.0 + NEAR_DEPTH), depth * (1.0 + NEAR_DEPTH));
            for dy in -NEAR_TEXELS..=NEAR_TEXELS {
                for dx in -NEAR_TEXELS..=NEAR_TEXELS {
                    let (bx, by) = (x + dx, y + dy);
                    if bx < 0 || by < 0 || bx >= n as i64 || by >= n as i64 {
                        continue;
                    }
                    let bucket = &buckets[face.index() * n * n + by as usize * n + bx as usize];
                    if bucket.iter().any(|d| (low..=high).contains(d)) {
                        return false;
                    }
                }
            }
            true
        })
        .collect();
    // Coarser levels: far when all four children are.
    let mut far: Vec<Vec<bool>> = vec![far0];
    for level in 1..layout.levels() {
        let (edge, child) = (layout.edge(level) as usize, layout.edge(level - 1) as usize);
        let previous = &far[level - 1];
        let next: Vec<bool> = (0..6 * edge * edge)
            .map(|index| {
                let face = index / (edge * edge);
                let (x, y) = (index % edge, (index / edge) % edge);
                let at = |cx: usize, cy: usize| {
                    previous[face * child * child + cy.min(child - 1) * child + cx.min(child - 1)]
                };
                at(2 * x, 2 * y)
                    && at(2 * x + 1, 2 * y)
                    && at(2 * x, 2 * y + 1)
                    && at(2 * x + 1, 2 * y + 1)
            })
            .collect();
        far.push(next);
    }
    let mut columns = Vec::new();
    let mut b = Vec::new();
    for (level, flags) in far.iter().enumerate() {
        let edge = layout.edge(level) as usize;
        for (index, _) in flags.iter().enumerate().filter(|(_, f)| **f) {
            let face = CubeFace::ALL[index / (edge * edge)];
            let (x, y) = ((index % edge) as u32, ((index / edge) % edge) as u32);
            columns.push(layout.column(Texel { level, face, x, y }));
            let texel = projected.levels[level][face.index()][index % (edge * edge)];
            b.push(texel.map(f64::from));
        }
    }
    let rows = columns.len();
    let mut matrix = TriMat::with_capacity((rows, layout.len()), rows);
    for (row, &column) in columns.iter().enumerate() {
        matrix.add_triplet(row, column, 1.0);
    }
    DirectEquations {
        a: matrix.to_csr(),
        confidence: vec![DIRECT_CONFIDENCE; rows],
        b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lensmap::{
        layers::{
            fixtures::BALL_BEFORE_PANEL,
            projected::{ProjectedOptions, em_origin, lens_shells, project_layers},
        },
        scene::Scene,
        trace::{EnvironmentHit, IntersectionRecord, Term},
    };

    #[test]
    fn texels_near_a_record_get_no_direct_equation_and_the_rest_the_projected_value() {
        let scene =
            Scene::from_toml_str(BALL_BEFORE_PANEL, std::path::Path::new("room.toml")).unwrap();
        let trace = TraceScene::new(&scene).unwrap();
        let origin = em_origin(&scene, 0);
        let shells = lens_shells(&trace, &scene, 0, origin);
        let size = 16;
        let (maps, _) = project_layers(
            &trace,
            0,
            origin,
            &shells,
            &ProjectedOptions {
                size,
                supersampling: 1,
            },
        );
        let layout = TexelLayout::new(size);
        // One record: a ray from the EM origin straight at the panel (−Z), hitting it at 2 m.
        let direction = DVec3::NEG_Z;
        let records = LensRecords {
            lens: 0,
            name: "ball".into(),
            records: vec![IntersectionRecord {
                image_position: glam::Vec2::ZERO,
                term: Term::Reflection,
                fresnel: DVec3::ONE,
                attenuation: DVec3::ONE,
                outgoing_ray: Ray::new(origin, direction),
                hits: 0..1,
                background: DVec3::ZERO,
                visible: true,
                truncated: false,
                local: None,
            }],
            hits: vec![EnvironmentHit {
                object: 1,
                lens: None,
                distance: 2.0 - origin.z.abs(),
                radiance: DVec3::ZERO,
            }],
        };
        let at = DirectLayer {
            trace: &trace,
            lens: LensIndex::new(0),
            origin,
            shells: &shells,
            layer: LayerIndex::new(0),
        };
        let none = direct_equations(&at, &layout, &maps[0], &[]);
        let some = direct_equations(&at, &layout, &maps[0], &[&records]);
        // Without records every texel of every level is far.
        assert_eq!(none.b.len(), layout.len());
        // With the record (its direction falls in texel (8, 8) of −Z), the (2·2 + 1)² level-0
        // texels within two of it lose their equations, and so do their ancestors.
        let level0 = 6 * 16 * 16;
        let kept_level0 = some
            .a
            .outer_iterator()
            .take_while(|row| row.indices()[0] < level0)
            .count();
        assert_eq!(kept_level0, level0 - 25, "{kept_level0}");
        let centre = layout.column(Texel {
            level: 0,
            face: CubeFace::NegativeZ,
            x: 8,
            y: 8,
        });
        assert!(
            some.a
                .outer_iterator()
                .all(|row| row.indices()[0] != centre)
        );
        // Every row selects one texel and asks for the projected value there.
        for (row, b) in some.a.outer_iterator().zip(&some.b) {
            assert_eq!(row.nnz(), 1);
            let texel = layout.texel(row.indices()[0]);
            let edge = layout.edge(texel.level) as usize;
            let want = maps[0].levels[texel.level][texel.face.index()]
                [texel.y as usize * edge + texel.x as usize];
            assert_eq!(*b, want.map(f64::from));
        }
        assert!(some.confidence.iter().all(|&c| c == DIRECT_CONFIDENCE));
    }
}
