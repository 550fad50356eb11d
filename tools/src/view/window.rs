//! The viewer's window: winit's event loop, the camera controls, the keys, scripts, and per
//! frame the hybrid frame rendered into the swapchain image, the overlay over it and the
//! presentation.

use lensmap::index::LensIndex;
use std::collections::{HashMap, HashSet, VecDeque};
use std::ffi::CStr;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, anyhow};
use egui::Pos2;
use glam::Vec3;
use lensmap::{
    cubemap::CubeMap,
    gpu::{Gpu, GpuOptions},
    hybrid::HybridScene,
    metrics::Encoding,
    runner::{FrameOptions, FrameRunner, HostFrame, HybridFrame, lens_error},
    scene::{Camera, CameraPath, Scene},
    trace::{image::ReferenceImage, image::srgb8, world::TraceScene},
};
use raw_window_handle::HasDisplayHandle;
use winit::{
    application::ApplicationHandler,
    dpi::PhysicalSize,
    event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent},
    event_loop::{ActiveEventLoop, EventLoop},
    keyboard::Key,
    window::{Window, WindowId},
};

use super::{
    EmChoice, PresentArg, ViewArgs, camera,
    keys::{Action, Experiment, ReferenceView},
    overlay::{Overlay, texture},
    present::{Acquired, Presenter},
    reference::ReferenceWorker,
    script::{Script, Step},
};

/// One lens object's maps, `[viewpoint sample][layer]`.
type LensMaps = Vec<Vec<Arc<CubeMap>>>;

mod status;
use status::Smoothed;

/// What the window starts with.
pub struct Start {
    /// The scene.
    pub scene: Scene,
    /// The starting camera (its size is the window's).
    pub camera: Camera,
    /// The starting frame options.
    pub options: FrameOptions,
    /// Where the EMs come from.
    pub ems: EmChoice,
    /// A script to replay, if any.
    pub script: Option<Script>,
}

/// The columns of `--stats`: one row per frame drawn, times in ms. `frame_ms` is the time since
/// the previous frame was done (empty for the first), `latency_ms` from the start of the frame's
/// work (input read) to its last submission done, `gpu_ms` from lensmap's submission of the frame
/// to its end on the GPU, `overlay_ms` the overlay's layout, recording, presentation and wait.
const STATS_HEADER: &str = "frame,width,height,frame_ms,latency_ms,total_ms,trace_ms,\
tessellation_ms,texgen_ms,assemble_ms,upload_ms,record_ms,gpu_ms,overlay_ms,rays,triangle_tests,passes,\
vertices_traced,lens_triangles,reused,traced_on_gpu";

/// How many notes the overlay keeps, and for how long, seconds.
const NOTES: usize = 4;
const NOTE_SECONDS: f32 = 4.0;
/// Wireframes with more edges than this are not drawn (said on screen): egui's tessellation of
/// that many lines would cost more than the frame.
const MAX_WIREFRAME_EDGES: usize = 1_000_000;

pub fn run(args: &ViewArgs, start: Start) -> anyhow::Result<()> {
    let event_loop = EventLoop::new().map_err(|e| {
        anyhow!(
            "view: cannot open a window ({e}); set DISPLAY to an X server (or run under Xvfb), or render headless with --record DIR"
        )
    })?;
    let display = event_loop
        .display_handle()
        .context("the display's handle")?;
    let surface_extensions: Vec<&'static CStr> =
        ash_window::enumerate_required_extensions(display.as_raw())
            .context("the window system's Vulkan extensions")?
            .iter()
            // SAFETY: ash-window's names are 'static NUL-terminated strings.
            .map(|&name| unsafe { CStr::from_ptr(name) })
            .collect();
    let gpu = Gpu::new(&GpuOptions {
        surface_extensions,
        ..GpuOptions::from_env()
    })?;
    let validation = gpu.validation_report().enabled;
    let runner = FrameRunner::new(gpu)?;
    runner.check_framebuffer(&start.camera, start.options.format)?;
    say!("device: {}", runner.gpu().device_id());
    let inferred = start.ems.inferred_first;
    let first = start.ems.load(&start.scene, inferred)?;
    let path = match start.script.as_ref().and_then(|s| s.path.as_ref()) {
        Some(path) if path == "orbit" => {
            let frames = start.script.as_ref().map_or(60, |s| s.frames);
            let mut centred = start.scene.clone();
            centred.camera = start.camera;
            Some(CameraPath::orbit(&centred, frames))
        }
        Some(file) => Some(CameraPath::load(Path::new(file), &start.camera)?),
        None => None,
    };
    let mut app = App {
        overlay: None,
        presenter: None,
        reference: None,
        runner,
        window: None,
        present: args.present,
        screenshots: args.screenshots.clone(),
        shots: 0,
        screenshot_next: None,
        scene: start.scene,
        scene_arg: args.scene.clone(),
        ems: start.ems,
        hybrids: [None, None],
        originals: [None, None],
        transparent: HashMap::new(),
        applied_layers: Vec::new(),
        trace: None,
        experiment: Experiment {
            options: start.options,
            multipass_blend: start.options.compositing.blend(),
            layers_off: Vec::new(),
            inferred,
            wireframe: false,
            reference: ReferenceView::Off,
            help: false,
        },
        camera: start.camera,
        script: start.script,
        path,
        frame: 0,
        notes: VecDeque::new(),
        inside: Vec::new(),
        start_inside: Vec::new(),
        input: Input::default(),
        stats: Smoothed::default(),
        csv: args
            .stats
            .clone()
            .map(|file| (file, format!("{STATS_HEADER}\n"))),
        last_frame_end: None,
        recreate: false,
        minimized: false,
        quit: false,
        frame_error: None,
        compared: None,
        error: None,
    };
    app.set_hybrid(inferred, first);
    let (_, inside) = camera::guard(app.hybrid(), app.camera);
    app.start_inside = inside.clone();
    app.inside = inside;
    event_loop.run_app(&mut app)?;
    if let Some((file, csv)) = &app.csv {
        lensmap::atomic::write_atomically(file, csv.as_bytes())
            .with_context(|| format!("writing {}", file.display()))?;
    }
    let App {
        error,
        overlay,
        presenter,
        reference,
        runner,
        window,
        frame,
        ..
    } = app;
    // Everything made on the device goes before the device; the surface before the window.
    drop((overlay, presenter, reference));
    drop(window);
    let report = runner.gpu().validation_report();
    if let Some(error) = error {
        return Err(error);
    }
    if validation {
        if !report.messages.is_empty() {
            for message in &report.messages {
                eprintln!("validation: {message}");
            }
            anyhow::bail!(
                "the validation layer reported {} messages in {frame} frames (listed above)",
                report.messages.len()
            );
        }
        say!("validation layer: no message in {frame} frames");
    }
    Ok(())
}

/// The mouse and the fly keys.
#[derive(Default)]
struct Input {
    cursor: Option<Pos2>,
    orbiting: bool,
    looking: bool,
    /// W, A, S, D held.
    fly: HashSet<char>,
}

/// What a hybrid frame compared with the reference depends on.
#[derive(Clone, Debug, PartialEq)]
struct ComparedKey {
    camera: Camera,
    options: FrameOptions,
    /// Inferred EMs (else projected).
    inferred: bool,
    layers_off: Vec<bool>,
}

/// The lens PSNR and the images of the reference shown against the frame it was compared with.
struct Compared {
    /// The camera and experiment the hybrid frame had.
    key: ComparedKey,
    reference: Arc<ReferenceImage>,
    psnr: Result<f64, String>,
    reference_texture: egui::TextureHandle,
    difference_texture: egui::TextureHandle,
}

struct App {
    // Dropped in this order: what lives on the device, then the device, then the window.
    overlay: Option<Overlay>,
    presenter: Option<Presenter>,
    reference: Option<ReferenceWorker>,
    runner: FrameRunner,
    window: Option<Window>,
    present: PresentArg,
    screenshots: PathBuf,
    shots: usize,
    /// Where the next frame's screenshot goes (without extension), if one was asked for.
    screenshot_next: Option<PathBuf>,
    scene: Scene,
    /// The scene as `lensmap render --scene` takes it (its name or its file).
    scene_arg: String,
    ems: EmChoice,
    /// The hybrid scene with projected EMs (0) and inferred ones (1), loaded when first shown.
    hybrids: [Option<HybridScene>; 2],
    /// Their maps as loaded, `[lens][viewpoint][layer]`, for turning layers back on.
    originals: [Option<Vec<LensMaps>>; 2],
    /// One transparent map per size, standing in for layers turned off (kept, so that frames
    /// with the same layers off are the same frame).
    transparent: HashMap<u32, Arc<CubeMap>>,
    /// The layers off in the maps the shown hybrid scene holds.
    applied_layers: Vec<bool>,
    /// The reference's trace scene, built when the reference is first asked for.
    trace: Option<Arc<TraceScene>>,
    experiment: Experiment,
    camera: Camera,
    script: Option<Script>,
    path: Option<CameraPath>,
    /// Frames drawn (the script's clock).
    frame: usize,
    notes: VecDeque<(String, Instant)>,
    /// The layer shells the camera is inside.
    inside: Vec<String>,
    /// Those the starting camera is inside (rooms around the scene): being inside them is normal.
    start_inside: Vec<String>,
    input: Input,
    stats: Smoothed,
    /// `--stats`: the file and its rows so far.
    csv: Option<(PathBuf, String)>,
    last_frame_end: Option<Instant>,
    recreate: bool,
    minimized: bool,
    /// A script pressed a quit key: close after this frame.
    quit: bool,
    /// Why the last frame could not be rendered, if it could not.
    frame_error: Option<String>,
    compared: Option<Compared>,
    error: Option<anyhow::Error>,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        if let Err(e) = self.open(event_loop) {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => {
                self.minimized = size.width == 0 || size.height == 0;
                self.recreate = true;
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let name = match &event.logical_key {
                    Key::Character(c) => c.to_lowercase(),
                    Key::Named(named) => format!("{named:?}").to_lowercase(),
                    _ => String::new(),
                };
                let pressed = event.state == ElementState::Pressed;
                if let Some(c @ ('w' | 'a' | 's' | 'd')) =
                    name.chars().next().filter(|_| name.len() == 1)
                {
                    if pressed {
                        self.input.fly.insert(c);
                    } else {
                        self.input.fly.remove(&c);
                    }
                    Ok(())
                } else if pressed && !event.repeat {
                    match super::keys::action(&name) {
                        Some(Action::Quit) => {
                            event_loop.exit();
                            Ok(())
                        }
                        Some(action) => self.act(action, None),
                        None => Ok(()),
                    }
                } else {
                    Ok(())
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let down = state == ElementState::Pressed;
                match button {
                    MouseButton::Left => self.input.orbiting = down,
                    MouseButton::Right => self.input.looking = down,
                    _ => {}
                }
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                let now = Pos2::new(position.x as f32, position.y as f32);
                if let Some(before) = self.input.cursor {
                    let d = now - before;
                    if self.input.orbiting {
                        self.move_camera(camera::orbit(&self.camera, -0.3 * d.x, 0.3 * d.y));
                    } else if self.input.looking {
                        self.move_camera(camera::look(&self.camera, -0.15 * d.x, -0.15 * d.y));
                    }
                }
                self.input.cursor = Some(now);
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.move_camera(camera::zoom(&self.camera, 0.9f32.powf(steps)));
                Ok(())
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        if let Some(window) = &self.window {
            window.request_redraw();
        }
    }
}

impl App {
    /// The window, its swapchain and the overlay.
    fn open(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<()> {
        let attributes = Window::default_attributes()
            .with_title(format!("lensmap view · {}", self.scene.name))
            .with_inner_size(PhysicalSize::new(self.camera.width, self.camera.height));
        let window = event_loop.create_window(attributes)?;
        let gpu = self.runner.gpu();
        let presenter = Presenter::new(gpu, &window, self.present)?;
        say!(
            "window {}×{}, swapchain {:?}, present mode {:?}",
            presenter.extent.width,
            presenter.extent.height,
            presenter.format.format,
            presenter.mode
        );
        self.overlay = Some(Overlay::new(gpu, presenter.format.format)?);
        self.presenter = Some(presenter);
        self.window = Some(window);
        Ok(())
    }

    /// A note on screen for a few seconds.
    fn note(&mut self, text: String) {
        self.notes.push_back((text, Instant::now()));
        while self.notes.len() > NOTES {
            self.notes.pop_front();
        }
    }

    /// The hybrid scene shown.
    fn hybrid(&self) -> &HybridScene {
        self.hybrids[usize::from(self.experiment.inferred)]
            .as_ref()
            .expect("the shown scene is loaded before it is shown (run, act)")
    }

    /// The current frame rendered again and read back in float (screenshots' EXR, the
    /// reference's comparison): the shown scene, camera and options.
    fn read_back(&mut self) -> anyhow::Result<HybridFrame> {
        let hybrid = self.hybrids[usize::from(self.experiment.inferred)]
            .as_ref()
            .expect("the shown scene is loaded before it is shown (run, act)");
        Ok(self
            .runner
            .frame(hybrid, &self.camera, &self.experiment.options)?)
    }

    /// Keeps `hybrid` as the scene with inferred (or projected) EMs, with its maps as loaded.
    fn set_hybrid(&mut self, inferred: bool, hybrid: HybridScene) {
        let maps = hybrid.lenses().iter().map(|l| l.maps.clone()).collect();
        self.originals[usize::from(inferred)] = Some(maps);
        self.hybrids[usize::from(inferred)] = Some(hybrid);
        // Its maps are the originals: layers off are applied before its first frame.
        self.applied_layers = Vec::new();
    }

    /// The camera moved, unless the guard stops it (said on screen).
    fn move_camera(&mut self, to: Camera) {
        let (moved, inside) = camera::guard(self.hybrid(), to);
        match moved {
            camera::Moved::To(camera) => {
                let entered: Vec<&String> =
                    inside.iter().filter(|s| !self.inside.contains(s)).collect();
                let left: Vec<&String> =
                    self.inside.iter().filter(|s| !inside.contains(s)).collect();
                let said = match (entered.is_empty(), left.is_empty()) {
                    (true, true) => None,
                    (false, _) => Some(format!(
                        "the camera entered layer shell {}: the environment there is drawn on the shell, so parallax inside it is wrong",
                        join(&entered)
                    )),
                    (true, false) => Some(format!("the camera left layer shell {}", join(&left))),
                };
                if let Some(said) = said {
                    self.note(said);
                }
                self.inside = inside;
                self.camera = camera;
            }
            camera::Moved::Stopped(why) => {
                if self.notes.back().is_none_or(|(n, _)| *n != why) {
                    self.note(why);
                }
            }
        }
    }

    /// A key's action; `screenshot` names a script's screenshot.
    fn act(&mut self, action: Action, screenshot: Option<&Path>) -> anyhow::Result<()> {
        match action {
            Action::Ems => {
                let inferred = !self.experiment.inferred;
                if inferred && self.ems.bake.is_none() {
                    self.note("no bake: only projected EMs (give --bake DIR)".into());
                    return Ok(());
                }
                if self.hybrids[usize::from(inferred)].is_none() {
                    let hybrid = self.ems.load(&self.scene, inferred)?;
                    self.set_hybrid(inferred, hybrid);
                }
                self.experiment.inferred = inferred;
                self.applied_layers = Vec::new();
                self.note(format!(
                    "{} layered EMs",
                    if inferred { "inferred" } else { "projected" }
                ));
            }
            Action::Snap | Action::NextSample | Action::PreviousSample => {
                let samples = self.hybrid().viewpoints().to_vec();
                let Some(fit) = self.hybrid().view_space_fit(&self.camera) else {
                    self.note("no viewpoint sample to go to".into());
                    return Ok(());
                };
                let n = samples.len();
                let index = match action {
                    Action::NextSample => (fit.nearest + 1) % n,
                    Action::PreviousSample => (fit.nearest + n - 1) % n,
                    _ => fit.nearest,
                };
                let to = self.camera.with_position(samples[index].as_vec3());
                self.move_camera(to);
                self.note(format!("viewpoint sample {index}"));
            }
            Action::Screenshot => {
                self.screenshot_next = Some(match screenshot {
                    Some(path) => path.to_path_buf(),
                    None => {
                        self.shots += 1;
                        self.screenshots.join(format!("shot-{:04}", self.shots))
                    }
                })
            }
            Action::Quit => {}
            other => {
                let before = self.experiment.clone();
                if let Some(said) = self.experiment.apply(other) {
                    match self.experiment.options.validate() {
                        Ok(()) => self.note(said),
                        Err(e) => {
                            self.experiment = before;
                            self.note(format!("refused: {}", crate::common::flag_error(e).0));
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

impl App {
    /// One frame: the script's steps and the fly keys, the hybrid frame into the swapchain
    /// image, the overlay, the presentation, then screenshots, the reference and the stats.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> anyhow::Result<()> {
        let start = Instant::now();
        if self.minimized || self.window.is_none() {
            return Ok(());
        }
        self.run_script_steps()?;
        self.fly(start);
        self.apply_layers();
        if self.recreate {
            self.recreate_swapchain()?;
            if self.minimized {
                return Ok(());
            }
        }
        let Some(presenter) = &mut self.presenter else {
            return Ok(());
        };
        let index = match presenter.acquire()? {
            Acquired::Image(index) => index,
            Acquired::OutOfDate => {
                self.recreate = true;
                return Ok(());
            }
        };
        self.camera.width = presenter.extent.width;
        self.camera.height = presenter.extent.height;
        let host = presenter.host_image(index);
        let hybrid = self.hybrids[usize::from(self.experiment.inferred)]
            .as_ref()
            .expect("the shown scene is loaded");
        // The wireframe needs the GPU's meshes on the host.
        self.runner.read_back_gpu_meshes(self.experiment.wireframe);
        let rendered =
            match self
                .runner
                .frame_into(hybrid, &self.camera, &self.experiment.options, &host)
            {
                Ok(frame) => {
                    self.frame_error = None;
                    Some(frame)
                }
                Err(e) => {
                    self.frame_error = Some(crate::words::error_line(&anyhow::Error::from(e)));
                    None
                }
            };
        // The GPU's part, timed alone: the overlay is laid out once the frame is done (on
        // lavapipe the two would share the same cores anyway).
        let submitted = Instant::now();
        let gpu_ms = match (&rendered, &self.presenter) {
            (Some(_), Some(presenter)) => {
                presenter.wait_for_frame()?;
                submitted.elapsed().as_secs_f64() * 1e3
            }
            _ => 0.0,
        };
        let overlay_start = Instant::now();
        let view = self.overlay_view(rendered.as_ref());
        let (presenter, overlay) = match (&mut self.presenter, &mut self.overlay) {
            (Some(p), Some(o)) => (p, o),
            _ => return Ok(()),
        };
        let primitives = overlay.prepare(presenter.extent, &view)?;
        let shot = self.screenshot_next.take();
        let copies = match shot.as_ref().map(|_| presenter.copies(self.runner.gpu())) {
            Some(Ok(copies)) => Some(copies),
            Some(Err(why)) => {
                self.notes.push_back((format!("{why:#}"), Instant::now()));
                None
            }
            None => None,
        };
        let fits = presenter.finish(
            self.runner.gpu(),
            index,
            rendered.is_some(),
            copies.as_ref(),
            |cb, extent| overlay.record(cb, extent, &primitives),
        )?;
        self.recreate |= !fits;
        presenter.wait()?;
        overlay.frame_done()?;
        let done = Instant::now();
        if let (Some(path), Some(copies)) = (shot, &copies) {
            self.write_screenshot(&path, copies)?;
        }
        if let Some(frame) = &rendered {
            let overlay_ms = done.duration_since(overlay_start).as_secs_f64() * 1e3;
            self.count(frame, start, gpu_ms, overlay_ms, done);
        }
        self.update_reference()?;
        self.frame += 1;
        if self.quit
            || self
                .script
                .as_ref()
                .is_some_and(|script| self.frame > script.last_frame())
        {
            event_loop.exit();
        }
        Ok(())
    }

    /// The script's steps for this frame, and its path's pose.
    fn run_script_steps(&mut self) -> anyhow::Result<()> {
        let Some(script) = &self.script else {
            return Ok(());
        };
        let steps: Vec<Step> = script.steps_at(self.frame).cloned().collect();
        if let Some(path) = &self.path
            && let Some(pose) = path.poses.get(self.frame % path.poses.len().max(1))
        {
            let to = Camera {
                position: pose.position,
                look_at: pose.look_at,
                ..self.camera
            };
            self.move_camera(to);
        }
        for step in &steps {
            if let Some((position, look_at)) = step.camera {
                self.move_camera(Camera {
                    position,
                    look_at,
                    ..self.camera
                });
            }
            if let Some((yaw, pitch)) = step.orbit {
                self.move_camera(camera::orbit(&self.camera, yaw, pitch));
            }
            if let Some(factor) = step.zoom {
                self.move_camera(camera::zoom(&self.camera, factor));
            }
            for &action in &step.keys {
                if action == Action::Quit {
                    self.quit = true;
                }
                self.act(action, None)?;
            }
            if let Some((width, height)) = step.resize
                && let Some(window) = &self.window
            {
                let _ = window.request_inner_size(PhysicalSize::new(width, height));
                self.recreate = true;
            }
            if let Some(path) = &step.screenshot {
                self.act(Action::Screenshot, Some(path))?;
            }
        }
        Ok(())
    }

    /// WASD: fly at a tenth of the distance to the look-at point per second.
    fn fly(&mut self, now: Instant) {
        let dt = self
            .last_frame_end
            .map_or(0.0, |t| now.duration_since(t).as_secs_f32().min(0.25));
        if self.input.fly.is_empty() || dt == 0.0 {
            return;
        }
        let speed = 0.5 * (self.camera.look_at - self.camera.position).length() * dt;
        let held = |c| f32::from(u8::from(self.input.fly.contains(&c)));
        let forward = (held('w') - held('s')) * speed;
        let right = (held('d') - held('a')) * speed;
        self.move_camera(camera::fly(&self.camera, forward, right));
    }

    /// The layers off replaced by transparent maps in the shown scene (and back on).
    fn apply_layers(&mut self) {
        let which = usize::from(self.experiment.inferred);
        if self.applied_layers == self.experiment.layers_off {
            return;
        }
        let off = self.experiment.layers_off.clone();
        let (Some(hybrid), Some(originals)) = (&mut self.hybrids[which], &self.originals[which])
        else {
            return;
        };
        for (lens, original) in LensIndex::all(originals.len()).zip(originals) {
            let maps = super::keys::with_layers_off(original, &off, &mut self.transparent);
            hybrid.set_lens_maps(lens, maps);
        }
        self.applied_layers = off;
    }

    fn recreate_swapchain(&mut self) -> anyhow::Result<()> {
        let (Some(window), Some(presenter), Some(overlay)) =
            (&self.window, &mut self.presenter, &mut self.overlay)
        else {
            return Ok(());
        };
        let size = window.inner_size();
        self.minimized = !presenter.recreate(size.width, size.height)?;
        overlay.set_format(presenter.format.format)?;
        self.recreate = false;
        Ok(())
    }

    /// Adds a frame's figures to the smoothed stats and mirrors them in the title bar.
    fn count(
        &mut self,
        frame: &HostFrame,
        start: Instant,
        gpu_ms: f64,
        overlay_ms: f64,
        done: Instant,
    ) {
        let s = &frame.stats;
        // A frame drawn where the GPU tessellation left it has its counts read with the next
        // frame: the counts shown are the frame before's (none while it is not done).
        let counted =
            (!s.counted_on_device || frame.previous.is_some()).then(|| frame.counted_stats());
        let count =
            |f: &dyn Fn(&lensmap::hybrid::HybridStats) -> f64| counted.as_ref().map_or(f64::NAN, f);
        let interval = self
            .last_frame_end
            .map(|last| done.duration_since(last).as_secs_f64() * 1e3);
        self.last_frame_end = Some(done);
        let figures: [(&'static str, f64); 16] = [
            ("latency", done.duration_since(start).as_secs_f64() * 1e3),
            ("total", frame.total_ms),
            ("trace", s.trace_ms),
            ("tessellation", s.tessellation_ms),
            ("texgen", s.texgen_ms),
            ("assemble", s.assemble_ms),
            ("upload", frame.upload_ms),
            ("record", frame.record_ms),
            ("gpu", gpu_ms),
            ("overlay", overlay_ms),
            (
                "rays",
                count(&|p| {
                    let c = p.counters;
                    (c.primary_rays + c.secondary_rays + c.shadow_rays) as f64
                }),
            ),
            (
                "triangle tests",
                count(&|p| p.counters.triangle_tests as f64),
            ),
            ("passes", frame.passes as f64),
            ("vertices", count(&|p| p.vertices_traced as f64)),
            ("triangles", count(&|p| p.triangles_out as f64)),
            ("frame", interval.unwrap_or(f64::NAN)),
        ];
        for (name, value) in figures {
            if value.is_finite() {
                self.stats.add(name, value);
            }
        }
        if let Some((_, csv)) = &mut self.csv {
            let _ = write!(
                csv,
                "{},{},{},{}",
                self.frame,
                self.camera.width,
                self.camera.height,
                interval.map_or_else(String::new, |ms| format!("{ms:.3}"))
            );
            for (name, value) in &figures[..15] {
                let _ = match *name {
                    // Counts not read yet (the frame before is not done) are left empty.
                    _ if !value.is_finite() => write!(csv, ","),
                    "rays" | "triangle tests" | "passes" | "vertices" | "triangles" => {
                        write!(csv, ",{value}")
                    }
                    _ => write!(csv, ",{value:.3}"),
                };
            }
            let _ = writeln!(csv, ",{},{}", s.reused, s.traced_on_gpu);
        }
        let stats = &self.stats;
        if let Some(window) = &self.window {
            let fps = 1e3 / stats.get("frame").max(1e-9);
            window.set_title(&format!(
                "lensmap view · {} · {fps:.1} fps · {:.0} ms: trace {:.0}, tessellation {:.0}, texgen {:.0}, GPU {:.0}",
                self.scene.name,
                stats.get("total") + stats.get("gpu"),
                stats.get("trace"),
                stats.get("tessellation"),
                stats.get("texgen"),
                stats.get("gpu"),
            ));
        }
    }

    /// Asks for the reference of the current camera when it is shown, and compares a finished
    /// one with the frame.
    fn update_reference(&mut self) -> anyhow::Result<()> {
        if self.experiment.reference == ReferenceView::Off {
            if let Some(worker) = &mut self.reference {
                worker.cancel();
            }
            return Ok(());
        }
        let key = ComparedKey {
            camera: self.camera,
            options: self.experiment.options,
            inferred: self.experiment.inferred,
            layers_off: self.experiment.layers_off.clone(),
        };
        if self.compared.as_ref().is_some_and(|c| c.key == key) {
            return Ok(());
        }
        // The same camera with other options: the reference stands, the comparison is redone.
        if let Some(compared) = self.compared.take()
            && compared.key.camera == self.camera
        {
            return self.compare(key, compared.reference);
        }
        if self.trace.is_none() {
            self.trace = Some(Arc::new(TraceScene::new(&self.scene)?));
        }
        if self.reference.is_none() {
            self.reference = Some(ReferenceWorker::new()?);
        }
        let (Some(worker), Some(trace)) = (&mut self.reference, &self.trace) else {
            return Ok(());
        };
        worker.want(trace, &self.camera);
        if let Some(finished) = worker.poll() {
            let image = finished.image.map_err(|e| anyhow!("reference: {e}"))?;
            self.compare(key, Arc::new(image))?;
        }
        Ok(())
    }

    /// The frame of `key` read back and compared with the reference over the lens pixels.
    fn compare(&mut self, key: ComparedKey, reference: Arc<ReferenceImage>) -> anyhow::Result<()> {
        let frame = self.read_back()?;
        let psnr = lens_error(&frame.image, &reference, Encoding::DisplaySrgb)
            .map(|e| e.psnr_db)
            .map_err(|e| e.to_string());
        let difference: Vec<Vec3> = frame
            .image
            .pixels
            .iter()
            .zip(&reference.radiance)
            .map(|(h, r)| (Vec3::new(h[0], h[1], h[2]) - *r).abs() * 4.0)
            .collect();
        let ctx = self
            .overlay
            .as_ref()
            .context("the overlay exists while the window does")?
            .context()
            .clone();
        let (w, h) = (reference.width, reference.height);
        self.compared = Some(Compared {
            key,
            psnr,
            reference_texture: texture(&ctx, "reference", w, h, &srgb8(&reference.radiance)),
            difference_texture: texture(&ctx, "difference", w, h, &srgb8(&difference)),
            reference,
        });
        Ok(())
    }

    /// Writes a screenshot: the frame through the swapchain (PNG), the same frame read back as
    /// floats (EXR), the window with its overlay (PNG), and what makes it (JSON).
    fn write_screenshot(
        &mut self,
        path: &Path,
        copies: &super::present::Copies,
    ) -> anyhow::Result<()> {
        // Rendered first: the swapchain's figures below borrow the presenter.
        let frame = self.read_back()?;
        let presenter = self
            .presenter
            .as_ref()
            .context("the swapchain exists while the window does")?;
        let (w, h) = (presenter.extent.width, presenter.extent.height);
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        let with = |suffix: &str| {
            let mut name = path.as_os_str().to_owned();
            name.push(suffix);
            PathBuf::from(name)
        };
        let png = with(".png");
        let window_png = with("-window.png");
        for (file, buffer) in [(&png, &copies.frame), (&window_png, &copies.window)] {
            image::save_buffer(file, &presenter.rgb8(buffer), w, h, image::ColorType::Rgb8)
                .with_context(|| format!("writing {}", file.display()))?;
        }
        let exr = with(".exr");
        lensmap::trace::image::stage_exr(
            &exr,
            frame.image.width,
            frame.image.height,
            &frame.image.rgb(),
        )?
        .commit()?;
        let c = &self.camera;
        let o = &self.experiment.options;
        let v3 = |v: Vec3| format!("{},{},{}", v.x, v.y, v.z);
        let ems = match (&self.ems.bake, self.experiment.inferred) {
            (Some(dir), true) => format!("--bake {}", dir.display()),
            _ => format!("--projected --em-size {}", self.ems.projected.size),
        } + &self.ems.radiance_flag();
        // A frame with layers off has no command that renders it.
        let render = (!self.experiment.layers_off.contains(&true)).then(|| {
            format!(
                "lensmap render --scene {} {ems} --camera-position={} --look-at={} --width {} --height {} --supersampling {} --t {} --angle-degrees {} --variant {} --blend {} --format {} {}",
                self.scene_arg,
                v3(c.position),
                v3(c.look_at),
                c.width,
                c.height,
                c.supersampling,
                o.hybrid.tessellation.t,
                // At f32 precision: the trip through radians does not show (3, not
                // 3.0000000000000004), and the radians it gives back are the same.
                o.hybrid.angle_radians.to_degrees() as f32,
                o.compositing.variant().name(),
                o.compositing.blend().name(),
                o.format.name(),
                crate::common::tracer_flags(&o.hybrid)
            )
        });
        let json = serde_json::json!({
            "frame": self.frame,
            "device": self.runner.gpu().device_name(),
            "driver": self.runner.gpu().device_id().driver_description(),
            "swapchain_format": format!("{:?}", presenter.format.format),
            "camera": {
                "position": c.position.to_array(),
                "look_at": c.look_at.to_array(),
                "width": c.width, "height": c.height, "supersampling": c.supersampling,
            },
            "t": o.hybrid.tessellation.t,
            "angle_degrees": o.hybrid.angle_radians.to_degrees() as f32,
            "variant": o.compositing.variant().name(),
            "blend": o.compositing.blend().name(),
            "format": o.format.name(),
            "inferred": self.experiment.inferred,
            "layers_off": self.experiment.layers_off,
            "render": render,
            "files": [png, exr.clone(), window_png],
        });
        crate::common::write_json(&with(".json"), &json)?;
        self.note(format!("screenshot {}", png.display()));
        say!("screenshot: {} (.exr, -window.png, .json)", png.display());
        Ok(())
    }
}

/// Names joined for a line: `a, b`.
fn join(names: &[&String]) -> String {
    names
        .iter()
        .map(|s| s.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}
