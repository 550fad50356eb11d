//! Projected layered EMs: the classic, non-inferred kind. For each layer shell of a lens object,
//! rays are cast from the EM origin through every cube-map texel onto the environment, and what
//! they hit is stored, with α = coverage for the inner shells.
//!
//! A ray's distance range is split between the shells at the midpoints of the shells' own
//! distances along it: layer i holds the first surface at a distance in
//! `(½(tᵢ₋₁ + tᵢ), ½(tᵢ + tᵢ₊₁)]`, found by continuing the ray from the range's start (so an
//! inner layer's surface does not hide what an outer layer holds, as the paper's ray continuation
//! does for the baker). The outermost layer is opaque: it also holds the environment at infinity.
//! Each texel is supersampled k×k; premultiplied colour and coverage are averaged, and the mip
//! chain is box-filtered (exact for premultiplied values).

use glam::DVec3;
use rayon::prelude::*;

use super::LayerShell;
use crate::{
    cubemap::{CubeFace, CubeMap},
    scene::{LayerSpec, Scene},
    trace::{
        Ray, TraceOptions,
        stats::TraceCounters,
        world::{Part, TraceScene},
    },
};

/// Options of the projected builder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectedOptions {
    /// Cube-map face size in texels (a power of two).
    pub size: u32,
    /// k: k×k rays per texel.
    pub supersampling: u32,
}

/// The default cube-map face size of projected EMs, texels.
pub const DEFAULT_EM_SIZE: u32 = 128;

/// The largest cube-map face size of projected EMs, texels.
pub const MAX_EM_SIZE: u32 = 2048;

impl Default for ProjectedOptions {
    fn default() -> Self {
        ProjectedOptions {
            size: DEFAULT_EM_SIZE,
            supersampling: 2,
        }
    }
}

impl ProjectedOptions {
    /// The defaults with face size `size`.
    pub fn with_size(size: u32) -> ProjectedOptions {
        ProjectedOptions {
            size,
            ..ProjectedOptions::default()
        }
    }

    /// Checks the face size: a power of two in 1 ..= [`MAX_EM_SIZE`] texels (cube maps carry a
    /// full mip chain; a size that is not one is refused, never rounded silently); and the
    /// supersampling: 1 ..= 16 rays per texel side.
    pub fn validate(&self) -> Result<(), crate::options::OptionError> {
        crate::options::OptionError::require(
            (1..=MAX_EM_SIZE).contains(&self.size) && self.size.is_power_of_two(),
            crate::options::names::EM_SIZE,
            self.size,
            "give a power-of-two cube-map face size from 1 to 2048 texels, e.g. 128",
        )?;
        crate::options::OptionError::require(
            (1..=16).contains(&self.supersampling),
            crate::options::names::EM_SUPERSAMPLING,
            self.supersampling,
            "give 1 to 16 rays per texel side, e.g. 2",
        )
    }
}

/// The EM origin of lens object `lens`: its area-weighted centroid (paper §4.2).
pub fn em_origin(scene: &Scene, lens: usize) -> DVec3 {
    let mut weighted = DVec3::ZERO;
    let mut area = 0.0;
    for &object in scene.lenses.get(lens).map_or(&[][..], |l| &l.objects) {
        let mesh = &scene.objects[object].mesh;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize].as_dvec3());
            let triangle_area = 0.5 * (b - a).cross(c - a).length();
            weighted += triangle_area * (a + b + c) / 3.0;
            area += triangle_area;
        }
    }
    if area > 0.0 {
        weighted / area
    } else {
        DVec3::ZERO
    }
}

/// The shells of lens object `lens` from the scene's layer specs, centred on `origin`. With no
/// specs: one sphere at the mean distance from `origin` of the environment seen through `size`²
/// rays per face (LBG with one cluster), or 100 m when nothing is hit.
pub fn lens_shells(
    trace: &TraceScene,
    scene: &Scene,
    lens: usize,
    origin: DVec3,
) -> Vec<LayerShell> {
    let specs = scene.lenses.get(lens).map_or(&[][..], |l| &l.layers);
    if specs.is_empty() {
        let directions = texel_directions(16, 1);
        let distances: Vec<f64> = directions
            .par_iter()
            .filter_map(|d| {
                let mut counters = TraceCounters::default();
                trace
                    .closest_hit(&Ray::new(origin, *d), None, Some(lens), &mut counters)
                    .map(|h| h.hit.distance)
            })
            .collect();
        let radius = if distances.is_empty() {
            100.0
        } else {
            distances.iter().sum::<f64>() / distances.len() as f64
        };
        return vec![LayerShell::Sphere {
            centre: origin,
            radius,
        }];
    }
    specs
        .iter()
        .map(|spec| match *spec {
            LayerSpec::Sphere(radius) => LayerShell::Sphere {
                centre: origin,
                radius: f64::from(radius),
            },
            LayerSpec::Cylinder(radius) => LayerShell::Cylinder {
                centre: origin,
                axis: DVec3::Y,
                radius: f64::from(radius),
                half_height: None,
            },
            LayerSpec::Box(half) => LayerShell::Box {
                centre: origin,
                half_extents: half.as_dvec3(),
            },
            LayerSpec::Ellipsoid(radii) => LayerShell::Ellipsoid {
                centre: origin,
                radii: radii.as_dvec3(),
            },
        })
        .collect()
}

/// Unit directions of the k×k sub-samples of every level-0 texel, face by face, row by row.
fn texel_directions(size: u32, k: u32) -> Vec<DVec3> {
    let (size, k) = (size as usize, k.max(1) as usize);
    let mut directions = Vec::with_capacity(6 * size * size * k * k);
    for face in CubeFace::ALL {
        for texel in 0..size * size {
            let (x, y) = (texel % size, texel / size);
            for sub in 0..k * k {
                let s = (x as f64 + (sub % k) as f64 / k as f64 + 0.5 / k as f64) / size as f64;
                let t = (y as f64 + (sub / k) as f64 / k as f64 + 0.5 / k as f64) / size as f64;
                directions.push(face.direction(2.0 * s - 1.0, 2.0 * t - 1.0).normalize());
            }
        }
    }
    directions
}

/// The distance range along a ray that layer `layer` holds, given the distances `distances` along
/// that ray to every shell (nearest shell first, ∞ for a miss): from the midpoint with the previous
/// shell (0 for the first) to the midpoint with the next (∞ for the last). The one rule the
/// projected EMs and the baker's targets both split rays by.
pub fn layer_range(distances: &[f64], layer: usize) -> (f64, f64) {
    let start = if layer == 0 {
        0.0
    } else {
        0.5 * (distances[layer - 1] + distances[layer])
    };
    let end = if layer + 1 >= distances.len() {
        f64::INFINITY
    } else {
        0.5 * (distances[layer] + distances[layer + 1])
    };
    (start, end)
}

/// Distance along the unit ray from `origin` to `shell`, ∞ when it misses.
fn shell_distance(shell: &LayerShell, origin: DVec3, direction: DVec3) -> f64 {
    shell
        .intersect(origin, direction)
        .map_or(f64::INFINITY, |hit| hit.t)
}

/// Radiance leaving the first surface along `ray` (skipping lens object `lens`) if it lies within
/// `max_distance`, with its distance; `None` when the ray meets nothing that close.
fn first_surface(
    trace: &TraceScene,
    lens: usize,
    ray: &Ray,
    max_distance: f64,
    options: &TraceOptions,
    counters: &mut TraceCounters,
) -> Option<DVec3> {
    let hit = trace.closest_hit(ray, None, Some(lens), counters)?;
    if hit.hit.distance > max_distance {
        return None;
    }
    Some(match hit.part {
        Part::Environment => trace.shade_diffuse(ray, &hit.hit, counters),
        Part::Lens(other) => {
            let [t, r] = trace.greedy_terms(other, ray, &hit.hit, 2, options, counters);
            t + r
        }
    })
}

/// Builds the projected layered EM of lens object `lens`: one cube map per shell, nearest first.
/// Returns the maps and the rays cast.
pub fn project_layers(
    trace: &TraceScene,
    lens: usize,
    origin: DVec3,
    shells: &[LayerShell],
    options: &ProjectedOptions,
) -> (Vec<CubeMap>, u64) {
    let size = options.size.max(1).next_power_of_two();
    let k = options.supersampling.max(1);
    let per_texel = (k * k) as usize;
    let directions = texel_directions(size, k);
    let n = shells.len();
    let trace_options = TraceOptions::default();
    // texels[texel][layer] = premultiplied rgba, averaged over the texel's sub-samples.
    let (texels, rays): (Vec<Vec<[f32; 4]>>, Vec<u64>) = directions
        .par_chunks(per_texel)
        .map(|subsamples| {
            let mut counters = TraceCounters::default();
            let mut sums = vec![[0.0f64; 4]; n];
            for &d in subsamples {
                let distances: Vec<f64> = shells
                    .iter()
                    .map(|s| shell_distance(s, origin, d))
                    .collect();
                for (layer, sum) in sums.iter_mut().enumerate() {
                    let (start, end) = layer_range(&distances, layer);
                    if start.partial_cmp(&end) != Some(std::cmp::Ordering::Less) {
                        continue;
                    }
                    counters.secondary_rays += 1;
                    let ray = Ray::new(origin + start.min(1e12) * d, d);
                    let radiance = match first_surface(
                        trace,
                        lens,
                        &ray,
                        end - start,
                        &trace_options,
                        &mut counters,
                    ) {
                        Some(radiance) => Some(radiance),
                        None if layer + 1 == n => Some(trace.background_radiance(d)),
                        None => None,
                    };
                    if let Some(radiance) = radiance {
                        sum[0] += radiance.x;
                        sum[1] += radiance.y;
                        sum[2] += radiance.z;
                        sum[3] += 1.0;
                    }
                }
            }
            let texel = sums
                .iter()
                .map(|s| s.map(|v| (v / per_texel as f64) as f32))
                .collect();
            (texel, counters.all_rays())
        })
        .unzip();
    let texels_per_face = (size * size) as usize;
    let maps = (0..n)
        .map(|layer| {
            let faces = std::array::from_fn(|face| {
                (0..texels_per_face)
                    .map(|i| texels[face * texels_per_face + i][layer])
                    .collect()
            });
            CubeMap::from_level0(size, faces)
        })
        .collect();
    (maps, rays.iter().sum())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layers::fixtures::BALL_BEFORE_PANEL;

    fn scene(text: &str) -> (Scene, TraceScene) {
        let scene = Scene::from_toml_str(text, std::path::Path::new("test.toml")).unwrap();
        let trace = TraceScene::new(&scene).unwrap();
        (scene, trace)
    }

    #[test]
    fn inner_layer_holds_the_near_panel_and_the_outer_layer_the_sky() {
        let (scene, trace) = scene(BALL_BEFORE_PANEL);
        let origin = em_origin(&scene, 0);
        assert!(origin.length() < 1e-3, "{origin}");
        let shells = lens_shells(&trace, &scene, 0, origin);
        assert_eq!(shells.len(), 2);
        let (maps, rays) = project_layers(
            &trace,
            0,
            origin,
            &shells,
            &ProjectedOptions {
                size: 16,
                supersampling: 1,
            },
        );
        assert!(rays > 0);
        // −Z face centre: the panel (unlit, so black but opaque) in layer 0; +Z: nothing near.
        let centre = 8 * 16 + 8;
        let minus_z = &maps[0].levels[0][5][centre];
        assert_eq!(minus_z[3], 1.0, "panel covers the −Z face centre");
        let plus_z = &maps[0].levels[0][4][centre];
        assert_eq!(*plus_z, [0.0; 4], "nothing near along +Z");
        // The outer layer is opaque everywhere and shows the environment along +Z.
        assert!(maps[1].levels[0].iter().flatten().all(|t| t[3] == 1.0));
        let sky = maps[1].levels[0][4][centre];
        assert!(
            (sky[0] - 0.2).abs() < 1e-6 && (sky[2] - 0.6).abs() < 1e-6,
            "{sky:?}"
        );
        // Behind the panel (−Z) the outer layer still sees the sky: the ray continues.
        let behind = maps[1].levels[0][5][centre];
        assert!((behind[1] - 0.4).abs() < 1e-6, "{behind:?}");
    }

    #[test]
    fn panel_edge_texels_have_fractional_coverage() {
        let (scene, trace) = scene(BALL_BEFORE_PANEL);
        let origin = em_origin(&scene, 0);
        let shells = lens_shells(&trace, &scene, 0, origin);
        let (maps, _) = project_layers(
            &trace,
            0,
            origin,
            &shells,
            &ProjectedOptions {
                size: 32,
                supersampling: 4,
            },
        );
        let alphas: Vec<f32> = maps[0].levels[0][5].iter().map(|t| t[3]).collect();
        assert!(
            alphas.iter().any(|a| *a > 0.0 && *a < 1.0),
            "some texels straddle the panel's edge"
        );
        // Premultiplied: rgb ≤ α everywhere (white panel, no light: rgb = 0).
        assert!(
            maps[0]
                .levels
                .iter()
                .flatten()
                .flatten()
                .all(|t| t[0] <= t[3] + 1e-6)
        );
    }

    #[test]
    fn no_layer_specs_place_one_sphere_at_the_mean_distance() {
        let text = BALL_BEFORE_PANEL.replace("layers = [{ sphere = 2.0 }, { sphere = 50.0 }]", "");
        let (scene, trace) = scene(&text);
        let shells = lens_shells(&trace, &scene, 0, DVec3::ZERO);
        match shells.as_slice() {
            // Only the panel (2 m to 2.5 m away) is hit.
            [LayerShell::Sphere { radius, .. }] => {
                assert!(*radius > 2.0 && *radius < 2.5, "{radius}")
            }
            other => panic!("{other:?}"),
        }
    }
}
