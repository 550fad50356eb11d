//! `lensmap view --script FILE`: timed camera moves, key presses, resizes and screenshots
//! replayed in the window, so that tests and demos drive the viewer deterministically without
//! synthetic window-system events. The clock is the frame number, not wall time: a step runs
//! before the frame of its number is drawn, whatever the machine's speed.
//!
//! ```toml
//! path = "orbit"        # optional: the camera follows a path, one pose per frame
//! frames = 60           # the frames of that orbit (default 60)
//!
//! [[step]]
//! frame = 10
//! keys = ["x", "v"]     # key names as in `lensmap view --help`
//! [[step]]
//! frame = 20
//! resize = [480, 360]   # the window's inner size, pixels
//! [[step]]
//! frame = 30
//! camera = { position = [0, 1, 4], look_at = [0, 1, 0] }
//! orbit = [15, 5]       # degrees yaw and pitch, as a left drag
//! zoom = 0.9
//! [[step]]
//! frame = 59
//! screenshot = "out/shot"   # out/shot.png, .exr, -window.png and .json
//! ```
//!
//! The viewer closes after the frame of the last step.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Deserialize;

use super::keys::{self, Action};
use crate::common::BadUsage;

/// A script file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScriptFile {
    path: Option<String>,
    frames: Option<usize>,
    #[serde(default)]
    step: Vec<StepFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StepFile {
    frame: usize,
    #[serde(default)]
    keys: Vec<String>,
    resize: Option<[u32; 2]>,
    camera: Option<PoseFile>,
    orbit: Option<[f32; 2]>,
    zoom: Option<f32>,
    screenshot: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseFile {
    position: [f32; 3],
    look_at: [f32; 3],
}

/// A checked script.
#[derive(Clone, Debug, PartialEq)]
pub struct Script {
    /// The camera path the camera follows, one pose per frame (`orbit` or a path file), if any.
    pub path: Option<String>,
    /// Frames of an orbit path.
    pub frames: usize,
    /// The steps, by frame, in file order within a frame.
    pub steps: Vec<Step>,
}

/// What happens before one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Step {
    /// The frame it runs before.
    pub frame: usize,
    /// Keys pressed, in order.
    pub keys: Vec<Action>,
    /// The window's new inner size.
    pub resize: Option<(u32, u32)>,
    /// A camera pose: position and look-at point.
    pub camera: Option<(Vec3, Vec3)>,
    /// An orbit, degrees yaw and pitch.
    pub orbit: Option<(f32, f32)>,
    /// A zoom factor (< 1 closer).
    pub zoom: Option<f32>,
    /// A screenshot's path without extension.
    pub screenshot: Option<PathBuf>,
}

impl Script {
    /// Reads and checks a script; one line naming the file, the step and the fix otherwise.
    pub fn load(file: &Path) -> Result<Script, BadUsage> {
        let text = std::fs::read_to_string(file).map_err(|e| {
            BadUsage(format!(
                "{}: cannot read the script ({e}); give a TOML file of [[step]] tables (docs/viewer.md#scripts)",
                file.display()
            ))
        })?;
        Script::parse(&text, file)
    }

    /// Parses a script's text; `file` is the name messages give.
    pub fn parse(text: &str, file: &Path) -> Result<Script, BadUsage> {
        let parsed: ScriptFile = toml::from_str(text).map_err(|e| {
            let message = e.message().trim().to_owned();
            let line = e
                .span()
                .map(|span| text[..span.start.min(text.len())].matches('\n').count() + 1);
            BadUsage(format!(
                "{}{}: {message}; a script has optional `path` and `frames` and [[step]] tables with frame, keys, resize, camera, orbit, zoom, screenshot (docs/viewer.md#scripts)",
                file.display(),
                line.map_or_else(String::new, |l| format!(":{l}"))
            ))
        })?;
        let bad = |i: usize, field: &str, problem: String, fix: &str| {
            BadUsage(format!(
                "{}: step[{i}].{field}: {problem}; {fix}",
                file.display()
            ))
        };
        if parsed.step.is_empty() {
            return Err(BadUsage(format!(
                "{}: the script has no [[step]]; add at least one (its frame ends the script)",
                file.display()
            )));
        }
        let mut steps = Vec::with_capacity(parsed.step.len());
        for (i, s) in parsed.step.into_iter().enumerate() {
            let keys = s
                .keys
                .iter()
                .map(|k| {
                    keys::action(k).ok_or_else(|| {
                        bad(
                            i,
                            "keys",
                            format!("no key \"{k}\""),
                            "use the names `lensmap view --help` lists",
                        )
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            if let Some([w, h]) = s.resize
                && (w == 0 || h == 0 || w > 8192 || h > 8192)
            {
                return Err(bad(
                    i,
                    "resize",
                    format!("{w}×{h}"),
                    "give a size from 1×1 to 8192×8192",
                ));
            }
            let camera = match s.camera {
                Some(pose) => {
                    let (p, l) = (Vec3::from(pose.position), Vec3::from(pose.look_at));
                    if !p.is_finite() || !l.is_finite() || p.distance(l) <= 0.0 {
                        return Err(bad(
                            i,
                            "camera",
                            format!("position {p} and look_at {l}"),
                            "give finite points apart from each other",
                        ));
                    }
                    Some((p, l))
                }
                None => None,
            };
            if let Some([yaw, pitch]) = s.orbit
                && !(yaw.is_finite() && pitch.is_finite())
            {
                return Err(bad(
                    i,
                    "orbit",
                    format!("[{yaw}, {pitch}]"),
                    "give finite degrees",
                ));
            }
            if let Some(zoom) = s.zoom
                && !(zoom.is_finite() && zoom > 0.0)
            {
                return Err(bad(
                    i,
                    "zoom",
                    zoom.to_string(),
                    "give a factor > 0 (< 1 moves closer)",
                ));
            }
            if let Some(previous) = steps.last().map(|p: &Step| p.frame)
                && s.frame < previous
            {
                return Err(bad(
                    i,
                    "frame",
                    format!("{} comes after frame {previous}", s.frame),
                    "list the steps in frame order",
                ));
            }
            steps.push(Step {
                frame: s.frame,
                keys,
                resize: s.resize.map(|[w, h]| (w, h)),
                camera,
                orbit: s.orbit.map(|[y, p]| (y, p)),
                zoom: s.zoom,
                screenshot: s.screenshot,
            });
        }
        if parsed.frames == Some(0) {
            return Err(BadUsage(format!(
                "{}: frames = 0: an orbit needs at least 1 frame",
                file.display()
            )));
        }
        Ok(Script {
            path: parsed.path,
            frames: parsed.frames.unwrap_or(60),
            steps,
        })
    }

    /// The steps that run before frame `frame`.
    pub fn steps_at(&self, frame: usize) -> impl Iterator<Item = &Step> {
        self.steps.iter().filter(move |s| s.frame == frame)
    }

    /// The frame of the last step: the viewer closes after drawing it.
    pub fn last_frame(&self) -> usize {
        self.steps.last().map_or(0, |s| s.frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Script, String> {
        Script::parse(text, Path::new("s.toml")).map_err(|e| e.0)
    }

    #[test]
    fn a_script_reads_in_frame_order_with_its_keys() {
        let script = parse(
            "path = \"orbit\"\nframes = 30\n[[step]]\nframe = 2\nkeys = [\"x\", \"V\"]\n\
             [[step]]\nframe = 5\nresize = [320, 240]\norbit = [10, -5]\nzoom = 0.5\n\
             [[step]]\nframe = 9\ncamera = { position = [0, 1, 4], look_at = [0, 1, 0] }\nscreenshot = \"out/a\"\n",
        )
        .expect("a good script");
        assert_eq!(script.path.as_deref(), Some("orbit"));
        assert_eq!(script.frames, 30);
        assert_eq!(script.steps.len(), 3);
        assert_eq!(
            script.steps[0].keys,
            vec![Action::Wireframe, Action::Variant]
        );
        assert_eq!(script.steps[1].resize, Some((320, 240)));
        assert_eq!(script.steps[1].orbit, Some((10.0, -5.0)));
        assert_eq!(
            script.steps[2].camera,
            Some((Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 1.0, 0.0)))
        );
        assert_eq!(script.last_frame(), 9);
        assert_eq!(script.steps_at(5).count(), 1);
        assert_eq!(script.steps_at(6).count(), 0);
    }

    #[test]
    fn bad_scripts_are_refused_naming_the_step_and_the_fix() {
        for (text, said) in [
            (
                "[[step]]\nframe = 1\nkeys = [\"z\"]\n",
                "step[0].keys: no key \"z\"",
            ),
            (
                "[[step]]\nframe = 1\nresize = [0, 5]\n",
                "step[0].resize: 0×5",
            ),
            (
                "[[step]]\nframe = 3\n[[step]]\nframe = 1\n",
                "step[1].frame",
            ),
            ("[[step]]\nframe = 1\nzoom = -1.0\n", "step[0].zoom"),
            (
                "[[step]]\nframe = 1\ncamera = { position = [0, 0, 0], look_at = [0, 0, 0] }\n",
                "step[0].camera",
            ),
            (
                "[[step]]\nframe = 1\nteleport = 3\n",
                "s.toml:3: unknown field `teleport`",
            ),
            ("frames = 4\n", "no [[step]]"),
        ] {
            let error = parse(text).expect_err(text);
            assert!(error.contains(said), "{text:?}: {error}");
            assert!(error.starts_with("s.toml"), "{error}");
            assert_eq!(error.lines().count(), 1, "{error}");
        }
    }
}
