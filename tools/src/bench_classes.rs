//! `lensmap bench classes`: ray-path models against the full ray tree, with no environment map
//! in between: what the papers' two greedy terms and the first N path classes can reach at best
//! (the model's ceiling, which no EM can lift), their cost in rays, and the share of the light
//! they drop. The full tree's own convergence (between two supersampling levels) is given
//! beside, so that a model's figure is not mistaken for the reference's noise.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use lensmap::metrics::{self, Channels, Encoding, Mask};
use lensmap::scene::Camera;
use lensmap::trace::bvh::SurfaceHit;
use lensmap::trace::classes::{rank_classes, trace_term};
use lensmap::trace::image::camera_ray;
use lensmap::trace::world::Part;
use lensmap::trace::{
    ClassSet, LensSelection, PathClass, PathModel, Ray, RayTreeOptions, ReferenceImage,
    TraceCounters, TraceOptions, TraceScene, render_reference,
};
use serde::Serialize;

use crate::common::BadUsage;

/// Arguments of `lensmap bench classes`.
#[derive(Args)]
#[command(
    after_help = "Example:\n  lensmap bench classes --scenes glass-sphere --tree greedy --tree 4 --width 160 --height 120"
)]
pub struct BenchClassesArgs {
    /// Scenes (built-in names or paths), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = ["glass-sphere".to_owned(), "teapot-room".to_owned(), "mirror-teapot".to_owned()])]
    scenes: Vec<String>,
    /// A ray-path model judged against the full tree (repeat it for several): `greedy`, a
    /// class count N, or a class list such as `R,TT,TRT,TRRT`. The four classes that carry
    /// most of each scene's lens light are judged too, as a list.
    #[arg(long = "tree", value_name = "greedy|N|CLASSES", value_parser = crate::reference::parse_tree,
          default_values = ["greedy", "2", "3", "4", "6", "greedy:2", "greedy:3"])]
    trees: Vec<PathModel>,
    /// Image width, pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Image height, pixels.
    /// Range: [1, 16384].
    #[arg(long, default_value_t = 240)]
    height: u32,
    /// Supersampling k×k of every render; the full tree is rendered at 2k too, for its own
    /// convergence, so 2k × the width and the height must keep within 16384 subpixels a side
    /// and 2²⁶ in all.
    /// Range: [1, 64].
    #[arg(long, value_name = "K", default_value_t = 2)]
    supersampling: u32,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
}

/// The lens radiance in rings about the lens pixels' centroid, each as a model's over the full
/// tree's (for a sphere the rings are r/R bands of its disc).
pub(crate) const RINGS: [(f64, f64); 5] = [
    (0.0, 0.5),
    (0.5, 0.8),
    (0.8, 0.9),
    (0.9, 0.95),
    (0.95, 1.01),
];

/// How many ranked classes are reported; the first [`RANKED_ROW`] of them are also judged as a
/// class list.
const RANKED: usize = 8;
const RANKED_ROW: usize = 4;

/// The first lens hits of `camera`'s pixel-centre rays, per lens object of `world`.
fn lens_hits(world: &TraceScene, camera: &Camera) -> Vec<Vec<(Ray, SurfaceHit)>> {
    let mut counters = TraceCounters::default();
    let mut hits: Vec<Vec<(Ray, SurfaceHit)>> = vec![Vec::new(); world.lenses.len()];
    for y in 0..camera.height {
        for x in 0..camera.width {
            let ray = camera_ray(camera, f64::from(x) + 0.5, f64::from(y) + 0.5);
            if let Some(hit) = world.closest_hit(&ray, None, None, &mut counters)
                && let Part::Lens(lens) = hit.part
            {
                hits[lens].push((ray, hit.hit));
            }
        }
    }
    hits
}

/// The classes carrying light through `world`'s lens objects at the rays of `hits`, by share
/// of the throughput, to 16 events.
fn ranked(world: &TraceScene, hits: &[Vec<(Ray, SurfaceHit)>]) -> Vec<(PathClass, f64)> {
    let limits = RayTreeOptions {
        max_depth: 16,
        cutoff: 1e-4,
    };
    let total: usize = hits.iter().map(Vec::len).sum();
    let mut shares: std::collections::BTreeMap<PathClass, f64> = Default::default();
    for (lens, hits) in hits.iter().enumerate() {
        let geometry = world.lens(lens);
        for (class, share) in rank_classes(&geometry, hits.iter().map(|(r, h)| (r, h)), limits) {
            *shares.entry(class).or_default() += share * hits.len() as f64 / total.max(1) as f64;
        }
    }
    let mut ranked: Vec<(PathClass, f64)> = shares.into_iter().collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    ranked
}

/// How many of `model`'s terms carry light through some lens object at the rays of `hits`
/// (the most over the lens objects): what a frame's layer passes scale with. Greedy counts
/// as the tree expanded to one event, which it is.
fn terms_carrying_light(
    world: &TraceScene,
    hits: &[Vec<(Ray, SurfaceHit)>],
    model: PathModel,
) -> usize {
    let set = match model {
        PathModel::Classes(set) => set,
        PathModel::Greedy | PathModel::Full => ClassSet::Expanded(1),
    };
    let mut counters = TraceCounters::default();
    hits.iter()
        .enumerate()
        .map(|(lens, hits)| {
            let geometry = world.lens(lens);
            let Some((_, first)) = hits.first() else {
                return 0;
            };
            let Some(interface) = world.interface(first.object) else {
                return 0;
            };
            set.terms(interface)
                .into_iter()
                .filter(|&term| {
                    hits.iter().any(|(ray, hit)| {
                        trace_term(&geometry, ray, hit, term, &mut counters)
                            .is_some_and(|path| path.weight().max_element() > 0.0)
                    })
                })
                .count()
        })
        .max()
        .unwrap_or(0)
}

/// One model on one scene against the full tree.
#[derive(Serialize)]
struct Row {
    scene: String,
    tree: PathModel,
    /// PSNR over the lens pixels, display sRGB, against the full tree.
    lens_psnr_srgb_db: f64,
    /// PSNR over the lens pixels, linear radiance (peak 1), against the full tree.
    lens_psnr_linear_db: f64,
    /// Σ lens radiance of the model / of the full tree (mean of the channels).
    radiance_ratio: f64,
    /// The same per ring of [`RINGS`] (null for a ring with no lens pixel).
    ring_ratios: Vec<Option<f64>>,
    /// Under path classes: the share of the lens objects' throughput they drop.
    class_dropped: Option<f64>,
    /// Secondary rays of the model / of the full tree.
    secondary_ray_ratio: f64,
    /// How many of the model's terms carry light through a lens object at the pixel centres
    /// (the most over the lens objects; what a frame's layer passes scale with).
    terms: usize,
    seconds: f64,
}

/// The full tree on one scene, and its convergence.
#[derive(Serialize)]
struct Reference {
    scene: String,
    lens_pixels: usize,
    /// The classes that carry light through the lens objects at the pixel centres, by share of
    /// the throughput (the first [`RANKED`]).
    ranked_classes: Vec<(String, f64)>,
    /// The full tree at k×k against itself at 2k×2k over the lens pixels, display sRGB.
    convergence_psnr_srgb_db: f64,
    seconds: f64,
}

#[derive(Serialize)]
struct BenchReport {
    width: u32,
    height: u32,
    supersampling: u32,
    references: Vec<Reference>,
    rows: Vec<Row>,
    rings: Vec<[f64; 2]>,
}

/// Σ over `mask`'s pixels of the mean channel of `image`.
fn lens_sum(image: &ReferenceImage, mask: &[bool]) -> f64 {
    image
        .radiance
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .map(|(r, _)| f64::from(r.x + r.y + r.z) / 3.0)
        .sum()
}

/// The lens pixels split into [`RINGS`] about their centroid, by the radius of a disc of their
/// area.
pub(crate) fn rings(image: &ReferenceImage, lens: &Mask) -> Vec<Vec<bool>> {
    let width = image.width as usize;
    let pixels: Vec<(f64, f64)> = (0..lens.pixel_count())
        .filter(|&i| lens.contains(i))
        .map(|i| ((i % width) as f64 + 0.5, (i / width) as f64 + 0.5))
        .collect();
    let count = pixels.len().max(1) as f64;
    let centre = pixels
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p.0 / count, y + p.1 / count));
    let radius = (count / std::f64::consts::PI).sqrt();
    RINGS
        .iter()
        .map(|&(inner, outer)| {
            (0..lens.pixel_count())
                .map(|i| {
                    let (x, y) = ((i % width) as f64 + 0.5, (i / width) as f64 + 0.5);
                    let r = (x - centre.0).hypot(y - centre.1) / radius;
                    lens.contains(i) && r >= inner && r < outer
                })
                .collect()
        })
        .collect()
}

/// Runs `lensmap bench classes`.
pub fn run(args: BenchClassesArgs) -> anyhow::Result<()> {
    let scenes: Vec<_> = args
        .scenes
        .iter()
        .map(|name| crate::common::load_scene(name).map(|scene| (name.clone(), scene)))
        .collect::<Result<_, _>>()?;
    // Every render's camera, the full tree's at 2k×2k too, before any work.
    for (name, scene) in &scenes {
        for k in [args.supersampling, args.supersampling * 2] {
            let camera = Camera {
                width: args.width,
                height: args.height,
                supersampling: k,
                ..scene.camera
            };
            lensmap::trace::image::validate_camera(&camera).map_err(|error| {
                BadUsage(format!(
                    "--width {} --height {} --supersampling {}: {name}'s render at {k}×{k} (the full tree's convergence renders at twice --supersampling): {error}",
                    args.width, args.height, args.supersampling
                ))
            })?;
        }
    }
    if crate::common::validate_only() {
        return Ok(());
    }
    let mut references = Vec::new();
    let mut rows = Vec::new();
    for (name, scene) in &scenes {
        let world =
            TraceScene::new(scene).with_context(|| format!("{name}: preparing the scene"))?;
        let camera = Camera {
            width: args.width,
            height: args.height,
            supersampling: args.supersampling,
            ..scene.camera
        };
        let render = |model, camera: &Camera| {
            let options = TraceOptions {
                model,
                ..TraceOptions::default()
            };
            render_reference(&world, camera, &options, &|_| {})
                .with_context(|| format!("{name}: rendering with {}", model.name()))
        };
        let full = render(PathModel::Full, &camera)?;
        let finer = render(
            PathModel::Full,
            &Camera {
                supersampling: args.supersampling * 2,
                ..camera
            },
        )?;
        let lens = Mask::lens(&full.lens_pixels, LensSelection::All);
        let lens_error = |image: &ReferenceImage, encoding| {
            metrics::compare(
                &image.radiance,
                &full.radiance,
                &lens,
                encoding,
                Channels::Rgb,
            )
            .with_context(|| format!("{name}: the lens pixels"))
        };
        let convergence = metrics::compare(
            &full.radiance,
            &finer.radiance,
            &lens,
            Encoding::DisplaySrgb,
            Channels::Rgb,
        )
        .with_context(|| format!("{name}: the lens pixels"))?;
        let hits = lens_hits(&world, &camera);
        let ranked = ranked(&world, &hits);
        let top = ranked
            .iter()
            .take(RANKED_ROW)
            .map(|(class, _)| class.name())
            .collect::<Vec<_>>()
            .join(",");
        let mut trees = args.trees.clone();
        if let Ok(set) = ClassSet::parse(&top) {
            trees.push(PathModel::Classes(set));
        }
        references.push(Reference {
            scene: name.clone(),
            lens_pixels: lens.selected(),
            ranked_classes: ranked
                .iter()
                .take(RANKED)
                .map(|(class, share)| (class.name(), *share))
                .collect(),
            convergence_psnr_srgb_db: convergence.psnr_db,
            seconds: full.stats.seconds,
        });
        let flags: Vec<bool> = (0..lens.pixel_count()).map(|i| lens.contains(i)).collect();
        let rings = rings(&full, &lens);
        let full_sum = lens_sum(&full, &flags);
        for &model in &trees {
            let image = render(model, &camera)?;
            let ratio = |mask: &[bool]| {
                let reference = lens_sum(&full, mask);
                (reference > 0.0).then(|| lens_sum(&image, mask) / reference)
            };
            rows.push(Row {
                scene: name.clone(),
                tree: model,
                lens_psnr_srgb_db: lens_error(&image, Encoding::DisplaySrgb)?.psnr_db,
                lens_psnr_linear_db: lens_error(&image, Encoding::Linear)?.psnr_db,
                radiance_ratio: lens_sum(&image, &flags) / full_sum,
                ring_ratios: rings.iter().map(|ring| ratio(ring)).collect(),
                class_dropped: match model {
                    PathModel::Classes(_) => image.stats.class_share.dropped(),
                    _ => None,
                },
                secondary_ray_ratio: image.stats.counters.secondary_rays as f64
                    / full.stats.counters.secondary_rays.max(1) as f64,
                seconds: image.stats.seconds,
                terms: terms_carrying_light(&world, &hits, model),
            });
        }
    }
    say_tables(&references, &rows);
    let report = BenchReport {
        width: args.width,
        height: args.height,
        supersampling: args.supersampling,
        references,
        rows,
        rings: RINGS.iter().map(|&(a, b)| [a, b]).collect(),
    };
    crate::common::report(&report, args.report.as_deref())
}

/// The tables on stdout.
fn say_tables(references: &[Reference], rows: &[Row]) {
    say!(
        "the full ray tree's convergence (k×k against 2k×2k, lens pixels, display sRGB), and the classes that carry the lens objects' light (share of Σ F·G at the pixel centres):"
    );
    for r in references {
        say!(
            "  {:<14} {:>6} lens pixels  {:>6.2} dB  ({:.2} s)  {}",
            r.scene,
            r.lens_pixels,
            r.convergence_psnr_srgb_db,
            r.seconds,
            r.ranked_classes
                .iter()
                .map(|(class, share)| format!("{class} {:.1} %", 100.0 * share))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    say!();
    say!("models against the full ray tree (lens pixels; radiance ratios model / full tree):");
    say!(
        "{:<14} {:<22} {:>6} {:>9} {:>9} {:>7} {:>7} {:>7} {:>9} {:>9}",
        "scene",
        "tree",
        "terms",
        "sRGB dB",
        "lin dB",
        "ratio",
        "r<0.5",
        "r>0.95",
        "dropped",
        "2nd rays"
    );
    let cell = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.3}"));
    for r in rows {
        say!(
            "{:<14} {:<22} {:>6} {:>9.2} {:>9.2} {:>7.3} {:>7} {:>7} {:>9} {:>9.2}",
            r.scene,
            r.tree.name(),
            r.terms,
            r.lens_psnr_srgb_db,
            r.lens_psnr_linear_db,
            r.radiance_ratio,
            cell(r.ring_ratios[0]),
            cell(r.ring_ratios[RINGS.len() - 1]),
            r.class_dropped
                .map_or_else(|| "-".to_owned(), |d| format!("{:.2} %", 100.0 * d)),
            r.secondary_ray_ratio
        );
    }
}
