//! What the overlay shows each frame: the settings, the viewpoint samples and their weights,
//! whether the camera has left the view space, the stage table and the notes, gathered from the
//! viewer's state.

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use egui::Pos2;
use glam::Vec4Swizzles;
use lensmap::runner::HostFrame;

use super::{App, MAX_WIREFRAME_EDGES, NOTE_SECONDS, join};
use crate::view::{keys::ReferenceView, overlay::OverlayView, reference::ReferenceWorker};

/// The per-frame figures, smoothed (exponential moving average, a tenth of each new frame).
#[derive(Default)]
pub(super) struct Smoothed {
    values: HashMap<&'static str, f64>,
}

impl Smoothed {
    const WEIGHT: f64 = 0.1;

    pub(super) fn add(&mut self, name: &'static str, value: f64) {
        let v = self.values.entry(name).or_insert(value);
        *v += Self::WEIGHT * (value - *v);
    }

    pub(super) fn get(&self, name: &str) -> f64 {
        self.values.get(name).copied().unwrap_or(0.0)
    }
}

impl App {
    /// What the overlay shows this frame.
    pub(super) fn overlay_view(&mut self, frame: Option<&HostFrame>) -> OverlayView {
        let now = Instant::now();
        self.notes
            .retain(|(_, at)| now.duration_since(*at).as_secs_f32() < NOTE_SECONDS);
        let e = &self.experiment;
        let o = &e.options;
        let hybrid = self.hybrid();
        let layers = hybrid
            .lenses()
            .iter()
            .map(|l| l.shells.len())
            .max()
            .unwrap_or(0);
        let layer_marks: String = (0..layers)
            .map(|i| {
                if e.layer_on(i) {
                    format!("{} ", i + 1)
                } else {
                    "- ".into()
                }
            })
            .collect();
        let ems = match (&self.ems.bake, e.inferred) {
            (Some(dir), true) => format!("inferred EMs ({})", dir.display()),
            _ => "projected EMs".to_owned(),
        };
        let settings = vec![
            format!("{} · {}", self.scene.name, self.runner.gpu().device_id()),
            format!(
                "{ems} · {} · {} · {}",
                o.compositing.variant().name(),
                o.compositing.blend().name(),
                o.format.name()
            ),
            format!(
                "t = {} · angle {:.1}° · layers {layer_marks}· wireframe {}",
                o.hybrid.tessellation.t,
                o.hybrid.angle_radians.to_degrees(),
                if e.wireframe { "on" } else { "off" }
            ),
            format!(
                "camera ({:.2}, {:.2}, {:.2}) → ({:.2}, {:.2}, {:.2}), {}×{}×{}²",
                self.camera.position.x,
                self.camera.position.y,
                self.camera.position.z,
                self.camera.look_at.x,
                self.camera.look_at.y,
                self.camera.look_at.z,
                self.camera.width,
                self.camera.height,
                self.camera.supersampling
            ),
        ];
        let blend = hybrid.viewpoint_blend(
            &self.camera,
            self.experiment.options.hybrid.viewpoint_blending,
        );
        let weights: Vec<String> = blend
            .samples
            .iter()
            .map(|(i, w)| format!("{i} ×{w:.2}"))
            .collect();
        let shared = hybrid.lenses().iter().all(|l| l.maps.len() == 1);
        let viewpoints = if shared {
            "viewpoints: projected EMs are the same at every sample".to_owned()
        } else {
            format!("viewpoint samples: {}", weights.join(", "))
        };
        let outside = hybrid.view_space_fit(&self.camera).and_then(|fit| {
            (fit.outside && !shared).then(|| {
                if fit.surface {
                    format!(
                        "OUTSIDE THE VIEW SPACE: {:.1}° from its triangles, blending their nearest point",
                        fit.outside_radians.to_degrees()
                    )
                } else {
                    format!(
                        "OUTSIDE THE VIEW SPACE: {:.1}° from sample {}, samples are {:.1}° apart",
                        fit.nearest_radians.to_degrees(),
                        fit.nearest,
                        fit.spacing_radians.to_degrees()
                    )
                }
            })
        });
        let st = &self.stats;
        let ms = |name: &str| format!("{:.1} ms", st.get(name));
        let count = |name: &str| format!("{:.0}", st.get(name));
        let mut table = vec![
            (
                "frame rate".to_owned(),
                format!("{:.1} fps", 1e3 / st.get("frame").max(1e-9)),
            ),
            ("latency".to_owned(), ms("latency")),
            ("trace".to_owned(), ms("trace")),
            ("tessellation".to_owned(), ms("tessellation")),
            ("texgen".to_owned(), ms("texgen")),
            ("assemble".to_owned(), ms("assemble")),
            ("upload".to_owned(), ms("upload")),
            ("record".to_owned(), ms("record")),
            ("GPU".to_owned(), ms("gpu")),
            ("overlay + present".to_owned(), ms("overlay")),
            ("CPU total".to_owned(), ms("total")),
            ("rays".to_owned(), count("rays")),
            ("triangle tests".to_owned(), count("triangle tests")),
            ("vertices traced".to_owned(), count("vertices")),
            ("lens triangles".to_owned(), count("triangles")),
            ("passes".to_owned(), count("passes")),
        ];
        table.extend(frame_rows(frame));
        let mut notes: Vec<String> = self.notes.iter().map(|(n, _)| n.clone()).collect();
        if let Some(error) = &self.frame_error {
            notes.push(format!("frame not rendered: {error}"));
        }
        let entered: Vec<&String> = self
            .inside
            .iter()
            .filter(|s| !self.start_inside.contains(s))
            .collect();
        if !entered.is_empty() {
            notes.push(format!(
                "inside layer shell {} (the start camera is not)",
                join(&entered)
            ));
        }
        let wireframe = if e.wireframe {
            self.wireframe_edges(&mut notes)
        } else {
            Vec::new()
        };
        let (reference, image) = self.reference_view();
        OverlayView {
            settings,
            table,
            viewpoints,
            outside,
            notes,
            reference,
            help: self.experiment.help,
            wireframe,
            image,
        }
    }

    /// The last frame's tessellation as window-pixel edges with their subdivision depth (each
    /// edge once; edges with an end behind the eye left out).
    pub(super) fn wireframe_edges(&self, notes: &mut Vec<String>) -> Vec<([Pos2; 2], u8)> {
        let Some(wireframe) = self.runner.last_wireframe() else {
            return Vec::new();
        };
        let view_proj = self.camera.view_proj(0.05, 1000.0);
        let (w, h) = (self.camera.width as f32, self.camera.height as f32);
        let mut edges = Vec::new();
        let mut seen = HashSet::new();
        for lens in &wireframe.lenses {
            let screen: Vec<Option<Pos2>> = lens
                .positions
                .iter()
                .map(|p| {
                    let clip = view_proj * p.extend(1.0);
                    (clip.w > 1e-6).then(|| {
                        let ndc = clip.xy() / clip.w;
                        Pos2::new((ndc.x * 0.5 + 0.5) * w, (ndc.y * 0.5 + 0.5) * h)
                    })
                })
                .collect();
            seen.clear();
            for (triangle, &depth) in lens.triangles.iter().zip(&lens.depths) {
                for k in 0..3 {
                    let (a, b) = (triangle[k], triangle[(k + 1) % 3]);
                    if !seen.insert((a.min(b), a.max(b))) {
                        continue;
                    }
                    if let (Some(Some(pa)), Some(Some(pb))) =
                        (screen.get(a as usize), screen.get(b as usize))
                    {
                        edges.push(([*pa, *pb], depth));
                    }
                }
            }
        }
        if edges.len() > MAX_WIREFRAME_EDGES {
            notes.push(format!(
                "wireframe not drawn: {} edges (more than {MAX_WIREFRAME_EDGES}); raise t",
                edges.len()
            ));
            return Vec::new();
        }
        edges
    }

    /// The reference's state line and image.
    pub(super) fn reference_view(
        &self,
    ) -> (Option<String>, Option<(ReferenceView, egui::TextureHandle)>) {
        let mode = self.experiment.reference;
        if mode == ReferenceView::Off {
            return (None, None);
        }
        if let Some(compared) = &self.compared
            && compared.key.camera == self.camera
        {
            let line = match &compared.psnr {
                Ok(db) => format!("reference ready: lens PSNR {db:.2} dB"),
                Err(why) => format!("reference ready: no lens PSNR ({why})"),
            };
            let texture = match mode {
                ReferenceView::Difference => compared.difference_texture.clone(),
                _ => compared.reference_texture.clone(),
            };
            return (Some(line), Some((mode, texture)));
        }
        let progress = self
            .reference
            .as_ref()
            .and_then(ReferenceWorker::progress)
            .unwrap_or(0.0);
        (
            Some(format!(
                "reference: ray tracing this camera, {:.0}% (moving the camera cancels it)",
                100.0 * progress
            )),
            None,
        )
    }
}

/// The overlay's rows about the frame itself: reused whole, and the radiance maps the glossy
/// pass read (reflection-space IBR).
fn frame_rows(frame: Option<&HostFrame>) -> Vec<(String, String)> {
    let mut rows = Vec::new();
    if frame.is_some_and(|f| f.stats.reused) {
        rows.push(("frame".to_owned(), "reused (still camera)".to_owned()));
    }
    if let Some(f) = frame.filter(|f| f.stats.glossy_maps > 0) {
        rows.push((
            "glossy maps read".to_owned(),
            f.stats.glossy_maps.to_string(),
        ));
    }
    rows
}
