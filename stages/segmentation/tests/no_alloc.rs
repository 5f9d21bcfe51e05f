//! Recognition and segmentation allocate nothing per frame once warm.

use acch_capture::{
    Background, DEFAULT_DISTANCE, Object, Renderer, SceneConfig, ViewPose, ViewSpec,
};
use acch_recognition::Detector;
use acch_segmentation::Segmenter;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn detect_and_segment_do_not_allocate_once_warm() {
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let plain = Renderer::new(SceneConfig::new(object.clone(), Background::default()), 0);
    let grid = ViewSpec::Grid {
        thetas_deg: vec![50.0, 80.0],
        phi_step_deg: 60.0,
    };
    let acch_testkit::Trained { db, model } =
        acch_testkit::train_on_views("fruitbox", &plain, &grid);
    let scene = Renderer::new(SceneConfig::new(object, Background::ClutterSimilar), 3);
    let frames: Vec<_> = [(55.0, 10.0), (85.0, 200.0), (65.0, 290.0)]
        .iter()
        .map(|&(t, p)| {
            db.palette.quantise(
                scene
                    .render(&ViewPose::new(t, p, DEFAULT_DISTANCE).unwrap(), 1)
                    .image
                    .as_raw(),
                640,
                480,
            )
        })
        .collect();
    let mut detector = Detector::new(model, 640, 480).unwrap();
    let mut segmenter = Segmenter::new(640, 480).unwrap();
    let run = |detector: &mut Detector, segmenter: &mut Segmenter| {
        let mut found = 0;
        for f in &frames {
            if let Some(d) = detector.detect(f, Some(1.0)) {
                found += segmenter.segment_detected(f, detector, &d).is_some() as usize;
            }
        }
        found
    };
    // Warm up: buffers take their sizes.
    assert_eq!(run(&mut detector, &mut segmenter), frames.len());
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for _ in 0..3 {
        run(&mut detector, &mut segmenter);
    }
    assert_eq!(
        ALLOCATIONS.load(Ordering::Relaxed) - before,
        0,
        "allocations per frame"
    );
}
