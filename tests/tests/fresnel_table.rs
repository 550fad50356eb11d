//! Schlick through the 1D table (`HybridOptions::fresnel`) in a whole frame, against exact
//! Fresnel: on mirror-teapot the tessellation cannot tell the two apart (a mirror always
//! reflects, and the split test looks at topology and directions, never at F·G), so the frames
//! share every vertex, and each vertex's F·G and each lens pixel may move only as far as the
//! table's derived error bound allows. GPU work runs with validation on.

use lensmap::hybrid::FrameBuilder;
use lensmap::hybrid::{FresnelModel, HybridOptions};
use lensmap::render::Compositing;
use lensmap::render::Renderer;
use lensmap::trace::schlick_table::SchlickTable;
use lensmap_tests::{assert_clean, fixtures, gpu, render_rgba32f};

/// mirror-teapot's silver: R₀ = 0.95 on every channel.
const SILVER: f32 = 0.95;

/// Per vertex, one path of `k` mirror bounces has F = ∏ Fᵢ with each Fᵢ in [R₀, 1] and its
/// table value off by at most (1 − R₀)·E (E: the table's bound), so
/// |∏ F̃ᵢ − ∏ Fᵢ| ≤ Σ |F̃ᵢ − Fᵢ| ≤ k·(1 − R₀)·E, k at most the greedy cap of 16 interfaces. A lens
/// pixel is the interpolated F·G times the filtered radiance (one term: a mirror has no
/// refraction), so its change is at most the largest relative change of F·G at a vertex of its
/// triangle times its exact value.
#[test]
fn mirror_teapot_with_the_table_stays_within_the_bound_of_exact_fresnel() {
    let scene = fixtures::built_in_scene("mirror-teapot", 64, 48, 1);
    let camera = scene.camera;
    let hybrid = fixtures::with_projected_ems(scene, 16);
    let texels = 16;
    let bound = SchlickTable::new(texels).expect("in range").error_bound();
    let exact_options = HybridOptions::with_t(4.0);
    let table_options = HybridOptions {
        fresnel: FresnelModel::Table { texels },
        ..exact_options
    };
    let (exact, _) = FrameBuilder::new()
        .frame(&hybrid, &camera, &exact_options)
        .expect("exact frame");
    let (table, _) = FrameBuilder::new()
        .frame(&hybrid, &camera, &table_options)
        .expect("table frame");

    let mut largest = 0.0f64;
    let mut largest_relative = 0.0f64;
    let mut vertices = 0;
    let mut within_one_bounce = 0;
    for (a, b) in exact.lenses.iter().zip(&table.lenses) {
        assert_eq!(
            a.positions, b.positions,
            "{}: the tessellation moved",
            a.name
        );
        assert_eq!(a.triangles, b.triangles, "{}", a.name);
        for (ta, tb) in a.terms.iter().zip(&b.terms) {
            assert_eq!(ta.directions, tb.directions, "{}: directions moved", a.name);
            for (fa, fb) in ta.fg.iter().zip(&tb.fg) {
                vertices += 1;
                let difference = f64::from((*fa - *fb).abs().max_element());
                // (1 − c)⁵ is convex, so its linear interpolant lies above it: every factor,
                // and so every product, is at least the exact one (to the f32 rounding of F·G).
                assert!(
                    fb.cmpge(*fa - 1e-6).all(),
                    "{}: the table's F·G {fb} is below the exact {fa}",
                    a.name
                );
                within_one_bounce += usize::from(
                    f64::from((*fa - *fb).abs().max_element())
                        <= f64::from(1.0 - SILVER) * bound + 1e-7,
                );
                largest = largest.max(difference);
                if fa.min_element() > 0.0 {
                    largest_relative =
                        largest_relative.max(f64::from(((*fa - *fb).abs() / *fa).max_element()));
                }
            }
        }
    }
    let per_bounce = f64::from(1.0 - SILVER) * bound;
    eprintln!(
        "{vertices} vertex terms: F·G moved by ≤ {largest:.3e} (one bounce's bound {per_bounce:.3e}; {within_one_bounce} within it), relatively ≤ {largest_relative:.3e}"
    );
    // Measured at 64×48, N = 16: 4658 vertex terms, F·G up by at most 2.9e-3, 5.2 bounces'
    // bound: grazing paths that bounce several times (each factor near grazing incidence is
    // off by nearly the whole bound, all the same way).
    assert!(vertices > 100, "too few lens vertices: {vertices}");
    // Each factor and F·G are stored in f32 on the way to the GPU: half an ulp of 1 each.
    assert!(
        largest <= 16.0 * per_bounce + 1e-7,
        "F·G moved by {largest:e}, over 16 bounces' bound"
    );
    assert!(largest > 0.0, "the table changed nothing");

    let device = gpu();
    let mut renderer = Renderer::new(&device).expect("a renderer");
    let images = [&exact, &table].map(|frame| {
        let mut uploaded = renderer.upload(&device, frame).expect("uploads");
        render_rgba32f(
            &mut renderer,
            &device,
            &mut uploaded,
            Compositing::SinglePass,
        )
    });
    assert_eq!(images[0].pixels.len(), images[1].pixels.len());
    let [exact_image, table_image] = &images;
    let mut lens_pixels = 0;
    for (pa, pb) in exact_image.pixels.iter().zip(&table_image.pixels) {
        for c in 0..3 {
            let allowed = largest_relative * f64::from(pa[c]) * (1.0 + 1e-4) + 1e-6;
            assert!(
                f64::from((pa[c] - pb[c]).abs()) <= allowed,
                "a pixel moved from {pa:?} to {pb:?}, over {allowed:e}"
            );
        }
        lens_pixels += usize::from(pa != pb);
    }
    assert!(lens_pixels > 0, "no pixel changed");
    assert_clean(&device);
}
