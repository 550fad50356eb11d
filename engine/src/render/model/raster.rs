//! The model's rasterizer: triangles through the vertex stage and viewport transform into
//! framebuffer coordinates, their coverage and depth at pixel centres by edge functions with the
//! top-left rule, the pixels of triangles the GPU would clip marked, and each fragment's
//! nearness to an edge (a coverage tie) recorded.

use glam::{DMat4, DVec2, DVec4};

use super::ModelOptions;
use crate::render::frame_input::{FrameInput, LensObject};
use crate::trace::Term;

/// Which draw a triangle belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Source {
    /// Environment mesh `mesh`.
    Environment { mesh: usize },
    /// Glossy draw `index`.
    Glossy { index: usize },
    /// Lens object `object`; `skip_local`: one of its hull triangles, drawn without layer 0
    /// (the convex-hull split, [`crate::render::LensObject::hull_triangles`]).
    Lens { object: usize, skip_local: bool },
}

/// A triangle after the vertex stage and viewport transform.
#[derive(Clone, Debug)]
pub(super) struct ScreenTriangle {
    pub(super) source: Source,
    pub(super) vertices: [usize; 3],
    /// Framebuffer coordinates (y down).
    pub(super) position: [DVec2; 3],
    /// z_clip / w_clip.
    pub(super) depth: [f64; 3],
    pub(super) inv_w: [f64; 3],
    /// cross(p1 − p0, p2 − p0); Vulkan's signed area is −cross/2.
    pub(super) cross: f64,
    /// The passes draw it: environment triangles always, lens triangles when front-facing or
    /// when their lens draws both faces.
    pub(super) drawn: bool,
    /// Drawn, or so thin that a GPU's facing decision could differ (then every pixel it could
    /// cover is near one of its edges anyway).
    pub(super) possibly_drawn: bool,
    pub(super) edge_length: [f64; 3],
    /// Whether an exact tie on edge i counts as covered (top-left rule).
    pub(super) top_left: [bool; 3],
    /// Inclusive pixel bounds, already clamped to the framebuffer.
    pub(super) x_range: (i64, i64),
    pub(super) y_range: (i64, i64),
}

impl ScreenTriangle {
    /// Edge functions E_i(q) = cross(p_{i+2} − p_{i+1}, q − p_{i+1}); Σ E_i = cross.
    fn edge_values(&self, q: DVec2) -> [f64; 3] {
        std::array::from_fn(|i| {
            let a = self.position[(i + 1) % 3];
            let b = self.position[(i + 2) % 3];
            let e = b - a;
            let r = q - a;
            e.x * r.y - e.y * r.x
        })
    }

    /// Perspective-correct barycentric weights at `q` (inside or outside the triangle), or
    /// `None` where the interpolated 1/w is not positive.
    pub(super) fn perspective_weights(&self, q: DVec2) -> Option<[f64; 3]> {
        let e = self.edge_values(q);
        let screen: [f64; 3] = std::array::from_fn(|i| e[i] / self.cross * self.inv_w[i]);
        let sum = screen[0] + screen[1] + screen[2];
        (sum > 0.0 && sum.is_finite()).then(|| screen.map(|w| w / sum))
    }
}

/// A triangle's sample at one pixel.
#[derive(Clone, Copy, Debug)]
pub(super) struct Fragment {
    pub(super) triangle: usize,
    pub(super) covered: bool,
    pub(super) near_edge: bool,
    pub(super) depth: f64,
}

/// The per-frame data every quad row reads.
pub(super) struct FrameSetup<'a> {
    pub(super) frame: &'a FrameInput,
    pub(super) options: ModelOptions,
    pub(super) triangles: Vec<ScreenTriangle>,
    /// Pixels touched by a clipped triangle.
    pub(super) clipped: Vec<bool>,
    /// Per lens object, its groups in pass order.
    pub(super) groups: Vec<Vec<PassGroup>>,
}

impl<'a> FrameSetup<'a> {
    /// Every drawn triangle of `frame` through the vertex stage, in draw order (environment
    /// meshes, then lens objects), and each lens object's groups.
    pub(super) fn new(frame: &'a FrameInput, options: &ModelOptions) -> Self {
        let view_proj: DMat4 = frame.view_proj.as_dmat4();
        let (width, height) = (frame.width as usize, frame.height as usize);
        let mut setup = FrameSetup {
            frame,
            options: *options,
            triangles: Vec::new(),
            clipped: vec![false; width * height],
            groups: Vec::new(),
        };
        let to_clip = |positions: &[glam::Vec3]| -> Vec<DVec4> {
            positions
                .iter()
                .map(|p| view_proj * p.as_dvec3().extend(1.0))
                .collect()
        };
        for (mesh, environment) in frame.environment.iter().enumerate() {
            let clip = to_clip(&environment.positions);
            for triangle in &environment.triangles {
                setup.add_triangle(Source::Environment { mesh }, &clip, *triangle);
            }
        }
        for (index, glossy) in frame.glossy.iter().enumerate() {
            let clip = to_clip(&glossy.mesh.positions);
            for triangle in &glossy.mesh.triangles {
                setup.add_triangle(Source::Glossy { index }, &clip, *triangle);
            }
        }
        for (object, lens) in frame.lenses.iter().enumerate() {
            let clip = to_clip(&lens.positions);
            let first_hull = lens.triangles.len().saturating_sub(lens.hull_triangles);
            for (t, triangle) in lens.triangles.iter().enumerate() {
                let skip_local = t >= first_hull;
                setup.add_triangle(Source::Lens { object, skip_local }, &clip, *triangle);
            }
            setup.groups.push(lens_groups(frame, lens));
        }
        setup
    }

    fn add_triangle(&mut self, source: Source, clip: &[DVec4], indices: [u32; 3]) {
        let vertices = indices.map(|i| i as usize);
        let Some(c) = vertices
            .iter()
            .map(|&v| clip.get(v).copied())
            .collect::<Option<Vec<DVec4>>>()
        else {
            return;
        };
        let (width, height) = (f64::from(self.frame.width), f64::from(self.frame.height));
        let inside = |v: &DVec4| v.w > 0.0 && v.z >= 0.0 && v.z <= v.w;
        if !c.iter().all(inside) {
            self.mark_clipped(&c);
            return;
        }
        let position: [DVec2; 3] = std::array::from_fn(|i| {
            let ndc = c[i].truncate() / c[i].w;
            DVec2::new((ndc.x + 1.0) * 0.5 * width, (ndc.y + 1.0) * 0.5 * height)
        });
        let depth: [f64; 3] = std::array::from_fn(|i| c[i].z / c[i].w);
        let inv_w: [f64; 3] = std::array::from_fn(|i| 1.0 / c[i].w);
        let cross = (position[1] - position[0]).perp_dot(position[2] - position[0]);
        if cross == 0.0 || !cross.is_finite() {
            // Zero area covers no sample.
            return;
        }
        let edge_length: [f64; 3] =
            std::array::from_fn(|i| (position[(i + 2) % 3] - position[(i + 1) % 3]).length());
        let top_left: [bool; 3] = std::array::from_fn(|i| {
            let e = position[(i + 2) % 3] - position[(i + 1) % 3];
            // ∇E_i = (−e.y, e.x); times sign(cross) it points into the triangle. Top-left rule
            // with y down: a left edge has the interior to its right (+x), a top edge is
            // horizontal with the interior below it (+y).
            let inward = DVec2::new(-e.y, e.x) * cross.signum();
            inward.x > 0.0 || (inward.x == 0.0 && inward.y > 0.0)
        });
        // Vulkan: a = −½ Σ (x_i y_{i+1} − x_{i+1} y_i) = −cross/2, front-facing (CCW) if a > 0.
        let front = cross < 0.0;
        let drawn = match source {
            Source::Environment { .. } | Source::Glossy { .. } => true,
            Source::Lens { object, .. } => {
                front || self.frame.lenses[object].faces == crate::render::LensFaces::Both
            }
        };
        let longest = edge_length.iter().copied().fold(0.0, f64::max);
        let thin = cross.abs() / longest < self.options.edge_tolerance_px;
        let margin = self.options.edge_tolerance_px;
        let pixel_range = |lo: f64, hi: f64, size: f64| -> (i64, i64) {
            // Pixel k's centre k + ½ must lie in [lo − margin, hi + margin].
            let first = (lo - margin - 0.5).ceil().max(0.0);
            let last = (hi + margin - 0.5).floor().min(size - 1.0);
            (first as i64, last as i64)
        };
        let xs = position.map(|p| p.x);
        let ys = position.map(|p| p.y);
        let x_range = pixel_range(
            xs.iter().copied().fold(f64::INFINITY, f64::min),
            xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            width,
        );
        let y_range = pixel_range(
            ys.iter().copied().fold(f64::INFINITY, f64::min),
            ys.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            height,
        );
        self.triangles.push(ScreenTriangle {
            source,
            vertices,
            position,
            depth,
            inv_w,
            cross,
            drawn,
            possibly_drawn: drawn || thin,
            edge_length,
            top_left,
            x_range,
            y_range,
        });
    }

    /// Marks the screen bounding box (plus a pixel) of the visible part of a triangle the GPU
    /// would clip: the triangle clipped to 0 ≤ z ≤ w and w > 0, projected.
    fn mark_clipped(&mut self, clip: &[DVec4]) {
        let mut polygon: Vec<DVec4> = clip.to_vec();
        let planes: [fn(DVec4) -> f64; 3] = [|v| v.z, |v| v.w - v.z, |v| v.w - 1e-12 * v.w.abs()];
        for plane in planes {
            let mut next = Vec::with_capacity(polygon.len() + 1);
            for k in 0..polygon.len() {
                let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
                let (da, db) = (plane(a), plane(b));
                if da >= 0.0 {
                    next.push(a);
                }
                if (da >= 0.0) != (db >= 0.0) {
                    next.push(a + (b - a) * (da / (da - db)));
                }
            }
            polygon = next;
            if polygon.is_empty() {
                return;
            }
        }
        let (width, height) = (f64::from(self.frame.width), f64::from(self.frame.height));
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for v in &polygon {
            if v.w <= 0.0 {
                continue;
            }
            let p = DVec2::new(
                (v.x / v.w + 1.0) * 0.5 * width,
                (v.y / v.w + 1.0) * 0.5 * height,
            );
            lo = lo.min(p);
            hi = hi.max(p);
        }
        if !(lo.x <= hi.x && lo.y <= hi.y) {
            return;
        }
        let x0 = (lo.x - 1.0).floor().clamp(0.0, width) as usize;
        let x1 = (hi.x + 1.0).ceil().clamp(0.0, width) as usize;
        let y0 = (lo.y - 1.0).floor().clamp(0.0, height) as usize;
        let y1 = (hi.y + 1.0).ceil().clamp(0.0, height) as usize;
        for y in y0..y1 {
            for x in x0..x1 {
                self.clipped[y * self.frame.width as usize + x] = true;
            }
        }
    }

    /// All triangles' fragments on row y, per pixel in draw order (triangles are stored in draw
    /// order, and a pixel's fragments keep that order, as Vulkan's primitive order does).
    pub(super) fn rasterize_row(&self, y: usize) -> Vec<Vec<Fragment>> {
        let width = self.frame.width as usize;
        let mut fragments = vec![Vec::new(); width];
        let yi = y as i64;
        let tolerance = self.options.edge_tolerance_px;
        for (index, triangle) in self.triangles.iter().enumerate() {
            if yi < triangle.y_range.0 || yi > triangle.y_range.1 {
                continue;
            }
            let sign = triangle.cross.signum();
            for x in triangle.x_range.0..=triangle.x_range.1 {
                let q = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let e = triangle.edge_values(q).map(|v| v * sign);
                // Signed distances to the edges' lines, positive inside. For a convex polygon
                // the minimum is the distance to the boundary inside, and a lower bound of
                // minus the distance outside, so (−tol, tol) contains every near-edge point.
                let distance = (0..3)
                    .map(|i| e[i] / triangle.edge_length[i])
                    .fold(f64::INFINITY, f64::min);
                if distance <= -tolerance {
                    continue;
                }
                let covered = (0..3).all(|i| e[i] > 0.0 || (e[i] == 0.0 && triangle.top_left[i]));
                let near_edge = distance < tolerance;
                if !covered && !near_edge {
                    continue;
                }
                let b: [f64; 3] = std::array::from_fn(|i| e[i] * sign / triangle.cross);
                let depth =
                    b[0] * triangle.depth[0] + b[1] * triangle.depth[1] + b[2] * triangle.depth[2];
                fragments[x as usize].push(Fragment {
                    triangle: index,
                    covered,
                    near_edge,
                    depth,
                });
            }
        }
        fragments
    }
}

/// One group of a lens object's layer passes: a viewpoint sample and a term (an index into the
/// object's `terms`).
#[derive(Clone, Copy, Debug)]
pub(super) struct PassGroup {
    pub(super) viewpoint: usize,
    pub(super) term: usize,
}

/// The groups a lens object's layer passes run, in pass order: viewpoints with a non-zero
/// weight, and within each, the object's terms with refraction before reflection.
fn lens_groups(frame: &FrameInput, object: &LensObject) -> Vec<PassGroup> {
    let mut terms: Vec<(Term, usize)> = object
        .terms
        .iter()
        .enumerate()
        .map(|(index, t)| (t.term, index))
        .collect();
    terms.sort();
    let mut groups = Vec::new();
    for (viewpoint, &weight) in frame.viewpoint_weights.iter().enumerate() {
        if weight == 0.0 || viewpoint >= object.layers.len() {
            continue;
        }
        for &(_, term) in &terms {
            groups.push(PassGroup { viewpoint, term });
        }
    }
    groups
}
