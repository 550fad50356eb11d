//! The C++ host example (`tools/examples/cpp-host/host.cpp`), built with the system C++ compiler
//! (C++17, warnings as errors) against `lensmap.h` and the cdylib cargo built: on its own Vulkan
//! instance and device, with the validation layer and synchronization validation on, it renders
//! teapot-room into its own `VkImage` through `lensmap_render_to_image`, reads the image back
//! itself and writes a PNG and a PFM. Its frame must equal `lensmap render` of the same camera and
//! options: the PNGs byte for byte, the linear values bit for bit in RGBA8 and within 1e-6
//! (relative above 1) in RGBA32F.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{lensmap, temp_dir};
use lensmap_tests::c_abi;

/// Builds the C++ host as `docs/capi.md` says (with the cdylib of this build).
fn build_host(scratch: &Path) -> PathBuf {
    let program = scratch.join("cpp-host");
    c_abi::build_host(
        "c++",
        &["-std=c++17", "-O2", "-ffp-contract=off"],
        &c_abi::repository().join("tools/examples/cpp-host/host.cpp"),
        &["-lvulkan"],
        &program,
    );
    program
}

/// A little-endian RGB PFM (rows bottom to top) as rows top to bottom.
fn read_pfm(path: &Path) -> (u32, u32, Vec<[f32; 3]>) {
    let bytes = std::fs::read(path).expect("the host wrote its PFM");
    let mut fields = Vec::new();
    let mut start = 0;
    while fields.len() < 4 {
        let end = start
            + bytes[start..]
                .iter()
                .position(|b| b.is_ascii_whitespace())
                .expect("a PFM header");
        fields.push(String::from_utf8_lossy(&bytes[start..end]).into_owned());
        start = end + 1;
    }
    assert_eq!(fields[0], "PF");
    assert_eq!(fields[3], "-1.0", "little-endian");
    let (width, height): (u32, u32) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    let floats: Vec<f32> = bytes[start..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(floats.len(), 3 * (width * height) as usize);
    let mut rows = Vec::with_capacity((width * height) as usize);
    for y in (0..height).rev() {
        let row = &floats[(3 * width * y) as usize..(3 * width * (y + 1)) as usize];
        rows.extend(row.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
    }
    (width, height, rows)
}

#[test]
fn the_cpp_host_renders_what_lensmap_render_renders() {
    lensmap_tests::name_the_binarys_driver_on_failure();
    let scratch = temp_dir("cpp-host", "render");
    let host = build_host(&scratch);
    // (framebuffer and image format, supersampling, exact): RGBA8 compares bit for bit; RGBA32F
    // within 1e-6 (the GPU box filter's sums in the CPU's order: bit for bit on lavapipe).
    for (format, k, exact) in [("rgba8", "1", true), ("rgba32f", "2", false)] {
        let size = [
            "--width",
            "64",
            "--height",
            "48",
            "--supersampling",
            k,
            "--em-size",
            "16",
            "--format",
            format,
        ];
        let render_png = scratch.join(format!("render-{format}.png"));
        let mut args = vec!["render", "--scene", "teapot-room", "--projected", "--out"];
        args.push(render_png.to_str().unwrap());
        args.extend(size);
        let render = lensmap(&args);
        assert!(
            render.status.success(),
            "{}",
            String::from_utf8_lossy(&render.stderr)
        );

        let (host_png, host_pfm) = (
            scratch.join(format!("host-{format}.png")),
            scratch.join(format!("host-{format}.pfm")),
        );
        let run = Command::new(&host)
            .args(["--validation", "--scene", "teapot-room", "--out"])
            .arg(&host_png)
            .arg("--pfm")
            .arg(&host_pfm)
            .args(size)
            .env("LD_LIBRARY_PATH", c_abi::library_path())
            .output()
            .expect("the C++ host runs");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{format}: {stderr}");
        assert!(
            !stderr.contains("validation"),
            "{format}: validation messages on the host's device: {stderr}"
        );

        let ours = image::open(&render_png).unwrap().to_rgb8();
        let theirs = image::open(&host_png).unwrap().to_rgb8();
        assert_eq!(ours.dimensions(), (64, 48));
        assert!(
            ours == theirs,
            "{format}: the host's PNG differs from lensmap render's"
        );

        let exr = image::open(render_png.with_extension("exr"))
            .unwrap()
            .to_rgb32f();
        let (width, height, pfm) = read_pfm(&host_pfm);
        assert_eq!((width, height), exr.dimensions());
        let mut worst = 0.0f32;
        for (expected, got) in exr.pixels().zip(&pfm) {
            for (&e, &g) in expected.0.iter().zip(got) {
                if exact {
                    assert_eq!(e.to_bits(), g.to_bits(), "{format}: {e} vs {g}");
                }
                worst = worst.max((e - g).abs() / e.abs().max(1.0));
            }
        }
        assert!(
            worst <= 1e-6,
            "{format}: the host's image is {worst} off lensmap render's"
        );
        let distinct: std::collections::HashSet<[u8; 3]> = ours.pixels().map(|p| p.0).collect();
        assert!(
            distinct.len() > 100,
            "{format}: a picture, not a flat frame"
        );
    }
}
