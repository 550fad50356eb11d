//! `lensmap bench bake`: how well baked (inferred) layered EMs render a scene away from where
//! they were fitted. Cameras around viewpoint sample A: on the sample, halfway (in angle)
//! between samples A and A+1, and 15° above the circle at sample A; in a 2D view space, on the
//! sample, in the middle of a spherical triangle of A, in the middle of an edge from A, and 15°
//! above A, each also drawn blending the two nearest samples and the nearest alone, to measure
//! what the three-sample blend is worth. Each is judged against an
//! independent reference traced with more supersamples than the bake's targets had, for
//! projected EMs (the scene's shells) and for every bake given, over the lens pixels and the
//! non-lens pixels; and, for the error budget, the frame with perfect information at each vertex
//! (`lensmap::hybrid::vertex_exact_frame`), whose lens error is the tessellation's share.

use std::path::PathBuf;

use clap::Args;
use glam::{DQuat, DVec3, Vec3};
use lensmap::{
    gpu::{Gpu, GpuOptions},
    hybrid::{HybridOptions, HybridScene, ViewpointBlending, sphere::SphereTriangulation},
    layers::{Bake, projected::ProjectedOptions},
    metrics::{self, Channels, Encoding, Mask},
    runner::{
        EmSource, FrameOptions, FrameRunner, camera_between, lens_error, load_hybrid_scene,
        non_lens_error,
    },
    scene::{Camera, Scene},
    trace::{LensSelection, PathModel, ReferenceImage, TraceOptions, TraceScene, render_reference},
};
use serde_json::json;

use crate::common::{BadUsage, JudgeArgs, report};
use crate::frame_args::FrameArgs;

#[derive(Args)]
#[command(
    mut_arg("format", |a| a.default_value("rgba32f")),
    mut_arg("tracer", |a| a.default_value("cpu")),
    after_help = "Example:
  lensmap bake --scene teapot-room --samples 0,1 --out out/bake
  lensmap bench bake --scene teapot-room --bake out/bake --sample 0"
)]
pub struct BenchBakeArgs {
    /// Built-in scene name or path.
    #[arg(long, default_value = "teapot-room")]
    scene: String,
    /// Bake directories to judge (each must hold samples A and A+1; in a 2D view space the
    /// samples round A), labelled by their names.
    #[arg(long, num_args = 1.., required = true)]
    bake: Vec<PathBuf>,
    /// Viewpoint sample A.
    /// Range: [0, ∞) (A and A + 1 must be samples of the scene).
    #[arg(long, default_value_t = 0)]
    sample: usize,
    #[command(flatten)]
    judge: JudgeArgs,
    /// How the judged frames are made (RGBA32F and the CPU tracer unless asked otherwise).
    #[command(flatten)]
    frame: FrameArgs,
    /// The reference's ray-path model: `greedy` (the papers' two terms, what greedy bakes fit),
    /// `full` (the full ray tree: the light), or a path-class set. Where it is not the frames'
    /// own model (`--terms`), each frame is also judged against its own model's reference, so
    /// that the EMs' error and the model's show apart; against `full`, the reference is also
    /// traced at half its supersampling, to show it converged.
    #[arg(long, default_value = "greedy", value_name = "greedy|full|N|CLASSES", value_parser = crate::reference::parse_tree)]
    reference_tree: PathModel,
    /// Projected EMs' face size (the baseline).
    /// Range: [1, 2048] (a power of two).
    #[arg(long, default_value_t = 128)]
    em_size: u32,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
}

/// Per lens object (when the scene has more than one): its name and its pixels in `reference`
/// (the engine's rule, [`lensmap::trace::lens_pixels`]).
fn lens_object_masks(trace: &TraceScene, reference: &ReferenceImage) -> Vec<(String, Mask)> {
    if trace.lenses.len() < 2 {
        return Vec::new();
    }
    trace
        .lenses
        .iter()
        .enumerate()
        .map(|(lens, object)| {
            let mask = Mask::lens(&reference.lens_pixels, LensSelection::Object(lens));
            (object.name.clone(), mask)
        })
        .collect()
}

/// The judged cameras, `base` moved: on sample A, halfway to A+1, 15° above A; in a 2D view
/// space on sample A, at the centroid of the first triangle holding A, at the middle of the arc
/// to A's lowest-numbered neighbour, and 15° above A (all at A's distance from the centre).
pub fn cameras(scene: &Scene, a: usize, base: Camera) -> Vec<(&'static str, Camera)> {
    let samples = scene.view_space.samples();
    let look_at = scene.camera.look_at;
    let pa = samples[a] - look_at;
    let in_2d = SphereTriangulation::of_scene(scene).and_then(|t| {
        let centre = scene.view_space.centre(look_at).as_dvec3();
        let own = samples[a].as_dvec3() - centre;
        let at = |direction: DVec3| (centre + direction.normalize() * own.length()).as_vec3();
        let unit = |i: usize| (samples[i].as_dvec3() - centre).normalize();
        let triangle = t.triangles().iter().find(|tri| tri.contains(&a))?;
        let middle = at(triangle.iter().map(|&i| unit(i)).sum());
        let neighbour = *t.neighbours(a).first()?;
        let edge = at(unit(a) + unit(neighbour));
        Some((middle, edge))
    });
    let halfway = camera_between(scene, a, a + 1).map_or(samples[a], |c| c.position);
    // Up by 15° about the horizontal axis perpendicular to the view direction.
    let axis = pa.cross(Vec3::Y).normalize_or(Vec3::X).as_dvec3();
    let above =
        look_at + (DQuat::from_axis_angle(axis, -15f64.to_radians()) * pa.as_dvec3()).as_vec3();
    let above = if above.y > samples[a].y {
        above
    } else {
        look_at + (DQuat::from_axis_angle(axis, 15f64.to_radians()) * pa.as_dvec3()).as_vec3()
    };
    match in_2d {
        Some((middle, edge)) => vec![
            ("on sample", base.with_position(samples[a])),
            ("triangle", base.with_position(middle)),
            ("edge", base.with_position(edge)),
            ("15° above", base.with_position(above)),
        ],
        None => vec![
            ("on sample", base.with_position(samples[a])),
            ("halfway", base.with_position(halfway)),
            ("15° above", base.with_position(above)),
        ],
    }
}

/// What is judged: the scene's projected EMs (first), then every bake given, labelled by its
/// directory's name.
fn contenders(scene: &Scene, args: &BenchBakeArgs) -> anyhow::Result<Vec<(String, HybridScene)>> {
    let mut contenders: Vec<(String, HybridScene)> = vec![(
        "projected".into(),
        load_hybrid_scene(
            scene.clone(),
            &EmSource::Projected(ProjectedOptions::with_size(args.em_size)).into(),
        )?
        .0,
    )];
    for dir in &args.bake {
        let bake = Bake::read(dir)?;
        let label = dir.file_name().map_or_else(
            || dir.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let ems = lensmap::hybrid::LayeredEms::Baked(bake);
        contenders.push((label, HybridScene::new(scene.clone(), ems.into())?.0));
    }
    Ok(contenders)
}

/// One camera's references: the judge's (`--reference-tree`), the frames' own model's where it
/// is another, their lens pixels and rim, and per lens object its pixels.
struct References {
    reference: ReferenceImage,
    own: Option<ReferenceImage>,
    lens: Mask,
    rim: Option<Mask>,
    per_lens: Vec<(String, Mask)>,
    /// The full tree's convergence, (coarse supersampling, the judge's, lens PSNR): the full
    /// tree at half the supersampling against the judge's; `None` for another model.
    convergence: Option<(u32, u32, f64)>,
}

impl References {
    /// The references of `camera` in `trace` under `model` (and `own`, the frames' model).
    fn traced(
        trace: &TraceScene,
        camera: &Camera,
        model: PathModel,
        own: Option<PathModel>,
        rows: &(dyn Fn(u32) + Sync),
    ) -> anyhow::Result<References> {
        let render = |model, camera: &Camera| {
            let options = TraceOptions {
                model,
                ..TraceOptions::default()
            };
            render_reference(trace, camera, &options, rows)
        };
        let reference = render(model, camera)?;
        let own = own
            .filter(|&own| own != model)
            .map(|own| render(own, camera))
            .transpose()?;
        let lens = Mask::lens(&reference.lens_pixels, LensSelection::All);
        let rim = crate::bench_classes::rings(&reference, &lens)
            .pop()
            .map(Mask::from_flags);
        let convergence = if model == PathModel::Full {
            let half = Camera {
                supersampling: (camera.supersampling / 2).max(1),
                ..*camera
            };
            let coarse = render(PathModel::Full, &half)?;
            let psnr = metrics::compare(
                &coarse.radiance,
                &reference.radiance,
                &lens,
                Encoding::DisplaySrgb,
                Channels::Rgb,
            )?
            .psnr_db;
            Some((half.supersampling, camera.supersampling, psnr))
        } else {
            None
        };
        Ok(References {
            per_lens: lens_object_masks(trace, &reference),
            reference,
            own,
            lens,
            rim,
            convergence,
        })
    }

    /// `frame` (labelled `label`, blending `samples`) judged against these references: its
    /// JSON cell, and its figures appended to `line`.
    fn judge(
        &self,
        frame: &lensmap::runner::HybridFrame,
        label: &str,
        samples: Vec<serde_json::Value>,
        line: &mut String,
    ) -> anyhow::Result<serde_json::Value> {
        let reference = &self.reference;
        let lens = lens_error(&frame.image, reference, Encoding::DisplaySrgb)?.psnr_db;
        let other = non_lens_error(&frame.image, reference, Encoding::DisplaySrgb)?.psnr_db;
        line.push_str(&format!("  {label}: {lens:.2} | {other:.2}"));
        let own_psnr = self
            .own
            .as_ref()
            .map(|own| lens_error(&frame.image, own, Encoding::DisplaySrgb))
            .transpose()?
            .map(|e| e.psnr_db);
        if let Some(own_psnr) = own_psnr {
            line.push_str(&format!(" (own {own_psnr:.2})"));
        }
        let radiance = crate::common::mean_ratio(&frame.image, reference, &self.lens);
        let rim_radiance = self
            .rim
            .as_ref()
            .and_then(|rim| crate::common::mean_ratio(&frame.image, reference, rim));
        if let (Some(all), Some(rim)) = (radiance, rim_radiance) {
            line.push_str(&format!(" ×{all:.3} rim ×{rim:.3}"));
        }
        // Per lens object, where there is more than one (null where it covers no pixel).
        let objects: Vec<_> = self
            .per_lens
            .iter()
            .map(|(object, mask)| {
                let psnr = metrics::compare(
                    &frame.image.pixels,
                    &reference.radiance,
                    mask,
                    Encoding::DisplaySrgb,
                    Channels::Rgb,
                )
                .ok()
                .map(|e| e.psnr_db);
                json!({"lens": object, "lens_psnr_db": psnr})
            })
            .collect();
        Ok(json!({
            "ems": label, "lens_psnr_db": lens, "non_lens_psnr_db": other,
            "own_model_lens_psnr_db": own_psnr,
            "lens_radiance_ratio": radiance, "rim_radiance_ratio": rim_radiance,
            "lens_objects": objects, "viewpoints": samples,
        }))
    }
}

pub fn run(args: BenchBakeArgs) -> anyhow::Result<()> {
    args.judge.validate()?;
    let scene = crate::common::load_scene(&args.scene)?;
    let surface = SphereTriangulation::of_scene(&scene).is_some();
    if surface && args.sample >= scene.view_space.len() {
        return Err(BadUsage(format!(
            "--sample {}: scene \"{}\" has samples 0..{}",
            args.sample,
            scene.name,
            scene.view_space.len()
        ))
        .into());
    }
    if !surface && args.sample >= scene.view_space.len().saturating_sub(1) {
        return Err(BadUsage(format!(
            "--sample {}: needs samples A and A+1; scene \"{}\" has samples 0..{}",
            args.sample,
            scene.name,
            scene.view_space.len()
        ))
        .into());
    }
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut runner = FrameRunner::new(Gpu::new(&GpuOptions::from_env())?)?;
    let device = runner.gpu().device_id().clone();
    let mut steps = crate::common::Steps::new(4);
    let step = steps.step("projected layered EMs, light maps and the bakes");
    let contenders = contenders(&scene, &args)?;
    // In a 2D view space every bake is also drawn with fewer samples blended.
    let blendings: &[(ViewpointBlending, &str)] = if surface {
        &[
            (ViewpointBlending::ViewSpace, ""),
            (ViewpointBlending::TwoNearest, " (2 nearest)"),
            (ViewpointBlending::Nearest, " (nearest)"),
        ]
    } else {
        &[(ViewpointBlending::ViewSpace, "")]
    };
    step.finish_and_clear();
    let options = args.frame.options()?;
    // The frames' own model, where their lens objects share one (else no "own" column).
    let own_model = crate::common::frame_model(options.hybrid.terms, &scene).ok();
    say!(
        "{}: {}×{} at {k}×{k}, t = {}, terms {}, reference {} paths at {r}×{r}, device {device} (driver {}); lens | non-lens PSNR, dB (sRGB){}; ×: mean lens radiance over the reference's, rim: r/R > 0.95",
        scene.name,
        args.judge.width,
        args.judge.height,
        args.frame.t,
        own_model.map_or_else(|| options.hybrid.terms.name(), |m| m.name()),
        args.reference_tree.name(),
        device.driver_description(),
        if own_model.is_some_and(|m| m != args.reference_tree) {
            ", own: against the frames' own model"
        } else {
            ""
        },
        k = args.judge.supersampling,
        r = args.judge.reference_supersampling
    );
    let mut rows = Vec::new();
    for (name, camera) in cameras(&scene, args.sample, args.judge.frame_camera(&scene.camera)) {
        let reference_camera = args.judge.reference_camera(&camera);
        let bar = steps.counted(
            &format!("camera {name}: reference, then the frames"),
            u64::from(reference_camera.height),
            "rows",
        );
        let refs = References::traced(
            contenders[0].1.trace(),
            &reference_camera,
            args.reference_tree,
            own_model,
            &|rows| bar.set_position(u64::from(rows)),
        )?;
        let mut cells = Vec::new();
        let mut line = format!("{name:<10}");
        if let Some((coarse, fine, converged)) = refs.convergence {
            line.push_str(&format!(
                "  [full tree {coarse}×{coarse} vs {fine}×{fine}: {converged:.2}]"
            ));
            cells.push(json!({
                "ems": "reference convergence", "lens_psnr_db": converged,
                "supersampling": [coarse, fine],
            }));
        }
        let drawn = contenders
            .iter()
            .enumerate()
            .flat_map(|(i, (label, hybrid))| {
                // Projected EMs are the same at every sample: one blending says all.
                let blendings = if i == 0 { &blendings[..1] } else { blendings };
                blendings
                    .iter()
                    .map(move |&(blending, suffix)| (format!("{label}{suffix}"), hybrid, blending))
            });
        for (label, hybrid, blending) in drawn {
            let options = FrameOptions {
                hybrid: HybridOptions {
                    viewpoint_blending: blending,
                    ..options.hybrid
                },
                ..options
            };
            let frame = runner.frame(hybrid, &camera, &options)?;
            let samples: Vec<_> = hybrid
                .viewpoint_blend(&camera, blending)
                .samples
                .iter()
                .map(|(i, w)| json!({"viewpoint": i, "weight": w}))
                .collect();
            cells.push(refs.judge(&frame, &label, samples, &mut line)?);
        }
        // The error budget's tessellation share: the same tessellation with the exact radiance
        // at every vertex, interpolated (no EM, no shell, no filtering).
        let (exact_frame, _) =
            lensmap::hybrid::vertex_exact_frame(&contenders[0].1, &camera, &options.hybrid)?;
        let exact = runner
            .render(&exact_frame, options.compositing, options.format)?
            .box_downsample(camera.supersampling);
        let exact_lens = lens_error(&exact, &refs.reference, Encoding::DisplaySrgb)?.psnr_db;
        line.push_str(&format!("  vertex-exact: {exact_lens:.2}"));
        cells.push(json!({"ems": "vertex-exact", "lens_psnr_db": exact_lens}));
        bar.finish_and_clear();
        say!("{line}");
        rows.push(json!({"camera": name, "position": camera.position, "results": cells}));
    }
    report(
        &json!({
            "scene": scene.name, "device": device.device, "driver": device.driver_description(), "width": args.judge.width, "height": args.judge.height,
            "supersampling": args.judge.supersampling, "reference_supersampling": args.judge.reference_supersampling,
            "t": args.frame.t, "sample": args.sample, "bakes": args.bake, "rows": rows,
            "terms": own_model.map_or_else(|| options.hybrid.terms.name(), |m| m.name()),
            "reference_tree": args.reference_tree,
        }),
        args.report.as_deref(),
    )?;
    Ok(())
}
