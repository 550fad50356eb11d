//! The viewer's keys: one table ([`KEYS`]) that `--help`, the `H` overlay, the window's key
//! events and scripts all read, and the experiment state they change.

use std::{collections::HashMap, sync::Arc};

use lensmap::{
    cubemap::CubeMap,
    hybrid::{VertexTracer, tessellate::TessellationOptions},
    render::{BlendScheme, Compositing, TargetFormat},
    runner::FrameOptions,
};

/// What a key does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Single pass ↔ multipass.
    Variant,
    /// The next blending scheme (the multipass variant's).
    Blend,
    /// The next larger tessellation threshold t.
    TUp,
    /// The next smaller t.
    TDown,
    /// The angle threshold up by [`ANGLE_STEP_DEGREES`].
    AngleUp,
    /// The angle threshold down by [`ANGLE_STEP_DEGREES`].
    AngleDown,
    /// Layer i (0 = nearest shell) on or off, in every lens object.
    Layer(usize),
    /// Projected ↔ inferred layered EMs.
    Ems,
    /// The next framebuffer format.
    Format,
    /// Where the lens vertices are traced: CPU → GPU → auto → CPU.
    Tracer,
    /// The tessellation wireframe, coloured by subdivision depth.
    Wireframe,
    /// The camera to the nearest viewpoint sample.
    Snap,
    /// The camera to the next viewpoint sample.
    NextSample,
    /// The camera to the previous viewpoint sample.
    PreviousSample,
    /// The reference ray tracer: off → side by side → difference → off.
    Reference,
    /// A screenshot: PNG and EXR of the frame, PNG of the window.
    Screenshot,
    /// The key list on screen.
    Help,
    /// Close the viewer.
    Quit,
}

/// Every key: its name (as winit's logical key writes it, lower case; scripts use the same
/// names), what it does, and the words `--help` and `H` show.
pub const KEYS: &[(&str, Action, &str)] = &[
    (
        "v",
        Action::Variant,
        "compositor variant: single pass / multipass",
    ),
    ("b", Action::Blend, "blending scheme (multipass)"),
    ("]", Action::TUp, "tessellation threshold t up"),
    ("[", Action::TDown, "t down"),
    (".", Action::AngleUp, "angle threshold up 0.5°"),
    (",", Action::AngleDown, "angle threshold down 0.5°"),
    ("1", Action::Layer(0), "layer 1 (nearest shell) on/off"),
    ("2", Action::Layer(1), "layer 2 on/off"),
    ("3", Action::Layer(2), "layer 3 on/off"),
    ("4", Action::Layer(3), "layer 4 on/off"),
    ("5", Action::Layer(4), "layer 5 on/off"),
    ("6", Action::Layer(5), "layer 6 on/off"),
    ("e", Action::Ems, "projected / inferred layered EMs"),
    ("f", Action::Format, "framebuffer format"),
    (
        "g",
        Action::Tracer,
        "lens vertices traced on the CPU / GPU / auto",
    ),
    (
        "x",
        Action::Wireframe,
        "tessellation wireframe by subdivision depth",
    ),
    ("n", Action::Snap, "snap to the nearest viewpoint sample"),
    ("arrowright", Action::NextSample, "next viewpoint sample"),
    (
        "arrowleft",
        Action::PreviousSample,
        "previous viewpoint sample",
    ),
    (
        "r",
        Action::Reference,
        "reference ray tracer: side by side / difference / off",
    ),
    (
        "p",
        Action::Screenshot,
        "screenshot (PNG + EXR of the frame, PNG of the window)",
    ),
    ("h", Action::Help, "this list on screen"),
    ("escape", Action::Quit, "close"),
    ("q", Action::Quit, "close"),
];

/// The camera's controls, said after the keys.
pub const CONTROLS: &str = "left drag: orbit around the look-at point · right drag: look around · \
wheel: zoom · w a s d: fly";

/// The thresholds `]` and `[` step through, subpixels.
pub const T_STEPS: [f32; 12] = [
    0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0,
];

/// How far `.` and `,` move the angle threshold, degrees; it stays in
/// [`ANGLE_STEP_DEGREES`, 45°].
pub const ANGLE_STEP_DEGREES: f64 = 0.5;
const MAX_ANGLE_DEGREES: f64 = 45.0;

/// The action of a key name, if it has one.
pub fn action(name: &str) -> Option<Action> {
    let name = name.to_lowercase();
    KEYS.iter().find(|(key, ..)| *key == name).map(|k| k.1)
}

/// The key list, one per line, for `--help` and the `H` overlay.
pub fn help_text() -> String {
    let mut text = String::from("Keys in the window (scripts name them the same way):\n");
    for (key, _, words) in KEYS {
        text.push_str(&format!("  {key:<11} {words}\n"));
    }
    text.push_str(&format!("  {CONTROLS}"));
    text
}

/// The reference ray tracer's place on screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceView {
    /// Not computed.
    Off,
    /// The window's right half shows the reference's right half.
    SideBySide,
    /// The whole window shows |hybrid − reference|, scaled ×4.
    Difference,
}

/// What the keys change: the frame options and what is drawn.
#[derive(Clone, Debug)]
pub struct Experiment {
    /// The frame's options.
    pub options: FrameOptions,
    /// The multipass variant's blending scheme while the single pass (front to back only) is
    /// shown.
    pub multipass_blend: BlendScheme,
    /// Layers turned off (index 0 = nearest shell).
    pub layers_off: Vec<bool>,
    /// Whether the inferred EMs are shown (else projected).
    pub inferred: bool,
    /// The wireframe overlay.
    pub wireframe: bool,
    /// The reference ray tracer.
    pub reference: ReferenceView,
    /// The key list on screen.
    pub help: bool,
}

impl Experiment {
    /// Applies a key that changes the experiment (not the camera, screenshots or quitting: the
    /// window does those) and says what it did, for the overlay.
    pub fn apply(&mut self, action: Action) -> Option<String> {
        let options = &mut self.options;
        let said = match action {
            Action::Variant => {
                // The single pass does not blend: the multipass scheme waits aside.
                options.compositing = match options.compositing {
                    Compositing::SinglePass => Compositing::Multipass(self.multipass_blend),
                    Compositing::Multipass(blend) => {
                        self.multipass_blend = blend;
                        Compositing::SinglePass
                    }
                };
                format!("variant: {}", options.compositing.variant().name())
            }
            Action::Blend => {
                let Compositing::Multipass(blend) = options.compositing else {
                    return Some(
                        "the single pass blends front to back only: key v for multipass".into(),
                    );
                };
                let all = BlendScheme::ALL;
                let at = all.iter().position(|b| *b == blend).unwrap_or(0);
                let next = all[(at + 1) % all.len()];
                options.compositing = Compositing::Multipass(next);
                format!("blending: {}", next.name())
            }
            Action::TUp | Action::TDown => {
                let t = options.hybrid.tessellation.t;
                let next = if action == Action::TUp {
                    T_STEPS.iter().copied().find(|s| *s > t)
                } else {
                    T_STEPS.iter().rev().copied().find(|s| *s < t)
                };
                options.hybrid.tessellation = TessellationOptions {
                    t: next.unwrap_or(t),
                    ..options.hybrid.tessellation
                };
                format!("t = {}", options.hybrid.tessellation.t)
            }
            Action::AngleUp | Action::AngleDown => {
                let step = if action == Action::AngleUp {
                    ANGLE_STEP_DEGREES
                } else {
                    -ANGLE_STEP_DEGREES
                };
                let degrees = (options.hybrid.angle_radians.to_degrees() + step)
                    .clamp(ANGLE_STEP_DEGREES, MAX_ANGLE_DEGREES);
                options.hybrid.angle_radians = degrees.to_radians();
                format!("angle threshold {degrees:.1}°")
            }
            Action::Layer(i) => {
                if self.layers_off.len() <= i {
                    self.layers_off.resize(i + 1, false);
                }
                self.layers_off[i] = !self.layers_off[i];
                format!(
                    "layer {} {}",
                    i + 1,
                    if self.layers_off[i] { "off" } else { "on" }
                )
            }
            Action::Format => {
                options.format = match options.format {
                    TargetFormat::Rgba8 => TargetFormat::Rgba16f,
                    TargetFormat::Rgba16f => TargetFormat::Rgba32f,
                    TargetFormat::Rgba32f => TargetFormat::Rgba8,
                };
                format!("framebuffer {}", options.format.name())
            }
            Action::Tracer => {
                options.hybrid.tracer = match options.hybrid.tracer {
                    VertexTracer::Cpu => VertexTracer::Gpu,
                    VertexTracer::Gpu => VertexTracer::Auto,
                    VertexTracer::Auto => VertexTracer::Cpu,
                };
                format!("vertex tracer: {}", options.hybrid.tracer.name())
            }
            Action::Wireframe => {
                self.wireframe = !self.wireframe;
                format!("wireframe {}", if self.wireframe { "on" } else { "off" })
            }
            Action::Reference => {
                self.reference = match self.reference {
                    ReferenceView::Off => ReferenceView::SideBySide,
                    ReferenceView::SideBySide => ReferenceView::Difference,
                    ReferenceView::Difference => ReferenceView::Off,
                };
                format!("reference: {:?}", self.reference).to_lowercase()
            }
            Action::Help => {
                self.help = !self.help;
                return None;
            }
            Action::Ems
            | Action::Snap
            | Action::NextSample
            | Action::PreviousSample
            | Action::Screenshot
            | Action::Quit => return None,
        };
        Some(said)
    }

    /// Whether layer `i` is on.
    pub fn layer_on(&self, i: usize) -> bool {
        !self.layers_off.get(i).copied().unwrap_or(false)
    }
}

/// `maps[viewpoint sample][layer]` with each layer `off` marks replaced by a transparent map
/// of its size (one a size, made once and kept in `transparent`): the layers switched off.
pub fn with_layers_off(
    maps: &[Vec<Arc<CubeMap>>],
    off: &[bool],
    transparent: &mut HashMap<u32, Arc<CubeMap>>,
) -> Vec<Vec<Arc<CubeMap>>> {
    maps.iter()
        .map(|layers| {
            let mut one = |(i, map): (usize, &Arc<CubeMap>)| {
                if off.get(i).copied().unwrap_or(false) {
                    let uniform = || Arc::new(CubeMap::uniform(map.size, [0.0; 4]));
                    Arc::clone(transparent.entry(map.size).or_insert_with(uniform))
                } else {
                    Arc::clone(map)
                }
            };
            layers.iter().enumerate().map(&mut one).collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn experiment() -> Experiment {
        Experiment {
            options: FrameOptions::default(),
            multipass_blend: BlendScheme::default(),
            layers_off: Vec::new(),
            inferred: false,
            wireframe: false,
            reference: ReferenceView::Off,
            help: false,
        }
    }

    #[test]
    fn every_key_is_named_once_and_found_by_its_name() {
        for (i, (key, action_of_key, _)) in KEYS.iter().enumerate() {
            assert!(KEYS[..i].iter().all(|(k, ..)| k != key), "{key} twice");
            assert_eq!(action(key), Some(*action_of_key));
            assert_eq!(action(&key.to_uppercase()), Some(*action_of_key));
        }
        assert_eq!(action("z"), None);
        let help = help_text();
        assert!(KEYS.iter().all(|(_, _, words)| help.contains(words)));
    }

    #[test]
    fn t_steps_through_the_list_and_stops_at_its_ends() {
        let mut e = experiment();
        e.options.hybrid.tessellation.t = 3.0;
        e.apply(Action::TUp);
        assert_eq!(e.options.hybrid.tessellation.t, 4.0);
        e.apply(Action::TDown);
        e.apply(Action::TDown);
        assert_eq!(e.options.hybrid.tessellation.t, 2.0);
        // A value between steps goes to its neighbours.
        e.options.hybrid.tessellation.t = 2.5;
        e.apply(Action::TUp);
        assert_eq!(e.options.hybrid.tessellation.t, 3.0);
        for _ in 0..20 {
            e.apply(Action::TUp);
        }
        assert_eq!(e.options.hybrid.tessellation.t, 32.0);
        for _ in 0..20 {
            e.apply(Action::TDown);
        }
        assert_eq!(e.options.hybrid.tessellation.t, 0.5);
        e.options.validate().expect("t stays valid");
    }

    #[test]
    fn the_angle_stays_in_its_range_and_the_options_stay_valid() {
        let mut e = experiment();
        for _ in 0..200 {
            e.apply(Action::AngleDown);
        }
        assert_eq!(
            e.options.hybrid.angle_radians.to_degrees(),
            ANGLE_STEP_DEGREES
        );
        for _ in 0..200 {
            e.apply(Action::AngleUp);
        }
        assert!((e.options.hybrid.angle_radians.to_degrees() - 45.0).abs() < 1e-9);
        e.options.validate().expect("the angle stays valid");
    }

    #[test]
    fn toggles_come_back_after_a_full_cycle() {
        let mut e = experiment();
        let start = e.options;
        e.apply(Action::Variant);
        assert_ne!(e.options.compositing, start.compositing);
        e.apply(Action::Variant);
        for _ in 0..3 {
            e.apply(Action::Format);
        }
        assert_eq!(e.options, start);
        let said: Vec<String> = (0..3).filter_map(|_| e.apply(Action::Tracer)).collect();
        assert_eq!(e.options, start, "{said:?}");
        assert!(said.iter().any(|s| s.ends_with("gpu")), "{said:?}");
        // Blending schemes cycle in the multipass variant, wait aside in the single pass, and
        // every state is one the frame accepts.
        e.options.compositing = Compositing::Multipass(start.compositing.blend());
        for _ in 0..BlendScheme::ALL.len() {
            e.apply(Action::Blend);
        }
        assert_eq!(e.options.compositing.blend(), start.compositing.blend());
        e.apply(Action::Blend);
        let chosen = e.options.compositing;
        e.apply(Action::Variant);
        assert_eq!(e.options.compositing, Compositing::SinglePass);
        assert!(e.apply(Action::Blend).is_some_and(|s| s.contains("key v")));
        assert_eq!(e.options.compositing, Compositing::SinglePass);
        e.apply(Action::Variant);
        assert_eq!(e.options.compositing, chosen);
        e.apply(Action::Layer(2));
        assert!(e.layer_on(0) && !e.layer_on(2) && e.layer_on(7));
        e.apply(Action::Layer(2));
        assert!(e.layer_on(2));
        for _ in 0..3 {
            e.apply(Action::Reference);
        }
        assert_eq!(e.reference, ReferenceView::Off);
    }
}
