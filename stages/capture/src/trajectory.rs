//! A smooth camera trajectory over the hemisphere, as an eye-in-hand arm
//! would move it, with the camera motion between frames.

use std::f64::consts::TAU;

use glam::DAffine3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::camera::{check_distance, wrap_deg, wrap_roll_deg};
use crate::{CaptureError, ViewPose};

/// A seeded, infinitely long, smooth camera path: elevation oscillates inside
/// a band ([45.5, 89.5] deg for [`Trajectory::new`], the database's range;
/// any band with [`Trajectory::with_elevation`]) as a sum of two slow
/// sinusoids; azimuth drifts at a steady rate plus a slow sinusoidal sway and
/// wraps through 360. Speeds stay below about 10 deg/s in θ (scaled by the
/// band's width over 44°) and 30 deg/s in φ, so consecutive frames at 30 fps
/// are close. The distance is constant. The camera does not roll unless
/// [`Trajectory::with_roll`] asks it to.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    fps: f64,
    distance: f64,
    theta_mid: f64,
    theta_amp: [f64; 2],
    theta_freq: [f64; 2],
    theta_phase: [f64; 2],
    phi0: f64,
    phi_rate: f64,
    sway_freq: f64,
    sway_phase: f64,
    roll_max: f64,
    roll_freq: [f64; 2],
    roll_phase: [f64; 2],
}

/// One frame of a [`Trajectory`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryFrame {
    /// Frame number, from 0.
    pub index: u64,
    /// Time of the frame in seconds (`index / fps`).
    pub time_s: f64,
    /// Camera view at this frame.
    pub view: ViewPose,
    /// The camera motion since the previous frame:
    /// `previous_camera_from_current_camera`, i.e. the current camera pose
    /// expressed in the previous camera's frame (identity for frame 0).
    pub camera_motion: DAffine3,
}

/// Amplitudes of the two elevation sinusoids in the default band, whose
/// half-width is [`DEFAULT_HALF_BAND`]; other bands scale them.
const THETA_AMP: [f64; 2] = [17.5, 4.5];
const DEFAULT_HALF_BAND: f64 = 22.0;
const PHI_SWAY: f64 = 25.0;
/// Weights of the two roll sinusoids (they sum to 1, so the roll stays
/// within the amplitude).
const ROLL_WEIGHT: [f64; 2] = [0.7, 0.3];

impl Trajectory {
    /// Elevation band of [`Trajectory::new`], degrees: inside the paper
    /// grid's 45..90.
    pub const DEFAULT_THETA_BAND: (f64, f64) = (45.5, 89.5);

    /// A trajectory drawn from `seed`, sampled at `fps` frames per second, at
    /// camera distance `distance` (bounding radii), elevation in
    /// [`Trajectory::DEFAULT_THETA_BAND`].
    pub fn new(seed: u64, fps: f64, distance: f64) -> Result<Self, CaptureError> {
        let (lo, hi) = Self::DEFAULT_THETA_BAND;
        Self::with_elevation(seed, fps, distance, lo, hi)
    }

    /// As [`Trajectory::new`], with the elevation sweeping
    /// `[theta_min_deg, theta_max_deg]` (0 <= min < max <= 90); the same seed
    /// gives the same path shape in any band. A real arm's camera passes
    /// through views below a database's range: a band below 45° makes the
    /// path do so too.
    pub fn with_elevation(
        seed: u64,
        fps: f64,
        distance: f64,
        theta_min_deg: f64,
        theta_max_deg: f64,
    ) -> Result<Self, CaptureError> {
        let (lo, hi) = (theta_min_deg, theta_max_deg);
        if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo < hi && hi <= 90.0) {
            return Err(CaptureError::InvalidTrajectory {
                reason: format!(
                    "elevation band [{lo}, {hi}] deg must satisfy 0 <= min < max <= 90"
                ),
            });
        }
        if !(fps.is_finite() && fps > 0.0) {
            return Err(CaptureError::InvalidTrajectory {
                reason: format!("frame rate {fps} must be finite and > 0"),
            });
        }
        check_distance(distance)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7472_616a);
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let half = (hi - lo) / 2.0;
        // The roll has its own stream, so the rest of the path does not
        // depend on it.
        let mut roll_rng = ChaCha8Rng::seed_from_u64(seed ^ 0x726f_6c6c);
        let roll_freq = [
            roll_rng.random_range(0.04..0.08),
            roll_rng.random_range(0.10..0.18),
        ];
        let roll_phase = [
            roll_rng.random_range(0.0..TAU),
            roll_rng.random_range(0.0..TAU),
        ];
        Ok(Trajectory {
            fps,
            distance,
            theta_mid: (lo + hi) / 2.0,
            theta_amp: THETA_AMP.map(|a| a * half / DEFAULT_HALF_BAND),
            theta_freq: [rng.random_range(0.02..0.05), rng.random_range(0.08..0.15)],
            theta_phase: [rng.random_range(0.0..TAU), rng.random_range(0.0..TAU)],
            phi0: rng.random_range(0.0..360.0),
            phi_rate: sign * rng.random_range(6.0..15.0),
            sway_freq: rng.random_range(0.03..0.07),
            sway_phase: rng.random_range(0.0..TAU),
            roll_max: 0.0,
            roll_freq,
            roll_phase,
        })
    }

    /// The same path with the camera rolling about its optical axis within
    /// `±max_deg` (0 <= max <= 180): a sum of two slow sinusoids (periods of
    /// about 12-25 s and 5-10 s, drawn from the trajectory's seed), at most
    /// about `0.7 · max_deg` deg/s, so 30° changes by under 1° per frame at
    /// 30 fps. Frame 0 may be rolled. 0 = no roll (the default).
    pub fn with_roll(self, max_deg: f64) -> Result<Self, CaptureError> {
        if !(max_deg.is_finite() && (0.0..=180.0).contains(&max_deg)) {
            return Err(CaptureError::InvalidTrajectory {
                reason: format!("roll amplitude {max_deg} deg must be in [0, 180]"),
            });
        }
        Ok(Trajectory {
            roll_max: max_deg,
            ..self
        })
    }

    /// The camera roll at time `t` seconds, degrees.
    fn roll_at(&self, t: f64) -> f64 {
        if self.roll_max == 0.0 {
            return 0.0;
        }
        let s: f64 = (0..2)
            .map(|i| ROLL_WEIGHT[i] * (TAU * self.roll_freq[i] * t + self.roll_phase[i]).sin())
            .sum();
        wrap_roll_deg((self.roll_max * s).clamp(-self.roll_max, self.roll_max))
    }

    /// Frames per second.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// The camera view at time `t` seconds.
    pub fn view_at(&self, t: f64) -> ViewPose {
        let theta = self.theta_mid
            + self.theta_amp[0] * (TAU * self.theta_freq[0] * t + self.theta_phase[0]).sin()
            + self.theta_amp[1] * (TAU * self.theta_freq[1] * t + self.theta_phase[1]).sin();
        let phi = self.phi0
            + self.phi_rate * t
            + PHI_SWAY * (TAU * self.sway_freq * t + self.sway_phase).sin();
        ViewPose {
            theta_deg: theta.clamp(0.0, 90.0),
            phi_deg: wrap_deg(phi),
            distance: self.distance,
            roll_deg: self.roll_at(t),
        }
    }

    /// The camera's view while frame `index`'s shutter is open for
    /// `shutter_s` seconds, centred on the frame's time: the path
    /// [`crate::Renderer::render_moving_into`] takes (`s` in [-0.5, 0.5],
    /// 0 the frame's own view).
    pub fn during(&self, index: u64, shutter_s: f64) -> impl Fn(f64) -> ViewPose + '_ {
        let time_s = index as f64 / self.fps;
        move |s| self.view_at(time_s + s * shutter_s)
    }

    /// Frame number `index`.
    pub fn frame(&self, index: u64) -> TrajectoryFrame {
        let time_s = index as f64 / self.fps;
        let view = self.view_at(time_s);
        let camera_motion = if index == 0 {
            DAffine3::IDENTITY
        } else {
            let prev = self.view_at((index - 1) as f64 / self.fps);
            prev.camera_from_world() * view.world_from_camera()
        };
        TrajectoryFrame {
            index,
            time_s,
            view,
            camera_motion,
        }
    }

    /// An endless iterator over the frames from frame 0.
    pub fn frames(&self) -> Frames<'_> {
        Frames {
            trajectory: self,
            next: 0,
        }
    }
}

/// Iterator over the frames of a [`Trajectory`] (endless; use `take`).
#[derive(Debug, Clone)]
pub struct Frames<'a> {
    trajectory: &'a Trajectory,
    next: u64,
}

impl Iterator for Frames<'_> {
    type Item = TrajectoryFrame;
    fn next(&mut self) -> Option<TrajectoryFrame> {
        let f = self.trajectory.frame(self.next);
        self.next += 1;
        Some(f)
    }
}

impl<'a> IntoIterator for &'a Trajectory {
    type Item = TrajectoryFrame;
    type IntoIter = Frames<'a>;
    fn into_iter(self) -> Frames<'a> {
        self.frames()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_band_is_swept_and_the_default_band_is_new() {
        let (lo, hi) = Trajectory::DEFAULT_THETA_BAND;
        assert_eq!(
            Trajectory::new(5, 5.0, 5.0).unwrap(),
            Trajectory::with_elevation(5, 5.0, 5.0, lo, hi).unwrap()
        );
        // Over many paths, a [20, 90] band goes well below the database's
        // 45° and never leaves the band.
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        for seed in 0..20 {
            let t = Trajectory::with_elevation(seed, 5.0, 5.0, 20.0, 90.0).unwrap();
            for f in t.frames().take(200) {
                min = min.min(f.view.theta_deg);
                max = max.max(f.view.theta_deg);
            }
        }
        assert!(
            (20.0..30.0).contains(&min) && max <= 90.0 && max > 80.0,
            "{min} {max}"
        );
        for (a, b) in [(50.0, 40.0), (-1.0, 10.0), (10.0, 91.0), (f64::NAN, 10.0)] {
            let e = Trajectory::with_elevation(0, 5.0, 5.0, a, b).unwrap_err();
            assert!(e.to_string().contains("elevation band"), "{e}");
        }
    }

    #[test]
    fn roll_is_smooth_bounded_and_off_by_default() {
        let plain = Trajectory::new(7, 30.0, 5.0).unwrap();
        let rolled = plain.clone().with_roll(30.0).unwrap();
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut prev: Option<f64> = None;
        for (a, b) in plain.frames().zip(rolled.frames()).take(30 * 120) {
            assert_eq!(a.view.roll_deg, 0.0);
            // Only the roll differs.
            assert_eq!(
                (a.view.theta_deg, a.view.phi_deg, a.view.distance),
                (b.view.theta_deg, b.view.phi_deg, b.view.distance)
            );
            let r = b.view.roll_deg;
            assert!(r.abs() <= 30.0, "frame {}: roll {r}", b.index);
            if let Some(p) = prev {
                assert!((r - p).abs() < 1.5, "frame {}: {p} -> {r}", b.index);
            }
            prev = Some(r);
            min = min.min(r);
            max = max.max(r);
        }
        // It really rolls, both ways, over two minutes.
        assert!(min < -15.0 && max > 15.0, "{min} {max}");
        // The camera motion includes the roll.
        let f = rolled.frame(45);
        let prev = rolled.view_at(44.0 / 30.0);
        let expect = prev.camera_from_world() * f.view.world_from_camera();
        assert!(f.camera_motion.abs_diff_eq(expect, 1e-12));
        assert!(
            !f.camera_motion
                .abs_diff_eq(plain.frame(45).camera_motion, 1e-9)
        );
        for bad in [-1.0, 181.0, f64::NAN] {
            let e = plain.clone().with_roll(bad).unwrap_err();
            assert!(e.to_string().contains("roll"), "{e}");
        }
        assert_eq!(plain.clone().with_roll(0.0).unwrap(), plain);
    }
}
