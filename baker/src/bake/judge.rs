//! What the baker judges EMs with: hybrid scenes with projected EMs on given shells, and the lens
//! PSNR of a hybrid frame against the reference over given pixels.

use std::sync::Arc;

use glam::{DVec3, Vec3};
use lensmap::{
    hybrid::{HybridScene, LensLayers},
    index::LensIndex,
    layers::{
        LayerShell,
        projected::{ProjectedOptions, project_layers},
    },
    metrics::{self, Channels, Encoding, Mask},
    render::TargetFormat,
    runner::{FrameOptions, FrameRunner},
    scene::{Camera, Scene},
};

use super::{failure::BakeFailure, options::BakeOptions};

/// Lens PSNR (sRGB) of `hybrid` at `camera` over `mask` against the reference radiance.
pub(super) fn masked_psnr(
    runner: &mut FrameRunner,
    hybrid: &HybridScene,
    camera: &Camera,
    reference: &[Vec3],
    mask: &Mask,
    options: &BakeOptions,
) -> Result<f64, BakeFailure> {
    let frame = runner.frame(
        hybrid,
        camera,
        &FrameOptions {
            hybrid: options.infer.frame_options(),
            compositing: options.infer.compositing,
            format: TargetFormat::Rgba32f,
        },
    )?;
    Ok(metrics::compare(
        &frame.image.pixels,
        reference,
        mask,
        Encoding::DisplaySrgb,
        Channels::Rgb,
    )?
    .psnr_db)
}

/// Projected EMs of every lens object on `shells` (per lens: origin and shells), at `size`.
pub(super) fn projected_scene(
    scene: &Scene,
    shells: Vec<(DVec3, Vec<LayerShell>)>,
    size: u32,
) -> Result<HybridScene, BakeFailure> {
    let options = lensmap::hybrid::HybridSceneOptions {
        ems: lensmap::hybrid::LayeredEms::ProjectedOn {
            shells,
            options: ProjectedOptions::with_size(size),
        },
        ..Default::default()
    };
    Ok(HybridScene::new(scene.clone(), options)?.0)
}

/// Replaces lens object `lens`'s layered EMs in `hybrid` by projected ones on `shells` (EM
/// origin `origin`) at face size `size`.
pub(super) fn project_into(
    hybrid: &mut HybridScene,
    lens: LensIndex,
    origin: DVec3,
    shells: Vec<LayerShell>,
    size: u32,
) {
    let (maps, _) = project_layers(
        hybrid.trace(),
        lens.index(),
        origin,
        &shells,
        &ProjectedOptions::with_size(size),
    );
    let layers = LensLayers {
        layering: hybrid.lenses()[lens.index()].layering,
        em_origins: vec![origin; shells.len()],
        shells,
        maps: vec![maps.into_iter().map(Arc::new).collect()],
    };
    hybrid.set_lens_layers(lens, layers);
}
