//! What the camera fixes before any lens object is traced ([`FrameView`]), and what each lens
//! object's tessellation is asked for in that view ([`LensJob`]): its scene objects inside the
//! view, its threshold after footprint coarsening, its faces and whether the convex-hull split
//! applies.

use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};

use super::{HybridOptions, HybridStats};
use crate::{
    hybrid::{
        paths::{PathOracle, ScreenCamera},
        scene::HybridScene,
        sky::SkyDome,
        tessellate::{TessellationError, TessellationOptions},
        viewpoints::ViewpointBlend,
    },
    index::LensIndex,
    options::{OptionError, names},
    render::{EnvironmentMesh, LensFaces},
    scene::Camera,
    trace::{
        Interface,
        classes::{ClassSet, ClassTerm},
        schlick_table::SchlickTable,
    },
};

/// What the camera fixes for a frame before any lens object is traced.
pub struct FrameView {
    /// Framebuffer width, subpixels (pixels × supersampling).
    pub(super) width: u32,
    /// Framebuffer height, subpixels.
    pub(super) height: u32,
    /// World → Vulkan clip space.
    pub(super) view_proj: Mat4,
    /// The same projection for the vertex oracles.
    pub(super) screen: ScreenCamera,
    /// The sky dome around the camera, drawn behind everything; `None` when the sky is black.
    pub(super) sky: Option<Arc<EnvironmentMesh>>,
    /// The table the vertex paths look Schlick's fifth-order term up in; `None`: evaluated.
    pub(super) fresnel: Option<SchlickTable>,
}

impl FrameView {
    /// The view of `camera` on `scene`: the framebuffer, the projection (its far plane just past
    /// the farthest scene point, so nothing the reference sees is clipped, and past the sky dome
    /// beyond it when there is one), the sky dome's mesh and `options`' Fresnel table.
    pub(super) fn new(
        scene: &HybridScene,
        camera: &Camera,
        options: &HybridOptions,
    ) -> Result<FrameView, TessellationError> {
        let k = camera.supersampling.max(1);
        let (width, height) = (camera.width * k, camera.height * k);
        let farthest = scene
            .scene()
            .objects
            .iter()
            .filter_map(|o| o.mesh.bounds())
            .flat_map(|(lo, hi)| box_corners(lo, hi))
            .map(|corner| corner.distance(camera.position))
            .fold(1.0f32, f32::max);
        let sky = scene.sky().map(|sky| {
            let radius = SkyDome::radius_beyond(farthest);
            (sky.mesh(camera.position, radius), radius)
        });
        let far = sky.as_ref().map_or(farthest, |(_, radius)| *radius);
        let view_proj = camera.view_proj(0.05, 1.01 * far + 1.0);
        Ok(FrameView {
            width,
            height,
            view_proj,
            screen: ScreenCamera {
                eye: camera.position.as_dvec3(),
                view_proj,
                subpixels: Vec2::new(width as f32, height as f32),
            },
            sky: sky.map(|(mesh, _)| mesh),
            fresnel: options.fresnel.table()?,
        })
    }
}

/// One lens object's part of a frame: what its vertex stage tessellates, traces and gives
/// texture coordinates.
pub struct LensJob<'a> {
    /// The scene.
    pub(super) scene: &'a HybridScene,
    /// The lens object (TraceScene order).
    pub(super) lens: LensIndex,
    /// The frame's view.
    pub(super) view: &'a FrameView,
    /// The frame's options.
    pub(super) options: &'a HybridOptions,
    /// Its tessellation options: the frame's, `t` coarsened by its footprint.
    pub(super) tessellation: TessellationOptions,
    /// Its scene objects whose bounds are not wholly outside the view.
    pub(super) objects: Vec<usize>,
    /// The faces its passes draw.
    pub(super) faces: LensFaces,
    /// Whether the convex-hull split applies (on, and the lens object is layered by bounce).
    pub(super) hull_split: bool,
    /// The viewpoint samples the frame blends (which of its maps the frame draws).
    pub(super) blend: &'a ViewpointBlend,
    /// The path-class terms its vertices trace ([`HybridOptions::terms`] for its material);
    /// empty: the two greedy terms.
    pub(super) classes: Vec<ClassTerm>,
}

impl<'a> LensJob<'a> {
    /// Lens object `lens` of `scene` in `view` with `options`, drawn from the samples of
    /// `blend`, counting in `stats` whether it lies outside the view and whether its `t` is
    /// coarsened; an error for path classes on a lens object they cannot shade
    /// ([`class_terms`]).
    pub(super) fn new(
        scene: &'a HybridScene,
        lens: LensIndex,
        view: &'a FrameView,
        options: &'a HybridOptions,
        blend: &'a ViewpointBlend,
        stats: &mut HybridStats,
    ) -> Result<LensJob<'a>, OptionError> {
        let classes = class_terms(scene, lens, options)?;
        let objects: Vec<usize> = scene.trace().lenses[lens.index()]
            .objects
            .iter()
            .copied()
            .filter(|&object| {
                !scene.scene().objects[object]
                    .mesh
                    .bounds()
                    .is_some_and(|(lo, hi)| box_outside_view(lo, hi, &view.view_proj))
            })
            .collect();
        // A lens object wholly outside the view keeps its (empty) place in the frame, so that
        // frame lens i is still trace lens i; an empty lens object records no pass.
        if objects.is_empty() {
            stats.lenses_outside_view += 1;
        }
        let tessellation = coarsened(scene, &objects, options, &view.screen);
        if tessellation.t != options.tessellation.t {
            stats.lenses_coarsened += 1;
        }
        Ok(LensJob {
            scene,
            lens,
            view,
            options,
            tessellation,
            faces: scene.faces().get(lens.index()).copied().unwrap_or_default(),
            hull_split: options.hull_split && !scene.lenses()[lens.index()].layering.is_distance(),
            objects,
            blend,
            classes,
        })
    }

    /// The vertex oracle of scene object `object` of this lens object: the frame's camera,
    /// angle threshold, precision and Fresnel table, the lens object's faces and bounces.
    pub(super) fn oracle(&self, object: usize) -> PathOracle<'a> {
        let layers = &self.scene.lenses()[self.lens.index()];
        PathOracle::new(
            self.scene.trace(),
            self.lens.index(),
            object,
            self.view.screen,
            self.options.angle_radians,
            self.faces,
        )
        .with_precision(self.options.precision)
        .with_bounces(layers.layering.bounces())
        .with_fresnel(self.view.fresnel.as_ref())
        .with_classes(self.classes.clone())
    }
}

/// The path-class terms of lens object `lens` under `options` (none for the greedy terms),
/// checked against the options ([`HybridOptions::validate_classes`]):
/// [`ClassSet::terms`] for the material of its surfaces (a count takes glass's order or a
/// mirror's). An error where they cannot shade it: a lens object layered by bounce (its paths
/// stop at the first bounce, and its layers hold what the later bounces see), or a count for a
/// lens object of glass and mirrors together (whose order is whose?).
fn class_terms(
    scene: &HybridScene,
    lens: LensIndex,
    options: &HybridOptions,
) -> Result<Vec<ClassTerm>, OptionError> {
    let Some(set) = options
        .terms
        .of(scene.scene().lenses.get(lens.index()).and_then(|l| l.terms))
    else {
        return Ok(Vec::new());
    };
    // Set in the scene file, they meet the options' checks here.
    options.validate_classes(set)?;
    let trace = scene.trace();
    let name = &trace.lenses[lens.index()].name;
    let refuse = |fix: String| Err(OptionError::new(names::TERMS, set.name(), fix));
    if !scene.lenses()[lens.index()].layering.is_distance() {
        return refuse(format!(
            "lens object '{name}' is layered by bounce, whose paths stop at the first bounce; path classes need its layers by distance (`layering = \"distance\"`), or give greedy"
        ));
    }
    let mut interfaces = trace.lenses[lens.index()]
        .objects
        .iter()
        .filter_map(|&o| trace.interface(o));
    let Some(first) = interfaces.next() else {
        return Ok(set.terms(Interface::Mirror {
            reflectance: glam::DVec3::ONE,
        }));
    };
    let glass = |i: &Interface| matches!(i, Interface::Dielectric { .. });
    if matches!(set, ClassSet::First(_)) && interfaces.any(|i| glass(&i) != glass(&first)) {
        return refuse(format!(
            "lens object '{name}' joins glass and mirrors, so a count has no one order; list the classes (e.g. R,TT,TRT,RR)"
        ));
    }
    Ok(set.terms(first))
}

/// The tessellation options of a lens object made of `objects`: `t` scaled up by footprint
/// coarsening where its projected bounds span fewer than `footprint_subpixels` (never when a
/// corner of its bounds is behind the eye: the footprint is then unknown).
fn coarsened(
    scene: &HybridScene,
    objects: &[usize],
    options: &HybridOptions,
    screen: &ScreenCamera,
) -> TessellationOptions {
    let mut tessellation = options.tessellation;
    if options.footprint_subpixels <= 0.0 || objects.is_empty() {
        return tessellation;
    }
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for &object in objects {
        let Some((a, b)) = scene.scene().objects[object].mesh.bounds() else {
            continue;
        };
        for corner in box_corners(a, b) {
            let Some(p) = screen.project(corner) else {
                return tessellation;
            };
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let extent = (hi - lo).max_element();
    if extent.is_finite() && extent < options.footprint_subpixels {
        let scale =
            (options.footprint_subpixels / extent.max(1e-3)).min(super::MAX_FOOTPRINT_COARSENING);
        tessellation.t *= scale;
    }
    tessellation
}

/// Whether the axis-aligned box from `lo` to `hi` lies wholly outside the view of `view_proj`:
/// its eight corners outside the clip volume as the tessellation's triangle test decides
/// ([`crate::hybrid::paths::outside_clip_volume`]).
pub(super) fn box_outside_view(lo: Vec3, hi: Vec3, view_proj: &Mat4) -> bool {
    crate::hybrid::paths::outside_clip_volume(
        &box_corners(lo, hi).map(|p| *view_proj * p.extend(1.0)),
    )
}

/// The eight corners of the axis-aligned box from `lo` to `hi`.
fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            [lo.x, hi.x][i & 1],
            [lo.y, hi.y][(i >> 1) & 1],
            [lo.z, hi.z][i >> 2],
        )
    })
}
