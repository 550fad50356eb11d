//! `lensmap view` in a window under Xvfb: 60 frames driven by `--script` along an orbit with key
//! toggles and a resize, a screenshot through the swapchain compared with `lensmap render` of the
//! same camera within 1/255, and not one validation message. Skipped, saying why, where no X
//! server can be started.

mod common;
use common::{assert_success, lensmap_command, read, succeeds, temp_dir};

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A private Xvfb server, stopped when dropped.
struct Xvfb {
    child: Child,
    display: String,
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        // SIGTERM first: Xvfb then removes its socket and lock file, which a SIGKILL leaves
        // behind to make the next run's display look taken.
        let terminated = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .is_ok_and(|s| s.success());
        let start = Instant::now();
        while terminated && start.elapsed() < Duration::from_secs(5) {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts Xvfb on the first free display from :90, or says why it cannot.
fn start_xvfb() -> Result<Xvfb, String> {
    for n in 90..130 {
        let socket = PathBuf::from(format!("/tmp/.X11-unix/X{n}"));
        if socket.exists() || Path::new(&format!("/tmp/.X{n}-lock")).exists() {
            continue;
        }
        let child = Command::new("Xvfb")
            .args([
                &format!(":{n}"),
                "-screen",
                "0",
                "640x480x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("Xvfb cannot be started ({e}); install the xvfb package"))?;
        let mut server = Xvfb {
            child,
            display: format!(":{n}"),
        };
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(20) {
            if socket.exists() {
                return Ok(server);
            }
            if let Ok(Some(status)) = server.child.try_wait() {
                return Err(format!("Xvfb :{n} exited at once ({status})"));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        return Err(format!("Xvfb :{n} made no socket in 20 s"));
    }
    Err("no free X display between :90 and :129".into())
}

/// The 8-bit RGB pixels and size of a PNG.
fn png(path: &Path) -> (Vec<u8>, u32, u32) {
    let image = image::load_from_memory(&read(path))
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8();
    let (w, h) = image.dimensions();
    (image.into_raw(), w, h)
}

/// 60 frames: an orbit of 60 poses; the lens vertices traced on the GPU (`g` twice: auto → cpu
/// → gpu), with the wireframe on (the meshes read back) and off (drawn where the GPU left them),
/// the variant to multipass and the blending scheme on, t up and down, the framebuffer format
/// round, one resize; a screenshot of the last frame.
const SCRIPT: &str = r#"
path = "orbit"
frames = 60
[[step]]
frame = 5
keys = ["x", "h", "g", "g"]
[[step]]
frame = 12
keys = ["v", "b", "b"]
[[step]]
frame = 20
resize = [128, 96]
keys = ["]", "f"]
[[step]]
frame = 30
keys = ["x", "[", "f", "f", "r"]
[[step]]
frame = 40
keys = ["r", "r", "h"]
[[step]]
frame = 59
screenshot = "SHOT"
"#;

#[test]
fn a_scripted_window_shows_what_render_renders_without_a_validation_message() {
    let server = match start_xvfb() {
        Ok(server) => server,
        Err(why) => {
            println!("skipped: no X server for the windowed test: {why}");
            return;
        }
    };
    let root = temp_dir("view", "window");
    let shot = root.join("shot");
    let script = root.join("script.toml");
    std::fs::write(
        &script,
        SCRIPT.replace("SHOT", shot.to_str().expect("a UTF-8 temporary path")),
    )
    .expect("writing the script");
    let output = lensmap_command(&[
        "view",
        "--scene",
        "glass-sphere",
        "--projected",
        "--em-size",
        "16",
        "--width",
        "96",
        "--height",
        "72",
        "--supersampling",
        "1",
        "--script",
        script.to_str().unwrap(),
    ])
    .env("DISPLAY", &server.display)
    .output()
    .expect("the lensmap binary runs");
    assert_success("lensmap view --script", &output);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("validation layer: no message in 60 frames"),
        "{stdout}"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&read(&shot.with_extension("json"))).expect("the screenshot's JSON");
    // The resize took: the last frame is 128×96, and the keys left multipass with the third
    // blending scheme and the format round to rgba16f.
    assert_eq!(json["camera"]["width"], 128, "{json}");
    assert_eq!(json["camera"]["height"], 96, "{json}");
    assert_eq!(json["variant"], "multipass", "{json}");
    assert_eq!(json["blend"], "group-targets", "{json}");
    assert_eq!(json["format"], "rgba16f", "{json}");
    assert_eq!(json["t"], 3.0, "{json}");
    let render = json["render"].as_str().expect("a render command line");
    assert!(
        render.ends_with("--tracer gpu --traversal auto --gpu-precision f32"),
        "{render}"
    );
    let out = root.join("render.png");
    let mut args: Vec<&str> = render.split(' ').skip(1).collect();
    let out_arg = out.to_str().unwrap();
    args.extend(["--out", out_arg, "--quiet"]);
    succeeds(&args);
    let (window, w, h) = png(&shot.with_extension("png"));
    let (rendered, rw, rh) = png(&out);
    assert_eq!((w, h), (rw, rh));
    let worst = window
        .iter()
        .zip(&rendered)
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .expect("pixels");
    assert!(
        worst <= 1,
        "the swapchain's frame differs from lensmap render by {worst}/255"
    );
    // The window as shown has the overlay over the frame.
    let (with_overlay, ..) = png(&root.join("shot-window.png"));
    assert_ne!(
        with_overlay, window,
        "no overlay in the window's screenshot"
    );
    drop(server);
    let _ = std::fs::remove_dir_all(&root);
}
