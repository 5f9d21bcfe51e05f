//! Encoding into a reused buffer allocates nothing: counted with a global
//! allocator (this file is its own test binary, with one test, so no other
//! thread allocates meanwhile).

use acch_ros2::msg::{
    CameraInfo, Header, Image, ImageRef, PoseWithCovarianceStamped, TFMessage, TransformStamped,
    encode_as,
};
use acch_ros2::{Attachment, AttachmentFormat, encode};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_during(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    f();
    ALLOCATIONS.load(Ordering::Relaxed) - before
}

#[test]
fn encoding_into_warm_buffers_does_not_allocate() {
    let pose = PoseWithCovarianceStamped::default();
    let info = CameraInfo {
        d: vec![0.0; 5],
        ..Default::default()
    };
    let tf = TFMessage {
        transforms: vec![TransformStamped::default(); 3],
    };
    let pixels = vec![7u8; 640 * 480 * 3];
    let header = Header::default();
    let image = ImageRef {
        header: &header,
        height: 480,
        width: 640,
        encoding: "rgb8",
        is_bigendian: 0,
        step: 640 * 3,
        data: &pixels,
    };
    let att = Attachment {
        sequence: 1,
        source_timestamp_ns: 2,
        gid: [3; 16],
    };
    let mut buf = Vec::new();
    let mut att_buf = Vec::new();
    // Warm up: the buffers grow to the largest message once.
    encode_as::<Image, _>(&image, &mut buf).unwrap();
    att.encode(AttachmentFormat::Legacy, &mut att_buf);

    let n = allocations_during(|| {
        for _ in 0..10 {
            encode(&pose, &mut buf).unwrap();
            encode(&info, &mut buf).unwrap();
            encode(&tf, &mut buf).unwrap();
            encode_as::<Image, _>(&image, &mut buf).unwrap();
            att.encode(AttachmentFormat::Current, &mut att_buf);
            att.encode(AttachmentFormat::Legacy, &mut att_buf);
        }
    });
    assert_eq!(n, 0, "encoding allocated {n} times");
    // The counter counts: encoding into a fresh buffer allocates (else the
    // zero above would hold for a counter that never moves).
    let fresh = allocations_during(|| {
        let mut cold = Vec::new();
        encode(&pose, &mut cold).unwrap();
        std::hint::black_box(&cold);
    });
    assert!(
        fresh >= 1,
        "a fresh buffer's encoding counted {fresh} allocations"
    );
}
