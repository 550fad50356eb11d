//! The model's fragment stage and passes at one pixel: the environment's shading, each lens
//! object's prime and layer passes with perspective-correct attributes, quad derivatives and
//! trilinear cube-map samples, composited by the blending scheme, and the exclusion bits of
//! everything a GPU may do differently.

use glam::{DVec2, DVec3};

use super::bounds::{Bounded, Interval, interval_product, light_map_bounds, point_bounds};
use super::raster::{Fragment, FrameSetup, PassGroup, ScreenTriangle, Source};
use super::{AlphaClearScope, DerivativeMode, Exclusion, LodMode};
use crate::cubemap::CubeMap;
use crate::cubemap::face::{competing_faces, major_face};
use crate::cubemap::sampling::{
    cube_lod_on_face, cube_lod_range_on_face, sample_cube, sample_cube_bounds,
};
use crate::render::frame_input::LensObject;
use crate::render::plan::BlendScheme;

/// One pixel of the model's output before the exclusion bits become a reason.
#[derive(Clone, Copy, Debug)]
pub(super) struct PixelResult {
    pub(super) rgba: [f64; 4],
    pub(super) bounds: [Interval; 4],
    pub(super) depth: f64,
    pub(super) lens: bool,
    pub(super) flags: u8,
    pub(super) visible: Option<usize>,
}

/// What the passes have left at one pixel so far.
struct PixelState {
    colour: Bounded,
    depth: f64,
    /// The triangle the pixel shows.
    visible: Option<usize>,
    /// Exclusion bits raised so far.
    flags: u8,
}

/// A pixel's column and row.
#[derive(Clone, Copy, Debug)]
struct Pixel {
    x: usize,
    y: usize,
}

impl FrameSetup<'_> {
    /// Renders framebuffer rows 2·quad_row and 2·quad_row + 1 (those that exist).
    pub(super) fn render_quad_row(&self, quad_row: usize) -> Vec<PixelResult> {
        let width = self.frame.width as usize;
        let height = self.frame.height as usize;
        let rows: Vec<usize> = (2 * quad_row..(2 * quad_row + 2).min(height)).collect();
        let mut results = Vec::with_capacity(rows.len() * width);
        for &y in &rows {
            let fragments = self.rasterize_row(y);
            for (x, pixel_fragments) in fragments.iter().enumerate() {
                results.push(self.shade_pixel(x, y, pixel_fragments));
            }
        }
        if self.options.flag_quad_straddle {
            self.flag_quad_straddles(&mut results, rows.len());
        }
        results
    }

    /// The passes at one pixel: the environment, then per lens object its prime and its groups
    /// of layer passes in the blending scheme's order, then the exclusion bits of the pixel's
    /// geometry.
    fn shade_pixel(&self, x: usize, y: usize, fragments: &[Fragment]) -> PixelResult {
        let mut pixel = PixelState {
            colour: Bounded::point([0.0; 4]),
            depth: 1.0,
            visible: None,
            flags: 0,
        };
        if self.clipped[y * self.frame.width as usize + x] {
            pixel.flags |= Exclusion::ClippedTriangle.bit();
        }
        let at = Pixel { x, y };
        self.environment_pass(&mut pixel, at, fragments);
        self.glossy_pass(&mut pixel, at, fragments);
        for object in 0..self.frame.lenses.len() {
            self.lens_passes(&mut pixel, object, at, fragments);
        }
        pixel.flags |= self.geometry_flags(fragments, pixel.depth);
        let lens = pixel
            .visible
            .is_some_and(|t| matches!(self.triangles[t].source, Source::Lens { .. }));
        PixelResult {
            rgba: pixel.colour.value,
            bounds: pixel.colour.bounds,
            depth: pixel.depth,
            lens,
            flags: pixel.flags,
            visible: pixel.visible,
        }
    }

    /// The environment pass: LESS, write, (colour, 1).
    fn environment_pass(
        &self,
        pixel: &mut PixelState,
        Pixel { x, y }: Pixel,
        fragments: &[Fragment],
    ) {
        let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
        for fragment in fragments {
            let triangle = &self.triangles[fragment.triangle];
            let Source::Environment { mesh } = triangle.source else {
                continue;
            };
            if fragment.covered && fragment.depth < pixel.depth {
                pixel.colour = self.environment_colour(triangle, mesh, centre);
                pixel.depth = fragment.depth;
                pixel.visible = Some(fragment.triangle);
            }
        }
    }

    /// The glossy pass: LESS, write, (radiance, 1), the radiance [`crate::rsibr::shade`]'s at the
    /// interpolated position and normal (no precision bounds: the value alone).
    fn glossy_pass(&self, pixel: &mut PixelState, Pixel { x, y }: Pixel, fragments: &[Fragment]) {
        let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
        for fragment in fragments {
            let triangle = &self.triangles[fragment.triangle];
            let Source::Glossy { index } = triangle.source else {
                continue;
            };
            if fragment.covered && fragment.depth < pixel.depth {
                let draw = &self.frame.glossy[index];
                let mesh = &draw.mesh;
                let position = self.interpolate(triangle, centre, |v| mesh.positions[v].as_dvec3());
                let normal = self
                    .interpolate(triangle, centre, |v| mesh.normals[v].as_dvec3())
                    .normalize_or_zero();
                let shading = crate::rsibr::GlossyShading {
                    brdf: draw.brdf,
                    lobes: draw.lobes.clone(),
                    slots: draw
                        .slots
                        .iter()
                        .map(|s| (f64::from(s.weight), s.rotation.as_dmat3(), s.maps.clone()))
                        .collect(),
                };
                let toward_viewer = (draw.eye.as_dvec3() - position).normalize_or_zero();
                let rgb = crate::rsibr::shade(&shading, normal, toward_viewer);
                pixel.colour = Bounded::point([rgb.x, rgb.y, rgb.z, 1.0]);
                pixel.depth = fragment.depth;
                pixel.visible = Some(fragment.triangle);
            }
        }
    }

    /// An environment fragment's colour at `centre`: the interpolated vertex colour times the
    /// light map's bilinear sample at the perspective-correct uv, α = 1.
    fn environment_colour(&self, triangle: &ScreenTriangle, mesh: usize, centre: DVec2) -> Bounded {
        let environment = &self.frame.environment[mesh];
        let colours = &environment.colours;
        let vertex_rgb = self.interpolate(triangle, centre, |v| colours[v].as_dvec3());
        let mut rgb = vertex_rgb;
        let mut light_bounds = None;
        if let Some(light_map) = &environment.light_map {
            let uv = self.interpolate(triangle, centre, |v| {
                light_map.uvs[v].as_dvec2().extend(0.0)
            });
            rgb *= light_map.map.sample_bilinear(uv.truncate());
            light_bounds = self
                .options
                .precision
                .map(|precision| light_map_bounds(&light_map.map, uv.truncate(), precision));
        }
        let mut colour = Bounded::point([rgb.x, rgb.y, rgb.z, 1.0]);
        if let Some(light) = light_bounds {
            for c in 0..3 {
                colour.bounds[c] = interval_product([vertex_rgb[c]; 2], light[c]);
            }
        }
        colour
    }

    /// Lens object `object_index`'s passes: the prime (LESS, write, (0,0,0,0)), then its groups
    /// of layer passes on the fragments that pass LESS_OR_EQUAL against the primed depth.
    fn lens_passes(
        &self,
        pixel: &mut PixelState,
        object_index: usize,
        Pixel { x, y }: Pixel,
        fragments: &[Fragment],
    ) {
        let object = &self.frame.lenses[object_index];
        let object_fragments: Vec<&Fragment> = fragments
            .iter()
            .filter(|f| {
                let t = &self.triangles[f.triangle];
                matches!(t.source, Source::Lens { object, .. } if object == object_index)
                    && t.drawn
                    && f.covered
            })
            .collect();
        for fragment in &object_fragments {
            if fragment.depth < pixel.depth {
                pixel.colour = Bounded::point([0.0; 4]);
                pixel.depth = fragment.depth;
                pixel.visible = Some(fragment.triangle);
            }
        }
        // The depth is final after the prime: layer passes test against it without writing it.
        let passing: Vec<LensFragment> = object_fragments
            .iter()
            .filter(|f| f.depth <= pixel.depth)
            .map(|f| self.lens_fragment(object, &self.triangles[f.triangle], x, y))
            .collect();
        for lens_fragment in &passing {
            pixel.flags |= lens_fragment.flags;
        }
        self.composite_groups(pixel, object_index, &passing);
    }

    /// A lens object's groups composited as [`ModelOptions::blend`] does: into the framebuffer
    /// with alpha clears between groups (front to back, programmable), or each into a cleared
    /// scratch image added to the framebuffer (back to front) or summed at the end (group
    /// targets).
    fn composite_groups(
        &self,
        pixel: &mut PixelState,
        object_index: usize,
        passing: &[LensFragment],
    ) {
        let object = &self.frame.lenses[object_index];
        let groups = &self.groups[object_index];
        let blend = self.options.blend;
        let into_framebuffer =
            matches!(blend, BlendScheme::FrontToBack | BlendScheme::Programmable);
        // Scratch images of the group-targets scheme.
        let mut scratch: Vec<Bounded> = Vec::new();
        for (group_index, &group) in groups.iter().enumerate() {
            if into_framebuffer && group_index > 0 {
                // The alpha clear (the programmable scheme's in-shader reset is the same
                // arithmetic: α of the current value taken as 0).
                let clears_here = match self.options.alpha_clear {
                    AlphaClearScope::FullScreen => true,
                    AlphaClearScope::LensCoverage => !passing.is_empty(),
                };
                if clears_here {
                    pixel.colour = pixel.colour.alpha_clear();
                }
            }
            // Where this group's layers composite: the framebuffer, or a cleared scratch.
            let start = if into_framebuffer {
                pixel.colour
            } else {
                Bounded::point([0.0; 4])
            };
            let target = self.composite_group(&mut pixel.flags, object, group, passing, start);
            let last = group_index + 1 == groups.len();
            match blend {
                BlendScheme::FrontToBack | BlendScheme::Programmable => pixel.colour = target,
                // Each group's scratch image added to the framebuffer: colour, and α for the
                // last group.
                BlendScheme::BackToFront => {
                    let mask = if last { 0b1111 } else { 0b0111 };
                    pixel.colour = pixel.colour.add_masked(target, mask);
                }
                BlendScheme::GroupTargets => scratch.push(target),
            }
        }
        // The group sum: the groups' colour summed in order from zero, α the last group's,
        // added to the framebuffer.
        if let Some(&last) = scratch.last() {
            let mut sum = Bounded::point([0.0; 4]);
            for value in &scratch {
                sum = sum.add_masked(*value, 0b0111);
            }
            (sum.value[3], sum.bounds[3]) = (last.value[3], last.bounds[3]);
            pixel.colour = pixel.colour.add_masked(sum, 0b1111);
        }
    }

    /// One group's layer passes over `target`: per layer (farthest first for back to front,
    /// else nearest first) every passing fragment's sample blended in; the samples' exclusion
    /// bits are added to `flags`.
    fn composite_group(
        &self,
        flags: &mut u8,
        object: &LensObject,
        PassGroup { viewpoint, term }: PassGroup,
        passing: &[LensFragment],
        mut target: Bounded,
    ) -> Bounded {
        let back_to_front = self.options.blend == BlendScheme::BackToFront;
        let weight = f64::from(self.frame.viewpoint_weights[viewpoint]);
        let n = object.layer_count();
        let order: Vec<usize> = if back_to_front {
            (0..n).rev().collect()
        } else {
            (0..n).collect()
        };
        for layer in order {
            for lens_fragment in passing {
                // A hull triangle's layer-0 sample is taken as zero, the identity of the blend.
                if layer == 0 && lens_fragment.skip_local {
                    continue;
                }
                let cube = &object.layers[viewpoint][layer];
                let sample = self.sample(cube, &lens_fragment.directions[term][layer]);
                *flags |= sample.flags;
                let fg = lens_fragment.fg[term].to_array();
                let source = Bounded::layer_source(weight, fg, sample.rgba, sample.bounds);
                target = if back_to_front {
                    target.blend_back_to_front(source)
                } else {
                    target.blend_front_to_back(source)
                };
            }
        }
        target
    }

    /// Coverage and depth ties that could change what the pixel shows.
    fn geometry_flags(&self, fragments: &[Fragment], final_depth: f64) -> u8 {
        let tolerance = self.options.depth_tolerance;
        let mut flags = 0;
        // An edge tie matters when its triangle is drawn and could be in front: at or nearer
        // than what the pixel finally shows (give or take the depth tolerance).
        if fragments.iter().any(|f| {
            f.near_edge
                && self.triangles[f.triangle].possibly_drawn
                && f.depth <= final_depth + tolerance
        }) {
            flags |= Exclusion::NearTriangleEdge.bit();
        }
        // Among covered, drawn fragments, the front-most and any other triangle within the
        // tolerance make the depth test (or the layer passes' LESS_OR_EQUAL) a coin toss.
        let mut drawn_depths = fragments
            .iter()
            .filter(|f| f.covered && self.triangles[f.triangle].drawn)
            .map(|f| (f.depth, f.triangle));
        if let Some(front) = drawn_depths.clone().min_by(|a, b| a.0.total_cmp(&b.0))
            && drawn_depths.any(|(d, t)| t != front.1 && (d - front.0).abs() < tolerance)
        {
            flags |= Exclusion::DepthTie.bit();
        }
        flags
    }

    /// Perspective-correct interpolation of a per-vertex attribute at `q`.
    fn interpolate(
        &self,
        triangle: &ScreenTriangle,
        q: DVec2,
        attribute: impl Fn(usize) -> DVec3,
    ) -> DVec3 {
        let weights = triangle.perspective_weights(q).unwrap_or([f64::NAN; 3]);
        (0..3)
            .map(|i| weights[i] * attribute(triangle.vertices[i]))
            .sum()
    }

    /// A visible lens fragment's interpolated data: F·G per term and, per term and layer, the
    /// direction at the pixel with the quad's coarse derivatives.
    fn lens_fragment(
        &self,
        object: &LensObject,
        triangle: &ScreenTriangle,
        x: usize,
        y: usize,
    ) -> LensFragment {
        let mut flags = 0u8;
        let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
        let top_left = DVec2::new((x & !1) as f64 + 0.5, (y & !1) as f64 + 0.5);
        let points = [
            centre,
            top_left,
            top_left + DVec2::new(1.0, 0.0),
            top_left + DVec2::new(0.0, 1.0),
            top_left + DVec2::new(1.0, 1.0),
        ];
        let weights: Vec<Option<[f64; 3]>> = points
            .iter()
            .map(|&q| triangle.perspective_weights(q))
            .collect();
        if weights.iter().any(Option::is_none) {
            flags |= Exclusion::UndefinedDerivative.bit();
        }
        let at = |k: usize, value: &dyn Fn(usize) -> DVec3| -> DVec3 {
            let w = weights[k].unwrap_or([0.0; 3]);
            (0..3).map(|i| w[i] * value(triangle.vertices[i])).sum()
        };
        let fg = object
            .terms
            .iter()
            .map(|term| at(0, &|v| term.fg[v].as_dvec3()))
            .collect();
        let directions = object
            .terms
            .iter()
            .map(|term| {
                term.directions
                    .iter()
                    .map(|layer| {
                        let value = |v: usize| layer[v].as_dvec3();
                        // The quad's pixels: top-left, top-right, bottom-left, bottom-right.
                        let quad = [at(1, &value), at(2, &value), at(3, &value), at(4, &value)];
                        let quad_top_left = quad[0];
                        let (column, row) = (x & 1, y & 1);
                        let coarse = (quad[1] - quad[0], quad[2] - quad[0]);
                        let fine = (
                            quad[2 * row + 1] - quad[2 * row],
                            quad[2 + column] - quad[column],
                        );
                        let (ddx, ddy) = match self.options.derivatives {
                            DerivativeMode::Coarse => coarse,
                            DerivativeMode::Fine => fine,
                        };
                        let direction = at(0, &value);
                        let lod_direction = match self.options.lod_mode {
                            LodMode::PerPixel => direction,
                            LodMode::PerQuadTopLeft => quad_top_left,
                        };
                        let finite = [direction, lod_direction, ddx, ddy]
                            .iter()
                            .all(|v| v.is_finite());
                        if !finite || direction == DVec3::ZERO || lod_direction == DVec3::ZERO {
                            flags |= Exclusion::UndefinedDerivative.bit();
                        }
                        DirectionSample {
                            direction,
                            lod_direction,
                            ddx,
                            ddy,
                            either_derivatives: [coarse, fine],
                        }
                    })
                    .collect()
            })
            .collect();
        LensFragment {
            skip_local: matches!(
                triangle.source,
                Source::Lens {
                    skip_local: true,
                    ..
                }
            ),
            fg,
            directions,
            flags,
        }
    }

    /// A trilinear sample as the layer pass takes it, its bounds, and the exclusion bits it
    /// raises.
    fn sample(&self, cube: &CubeMap, at: &DirectionSample) -> FilteredSample {
        let levels = cube.levels.len() as u32;
        let lod_on = |face| {
            cube_lod_on_face(
                face,
                cube.size,
                levels,
                at.lod_direction,
                at.ddx,
                at.ddy,
                self.options.lod_log2,
            )
        };
        let lambda = lod_on(major_face(at.lod_direction));
        let mut flags = 0u8;
        let competing = competing_faces(at.lod_direction, self.options.face_tie_tolerance);
        if competing.len() > 1 {
            let lods: Vec<f64> = competing.iter().copied().map(lod_on).collect();
            let spread = lods.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - lods.iter().copied().fold(f64::INFINITY, f64::min);
            if spread > self.options.lod_tie_tolerance {
                flags |= Exclusion::CubeFaceTie.bit();
            }
        }
        let sample = sample_cube(cube, at.direction, lambda);
        if sample.corner {
            flags |= Exclusion::CubeCorner.bit();
        }
        let bounds = match self.options.precision {
            None => point_bounds(sample.rgba),
            Some(precision) => {
                // Every LOD the spec allows, on whichever face f32 face selection may pick.
                let mut lod_range = [f64::INFINITY, f64::NEG_INFINITY];
                for face in competing
                    .iter()
                    .copied()
                    .chain([major_face(at.lod_direction)])
                {
                    let range = cube_lod_range_on_face(
                        face,
                        cube.size,
                        levels,
                        at.lod_direction,
                        &at.either_derivatives,
                        precision,
                    );
                    lod_range = [lod_range[0].min(range[0]), lod_range[1].max(range[1])];
                }
                let range = sample_cube_bounds(cube, at.direction, lod_range, precision);
                if range.corner {
                    flags |= Exclusion::CubeCorner.bit();
                }
                range.bounds
            }
        };
        FilteredSample {
            rgba: sample.rgba,
            bounds,
            flags,
        }
    }

    /// Marks lens pixels whose quad shows more than one triangle (or some non-lens pixel).
    fn flag_quad_straddles(&self, results: &mut [PixelResult], rows: usize) {
        let width = self.frame.width as usize;
        for qx in (0..width).step_by(2) {
            let members: Vec<usize> = (0..rows)
                .flat_map(|r| (qx..(qx + 2).min(width)).map(move |x| r * width + x))
                .collect();
            let first = results[members[0]].visible;
            let straddles =
                members.iter().any(|&m| results[m].visible != first) || members.len() < 4;
            if straddles {
                for &m in &members {
                    if results[m].lens {
                        results[m].flags |= Exclusion::QuadStraddle.bit();
                    }
                }
            }
        }
    }
}

/// Where one layer of one term is sampled at a pixel.
#[derive(Clone, Copy, Debug)]
struct DirectionSample {
    /// The interpolated direction at the pixel centre (what is filtered).
    direction: DVec3,
    /// The direction whose face and position decide the LOD ([`LodMode`]).
    lod_direction: DVec3,
    /// Quad derivatives of the direction, coarse or fine as [`ModelOptions::derivatives`] says.
    ddx: DVec3,
    ddy: DVec3,
    /// `(ddx, ddy)` both ways, coarse then fine: an implementation may take either.
    either_derivatives: [(DVec3, DVec3); 2],
}

/// A layer sample at a pixel: the model's value, its bounds ([`ModelImage::bounds`]) and the
/// exclusion bits it raises.
#[derive(Clone, Copy, Debug)]
struct FilteredSample {
    rgba: [f64; 4],
    bounds: [Interval; 4],
    flags: u8,
}

/// A lens fragment that passes the layer passes' depth test.
#[derive(Clone, Debug)]
struct LensFragment {
    /// Its triangle is a hull triangle of the convex-hull split: layer 0 is not drawn on it.
    skip_local: bool,
    /// Per term (in `object.terms` order), interpolated F·G.
    fg: Vec<DVec3>,
    /// `directions[term][layer]`.
    directions: Vec<Vec<DirectionSample>>,
    flags: u8,
}
