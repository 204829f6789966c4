//! A global allocator that counts the allocations of each thread, for the tests that
//! prove hot paths allocate nothing. Include with
//! `#[path = "support/counting_alloc.rs"] mod counting_alloc;` and declare
//! `#[global_allocator] static GLOBAL: counting_alloc::Counting = counting_alloc::Counting;`.
#![allow(unsafe_code, dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Counts the allocations of the current thread (tests run on several threads).
pub struct Counting;

thread_local! {
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        COUNT.with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        COUNT.with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations made by this thread so far.
pub fn count() -> usize {
    COUNT.with(|c| c.get())
}

/// Allocations of five calls of `f` after one warm-up call (thread-local caches of the
/// matrix kernels are set up lazily).
pub fn allocations(mut f: impl FnMut()) -> usize {
    f();
    let before = count();
    for _ in 0..5 {
        f();
    }
    count() - before
}
