//! A steady stream of frames allocates nothing on the per-frame path, once
//! the buffers have taken their sizes: quantising into the published
//! indices, recognition's region counts written and read back, region
//! growing, the pose stage at a scale that changes every frame, the
//! confidence stage, seeding with fusion, the step both executors take,
//! the JSON written for zenoh, a palette that smooths the frame first, a
//! chain measuring each frame to choose its database set, and the stage
//! process's own loop over iceoryx2. A counting global allocator
//! watches the threads that run them; each check starts with a positive
//! control that proves it counts.
//!
//! One allocation per published sample is iceoryx2's, not ours: 0.10's
//! `Publisher::loan_slice_uninit` puts each loaned sample's shared state in
//! an `Rc` (seen in a backtrace taken from this allocator). The stage loop
//! test holds the loop to exactly that one.

use acch_capture::{Background, Object, Renderer, SceneConfig, ViewPose, ViewSpec};
use acch_core::ViewDatabase;
use acch_pipeline::json::JsonWriter;
use acch_pipeline::stages::{Confidence, Recognised, Stages};
use acch_pipeline::wire::{ArmPose, DatabaseSet, Intrinsics, Maybe};
use acch_pipeline::{Chain, FrameHeader, Hop, PipelineConfig, StageId, StageSettings};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

struct Counting;

thread_local! {
    /// Whether this thread's allocations are the ones watched.
    static WATCHED: Cell<bool> = const { Cell::new(false) };
}
/// Counting is on (watched threads only).
static ARMED: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

fn count() {
    if ARMED.load(Ordering::Relaxed) && WATCHED.with(|w| w.get()) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// The tests share the counter: one at a time.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// Allocations `f` makes on this thread.
fn allocations(f: impl FnOnce()) -> usize {
    WATCHED.with(|w| w.set(true));
    ALLOCATIONS.store(0, Ordering::Relaxed);
    ARMED.store(true, Ordering::Relaxed);
    f();
    ARMED.store(false, Ordering::Relaxed);
    WATCHED.with(|w| w.set(false));
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// A small database with a recognition model and a confidence network (so
/// the confidence stage really rates).
fn database() -> ViewDatabase {
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let plain = Renderer::new(SceneConfig::new(object, Background::default()), 0);
    let grid = ViewSpec::Grid {
        thetas_deg: vec![50.0, 70.0, 90.0],
        phi_step_deg: 30.0,
    };
    let acch_testkit::Trained { mut db, model } =
        acch_testkit::train_on_views("fruitbox", &plain, &grid);
    db.sections
        .insert(acch_recognition::SECTION.to_owned(), model.to_bytes());
    let views = db.views().len();
    // Any network of the response kind that accepts everything: what it
    // says does not matter here, only that seeding then seeds and fuses.
    let samples: Vec<(Vec<f32>, bool)> = (0..16)
        .map(|i| {
            (
                (0..views)
                    .map(|v| ((v * 7 + i) % 11) as f32 / 11.0)
                    .collect(),
                i % 2 == 0,
            )
        })
        .collect();
    let config = acch_confidence::TrainConfig {
        epochs: 5,
        ..acch_confidence::TrainConfig::new(acch_confidence::Kind::Response)
    };
    let mut model = acch_confidence::train(&samples, &config).unwrap();
    model.set_threshold(0.0).unwrap();
    model.store(&mut db);
    db
}

/// Frames of a moving camera at changing distances (the scale read off the
/// region changes every frame), with the arm's pose so seeding fuses.
fn frames() -> Vec<(FrameHeader, Vec<u8>)> {
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let scene = Renderer::new(SceneConfig::new(object, Background::A), 3);
    [
        (55.0, 10.0, 5.0),
        (58.0, 14.0, 4.6),
        (61.0, 19.0, 5.3),
        (64.0, 25.0, 4.8),
        (30.0, 40.0, 5.1),
    ]
    .iter()
    .enumerate()
    .map(|(i, &(t, p, d))| {
        let r = scene.render(&ViewPose::new(t, p, d).unwrap(), i as u64);
        let (w, h) = r.image.dimensions();
        let mut f = FrameHeader::rgb(i as u64, w, h, Intrinsics::from(&r.truth.intrinsics));
        f.envelope.frame.arm = Maybe::Present(ArmPose {
            world_from_camera: r.truth.world_from_camera.to_cols_array(),
        });
        (f, r.image.into_raw())
    })
    .collect()
}

#[test]
fn the_positive_control_counts() {
    let _one = serial();
    assert_eq!(
        allocations(|| drop(std::hint::black_box(Vec::<u8>::with_capacity(8)))),
        1
    );
    // What the pose stage used to do when the scale changed: a new offsets
    // table per frame.
    let params = acch_core::HistogramParams::default();
    assert!(allocations(|| drop(std::hint::black_box(params.offsets(1.1)))) >= 1);
    let mut reused = params.offsets(1.0);
    reused.reserve(64);
    assert_eq!(allocations(|| params.offsets_into(1.1, &mut reused)), 0);
}

#[test]
fn the_chain_and_the_json_allocate_nothing_once_warm() {
    let _one = serial();
    let db = database();
    let frames = frames();
    let (w, h) = (
        frames[0].0.envelope.frame.width,
        frames[0].0.envelope.frame.height,
    );
    let settings = StageSettings {
        width: w,
        height: h,
        // Unknown: the pose stage's scale follows each region.
        distance_m: None,
        unrated: false,
        // The roll search too: its shortlist and turned histogram are
        // the estimator's own buffers.
        roll_search_deg: 45.0,
        light_search: 0,
        verify_shape: true,
    };
    let mut chain = Chain::build(&db, &settings).unwrap();
    let mut json = JsonWriter::default();
    let pass = |chain: &mut Chain, json: &mut JsonWriter| {
        let mut estimated = 0;
        for (f, rgb) in &frames {
            let out = chain.process(f, rgb);
            estimated += out.pose().done().is_some() as usize;
            std::hint::black_box(json.write("fruitbox", &out).unwrap());
        }
        estimated
    };
    // Warm up: buffers take their sizes.
    assert!(
        pass(&mut chain, &mut json) >= 4,
        "the scenes must be estimated"
    );
    let scales: Vec<f32> = frames
        .iter()
        .filter_map(|(f, rgb)| chain.process(f, rgb).pose().done().map(|p| p.scale))
        .collect();
    assert!(
        scales.windows(2).all(|s| s[0] != s[1]),
        "the scale must change from frame to frame: {scales:?}"
    );
    let mut estimated = 0;
    assert_eq!(
        allocations(|| estimated = pass(&mut chain, &mut json)),
        0,
        "allocations over {} frames",
        frames.len()
    );
    assert!(estimated >= 4);
    // Every stage ran: the confidence stage rated and seeding fused.
    let out = chain.process(&frames[3].0, &frames[3].1);
    assert!(out.rating().verdict().is_some(), "{:?}", out.rating());
    assert!(out.seeding.fused.get().is_some());
    // ... and a stage built unrated allocates nothing either.
    let mut stages = Stages::new(&db, &settings).unwrap();
    stages.confidence = acch_pipeline::stages::BySet::sharp_only(Confidence::unrated(&db));
    let mut unrated = Chain::new(stages);
    pass(&mut unrated, &mut json);
    assert_eq!(
        allocations(|| {
            pass(&mut unrated, &mut json);
        }),
        0
    );
    // ... and a chain choosing its database set per frame, measuring each
    // frame, with every other frame noisy enough for the smoothed set.
    let mut smoothed = db.clone();
    smoothed.palette = smoothed
        .palette
        .with_smoothing(acch_core::Smoothing::Binomial);
    let mut choosing = Chain::build_for_sets(&db, Some(&smoothed), &settings).unwrap();
    let mixed: Vec<(FrameHeader, Vec<u8>)> = frames
        .iter()
        .enumerate()
        .map(|(i, (f, rgb))| {
            let mut rgb = rgb.clone();
            if i % 2 == 1 {
                for (k, v) in rgb.iter_mut().enumerate() {
                    let n = (k * 7919 % 13) as i16 - 6;
                    *v = (*v as i16 + n).clamp(0, 255) as u8;
                }
            }
            (*f, rgb)
        })
        .collect();
    let mut sets = Vec::new();
    for (f, rgb) in &mixed {
        sets.push(choosing.process(f, rgb).envelope().imaging.set);
    }
    assert!(sets.contains(&DatabaseSet::Smoothed) && sets.contains(&DatabaseSet::Sharp));
    let after = allocations(|| {
        for (f, rgb) in &mixed {
            std::hint::black_box(json.write("fruitbox", &choosing.process(f, rgb)).unwrap());
        }
    });
    assert_eq!(after, 0, "allocations choosing over {} frames", mixed.len());
}

#[test]
fn a_smoothing_palette_quantises_without_allocating_once_warm() {
    let _one = serial();
    let palette = database()
        .palette
        .with_smoothing(acch_core::Smoothing::Binomial);
    let frames = frames();
    let (w, h) = (
        frames[0].0.envelope.frame.width,
        frames[0].0.envelope.frame.height,
    );
    let mut index = acch_core::IndexImage::default();
    let mut slice = vec![0u8; (w * h) as usize];
    // The first frame sizes this thread's scratch: the control that the
    // smoothing's buffers are counted.
    assert!(allocations(|| palette.quantise_into(&frames[0].1, w, h, &mut index)) >= 1);
    let after = allocations(|| {
        for (_, rgb) in &frames {
            palette.quantise_into(rgb, w, h, &mut index);
            palette.quantise_into_slice(rgb, w, h, &mut slice);
        }
    });
    assert_eq!(after, 0, "allocations over {} frames", frames.len());
    assert_eq!(slice, index.data);
}

#[test]
fn a_stage_process_loop_allocates_only_iceoryx2s_loan_once_warm() {
    let _one = serial();
    let db = database();
    let dir = tempfile::tempdir().unwrap();
    let db_path = dir.path().join("db.acchdb");
    db.save(&db_path).unwrap();
    let frames = frames();
    let (w, h) = (
        frames[0].0.envelope.frame.width,
        frames[0].0.envelope.frame.height,
    );
    let mut cfg = PipelineConfig::default();
    cfg.run.instance = format!("noalloc-{}", std::process::id());
    cfg.run.stage_cpus = acch_ipc::sched::StageCpus::Free;
    cfg.object.db = Some(db_path);
    (cfg.camera.width, cfg.camera.height) = (w, h);
    let _wake = acch_ipc::wake::RunFiles::new(&cfg.run.instance);
    let ipc = cfg.ipc("test").unwrap();
    let ready = ipc.control_listener(acch_pipeline::node::READY).unwrap();
    let output = ipc
        .output::<FrameHeader>(
            acch_pipeline::streams::frames(cfg.run.frame_history),
            3 * (w * h) as usize,
        )
        .unwrap();
    let results = ipc
        .input::<Recognised>(
            acch_pipeline::streams::results(StageId::Recognition),
            acch_ipc::Wake::Event,
        )
        .unwrap();
    // The recognition stage's own process loop, on a thread of its own
    // whose allocations are watched. It runs until the test process ends.
    let stage_cfg = cfg.clone();
    std::thread::spawn(move || {
        let db = stage_cfg.database().unwrap();
        let stage = acch_pipeline::stages::Recognition::new(&db, &stage_cfg.settings(&db).unwrap())
            .unwrap();
        WATCHED.with(|w| w.set(true));
        let _ = acch_pipeline::node::run_stage(&stage_cfg, stage, |_| Ok(()));
    });
    let mut up = false;
    let until = Instant::now() + Duration::from_secs(30);
    while !up && Instant::now() < until {
        ready
            .take(Duration::from_millis(100), |_| up = true)
            .unwrap();
    }
    assert!(up, "the stage did not announce itself");
    let mut sequence = 0u64;
    // Where capture says it wrote the pixels, as capture does: the stage
    // checks it reads them in place.
    let mut locator = acch_ipc::ShmLocator::new();
    let mut stream = |n: usize| {
        let mut got = 0;
        for _ in 0..n {
            for (f, rgb) in &frames {
                let mut header = *f;
                header.envelope.frame.sequence = sequence;
                sequence += 1;
                output
                    .send(rgb, |h, addr| {
                        let (file, offset) = locator.locate(addr).unwrap_or_default();
                        header.location = acch_pipeline::frame::ShmLocation { file, offset };
                        *h = header;
                    })
                    .unwrap();
                let t = Instant::now();
                loop {
                    results.wait(Duration::from_millis(50)).unwrap();
                    if let Some(r) = results.receive().unwrap() {
                        let reads = r.user_header().envelope.reads;
                        assert_eq!((reads.reads, reads.in_place), (1, 1), "read in place");
                        got += 1;
                        break;
                    }
                    assert!(t.elapsed() < Duration::from_secs(10), "no result");
                }
            }
        }
        got
    };
    // Warm up, then watch the stage's thread (this one is not watched).
    assert_eq!(stream(2), 2 * frames.len());
    ALLOCATIONS.store(0, Ordering::Relaxed);
    ARMED.store(true, Ordering::Relaxed);
    let got = stream(3);
    ARMED.store(false, Ordering::Relaxed);
    assert_eq!(got, 3 * frames.len());
    // iceoryx2's one per loan (see the module docs), nothing of ours.
    assert_eq!(
        ALLOCATIONS.load(Ordering::Relaxed),
        got,
        "allocations in the stage loop over {got} frames"
    );
}
