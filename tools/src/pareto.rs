//! The Pareto plot of `lensmap bench error`: frame time (log scale) against lens PSNR, one colour
//! per series, the frontier as a line, the default ringed, drawn once by plotters into an SVG and
//! into an RGB buffer that the `image` crate encodes as a PNG. Both measure their labels with a
//! TrueType font (DejaVu Sans, Debian's `fonts-dejavu-core`); without one no plot is written, with
//! a warning.

use std::path::Path;

use anyhow::Context;
use plotters::coord::Shift;
use plotters::prelude::*;

/// One point as the plot shows it.
#[derive(Clone, Debug)]
pub struct PlotPoint {
    /// Its series (colour and legend entry).
    pub series: String,
    /// Frame time, ms.
    pub x_ms: f64,
    /// Lens PSNR, dB.
    pub y_db: f64,
    /// On the Pareto frontier.
    pub frontier: bool,
    /// The default setting.
    pub default: bool,
}

const SIZE: (u32, u32) = (1024, 680);

/// Distinct, saturated colours for the series (Tableau's ten, then darker ones).
const COLOURS: [RGBColor; 14] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 128),
    RGBColor(128, 0, 0),
    RGBColor(0, 100, 0),
    RGBColor(90, 90, 0),
];

/// The baselines' colours (triangles): black, crimson, navy.
const BASELINE_COLOURS: [RGBColor; 3] = [
    RGBColor(0, 0, 0),
    RGBColor(200, 0, 60),
    RGBColor(0, 60, 200),
];

/// Where the PNG's font is looked for.
const FONTS: [&str; 2] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
];

/// Registers the labels' font with plotters once per process; false when there is none.
fn font_registered() -> bool {
    static REGISTERED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *REGISTERED.get_or_init(|| {
        let Some(font) = FONTS.iter().find_map(|path| std::fs::read(path).ok()) else {
            return false;
        };
        // plotters keeps registered fonts for the process: the bytes live as long.
        let font: &'static [u8] = Box::leak(font.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, font).is_ok()
    })
}

/// Writes `pareto.svg` and `pareto.png` into `dir`; without a font for the labels (both
/// backends measure text with it), warns and writes neither.
pub fn write(dir: &Path, points: &[PlotPoint], scene: &str, device: &str) -> anyhow::Result<()> {
    if !font_registered() {
        warn!(
            "no DejaVu Sans font ({}): no plot written; install fonts-dejavu-core",
            FONTS[0]
        );
        return Ok(());
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let title = format!("{scene}: frame time against lens error ({device})");
    let svg_path = dir.join("pareto.svg");
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        draw(&root, points, &title).map_err(|e| anyhow::anyhow!("drawing the SVG: {e}"))?;
        root.present()
            .map_err(|e| anyhow::anyhow!("drawing the SVG: {e}"))?;
    }
    lensmap::atomic::write_atomically(&svg_path, svg.as_bytes())
        .with_context(|| format!("writing {}", svg_path.display()))?;
    let mut rgb = vec![255u8; (SIZE.0 * SIZE.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        draw(&root, points, &title).map_err(|e| anyhow::anyhow!("drawing the PNG: {e}"))?;
        root.present()
            .map_err(|e| anyhow::anyhow!("drawing the PNG: {e}"))?;
    }
    let image = image::RgbImage::from_raw(SIZE.0, SIZE.1, rgb).context("the plot's pixels")?;
    let mut png = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut png, image::ImageFormat::Png)
        .context("encoding the PNG")?;
    let png_path = dir.join("pareto.png");
    lensmap::atomic::write_atomically(&png_path, png.get_ref())
        .with_context(|| format!("writing {}", png_path.display()))
}

/// The plot on any plotters backend.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    points: &[PlotPoint],
    title: &str,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let (x_low, x_high) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
        (lo.min(p.x_ms), hi.max(p.x_ms))
    });
    let (y_low, y_high) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| {
        (lo.min(p.y_db), hi.max(p.y_db))
    });
    let mut chart = ChartBuilder::on(root)
        .caption(title, ("sans-serif", 20))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(64)
        .build_cartesian_2d(
            ((x_low * 0.8).max(1e-3)..x_high * 1.25).log_scale(),
            (y_low - 1.0)..(y_high + 1.0),
        )?;
    chart
        .configure_mesh()
        .x_labels(16)
        .x_label_formatter(&|ms| format!("{ms:.0}"))
        .x_desc("frame time, ms (log scale; mean over the cameras of each camera's median)")
        .y_desc("lens PSNR, dB (display sRGB)")
        .label_style(("sans-serif", 14))
        .draw()?;

    let mut series: Vec<&str> = Vec::new();
    for p in points {
        if !series.contains(&p.series.as_str()) {
            series.push(&p.series);
        }
    }
    let (mut plain, mut baselines) = (0, 0);
    for name in &series {
        let baseline = name.starts_with("baseline");
        let colour = if baseline {
            baselines += 1;
            BASELINE_COLOURS[(baselines - 1) % BASELINE_COLOURS.len()]
        } else {
            plain += 1;
            COLOURS[(plain - 1) % COLOURS.len()]
        };
        let members: Vec<(f64, f64)> = points
            .iter()
            .filter(|p| p.series == *name)
            .map(|p| (p.x_ms, p.y_db))
            .collect();
        chart
            .draw_series(members.iter().map(|&(x, y)| {
                if baseline {
                    TriangleMarker::new((x, y), 9, colour.filled()).into_dyn()
                } else {
                    Circle::new((x, y), 5, colour.filled()).into_dyn()
                }
            }))?
            .label(*name)
            .legend(move |(x, y)| {
                if baseline {
                    TriangleMarker::new((x + 8, y), 7, colour.filled()).into_dyn()
                } else {
                    Circle::new((x + 8, y), 5, colour.filled()).into_dyn()
                }
            });
    }
    let mut frontier: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.frontier)
        .map(|p| (p.x_ms, p.y_db))
        .collect();
    frontier.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart
        .draw_series(LineSeries::new(frontier, BLACK.stroke_width(2)))?
        .label("Pareto frontier")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLACK.stroke_width(2)));
    if let Some(default) = points.iter().find(|p| p.default) {
        chart
            .draw_series(std::iter::once(Circle::new(
                (default.x_ms, default.y_db),
                11,
                BLACK.stroke_width(2),
            )))?
            .label("the default (lensmap render)")
            .legend(|(x, y)| Circle::new((x + 8, y), 6, BLACK.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .draw()?;
    Ok(())
}
