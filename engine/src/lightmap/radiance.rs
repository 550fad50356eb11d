//! Filling one environment object's atlas with ray-traced radiance, once per scene.
//!
//! 1. **Coverage.** Every texel whose square overlaps a triangle of its chart (a conservative
//!    rasterization in atlas texels) is shaded; it belongs to the triangle that contains its
//!    centre most deeply, so texels along a chart's rim, half outside it, are shaded too.
//! 2. **Centre samples.** Each covered texel is shaded at its centre: the point is mapped back
//!    through the barycentrics of the nearest containing triangle of its neighbourhood (clamped
//!    onto that triangle when it lies outside every one, so a rim texel takes the value at the
//!    rim instead of a point off the surface), and [`TraceScene::shade_diffuse`] is asked for
//!    the radiance leaving the front face — normals, texture and shadow rays exactly as the
//!    reference tracer's camera rays get them ([`SourceTriangle::surface_at`]).
//! 3. **Adaptive supersampling.** A texel where the centre values bend (a second difference
//!    along a row or column of its chart: a shadow edge or a texture edge runs nearby) becomes the
//!    mean of k×k stratified sub-samples; smooth texels keep their centre sample, the exact mean
//!    of any linear change.
//! 4. **Gutter.** Texels of a chart's rectangle that no triangle covers are dilated, breadth
//!    first, from the mean of their already filled neighbours.
//!
//! Rows are shaded in parallel (rayon) and every value depends only on its texel, so the map is
//! the same whatever the thread count.

use std::time::Instant;

use glam::{DVec2, DVec3, Vec2, Vec3};
use half::f16;
use rayon::prelude::*;

use super::{Atlas, AtlasError, LightMap};
use crate::{
    scene::TriangleMesh,
    trace::{
        Ray,
        bvh::{SourceTriangle, SurfaceHit},
        stats::TraceCounters,
        world::{TraceScene, source_triangle},
    },
};

/// A second difference of centre values (along a row or a column) above this fraction of the
/// largest of the three (per colour channel, plus [`ABSOLUTE_THRESHOLD`]) marks a texel for
/// supersampling.
const RELATIVE_THRESHOLD: f32 = 0.02;

/// Absolute part of the supersampling test, in radiance units: below display precision.
const ABSOLUTE_THRESHOLD: f32 = 1e-4;

/// No triangle covers the texel.
const NONE: u32 = u32::MAX;

/// An environment object ready for the GPU: its triangles with per-vertex light-map texture
/// coordinates (vertices split where charts meet) and its light map.
#[derive(Clone, Debug, PartialEq)]
pub struct LightMappedMesh {
    /// World-space positions, metres.
    pub positions: Vec<Vec3>,
    /// Light-map texture coordinates per vertex, in [0, 1]².
    pub uvs: Vec<Vec2>,
    /// The object's triangles in their original order, indexing `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// The light map.
    pub map: LightMap,
}

/// What building light maps cost (one object, or summed over several).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LightMapStats {
    /// Objects mapped.
    pub objects: usize,
    /// Charts.
    pub charts: usize,
    /// Atlas texels (all of them, unused space included).
    pub texels: u64,
    /// Texels covered by a triangle and shaded.
    pub shaded_texels: u64,
    /// Of which supersampled.
    pub supersampled_texels: u64,
    /// Radiance samples (one per shaded texel, plus k² per supersampled one).
    pub samples: u64,
    /// Shadow rays cast.
    pub shadow_rays: u64,
    /// GPU memory of the maps (RGBA16F), bytes.
    pub gpu_bytes: u64,
    /// Wall time, ms.
    pub ms: f64,
    /// Lowest chart density, texels per metre (0 when no object was mapped).
    pub min_texels_per_metre: f64,
    /// Highest chart density, texels per metre (0 when no object was mapped).
    pub max_texels_per_metre: f64,
}

impl std::ops::AddAssign for LightMapStats {
    fn add_assign(&mut self, other: LightMapStats) {
        if other.objects > 0 {
            if self.objects == 0 {
                self.min_texels_per_metre = other.min_texels_per_metre;
                self.max_texels_per_metre = other.max_texels_per_metre;
            } else {
                self.min_texels_per_metre =
                    self.min_texels_per_metre.min(other.min_texels_per_metre);
                self.max_texels_per_metre =
                    self.max_texels_per_metre.max(other.max_texels_per_metre);
            }
        }
        self.objects += other.objects;
        self.charts += other.charts;
        self.texels += other.texels;
        self.shaded_texels += other.shaded_texels;
        self.supersampled_texels += other.supersampled_texels;
        self.samples += other.samples;
        self.shadow_rays += other.shadow_rays;
        self.gpu_bytes += other.gpu_bytes;
        self.ms += other.ms;
    }
}

/// Fills the light map of `mesh` (scene object `object` of `trace`) over `atlas`, made from
/// this mesh (see [`super::plan_atlases`]), with k = `supersampling`, and returns the mesh with
/// light-map texture coordinates.
pub fn build_light_mapped_mesh(
    trace: &TraceScene,
    mesh: &TriangleMesh,
    object: usize,
    atlas: &Atlas,
    supersampling: u32,
) -> Result<(LightMappedMesh, LightMapStats), AtlasError> {
    let start = Instant::now();
    if atlas.chart_of.len() != mesh.triangles.len() {
        return Err(AtlasError::OtherMesh {
            atlas_triangles: atlas.chart_of.len(),
            mesh_triangles: mesh.triangles.len(),
        });
    }
    let filler = Filler::new(trace, mesh, object, atlas);
    let (texels, mut stats) = filler.fill(supersampling.max(1));
    let map = LightMap {
        width: atlas.width,
        height: atlas.height,
        texels,
    };
    let mut vertex_of = std::collections::HashMap::new();
    let (mut positions, mut uvs) = (Vec::new(), Vec::new());
    let triangles = mesh
        .triangles
        .iter()
        .enumerate()
        .map(|(t, triangle)| {
            let chart = atlas.chart_of[t];
            triangle.map(|i| {
                *vertex_of.entry((chart, i)).or_insert_with(|| {
                    let p = mesh.positions[i as usize];
                    positions.push(p);
                    uvs.push(atlas.uv(&atlas.charts[chart], p.as_dvec3()).as_vec2());
                    (positions.len() - 1) as u32
                })
            })
        })
        .collect();
    stats.objects = 1;
    stats.charts = atlas.charts.len();
    let densities = atlas.charts.iter().map(|c| c.texels_per_metre);
    stats.min_texels_per_metre = densities.clone().fold(f64::INFINITY, f64::min);
    stats.max_texels_per_metre = densities.fold(0.0, f64::max);
    stats.texels = u64::from(atlas.width) * u64::from(atlas.height);
    stats.gpu_bytes = map.gpu_bytes();
    stats.ms = start.elapsed().as_secs_f64() * 1e3;
    Ok((
        LightMappedMesh {
            positions,
            uvs,
            triangles,
            map,
        },
        stats,
    ))
}

/// One object's atlas being filled.
struct Filler<'a> {
    trace: &'a TraceScene,
    atlas: &'a Atlas,
    /// The mesh's triangles as the tracer sees them (`None`: index out of range).
    sources: Vec<Option<SourceTriangle>>,
    /// Each triangle's corners in atlas texel coordinates.
    corners: Vec<[DVec2; 3]>,
    /// Per atlas texel, the triangle it belongs to, or [`NONE`].
    owner: Vec<u32>,
}

impl<'a> Filler<'a> {
    fn new(trace: &'a TraceScene, mesh: &TriangleMesh, object: usize, atlas: &'a Atlas) -> Self {
        let corners: Vec<[DVec2; 3]> = mesh
            .triangles
            .iter()
            .enumerate()
            .map(|(t, triangle)| {
                let chart = &atlas.charts[atlas.chart_of[t]];
                triangle.map(|i| {
                    let p = mesh.positions[i as usize].as_dvec3();
                    chart.texel_of_local(chart.local(p))
                })
            })
            .collect();
        let mut filler = Filler {
            trace,
            atlas,
            sources: mesh
                .triangles
                .iter()
                .map(|t| source_triangle(mesh, t, object))
                .collect(),
            corners,
            owner: vec![NONE; (atlas.width as usize) * (atlas.height as usize)],
        };
        filler.rasterize();
        filler
    }

    fn index(&self, x: u32, y: u32) -> usize {
        (y as usize) * (self.atlas.width as usize) + x as usize
    }

    /// Conservative coverage: each texel square that overlaps a triangle (separating axes: the
    /// square's two and the triangle's three edge normals) belongs to the overlapping triangle
    /// that contains the texel centre most deeply.
    fn rasterize(&mut self) {
        let mut depth = vec![f64::NEG_INFINITY; self.owner.len()];
        for (t, corners) in self.corners.iter().enumerate() {
            let rect = self.atlas.charts[self.atlas.chart_of[t]].rect;
            let Some(barycentric) = Barycentric::new(corners) else {
                continue;
            };
            let lo = corners[0].min(corners[1]).min(corners[2]);
            let hi = corners[0].max(corners[1]).max(corners[2]);
            let x0 = ((lo.x.ceil() - 1.0).max(f64::from(rect.x))) as u32;
            let y0 = ((lo.y.ceil() - 1.0).max(f64::from(rect.y))) as u32;
            let x1 = (hi.x.floor().min(f64::from(rect.x + rect.width - 1))) as u32;
            let y1 = (hi.y.floor().min(f64::from(rect.y + rect.height - 1))) as u32;
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let centre = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                    if !barycentric.overlaps_square(centre) {
                        continue;
                    }
                    let inside = barycentric.depth(centre);
                    let i = (y as usize) * (self.atlas.width as usize) + x as usize;
                    if inside > depth[i] {
                        depth[i] = inside;
                        self.owner[i] = t as u32;
                    }
                }
            }
        }
    }

    /// Radiance at atlas point `q` in texel `(x, y)`: through the triangle of the 3×3 texel
    /// neighbourhood that contains `q` most deeply, clamped onto it when none contains `q`.
    fn radiance(&self, q: DVec2, x: u32, y: u32, counters: &mut TraceCounters) -> DVec3 {
        let chart = self.atlas.chart_of[self.owner[self.index(x, y)] as usize];
        let rect = self.atlas.charts[chart].rect;
        let mut best: Option<(f64, usize, Barycentric)> = None;
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (nx, ny) = (i64::from(x) + dx, i64::from(y) + dy);
                if nx < 0 || ny < 0 || !rect.contains(nx as u32, ny as u32) {
                    continue;
                }
                let t = self.owner[self.index(nx as u32, ny as u32)];
                if t == NONE || best.as_ref().is_some_and(|b| b.1 == t as usize) {
                    continue;
                }
                let Some(b) = Barycentric::new(&self.corners[t as usize]) else {
                    continue;
                };
                let depth = b.depth(q);
                if best.as_ref().is_none_or(|(d, _, _)| depth > *d) {
                    best = Some((depth, t as usize, b));
                }
            }
        }
        let Some((_, t, b)) = best else {
            return DVec3::ZERO;
        };
        let [_, u, v] = b.clamped_weights(q);
        let Some(hit) = self.sources[t].and_then(|s| s.surface_at(u, v)) else {
            return DVec3::ZERO;
        };
        shade_front(self.trace, hit, counters)
    }

    /// Steps 2–4 of the module doc: the map's texels and the work done.
    fn fill(&self, k: u32) -> (Vec<[f16; 4]>, super::LightMapStats) {
        let (width, height) = (self.atlas.width as usize, self.atlas.height as usize);
        // Centre samples, rows in parallel.
        let rows: Vec<(Vec<Vec3>, TraceCounters)> = (0..height)
            .into_par_iter()
            .map(|y| {
                let mut counters = TraceCounters::default();
                let row = (0..width)
                    .map(|x| {
                        let (x, y) = (x as u32, y as u32);
                        if self.owner[self.index(x, y)] == NONE {
                            return Vec3::ZERO;
                        }
                        let centre = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                        self.radiance(centre, x, y, &mut counters).as_vec3()
                    })
                    .collect();
                (row, counters)
            })
            .collect();
        let mut counters = TraceCounters::default();
        let mut values: Vec<Vec3> = Vec::with_capacity(width * height);
        for (row, c) in rows {
            values.extend(row);
            counters += c;
        }
        let shaded = self.owner.iter().filter(|&&t| t != NONE).count() as u64;

        // Texels where the radiance bends: a second difference along a row or a column (within
        // the chart) above the threshold. A linear change has none, so smooth falloff is not
        // supersampled; a step between two texels marks both.
        let chart_at = |x: i64, y: i64| {
            if x < 0 || y < 0 || x >= width as i64 || y >= height as i64 {
                return None;
            }
            let t = self.owner[(y as usize) * width + x as usize];
            (t != NONE).then(|| self.atlas.chart_of[t as usize])
        };
        let edges: Vec<usize> = (0..width * height)
            .into_par_iter()
            .filter(|&i| {
                let (x, y) = ((i % width) as i64, (i / width) as i64);
                let Some(chart) = chart_at(x, y) else {
                    return false;
                };
                let value = |x: i64, y: i64| values[(y as usize) * width + x as usize];
                [(1i64, 0i64), (0, 1)].iter().any(|&(dx, dy)| {
                    if chart_at(x - dx, y - dy) != Some(chart)
                        || chart_at(x + dx, y + dy) != Some(chart)
                    {
                        return false;
                    }
                    let (a, b, c) = (value(x - dx, y - dy), value(x, y), value(x + dx, y + dy));
                    let limit =
                        a.max(b).max(c) * RELATIVE_THRESHOLD + Vec3::splat(ABSOLUTE_THRESHOLD);
                    (a + c - 2.0 * b).abs().cmpgt(limit).any()
                })
            })
            .collect();
        let supersampled: Vec<(Vec3, TraceCounters)> = edges
            .par_iter()
            .map(|&i| {
                let (x, y) = ((i % width) as u32, (i / width) as u32);
                let mut counters = TraceCounters::default();
                let mut sum = DVec3::ZERO;
                for j in 0..k {
                    for s in 0..k {
                        let q = DVec2::new(
                            f64::from(x) + (f64::from(s) + 0.5) / f64::from(k),
                            f64::from(y) + (f64::from(j) + 0.5) / f64::from(k),
                        );
                        sum += self.radiance(q, x, y, &mut counters);
                    }
                }
                ((sum / f64::from(k * k)).as_vec3(), counters)
            })
            .collect();
        for (&i, (value, c)) in edges.iter().zip(&supersampled) {
            values[i] = *value;
            counters += *c;
        }

        let filled = self.dilate(&mut values);
        let texels = values
            .iter()
            .zip(&filled)
            .map(|(v, &f)| [v.x, v.y, v.z, if f { 1.0 } else { 0.0 }].map(saturating_f16))
            .collect();
        let stats = super::LightMapStats {
            shaded_texels: shaded,
            supersampled_texels: edges.len() as u64,
            samples: shaded + edges.len() as u64 * u64::from(k * k),
            shadow_rays: counters.shadow_rays,
            ..Default::default()
        };
        (texels, stats)
    }

    /// Fills every uncovered texel of every chart's rectangle, breadth first from the covered
    /// ones: each ring takes the mean of its filled 8-neighbours. Returns which texels hold a
    /// value (every texel of every chart rectangle with any covered texel).
    fn dilate(&self, values: &mut [Vec3]) -> Vec<bool> {
        let width = self.atlas.width as usize;
        let mut filled: Vec<bool> = self.owner.iter().map(|&t| t != NONE).collect();
        for chart in &self.atlas.charts {
            let r = chart.rect;
            let neighbours = |x: u32, y: u32| {
                (-1i64..=1)
                    .flat_map(move |dy| (-1i64..=1).map(move |dx| (dx, dy)))
                    .filter_map(move |(dx, dy)| {
                        let (nx, ny) = (i64::from(x) + dx, i64::from(y) + dy);
                        (nx >= 0 && ny >= 0 && r.contains(nx as u32, ny as u32))
                            .then_some((nx as u32, ny as u32))
                    })
            };
            let index = |x: u32, y: u32| (y as usize) * width + x as usize;
            let mut ring: Vec<(u32, u32)> = (r.y..r.y + r.height)
                .flat_map(|y| (r.x..r.x + r.width).map(move |x| (x, y)))
                .filter(|&(x, y)| {
                    !filled[index(x, y)] && neighbours(x, y).any(|(nx, ny)| filled[index(nx, ny)])
                })
                .collect();
            while !ring.is_empty() {
                let means: Vec<Vec3> = ring
                    .iter()
                    .map(|&(x, y)| {
                        let (sum, count) = neighbours(x, y)
                            .filter(|&(nx, ny)| filled[index(nx, ny)])
                            .fold((Vec3::ZERO, 0.0), |(s, c), (nx, ny)| {
                                (s + values[index(nx, ny)], c + 1.0)
                            });
                        sum / count
                    })
                    .collect();
                for (&(x, y), mean) in ring.iter().zip(means) {
                    values[index(x, y)] = mean;
                    filled[index(x, y)] = true;
                }
                let mut next: Vec<(u32, u32)> = ring
                    .iter()
                    .flat_map(|&(x, y)| neighbours(x, y))
                    .filter(|&(x, y)| !filled[index(x, y)])
                    .collect();
                next.sort_unstable_by_key(|&(x, y)| (y, x));
                next.dedup();
                ring = next;
            }
        }
        filled
    }
}

/// The radiance leaving the front face (the side the normals point to) of `hit`: the two-sided
/// Lambert of the reference, seen from just off the surface.
fn shade_front(trace: &TraceScene, hit: SurfaceHit, counters: &mut TraceCounters) -> DVec3 {
    let normal = hit.geometric_normal;
    let ray = Ray::new(hit.position + normal, -normal);
    let hit = SurfaceHit {
        distance: 1.0,
        ..hit
    };
    trace.shade_diffuse(&ray, &hit, counters)
}

/// Barycentric coordinates over one 2D triangle.
#[derive(Clone, Copy, Debug)]
struct Barycentric {
    corners: [DVec2; 3],
    /// Twice the signed area.
    area: f64,
}

impl Barycentric {
    /// `None` for a triangle of (nearly) no area.
    fn new(corners: &[DVec2; 3]) -> Option<Barycentric> {
        let [a, b, c] = *corners;
        let area = (b - a).perp_dot(c - a);
        let scale = (b - a).length_squared().max((c - a).length_squared());
        (area.abs() > 1e-12 * scale && area.is_finite()).then_some(Barycentric {
            corners: *corners,
            area,
        })
    }

    /// Weights of the three corners at `q` (summing to 1; negative outside).
    fn weights(&self, q: DVec2) -> [f64; 3] {
        let [a, b, c] = self.corners;
        let u = (q - a).perp_dot(c - a) / self.area;
        let v = (b - a).perp_dot(q - a) / self.area;
        [1.0 - u - v, u, v]
    }

    /// How deep `q` lies inside: the smallest weight (negative outside).
    fn depth(&self, q: DVec2) -> f64 {
        let w = self.weights(q);
        w[0].min(w[1]).min(w[2])
    }

    /// The weights of the point of the triangle nearest to `q`.
    fn clamped_weights(&self, q: DVec2) -> [f64; 3] {
        let w = self.weights(q);
        if w.iter().all(|&x| x >= 0.0) {
            return w;
        }
        let [a, b, c] = self.corners;
        let nearest_on = |p: DVec2, s: DVec2| {
            let d = s - p;
            let t = ((q - p).dot(d) / d.length_squared().max(1e-300)).clamp(0.0, 1.0);
            p + d * t
        };
        let candidates = [nearest_on(a, b), nearest_on(b, c), nearest_on(c, a)];
        let nearest = candidates
            .into_iter()
            .min_by(|m, n| m.distance_squared(q).total_cmp(&n.distance_squared(q)))
            .unwrap_or(a);
        // A hair inside (towards the centroid), so that a texture edge lying exactly on the
        // triangle's edge (a checker square on a grid cell) reads this triangle's side.
        let inside = nearest + (a + b + c - 3.0 * nearest) * (1e-4 / 3.0);
        self.weights(inside).map(|x| x.clamp(0.0, 1.0))
    }

    /// Whether the unit texel square centred at `centre` overlaps the triangle (closed sets).
    fn overlaps_square(&self, centre: DVec2) -> bool {
        let [a, b, c] = self.corners;
        let lo = a.min(b).min(c);
        let hi = a.max(b).max(c);
        if centre.x + 0.5 < lo.x
            || centre.x - 0.5 > hi.x
            || centre.y + 0.5 < lo.y
            || centre.y - 0.5 > hi.y
        {
            return false;
        }
        // Each edge's outward half-plane must not contain the whole square.
        [(a, b, c), (b, c, a), (c, a, b)]
            .iter()
            .all(|&(p, s, opposite)| {
                let normal = (s - p).perp();
                let side = normal.dot(opposite - p).signum();
                side * normal.dot(centre - p) + 0.5 * (normal.x.abs() + normal.y.abs()) >= 0.0
            })
    }
}

/// `value` as RGBA16F, radiance past the format's largest finite value (65504) saturating to
/// it rather than becoming infinite: a bright light close to a wall is as white as the display
/// shows it (the RGBA16F framebuffer saturates the same way), not a light map that fails. A NaN
/// stays NaN, for [`super::LightMap::validate`] to refuse.
fn saturating_f16(value: f32) -> f16 {
    let max = f16::MAX.to_f32();
    f16::from_f32(if value > max { max } else { value })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{lightmap::LightMapOptions, scene::Scene};

    /// Every texel of every chart's rectangle is filled (α = 1: shaded or dilated), and the
    /// bilinear footprint of any point of any triangle lies in its own chart's rectangle.
    #[test]
    fn gutters_are_filled_and_footprints_stay_in_their_chart() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(0x6077e7);
        let scene = Scene::load_named("teapot-room").unwrap();
        let trace = TraceScene::new(&scene).unwrap();
        let options = LightMapOptions::uniform(6.0);
        for name in ["floor", "column-0", "wall-left"] {
            let object = scene.objects.iter().position(|o| o.name == name).unwrap();
            let mesh = &scene.objects[object].mesh;
            let atlas = Atlas::new(
                &mesh.positions,
                &mesh.triangles,
                options.min_texels_per_metre,
                options.max_atlas_size,
            )
            .unwrap();
            let (lit, stats) =
                build_light_mapped_mesh(&trace, mesh, object, &atlas, options.supersampling)
                    .unwrap();
            assert_eq!((lit.map.width, lit.map.height), (atlas.width, atlas.height));
            assert!(
                stats.shaded_texels > 0 && stats.shadow_rays > 0,
                "{stats:?}"
            );
            for chart in &atlas.charts {
                let r = chart.rect;
                for y in r.y..r.y + r.height {
                    for x in r.x..r.x + r.width {
                        assert_eq!(lit.map.texel(x, y)[3], 1.0, "{name}: texel ({x}, {y})");
                    }
                }
            }
            let (w, h) = (f64::from(lit.map.width), f64::from(lit.map.height));
            for (t, triangle) in lit.triangles.iter().enumerate() {
                let rect = atlas.charts[atlas.chart_of[t]].rect;
                for _ in 0..10 {
                    let (mut a, mut b) = (rng.r#gen::<f64>(), rng.r#gen::<f64>());
                    if a + b > 1.0 {
                        (a, b) = (1.0 - a, 1.0 - b);
                    }
                    let [u0, u1, u2] = triangle.map(|i| lit.uvs[i as usize].as_dvec2());
                    let uv = u0 + (u1 - u0) * a + (u2 - u0) * b;
                    let (fx, fy) = ((uv.x * w - 0.5).floor(), (uv.y * h - 0.5).floor());
                    for (x, y) in [
                        (fx, fy),
                        (fx + 1.0, fy),
                        (fx, fy + 1.0),
                        (fx + 1.0, fy + 1.0),
                    ] {
                        assert!(
                            x >= 0.0 && y >= 0.0 && rect.contains(x as u32, y as u32),
                            "{name}: triangle {t} reads texel ({x}, {y}) outside {rect:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn barycentric_weights_depth_and_clamping() {
        let b =
            Barycentric::new(&[DVec2::ZERO, DVec2::new(4.0, 0.0), DVec2::new(0.0, 4.0)]).unwrap();
        let w = b.weights(DVec2::new(1.0, 1.0));
        assert!((w[0] - 0.5).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12);
        assert!(b.depth(DVec2::new(-1.0, 1.0)) < 0.0);
        let c = b.clamped_weights(DVec2::new(-1.0, 1.0));
        assert!(
            (c[2] - 0.25).abs() < 1e-4 && c[1] > 0.0 && c[1] < 1e-4,
            "{c:?}"
        );
        assert!(b.overlaps_square(DVec2::new(-0.5, 1.0)));
        assert!(!b.overlaps_square(DVec2::new(-0.6, 1.0)));
        // Beyond the hypotenuse x + y = 4: the square at (2.4, 2.4) reaches down to x + y = 3.8,
        // the one at (2.6, 2.6) only to 4.2.
        assert!(b.overlaps_square(DVec2::new(2.4, 2.4)));
        assert!(!b.overlaps_square(DVec2::new(2.6, 2.6)));
    }
}
