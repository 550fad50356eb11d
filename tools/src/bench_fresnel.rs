//! `lensmap bench fresnel`: the largest error of Schlick through the 1D table over incidence
//! 0–90°, per table size, for each lens material of the scenes asked for: against the table's
//! derived bound, against Schlick evaluated exactly (mirrors and glass), and for glass against
//! exact dielectric Fresnel entering and leaving the glass, beside Schlick's own error there.
//! Then the cost of one Fresnel evaluation, exact against the table, alternating runs. No GPU:
//! the numbers are the per-vertex arithmetic's.

use std::path::PathBuf;

use lensmap::runner::median;
use lensmap::scene::{Material, Scene};
use lensmap::trace::path::Interface;
use lensmap::trace::schlick_table::{
    FresnelModel, InterfaceErrors, SchlickTable, interface_errors, interpolation_error,
};
use serde_json::json;

use crate::common::{BadUsage, report};

/// Arguments of `lensmap bench fresnel`.
#[derive(clap::Args, Debug, Clone)]
#[command(
    after_help = "Example:\n  lensmap bench fresnel --scene mirror-teapot --scene glass-sphere --texels 16,32,64,256"
)]
pub struct BenchFresnelArgs {
    /// Built-in scene name or path; repeat for several. Each distinct lens material is measured.
    #[arg(long, default_values_t = ["mirror-teapot".to_owned(), "glass-sphere".to_owned()])]
    pub scene: Vec<String>,
    /// Table sizes, texels, comma-separated.
    /// Range: [2, 4096].
    #[arg(long, value_delimiter = ',', default_values_t = [16, 32, 64, 256])]
    pub texels: Vec<u32>,
    /// Incidence cosines sampled over 0–90°, uniform in the angle and as many again uniform in
    /// the cosine.
    /// Range: [2, 16777216].
    #[arg(long, default_value_t = 1 << 18)]
    pub samples: u32,
    /// Also write the JSON results to this file (--json prints them on stdout).
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
}

/// The lens materials of `scene`, each once, named by their material.
fn lens_interfaces(scene: &Scene) -> Vec<(String, Interface)> {
    let mut seen: Vec<(String, Interface)> = Vec::new();
    for object in &scene.objects {
        let interface = match &scene.materials[object.material] {
            Material::Glass { ior, absorption } => Interface::Dielectric {
                ior: f64::from(*ior),
                absorption: absorption.as_dvec3(),
            },
            Material::Mirror { reflectance } => Interface::Mirror {
                reflectance: reflectance.as_dvec3(),
            },
            Material::Diffuse { .. } | Material::Glossy(_) => continue,
        };
        if !seen.iter().any(|(_, known)| *known == interface) {
            seen.push((format!("{}:{}", scene.name, describe(interface)), interface));
        }
    }
    seen
}

/// `R0 = (r, g, b)` or `IOR n`.
fn describe(interface: Interface) -> String {
    match interface {
        // The scene's values are f32: shown as written, not as their f64 widening.
        Interface::Mirror { reflectance: r } => {
            format!("mirror R0=({},{},{})", r.x as f32, r.y as f32, r.z as f32)
        }
        Interface::Dielectric { ior, .. } => format!("glass IOR {}", ior as f32),
    }
}

pub fn run(args: BenchFresnelArgs) -> anyhow::Result<()> {
    let mut tables = Vec::new();
    for &texels in &args.texels {
        let table = FresnelModel::Table { texels }
            .table()
            .map_err(|_| {
                use lensmap::trace::schlick_table::{MAX_TEXELS, MIN_TEXELS};
                BadUsage(format!(
                    "--texels {texels}: give table sizes of {MIN_TEXELS} to {MAX_TEXELS} texels"
                ))
            })?
            .ok_or_else(|| anyhow::anyhow!("a table model has a table"))?;
        tables.push(table);
    }
    let mut materials = Vec::new();
    for name in &args.scene {
        materials.extend(lens_interfaces(&crate::common::load_scene(name)?));
    }
    if crate::common::validate_only() {
        return Ok(());
    }
    say!(
        "{:>6} {:>10} {:>10} {:>10}   largest error over 0–90° of (1 − cos θ)⁵ through the table",
        "texels",
        "bound",
        "measured",
        "ratio"
    );
    let mut rows = Vec::new();
    for table in &tables {
        let measured = interpolation_error(table, args.samples);
        let bound = table.error_bound();
        say!(
            "{:>6} {bound:>10.3e} {measured:>10.3e} {:>10.4}",
            table.texels().len(),
            measured / bound
        );
        rows.push(json!({
            "texels": table.texels().len(), "bound": bound, "least_attained": table.error_attained(),
            "measured": measured, "materials": materials.iter().map(|(name, interface)| {
                let errors = interface_errors(table, *interface, args.samples);
                json!({ "material": name, "errors": errors })
            }).collect::<Vec<_>>(),
        }));
    }
    for (name, interface) in &materials {
        print_material(name, &tables, *interface, args.samples);
    }
    let timings = evaluation_costs(&tables, &materials);
    report(
        &json!({ "samples": args.samples, "tables": rows, "ns_per_evaluation": timings }),
        args.report.as_deref(),
    )?;
    Ok(())
}

/// Evaluations per timed run of [`evaluation_costs`].
const EVALUATIONS: u32 = 1 << 20;

/// Runs per setting of [`evaluation_costs`]; the median counts.
const RUNS: usize = 15;

/// Nanoseconds per Fresnel evaluation at each material, exact and through each table, over
/// cosines spread over 0–90° (what a frame's vertices see): medians of [`RUNS`] runs of
/// [`EVALUATIONS`] each, the settings taking turns run by run; printed and as JSON.
fn evaluation_costs(
    tables: &[SchlickTable],
    materials: &[(String, Interface)],
) -> serde_json::Value {
    let mut out = Vec::new();
    for (name, interface) in materials {
        // The settings: exact (None), then each table.
        let settings: Vec<Option<&SchlickTable>> = std::iter::once(None)
            .chain(tables.iter().map(Some))
            .collect();
        let mut times = vec![Vec::new(); settings.len()];
        for _ in 0..RUNS {
            for (slot, table) in settings.iter().enumerate() {
                let start = std::time::Instant::now();
                let mut sum = 0.0;
                for k in 0..EVALUATIONS {
                    let c = std::hint::black_box((f64::from(k) + 0.5) / f64::from(EVALUATIONS));
                    sum += evaluate(*interface, *table, c);
                }
                std::hint::black_box(sum);
                times[slot].push(start.elapsed().as_secs_f64() * 1e9 / f64::from(EVALUATIONS));
            }
        }
        let medians: Vec<f64> = times.iter_mut().map(|t| median(t)).collect();
        say!(
            "{name}: ns per evaluation, exact {:.2}; {}",
            medians[0],
            tables
                .iter()
                .zip(&medians[1..])
                .map(|(t, ns)| format!("table:{} {ns:.2}", t.texels().len()))
                .collect::<Vec<_>>()
                .join(", ")
        );
        out.push(json!({ "material": name, "exact": medians[0],
            "tables": tables.iter().zip(&medians[1..]).map(|(t, ns)| json!({"texels": t.texels().len(), "ns": ns})).collect::<Vec<_>>() }));
    }
    json!(out)
}

/// One Fresnel evaluation at `interface` for light arriving at cosine `c` (from outside), as the
/// per-vertex paths do it: exact (`None`) or through `table`; the largest channel.
fn evaluate(interface: Interface, table: Option<&SchlickTable>, c: f64) -> f64 {
    match (interface, table) {
        (Interface::Mirror { reflectance }, None) => {
            lensmap::trace::fresnel::schlick(reflectance, c).max_element()
        }
        (Interface::Mirror { reflectance }, Some(table)) => {
            lensmap::trace::fresnel::schlick_by(reflectance, c, |x| table.fifth_power(x))
                .max_element()
        }
        (Interface::Dielectric { ior, .. }, None) => {
            lensmap::trace::fresnel::dielectric(c, 1.0, ior).reflectance
        }
        (Interface::Dielectric { ior, .. }, Some(table)) => {
            lensmap::trace::fresnel::dielectric_schlick(c, 1.0, ior, |x| table.fifth_power(x))
                .reflectance
        }
    }
}

/// One material's table: per size, the largest error against each reference.
fn print_material(name: &str, tables: &[SchlickTable], interface: Interface, samples: u32) {
    say!("\n{name}");
    let glass = matches!(interface, Interface::Dielectric { .. });
    if glass {
        say!(
            "{:>6} {:>12} {:>14} {:>14} {:>16} {:>16}",
            "texels",
            "vs Schlick",
            "vs exact, in",
            "vs exact, out",
            "Schlick alone in",
            "Schlick alone out"
        );
    } else {
        say!("{:>6} {:>12}", "texels", "vs Schlick");
    }
    for table in tables {
        let InterfaceErrors {
            against_schlick,
            against_dielectric,
            schlick_against_dielectric,
        } = interface_errors(table, interface, samples);
        match (against_dielectric, schlick_against_dielectric) {
            (Some([table_in, table_out]), Some([alone_in, alone_out])) => say!(
                "{:>6} {against_schlick:>12.3e} {table_in:>14.3e} {table_out:>14.3e} {alone_in:>16.3e} {alone_out:>16.3e}",
                table.texels().len()
            ),
            _ => say!("{:>6} {against_schlick:>12.3e}", table.texels().len()),
        }
    }
}
