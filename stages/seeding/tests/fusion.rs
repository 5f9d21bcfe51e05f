//! The view filter against the renderer's ground truth: wrap-around at
//! φ = 0/360, the pole θ = 90, gating, recovery from a wrong start,
//! convergence and covariance.

use acch_capture::{Intrinsics, Trajectory, ViewPose};
use acch_seeding::fusion::{theta_censored, view_of};
use acch_seeding::{
    CovarianceModel, Distance, FilterConfig, FusionError, GridSpacing, Measurement, Outcome,
    Pinhole, SeedInput, ViewFilter, seed,
};
use glam::{DAffine3, DMat3, DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const DISTANCE: f64 = 5.0;

fn phi_err(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// The measurement a single-frame estimate (θ + dθ, φ + dφ) of `view` gives
/// with the object on the optical axis, as the seeding stage builds it
/// (the confidence, once accepted, does not change the measurement).
fn measurement(view: &ViewPose, dtheta: f64, dphi: f64, confidence: f64) -> Measurement {
    Measurement::from_estimate(
        &input(view, dtheta, dphi, confidence),
        &CovarianceModel::default(),
    )
    .unwrap()
}

/// The seed input of the estimate (θ + dθ, φ + dφ) of `view`.
fn input(view: &ViewPose, dtheta: f64, dphi: f64, confidence: f64) -> SeedInput {
    let k = Intrinsics::default();
    let centre = k
        .project(view.camera_from_world().transform_point3(DVec3::ZERO))
        .unwrap();
    {
        SeedInput {
            theta_deg: (view.theta_deg + dtheta).clamp(0.0, 90.0),
            phi_deg: view.phi_deg + dphi,
            roll_deg: 0.0,
            roi_centre_px: centre,
            intrinsics: Pinhole {
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
            },
            distance: Distance::Known {
                value: DISTANCE,
                sigma: 0.05,
            },
            confidence,
            grid: GridSpacing {
                theta_deg: 10.0,
                phi_deg: 10.0,
            },
        }
    }
}

fn view(theta: f64, phi: f64) -> ViewPose {
    ViewPose::new(theta, phi, DISTANCE).unwrap()
}

/// `previous_camera_from_current_camera` between two views.
fn motion(prev: &ViewPose, cur: &ViewPose) -> DAffine3 {
    prev.camera_from_world() * cur.world_from_camera()
}

fn filter() -> ViewFilter {
    ViewFilter::new(FilterConfig::default()).unwrap()
}

fn trace(f: &ViewFilter) -> f64 {
    let c = f.state().unwrap().rotation_covariance;
    c[0][0] + c[1][1] + c[2][2]
}

#[test]
fn view_is_read_back_from_the_pose_everywhere_including_the_pole() {
    for theta in [0.5, 30.0, 45.0, 67.5, 89.0, 89.999, 90.0] {
        for phi in [0.0, 0.001, 45.0, 179.9, 180.0, 270.0, 359.999] {
            let v = view(theta, phi);
            let (t, p) = view_of(&v.camera_from_world());
            assert!((t - theta).abs() < 1e-6, "θ {theta} φ {phi}: θ {t}");
            assert!(phi_err(p, phi) < 1e-6, "θ {theta} φ {phi}: φ {p}");
        }
    }
    // An off-centre object: the camera is turned, the view is unchanged.
    let v = view(70.0, 200.0);
    let k = Intrinsics::default();
    let s = seed(
        &SeedInput {
            theta_deg: 70.0,
            phi_deg: 200.0,
            roll_deg: 0.0,
            roi_centre_px: DVec2::new(500.0, 90.0),
            intrinsics: Pinhole {
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
            },
            distance: Distance::Known {
                value: DISTANCE,
                sigma: 0.0,
            },
            confidence: 1.0,
            grid: GridSpacing {
                theta_deg: 10.0,
                phi_deg: 10.0,
            },
        },
        &CovarianceModel::default(),
    )
    .unwrap();
    let (t, p) = view_of(&s.camera_from_object);
    assert!((t - v.theta_deg).abs() < 1e-6 && phi_err(p, v.phi_deg) < 1e-6);
}

#[test]
fn exact_motion_and_measurements_track_the_truth_and_covariance_shrinks() {
    let traj = Trajectory::new(3, 5.0, DISTANCE).unwrap();
    let mut f = filter();
    let mut traces = Vec::new();
    for frame in traj.frames().take(40) {
        f.predict(&frame.camera_motion).unwrap();
        let before = f.is_initialised().then(|| trace(&f));
        let out = f.update(&measurement(&frame.view, 0.0, 0.0, 1.0)).unwrap();
        assert!(matches!(out, Outcome::Initialised | Outcome::Fused { .. }));
        let s = f.state().unwrap();
        assert!((s.theta_deg - frame.view.theta_deg).abs() < 1e-6);
        assert!(phi_err(s.phi_deg, frame.view.phi_deg) < 1e-6);
        traces.push(trace(&f));
        if let Some(b) = before {
            assert!(trace(&f) < b, "an update must shrink the covariance");
        }
    }
    // A prediction without a measurement grows it again.
    let t = trace(&f);
    f.predict(&traj.frame(40).camera_motion).unwrap();
    assert!(trace(&f) > t);
    assert!(
        traces[39] < traces[0] / 4.0,
        "covariance after 40 frames {:.3e} vs after 1 {:.3e}",
        traces[39],
        traces[0]
    );
    let vc = f.state().unwrap().view_covariance_deg2;
    assert!(vc[0][0] > 0.0 && vc[1][1] > 0.0 && (vc[0][1] - vc[1][0]).abs() < 1e-9);
}

#[test]
fn noisy_estimates_fuse_to_a_smaller_error_than_single_frames() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut single, mut fused, mut n) = (0.0, 0.0, 0);
    for seed_ in 0..5 {
        let traj = Trajectory::new(seed_, 5.0, DISTANCE).unwrap();
        let mut f = filter();
        for frame in traj.frames().take(60) {
            f.predict(&frame.camera_motion).unwrap();
            let (dt, dp) = (rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0));
            let theta_meas = (frame.view.theta_deg + dt).clamp(0.0, 90.0);
            f.update(&measurement(&frame.view, dt, dp, 1.0)).unwrap();
            if frame.index >= 10 {
                let s = f.state().unwrap();
                single += (theta_meas - frame.view.theta_deg).abs() + dp.abs();
                fused += (s.theta_deg - frame.view.theta_deg).abs()
                    + phi_err(s.phi_deg, frame.view.phi_deg);
                n += 1;
            }
        }
    }
    let (single, fused) = (single / n as f64, fused / n as f64);
    assert!(
        fused < 0.6 * single,
        "mean |Δθ| + |Δφ|: fused {fused:.2}° vs single {single:.2}°"
    );
}

#[test]
fn the_azimuth_wraps_through_zero_without_a_jump() {
    let mut f = filter();
    let mut prev = view(60.0, 340.0);
    let mut last_phi: Option<f64> = None;
    for i in 0..25 {
        let cur = view(60.0, 340.0 + 2.0 * i as f64);
        f.predict(&motion(&prev, &cur)).unwrap();
        // Estimates scattered on both sides of the truth, also across 0/360.
        let dphi = if i % 2 == 0 { 3.0 } else { -3.0 };
        f.update(&measurement(&cur, 0.0, dphi, 1.0)).unwrap();
        let s = f.state().unwrap();
        assert!((0.0..360.0).contains(&s.phi_deg));
        assert!(
            phi_err(s.phi_deg, cur.phi_deg) <= 3.0 + 1e-9,
            "frame {i}: fused φ {} vs {}",
            s.phi_deg,
            cur.phi_deg
        );
        if let Some(p) = last_phi {
            assert!(phi_err(p, s.phi_deg) < 6.0, "jump {p} -> {}", s.phi_deg);
        }
        last_phi = Some(s.phi_deg);
        prev = cur;
    }
    // Crossed 0: the last truth is 28°.
    assert!(phi_err(last_phi.unwrap(), 28.0) < 3.0);
}

#[test]
fn at_the_pole_phi_is_the_roll_and_stays_defined() {
    // Straight down, the camera turns about its optical axis.
    let mut f = filter();
    let mut prev = view(90.0, 350.0);
    let mut last_var = f64::INFINITY;
    for i in 0..20 {
        let cur = view(90.0, 350.0 + 3.0 * i as f64);
        f.predict(&motion(&prev, &cur)).unwrap();
        let d = if i % 2 == 0 { 2.0 } else { -2.0 };
        f.update(&measurement(&cur, 0.0, d, 1.0)).unwrap();
        let s = f.state().unwrap();
        assert!((s.theta_deg - 90.0).abs() < 1e-6, "θ {}", s.theta_deg);
        assert!(
            phi_err(s.phi_deg, cur.phi_deg) <= 2.0 + 1e-9,
            "φ {}",
            s.phi_deg
        );
        let vc = s.view_covariance_deg2;
        assert!(vc.iter().flatten().all(|x| x.is_finite()));
        // One measurement: φ spacing²/12 and the 5° roll, both about the
        // optical axis here, plus the sideways tilt the pole floor adds
        // (8.3 + 25 + 8.3 deg²); fusion shrinks it.
        assert!(vc[1][1] > 0.0 && vc[1][1] < 42.0, "var φ {}", vc[1][1]);
        last_var = vc[1][1];
        prev = cur;
    }
    assert!(last_var < 42.0 / 4.0, "var φ after 20 frames {last_var}");
    // Over the top: θ up to 90 at φ = 30, then down on the other side, φ =
    // 210. The filter follows through the pole with exact predictions only.
    let mut f = filter();
    let path: Vec<ViewPose> = (0..=10)
        .map(|i| view(80.0 + i as f64, 30.0))
        .chain((1..=10).map(|i| view(90.0 - i as f64, 210.0)))
        .collect();
    f.update(&measurement(&path[0], 0.0, 0.0, 1.0)).unwrap();
    for w in path.windows(2) {
        f.predict(&motion(&w[0], &w[1])).unwrap();
        let s = f.state().unwrap();
        assert!((s.theta_deg - w[1].theta_deg).abs() < 1e-6);
        if w[1].theta_deg < 90.0 {
            assert!(phi_err(s.phi_deg, w[1].phi_deg) < 1e-6);
        }
    }
}

#[test]
fn a_wrong_estimate_is_gated_and_does_not_move_the_fused_pose() {
    let mut f = filter();
    let v = view(60.0, 100.0);
    for i in 0..8 {
        f.predict(&DAffine3::IDENTITY).unwrap();
        let d = if i % 2 == 0 { 1.5 } else { -1.5 };
        f.update(&measurement(&v, d, -d, 1.0)).unwrap();
    }
    let before = f.state().unwrap();
    for (dt, dp) in [(0.0, 180.0), (25.0, 0.0), (0.0, -40.0)] {
        f.predict(&DAffine3::IDENTITY).unwrap();
        let out = f.update(&measurement(&v, dt, dp, 0.9)).unwrap();
        assert!(
            matches!(out, Outcome::Gated { .. }),
            "Δθ {dt} Δφ {dp}: {out:?}"
        );
        let s = f.state().unwrap();
        assert!((s.theta_deg - before.theta_deg).abs() < 1e-9);
        assert!(phi_err(s.phi_deg, before.phi_deg) < 1e-9);
    }
    // A consistent one is fused again.
    f.predict(&DAffine3::IDENTITY).unwrap();
    let out = f.update(&measurement(&v, 0.5, 0.5, 1.0)).unwrap();
    assert!(matches!(out, Outcome::Fused { .. }), "{out:?}");
}

#[test]
fn a_wrong_start_is_abandoned_when_consistent_estimates_disagree() {
    let mut f = filter();
    let mut prev = view(55.0, 10.0);
    // The first accepted estimate is a 180° flip.
    f.update(&measurement(&prev, 0.0, 180.0, 1.0)).unwrap();
    let mut outcomes = Vec::new();
    for i in 1..8 {
        let cur = view(55.0, 10.0 + 4.0 * i as f64);
        f.predict(&motion(&prev, &cur)).unwrap();
        outcomes.push(f.update(&measurement(&cur, 0.5, -0.5, 1.0)).unwrap());
        prev = cur;
    }
    let reinit = outcomes
        .iter()
        .position(|o| matches!(o, Outcome::Reinitialised { .. }))
        .expect("the filter restarts from the consistent estimates");
    assert_eq!(reinit + 1, FilterConfig::default().reinit_after as usize);
    let s = f.state().unwrap();
    assert!(phi_err(s.phi_deg, prev.phi_deg) < 2.0, "φ {}", s.phi_deg);
    assert!(
        outcomes[reinit + 1..]
            .iter()
            .all(|o| matches!(o, Outcome::Fused { .. }))
    );
}

#[test]
fn scattered_outliers_never_take_over() {
    // Wrong estimates that disagree with each other keep restarting the
    // challenger and never reach the fused state.
    let mut f = filter();
    let v = view(70.0, 250.0);
    f.update(&measurement(&v, 0.0, 0.0, 1.0)).unwrap();
    for (i, dp) in [120.0, -90.0, 170.0, 60.0, -150.0, 100.0]
        .iter()
        .enumerate()
    {
        f.predict(&DAffine3::IDENTITY).unwrap();
        let out = f.update(&measurement(&v, 0.0, *dp, 1.0)).unwrap();
        assert!(matches!(out, Outcome::Gated { in_a_row, .. } if in_a_row == i as u32 + 1));
    }
    assert!(phi_err(f.state().unwrap().phi_deg, 250.0) < 1e-6);
}

#[test]
fn bad_inputs_are_errors_naming_the_input() {
    let mut f = filter();
    let mut nan = DAffine3::IDENTITY;
    nan.translation.x = f64::NAN;
    assert!(matches!(
        f.predict(&nan),
        Err(FusionError::InvalidMotion(_))
    ));
    let skew = DAffine3::from_mat3(DMat3::from_diagonal(DVec3::new(1.0, 2.0, 1.0)));
    let e = f.predict(&skew).unwrap_err();
    assert!(e.to_string().contains("orthonormal"), "{e}");
    let mut m = measurement(&view(60.0, 0.0), 0.0, 0.0, 1.0);
    m.rotation_covariance = DMat3::from_diagonal(DVec3::new(1e-3, -1e-3, 1e-3));
    let e = f.update(&m).unwrap_err();
    assert!(e.to_string().contains("positive definite"), "{e}");
    m.rotation_covariance = DMat3::from_diagonal(DVec3::splat(1e-3));
    m.camera_from_object.translation = DVec3::ZERO;
    assert!(matches!(
        f.update(&m),
        Err(FusionError::InvalidMeasurement(_))
    ));
    assert!(!f.is_initialised());
    let bad = FilterConfig {
        gate_chi2: f64::NAN,
        ..FilterConfig::default()
    };
    assert!(matches!(
        ViewFilter::new(bad),
        Err(FusionError::InvalidConfig(_))
    ));
    let bad = FilterConfig {
        reinit_after: 0,
        ..FilterConfig::default()
    };
    assert!(ViewFilter::new(bad).is_err());
}

#[test]
fn a_measurement_at_the_pole_is_uncertain_in_every_direction() {
    // The seed's φ term turns about the optical axis at θ = 90; the view
    // direction must still be uncertain across e_θ, as much as along it.
    let var_theta = 10f64.to_radians().powi(2) / 12.0;
    for theta in [45.0, 80.0, 89.5, 90.0] {
        let m = measurement(&view(theta, 123.0), 0.0, 0.0, 1.0);
        let c = m.rotation_covariance;
        assert!(c.determinant() > 0.0, "θ {theta}: {c:?}");
        assert!(
            c.x_axis.x >= var_theta && c.y_axis.y >= var_theta * 0.999,
            "θ {theta}: {c:?}"
        );
    }
}

#[test]
fn a_censored_estimate_moves_phi_but_not_theta() {
    assert!(theta_censored(45.0, 45.0) && !theta_censored(45.5, 45.0));
    // Tracking at θ = 60 from exact estimates, then the camera goes down to
    // θ = 30, below a database whose lowest slice is 45: every estimate there
    // says 45 (censored) with φ 3° off.
    let mut f = filter();
    let mut prev = view(60.0, 100.0);
    f.update(&measurement(&prev, 0.0, 0.0, 1.0)).unwrap();
    for k in 1..=30 {
        let cur = view(60.0 - k as f64, 100.0 + k as f64);
        f.predict(&motion(&prev, &cur)).unwrap();
        let dtheta = 45.0 - cur.theta_deg;
        let m = measurement(&cur, dtheta.max(0.0), 3.0, 1.0);
        let m = if dtheta > 0.0 {
            m.without_theta(&input(&cur, dtheta, 3.0, 1.0))
        } else {
            m
        };
        f.update(&m).unwrap();
        prev = cur;
    }
    let s = f.state().unwrap();
    assert!(
        (s.theta_deg - 30.0).abs() < 1.0,
        "fused θ {:.2} must follow the motion, not the censored 45",
        s.theta_deg
    );
    let dphi = phi_err(s.phi_deg, 130.0);
    assert!(
        dphi > 1.0 && dphi < 3.5,
        "fused φ {:.2} must move towards the estimates' (off by 3°)",
        s.phi_deg
    );

    // A filter started from a censored estimate knows it does not know θ,
    // and the first uncensored estimate sets it, 15° away or not.
    let mut g = filter();
    let low = view(35.0, 200.0);
    g.update(&measurement(&low, 10.0, 0.0, 1.0).without_theta(&input(&low, 10.0, 0.0, 1.0)))
        .unwrap();
    let s = g.state().unwrap();
    assert!((s.theta_deg - 45.0).abs() < 1e-6);
    assert!(s.view_covariance_deg2[0][0].sqrt() > 60.0, "{s:?}");
    let up = view(50.0, 200.0);
    g.predict(&motion(&low, &up)).unwrap();
    let out = g.update(&measurement(&up, 0.0, 0.0, 1.0)).unwrap();
    assert!(matches!(out, Outcome::Fused { .. }), "{out:?}");
    let s = g.state().unwrap();
    assert!((s.theta_deg - 50.0).abs() < 1.0, "{s:?}");
    assert!(s.view_covariance_deg2[0][0].sqrt() < 5.0, "{s:?}");
}
