//! The shape of every stream of a run. Each process opens the streams it
//! uses with these shapes: iceoryx2 sizes shared memory from them up front
//! and refuses a process that opens one with another shape.

use crate::wire::StageId;
use acch_ipc::StreamSpec;

/// Readers of the frame stream: recognition, pose (which fits the object's
/// shape to the pixels), the viewer, the recorder and the ROS 2 image
/// publisher of the seeding process.
const FRAME_SUBSCRIBERS: usize = 5;
/// Readers of a stage's results: the next stage (or, for seeding's, a
/// free-running replay's capture), the launcher, the viewer and the
/// recorder.
const RESULT_SUBSCRIBERS: usize = 4;
/// Results queued per reader before the oldest is dropped.
const RESULT_BUFFER: usize = 8;

/// The frame stream: `frame_history` frames queued per reader.
pub fn frames(frame_history: usize) -> StreamSpec {
    let h = frame_history.max(1);
    StreamSpec {
        name: "frames",
        subscribers: FRAME_SUBSCRIBERS,
        buffer: h,
        borrowed: h + 1,
    }
}

/// Stage `stage`'s result stream.
pub fn results(stage: StageId) -> StreamSpec {
    StreamSpec {
        name: stage.name(),
        subscribers: RESULT_SUBSCRIBERS,
        buffer: RESULT_BUFFER,
        borrowed: 2,
    }
}

/// The stream stage `stage` reads: the frames for recognition, its
/// upstream's results for the others.
pub fn input_of(stage: StageId, frame_history: usize) -> Option<StreamSpec> {
    match stage.upstream()? {
        StageId::Capture => Some(frames(frame_history)),
        up => Some(results(up)),
    }
}
