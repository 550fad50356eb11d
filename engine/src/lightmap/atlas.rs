//! The light-map parameterization of one mesh: planar charts packed into an atlas.
//!
//! A **chart** is one triangle, or two that form a quad: a triangle and the neighbour across its
//! longest edge when their face normals agree within [`COPLANAR_COSINE`] (a grid cell of a
//! plane, one quad of a cylinder's side or of a box face). Charts end at mesh edges, so a texture
//! or shading discontinuity along a mesh edge (a checker square aligned with the plane's grid)
//! stays sharp: bilinear filtering never mixes the two sides. Its texture coordinates are the orthogonal projection onto its plane along
//! two axes chosen to make its bounding rectangle smallest (one of its edges' directions), scaled
//! by the chart's own texel density (chosen per chart by the caller, see [`super::density`]):
//! distances on the surface keep their length, so a texel covers the same area everywhere in a
//! chart. Each chart gets its own rectangle of the atlas, its bounding rectangle in
//! texels plus a [`GUTTER_TEXELS`] border, which the radiance pass fills (conservatively
//! covered texels are shaded, the rest dilated), so bilinear filtering anywhere inside a
//! triangle reads only texels of its own chart.
//!
//! Packing is a shelf packer over charts sorted by height. Crates exist for rectangle packing
//! (etagere, guillotiere: dynamic allocators into an atlas of fixed size; rectangle-pack: bins of
//! fixed size), but each would still need the outer search for the atlas size and the density
//! cap, and this static case — every rectangle known up front, sorted once — is a few lines
//! that stay deterministic and dependency-free.

use glam::{DVec2, DVec3, Vec3};

/// Texels of border around every chart's rectangle. One ring is needed for bilinear filtering
/// at a chart's edge (the texel half a texel outside it); the second keeps a margin for
/// hardware that quantizes texture coordinates to sub-texel precision.
pub const GUTTER_TEXELS: u32 = 2;

/// Smallest cosine between a triangle's face normal and its chart's: 0.26°. Flat surfaces'
/// triangles agree to float rounding; a tessellated curve's neighbours differ by degrees.
pub const COPLANAR_COSINE: f64 = 1.0 - 1e-5;

/// A rectangle of atlas texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TexelRect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Columns, ≥ 1.
    pub width: u32,
    /// Rows, ≥ 1.
    pub height: u32,
}

impl TexelRect {
    /// Whether texel `(x, y)` lies in the rectangle.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x && y >= self.y && x - self.x < self.width && y - self.y < self.height
    }

    /// Whether the two rectangles share a texel.
    pub fn overlaps(&self, other: &TexelRect) -> bool {
        self.x < other.x + other.width
            && other.x < self.x + self.width
            && self.y < other.y + other.height
            && other.y < self.y + self.height
    }
}

/// One chart: coplanar, edge-connected triangles and where they lie in the atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct Chart {
    /// Indices of the mesh's triangles in this chart, ascending.
    pub triangles: Vec<usize>,
    /// The world point at chart coordinates (0, 0): the corner of the charted area, metres.
    pub origin: DVec3,
    /// Unit axes of the chart plane (chart coordinates are distances along them), orthogonal.
    pub axes: [DVec3; 2],
    /// Size of the charted area along the axes, metres.
    pub extent: DVec2,
    /// This chart's texel density, texels per metre along both axes: the one asked for, times
    /// the atlas's [`Atlas::density_scale`].
    pub texels_per_metre: f64,
    /// The chart's rectangle in the atlas, gutter included.
    pub rect: TexelRect,
}

impl Chart {
    /// Chart coordinates (metres along the axes from the origin) of world point `p`, projected
    /// onto the chart plane.
    pub fn local(&self, p: DVec3) -> DVec2 {
        let d = p - self.origin;
        DVec2::new(d.dot(self.axes[0]), d.dot(self.axes[1]))
    }

    /// Continuous atlas texel coordinates of chart coordinates `local` (texel `(x, y)` spans
    /// `[x, x+1] × [y, y+1]`) at the chart's density.
    pub fn texel_of_local(&self, local: DVec2) -> DVec2 {
        let corner = f64::from(GUTTER_TEXELS);
        DVec2::new(
            f64::from(self.rect.x) + corner + local.x * self.texels_per_metre,
            f64::from(self.rect.y) + corner + local.y * self.texels_per_metre,
        )
    }

    /// Chart coordinates of continuous atlas texel coordinates `texel` (the inverse of
    /// [`Chart::texel_of_local`]).
    pub fn local_of_texel(&self, texel: DVec2) -> DVec2 {
        let corner = f64::from(GUTTER_TEXELS);
        DVec2::new(
            (texel.x - f64::from(self.rect.x) - corner) / self.texels_per_metre,
            (texel.y - f64::from(self.rect.y) - corner) / self.texels_per_metre,
        )
    }

    /// Texels of the chart's rectangle, gutter included.
    fn size_at(&self, texels_per_metre: f64) -> (u32, u32) {
        let side =
            |metres: f64| ((metres * texels_per_metre).ceil() as u32).max(1) + 2 * GUTTER_TEXELS;
        (side(self.extent.x), side(self.extent.y))
    }
}

/// Why a mesh has no atlas.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AtlasError {
    /// Even at the lowest density tried, the charts do not fit the size cap.
    #[error(
        "{charts} light-map charts do not fit a {max_size}² atlas even at {scale:.3e} × their densities; raise the atlas size cap"
    )]
    DoesNotFit {
        /// Charts of the mesh.
        charts: usize,
        /// The cap, texels.
        max_size: u32,
        /// The last factor tried on the charts' densities.
        scale: f64,
    },
    /// The atlas was made from a mesh with another number of triangles.
    #[error(
        "the atlas charts {atlas_triangles} triangles but the mesh has {mesh_triangles}; make the atlas from this mesh"
    )]
    OtherMesh {
        /// Triangles the atlas charts.
        atlas_triangles: usize,
        /// Triangles of the mesh.
        mesh_triangles: usize,
    },
    /// A vertex index points past the positions.
    #[error("triangle {triangle} indexes past the {positions} positions")]
    BadIndex {
        /// The triangle.
        triangle: usize,
        /// Positions of the mesh.
        positions: usize,
    },
}

/// A mesh's charts packed into one atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct Atlas {
    /// Atlas width, texels.
    pub width: u32,
    /// Atlas height, texels.
    pub height: u32,
    /// The factor, in (0, 1], by which the size cap lowered every chart's requested density
    /// (1 where the atlas fitted as asked).
    pub density_scale: f64,
    /// The charts, in order of their first triangle.
    pub charts: Vec<Chart>,
    /// `chart_of[triangle]`: the chart holding each triangle of the mesh.
    pub chart_of: Vec<usize>,
}

impl Atlas {
    /// Charts `triangles` over `positions` and packs them at one density, `texels_per_metre`,
    /// lowered for this mesh until the atlas fits `max_size` on both sides.
    pub fn new(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        texels_per_metre: f64,
        max_size: u32,
    ) -> Result<Atlas, AtlasError> {
        Self::with_densities(positions, triangles, |_| texels_per_metre, max_size)
    }

    /// Charts `triangles` over `positions` and packs them, each chart at the density
    /// `density(corners)` gives for the world corners of its triangles (texels per metre, > 0),
    /// all lowered by one factor until the atlas fits `max_size` on both sides.
    pub fn with_densities(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        density: impl Fn(&[[DVec3; 3]]) -> f64,
        max_size: u32,
    ) -> Result<Atlas, AtlasError> {
        if let Some(triangle) = triangles
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= positions.len()))
        {
            return Err(AtlasError::BadIndex {
                triangle,
                positions: positions.len(),
            });
        }
        let mut charts = planar_charts(positions, triangles);
        let mut chart_of = vec![0; triangles.len()];
        for (c, chart) in charts.iter_mut().enumerate() {
            for &t in &chart.triangles {
                chart_of[t] = c;
            }
            let corners: Vec<[DVec3; 3]> = chart
                .triangles
                .iter()
                .map(|&t| triangles[t].map(|i| positions[i as usize].as_dvec3()))
                .collect();
            chart.texels_per_metre = density(&corners);
        }
        pack(charts, chart_of, 1.0, max_size)
    }

    /// The same charts with every density times `scale` (in (0, 1]), packed again under
    /// `max_size`: how a budget over several atlases lowers them all alike.
    pub fn rescaled(&self, scale: f64, max_size: u32) -> Result<Atlas, AtlasError> {
        let mut charts = self.charts.clone();
        for chart in &mut charts {
            chart.texels_per_metre *= scale;
        }
        pack(
            charts,
            self.chart_of.clone(),
            self.density_scale * scale,
            max_size,
        )
    }

    /// Texels of the atlas, unused space included.
    pub fn texels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Light-map texture coordinates ([0, 1]²) of world point `p` in `chart`.
    pub fn uv(&self, chart: &Chart, p: DVec3) -> DVec2 {
        let texel = chart.texel_of_local(chart.local(p));
        DVec2::new(
            texel.x / f64::from(self.width),
            texel.y / f64::from(self.height),
        )
    }
}

/// Packs `charts` at their densities, all lowered by one factor until the atlas fits
/// `max_size`; `density_scale` is the factor already applied to them.
fn pack(
    mut charts: Vec<Chart>,
    chart_of: Vec<usize>,
    density_scale: f64,
    max_size: u32,
) -> Result<Atlas, AtlasError> {
    let mut scale = 1.0;
    // Each retry shrinks every chart by the atlas's excess; a few suffice (charts have a
    // minimum size of one texel plus the gutter, so a hopeless mesh stops at the limit).
    for _ in 0..24 {
        let sizes: Vec<(u32, u32)> = charts
            .iter()
            .map(|c| c.size_at(c.texels_per_metre * scale))
            .collect();
        let (width, height, places) = shelf_pack(&sizes);
        if width <= max_size && height <= max_size {
            for (chart, (&(w, h), (x, y))) in charts.iter_mut().zip(sizes.iter().zip(places)) {
                chart.texels_per_metre *= scale;
                chart.rect = TexelRect {
                    x,
                    y,
                    width: w,
                    height: h,
                };
            }
            return Ok(Atlas {
                width,
                height,
                density_scale: density_scale * scale,
                charts,
                chart_of,
            });
        }
        scale *= 0.97 * f64::from(max_size) / f64::from(width.max(height));
    }
    Err(AtlasError::DoesNotFit {
        charts: charts.len(),
        max_size,
        scale: density_scale * scale,
    })
}

/// Triangles paired into quads across their longest edges (in index order, so the result
/// depends only on the mesh), or alone.
/// Each chart comes without a density or a place in the atlas yet.
fn planar_charts(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Chart> {
    let p = |i: u32| positions[i as usize].as_dvec3();
    let normal = |t: &[u32; 3]| {
        (p(t[1]) - p(t[0]))
            .cross(p(t[2]) - p(t[0]))
            .normalize_or_zero()
    };
    let normals: Vec<DVec3> = triangles.iter().map(normal).collect();
    // Edges by the bit patterns of their end points, so meshes with split vertices connect too.
    let key = |i: u32| positions[i as usize].to_array().map(f32::to_bits);
    let mut edges: std::collections::HashMap<_, Vec<usize>> = std::collections::HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (key(tri[e]), key(tri[(e + 1) % 3]));
            edges
                .entry(if a < b { (a, b) } else { (b, a) })
                .or_default()
                .push(t);
        }
    }
    let mut assigned = vec![false; triangles.len()];
    let mut charts = Vec::new();
    for seed in 0..triangles.len() {
        if assigned[seed] {
            continue;
        }
        assigned[seed] = true;
        let seed_normal = normals[seed];
        let mut members = vec![seed];
        let tri = triangles[seed];
        let longest = (0..3)
            .max_by(|&e, &f| {
                let length = |e: usize| p(tri[e]).distance_squared(p(tri[(e + 1) % 3]));
                length(e).total_cmp(&length(f)).then(f.cmp(&e))
            })
            .unwrap_or(0);
        let (a, b) = (key(tri[longest]), key(tri[(longest + 1) % 3]));
        // A degenerate seed (zero normal) stays alone.
        if let Some(&mate) = edges[&if a < b { (a, b) } else { (b, a) }]
            .iter()
            .find(|&&other| {
                !assigned[other]
                    && seed_normal != DVec3::ZERO
                    && normals[other].dot(seed_normal) >= COPLANAR_COSINE
            })
        {
            assigned[mate] = true;
            members.push(mate);
        }
        members.sort_unstable();
        charts.push(chart_shape(positions, triangles, members, seed_normal));
    }
    charts
}

/// The axes and bounding rectangle of one chart: of the directions of its edges (one of which a
/// smallest enclosing rectangle always shares), the one giving the smallest area.
fn chart_shape(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    members: Vec<usize>,
    normal: DVec3,
) -> Chart {
    let p = |i: u32| positions[i as usize].as_dvec3();
    let points: Vec<DVec3> = members.iter().flat_map(|&t| triangles[t].map(p)).collect();
    let normal = if normal == DVec3::ZERO {
        DVec3::Z
    } else {
        normal
    };
    let mut candidates: Vec<DVec3> = Vec::new();
    for &t in &members {
        let tri = triangles[t];
        for e in 0..3 {
            let d = p(tri[(e + 1) % 3]) - p(tri[e]);
            let d = (d - normal * d.dot(normal)).normalize_or_zero();
            // Directions a quarter turn apart give the same rectangle: keep one per class.
            let same = |c: &DVec3| c.dot(d).abs() > 1.0 - 1e-9 || c.dot(d).abs() < 1e-9;
            if d != DVec3::ZERO && !candidates.iter().any(same) && candidates.len() < 64 {
                candidates.push(d);
            }
        }
    }
    if candidates.is_empty() {
        candidates.push(normal.any_orthonormal_vector());
    }
    let bounds = |u: DVec3| {
        let v = normal.cross(u);
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for q in &points {
            let local = DVec2::new(q.dot(u), q.dot(v));
            lo = lo.min(local);
            hi = hi.max(local);
        }
        (u, v, lo, hi)
    };
    let (u, v, lo, hi) = candidates
        .iter()
        .map(|&u| bounds(u))
        .min_by(|a, b| {
            let area =
                |(_, _, lo, hi): &(DVec3, DVec3, DVec2, DVec2)| (*hi - *lo).element_product();
            area(a).total_cmp(&area(b))
        })
        .unwrap_or_else(|| bounds(DVec3::X));
    // The origin on the chart plane (through the first point), at the rectangle's corner.
    let plane_offset = points.first().map_or(0.0, |q| q.dot(normal));
    Chart {
        triangles: members,
        origin: u * lo.x + v * lo.y + normal * plane_offset,
        axes: [u, v],
        extent: hi - lo,
        texels_per_metre: 0.0,
        rect: TexelRect {
            x: 0,
            y: 0,
            width: 1,
            height: 1,
        },
    }
}

/// Shelf packing: rectangles sorted by height (then width, then index), placed left to right on
/// shelves as wide as the square root of their total area (at least the widest rectangle).
/// Returns the atlas size and each rectangle's corner, in input order.
fn shelf_pack(sizes: &[(u32, u32)]) -> (u32, u32, Vec<(u32, u32)>) {
    let area: u64 = sizes
        .iter()
        .map(|&(w, h)| u64::from(w) * u64::from(h))
        .sum();
    let widest = sizes.iter().map(|s| s.0).max().unwrap_or(1);
    let shelf_width = widest.max((area as f64).sqrt().ceil() as u32);
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    order.sort_by_key(|&i| {
        (
            std::cmp::Reverse(sizes[i].1),
            std::cmp::Reverse(sizes[i].0),
            i,
        )
    });
    let mut places = vec![(0, 0); sizes.len()];
    let (mut x, mut y, mut shelf_height, mut width) = (0u32, 0u32, 0u32, 1u32);
    for i in order {
        let (w, h) = sizes[i];
        if x > 0 && x + w > shelf_width {
            y += shelf_height;
            x = 0;
            shelf_height = 0;
        }
        places[i] = (x, y);
        x += w;
        width = width.max(x);
        shelf_height = shelf_height.max(h);
    }
    (width, (y + shelf_height).max(1), places)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::shapes;

    #[test]
    fn a_plane_grid_is_one_chart_per_cell_of_the_cells_size() {
        let mesh = shapes::plane(glam::Vec2::new(20.0, 8.0), 8);
        let atlas = Atlas::new(&mesh.positions, &mesh.triangles, 16.0, 4096).unwrap();
        assert_eq!(atlas.charts.len(), 64);
        for chart in &atlas.charts {
            assert_eq!(chart.triangles.len(), 2);
            let rect = chart.rect;
            assert_eq!(
                (rect.width, rect.height),
                (40 + 2 * GUTTER_TEXELS, 16 + 2 * GUTTER_TEXELS)
            );
        }
    }

    #[test]
    fn a_cylinder_side_is_one_chart_per_quad() {
        let mesh = shapes::cylinder(0.15, 3.0, 32, true);
        let atlas = Atlas::new(&mesh.positions, &mesh.triangles, 128.0, 4096).unwrap();
        let side: Vec<&Chart> = atlas
            .charts
            .iter()
            .filter(|c| c.axes[0].cross(c.axes[1]).y.abs() < 1e-6)
            .collect();
        assert_eq!(side.len(), 32);
        for chart in side {
            assert_eq!(chart.triangles.len(), 2);
            // 3 m tall, 2π·0.15/32 m wide: the rectangle is the quad.
            assert!((chart.extent.x.min(chart.extent.y) - 0.0294).abs() < 1e-3);
            assert!((chart.extent.x.max(chart.extent.y) - 3.0).abs() < 1e-6);
        }
    }

    #[test]
    fn the_cap_lowers_the_density_until_the_atlas_fits() {
        let mesh = shapes::plane(glam::Vec2::new(20.0, 20.0), 4);
        let atlas = Atlas::new(&mesh.positions, &mesh.triangles, 128.0, 1024).unwrap();
        assert!(atlas.width <= 1024 && atlas.height <= 1024);
        assert!(atlas.density_scale < 1.0 && atlas.density_scale > 40.0 / 128.0);
        for chart in &atlas.charts {
            assert_eq!(chart.texels_per_metre, 128.0 * atlas.density_scale);
        }
    }

    /// Every chart inside the atlas, no two sharing a texel, and every point of every triangle
    /// inside its chart's rectangle with the whole gutter around it: bilinear filtering at any
    /// point of a triangle reads texels of its own chart only.
    #[test]
    fn charts_lie_inside_the_atlas_disjoint_and_with_their_gutter() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(0xa71a5);
        let mut meshes = vec![
            shapes::plane(glam::Vec2::new(3.0, 2.0), 5),
            shapes::cuboid(Vec3::new(0.7, 0.3, 1.1)),
            shapes::sphere(0.5, 24, 12),
            shapes::cylinder(0.15, 3.0, 32, true),
            shapes::torus(0.3, 0.05, 24, 8),
        ];
        // A random rotation of each, so no chart is axis aligned by construction.
        for mesh in &mut meshes {
            let rotation = glam::Quat::from_euler(
                glam::EulerRot::XYZ,
                rng.gen_range(0.0..6.0),
                rng.gen_range(0.0..6.0),
                rng.gen_range(0.0..6.0),
            );
            mesh.transform(&glam::Affine3A::from_quat(rotation));
        }
        for mesh in &meshes {
            let density = rng.gen_range(20.0..90.0);
            let atlas = Atlas::new(&mesh.positions, &mesh.triangles, density, 4096).unwrap();
            for (c, chart) in atlas.charts.iter().enumerate() {
                let r = chart.rect;
                assert!(r.x + r.width <= atlas.width && r.y + r.height <= atlas.height);
                for other in &atlas.charts[c + 1..] {
                    assert!(!r.overlaps(&other.rect), "{r:?} {:?}", other.rect);
                }
                assert!((chart.axes[0].dot(chart.axes[1])).abs() < 1e-9);
            }
            for (t, tri) in mesh.triangles.iter().enumerate() {
                let chart = &atlas.charts[atlas.chart_of[t]];
                assert!(chart.triangles.contains(&t));
                let g = f64::from(GUTTER_TEXELS);
                let r = chart.rect;
                for _ in 0..20 {
                    let (mut a, mut b) = (rng.r#gen::<f64>(), rng.r#gen::<f64>());
                    if a + b > 1.0 {
                        (a, b) = (1.0 - a, 1.0 - b);
                    }
                    let [p0, p1, p2] = tri.map(|i| mesh.positions[i as usize].as_dvec3());
                    let p = p0 + (p1 - p0) * a + (p2 - p0) * b;
                    let texel = chart.texel_of_local(chart.local(p));
                    assert!(
                        texel.x >= f64::from(r.x) + g - 1e-6
                            && texel.y >= f64::from(r.y) + g - 1e-6
                            && texel.x <= f64::from(r.x + r.width) - g + 1e-6
                            && texel.y <= f64::from(r.y + r.height) - g + 1e-6,
                        "{texel} outside {r:?} less its gutter"
                    );
                    // The point lies in the chart plane: projection loses nothing.
                    let back = chart.origin
                        + chart.axes[0] * chart.local(p).x
                        + chart.axes[1] * chart.local(p).y;
                    assert!(back.distance(p) < 1e-4, "{back} {p}");
                }
            }
        }
    }

    #[test]
    fn shelves_hold_every_rectangle_without_overlap() {
        let sizes = [(5, 9), (3, 3), (10, 2), (1, 1), (7, 9), (4, 4)];
        let (width, height, places) = shelf_pack(&sizes);
        let rects: Vec<TexelRect> = sizes
            .iter()
            .zip(&places)
            .map(|(&(w, h), &(x, y))| TexelRect {
                x,
                y,
                width: w,
                height: h,
            })
            .collect();
        for (i, r) in rects.iter().enumerate() {
            assert!(r.x + r.width <= width && r.y + r.height <= height);
            assert!(rects[i + 1..].iter().all(|o| !o.overlaps(r)));
        }
    }
}
