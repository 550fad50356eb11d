//! The allocation budget of a fuzz target: a global allocator that counts the bytes live on the
//! Rust heap and aborts (a crash afl records) when an allocation would take them past
//! [`BUDGET_BYTES`]. afl's own `-m` limit counts virtual memory, which the Vulkan driver and
//! LLVM reserve by the gigabyte, so it cannot tell an input's allocations apart from them.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The most bytes an input may have live on the Rust heap at once: 512 MiB.
pub const BUDGET_BYTES: usize = 512 << 20;

/// The system allocator, counting; install it with `#[global_allocator]`.
pub struct Budget {
    live: AtomicUsize,
}

impl Budget {
    /// A counter at zero.
    pub const fn new() -> Budget {
        Budget {
            live: AtomicUsize::new(0),
        }
    }

    /// Counts `size` more bytes, aborting past the budget.
    fn charge(&self, size: usize) {
        let live = self
            .live
            .fetch_add(size, Ordering::Relaxed)
            .saturating_add(size);
        if live > BUDGET_BYTES {
            // No allocation here: the message is a static string written straight to stderr.
            let message = b"lensmap-fuzz: allocation past the 512 MiB budget\n";
            // SAFETY: writing a valid buffer of its own length to file descriptor 2.
            unsafe { libc_write(2, message.as_ptr(), message.len()) };
            std::process::abort();
        }
    }
}

impl Default for Budget {
    fn default() -> Budget {
        Budget::new()
    }
}

unsafe extern "C" {
    #[link_name = "write"]
    fn libc_write(fd: i32, buffer: *const u8, count: usize) -> isize;
}

// SAFETY: every call is passed to the system allocator unchanged; only counters are added.
unsafe impl GlobalAlloc for Budget {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        self.charge(layout.size());
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        self.charge(layout.size());
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, pointer: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(pointer, layout) };
        self.live.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, pointer: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            self.charge(new_size - layout.size());
        }
        // SAFETY: the caller's contract, passed on.
        let moved = unsafe { System.realloc(pointer, layout, new_size) };
        if new_size < layout.size() {
            self.live
                .fetch_sub(layout.size() - new_size, Ordering::Relaxed);
        }
        moved
    }
}
