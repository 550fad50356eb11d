//! The timeline semaphore frames in flight are tracked by.

use std::sync::Arc;

use ash::vk;

use super::{Gpu, GpuError, VkContext, context::Shared};

/// A timeline semaphore: a counter the queue raises as submissions complete. Frames in flight
/// each signal the next value, and the host waits for a frame by its value.
pub struct Timeline {
    shared: Arc<Shared>,
    semaphore: vk::Semaphore,
}

impl Timeline {
    /// A timeline starting at 0.
    pub fn new(gpu: &Gpu) -> Result<Timeline, GpuError> {
        let mut kind = vk::SemaphoreTypeCreateInfo::default()
            .semaphore_type(vk::SemaphoreType::TIMELINE)
            .initial_value(0);
        let info = vk::SemaphoreCreateInfo::default().push_next(&mut kind);
        // SAFETY: valid create info; destroyed in Drop.
        let semaphore =
            unsafe { gpu.shared.device.create_semaphore(&info, None) }.vk("vkCreateSemaphore")?;
        Ok(Timeline {
            shared: gpu.shared.clone(),
            semaphore,
        })
    }

    /// The semaphore, for a submission to signal or wait for (a host image's
    /// [`crate::render::HostImage::signal`]).
    pub fn handle(&self) -> vk::Semaphore {
        self.semaphore
    }

    /// Whether the counter has reached `value`, without waiting.
    pub fn reached(&self, value: u64) -> Result<bool, GpuError> {
        // SAFETY: a live timeline semaphore of this device.
        let counter = unsafe {
            self.shared
                .device
                .get_semaphore_counter_value(self.semaphore)
        }
        .vk("vkGetSemaphoreCounterValue")?;
        Ok(counter >= value)
    }

    /// Blocks until the counter reaches `value` (at once for 0).
    pub fn wait(&self, value: u64) -> Result<(), GpuError> {
        if value == 0 {
            return Ok(());
        }
        let semaphores = [self.semaphore];
        let values = [value];
        let info = vk::SemaphoreWaitInfo::default()
            .semaphores(&semaphores)
            .values(&values);
        // SAFETY: a live timeline semaphore of this device.
        unsafe { self.shared.device.wait_semaphores(&info, u64::MAX) }.vk("vkWaitSemaphores")
    }
}

impl Drop for Timeline {
    fn drop(&mut self) {
        // SAFETY: nothing can wait on or signal the semaphore once its owner is gone, except
        // submissions still running, which the idle wait covers.
        unsafe {
            let _ = self.shared.device.device_wait_idle();
            self.shared.device.destroy_semaphore(self.semaphore, None);
        }
    }
}
