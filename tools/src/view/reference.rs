//! The reference ray tracer for the viewer's camera, on a thread of its own so that the window
//! keeps drawing. One render at a time: asking for another camera cancels the one under way
//! (it stops at its next row), it is not queued.

use std::sync::{
    Arc,
    atomic::{AtomicBool, AtomicU32, Ordering},
    mpsc::{self, Receiver, Sender},
};
use std::thread::JoinHandle;

use lensmap::{
    scene::Camera,
    trace::{
        TraceOptions, image::ReferenceImage, image::render_reference_cancellable, world::TraceScene,
    },
};

/// A render under way.
struct Pending {
    camera: Camera,
    cancel: Arc<AtomicBool>,
    rows: Arc<AtomicU32>,
}

/// A finished render for `camera`.
pub struct Finished {
    /// The camera it was rendered for.
    pub camera: Camera,
    /// The image, or why the ray tracer refused the camera.
    pub image: Result<ReferenceImage, String>,
}

struct Request {
    scene: Arc<TraceScene>,
    camera: Camera,
    cancel: Arc<AtomicBool>,
    rows: Arc<AtomicU32>,
}

/// The background reference renderer.
pub struct ReferenceWorker {
    requests: Option<Sender<Request>>,
    results: Receiver<Finished>,
    pending: Option<Pending>,
    thread: Option<JoinHandle<()>>,
}

impl ReferenceWorker {
    /// A worker thread rendering on a rayon pool of all but one of the machine's threads (at
    /// least one), so that the frame keeps a core.
    pub fn new() -> anyhow::Result<ReferenceWorker> {
        let threads = std::thread::available_parallelism()
            .map_or(1, |n| n.get())
            .saturating_sub(1)
            .max(1);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("lensmap-reference-{i}"))
            .build()?;
        let (requests, inbox) = mpsc::channel::<Request>();
        let (outbox, results) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("lensmap-reference".into())
            .spawn(move || {
                for request in inbox {
                    let image = pool.install(|| {
                        render_reference_cancellable(
                            &request.scene,
                            &request.camera,
                            &TraceOptions::default(),
                            &|rows| {
                                request.rows.fetch_max(rows, Ordering::Relaxed);
                            },
                            &request.cancel,
                        )
                    });
                    let image = match image {
                        Ok(Some(image)) => Ok(image),
                        // Cancelled: nobody waits for it.
                        Ok(None) => continue,
                        Err(e) => Err(e.to_string()),
                    };
                    let finished = Finished {
                        camera: request.camera,
                        image,
                    };
                    if outbox.send(finished).is_err() {
                        break;
                    }
                }
            })?;
        Ok(ReferenceWorker {
            requests: Some(requests),
            results,
            pending: None,
            thread: Some(thread),
        })
    }

    /// Makes sure the reference under way is for `camera`: a render for another camera is
    /// cancelled and this one started. Nothing happens when it already is.
    pub fn want(&mut self, scene: &Arc<TraceScene>, camera: &Camera) {
        if self.pending.as_ref().is_some_and(|p| p.camera == *camera) {
            return;
        }
        self.cancel();
        let cancel = Arc::new(AtomicBool::new(false));
        let rows = Arc::new(AtomicU32::new(0));
        let request = Request {
            scene: Arc::clone(scene),
            camera: *camera,
            cancel: Arc::clone(&cancel),
            rows: Arc::clone(&rows),
        };
        if let Some(requests) = &self.requests
            && requests.send(request).is_ok()
        {
            self.pending = Some(Pending {
                camera: *camera,
                cancel,
                rows,
            });
        }
    }

    /// Cancels the render under way, if any.
    pub fn cancel(&mut self) {
        if let Some(pending) = self.pending.take() {
            pending.cancel.store(true, Ordering::Relaxed);
        }
    }

    /// The share of the render under way that is done, in [0, 1], if one is.
    pub fn progress(&self) -> Option<f32> {
        self.pending
            .as_ref()
            .map(|p| p.rows.load(Ordering::Relaxed) as f32 / p.camera.height.max(1) as f32)
    }

    /// A finished render for the camera still wanted, if one arrived (others are dropped).
    pub fn poll(&mut self) -> Option<Finished> {
        while let Ok(finished) = self.results.try_recv() {
            if self
                .pending
                .as_ref()
                .is_some_and(|p| p.camera == finished.camera)
            {
                self.pending = None;
                return Some(finished);
            }
        }
        None
    }
}

impl Drop for ReferenceWorker {
    fn drop(&mut self) {
        self.cancel();
        // Closing the channel ends the thread's loop once the cancelled render returns.
        self.requests = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}
