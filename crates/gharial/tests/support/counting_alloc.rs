//! A global allocator that counts allocations, per thread and in total, for the tests
//! that prove hot paths allocate nothing. A test binary includes it with
//! `#[path = "support/counting_alloc.rs"] mod counting_alloc;` and declares
//! `#[global_allocator] static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;`
//! (each test binary has its own allocator; tests of a binary run on several threads).
// A global allocator can only be written with `unsafe`; it forwards to `System`.
#![allow(unsafe_code, dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts allocations and forwards to the system allocator.
pub struct Counting;

static TOTAL: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Allocations made by the current thread (const-initialised, no destructor: usable
    /// from the allocator).
    static LOCAL: Cell<usize> = const { Cell::new(0) };
}

fn record() {
    TOTAL.fetch_add(1, Ordering::SeqCst);
    LOCAL.with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        record();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        record();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations made by the current thread while `f` runs.
pub fn local_allocations_during(f: impl FnOnce()) -> usize {
    let before = LOCAL.with(|c| c.get());
    f();
    LOCAL.with(|c| c.get()) - before
}

/// Allocations made by every thread while `f` runs (meaningful when no other test of
/// the binary runs concurrently).
pub fn allocations_during(f: impl FnOnce()) -> usize {
    let before = TOTAL.load(Ordering::SeqCst);
    f();
    TOTAL.load(Ordering::SeqCst) - before
}

/// Allocations of the current thread in five calls of `f` after one warm-up call
/// (thread-local caches of the matrix kernels are set up lazily).
pub fn allocations(mut f: impl FnMut()) -> usize {
    f();
    local_allocations_during(|| {
        for _ in 0..5 {
            f();
        }
    })
}
