//! `Model::rate` allocates nothing: a counting global allocator watches
//! this thread while it rates.

mod common;

use acch_confidence::{Kind, Model, TrainConfig, train};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

thread_local! {
    static WATCH: Cell<bool> = const { Cell::new(false) };
}
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if WATCH.with(|w| w.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if WATCH.with(|w| w.get()) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn rating_does_not_allocate() {
    // The counter sees an allocation on this thread.
    WATCH.with(|w| w.set(true));
    drop(std::hint::black_box(vec![1u8; 8]));
    WATCH.with(|w| w.set(false));
    assert_eq!(ALLOCATIONS.swap(0, Ordering::Relaxed), 1);

    let (slices, views) = common::grid();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let responses: Vec<(Vec<f32>, bool)> = (0..40)
        .map(|i| (common::response(&mut rng, &views, i % 2 == 0), i % 2 == 0))
        .collect();
    for kind in [Kind::Features, Kind::Response] {
        let config = TrainConfig {
            epochs: 20,
            ..TrainConfig::new(kind)
        };
        let samples: Vec<(Vec<f32>, bool)> = responses
            .iter()
            .map(|(r, l)| {
                (
                    kind.input(&config.features, r, &slices, &views).unwrap(),
                    *l,
                )
            })
            .collect();
        let model: Model = train(&samples, &config).unwrap();
        // Bad input too: errors are built without allocating.
        let bad = &responses[0].0[1..];
        let mut sum = 0.0;
        WATCH.with(|w| w.set(true));
        for (r, _) in &responses {
            sum += model.rate(r, &slices, &views);
            sum += model.rating(r, &slices, &views).confidence;
        }
        sum += model.rate(bad, &slices, &views);
        WATCH.with(|w| w.set(false));
        assert!(sum.is_finite());
        assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0, "{kind:?}");
    }
}
