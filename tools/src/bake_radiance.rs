//! `lensmap bake --radiance-maps`: the glossy objects' radiance environment maps at every view
//! sample of their geodesic view space (reflection-space IBR), per sample, resumable and
//! shardable like the layered bake; `--merge` joins shards.

use std::path::Path;
use std::time::Instant;

use lensmap::rsibr::bake::{RadianceManifest, RadianceStaging, SampleRecord, merge};
use lensmap::rsibr::maps::sample_maps;
use lensmap::rsibr::{GlossyViews, RadianceMapOptions, glossy_objects};
use lensmap::trace::TraceScene;
use lensmap_baker::bake::{parse_samples, parse_shard, shard_samples};
use serde_json::json;

use crate::bake::BakeArgs;
use crate::common::{BadUsage, report};

/// The largest face size of a radiance map (`--map-size`): 6 × 1024² texels, 24 MB per lobe.
pub const MAX_MAP_SIZE: u32 = 1024;

/// The map options the arguments ask for.
fn options(args: &BakeArgs) -> anyhow::Result<RadianceMapOptions> {
    if GlossyViews::geodesic(args.views).is_none() {
        return Err(BadUsage(format!(
            "--views {}: give a geodesic count, one of {:?}",
            args.views,
            &lensmap::rsibr::views::GEODESIC_COUNTS[..3]
        ))
        .into());
    }
    if !(1..=MAX_MAP_SIZE).contains(&args.map_size) || args.map_samples < 2 {
        return Err(BadUsage(format!(
            "--map-size {} --map-samples {}: give a face size in [1, 1024] and at least 2 samples per texel",
            args.map_size, args.map_samples
        ))
        .into());
    }
    Ok(RadianceMapOptions {
        size: args.map_size,
        samples: args.map_samples,
        seed: args.map_seed,
        views: args.views,
    })
}

/// Runs `lensmap bake --radiance-maps`.
pub fn run(args: &BakeArgs, out: &Path) -> anyhow::Result<()> {
    if !args.merge.is_empty() {
        if crate::common::validate_only() {
            return Ok(());
        }
        let manifest = merge(&args.merge, out)?;
        let samples: Vec<usize> = manifest.samples.iter().map(|r| r.sample).collect();
        report(
            &json!({ "out": out, "merged": args.merge, "samples": samples }),
            None,
        )?;
        crate::bake::say_merged(args, out, &samples);
        return Ok(());
    }
    let Some(scene_name) = &args.scene else {
        return Err(BadUsage("--scene: name the scene, e.g. --scene glossy-studio".into()).into());
    };
    let options = options(args)?;
    let scene = crate::common::load_scene(scene_name)?;
    let objects = glossy_objects(&scene);
    if objects.is_empty() {
        return Err(BadUsage(format!(
            "--radiance-maps: scene \"{}\" has no glossy object; give a scene with `glossy` materials, e.g. glossy-studio",
            scene.name
        ))
        .into());
    }
    let views = GlossyViews::geodesic(options.views).expect("checked above");
    let mut samples = parse_samples(&args.samples, views.directions().len(), &scene.name)?;
    if let Some(spec) = &args.shard {
        samples = shard_samples(&samples, parse_shard(spec)?);
    }
    if crate::common::validate_only() {
        return Ok(());
    }
    let template = RadianceManifest::template(&scene, &options);
    let staging = RadianceStaging::open(out, template.identity.clone(), args.resume)?;
    if let Some(staging) = RadianceStaging::path_of(out) {
        crate::interrupt::stop_on_signals(crate::interrupt::Interruptible {
            out: out.to_owned(),
            staging,
        })?;
    }
    let trace = TraceScene::new(&scene)?;
    let (mut baked, mut resumed) = (Vec::new(), Vec::new());
    for &sample in &samples {
        if staging.is_complete(sample) {
            resumed.push(sample);
            continue;
        }
        let start = Instant::now();
        let view = views.directions()[sample];
        let mut maps = Vec::with_capacity(objects.len());
        let (mut max_error, mut rms_error, mut rays) = (Vec::new(), Vec::new(), 0);
        for object in &objects {
            let (lobes, counters) = sample_maps(&trace, object, sample, view, &options);
            rays += counters.all_rays();
            let (mut max, mut squares, mut count) = (0f32, 0f64, 0usize);
            for lobe in &lobes {
                for (face, errors) in lobe.map.levels[0].iter().zip(&lobe.errors) {
                    for (texel, error) in face.iter().zip(errors) {
                        if texel[3] > 0.0 {
                            max = max.max(*error);
                            squares += f64::from(*error).powi(2);
                            count += 1;
                        }
                    }
                }
            }
            max_error.push(max);
            rms_error.push((squares / count.max(1) as f64).sqrt() as f32);
            maps.push(
                lobes
                    .into_iter()
                    .map(|m| std::sync::Arc::new(m.map))
                    .collect::<Vec<_>>(),
            );
        }
        let record = SampleRecord {
            sample,
            max_standard_error: max_error,
            rms_standard_error: rms_error,
            rays,
            seconds: start.elapsed().as_secs_f64(),
            device: None,
        };
        staging.write_sample(&objects, &maps, &record)?;
        say!(
            "  sample {sample}: {:.1} s, {} rays, texel standard error rms {:?} (max {:?})",
            record.seconds,
            record.rays,
            record.rms_standard_error,
            record.max_standard_error
        );
        baked.push(sample);
    }
    let manifest = staging.commit(&template)?;
    let complete: Vec<usize> = manifest.samples.iter().map(|r| r.sample).collect();
    report(
        &json!({
            "scene": scene.name,
            "out": out,
            "views": options.views,
            "map_size": manifest.size,
            "samples_per_texel": options.samples,
            "baked": baked,
            "resumed": resumed,
            "complete": complete,
            "objects": manifest.objects,
        }),
        None,
    )?;
    say!(
        "{}: radiance maps of {} glossy object(s) at {} of {} view samples in {} ({} baked now, {} resumed), {}² texels, {} samples per texel",
        scene.name,
        objects.len(),
        complete.len(),
        options.views,
        out.display(),
        baked.len(),
        resumed.len(),
        manifest.size,
        options.samples
    );
    Ok(())
}
