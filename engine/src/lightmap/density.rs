//! View-dependent texel density: how fine each chart's texels are.
//!
//! A texel should be about as fine as the pixels that will show it. Seen from distance `d`, a
//! pixel of angular size `α` (the camera's vertical field of view over its height) covers
//! `d·α` metres of a surface facing the camera, so one texel per `P` pixels is
//! `1 / (P·d·α)` texels per metre. Each chart takes `d` as the distance from its nearest point
//! to the nearest place the scene is viewed from ([`Viewers`]: the view space's samples and the
//! camera), clamped to the options' `[min, max]`. Surfaces seen at a slant show more texels per
//! pixel along the slant, never fewer, so the nearest distance is the conservative choice.
//!
//! A budget over all of a scene's atlases ([`LightMapOptions::max_texels`]) then lowers every
//! density by one factor, as the per-atlas size cap does for one object's charts.

use glam::DVec3;

use super::{Atlas, AtlasError, LightMapOptions};
use crate::scene::{Scene, TriangleMesh};

/// Where a scene is viewed from, and how large its pixels are.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewers {
    /// Viewpoints, metres; at least one.
    pub positions: Vec<DVec3>,
    /// Angle one pixel spans, radians, > 0: the field of view over the image height.
    pub pixel_radians: f64,
}

impl Viewers {
    /// A scene's viewpoints: its view space's samples and its camera's position, with the
    /// camera's pixel size (vertical field of view over its height in pixels; supersampling
    /// does not count, since the image is shown at its resolution).
    pub fn of_scene(scene: &Scene) -> Viewers {
        let camera = &scene.camera;
        let mut positions: Vec<DVec3> = scene
            .view_space
            .samples()
            .iter()
            .map(|p| p.as_dvec3())
            .collect();
        positions.push(camera.position.as_dvec3());
        Viewers {
            positions,
            pixel_radians: f64::from(camera.vfov_radians) / f64::from(camera.height.max(1)),
        }
    }

    /// Distance from the nearest viewpoint to the nearest point of `triangles`, metres.
    pub fn distance(&self, triangles: &[[DVec3; 3]]) -> f64 {
        self.positions
            .iter()
            .flat_map(|&p| {
                triangles
                    .iter()
                    .map(move |t| p.distance(closest_point_on_triangle(p, t)))
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// The density, texels per metre, for a chart of `triangles`: one texel per
    /// `options.pixels_per_texel` pixels at its distance, within the options' bounds.
    pub fn texels_per_metre(&self, triangles: &[[DVec3; 3]], options: &LightMapOptions) -> f64 {
        let footprint = options.pixels_per_texel * self.pixel_radians * self.distance(triangles);
        let wanted = if footprint > 0.0 {
            1.0 / footprint
        } else {
            f64::INFINITY
        };
        wanted.clamp(options.min_texels_per_metre, options.max_texels_per_metre)
    }
}

/// Why a scene's atlases cannot be planned.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// One mesh's atlas cannot be made.
    #[error("mesh {mesh}: {error}")]
    Mesh {
        /// Index of the mesh in the list given.
        mesh: usize,
        /// Why.
        error: AtlasError,
    },
    /// Even at the lowest densities tried, the atlases together pass the texel budget.
    #[error(
        "the light maps need {texels} texels even at their lowest densities, over the budget of {max_texels}; raise the light-map texel budget"
    )]
    OverBudget {
        /// Texels of the smallest atlases made.
        texels: u64,
        /// The budget.
        max_texels: u64,
    },
}

/// The atlases of `meshes` (in order), each chart at the density [`Viewers::texels_per_metre`]
/// gives it, each atlas within `options.max_atlas_size`, and all of them together within
/// `options.max_texels` (every density lowered by one factor until they fit).
pub fn plan_atlases(
    meshes: &[&TriangleMesh],
    viewers: &Viewers,
    options: &LightMapOptions,
) -> Result<Vec<Atlas>, PlanError> {
    let density = |corners: &[[DVec3; 3]]| viewers.texels_per_metre(corners, options);
    let mut atlases = meshes
        .iter()
        .enumerate()
        .map(|(mesh, m)| {
            Atlas::with_densities(&m.positions, &m.triangles, density, options.max_atlas_size)
                .map_err(|error| PlanError::Mesh { mesh, error })
        })
        .collect::<Result<Vec<Atlas>, PlanError>>()?;
    let total = |atlases: &[Atlas]| atlases.iter().map(Atlas::texels).sum::<u64>();
    // Texels go with the square of the density; the margin covers rounding up to whole texels
    // and the gutters, which do not shrink.
    for _ in 0..24 {
        let texels = total(&atlases);
        if texels <= options.max_texels {
            return Ok(atlases);
        }
        let scale = 0.97 * (options.max_texels as f64 / texels as f64).sqrt();
        atlases = atlases
            .iter()
            .enumerate()
            .map(|(mesh, atlas)| {
                atlas
                    .rescaled(scale, options.max_atlas_size)
                    .map_err(|error| PlanError::Mesh { mesh, error })
            })
            .collect::<Result<Vec<Atlas>, PlanError>>()?;
    }
    Err(PlanError::OverBudget {
        texels: total(&atlases),
        max_texels: options.max_texels,
    })
}

/// The point of triangle `t` nearest to `p` (Ericson, *Real-Time Collision Detection*, 5.1.5:
/// the Voronoi region of `p` among the corners, edges and face).
fn closest_point_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denominator = va + vb + vc;
    if denominator.abs() < f64::MIN_POSITIVE {
        // A degenerate triangle: its nearest corner.
        return [a, b, c]
            .into_iter()
            .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
            .unwrap_or(a);
    }
    a + ab * (vb / denominator) + ac * (vc / denominator)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shapes;
    use glam::Vec3;
    use rand::{Rng, SeedableRng};

    fn options() -> LightMapOptions {
        LightMapOptions {
            min_texels_per_metre: 8.0,
            max_texels_per_metre: 256.0,
            pixels_per_texel: 2.0,
            ..LightMapOptions::default()
        }
    }

    /// The closest point against a brute-force search over a fine barycentric grid.
    #[test]
    fn closest_point_matches_a_dense_search() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(0xd15);
        let mut point = || {
            DVec3::new(
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
            )
        };
        for _ in 0..200 {
            let t = [point(), point(), point()];
            let p = point();
            let nearest = closest_point_on_triangle(p, &t);
            let n = 300;
            let mut best = f64::INFINITY;
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (f64::from(i) / f64::from(n), f64::from(j) / f64::from(n));
                    let q = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                    best = best.min(q.distance(p));
                }
            }
            let found = nearest.distance(p);
            assert!(found <= best + 1e-9, "{found} > {best}");
            assert!(found >= best - 0.02, "{found} far below the grid's {best}");
        }
    }

    /// On a 20 m floor seen from one point 2 m above one corner, the chart under the viewer is
    /// denser than one across the floor, both follow 1 / (P·d·α) within the bounds, and a
    /// budget lowers them all by one factor while keeping their order.
    #[test]
    fn nearer_charts_are_denser_and_the_budget_holds() {
        let mut floor = shapes::plane(glam::Vec2::new(20.0, 20.0), 10);
        for p in &mut floor.positions {
            *p += Vec3::new(10.0, 0.0, 10.0);
        }
        let viewers = Viewers {
            positions: vec![DVec3::new(1.0, 2.0, 1.0)],
            pixel_radians: 40f64.to_radians() / 480.0,
        };
        let options = options();
        let atlases = plan_atlases(&[&floor], &viewers, &options).unwrap();
        let atlas = &atlases[0];
        assert_eq!(atlas.density_scale, 1.0);
        let centre = |c: &super::super::Chart| {
            c.origin + (c.axes[0] * c.extent.x + c.axes[1] * c.extent.y) / 2.0
        };
        let near = atlas
            .charts
            .iter()
            .min_by(|a, b| {
                centre(a)
                    .x
                    .total_cmp(&centre(b).x)
                    .then(centre(a).z.total_cmp(&centre(b).z))
            })
            .unwrap();
        let far = atlas
            .charts
            .iter()
            .max_by(|a, b| {
                centre(a)
                    .x
                    .total_cmp(&centre(b).x)
                    .then(centre(a).z.total_cmp(&centre(b).z))
            })
            .unwrap();
        assert!(
            near.texels_per_metre > 2.0 * far.texels_per_metre,
            "{} {}",
            near.texels_per_metre,
            far.texels_per_metre
        );
        // Under the viewer: 2 m away; across the floor: 17√2 m horizontally, 2 m down.
        let expected = |d: f64| (1.0 / (2.0 * viewers.pixel_radians * d)).clamp(8.0, 256.0);
        assert!((near.texels_per_metre - expected(2.0)).abs() < 1e-9);
        let far_distance = (2.0 * 17f64.powi(2) + 4.0).sqrt();
        assert!((far.texels_per_metre - expected(far_distance)).abs() < 1e-9);

        let unbounded: u64 = atlases.iter().map(Atlas::texels).sum();
        let budget = LightMapOptions {
            max_texels: unbounded / 4,
            ..options
        };
        let lowered = plan_atlases(&[&floor], &viewers, &budget).unwrap();
        let texels: u64 = lowered.iter().map(Atlas::texels).sum();
        assert!(
            texels <= budget.max_texels,
            "{texels} > {}",
            budget.max_texels
        );
        let scale = lowered[0].density_scale;
        assert!(scale < 1.0 && scale > 0.3, "{scale}");
        for (before, after) in atlas.charts.iter().zip(&lowered[0].charts) {
            assert!((after.texels_per_metre - before.texels_per_metre * scale).abs() < 1e-9);
        }
        // The per-atlas size cap holds too.
        let capped = LightMapOptions {
            max_atlas_size: 512,
            ..options
        };
        let small = plan_atlases(&[&floor], &viewers, &capped).unwrap();
        assert!(small[0].width <= 512 && small[0].height <= 512);
        assert!(small[0].density_scale < 1.0);
    }

    /// The same inputs give the same atlases.
    #[test]
    fn plans_are_deterministic() {
        let meshes = [
            shapes::sphere(0.5, 24, 12),
            shapes::plane(glam::Vec2::new(3.0, 2.0), 5),
        ];
        let refs: Vec<&TriangleMesh> = meshes.iter().collect();
        let viewers = Viewers {
            positions: vec![DVec3::new(0.3, 1.0, 2.0), DVec3::new(-1.0, 0.5, 1.0)],
            pixel_radians: 1e-3,
        };
        let options = LightMapOptions {
            max_texels: 200_000,
            ..options()
        };
        let first = plan_atlases(&refs, &viewers, &options).unwrap();
        assert_eq!(first, plan_atlases(&refs, &viewers, &options).unwrap());
        assert!(first.iter().map(Atlas::texels).sum::<u64>() <= 200_000);
    }
}
