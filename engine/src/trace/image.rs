//! Reference images: the film, the supersampled render loop and the EXR/PNG output.
//!
//! Every pixel is the box-filtered mean of a fixed k×k stratified grid of supersamples (subsample
//! `(i, j)` of pixel `(x, y)` sits at `(x + (i + ½)/k, y + (j + ½)/k)`), summed in a fixed order
//! in f64. Rows are rendered in parallel on the current rayon pool; each pixel depends on nothing
//! but its own samples, so the output is bit-identical whatever the thread count.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::lens_pixels::{LensPixels, PixelCover};
use super::shade::{ClassShare, TraceOptions};
use super::stats::{RenderStats, TraceCounters};
use super::world::TraceScene;
use super::{Ray, TraceError};
use crate::scene::Camera;

/// A rendered reference image with its two term images and lens mask (linear radiance,
/// row-major, top row first).
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Final radiance per pixel (`T·F_T·G_T + R·F_R·G_R` on lens objects, the environment
    /// elsewhere), linear, ≥ 0, finite.
    pub radiance: Vec<Vec3>,
    /// The refraction term `T·F_T·G_T` per pixel (0 where no lens object is seen).
    pub refraction: Vec<Vec3>,
    /// The reflection term `R·F_R·G_R` per pixel (0 where no lens object is seen).
    pub reflection: Vec<Vec3>,
    /// Fraction of each pixel's supersamples whose camera ray hits a lens object first, in [0, 1].
    pub lens_mask: Vec<f32>,
    /// Which lens object each pixel shows, by the rule every lens-error figure uses (see
    /// [`super::lens_pixels`]).
    pub lens_pixels: LensPixels,
    /// The Monte Carlo standard error of each pixel's `radiance` (root mean square over channels),
    /// from its subsamples that meet a glossy surface first ([`super::glossy`]); 0 elsewhere,
    /// and where one sample per ray gives no estimate of it.
    pub glossy_error: Vec<f32>,
    /// Fraction of each pixel's subsamples whose camera ray meets a glossy surface first.
    pub glossy_mask: Vec<f32>,
    /// Work and time of the render.
    pub stats: RenderStats,
}

/// The per-pixel sums of one image row.
struct Row {
    glossy_error: Vec<f32>,
    glossy_mask: Vec<f32>,
    radiance: Vec<Vec3>,
    refraction: Vec<Vec3>,
    reflection: Vec<Vec3>,
    lens_mask: Vec<f32>,
    covers: Vec<PixelCover>,
    counters: TraceCounters,
    class_share: ClassShare,
}

/// The largest side of a supersampled image, subpixels: 16384, what most Vulkan devices allow
/// for a 2D image (the renderer also checks the device's own limit).
pub const MAX_SUBPIXEL_SIDE: u32 = 16384;

/// The most subpixels of an image (8192²): an RGBA32F target, its depth, its readback and the
/// host copy take ~50 bytes each, 3.4 GB here.
pub const MAX_SUBPIXELS: u64 = 8192 * 8192;

/// How far from the scene origin a camera's position and look-at point may lie, metres: beyond it
/// f32 view directions lose the precision to aim.
pub const MAX_CAMERA_METRES: f32 = 1e6;

/// Checks that `camera` can generate rays: a non-empty image within [`MAX_SUBPIXEL_SIDE`] and
/// [`MAX_SUBPIXELS`], k ≥ 1, a finite position within [`MAX_CAMERA_METRES`] distinct from the
/// look-at point, an up vector not parallel to the view direction, a field of view in (0, π).
pub fn validate_camera(camera: &Camera) -> Result<(), TraceError> {
    let forward = camera.look_at - camera.position;
    let side = |n: u32| u64::from(n) * u64::from(camera.supersampling);
    // Saturating: two sides of 2³² subpixels each would overflow u64 (found by fuzzing).
    let subpixels = side(camera.width).saturating_mul(side(camera.height));
    let problem = if camera.width == 0 || camera.height == 0 {
        Some(format!(
            "the image is empty ({}×{})",
            camera.width, camera.height
        ))
    } else if camera.supersampling == 0 {
        Some("supersampling is 0 (use 1 or more)".to_owned())
    } else if side(camera.width).max(side(camera.height)) > u64::from(MAX_SUBPIXEL_SIDE)
        || subpixels > MAX_SUBPIXELS
    {
        Some(format!(
            "{}×{} pixels with {k}×{k} supersampling is {}×{} subpixels; the limit is {MAX_SUBPIXEL_SIDE} a side and {MAX_SUBPIXELS} in all",
            camera.width,
            camera.height,
            side(camera.width),
            side(camera.height),
            k = camera.supersampling
        ))
    } else if !(camera.position.is_finite() && camera.look_at.is_finite() && camera.up.is_finite())
    {
        Some("the position, look-at or up vector is not finite".to_owned())
    } else if camera.position.abs().max_element() > MAX_CAMERA_METRES
        || camera.look_at.abs().max_element() > MAX_CAMERA_METRES
    {
        Some(format!(
            "the position {} or look-at {} lies farther than {MAX_CAMERA_METRES:e} m from the origin",
            camera.position, camera.look_at
        ))
    } else if forward.length_squared() <= 1e-12 {
        Some("the look-at point equals the camera position".to_owned())
    } else if forward.normalize().cross(camera.up).length_squared() <= 1e-12 {
        Some("the up vector is parallel to the view direction".to_owned())
    } else if !(camera.vfov_radians > 0.0 && camera.vfov_radians < std::f32::consts::PI) {
        Some(format!(
            "the vertical field of view {} rad is outside (0, π)",
            camera.vfov_radians
        ))
    } else {
        None
    };
    match problem {
        Some(problem) => Err(TraceError::InvalidCamera(problem)),
        None => Ok(()),
    }
}

/// The world-space ray through image position `(x, y)` (pixels, (0, 0) the top-left corner).
pub fn camera_ray(camera: &Camera, x: f64, y: f64) -> Ray {
    let (origin, direction) = camera.primary_ray(x as f32, y as f32);
    Ray::new(origin.as_dvec3(), direction.as_dvec3())
}

/// Image position of supersample `(i, j)` of pixel `(x, y)` with `k`×`k` supersampling.
pub fn subsample_position(x: u32, y: u32, i: u32, j: u32, k: u32) -> (f64, f64) {
    let k = f64::from(k.max(1));
    (
        f64::from(x) + (f64::from(i) + 0.5) / k,
        f64::from(y) + (f64::from(j) + 0.5) / k,
    )
}

/// Renders the reference image of `scene` seen by `camera` (its size and supersampling), on the
/// current rayon pool. `progress` is called with the number of rows finished so far (from any
/// thread, in no particular order).
pub fn render_reference(
    scene: &TraceScene,
    camera: &Camera,
    options: &TraceOptions,
    progress: &(dyn Fn(u32) + Sync),
) -> Result<ReferenceImage, TraceError> {
    let never = AtomicBool::new(false);
    render_reference_cancellable(scene, camera, options, progress, &never)?.ok_or_else(|| {
        // Unreachable: nothing sets `never`.
        TraceError::InvalidImage("the render was cancelled".to_owned())
    })
}

/// [`render_reference`] that an interactive caller can stop: `cancel` is read at the start of
/// every row, and once it is set the rows not yet begun are skipped (a row already begun runs to
/// its end). Returns `Ok(None)` when `cancel` was set at any point before the last row finished
/// (then no image is assembled), `Ok(Some(image))`, equal to [`render_reference`]'s, otherwise.
/// `progress` counts only the rows rendered. The camera is checked first: an invalid camera is an
/// error even when `cancel` is already set.
pub fn render_reference_cancellable(
    scene: &TraceScene,
    camera: &Camera,
    options: &TraceOptions,
    progress: &(dyn Fn(u32) + Sync),
    cancel: &AtomicBool,
) -> Result<Option<ReferenceImage>, TraceError> {
    validate_camera(camera)?;
    let start = Instant::now();
    let finished = AtomicU32::new(0);
    let rows: Vec<Option<Row>> = (0..camera.height)
        .into_par_iter()
        .map(|y| {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            let row = render_row(scene, camera, options, y);
            progress(finished.fetch_add(1, Ordering::Relaxed) + 1);
            Some(row)
        })
        .collect();
    // A flag set after the last row began still cancels: the caller asked for no image.
    if cancel.load(Ordering::Relaxed) {
        return Ok(None);
    }
    let Some(rows) = rows.into_iter().collect::<Option<Vec<Row>>>() else {
        return Ok(None);
    };
    let seconds = start.elapsed().as_secs_f64();

    let pixels = camera.width as usize * camera.height as usize;
    let mut image = ReferenceImage {
        width: camera.width,
        height: camera.height,
        radiance: Vec::with_capacity(pixels),
        refraction: Vec::with_capacity(pixels),
        reflection: Vec::with_capacity(pixels),
        lens_mask: Vec::with_capacity(pixels),
        glossy_error: Vec::with_capacity(pixels),
        glossy_mask: Vec::with_capacity(pixels),
        lens_pixels: LensPixels {
            width: camera.width,
            height: camera.height,
            covers: Vec::with_capacity(pixels),
        },
        stats: RenderStats {
            width: camera.width,
            height: camera.height,
            supersampling: camera.supersampling,
            counters: TraceCounters::default(),
            seconds,
            class_share: ClassShare::default(),
        },
    };
    for row in rows {
        image.radiance.extend(row.radiance);
        image.refraction.extend(row.refraction);
        image.reflection.extend(row.reflection);
        image.lens_mask.extend(row.lens_mask);
        image.glossy_error.extend(row.glossy_error);
        image.glossy_mask.extend(row.glossy_mask);
        image.lens_pixels.covers.extend(row.covers);
        image.stats.counters += row.counters;
        image.stats.class_share += row.class_share;
    }
    Ok(Some(image))
}

fn render_row(scene: &TraceScene, camera: &Camera, options: &TraceOptions, y: u32) -> Row {
    let k = camera.supersampling.max(1);
    let width = camera.width as usize;
    let scale = 1.0 / f64::from(k * k);
    let mut row = Row {
        glossy_error: Vec::with_capacity(width),
        glossy_mask: Vec::with_capacity(width),
        radiance: Vec::with_capacity(width),
        refraction: Vec::with_capacity(width),
        reflection: Vec::with_capacity(width),
        lens_mask: Vec::with_capacity(width),
        covers: Vec::with_capacity(width),
        counters: TraceCounters::default(),
        class_share: ClassShare::default(),
    };
    let mut first_hits = Vec::with_capacity((k * k) as usize);
    for x in 0..camera.width {
        let mut sums = [DVec3::ZERO; 3];
        // Σ of the subsamples' variances (squared standard errors), mean over channels.
        let mut variance = 0.0;
        let mut glossy_hits = 0u32;
        let mut lens_hits = 0u32;
        for j in 0..k {
            for i in 0..k {
                let (sx, sy) = subsample_position(x, y, i, j, k);
                let ray = camera_ray(camera, sx, sy);
                let sample = scene.trace_camera_ray(&ray, options, &mut row.counters);
                sums[0] += sample.radiance;
                sums[1] += sample.refraction;
                sums[2] += sample.reflection;
                variance += (sample.standard_error * sample.standard_error).element_sum() / 3.0;
                glossy_hits += u32::from(sample.glossy);
                lens_hits += u32::from(sample.lens.is_some());
                first_hits.push(sample.lens);
                row.class_share += sample.class_share;
            }
        }
        row.covers.push(PixelCover::of(first_hits.drain(..)));
        row.radiance.push((sums[0] * scale).as_vec3());
        row.refraction.push((sums[1] * scale).as_vec3());
        row.reflection.push((sums[2] * scale).as_vec3());
        row.lens_mask.push((f64::from(lens_hits) * scale) as f32);
        // The pixel is the mean of k² independent subsamples.
        row.glossy_error.push((variance.sqrt() * scale) as f32);
        row.glossy_mask
            .push((f64::from(glossy_hits) * scale) as f32);
    }
    row
}

/// The files [`ReferenceImage::write`] produces.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct WrittenFiles {
    /// Every file written, EXR and PNG, in a fixed order.
    pub paths: Vec<PathBuf>,
}

impl ReferenceImage {
    /// Writes `reference`, `refraction` (T·F_T·G_T), `reflection` (R·F_R·G_R) and `lens_mask`,
    /// each as linear EXR and sRGB PNG, into `directory` (created if missing).
    pub fn write(&self, directory: &Path) -> Result<WrittenFiles, TraceError> {
        std::fs::create_dir_all(directory).map_err(|source| TraceError::Io {
            path: directory.to_path_buf(),
            source,
        })?;
        let mask: Vec<Vec3> = self.lens_mask.iter().map(|&m| Vec3::splat(m)).collect();
        // Every file staged before any is put in place: a failure (a full disk) leaves the
        // earlier set whole.
        let mut paths = Vec::new();
        let mut staged = Vec::new();
        for (name, pixels) in [
            ("reference", &self.radiance),
            ("refraction", &self.refraction),
            ("reflection", &self.reflection),
            ("lens_mask", &mask),
        ] {
            let exr = directory.join(format!("{name}.exr"));
            staged.push(stage_exr(&exr, self.width, self.height, pixels)?);
            paths.push(exr);
            let png = directory.join(format!("{name}.png"));
            staged.push(stage_png(&png, self.width, self.height, pixels)?);
            paths.push(png);
        }
        for file in staged {
            file.commit()?;
        }
        Ok(WrittenFiles { paths })
    }

    /// The final image as sRGB-encoded 8-bit RGB (clamped to [0, 1] before encoding).
    pub fn to_srgb8(&self) -> Vec<u8> {
        srgb8(&self.radiance)
    }
}

/// Writes linear RGB pixels as a 32-bit float EXR, atomically ([`crate::atomic`]).
pub fn write_exr(path: &Path, width: u32, height: u32, pixels: &[Vec3]) -> Result<(), TraceError> {
    stage_exr(path, width, height, pixels)?.commit()
}

/// Writes linear RGB pixels as an 8-bit sRGB PNG (clamped to [0, 1]), atomically.
pub fn write_png(path: &Path, width: u32, height: u32, pixels: &[Vec3]) -> Result<(), TraceError> {
    stage_png(path, width, height, pixels)?.commit()
}

/// An image file written beside its place, not yet in it ([`crate::atomic::Staged`]): stage
/// every file of a set (a PNG and its EXR) before committing any, so that a failure leaves the
/// earlier set whole.
#[derive(Debug)]
#[must_use = "a staged image is removed unless committed"]
pub struct StagedImage {
    path: PathBuf,
    staged: crate::atomic::Staged,
}

impl StagedImage {
    /// Puts the file in place; an error names its path.
    pub fn commit(self) -> Result<(), TraceError> {
        let path = self.path;
        self.staged
            .commit()
            .map_err(|source| TraceError::Io { path, source })
    }
}

/// [`write_exr`] up to its last step: the EXR encoded, written and synced beside `path`.
pub fn stage_exr(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
) -> Result<StagedImage, TraceError> {
    let data: Vec<f32> = pixels.iter().flat_map(|p| p.to_array()).collect();
    let image = image::Rgb32FImage::from_raw(width, height, data).ok_or_else(|| {
        TraceError::InvalidImage(format!(
            "{} pixels do not fill {width}×{height}",
            pixels.len()
        ))
    })?;
    stage_encoded(path, |bytes| {
        image.write_to(bytes, image::ImageFormat::OpenExr)
    })
}

/// [`write_png`] up to its last step: the PNG encoded, written and synced beside `path`.
pub fn stage_png(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
) -> Result<StagedImage, TraceError> {
    let image = image::RgbImage::from_raw(width, height, srgb8(pixels)).ok_or_else(|| {
        TraceError::InvalidImage(format!(
            "{} pixels do not fill {width}×{height}",
            pixels.len()
        ))
    })?;
    stage_encoded(path, |bytes| image.write_to(bytes, image::ImageFormat::Png))
}

/// Encodes an image in memory with `encode`, then stages the bytes beside `path`: a failure (a
/// full disk) leaves an earlier file at `path` as it was. Errors name `path`, never the
/// temporary.
fn stage_encoded(
    path: &Path,
    encode: impl FnOnce(&mut std::io::Cursor<Vec<u8>>) -> image::ImageResult<()>,
) -> Result<StagedImage, TraceError> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    encode(&mut bytes).map_err(|source| TraceError::Image {
        path: path.to_path_buf(),
        source,
    })?;
    let staged = crate::atomic::stage(path, bytes.get_ref()).map_err(|source| TraceError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(StagedImage {
        path: path.to_path_buf(),
        staged,
    })
}

/// sRGB encoding of linear values (clamped to [0, 1]) to 8 bits, three bytes per pixel.
pub fn srgb8(pixels: &[Vec3]) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|p| p.to_array())
        .map(|c| (srgb_encode(c) * 255.0 + 0.5) as u8)
        .collect()
}

/// The sRGB transfer function of one linear channel, clamped to [0, 1] (NaN → 0).
pub fn srgb_encode(linear: f32) -> f32 {
    let c = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use crate::trace::{PathModel, compile_records};

    fn in_pool<T: Send>(threads: usize, work: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(work)
    }

    #[test]
    fn output_is_bit_identical_whatever_the_thread_count() {
        let scene = Scene::load_named("teapot-room").expect("built-in scene");
        let world = TraceScene::new(&scene).expect("traceable");
        let camera = Camera {
            width: 40,
            height: 30,
            supersampling: 2,
            ..scene.camera
        };
        for model in [PathModel::Greedy, PathModel::Full] {
            let options = TraceOptions {
                model,
                ..TraceOptions::default()
            };
            let render = || render_reference(&world, &camera, &options, &|_| {}).unwrap();
            let mut one = in_pool(1, render);
            let mut two = in_pool(2, render);
            one.stats.seconds = 0.0;
            two.stats.seconds = 0.0;
            let bits = |v: &[Vec3]| {
                v.iter()
                    .flat_map(|p| p.to_array().map(f32::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(bits(&one.radiance), bits(&two.radiance), "{model:?}");
            assert_eq!(bits(&one.refraction), bits(&two.refraction));
            assert_eq!(bits(&one.reflection), bits(&two.reflection));
            assert_eq!(one, two);
        }
        let records = |threads| {
            in_pool(threads, || {
                compile_records(&world, &camera, &TraceOptions::default()).unwrap()
            })
        };
        let (one, two) = (records(1), records(2));
        assert!(one.lenses.iter().any(|l| !l.records.is_empty()));
        assert_eq!(one, two);
    }

    fn small_glass_sphere() -> (TraceScene, Camera) {
        let scene = Scene::load_named("glass-sphere").expect("built-in scene");
        let world = TraceScene::new(&scene).expect("traceable");
        let camera = scene.camera.with_resolution(16, 12, 1);
        (world, camera)
    }

    #[test]
    fn uncancelled_render_equals_render_reference() {
        let (world, camera) = small_glass_sphere();
        let options = TraceOptions::default();
        let never = AtomicBool::new(false);
        let rows = AtomicU32::new(0);
        let mut cancellable = render_reference_cancellable(
            &world,
            &camera,
            &options,
            &|_| {
                rows.fetch_add(1, Ordering::Relaxed);
            },
            &never,
        )
        .unwrap()
        .expect("not cancelled");
        let mut plain = render_reference(&world, &camera, &options, &|_| {}).unwrap();
        cancellable.stats.seconds = 0.0;
        plain.stats.seconds = 0.0;
        assert_eq!(cancellable, plain);
        assert_eq!((plain.width, plain.height), (16, 12));
        assert!(
            plain.lens_mask.iter().any(|&m| m > 0.0),
            "the sphere is seen"
        );
        assert_eq!(
            rows.load(Ordering::Relaxed),
            12,
            "one progress call per row"
        );
    }

    #[test]
    fn cancel_set_before_the_call_renders_no_row() {
        let (world, camera) = small_glass_sphere();
        // The scene's full 640×480 at 3×3: millions of rays had any row been begun.
        let camera = camera.with_resolution(640, 480, 3);
        let cancel = AtomicBool::new(true);
        let rows = AtomicU32::new(0);
        let start = Instant::now();
        let result = render_reference_cancellable(
            &world,
            &camera,
            &TraceOptions::default(),
            &|_| {
                rows.fetch_add(1, Ordering::Relaxed);
            },
            &cancel,
        )
        .unwrap();
        assert!(result.is_none());
        assert_eq!(rows.load(Ordering::Relaxed), 0);
        assert!(start.elapsed().as_secs_f64() < 1.0, "{:?}", start.elapsed());
        // The camera is still checked: an invalid one is an error, not a cancellation.
        let empty = Camera { width: 0, ..camera };
        assert!(
            render_reference_cancellable(
                &world,
                &empty,
                &TraceOptions::default(),
                &|_| {},
                &cancel
            )
            .is_err()
        );
    }

    #[test]
    fn cancel_set_during_the_render_skips_the_remaining_rows() {
        let (world, camera) = small_glass_sphere();
        let cancel = AtomicBool::new(false);
        let rows = AtomicU32::new(0);
        // One thread renders the rows in order: the flag set after the first row stops the rest.
        let result = in_pool(1, || {
            render_reference_cancellable(
                &world,
                &camera,
                &TraceOptions::default(),
                &|_| {
                    rows.fetch_add(1, Ordering::Relaxed);
                    cancel.store(true, Ordering::Relaxed);
                },
                &cancel,
            )
        })
        .unwrap();
        assert!(result.is_none());
        assert_eq!(rows.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn exr_keeps_linear_values_and_png_is_srgb() {
        let pixels = vec![
            Vec3::new(0.0, 0.25, 3.5),
            Vec3::new(1e-4, 0.5, 1.0),
            Vec3::new(0.2, 0.7, 12.0),
            Vec3::new(0.9, 0.01, 0.3),
        ];
        let directory = std::env::temp_dir().join(format!("lensmap-exr-{}", std::process::id()));
        std::fs::create_dir_all(&directory).unwrap();
        let exr = directory.join("t.exr");
        let png = directory.join("t.png");
        write_exr(&exr, 2, 2, &pixels).unwrap();
        write_png(&png, 2, 2, &pixels).unwrap();
        let back = image::open(&exr).unwrap().to_rgb32f();
        let values: Vec<f32> = back.into_raw();
        let expected: Vec<f32> = pixels.iter().flat_map(|p| p.to_array()).collect();
        assert_eq!(values, expected);
        let back = image::open(&png).unwrap().to_rgb8().into_raw();
        assert_eq!(back, srgb8(&pixels));
        assert!(write_exr(&exr, 3, 2, &pixels).is_err());
        std::fs::remove_dir_all(&directory).ok();
    }

    #[test]
    fn srgb_transfer_endpoints_and_knee() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        assert_eq!(srgb_encode(f32::NAN), 0.0);
        assert_eq!(srgb_encode(7.0), srgb_encode(1.0));
        let knee = 0.003_130_8;
        assert!((srgb_encode(knee) - 1.055 * knee.powf(1.0 / 2.4) + 0.055).abs() < 1e-5);
        assert_eq!(srgb8(&[Vec3::new(0.0, 0.5, 1.0)]), vec![0, 188, 255]);
    }

    #[test]
    fn subsamples_are_stratified_inside_the_pixel() {
        let k = 3;
        let mut positions = Vec::new();
        for j in 0..k {
            for i in 0..k {
                positions.push(subsample_position(10, 4, i, j, k));
            }
        }
        assert_eq!(positions[0], (10.0 + 1.0 / 6.0, 4.0 + 1.0 / 6.0));
        assert_eq!(positions[8], (10.0 + 5.0 / 6.0, 4.0 + 5.0 / 6.0));
        let mean_x = positions.iter().map(|p| p.0).sum::<f64>() / 9.0;
        assert!((mean_x - 10.5).abs() < 1e-12);
    }
}
