//! The group operations and Jacobians of the spaces do not allocate, counted with a
//! global allocator.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;

use faer::Mat;
use gharial::spaces::{Arg, CartesianProduct, Manifold, SE2, SE3, SO2, SO3, TangentBundle, VectorSpace};
use rand::SeedableRng;

/// Counts the allocations of the current thread (tests run on several threads).
struct Counting;

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

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations(f: impl FnOnce()) -> usize {
    let before = COUNT.with(|c| c.get());
    f();
    COUNT.with(|c| c.get()) - before
}

#[test]
fn space_operations_do_not_allocate() {
    // The counter sees allocations.
    assert!(allocations(|| drop(std::hint::black_box(vec![0u8; 16]))) >= 1);
    let spaces: Vec<Arc<dyn Manifold>> = vec![
        Arc::new(VectorSpace::new(4)),
        Arc::new(SO2),
        Arc::new(SO3),
        Arc::new(SE2),
        Arc::new(SE3),
        Arc::new(CartesianProduct::new(vec![
            Arc::new(SE3),
            Arc::new(VectorSpace::new(6)),
        ])),
        Arc::new(TangentBundle::new(Arc::new(CartesianProduct::pair(
            Arc::new(SO3),
            Arc::new(SE2),
        )))),
    ];
    for m in &spaces {
        let (nx, ndx) = (m.nx(), m.ndx());
        let (mut x, mut y, mut z) = (vec![0.0; nx], vec![0.0; nx], vec![0.0; nx]);
        let mut rng = rand::rngs::SmallRng::seed_from_u64(3);
        m.random(&mut rng, &mut x);
        let v: Vec<f64> = (0..ndx).map(|i| 0.1 * (i as f64 + 1.0)).collect();
        let mut d = vec![0.0; ndx];
        let mut j = Mat::<f64>::zeros(ndx, ndx);
        let mut t = Mat::<f64>::zeros(ndx, 5);
        let (mut tm, mut tmi) = (Mat::<f64>::zeros(nx, ndx), Mat::<f64>::zeros(ndx, nx));
        let n = allocations(|| {
            for _ in 0..10 {
                m.integrate(&x, &v, &mut y);
                m.difference(&x, &y, &mut d);
                m.interpolate(&x, &y, 0.3, &mut z);
                for arg in [Arg::First, Arg::Second] {
                    m.jintegrate(&x, &v, arg, j.as_mut());
                    m.jdifference(&x, &y, arg, j.as_mut());
                    m.jintegrate_transport(&x, &v, arg, t.as_mut());
                }
                m.tangent_map(&x, tm.as_mut());
                m.tangent_map_inverse(&x, tmi.as_mut());
                m.normalize(&mut z);
                assert!(m.is_valid(&z));
            }
        });
        assert_eq!(n, 0, "{m:?} allocated {n} times");
    }
}
