//! What the runner measured: a hybrid frame's image and per-stage costs, repeated frames and
//! compositor-only renders with their medians.

use crate::{
    hybrid::HybridStats,
    render::{FrameTimings, RenderedImage},
};

/// How many frames to render before timing (the first pays for pipeline creation and shader
/// compilation) and how many to time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Repetitions {
    /// Untimed frames first.
    pub warmup: usize,
    /// Timed frames (at least one is rendered).
    pub timed: usize,
}

/// One hybrid frame's image and costs.
#[derive(Clone, Debug)]
pub struct HybridFrame {
    /// The frame at the camera's resolution (box-filtered from the supersampled framebuffer).
    pub image: RenderedImage,
    /// CPU stages.
    pub stats: HybridStats,
    /// GPU upload, rendering and readback, ms.
    pub gpu_ms: f64,
    /// Of which: uploading the frame's data (lens geometry; EMs only when new), ms.
    pub upload_ms: f64,
    /// Of which: recording, executing and reading back the frame.
    pub render: FrameTimings,
    /// Of which: box-filtering the supersampled framebuffer to pixels, ms.
    pub downsample_ms: f64,
    /// Whole frame, ms.
    pub total_ms: f64,
}

impl HybridFrame {
    /// "Other" in the paper's table: everything but vertex tracing, texture coordinates and
    /// tessellation, ms.
    pub fn other_ms(&self) -> f64 {
        (self.total_ms - self.stats.trace_ms - self.stats.texgen_ms - self.stats.tessellation_ms)
            .max(0.0)
    }

    /// What no stage accounts for (waiting, scheduling): the total minus every measured stage,
    /// ms. Near zero for a frame rendered alone; in a stream it includes waiting for the GPU.
    pub fn unaccounted_ms(&self) -> f64 {
        (self.total_ms
            - self.stats.trace_ms
            - self.stats.texgen_ms
            - self.stats.tessellation_ms
            - self.stats.assemble_ms
            - self.upload_ms
            - self.render.record_ms
            - self.render.execute_ms
            - self.render.readback_ms
            - self.downsample_ms)
            .max(0.0)
    }
}

/// A hybrid frame submitted into a host's image ([`FrameRunner::frame_into`](super::FrameRunner::frame_into)): its costs up to
/// the submission (the GPU's part is the host's to time).
#[derive(Clone, Debug)]
pub struct HostFrame {
    /// CPU stages.
    pub stats: HybridStats,
    /// The stats of the frame before, with the device's counts added, when its lens objects
    /// were drawn from the device's buffers ([`HybridStats::counted_on_device`]) and it was
    /// done by the time this frame was submitted (its counts are read then, never waited for);
    /// `None` otherwise.
    pub previous: Option<HybridStats>,
    /// Uploading the frame's data, ms.
    pub upload_ms: f64,
    /// Compiling the plan and recording the command buffer, ms.
    pub record_ms: f64,
    /// Passes recorded (the box filter and the hand-back included).
    pub passes: usize,
    /// From the start of the CPU stages to the submission, ms.
    pub total_ms: f64,
}

impl HostFrame {
    /// The frame's stats with what is counted on the device (rays, triangle tests, vertices
    /// traced, lens triangles, the convex-hull split's and the budget's stops) taken from the
    /// frame before, when this frame was drawn where the GPU tessellation left it
    /// ([`HybridStats::counted_on_device`]): the frame before's once it is done (its counts
    /// are read then), zeros while it is not.
    pub fn counted_stats(&self) -> HybridStats {
        let s = self.stats;
        if !s.counted_on_device {
            return s;
        }
        let counted = self.previous.unwrap_or_default();
        HybridStats {
            counters: counted.counters,
            vertices_traced: counted.vertices_traced,
            triangles_out: counted.triangles_out,
            hull_triangles: counted.hull_triangles,
            stopped_by_budget: counted.stopped_by_budget,
            ..s
        }
    }

    /// "Other" in the paper's table: everything but vertex tracing, texture coordinates and
    /// tessellation, ms (here: assembly, upload, recording and submission).
    pub fn other_ms(&self) -> f64 {
        (self.total_ms - self.stats.trace_ms - self.stats.texgen_ms - self.stats.tessellation_ms)
            .max(0.0)
    }
}

/// Timed hybrid frames of one setting: at least one (made only by
/// [`FrameRunner::timed_frames`](super::FrameRunner::timed_frames)).
#[derive(Clone, Debug)]
pub struct TimedFrames {
    pub(super) frames: Vec<HybridFrame>,
}

impl TimedFrames {
    /// The timed frames in order.
    pub fn frames(&self) -> &[HybridFrame] {
        &self.frames
    }

    /// Median over the frames of one stage's time.
    pub fn median(&self, stage: impl Fn(&HybridFrame) -> f64) -> f64 {
        median(&mut self.frames.iter().map(stage).collect::<Vec<_>>())
    }

    /// The last frame (its image and counters; counters are the same for every frame).
    pub fn last(&self) -> &HybridFrame {
        // `FrameRunner::timed_frames` renders at least one frame.
        &self.frames[self.frames.len() - 1]
    }
}

/// Compositor-only renders of one uploaded frame.
#[derive(Clone, Debug)]
pub struct TimedRenders {
    /// The image of the first (warm-up) render.
    pub image: RenderedImage,
    /// Timings of the timed renders (at least one).
    pub timings: Vec<FrameTimings>,
}

impl TimedRenders {
    /// Median over the timed renders of `stage`.
    pub fn median(&self, stage: impl Fn(&FrameTimings) -> f64) -> f64 {
        median(&mut self.timings.iter().map(stage).collect::<Vec<_>>())
    }
}

/// Median of a sample (0 for none).
pub fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        0.5 * (values[mid - 1] + values[mid])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_even_and_empty_samples() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&mut []), 0.0);
    }

    #[test]
    fn other_is_what_the_papers_three_cpu_stages_leave() {
        let frame = HybridFrame {
            image: RenderedImage {
                width: 1,
                height: 1,
                pixels: vec![[0.0; 4]],
            },
            stats: HybridStats {
                trace_ms: 4.0,
                texgen_ms: 1.0,
                tessellation_ms: 2.0,
                ..HybridStats::default()
            },
            gpu_ms: 2.5,
            upload_ms: 0.5,
            render: FrameTimings {
                record_ms: 0.25,
                execute_ms: 1.0,
                readback_ms: 0.5,
                passes: 3,
                saturated: 0,
                ..FrameTimings::default()
            },
            downsample_ms: 0.25,
            total_ms: 10.0,
        };
        assert_eq!(frame.other_ms(), 3.0);
        // Of the other 3 ms, 2.5 are measured stages.
        assert_eq!(frame.unaccounted_ms(), 0.5);
    }
}
