//! `lensmap passes`: the compositor's pass plans for pass-count and blending-mode experiments,
//! built from a frame's shape alone (no data, no GPU).

use clap::Args;
use lensmap::hybrid::gpu::{Texgen, planned_part};
use lensmap::options::Worded;
use lensmap::render::{
    BlendScheme, Compositing, FrameShape, Output, PassCategory, PlanOptions, SinglePassLimits,
    TargetFormat, Variant, plan::frame_graph,
};
use lensmap::trace::classes::ClassSet;
use lensmap::trace::{Interface, Term};
use serde_json::json;

use crate::common::{BadUsage, BlendArg, FormatArg, VariantArg, report, voice};
use crate::words::Flags;

#[derive(Args)]
#[command(
    after_help = "Example:\n  lensmap passes --layers 3 --viewpoints 2 --terms greedy --variant multipass --format rgba8\n  lensmap passes --layers 2 --viewpoints 1 --terms R,TT,TRT,TRRT\n  lensmap passes --variant single-pass --gpu-parts 2"
)]
pub struct PassesArgs {
    /// Layers n per viewpoint sample.
    /// Range: [1, 256].
    #[arg(long, default_value_t = 3)]
    layers: usize,
    /// Viewpoint samples blended: 1 when the camera sits on a sample, 2 between two (on a circle,
    /// or on an edge of a 2D view space's triangle), 3 inside a spherical triangle.
    /// Range: [1, 3].
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=3))]
    viewpoints: u8,
    /// Shading terms per lens object: `greedy` (the papers' two terms, refraction and
    /// reflection), `mirror` (a mirror's one greedy term, reflection), a count N of path classes (the first N
    /// of R, TT, TRT, TR²T, …), a list such as `R,TT,TRT,TRRT`, or `greedy:D` (the ray tree
    /// expanded to D events, greedy below). Each term is a group of V·n layer passes; the single
    /// pass takes the greedy terms (`greedy`, `mirror`) only.
    #[arg(long, default_value = "greedy", value_parser = parse_terms)]
    terms: Terms,
    /// Compositor variant.
    #[arg(long, value_enum, default_value = "multipass")]
    variant: VariantArg,
    /// How the multipass variant combines layers and groups.
    #[arg(long, value_enum, default_value = "front-to-back")]
    blend: BlendArg,
    /// Framebuffer format.
    #[arg(long, value_enum, default_value = "rgba8")]
    format: FormatArg,
    /// The lens object is tessellated on the GPU (`--tracer gpu`) from this many scene objects,
    /// at the default depth cap: the frame opens with every dispatch and barrier of their
    /// tessellations, texgen and draw lists, which the lens passes wait for; 0 for a lens object
    /// traced on the CPU.
    /// Range: [0, 16].
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=16))]
    gpu_parts: u8,
    /// Glossy objects drawn by reflection-space IBR (the glossy pass after the environment,
    /// one draw each).
    /// Range: [0, 16].
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=16))]
    glossy: u8,
}

/// A lens object's shading terms as `--terms` gives them.
#[derive(Clone, Debug)]
struct Terms {
    terms: Vec<Term>,
}

/// Reads `--terms`: `greedy` (glass's two terms), `mirror` (a mirror's greedy reflection), or a path-class set ([`ClassSet::parse`]), whose terms are glass's.
fn parse_terms(text: &str) -> Result<Terms, String> {
    match text.trim() {
        "greedy" => {
            return Ok(Terms {
                terms: vec![Term::Refraction, Term::Reflection],
            });
        }
        "mirror" => {
            return Ok(Terms {
                terms: vec![Term::Reflection],
            });
        }
        _ => {}
    }
    let set = ClassSet::parse(text)
        .map_err(|problem| format!("{problem}; or give greedy (glass) or mirror"))?;
    let glass = Interface::Dielectric {
        ior: 1.5,
        absorption: glam::DVec3::ONE,
    };
    let mut terms: Vec<Term> = set.terms(glass).into_iter().map(Term::Class).collect();
    terms.sort();
    Ok(Terms { terms })
}

/// Prints the plan of one lens object's frame.
pub fn run(args: PassesArgs) -> anyhow::Result<()> {
    let terms = &args.terms.terms;
    if !(1..=FrameShape::MAX_EXPERIMENT_LAYERS).contains(&args.layers) {
        return Err(BadUsage(format!(
            "--layers {}: give 1 to {} layers per viewpoint sample",
            args.layers,
            FrameShape::MAX_EXPERIMENT_LAYERS
        ))
        .into());
    }
    let mut shape = FrameShape::synthetic(640, 480, args.layers, args.viewpoints as usize, terms);
    let levels = lensmap::hybrid::tessellate::DEFAULT_MAX_DEPTH + 1;
    for lens in &mut shape.lenses {
        lens.parts = (0..usize::from(args.gpu_parts))
            .map(|object| {
                let name = format!("object{object} output0");
                planned_part(&name, object, levels, Texgen::On)
            })
            .collect();
    }
    shape.glossy = (0..args.glossy).map(|g| format!("glossy{g}")).collect();
    let format = TargetFormat::from(args.format);
    let compositing = Compositing::new(Variant::from(args.variant), BlendScheme::from(args.blend))
        .map_err(|error| BadUsage(error.worded(&Flags)))?;
    let options = PlanOptions {
        compositing,
        format,
        output: Output::Readback,
        single_pass: SinglePassLimits::COMPILED,
    };
    let (graph, _) = frame_graph(&shape, &options).map_err(|error| {
        let names: Vec<String> = terms.iter().map(|term| term.name()).collect();
        BadUsage(format!(
            "--layers {} --terms {}: {error}",
            args.layers,
            names.join(",")
        ))
    })?;
    if crate::common::validate_only() {
        return Ok(());
    }
    let plan = graph.compile()?;
    let counts = json!({
        "tessellation": plan.count(PassCategory::Tessellation),
        "prime": plan.count(PassCategory::Prime),
        "layer": plan.count(PassCategory::Layer),
        "alpha_clear": plan.count(PassCategory::AlphaClear),
        "scratch_clear": plan.count(PassCategory::ScratchClear),
        "group_sum": plan.count(PassCategory::GroupSum),
        "single_pass": plan.count(PassCategory::SinglePass),
        "environment": plan.count(PassCategory::Environment),
        "rendering_instances": plan.rendering_instances(),
        "barriers": plan.barrier_count(),
    });
    if voice().json {
        let steps: Vec<_> = plan
            .steps
            .iter()
            .map(|s| {
                let key = s.pass.pipeline_key(&plan.images);
                json!({
                    "pass": s.pass.name,
                    "category": s.pass.category.name(),
                    "draws": s.pass.draw_count(),
                    "blend": key.map(|k| k.blend.to_string()),
                    "write_mask": key.map(|k| k.write_mask.to_string()),
                    "barriers": s.barriers.len() + s.buffer_barriers.len(),
                })
            })
            .collect();
        let out = json!({
            "layers": args.layers, "viewpoints": args.viewpoints, "terms": args.terms.terms,
            "variant": compositing.variant().name(), "blend": compositing.blend().name(), "format": format.name(), "counts": counts, "steps": steps,
            "culled": plan.culled.iter().map(|(n, r)| json!({"pass": n, "reason": r.to_string()})).collect::<Vec<_>>(),
        });
        report(&out, None)?;
    } else {
        say!("{}", plan.to_string().trim_end_matches('\n'));
        say!(
            "{} ({}) lens passes: {}{} prime + {} layer + {} alpha clear + {} scratch clear + {} group sum + {} single-pass; {} rendering instance(s), {} barrier(s)",
            compositing.variant().name(),
            compositing.blend().name(),
            match plan.count(PassCategory::Tessellation) {
                0 => String::new(),
                n => format!("{n} tessellation (compute) + "),
            },
            counts["prime"],
            counts["layer"],
            counts["alpha_clear"],
            counts["scratch_clear"],
            counts["group_sum"],
            counts["single_pass"],
            counts["rendering_instances"],
            counts["barriers"]
        );
    }
    Ok(())
}
